//! The module count N of a symbol whose backend did not report it (stage 1 of
//! [`super::refine_corners`]): the version whose function patterns, sampled through the
//! corners, match best.

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

use super::MIN_PX_PER_MODULE;
use super::modules::{function_module_count, function_modules};
use crate::raster::GrayImage;
use crate::refine::homography::{Homography, ModulePoint};
use qrpose_core::geometry::frames::PixelPoint;

/// How well the function patterns (finders, separators, timing) under the corners match
/// an N-module symbol, in [−1, 1]: the mean signed darkness at their module centres.
/// `None` when a module cannot be sampled, or, given `to_beat`, as soon as the score can no
/// longer exceed it (each module adds at most 1): the search over versions then reads only
/// a fraction of the modules of most wrong versions.
fn function_pattern_score(
    image: &GrayImage,
    corners: &[PixelPoint; 4],
    n: usize,
    (light, dark): (f64, f64),
    to_beat: Option<f64>,
) -> Option<f64> {
    let h = Homography::from_corners(corners, n as f64)?;
    let contrast = light - dark;
    if contrast.abs() < 1.0 {
        return None;
    }
    let mid = 0.5 * (light + dark);
    let total = function_module_count(n) as f64;
    let mut score = 0.0;
    for (seen, (i, j, expected_dark)) in function_modules(n).enumerate() {
        let x = h.map(ModulePoint::new(i as f64 + 0.5, j as f64 + 0.5));
        let value = image.sample(x.u(), x.v())?;
        let darkness = ((mid - value) / (0.5 * contrast)).clamp(-1.0, 1.0);
        score += if expected_dark { darkness } else { -darkness };
        let left = total - (seen + 1) as f64;
        if to_beat.is_some_and(|best| score + left <= best * total) {
            return None;
        }
    }
    Some(score / total)
}

/// Light and dark levels inside a quad (90th and 10th percentiles of a 32 × 32 grid), for
/// the module-count search, which must not depend on N.
fn quad_levels(image: &GrayImage, corners: &[PixelPoint; 4]) -> Option<(f64, f64)> {
    let h = Homography::from_corners(corners, 1.0)?;
    let mut values = Vec::with_capacity(1024);
    for a in 0..32 {
        for b in 0..32 {
            let x = h.map(ModulePoint::new(
                (f64::from(a) + 0.5) / 32.0,
                (f64::from(b) + 0.5) / 32.0,
            ));
            if let Some(v) = image.sample(x.u(), x.v()) {
                values.push(v);
            }
        }
    }
    if values.len() < 100 {
        return None;
    }
    let mut at = |q: f64| {
        let k = ((values.len() - 1) as f64 * q) as usize;
        *values.select_nth_unstable_by(k, f64::total_cmp).1
    };
    Some((at(0.9), at(0.1)))
}

/// The module count whose function patterns fit best, among versions with at least
/// [`MIN_PX_PER_MODULE`] pixels per module.
pub(crate) fn estimate_module_count(image: &GrayImage, corners: &[PixelPoint; 4]) -> Option<usize> {
    let side_px = (0..4)
        .map(|i| (corners[i].0 - corners[(i + 1) % 4].0).norm())
        .fold(f64::INFINITY, f64::min);
    let levels = quad_levels(image, corners)?;
    let mut best: Option<(f64, usize)> = None;
    for version in 1..=40usize {
        let n = 17 + 4 * version;
        if side_px / (n as f64) < MIN_PX_PER_MODULE {
            break;
        }
        if let Some(score) = function_pattern_score(image, corners, n, levels, best.map(|b| b.0))
            && best.is_none_or(|(s, _)| score > s)
        {
            best = Some((score, n));
        }
    }
    best.filter(|(s, _)| *s > 0.3).map(|(_, n)| n)
}
