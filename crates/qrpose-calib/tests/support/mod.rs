//! Synthetic calibration sets with a known camera: the points of a QR-code-like target,
//! views of it at chosen or random poses, projected through qrpose-core's camera and
//! perturbed by Gaussian noise from a seeded `StdRng`. Shared by the tests and the
//! `calib_speed` example.

#![allow(dead_code)]

use nalgebra::{Point2, Point3, Rotation3, Unit, Vector3};
use qrpose_calib::{Correspondence, ImageSize, View};
use qrpose_core::geometry::camera::{Camera, Distortion, DistortionModel};
use qrpose_core::geometry::frames::{MarkerPoint, MarkerToCamera, PixelPoint};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::collections::BTreeSet;
use std::f64::consts::PI;

/// The image of every test camera.
pub const IMAGE: ImageSize = ImageSize::new(1280, 720);

/// The printed code's side, mm.
pub const CODE_MM: f64 = 120.0;

/// Modules per side (a version-4 symbol).
pub const MODULES: u32 = 33;

/// The reference camera: off-centre principal point, barrel plumb_bob.
pub fn barrel_camera() -> Camera {
    camera(
        (1000.0, 1005.0, 650.0, 350.0),
        DistortionModel::PlumbBob,
        &[-0.25, 0.08, 1e-3, -5e-4, 0.0],
    )
}

/// A wide-angle camera with OpenCV's rational model (the coefficients of qrpose-site's
/// `opencv_rational_polynomial.yaml` fixture, on a 1280 × 720 sensor).
pub fn wide_angle_camera() -> Camera {
    camera(
        (900.0, 902.0, 645.0, 355.0),
        DistortionModel::RationalPolynomial,
        &[
            0.3521, -0.0472, 0.00037, -0.00029, 0.0013, 0.6893, 0.0104, -0.0031,
        ],
    )
}

/// A fisheye camera (the coefficients of qrpose-site's `opencv_fisheye.yaml` fixture, on a
/// 1280 × 720 sensor: rays up to 70° off the axis reach the image corners).
pub fn fisheye_camera() -> Camera {
    camera(
        (600.0, 601.0, 645.0, 355.0),
        DistortionModel::Equidistant,
        &[-0.00566, 0.04186, -0.03869, 0.00673],
    )
}

/// A camera from (fx, fy, cx, cy), px, and a lens.
pub fn camera(k: (f64, f64, f64, f64), model: DistortionModel, coefficients: &[f64]) -> Camera {
    Camera::from_pixels(k.0, k.1, k.2, k.3)
        .expect("valid intrinsics")
        .with_distortion(Distortion::from_coefficients(model, coefficients).expect("valid lens"))
}

/// The known points of a QR code of `MODULES` modules on a side of `CODE_MM`, centred on the
/// origin, mm: the corners of each finder pattern's three squares (7, 5 and 3 modules),
/// every module corner along the symbol's outer edges and along both timing patterns, and
/// the alignment pattern's corners and centre. 225 points for version 4.
pub fn qr_target_mm() -> Vec<Point2<f64>> {
    let n = MODULES;
    // In half modules, to hold the alignment pattern's centre.
    let mut half: BTreeSet<(u32, u32)> = BTreeSet::new();
    let mut corner = |i: u32, j: u32| {
        half.insert((2 * i, 2 * j));
    };
    for (fi, fj) in [(0, 0), (n - 7, 0), (0, n - 7)] {
        for (a, b) in [(0, 7), (1, 6), (2, 5)] {
            for (i, j) in [(a, a), (b, a), (b, b), (a, b)] {
                corner(fi + i, fj + j);
            }
        }
    }
    for k in 0..=n {
        corner(k, 0);
        corner(k, n);
        corner(0, k);
        corner(n, k);
    }
    for k in 8..=n - 8 {
        for edge in [6, 7] {
            corner(k, edge);
            corner(edge, k);
        }
    }
    let a = n - 9; // the alignment pattern spans modules a..a + 5
    for (i, j) in [(a, a), (a + 5, a), (a + 5, a + 5), (a, a + 5)] {
        corner(i, j);
    }
    half.insert((2 * a + 5, 2 * a + 5));
    let module = CODE_MM / f64::from(n);
    half.into_iter()
        .map(|(i, j)| {
            Point2::new(
                f64::from(i) * 0.5 * module - 0.5 * CODE_MM,
                f64::from(j) * 0.5 * module - 0.5 * CODE_MM,
            )
        })
        .collect()
}

