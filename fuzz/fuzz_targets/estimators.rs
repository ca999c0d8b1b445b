//! The three estimators on arbitrary finite corners, cameras and marker sizes: never a
//! panic, never a hang (every iteration is capped). The first byte chooses how the rest
//! becomes eleven numbers (four corners, px; fx = fy, cx, cy): even, each from two bytes
//! on a 1/16-px grid over 0-4096 px, where real quadrilaterals are; odd, raw f64 bit
//! patterns, which reach every magnitude. The marker size comes from the last byte.
#![no_main]

use libfuzzer_sys::fuzz_target;
use qrpose_core::estimate::{Method, ValidSolver, estimate_pose};
use qrpose_core::geometry::camera::Camera;
use qrpose_core::geometry::frames::PixelPoint;
use qrpose_core::geometry::marker::{CornerOrder, Marker};
use qrpose_core::geometry::quad::ImageQuad;

fn floats(bytes: &[u8]) -> Vec<f64> {
    let Some((&mode, rest)) = bytes.split_first() else {
        return Vec::new();
    };
    if mode % 2 == 0 {
        rest.chunks_exact(2)
            .map(|c| f64::from(u16::from_le_bytes([c[0], c[1]])) / 16.0)
            .collect()
    } else {
        rest.chunks_exact(8)
            .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
            .collect()
    }
}

fuzz_target!(|bytes: &[u8]| {
    let v = floats(bytes);
    if v.len() < 11 || v.iter().any(|x| !x.is_finite()) {
        return;
    }
    let corners = [
        PixelPoint::new(v[0], v[1]),
        PixelPoint::new(v[2], v[3]),
        PixelPoint::new(v[4], v[5]),
        PixelPoint::new(v[6], v[7]),
    ];
    let Ok(quad) = ImageQuad::try_new(corners, CornerOrder::Qr) else {
        return;
    };
    let Ok(camera) = Camera::from_pixels(v[8].abs(), v[8].abs(), v[9], v[10]) else {
        return;
    };
    let size_mm = f64::from(bytes.last().copied().unwrap_or(50)) + 1.0;
    let Ok(marker) = Marker::try_new(size_mm) else {
        return;
    };
    for method in Method::ALL {
        let solver = ValidSolver::default_for(method);
        let _ = estimate_pose(&quad, &camera, &marker, &solver);
    }
});
