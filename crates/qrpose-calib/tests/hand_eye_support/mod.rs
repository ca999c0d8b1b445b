//! Synthetic hand-eye sessions with a known mount and target: views of a QR code's points
//! (support's `qr_target_mm`, moved into qrpose-detect's marker frame, origin at corner P2)
//! projected through support's barrel camera, with Gaussian pixel noise and flange poses
//! reported with Gaussian noise, all from a seeded `StdRng`.

#![allow(dead_code)]

use crate::support::{CODE_MM, IMAGE, barrel_camera, gaussian, qr_target_mm, tilted};
use nalgebra::{Isometry3, Point2, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use qrpose_calib::Correspondence;
use qrpose_calib::handeye::{HandEyeSetup, HandEyeView};
use qrpose_core::geometry::camera::Camera;
use qrpose_core::geometry::frames::CameraPoint;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// How the views are drawn.
#[derive(Debug, Clone, Copy)]
pub struct Draw {
    pub views: usize,
    /// Largest tilt of the code from facing the camera, rad.
    pub max_tilt: f64,
    /// Largest spin about the code's normal, rad.
    pub max_spin: f64,
    /// Depth of the code's centre, mm.
    pub depth_mm: (f64, f64),
    /// Pixel noise per axis, px.
    pub noise_px: f64,
    /// Flange noise per axis, mm and rad.
    pub flange_mm: f64,
    pub flange_rad: f64,
    /// Only spin (the code never tilts): every motion turns about the camera's axis.
    pub spin_only: bool,
}

impl Draw {
    /// 12 views at 0.3-0.7 m tilted up to 40°, 0.1 px pixel noise, 0.2 mm / 0.02° flange noise.
    pub fn good() -> Self {
        Self {
            views: 12,
            max_tilt: 40f64.to_radians(),
            max_spin: 60f64.to_radians(),
            depth_mm: (300.0, 700.0),
            noise_px: 0.1,
            flange_mm: 0.2,
            flange_rad: 0.02f64.to_radians(),
            spin_only: false,
        }
    }

    /// `good()` without any noise.
    pub fn exact() -> Self {
        Self {
            noise_px: 0.0,
            flange_mm: 0.0,
            flange_rad: 0.0,
            ..Self::good()
        }
    }
}

/// A session and its truth.
pub struct Session {
    pub setup: HandEyeSetup,
    pub camera: Camera,
    /// T_flange←camera or T_robot←camera.
    pub mount: Isometry3<f64>,
    /// T_robot←marker or T_flange←marker, marker frame at the symbol's centre.
    pub target: Isometry3<f64>,
    pub views: Vec<HandEyeView>,
    /// The true flange poses.
    pub flanges: Vec<Isometry3<f64>>,
}

/// The symbol's centre in the paper's marker frame (origin P2): (−l/2, l/2, 0).
pub fn centre_offset() -> Isometry3<f64> {
    Isometry3::translation(-0.5 * CODE_MM, 0.5 * CODE_MM, 0.0)
}

/// The code's points in the paper's marker frame, mm.
pub fn paper_points() -> Vec<Point2<f64>> {
    qr_target_mm()
        .iter()
        .map(|p| Point2::new(p.x - 0.5 * CODE_MM, p.y + 0.5 * CODE_MM))
        .collect()
}

fn iso(r: Rotation3<f64>, t: Vector3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

/// The true mount and target of each setup.
pub fn truth(setup: HandEyeSetup) -> (Isometry3<f64>, Isometry3<f64>) {
    match setup {
        HandEyeSetup::EyeInHand => (
            iso(
                Rotation3::from_euler_angles(0.05, -0.08, 1.6),
                Vector3::new(42.0, -27.0, 95.0),
            ),
            iso(
                Rotation3::from_euler_angles(3.1, 0.02, 0.4),
                Vector3::new(650.0, 120.0, 15.0),
            ),
        ),
        HandEyeSetup::EyeToHand => (
            iso(
                Rotation3::from_euler_angles(-2.2, 0.1, 1.9),
                Vector3::new(900.0, 700.0, 850.0),
            ),
            iso(
                Rotation3::from_euler_angles(0.1, 3.0, -0.7),
                Vector3::new(10.0, -35.0, 160.0),
            ),
        ),
    }
}

/// A pose perturbed as the flange noise: R̃ = exp([ε_θ]×)·R, t̃ = t + ε_t.
pub fn noisy(pose: &Isometry3<f64>, mm: f64, rad: f64, rng: &mut StdRng) -> Isometry3<f64> {
    let w = Vector3::new(gaussian(rng), gaussian(rng), gaussian(rng)) * rad;
    let dt = Vector3::new(gaussian(rng), gaussian(rng), gaussian(rng)) * mm;
    Isometry3::from_parts(
        Translation3::from(pose.translation.vector + dt),
        UnitQuaternion::from_scaled_axis(w) * pose.rotation,
    )
}

/// The code's pose in the camera (paper frame) for view k.
fn code_in_camera(draw: &Draw, rng: &mut StdRng) -> Isometry3<f64> {
    let depth = rng.gen_range(draw.depth_mm.0..=draw.depth_mm.1);
    let tilt = if draw.spin_only {
        0.35
    } else {
        rng.gen_range(0.0..=draw.max_tilt)
    };
    let azimuth = if draw.spin_only {
        0.3
    } else {
        rng.gen_range(0.0..std::f64::consts::TAU)
    };
    let spin = rng.gen_range(-draw.max_spin..=draw.max_spin);
    let r = tilted(tilt, azimuth, spin);
    let (ox, oy) = (rng.gen_range(-0.2..0.2), rng.gen_range(-0.12..0.12));
    let centre = Vector3::new(ox * depth, oy * depth, depth);
    iso(r, centre) * centre_offset().inverse()
}

/// Where the code's points are seen, px, with noise; `None` unless all are inside the image.
fn observe(
    camera: &Camera,
    code: &Isometry3<f64>,
    noise_px: f64,
    rng: &mut StdRng,
) -> Option<Vec<Correspondence>> {
    paper_points()
        .iter()
        .map(|m| {
            let p = code * Point3::new(m.x, m.y, 0.0);
            let uv = camera.project(&CameraPoint(p))?;
            let inside = uv.u() > 2.0
                && uv.v() > 2.0
                && uv.u() < IMAGE.width() - 3.0
                && uv.v() < IMAGE.height() - 3.0;
            inside.then(|| {
                Correspondence::new(
                    m.x,
                    m.y,
                    uv.u() + noise_px * gaussian(rng),
                    uv.v() + noise_px * gaussian(rng),
                )
            })
        })
        .collect()
}

/// The flange pose F for the camera seeing the code at `code` (paper frame).
fn flange_for(
    setup: HandEyeSetup,
    mount: &Isometry3<f64>,
    target: &Isometry3<f64>,
    code: &Isometry3<f64>,
) -> Isometry3<f64> {
    // Y_paper = G·X·C, G = F (eye-in-hand) or F⁻¹.
    let y_paper = target * centre_offset().inverse();
    let g = y_paper * code.inverse() * mount.inverse();
    match setup {
        HandEyeSetup::EyeInHand => g,
        HandEyeSetup::EyeToHand => g.inverse(),
    }
}

/// A session drawn from `seed`.
pub fn session(setup: HandEyeSetup, draw: &Draw, seed: u64) -> Session {
    let mut rng = StdRng::seed_from_u64(seed);
    let camera = barrel_camera();
    let (mount, target) = truth(setup);
    let mut views = Vec::new();
    let mut flanges = Vec::new();
    while views.len() < draw.views {
        let code = code_in_camera(draw, &mut rng);
        let Some(correspondences) = observe(&camera, &code, draw.noise_px, &mut rng) else {
            continue;
        };
        let flange = flange_for(setup, &mount, &target, &code);
        let flange_pose = noisy(&flange, draw.flange_mm, draw.flange_rad, &mut rng);
        flanges.push(flange);
        views.push(HandEyeView {
            correspondences,
            flange_pose,
        });
    }
    Session {
        setup,
        camera,
        mount,
        target,
        views,
        flanges,
    }
}

/// The rotation angle between two poses, rad, and the distance between their origins, mm.
pub fn pose_error(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    (
        a.rotation.angle_to(&b.rotation),
        (a.translation.vector - b.translation.vector).norm(),
    )
}