/// A standard normal sample (Box-Muller).
pub fn gaussian(rng: &mut StdRng) -> f64 {
    let u1: f64 = rng.gen_range(f64::EPSILON..1.0);
    let u2: f64 = rng.r#gen();
    (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
}

/// Where the target at `pose` is seen, px; `None` unless every point is in front of the
/// camera and inside the image by `margin_px`.
pub fn project_all(
    camera: &Camera,
    pose: &MarkerToCamera,
    target: &[Point2<f64>],
    margin_px: f64,
) -> Option<Vec<PixelPoint>> {
    target
        .iter()
        .map(|m| {
            let p = camera.project(&pose.transform(&MarkerPoint(Point3::new(m.x, m.y, 0.0))))?;
            let inside = p.u() >= margin_px - 0.5
                && p.v() >= margin_px - 0.5
                && p.u() <= IMAGE.width() - 0.5 - margin_px
                && p.v() <= IMAGE.height() - 0.5 - margin_px;
            inside.then_some(p)
        })
        .collect()
}

/// A view of `target` at `pose` with Gaussian noise of `noise_px` per axis.
pub fn observe(
    camera: &Camera,
    pose: &MarkerToCamera,
    target: &[Point2<f64>],
    noise_px: f64,
    rng: &mut StdRng,
) -> Option<View> {
    let pixels = project_all(camera, pose, target, 2.0)?;
    let points = target
        .iter()
        .zip(pixels)
        .map(|(m, p)| {
            let (du, dv) = (noise_px * gaussian(rng), noise_px * gaussian(rng));
            Correspondence::new(m.x, m.y, p.u() + du, p.v() + dv)
        })
        .collect();
    Some(View { points })
}

/// The rotation tilting the target by `tilt` about the in-plane direction at `azimuth`,
/// after a spin of `spin` about its normal (rad).
pub fn tilted(tilt: f64, azimuth: f64, spin: f64) -> Rotation3<f64> {
    let axis = Unit::new_normalize(Vector3::new(azimuth.cos(), azimuth.sin(), 0.0));
    Rotation3::from_axis_angle(&axis, tilt) * Rotation3::from_axis_angle(&Vector3::z_axis(), spin)
}

/// The pose that puts the target's centre on the ray seen at pixel (u, v), `depth_mm` deep.
pub fn pose_at(
    camera: &Camera,
    u: f64,
    v: f64,
    depth_mm: f64,
    r: Rotation3<f64>,
) -> MarkerToCamera {
    let ray = camera
        .normalize(&PixelPoint::new(u, v))
        .expect("an invertible lens");
    MarkerToCamera::new(r, ray.at_depth(depth_mm).0.coords)
}

/// Image positions (fractions of width and height) that a good set places its views at:
/// the four corners, the four edges, the centre, and six more inside.
pub const GOOD_POSITIONS: [(f64, f64); 15] = [
    (0.12, 0.14),
    (0.88, 0.14),
    (0.88, 0.86),
    (0.12, 0.86),
    (0.5, 0.15),
    (0.88, 0.5),
    (0.5, 0.85),
    (0.12, 0.5),
    (0.5, 0.5),
    (0.3, 0.35),
    (0.7, 0.35),
    (0.7, 0.65),
    (0.3, 0.65),
    (0.42, 0.55),
    (0.6, 0.45),
];

/// What to draw a random view from.
#[derive(Debug, Clone, Copy)]
pub struct ViewSpec {
    /// Image position of the target's centre, fractions of width and height.
    pub at: (f64, f64),
    /// Random shift of that position, fraction of the image.
    pub jitter: f64,
    /// Depth range, mm.
    pub depth_mm: (f64, f64),
    /// Tilt range, rad.
    pub tilt_rad: (f64, f64),
}

impl ViewSpec {
    /// A view at `at`, 0.3-0.7 m deep, tilted 10-40°.
    pub fn good(at: (f64, f64)) -> Self {
        Self {
            at,
            jitter: 0.04,
            depth_mm: (300.0, 700.0),
            tilt_rad: (10f64.to_radians(), 40f64.to_radians()),
        }
    }

    /// A random pose that keeps every target point inside the image (retrying).
    pub fn draw(
        &self,
        camera: &Camera,
        target: &[Point2<f64>],
        rng: &mut StdRng,
    ) -> MarkerToCamera {
        for _ in 0..10_000 {
            let fu = self.at.0 + self.jitter * rng.gen_range(-1.0..=1.0);
            let fv = self.at.1 + self.jitter * rng.gen_range(-1.0..=1.0);
            let depth = rng.gen_range(self.depth_mm.0..=self.depth_mm.1);
            let tilt = rng.gen_range(self.tilt_rad.0..=self.tilt_rad.1);
            let r = tilted(
                tilt,
                rng.gen_range(0.0..2.0 * PI),
                rng.gen_range(0.0..2.0 * PI),
            );
            let pose = pose_at(camera, fu * IMAGE.width(), fv * IMAGE.height(), depth, r);
            if project_all(camera, &pose, target, 2.0).is_some() {
                return pose;
            }
        }
        panic!("no pose of {self:?} keeps the target inside the image");
    }
}

/// A synthetic set: the views and the poses that made them.
pub struct Set {
    pub views: Vec<View>,
    pub poses: Vec<MarkerToCamera>,
}

/// Views drawn from `specs` with noise `noise_px`, seeded by `seed`.
pub fn set_of(camera: &Camera, specs: &[ViewSpec], noise_px: f64, seed: u64) -> Set {
    let mut rng = StdRng::seed_from_u64(seed);
    let target = qr_target_mm();
    let poses: Vec<MarkerToCamera> = specs
        .iter()
        .map(|s| s.draw(camera, &target, &mut rng))
        .collect();
    let views = poses
        .iter()
        .map(|pose| observe(camera, pose, &target, noise_px, &mut rng).expect("inside the image"))
        .collect();
    Set { views, poses }
}

/// The reference set: 15 views of the 120 mm code at 0.3-0.7 m, tilted 10-40°,
/// spread over the image, with `noise_px` of noise.
pub fn good_set(camera: &Camera, noise_px: f64, seed: u64) -> Set {
    let specs: Vec<ViewSpec> = GOOD_POSITIONS
        .iter()
        .map(|&at| ViewSpec::good(at))
        .collect();
    set_of(camera, &specs, noise_px, seed)
}
