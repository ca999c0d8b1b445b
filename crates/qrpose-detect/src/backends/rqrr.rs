//! The rqrr backend (pure Rust, quirc's algorithm).
//!
//! Two upstream traps are handled here:
//! - `PreparedImage::detect_grids` panics on some real photos (reported upstream,
//!   <https://github.com/WanzenBug/rqrr/issues/54>); the whole call runs inside
//!   [`crate::contain::contain`] and a panic counts as "nothing found".
//! - `Grid::bounds` maps module coordinates (0, 0), (N + 1, 0), (N + 1, N + 1), (0, N + 1):
//!   the top-right, bottom-right and bottom-left corners lie one module too far out. The
//!   homography through the four bounds is evaluated at N instead, and the result rounded
//!   to whole pixels anyway; [`crate::refine::corners`] refines it.

use super::{Backend, Candidate, Detector};
use crate::contain::contain;
use crate::raster::GrayImage;
use crate::refine::homography::Homography;
use qrpose_core::geometry::frames::PixelPoint;
use strength_reduce::StrengthReducedUsize;

/// rqrr behind the [`Detector`] interface.
#[derive(Debug, Clone, Copy, Default)]
pub struct RqrrDetector;

/// Corners in qr order from rqrr's bounds of a grid of `n` modules, moved one module in.
pub(crate) fn corners_from_rqrr_bounds(
    bounds: &[PixelPoint; 4],
    n: usize,
) -> Option<[PixelPoint; 4]> {
    let n = n as f64;
    Some(Homography::from_corners(bounds, n + 1.0)?.corners(n))
}

/// Which pixels of `image` are dark by quirc's adaptive threshold, bit for bit as rqrr's
/// `PreparedImage::prepare` decides (row-major): a running mean over `s` = width / 8 pixels
/// along each row, both ways, snaking from row to row, and a pixel is dark below 95 % of
/// the mean of the two. rqrr divides by `s` twice per pixel and by 200·s once more; here
/// the divisions by those image-wide constants are multiplications (`strength_reduce`,
/// exact): rqrr's region reads of the development photos took 11 % less time
/// (docs/measurements/detection.md). The threshold is still about half of rqrr's time on a
/// crop: each running mean is one chain of dependent steps through the whole image.
fn dark_pixels(image: &GrayImage) -> Vec<bool> {
    let (w, h) = (image.width(), image.height());
    if w == 0 || h == 0 {
        return Vec::new();
    }
    let s = (w / 8).max(1);
    let by_s = StrengthReducedUsize::new(s);
    let by_200s = StrengthReducedUsize::new(200 * s);
    let mut row_average = vec![0usize; w];
    let (mut avg_v, mut avg_u) = (0usize, 0usize);
    let mut dark = vec![false; w * h];
    for (y, (row, out)) in image
        .pixels()
        .chunks_exact(w)
        .zip(dark.chunks_exact_mut(w))
        .enumerate()
    {
        row_average.fill(0);
        for x in 0..w {
            let (v, u) = if y % 2 == 0 {
                (w - 1 - x, x)
            } else {
                (x, w - 1 - x)
            };
            avg_v = avg_v * (s - 1) / by_s + usize::from(row[v]);
            avg_u = avg_u * (s - 1) / by_s + usize::from(row[u]);
            row_average[v] += avg_v;
            row_average[u] += avg_u;
        }
        for ((d, &p), &mean) in out.iter_mut().zip(row).zip(&row_average) {
            *d = usize::from(p) < mean * (100 - 5) / by_200s;
        }
    }
    dark
}

fn detect_unguarded(image: &GrayImage) -> Vec<Candidate> {
    let (w, h) = (image.width(), image.height());
    let dark = dark_pixels(image);
    let mut prepared =
        rqrr::PreparedImage::prepare_from_bitmap(w, h, |x, y| dark.get(y * w + x) == Some(&true));
    let grids = prepared.detect_grids();
    let mut out = Vec::new();
    for grid in grids {
        let n = rqrr::BitGrid::size(&grid.grid);
        let bounds = grid
            .bounds
            .map(|p| PixelPoint::new(f64::from(p.x), f64::from(p.y)));
        let Some(corners_px) = corners_from_rqrr_bounds(&bounds, n) else {
            continue;
        };
        let mut bytes = Vec::new();
        let payload = grid.decode_to(&mut bytes).ok().map(|_| bytes);
        let text = payload
            .as_ref()
            .and_then(|b| String::from_utf8(b.clone()).ok());
        out.push(Candidate {
            corners_px,
            payload,
            text,
            module_count: Some(n),
            backend: Backend::Rqrr,
        });
    }
    out
}

impl Detector for RqrrDetector {
    fn backend(&self) -> Backend {
        Backend::Rqrr
    }

    fn detect(&self, image: &GrayImage) -> Vec<Candidate> {
        contain(|| detect_unguarded(image)).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic grey image with structure at several scales and noise.
    fn textured(w: usize, h: usize, seed: u64) -> GrayImage {
        let mut state = seed;
        let pixels = (0..w * h)
            .map(|i| {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                let (x, y) = (i % w, i / w);
                let pattern = if (x / 7 + y / 5) % 2 == 0 { 60 } else { 190 };
                let noise = (state >> 58) as usize; // 0..64
                u8::try_from((pattern + noise + x / 3) % 256).unwrap_or(0)
            })
            .collect();
        GrayImage::new(w, h, pixels).expect("a size")
    }

    /// The threshold done here marks exactly the pixels rqrr's own preparation marks, on
    /// images narrower than 8 px (s = 1) up to wide ones, odd and even heights.
    #[test]
    fn the_threshold_matches_rqrrs_preparation_pixel_for_pixel() {
        for (i, &(w, h)) in [(1, 1), (5, 3), (8, 9), (63, 40), (200, 121), (641, 480)]
            .iter()
            .enumerate()
        {
            let image = textured(w, h, i as u64 + 1);
            let theirs = rqrr::PreparedImage::prepare_from_greyscale(w, h, |x, y| image.get(x, y));
            let dark = dark_pixels(&image);
            let ours = rqrr::PreparedImage::prepare_from_bitmap(w, h, |x, y| dark[y * w + x]);
            for y in 0..h {
                for x in 0..w {
                    assert_eq!(
                        ours.get_pixel_at(x, y),
                        theirs.get_pixel_at(x, y),
                        "{w} x {h} at ({x}, {y})"
                    );
                }
            }
        }
    }
}
