//! Pose from a rendered fisheye photo against the pinhole photo of the same scene:
//! the same codes at the same poses, seen once through OpenCV's fisheye model (`equidistant`)
//! and once through a distortion-free lens of the same focal length, each run through the
//! photo pipeline (`locate_markers`) with its own camera.
//!
//! The fisheye has the coefficients of the tracking camera of
//! `crates/qrpose-core/tests/fixtures/opencv_projections.json` and a longer focal length; its
//! 90° circle reaches past the frame's sides. The codes stand from on the axis to 47° off it.
//!
//! From the true corners the fisheye pose is exact (first test): the lens model is exact.
//! A fisheye bows the symbol's straight sides, so the pipeline refines a distorting
//! camera's corners through its lens (`qrpose_detect::refine::refine_corners_through`).
//! Measured (this file, clean renders; largest corner error of a code, then its position
//! and rotation error, over the five codes): pinhole 0.04-0.15 px, 0.015-0.041 mm,
//! 0.05-0.19°; fisheye 0.03-0.11 px, 0.007-0.070 mm, 0.09-0.21°. Refined with straight
//! sides, as the detector without a camera does, the fisheye corners are 0.3-2.7 px off
//! and the poses 0.6-1.6 mm and up to 5.0°.

use nalgebra::Vector3;
use qrpose_core::estimate::{ValidSolver, estimate_pose};
use qrpose_core::geometry::camera::{Camera, Distortion, Equidistant};
use qrpose_core::geometry::euler::{EulerXyz, angle_between};
use qrpose_core::geometry::frames::PixelPoint;
use qrpose_core::geometry::marker::{CornerOrder, Marker};
use qrpose_core::geometry::quad::ImageQuad;
use qrpose_detect::pipeline::{Options, Setup, locate_markers};
use qrpose_detect::refine::{refine_corners, refine_corners_through};
use qrpose_detect::{Budget, Effort, detect_within};
use qrpose_sim::render::{EcLevel, Effects, Rendered, Scene, render};
use std::time::Duration;

const WIDTH_PX: u32 = 1280;
const HEIGHT_PX: u32 = 800;
const FOCAL_PX: f64 = 420.0;
const MARKER_SIZE_MM: f64 = 50.0;

/// Each code: its centre's direction off the axis (deg, along x then y), its distance
/// (mm), and its Euler angles (deg).
const CODES: [(f64, f64, f64, [f64; 3]); 5] = [
    (0.0, 0.0, 220.0, [10.0, -15.0, 5.0]),
    (20.0, 5.0, 240.0, [-5.0, 25.0, 30.0]),
    (-30.0, -10.0, 230.0, [15.0, -30.0, -20.0]),
    (40.0, 15.0, 220.0, [0.0, 40.0, 10.0]),
    (-45.0, 20.0, 210.0, [-20.0, -35.0, 60.0]),
];

/// Pose error from exact corners allowed: mm, degrees.
const EXACT_CORNERS_TOL: (f64, f64) = (1e-6, 1e-6);
/// The pinhole photos' pose error, as measured with margin: mm, degrees.
const PINHOLE_TOL: (f64, f64) = (0.1, 0.3);
/// How much worse than the pinhole photo the fisheye photo may be: the factor on
/// the pinhole tolerance.
const FISHEYE_OVER_PINHOLE: f64 = 2.0;
/// The fisheye photos' pose error, refined through the lens, as measured with margin: mm,
/// degrees.
const FISHEYE_TOL: (f64, f64) = (0.1, 0.3);
/// Largest corner error of either photo, as measured with margin, px.
const CORNER_TOL_PX: f64 = 0.25;
/// Detection deadline: long enough that a loaded test machine does not cut the passes short.
const DETECT_DEADLINE: Duration = Duration::from_secs(60);

fn pinhole() -> Camera {
    let cx = f64::from(WIDTH_PX - 1) / 2.0;
    let cy = f64::from(HEIGHT_PX - 1) / 2.0;
    Camera::from_pixels(FOCAL_PX, FOCAL_PX, cx, cy).expect("valid camera")
}

fn fisheye() -> Camera {
    pinhole().with_distortion(Distortion::from(Equidistant {
        k1: -0.00566,
        k2: 0.04186,
        k3: -0.03869,
        k4: 0.00673,
    }))
}

fn marker() -> Marker {
    Marker::try_new(MARKER_SIZE_MM).expect("valid size")
}

fn scene(camera: Camera, i: usize) -> Scene {
    let (ax, ay, distance_mm, [a, b, g]) = CODES[i];
    let direction = Vector3::new(ax.to_radians().tan(), ay.to_radians().tan(), 1.0).normalize();
    let rotation = EulerXyz::from_degrees(a, b, g).to_rotation();
    Scene {
        payload: format!("FISH-{i}").into_bytes(),
        ec_level: EcLevel::M,
        marker: marker(),
        camera,
        width_px: WIDTH_PX,
        height_px: HEIGHT_PX,
        pose: marker().pose_centred_at(rotation, direction * distance_mm),
    }
}

/// How far a photo's result is from the truth.
#[derive(Debug, Clone, Copy)]
struct PhotoErrors {
    /// Largest distance of a found corner from its true position, px.
    corner_px: f64,
    /// Position error, mm.
    position_mm: f64,
    /// Rotation error, degrees.
    rotation_deg: f64,
}

