//! Reading a found-but-undecoded symbol again through its refined module grid.
//!
//! A backend that finds a symbol but cannot read it (rqrr and zxing-cpp report such
//! symbols) sampled its modules through whole-pixel corners. At about 2 px per module that
//! is a module off in places, and the Reed-Solomon code gives up. After
//! [`crate::refine::corners::refine_corners`] the module grid is known to a few hundredths of a
//! pixel, so the modules are sampled again at their centres through the refined
//! homography and handed to rqrr's decoder (format information, unmasking, Reed-Solomon,
//! segments).
//!
//! Thresholds: under a blur of σ ≈ 0.6 module an isolated dark module keeps only about a
//! third of the full contrast at its centre, so a single mid-grey threshold reads it as
//! light. The mean of the module centres around a module (a [`LOCAL_WINDOW_MODULES`]-wide
//! window) follows the blur and uneven lighting but calls the inside of a large dark area
//! light; the threshold is first their average, then the symbol-wide mid-grey alone, then
//! the local mean alone.

use crate::contain::contain;
use crate::raster::GrayImage;
use crate::raster::sharpen;
use crate::refine::homography::{Homography, ModulePoint};
use crate::search::region::{Crop, Region};
use qrpose_core::geometry::frames::PixelPoint;

/// Side of the square window of module centres whose mean is a module's threshold.
pub(crate) const LOCAL_WINDOW_MODULES: usize = 7;
/// Weights of the local mean in the thresholds tried, in order (the rest is the global
/// mid-grey).
const LOCAL_WEIGHTS: [f64; 3] = [0.5, 0.0, 1.0];

/// What a re-read recovered.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reread {
    /// The symbol's content bytes.
    pub payload: Vec<u8>,
    /// The content as UTF-8 text, if it is.
    pub text: Option<String>,
}

/// Module colours, row-major, `true` dark, for rqrr's decoder.
struct ModuleGrid {
    n: usize,
    dark: Vec<bool>,
}

impl rqrr::BitGrid for ModuleGrid {
    fn size(&self) -> usize {
        self.n
    }

    fn bit(&self, y: usize, x: usize) -> bool {
        self.dark.get(y * self.n + x).copied().unwrap_or(false)
    }
}

/// Grey values at the centres of the n × n modules under the corners (qr order, px);
/// `None` when a centre falls outside the image or the corners are degenerate.
fn module_centres(image: &GrayImage, corners_px: &[PixelPoint; 4], n: usize) -> Option<Vec<f64>> {
    let h = Homography::from_corners(corners_px, n as f64)?;
    let mut values = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let x = h.map(ModulePoint::new(i as f64 + 0.5, j as f64 + 0.5));
            values.push(image.sample(x.u(), x.v())?);
        }
    }
    Some(values)
}

/// The mean of each module's window of module centres (clipped at the symbol's edges),
/// from a summed-area table.
fn local_means(values: &[f64], n: usize) -> Vec<f64> {
    let mut sums = vec![0.0; (n + 1) * (n + 1)];
    for j in 0..n {
        for i in 0..n {
            sums[(j + 1) * (n + 1) + i + 1] =
                values[j * n + i] + sums[j * (n + 1) + i + 1] + sums[(j + 1) * (n + 1) + i]
                    - sums[j * (n + 1) + i];
        }
    }
    let half = LOCAL_WINDOW_MODULES / 2;
    let mut means = Vec::with_capacity(n * n);
    for j in 0..n {
        let (j0, j1) = (j.saturating_sub(half), (j + half + 1).min(n));
        for i in 0..n {
            let (i0, i1) = (i.saturating_sub(half), (i + half + 1).min(n));
            let sum = sums[j1 * (n + 1) + i1] - sums[j0 * (n + 1) + i1] - sums[j1 * (n + 1) + i0]
                + sums[j0 * (n + 1) + i0];
            means.push(sum / ((j1 - j0) * (i1 - i0)) as f64);
        }
    }
    means
}

/// The midpoint of the 10th and 90th percentiles of the module centres.
fn global_mid(values: &[f64]) -> Option<f64> {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let at = |q: f64| {
        sorted
            .get(((sorted.len().max(1) - 1) as f64 * q) as usize)
            .copied()
    };
    Some(0.5 * (at(0.1)? + at(0.9)?))
}

/// Module colours for thresholds that mix the local window mean (weight `local`) and the
/// symbol-wide mid-grey (weight 1 − `local`). The mix reads an isolated blurred module
/// (the local mean) without calling the inside of a large dark area light (the global
/// level).
fn threshold(values: &[f64], means: &[f64], mid: f64, local: f64) -> Vec<bool> {
    values
        .iter()
        .zip(means)
        .map(|(&v, &m)| v < local * m + (1.0 - local) * mid)
        .collect()
}

