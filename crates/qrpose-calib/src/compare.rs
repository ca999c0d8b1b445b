//! Comparing two cameras over an image, in pixels: how far apart their distortion fields
//! are ([`distortion_field_difference_px`]), and how far apart they project the same rays
//! ([`projection_difference_px`]).
//!
//! A camera's distortion field is the displacement d(p) = p − ideal(p) of each pixel p from
//! where a distortion-free camera with the same intrinsics would see the same ray:
//! ideal(p) = K·D⁻¹(K⁻¹·p). The difference of two cameras' fields at p is
//! ‖d_a(p) − d_b(p)‖; each camera uses its own K, so a focal length error shows only through
//! its effect on the distortion, not as a scale of the whole image. The measure reported is
//! a quantile of that difference over a grid of pixels on the image's inner part (the tests
//! and `scripts/calibration_compare.py` use the 95th percentile over the inner 90 %).
//!
//! The projection difference at p is ‖π_b(ray_a(p)) − p‖: the ray that camera a sees at p,
//! projected by camera b. It includes the intrinsics' errors, and unlike the field
//! difference it stays meaningful for a fisheye, whose displacement field runs to hundreds
//! of pixels near the rim (tan θ against θ), where a 0.1 % focal error moves it by pixels.

use crate::input::ImageSize;
use nalgebra::Vector2;
use qrpose_core::geometry::camera::Camera;
use qrpose_core::geometry::frames::PixelPoint;

/// Grid points along the image's longer side (the shorter side in proportion).
const SAMPLES_LONG_SIDE: u32 = 96;

/// d(p) of the module doc, px; `None` where the camera's lens cannot be inverted.
fn displacement_px(camera: &Camera, p: &PixelPoint) -> Option<Vector2<f64>> {
    let ideal = camera.ideal_from_normalized(&camera.normalize(p).ok()?);
    Some(p.0 - ideal.0)
}

/// The `quantile` (in [0, 1]) of `difference` over a grid on the centred `inner` fraction of
/// the image (0.9: a 5 % margin on each side), px; `None` when `difference` is at any grid
/// pixel.
fn quantile_over_grid(
    image: ImageSize,
    inner: f64,
    quantile: f64,
    difference: impl Fn(&PixelPoint) -> Option<f64>,
) -> Option<f64> {
    let (w, h) = (image.width(), image.height());
    let long = w.max(h);
    let steps = |side: f64| -> u32 {
        let n = f64::from(SAMPLES_LONG_SIDE) * side / long;
        // Between 2 and SAMPLES_LONG_SIDE: the conversion is exact.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let n = n.round().clamp(2.0, f64::from(SAMPLES_LONG_SIDE)) as u32;
        n
    };
    let (nu, nv) = (steps(w), steps(h));
    let margin = 0.5 * (1.0 - inner);
    let at = |i: u32, n: u32, size: f64| {
        let f = margin + inner * f64::from(i) / f64::from(n - 1);
        f * size - 0.5
    };
    let mut differences = Vec::with_capacity((nu * nv) as usize);
    for j in 0..nv {
        for i in 0..nu {
            differences.push(difference(&PixelPoint::new(at(i, nu, w), at(j, nv, h)))?);
        }
    }
    differences.sort_by(f64::total_cmp);
    let last = differences.len().checked_sub(1)?;
    let rank = quantile.clamp(0.0, 1.0) * last as f64;
    // rank is in [0, last]: the conversion is exact after rounding.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let index = rank.round() as usize;
    differences.get(index).copied()
}

/// The `quantile` (in [0, 1]) of ‖d_a(p) − d_b(p)‖ (module doc) over a grid on the centred
/// `inner` fraction of the image (0.9: a 5 % margin on each side), px. `None` where either
/// lens cannot be inverted at a grid pixel (it folds over inside the image).
#[must_use]
pub fn distortion_field_difference_px(
    a: &Camera,
    b: &Camera,
    image: ImageSize,
    inner: f64,
    quantile: f64,
) -> Option<f64> {
    quantile_over_grid(image, inner, quantile, |p| {
        Some((displacement_px(a, p)? - displacement_px(b, p)?).norm())
    })
}

/// The `quantile` (in [0, 1]) of ‖π_b(ray_a(p)) − p‖ (module doc) over a grid on the centred
/// `inner` fraction of the image, px. `None` where camera a cannot be inverted at a grid
/// pixel or camera b cannot project its ray.
#[must_use]
pub fn projection_difference_px(
    a: &Camera,
    b: &Camera,
    image: ImageSize,
    inner: f64,
    quantile: f64,
) -> Option<f64> {
    quantile_over_grid(image, inner, quantile, |p| {
        let ray = a.normalize(p).ok()?;
        Some((b.pixel_from_normalized(&ray).0 - p.0).norm())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use qrpose_core::geometry::camera::{Distortion, PlumbBob};

    #[test]
    fn a_lens_differs_from_itself_by_nothing_and_from_a_pinhole_by_its_displacement() {
        let image = ImageSize::new(1280, 720);
        let pinhole = Camera::from_pixels(1000.0, 1000.0, 640.0, 360.0).expect("valid");
        let barrel = pinhole.with_distortion(Distortion::from(PlumbBob {
            k1: -0.1,
            ..PlumbBob::NONE
        }));
        let same = distortion_field_difference_px(&barrel, &barrel, image, 0.9, 0.95);
        assert_eq!(same, Some(0.0));
        let worst =
            distortion_field_difference_px(&barrel, &pinhole, image, 0.9, 1.0).expect("invertible");
        // The inner 90 % reaches (-576.5, -324.5) px from the centre, 0.6616 normalised; the
        // ideal radius r there solves r·(1 − 0.1·r²) = 0.6616, r = 0.6951: 33.6 px further.
        assert!((worst - 33.59).abs() < 0.01, "{worst} px");
        // The pinhole's ray at that corner, r = 0.6616, the barrel lens sees 0.1·r³ nearer
        // the centre: 28.95 px.
        let moved =
            projection_difference_px(&pinhole, &barrel, image, 0.9, 1.0).expect("invertible");
        assert!((moved - 28.95).abs() < 0.01, "{moved} px");
        // Its own rays come back to their pixels, to the undistortion's rounding.
        let own = projection_difference_px(&barrel, &barrel, image, 0.9, 1.0).expect("invertible");
        assert!(own < 1e-9, "{own} px");
    }
}
