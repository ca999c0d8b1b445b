//! Seeded sets of noisy corner observations, for accuracy studies and benchmarks shared with
//! external tools (OpenCV) through CSV.
//!
//! A case is a 50 mm marker in front of a 1280×720 camera with fx = fy = 1000 px (by
//! default), at a random distance, tilted up to a maximum about a random in-plane axis,
//! turned any way in its plane, centred anywhere such that all four corners lie inside the
//! image, its face at most 75° oblique to the viewing ray; Gaussian noise of σ px is added to
//! each corner coordinate.

use nalgebra::{Rotation3, Unit, Vector3};
use qrpose_core::geometry::{
    camera::{Camera, CameraError},
    frames::{MarkerToCamera, PixelPoint},
    marker::{CornerOrder, Marker, MarkerError},
};
use rand::{Rng, SeedableRng, rngs::StdRng};
use rand_distr::{Distribution, Normal, NormalError};
use std::fmt::Write;
use thiserror::Error;

/// What to generate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DatasetSpec {
    /// Number of cases.
    pub cases: usize,
    /// Seed of the generator.
    pub seed: u64,
    /// Corner noise σ per coordinate, px.
    pub sigma_px: f64,
    /// Image size, px.
    pub image_px: (u32, u32),
    /// Focal length, px (fx = fy), principal point at the image centre.
    pub f_px: f64,
    /// Marker side, mm.
    pub marker_mm: f64,
    /// Distance range of the marker centre, mm.
    pub distance_mm: (f64, f64),
    /// Largest tilt, degrees.
    pub max_tilt_deg: f64,
}

impl Default for DatasetSpec {
    fn default() -> Self {
        Self {
            cases: 2000,
            seed: 2022,
            sigma_px: 0.5,
            image_px: (1280, 720),
            f_px: 1000.0,
            marker_mm: 50.0,
            distance_mm: (200.0, 1500.0),
            max_tilt_deg: 60.0,
        }
    }
}

/// One observation and its truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CornerCase {
    /// The true pose.
    pub truth: MarkerToCamera,
    /// The true marker centre, camera frame, mm.
    pub centre_mm: Vector3<f64>,
    /// The exact corners, px, in `"qr"` order.
    pub exact_px: [PixelPoint; 4],
    /// The noisy corners, px, in `"qr"` order.
    pub noisy_px: [PixelPoint; 4],
}

/// Why a dataset could not be made.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DatasetError {
    /// The camera was refused.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// The marker was refused.
    #[error(transparent)]
    Marker(#[from] MarkerError),
    /// σ was negative or not finite.
    #[error("invalid noise: {0}")]
    Noise(#[from] NormalError),
}

impl DatasetSpec {
    /// The camera of this dataset.
    ///
    /// # Errors
    /// [`DatasetError::Camera`] for a non-positive focal length.
    pub fn camera(&self) -> Result<Camera, DatasetError> {
        let (w, h) = self.image_px;
        Ok(Camera::from_pixels(
            self.f_px,
            self.f_px,
            (f64::from(w) - 1.0) / 2.0,
            (f64::from(h) - 1.0) / 2.0,
        )?)
    }

    /// The marker of this dataset.
    ///
    /// # Errors
    /// [`DatasetError::Marker`] for a non-positive size.
    pub fn marker(&self) -> Result<Marker, DatasetError> {
        Ok(Marker::try_new(self.marker_mm)?)
    }
}

fn draw_pose(
    rng: &mut StdRng,
    spec: &DatasetSpec,
    camera: &Camera,
    marker: &Marker,
) -> MarkerToCamera {
    let (w, h) = (f64::from(spec.image_px.0), f64::from(spec.image_px.1));
    let axis_angle = rng.gen_range(0.0..std::f64::consts::TAU);
    let axis = Unit::new_normalize(Vector3::new(axis_angle.cos(), axis_angle.sin(), 0.0));
    let tilt = rng.gen_range(0.0..=spec.max_tilt_deg).to_radians();
    let spin = rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI);
    let r = Rotation3::from_axis_angle(&axis, tilt)
        * Rotation3::from_axis_angle(&Vector3::z_axis(), spin);
    let (u, v) = (rng.gen_range(0.0..w - 1.0), rng.gen_range(0.0..h - 1.0));
    let d = rng.gen_range(spec.distance_mm.0..spec.distance_mm.1);
    let ray = Vector3::new(
        (u - camera.cx()) / camera.fx(),
        (v - camera.cy()) / camera.fy(),
        1.0,
    )
    .normalize();
    let centre = ray * d;
    marker.pose_centred_at(r, centre)
}

