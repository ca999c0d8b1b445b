//! Hand-eye sessions with ground truth (`docs/hand-eye.md`): a camera on a robot arm
//! (eye-in-hand: on the flange, the code still in the robot's frame; eye-to-hand: the
//! camera still, the code held by the flange), the true mount and target, the true flange
//! pose of each photo, the flange poses as a controller would report them (with Gaussian
//! noise), and the photos rendered by the same rasteriser as every other photo
//! ([`super::render`]), optionally with a checkerboard of the code's size at the very same
//! poses ([`super::render_checkerboard`]).
//!
//! Frames as `docs/hand-eye.md`: `robot`, `flange`, `camera` (x right, y down, z
//! forward), `marker` at the symbol's centre with the axes of `docs/conventions.md`.
//! Transforms are T_parent←child, p_parent = R·p_child + t, mm. With X the mount
//! (T_flange←camera or T_robot←camera), Y the target (T_robot←marker or T_flange←marker)
//! and F the flange (T_robot←flange), the code is seen at T_camera←marker = X⁻¹·F⁻¹·Y
//! (eye-in-hand) or X⁻¹·F·Y (eye-to-hand).
//!
//! Flange noise: a reported pose is R̃ = exp([ε_θ]×)·R, t̃ = t + ε_t, each component of
//! ε_θ (rad) and ε_t (mm) independent Gaussian of the given standard deviation, in the
//! robot frame's axes.
//!
//! Generated views ([`ViewGenerator`]): the code's centre at a depth drawn uniformly in
//! `distance_mm` and at an image position drawn uniformly within the central 70 % of each
//! axis; its normal tilted from the line of sight by an angle drawn uniformly up to
//! `max_tilt_deg` about a direction drawn uniformly in the code's plane, then spun about
//! its normal by up to ±[`MAX_SPIN_DEG`]: the relative rotations turn about varied axes.
//! Redrawn until the code with its quiet zone is inside the image by [`MARGIN_PX`].

use super::{DEFAULT_QUIET_ZONE_MODULES, RenderError};
use nalgebra::{Isometry3, Point3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};
use qrpose_core::geometry::camera::Camera;
use qrpose_core::geometry::frames::{CameraPoint, MarkerToCamera};
use qrpose_core::geometry::marker::Marker;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// Largest spin of a generated view's code about its normal, degrees.
pub const MAX_SPIN_DEG: f64 = 60.0;
/// Pixels the code with its quiet zone keeps from the image's edge in a generated view.
pub const MARGIN_PX: f64 = 4.0;
/// Fraction of each image axis the generated code centres are drawn within.
const CENTRE_SPAN: f64 = 0.7;
/// Draws of one view before the generator gives up.
const MAX_DRAWS: usize = 10_000;

/// Where the camera is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Setup {
    /// The camera on the flange, the code still in the robot's frame.
    EyeInHand,
    /// The camera still in the robot's frame, the code on the flange.
    EyeToHand,
}

/// A transform as the API writes it: p_parent = R·p_child + t.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Transform {
    /// t, mm.
    pub translation_mm: [f64; 3],
    /// R as a unit quaternion (w, x, y, z); normalised when read.
    pub quaternion_wxyz: [f64; 4],
}

impl Transform {
    /// The isometry; `None` for a zero or non-finite quaternion or translation.
    #[must_use]
    pub fn to_isometry(&self) -> Option<Isometry3<f64>> {
        let [w, x, y, z] = self.quaternion_wxyz;
        let q = nalgebra::Quaternion::new(w, x, y, z);
        let n = q.norm();
        let finite = self
            .translation_mm
            .iter()
            .chain(&self.quaternion_wxyz)
            .all(|v| v.is_finite());
        (finite && n > 0.0).then(|| {
            Isometry3::from_parts(
                Translation3::from(Vector3::from(self.translation_mm)),
                UnitQuaternion::from_quaternion(q),
            )
        })
    }

    /// The transform of an isometry, w ≥ 0.
    #[must_use]
    pub fn from_isometry(iso: &Isometry3<f64>) -> Self {
        let q = iso.rotation.into_inner();
        let s = if q.w < 0.0 { -1.0 } else { 1.0 };
        let t = iso.translation.vector;
        Self {
            translation_mm: [t.x, t.y, t.z],
            quaternion_wxyz: [s * q.w, s * q.i, s * q.j, s * q.k],
        }
    }
}

/// How views are drawn (module doc).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ViewGenerator {
    /// Number of views.
    pub views: usize,
    /// Depth range of the code's centre, mm.
    pub distance_mm: [f64; 2],
    /// Largest tilt of the code from facing the camera, degrees.
    pub max_tilt_deg: f64,
}

impl Default for ViewGenerator {
    fn default() -> Self {
        Self {
            views: 12,
            distance_mm: [300.0, 700.0],
            max_tilt_deg: 40.0,
        }
    }
}

