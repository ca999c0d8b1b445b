//! Each used view's residuals, the outlier test that leaves a view out, and how much of the
//! image a view's code covers (the thresholds of `outlier_view` and `little_image_coverage`).

use crate::input::ImageSize;
use crate::lm::ViewData;
use crate::model::{Intrinsics, Pose, project};
use crate::robust::median;
use nalgebra::{Point2, Vector2, Vector6};
use qrpose_core::geometry::camera::Distortion;

/// A view whose flange correction exceeds this many standard deviations of the flange
/// noise (√ of its six squared normalised components) is an outlier: for a correct pose
/// the squared length is at most χ²(6), which exceeds 25 with probability 3·10⁻⁴.
pub const OUTLIER_FLANGE_SIGMAS: f64 = 5.0;

/// A view whose reprojection RMS exceeds this many times the median view's (and
/// [`OUTLIER_RMS_FLOOR_PX`]) is an outlier.
pub const OUTLIER_RMS_RATIO: f64 = 3.0;

/// Reprojection RMS below which no view is an outlier for its pixels, px: sub-pixel
/// corners of a sharp code are all within it.
pub const OUTLIER_RMS_FLOOR_PX: f64 = 0.5;

/// At most this fraction of the views read may be left out as outliers (a quarter): more
/// disagreement means the data, not a few views, are wrong.
pub const MAX_OUTLIER_FRACTION: f64 = 0.25;

/// A view whose code covers less than this fraction of the image (1 %: a 120 mm code
/// beyond ~1 m with a 1000 px focal length, under 96 × 96 px of a 1280 × 720 image) raises
/// `little_image_coverage`.
pub const MIN_CODE_AREA_FRACTION: f64 = 0.01;

/// RMS of residual lengths, px.
pub(super) fn rms(residuals: &[Vector2<f64>]) -> f64 {
    if residuals.is_empty() {
        return 0.0;
    }
    #[allow(clippy::cast_precision_loss)]
    let n = residuals.len() as f64;
    (residuals.iter().map(Vector2::norm_squared).sum::<f64>() / n).sqrt()
}

/// A used view's fit: RMS, px, and its flange correction in flange-noise units.
pub(super) struct UsedFit {
    pub rms_px: f64,
    pub flange_sigmas: f64,
    pub correction: Vector6<f64>,
}

pub(super) fn view_residuals(
    k: &Intrinsics,
    lens: &Distortion,
    c: &Pose,
    data: &ViewData,
) -> Vec<Vector2<f64>> {
    data.target_mm
        .iter()
        .zip(&data.pixel_px)
        .filter_map(|(m, uv)| project(k, lens, c, m).map(|q| q - uv))
        .collect()
}

/// The position in `fitted.used` of the worst outlier, if any (module constants).
pub(super) fn worst_outlier(fits: &[UsedFit]) -> Option<usize> {
    let rms: Vec<f64> = fits.iter().map(|f| f.rms_px).collect();
    let median_rms = median(&rms)?;
    let badness = |f: &UsedFit| {
        let flange = f.flange_sigmas / OUTLIER_FLANGE_SIGMAS;
        let pixels = if f.rms_px > OUTLIER_RMS_FLOOR_PX {
            f.rms_px / (OUTLIER_RMS_RATIO * median_rms)
        } else {
            0.0
        };
        flange.max(pixels)
    };
    fits.iter()
        .enumerate()
        .map(|(i, f)| (i, badness(f)))
        .filter(|&(_, b)| b > 1.0)
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

/// The fraction of the image the code's extent covers in `pose`.
pub(super) fn code_area_fraction(
    k: &Intrinsics,
    lens: &Distortion,
    pose: &Pose,
    data: &ViewData,
    image: ImageSize,
) -> f64 {
    let Some(first) = data.target_mm.first() else {
        return 0.0;
    };
    let (lo, hi) = data
        .target_mm
        .iter()
        .fold((*first, *first), |(lo, hi), m| (lo.inf(m), hi.sup(m)));
    let corners = [
        Point2::new(lo.x, lo.y),
        Point2::new(hi.x, lo.y),
        Point2::new(hi.x, hi.y),
        Point2::new(lo.x, hi.y),
    ];
    let projected: Option<Vec<Vector2<f64>>> =
        corners.iter().map(|m| project(k, lens, pose, m)).collect();
    let Some(p) = projected else {
        return 0.0;
    };
    // Shoelace.
    let area = 0.5
        * (0..4)
            .map(|i| {
                let (a, b) = (p[i], p[(i + 1) % 4]);
                a.x * b.y - b.x * a.y
            })
            .sum::<f64>()
            .abs();
    area / (image.width() * image.height())
}
