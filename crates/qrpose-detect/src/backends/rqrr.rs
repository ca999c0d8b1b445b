//! The rqrr backend (pure Rust, quirc's algorithm).
//!
//! Two upstream traps are handled here:
//! - `PreparedImage::detect_grids` panics on some real photos (upstream rqrr issue #54,
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

fn detect_unguarded(image: &GrayImage) -> Vec<Candidate> {
    let mut prepared =
        rqrr::PreparedImage::prepare_from_greyscale(image.width(), image.height(), |x, y| {
            image.get(x, y)
        });
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