/// The flange noise: standard deviations per axis.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FlangeNoise {
    /// Each position coordinate, mm.
    pub translation_mm: f64,
    /// Rotation about each axis, degrees.
    pub rotation_deg: f64,
}

/// The symbol's centre in the paper's marker frame (origin P2): (−l/2, l/2, 0).
fn centre_offset(marker: &Marker) -> Isometry3<f64> {
    let half = 0.5 * marker.size_mm();
    Isometry3::translation(-half, half, 0.0)
}

/// T_camera←marker (marker frame at the symbol's centre) for the flange pose `flange`.
#[must_use]
pub fn code_in_camera(
    setup: Setup,
    mount: &Isometry3<f64>,
    target: &Isometry3<f64>,
    flange: &Isometry3<f64>,
) -> Isometry3<f64> {
    let h = match setup {
        Setup::EyeInHand => flange.inverse(),
        Setup::EyeToHand => *flange,
    };
    mount.inverse() * h * target
}

/// The flange pose that shows the code at `code` (T_camera←marker, centre frame).
#[must_use]
pub fn flange_for(
    setup: Setup,
    mount: &Isometry3<f64>,
    target: &Isometry3<f64>,
    code: &Isometry3<f64>,
) -> Isometry3<f64> {
    // code = X⁻¹·H·Y  ⇒  H = X·code·Y⁻¹; H = F⁻¹ (eye-in-hand) or F.
    let h = mount * code * target.inverse();
    match setup {
        Setup::EyeInHand => h.inverse(),
        Setup::EyeToHand => h,
    }
}

/// The code's pose in the core's type (paper frame, origin P2) from the centre-frame pose.
#[must_use]
pub fn marker_to_camera(code: &Isometry3<f64>, marker: &Marker) -> MarkerToCamera {
    let paper = code * centre_offset(marker).inverse();
    MarkerToCamera::new(
        paper.rotation.to_rotation_matrix(),
        paper.translation.vector,
    )
}

