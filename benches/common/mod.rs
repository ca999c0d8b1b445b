//! The speed benchmark's frame, shared by `benches/detect.rs` and `examples/detect_speed.rs`:
//! one 50 mm code at 500 mm, tilted (20°, −15°, 30°), blur 0.8 px, noise 2, uneven lighting,
//! 30 clutter shapes, JPEG 85. About 4 px per module at f = 1000 px.

use nalgebra::Vector3;
use qrpose::geometry::{camera::Camera, euler::EulerXyz, marker::Marker};
use qrpose_sim::render::{EcLevel, Effects, Encoding, Scene, render};

/// The frames measured: name, width px, height px, focal length px.
pub const FRAMES: [(&str, u32, u32, f64); 2] = [
    ("1280x720", 1280, 720, 1000.0),
    ("1920x1080", 1920, 1080, 1400.0),
];

/// The JPEG bytes of the frame; empty if rendering failed (the caller reports it).
pub fn frame(width_px: u32, height_px: u32, f_px: f64) -> Vec<u8> {
    let Ok(marker) = Marker::try_new(50.0) else {
        return Vec::new();
    };
    let Ok(camera) = Camera::from_pixels(
        f_px,
        f_px,
        f64::from(width_px) / 2.0 - 0.5,
        f64::from(height_px) / 2.0 - 0.5,
    ) else {
        return Vec::new();
    };
    let r = EulerXyz::from_degrees(20.0, -15.0, 30.0).to_rotation();
    let centre = Vector3::new(40.0, -20.0, 500.0);
    let scene = Scene {
        payload: b"SKU-0042-warehouse-bin-17".to_vec(),
        ec_level: EcLevel::M,
        marker,
        camera,
        width_px,
        height_px,
        pose: marker.pose_centred_at(r, centre),
    };
    let effects = Effects {
        blur_px: 0.8,
        noise: 2.0,
        lighting: 0.3,
        clutter: 30,
        encoding: Encoding::Jpeg(85),
        seed: 3,
        ..Effects::default()
    };
    render(&scene, &effects)
        .map(|r| r.encoded)
        .unwrap_or_default()
}
