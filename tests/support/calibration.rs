//! Rendered calibration photos with a known camera, for the tests of `POST /v1/calibrate`
//! and `qrpose calibrate`: eight views of one printed 100 mm code (version 3) seen by a
//! 640 × 480 camera with an off-centre principal point and barrel distortion, from 0.3 to
//! 0.45 m, tilted by 20-35° about different axes, across the frame; blur σ 0.7 px, noise,
//! JPEG quality 92.

use nalgebra::{Rotation3, Unit, Vector3};
use qrpose::geometry::camera::{Camera, Distortion, DistortionModel};
use qrpose::geometry::frames::PixelPoint;
use qrpose::geometry::marker::Marker;
use qrpose_sim::render::{EcLevel, Effects, Encoding, Scene, render};
use std::path::{Path, PathBuf};

/// Width and height of the photos, px.
pub const SIZE_PX: (u32, u32) = (640, 480);
/// The printed code's side, mm.
pub const CODE_MM: f64 = 100.0;
/// The lens: k1 k2 p1 p2 k3.
pub const LENS: [f64; 5] = [-0.2, 0.05, 0.0005, -0.0003, 0.0];

/// The camera that takes the photos.
pub fn camera() -> Camera {
    let lens = Distortion::from_coefficients(DistortionModel::PlumbBob, &LENS).expect("a lens");
    Camera::from_pixels(560.0, 563.0, 328.0, 236.0)
        .expect("a camera")
        .with_distortion(lens)
}

/// One view: image position (fractions of width and height), depth mm, tilt deg, tilt axis
/// azimuth deg, spin about the code's normal deg.
type ViewSpec = ((f64, f64), f64, f64, f64, f64);

/// The views.
const VIEWS: [ViewSpec; 8] = [
    ((0.27, 0.3), 330.0, 30.0, 40.0, 10.0),
    ((0.73, 0.3), 350.0, 25.0, 130.0, -20.0),
    ((0.73, 0.7), 340.0, 35.0, 220.0, 95.0),
    ((0.27, 0.7), 360.0, 30.0, 310.0, 180.0),
    ((0.5, 0.5), 420.0, 20.0, 0.0, 45.0),
    ((0.5, 0.3), 380.0, 30.0, 90.0, -60.0),
    ((0.3, 0.5), 400.0, 25.0, 180.0, 150.0),
    ((0.7, 0.5), 450.0, 35.0, 270.0, -120.0),
];

/// [`photos`] written into `dir` as `view_00.jpg`, `view_01.jpg`, …, their paths in order
/// (for the tests that hand files to the CLI or to a browser).
#[allow(dead_code)] // tests/api sends the bytes, not files
pub fn photo_files(dir: &Path) -> Vec<PathBuf> {
    photos()
        .iter()
        .enumerate()
        .map(|(k, jpeg)| {
            let path = dir.join(format!("view_{k:02}.jpg"));
            std::fs::write(&path, jpeg).expect("writes a photo");
            path
        })
        .collect()
}

/// The photos as JPEG files, in [`VIEWS`] order.
pub fn photos() -> Vec<Vec<u8>> {
    let camera = camera();
    let marker = Marker::try_new(CODE_MM).expect("a size");
    VIEWS
        .iter()
        .enumerate()
        .map(
            |(k, &((fu, fv), depth_mm, tilt_deg, azimuth_deg, spin_deg))| {
                let az = azimuth_deg.to_radians();
                let axis = Unit::new_normalize(Vector3::new(az.cos(), az.sin(), 0.0));
                let r = Rotation3::from_axis_angle(&axis, tilt_deg.to_radians())
                    * Rotation3::from_axis_angle(&Vector3::z_axis(), spin_deg.to_radians());
                let pixel = PixelPoint::new(fu * f64::from(SIZE_PX.0), fv * f64::from(SIZE_PX.1));
                let ray = camera.normalize(&pixel).expect("an invertible lens");
                let scene = Scene {
                    payload: b"https://example.com/cal/100mm".to_vec(),
                    ec_level: EcLevel::M,
                    marker,
                    camera,
                    width_px: SIZE_PX.0,
                    height_px: SIZE_PX.1,
                    pose: marker.pose_centred_at(r, ray.at_depth(depth_mm).0.coords),
                };
                let effects = Effects {
                    supersample: 4,
                    blur_px: 0.7,
                    noise: 2.0,
                    encoding: Encoding::Jpeg(92),
                    seed: k as u64,
                    ..Effects::default()
                };
                render(&scene, &effects).expect("the view renders").encoded
            },
        )
        .collect()
}