fn decode(n: usize, dark: Vec<bool>) -> Option<Reread> {
    let grid = rqrr::Grid::new(ModuleGrid { n, dark });
    let mut payload = Vec::new();
    // rqrr's decoder indexes tables by version and bit position; contain any panic on a
    // grid that is not a QR symbol, as for its detector (see `backends::rqrr`).
    let decoded = contain(|| grid.decode_to(&mut payload).is_ok()).unwrap_or(false);
    decoded.then(|| Reread {
        text: String::from_utf8(payload.clone()).ok(),
        payload,
    })
}

/// Reads the symbol of `n` modules under refined corners (qr order, px), or `None` when
/// neither threshold gives a grid that rqrr's decoder accepts (format information and
/// Reed-Solomon check included, so a wrong read is as unlikely as for any backend).
pub fn reread(image: &GrayImage, corners_px: &[PixelPoint; 4], n: usize) -> Option<Reread> {
    if !(21..=177).contains(&n) || !(n - 17).is_multiple_of(4) {
        return None;
    }
    let plain = module_centres(image, corners_px, n).and_then(|values| read_values(&values, n));
    plain.or_else(|| {
        let (patch, corners) = sharpened_patch(image, corners_px)?;
        read_values(&module_centres(&patch, &corners, n)?, n)
    })
}

/// The symbol read from its module-centre grey values, or `None` when no threshold gives
/// a grid that decodes.
fn read_values(values: &[f64], n: usize) -> Option<Reread> {
    let means = local_means(values, n);
    let mid = global_mid(values)?;
    LOCAL_WEIGHTS
        .iter()
        .find_map(|&local| decode(n, threshold(values, &means, mid, local)))
}

/// Unsharp mask of the second sampling ([`sharpened_patch`]): Gaussian σ, px.
pub(crate) const REREAD_SHARPEN_SIGMA_PX: f64 = 1.0;
/// Unsharp mask of the second sampling: amount.
pub(crate) const REREAD_SHARPEN_AMOUNT: f64 = 2.0;
/// Margin of the sharpened patch around the corners' box, px (the mask's reach).
const PATCH_MARGIN_PX: f64 = 4.0;

/// The symbol's box (widened by [`PATCH_MARGIN_PX`]) copied out and unsharp-masked, and the
/// corners in its pixels. At 1.5-2 px per module under a blur of σ ≈ 0.6-1 px an isolated
/// module keeps too little contrast at its centre for any threshold; the mask gives it back
/// (measured on the rendered multi-code frames' misses, docs/detection.md: with exact
/// corners 12 of 15 codes of 1.5-2.1 px per module read from the sharpened patch, 3 from
/// the plain image).
fn sharpened_patch(
    image: &GrayImage,
    corners_px: &[PixelPoint; 4],
) -> Option<(GrayImage, [PixelPoint; 4])> {
    let region = Region::around(corners_px, PATCH_MARGIN_PX)?;
    let crop = Crop::with_margin(image, &region, 0.0)?;
    let patch = sharpen(
        crop.image.as_ref()?,
        REREAD_SHARPEN_SIGMA_PX,
        REREAD_SHARPEN_AMOUNT,
    )?;
    Some((patch, corners_px.map(|p| crop.to_crop(&p))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mixed_threshold_reads_an_isolated_blurred_module_and_a_dark_block() {
        // A light field with one weakly dark module (a third of the contrast, as blur
        // leaves it) and an 8 × 8 dark block.
        let n = 21;
        let mut values = vec![200.0; n * n];
        values[10 * n + 10] = 150.0;
        for j in 0..8 {
            for i in 0..8 {
                values[j * n + i] = 50.0;
            }
        }
        let means = local_means(&values, n);
        let mid = global_mid(&values).expect("levels");
        let mixed = threshold(&values, &means, mid, 0.5);
        let global = threshold(&values, &means, mid, 0.0);
        let local = threshold(&values, &means, mid, 1.0);
        assert!(mixed[10 * n + 10], "the mix reads the weak module as dark");
        assert!(!global[10 * n + 10], "the global mid-grey does not");
        assert!(
            mixed[2 * n + 2],
            "the mix reads the inside of the block as dark"
        );
        assert!(!local[2 * n + 2], "the local mean alone does not");
        assert!(!mixed[15 * n + 15]);
    }

    #[test]
    fn refuses_a_module_count_that_is_no_qr_version() {
        let image = GrayImage::new(64, 64, vec![255; 64 * 64]).expect("image");
        let corners = [
            PixelPoint::new(5.0, 5.0),
            PixelPoint::new(55.0, 5.0),
            PixelPoint::new(55.0, 55.0),
            PixelPoint::new(5.0, 55.0),
        ];
        assert_eq!(reread(&image, &corners, 22), None);
        assert_eq!(
            reread(&image, &corners, 21),
            None,
            "a blank square is no symbol"
        );
    }
}