/// Position error (mm) and rotation error (deg) of `found` against the scene's pose.
fn errors(
    scene: &Scene,
    rendered: &Rendered,
    found: &qrpose_core::estimate::PoseEstimate,
) -> (f64, f64) {
    let truth = Vector3::from(rendered.truth.position_mm);
    let position_mm = (found.centre_mm - truth).norm();
    let rotation_deg = angle_between(&found.pose.rotation(), &scene.pose.rotation()).to_degrees();
    (position_mm, rotation_deg)
}

fn options() -> Options {
    Options {
        budget: Budget::new(Effort::Balanced, Some(DETECT_DEADLINE)),
        ..Options::default()
    }
}

/// The corner and pose errors of the photo of code `i` through `camera`, run through the
/// pipeline.
fn photo_errors(camera: Camera, i: usize) -> PhotoErrors {
    let scene = scene(camera, i);
    let rendered = render(&scene, &Effects::default()).expect("renders");
    let setup = Setup {
        camera,
        sizes: marker(),
        solver: ValidSolver::default(),
    };
    let located = locate_markers(&rendered.image, &setup, &options()).expect("detector built");
    let found = located.markers.first().expect("the code is found");
    assert!(found.code.is_refined(), "code {i}: corners refined");
    let corner_px = found
        .code
        .corners_px()
        .iter()
        .zip(rendered.truth.corners_px)
        .map(|(p, [u, v])| (p.u() - u).hypot(p.v() - v))
        .fold(0.0, f64::max);
    let estimate = found.pose.as_ref().expect("a pose");
    let (position_mm, rotation_deg) = errors(&scene, &rendered, estimate);
    PhotoErrors {
        corner_px,
        position_mm,
        rotation_deg,
    }
}

fn within(errors: (f64, f64), tol: (f64, f64)) -> bool {
    errors.0 <= tol.0 && errors.1 <= tol.1
}

impl PhotoErrors {
    fn within(&self, pose_tol: (f64, f64), corner_tol_px: f64) -> bool {
        self.corner_px <= corner_tol_px && within((self.position_mm, self.rotation_deg), pose_tol)
    }
}

#[test]
fn the_true_corners_of_a_fisheye_render_give_the_exact_pose() {
    for i in 0..CODES.len() {
        let scene = scene(fisheye(), i);
        let rendered = render(&scene, &Effects::default()).expect("renders");
        let corners = rendered
            .truth
            .corners_px
            .map(|[u, v]| PixelPoint::new(u, v));
        let quad = ImageQuad::try_new(corners, CornerOrder::Qr).expect("a quad");
        let estimate =
            estimate_pose(&quad, &fisheye(), &marker(), &ValidSolver::default()).expect("a pose");
        let e = errors(&scene, &rendered, &estimate);
        assert!(within(e, EXACT_CORNERS_TOL), "code {i}: {e:?} (mm, deg)");
    }
}

#[test]
fn fisheye_and_pinhole_photos_are_posed_within_their_measured_errors() {
    for i in 0..CODES.len() {
        let pinhole = photo_errors(pinhole(), i);
        let fisheye = photo_errors(fisheye(), i);
        eprintln!("code {i}: pinhole {pinhole:?}, fisheye {fisheye:?}");
        assert!(
            pinhole.within(PINHOLE_TOL, CORNER_TOL_PX),
            "code {i}: pinhole {pinhole:?}"
        );
        assert!(
            fisheye.within(FISHEYE_TOL, CORNER_TOL_PX),
            "code {i}: fisheye {fisheye:?}"
        );
    }
}

#[test]
fn a_camera_without_distortion_keeps_the_corners_of_the_detector_without_a_camera() {
    let no_lens = pinhole().with_distortion(Distortion::NONE);
    for i in [0, 3] {
        let rendered = render(&scene(pinhole(), i), &Effects::default()).expect("renders");
        let detected = detect_within(&rendered.image, options().detector, &options().budget)
            .expect("detector built");
        let code = detected.codes.first().expect("the code is found");
        let (corners_px, n) = (code.candidate.corners_px, code.candidate.module_count);
        for camera in [pinhole(), no_lens] {
            assert_eq!(
                refine_corners_through(&rendered.image, &corners_px, n, &camera),
                refine_corners(&rendered.image, &corners_px, n),
                "code {i}"
            );
            let setup = Setup {
                camera,
                sizes: marker(),
                solver: ValidSolver::default(),
            };
            let located =
                locate_markers(&rendered.image, &setup, &options()).expect("detector built");
            let found = located.markers.first().expect("the code is found");
            assert_eq!(found.code, *code, "code {i}");
        }
    }
}

/// Pose from a rendered fisheye photo within the same accuracy as a pinhole one.
#[test]
fn fisheye_photos_are_posed_as_accurately_as_pinhole_photos_of_the_same_scene() {
    let tol = (
        FISHEYE_OVER_PINHOLE * PINHOLE_TOL.0,
        FISHEYE_OVER_PINHOLE * PINHOLE_TOL.1,
    );
    for i in 0..CODES.len() {
        let fisheye = photo_errors(fisheye(), i);
        assert!(
            within((fisheye.position_mm, fisheye.rotation_deg), tol),
            "code {i}: fisheye {fisheye:?}"
        );
    }
}