/// Whether the code with its quiet zone projects inside the image by [`MARGIN_PX`].
fn in_view(
    camera: &Camera,
    width_px: u32,
    height_px: u32,
    marker: &Marker,
    code: &Isometry3<f64>,
) -> bool {
    // The quiet zone of a 4-module margin on a symbol of at least 21 modules: at most
    // 4/21 of the side on each side; the outline of the printed square with it.
    let half = 0.5 * marker.size_mm() * (1.0 + 2.0 * DEFAULT_QUIET_ZONE_MODULES / 21.0);
    let (w, h) = (f64::from(width_px), f64::from(height_px));
    [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .iter()
        .all(|&(sx, sy)| {
            let p = code * Point3::new(sx * half, sy * half, 0.0);
            camera.project(&CameraPoint(p)).is_some_and(|uv| {
                uv.u() >= MARGIN_PX - 0.5
                    && uv.v() >= MARGIN_PX - 0.5
                    && uv.u() <= w - 0.5 - MARGIN_PX
                    && uv.v() <= h - 0.5 - MARGIN_PX
            })
        })
}

/// `views` code poses in the camera (centre frame) drawn as the module doc says.
///
/// # Errors
/// [`RenderError::Range`] when a range is empty or not finite, or when no pose in range
/// shows the whole code in [`MAX_DRAWS`] draws.
pub fn generate_code_poses(
    generator: &ViewGenerator,
    camera: &Camera,
    width_px: u32,
    height_px: u32,
    marker: &Marker,
    rng: &mut StdRng,
) -> Result<Vec<Isometry3<f64>>, RenderError> {
    let [near, far] = generator.distance_mm;
    if !(near.is_finite() && far.is_finite() && near > 0.0 && far >= near) {
        return Err(RenderError::Range {
            name: "distance_mm",
            value: near,
        });
    }
    let tilt = generator.max_tilt_deg;
    if !(tilt.is_finite() && (0.0..90.0).contains(&tilt)) {
        return Err(RenderError::Range {
            name: "max_tilt_deg",
            value: tilt,
        });
    }
    let (w, h) = (f64::from(width_px), f64::from(height_px));
    let mut poses = Vec::with_capacity(generator.views);
    for _ in 0..generator.views {
        let found = (0..MAX_DRAWS).find_map(|_| {
            let depth = rng.gen_range(near..=far);
            let u = (0.5 + CENTRE_SPAN * (rng.r#gen::<f64>() - 0.5)) * w - 0.5;
            let v = (0.5 + CENTRE_SPAN * (rng.r#gen::<f64>() - 0.5)) * h - 0.5;
            let ray = camera
                .normalize(&qrpose_core::geometry::frames::PixelPoint::new(u, v))
                .ok()?;
            let centre = Vector3::new(ray.x() * depth, ray.y() * depth, depth);
            let azimuth = rng.gen_range(0.0..std::f64::consts::TAU);
            let axis = Unit::new_normalize(Vector3::new(azimuth.cos(), azimuth.sin(), 0.0));
            let tilt_rad = rng.gen_range(0.0..=tilt).to_radians();
            let spin = rng.gen_range(-MAX_SPIN_DEG..=MAX_SPIN_DEG).to_radians();
            let r = Rotation3::from_axis_angle(&axis, tilt_rad)
                * Rotation3::from_axis_angle(&Vector3::z_axis(), spin);
            let code = Isometry3::from_parts(
                Translation3::from(centre),
                UnitQuaternion::from_rotation_matrix(&r),
            );
            in_view(camera, width_px, height_px, marker, &code).then_some(code)
        });
        poses.push(found.ok_or(RenderError::Range {
            name: "distance_mm",
            value: near,
        })?);
    }
    Ok(poses)
}

/// `pose` as a controller reports it with `noise` (module doc), drawn from `rng`.
#[must_use]
pub fn reported_flange(
    pose: &Isometry3<f64>,
    noise: &FlangeNoise,
    rng: &mut StdRng,
) -> Isometry3<f64> {
    let mut draw = || -> f64 { StandardNormal.sample(rng) };
    let w = Vector3::new(draw(), draw(), draw()) * noise.rotation_deg.to_radians();
    let dt = Vector3::new(draw(), draw(), draw()) * noise.translation_mm;
    Isometry3::from_parts(
        Translation3::from(pose.translation.vector + dt),
        UnitQuaternion::from_scaled_axis(w) * pose.rotation,
    )
}

/// A session's geometry: the true and reported flange poses and where the code is.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionPoses {
    /// The true flange poses, T_robot←flange.
    pub flanges: Vec<Isometry3<f64>>,
    /// The reported ones.
    pub reported: Vec<Isometry3<f64>>,
    /// The code in the camera in each view (centre frame).
    pub codes: Vec<Isometry3<f64>>,
}

/// The session's poses: the given true flange poses, or generated ones; each reported with
/// `noise`, drawn from `seed` (the same seed gives the same poses and noise; the views are
/// drawn first, then the noise, so the same seed with twice the noise draws the same
/// normal deviates, doubled).
///
/// # Errors
/// As [`generate_code_poses`].
#[allow(clippy::too_many_arguments)]
pub fn session_poses(
    setup: Setup,
    mount: &Isometry3<f64>,
    target: &Isometry3<f64>,
    flanges: Option<&[Isometry3<f64>]>,
    generator: &ViewGenerator,
    noise: &FlangeNoise,
    camera: &Camera,
    size_px: [u32; 2],
    marker: &Marker,
    seed: u64,
) -> Result<SessionPoses, RenderError> {
    let mut rng = StdRng::seed_from_u64(seed);
    let flanges: Vec<Isometry3<f64>> = match flanges {
        Some(f) => f.to_vec(),
        None => generate_code_poses(generator, camera, size_px[0], size_px[1], marker, &mut rng)?
            .iter()
            .map(|code| flange_for(setup, mount, target, code))
            .collect(),
    };
    let mut noise_rng = StdRng::seed_from_u64(seed ^ 0x5eed_f1a6_e000_0000);
    let reported = flanges
        .iter()
        .map(|f| reported_flange(f, noise, &mut noise_rng))
        .collect();
    let codes = flanges
        .iter()
        .map(|f| code_in_camera(setup, mount, target, f))
        .collect();
    Ok(SessionPoses {
        flanges,
        reported,
        codes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_flange_for_a_code_pose_shows_the_code_there_in_both_setups() {
        let mount = Isometry3::from_parts(
            Translation3::new(40.0, -20.0, 90.0),
            UnitQuaternion::from_euler_angles(0.1, -0.2, 1.5),
        );
        let target = Isometry3::from_parts(
            Translation3::new(600.0, 100.0, 10.0),
            UnitQuaternion::from_euler_angles(3.0, 0.1, 0.2),
        );
        let code = Isometry3::from_parts(
            Translation3::new(10.0, -5.0, 450.0),
            UnitQuaternion::from_euler_angles(0.3, 0.2, -0.4),
        );
        for setup in [Setup::EyeInHand, Setup::EyeToHand] {
            let f = flange_for(setup, &mount, &target, &code);
            let back = code_in_camera(setup, &mount, &target, &f);
            assert!(
                (back.to_homogeneous() - code.to_homogeneous()).norm() < 1e-9,
                "{setup:?}"
            );
        }
    }

    #[test]
    fn generated_views_keep_the_code_in_view_within_the_ranges() {
        let camera = Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("valid");
        let marker = Marker::try_new(120.0).expect("valid");
        let g = ViewGenerator::default();
        let mut rng = StdRng::seed_from_u64(3);
        let poses = generate_code_poses(&g, &camera, 1280, 720, &marker, &mut rng).expect("drawn");
        assert_eq!(poses.len(), 12);
        for p in &poses {
            let z = p.translation.vector.z;
            assert!((300.0..=700.0).contains(&z), "{z}");
            let normal = p.rotation * Vector3::z();
            let tilt = normal.angle(&Vector3::z()).to_degrees();
            assert!(tilt <= 40.0 + 1e-9, "{tilt}");
        }
    }
}