/// Generates the dataset: deterministic for a given spec.
///
/// # Errors
/// [`DatasetError`] for an invalid camera, marker or noise.
pub fn generate(spec: &DatasetSpec) -> Result<Vec<CornerCase>, DatasetError> {
    let camera = spec.camera()?;
    let marker = spec.marker()?;
    let noise = Normal::new(0.0, spec.sigma_px)?;
    let mut rng = StdRng::seed_from_u64(spec.seed);
    let (w, h) = (f64::from(spec.image_px.0), f64::from(spec.image_px.1));
    let inside =
        |p: &PixelPoint| (0.0..w - 1.0).contains(&p.u()) && (0.0..h - 1.0).contains(&p.v());
    let mut out = Vec::with_capacity(spec.cases);
    while out.len() < spec.cases {
        let truth = draw_pose(&mut rng, spec, &camera, &marker);
        let centre_mm = truth.transform(&marker.centre()).0.coords;
        let normal = truth.rotation() * Vector3::z();
        if normal.angle(&centre_mm).to_degrees() > 75.0 {
            continue;
        }
        let projected: Option<Vec<PixelPoint>> = marker
            .object_points()
            .iter()
            .map(|m| camera.project(&truth.transform(m)))
            .collect();
        let Some(p) = projected.filter(|p| p.iter().all(inside)) else {
            continue;
        };
        let exact_px = CornerOrder::Qr.from_paper([p[0], p[1], p[2], p[3]]);
        let noisy_px = exact_px.map(|q| {
            PixelPoint::new(
                q.u() + noise.sample(&mut rng),
                q.v() + noise.sample(&mut rng),
            )
        });
        out.push(CornerCase {
            truth,
            centre_mm,
            exact_px,
            noisy_px,
        });
    }
    Ok(out)
}

/// The dataset as CSV: the camera and marker in a comment header, then per case the true
/// rotation (row-major), the true centre (mm) and the noisy corners in `"qr"` order (px).
pub fn to_csv(spec: &DatasetSpec, cases: &[CornerCase]) -> String {
    let (w, h) = spec.image_px;
    let mut out = format!(
        "# width_px={w} height_px={h} f_px={} cx_px={} cy_px={} marker_mm={} sigma_px={} seed={}\n",
        spec.f_px,
        (f64::from(w) - 1.0) / 2.0,
        (f64::from(h) - 1.0) / 2.0,
        spec.marker_mm,
        spec.sigma_px,
        spec.seed
    );
    out.push_str("id,r11,r12,r13,r21,r22,r23,r31,r32,r33,cx_mm,cy_mm,cz_mm,u_tl,v_tl,u_tr,v_tr,u_br,v_br,u_bl,v_bl\n");
    for (i, c) in cases.iter().enumerate() {
        let _ = write!(out, "{i}");
        let r = c.truth.rotation();
        for row in 0..3 {
            for col in 0..3 {
                let _ = write!(out, ",{:.17e}", r[(row, col)]);
            }
        }
        for v in c.centre_mm.iter() {
            let _ = write!(out, ",{v:.17e}");
        }
        for p in c.noisy_px {
            let _ = write!(out, ",{:.17e},{:.17e}", p.u(), p.v());
        }
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn datasets_are_reproducible_and_inside_the_image() {
        let spec = DatasetSpec {
            cases: 50,
            ..DatasetSpec::default()
        };
        let a = generate(&spec).expect("valid spec");
        let b = generate(&spec).expect("valid spec");
        assert_eq!(a, b);
        for c in &a {
            assert!(
                c.noisy_px
                    .iter()
                    .all(|p| p.u() > -2.0 && p.u() < 1282.0 && p.v() > -2.0 && p.v() < 722.0)
            );
            let d = c.centre_mm.norm();
            assert!((200.0..1500.0).contains(&d), "distance {d}");
        }
        let csv = to_csv(&spec, &a);
        assert_eq!(csv.lines().count(), 2 + 50);
        assert!(
            csv.lines()
                .nth(2)
                .is_some_and(|l| l.split(',').count() == 21)
        );
    }

    #[test]
    fn exact_corners_are_the_projection_of_the_truth() {
        let spec = DatasetSpec {
            cases: 5,
            sigma_px: 0.0,
            ..DatasetSpec::default()
        };
        let camera = spec.camera().expect("camera");
        let marker = spec.marker().expect("marker");
        for c in generate(&spec).expect("valid spec") {
            let tl = camera
                .project(&c.truth.transform(&marker.object_points()[2]))
                .expect("in front");
            assert!((tl.0 - c.exact_px[0].0).norm() < 1e-9 && c.noisy_px == c.exact_px);
        }
    }
}
