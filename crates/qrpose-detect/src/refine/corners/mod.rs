//! Sub-pixel corners of a QR symbol, whatever backend found it.
//!
//! Backends return whole-pixel corners (rqrr, rxing, zxing-cpp). Starting from them:
//!
//! 1. **Module count** N: from the backend when it knows the version (every backend's own
//!    reads do), otherwise the N whose function patterns (finders, separators, timing)
//!    match best (module `count`, [`estimate_module_count`]).
//! 2. **Module map**: the function patterns (three finders, separators, timing) are known;
//!    the other modules are read at their centres through the current homography
//!    (module `modules`).
//! 3. **Edge observations**: across every module boundary on the symbol's outer sides and
//!    on the four sides of each finder pattern, a 1-D profile is fitted with the blurred
//!    module pattern it must show ([`super::profile`]); each fit puts one image point on
//!    a known line of the module grid, u = 0, 7, N − 7, N or v = the same (module
//!    `edges`).
//! 4. **Homography**: the module-to-image homography that puts every observed point on its
//!    line, by iteratively reweighted linear least squares (Sturm's reweighting turns the
//!    algebraic error into module units; a Huber weight tames misread data modules;
//!    module `fit`).
//!    Steps 2-4 run once as a scan (every other site, each edge searched for), then as
//!    final passes (every site) until one moves no corner by more than [`SETTLED_PX`], at
//!    most [`MAX_FINAL_PASSES`] of them.
//! 5. **Corners** are the homography at (0, 0), (N, 0), (N, N), (0, N) (qr order).
//!    **Finder corners**: each finder's four sides are fitted as image lines from their
//!    own observations only and intersected (twelve points, independent of the data area;
//!    module `fit`).
//!
//! Refinement never makes things silently worse: with too few observations, a poor
//! finder-pattern match, or corners that moved further than [`MAX_MOVE_MODULES`] from the
//! backend's, the backend corners are kept and [`Refinement::status`] says why.
//!
//! **Distorting lenses** ([`refine_corners_through`]): with the camera's lens, the
//! homography maps modules to ideal (undistorted) pixels, every sample of the photo is
//! taken through the distortion, and the fits of stages 4 and 5 run on edge points in ideal
//! pixels, where the grid's lines are straight again (module `lens`). The corners are
//! reported in the photo's pixels either way.
//!
//! This module runs the passes ([`refine_corners`], [`refine_corners_through`]) and owns
//! the result types.

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

mod count;
mod edges;
mod fit;
mod lens;
mod modules;

pub(crate) use count::estimate_module_count;
pub(crate) use lens::Lens;
pub(crate) use modules::{ModuleMap, is_function_module, module_map, reference_levels};

use crate::raster::GrayImage;
use crate::refine::homography::ModulePoint;
use edges::observe;
use fit::{finder_corners, fit_homography};
use lens::Grid;
use qrpose_core::geometry::camera::Camera;
use qrpose_core::geometry::frames::PixelPoint;

/// Most final refinement passes. The first pass scans (every other site, each edge searched
/// over ±[`super::profile::MAX_SHIFT_MODULES`]) to bring the homography close; final passes
/// (every site, each fit from the current edge) follow, another while the last one still
/// moved a corner by more than [`SETTLED_PX`]. Each final pass leaves about a tenth of the
/// error it started from, so a start a pixel or more off (corners read at half scale, say)
/// gets a second one. A pass that moves the corners further than the pass before (the
/// passes do not converge, as on some hard photos) is dropped and the one before kept.
pub(crate) const MAX_FINAL_PASSES: usize = 3;
/// A final pass that moved no corner further than this has settled, px.
pub(crate) const SETTLED_PX: f64 = 0.5;
/// Refined corners further than this from the backend's (in modules) mean a failure.
pub(crate) const MAX_MOVE_MODULES: f64 = 2.0;
/// Fewest pixels per module the refinement works with.
pub(crate) const MIN_PX_PER_MODULE: f64 = 1.2;

/// How refinement ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RefineStatus {
    /// Corners refined from the image.
    Refined,
    /// The backend's corners were kept: too few edges could be measured.
    TooFewEdges,
    /// The backend's corners were kept: the refined ones moved too far (the symbol is
    /// probably misgrouped or misread).
    MovedTooFar,
    /// The backend's corners were kept: the symbol is too small to refine.
    TooSmall,
    /// The backend's corners were kept: the module count could not be determined.
    UnknownModuleCount,
}

impl RefineStatus {
    /// The snake_case name used on the wire.
    pub fn as_str(self) -> &'static str {
        match self {
            RefineStatus::Refined => "refined",
            RefineStatus::TooFewEdges => "too_few_edges",
            RefineStatus::MovedTooFar => "moved_too_far",
            RefineStatus::TooSmall => "too_small",
            RefineStatus::UnknownModuleCount => "unknown_module_count",
        }
    }
}

/// Refined corners of one symbol.
#[derive(Debug, Clone, PartialEq)]
pub struct Refinement {
    /// Corners in qr order (TL, TR, BR, BL), px: refined, or the backend's when
    /// `status` is not [`RefineStatus::Refined`].
    pub corners_px: [PixelPoint; 4],
    /// The twelve outer corners of the three finder patterns, px (see
    /// [`super::finder_model_points`] for their order), when every finder side was
    /// measured.
    pub finder_corners_px: Option<[PixelPoint; 12]>,
    /// The module count N (21 for version 1, 4 more per version).
    pub module_count: Option<usize>,
    /// How refinement ended.
    pub status: RefineStatus,
    /// Edge observations used in the final homography.
    pub observations: usize,
}

/// The largest distance between corresponding corners of two quads, px.
fn largest_move_px(a: &[PixelPoint; 4], b: &[PixelPoint; 4]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p.0 - q.0).norm())
        .fold(0.0, f64::max)
}

/// Refines a backend's corners (qr order). `module_count` is N when the backend knows it.
/// The symbol's sides are taken to be straight in the photo: a camera without distortion
/// (for one that distorts, [`refine_corners_through`]).
pub fn refine_corners(
    image: &GrayImage,
    backend_corners: &[PixelPoint; 4],
    module_count: Option<usize>,
) -> Refinement {
    refine(image, backend_corners, module_count, None)
}

/// Refines a backend's corners (qr order, px) in a photo taken by `camera`, whose lens
/// distortion bows the symbol's straight lines. Without distortion this is
/// [`refine_corners`], with the same result. The backend's corners are kept (status
/// [`RefineStatus::TooFewEdges`]) also when one of them cannot be undistorted.
pub fn refine_corners_through(
    image: &GrayImage,
    backend_corners: &[PixelPoint; 4],
    module_count: Option<usize>,
    camera: &Camera,
) -> Refinement {
    refine(image, backend_corners, module_count, Lens::of(camera))
}

/// The passes of [`refine_corners`], through `lens` when there is one.
fn refine(
    image: &GrayImage,
    backend_corners: &[PixelPoint; 4],
    module_count: Option<usize>,
    lens: Option<Lens>,
) -> Refinement {
    let unrefined = |status, module_count| Refinement {
        corners_px: *backend_corners,
        finder_corners_px: None,
        module_count,
        status,
        observations: 0,
    };
    let Some(n) = module_count.or_else(|| estimate_module_count(image, backend_corners)) else {
        return unrefined(RefineStatus::UnknownModuleCount, None);
    };
    let Some(mut grid) = Grid::from_corners(backend_corners, n as f64, lens) else {
        return unrefined(RefineStatus::TooFewEdges, Some(n));
    };
    let (ppm_u, ppm_v) = grid.px_per_module(ModulePoint::new(n as f64 / 2.0, n as f64 / 2.0));
    if ppm_u.min(ppm_v) < MIN_PX_PER_MODULE {
        return unrefined(RefineStatus::TooSmall, Some(n));
    }
    let mut obs = Vec::new();
    let mut corners_px = grid.corners(n as f64);
    let mut last_step_px = f64::INFINITY;
    for pass in 0..=MAX_FINAL_PASSES {
        let scan = pass == 0;
        let Some((light, dark)) = reference_levels(image, |m| grid.map(m), n) else {
            return unrefined(RefineStatus::TooFewEdges, Some(n));
        };
        let map = module_map(image, |m| grid.map(m), n, light, dark);
        let pass_obs = observe(image, &grid, &map, scan);
        // The observations are in ideal pixels, where the grid's lines are straight.
        let Some(next_h) = fit_homography(&pass_obs, grid.homography()) else {
            return unrefined(RefineStatus::TooFewEdges, Some(n));
        };
        let next_grid = grid.with_homography(next_h);
        let next = next_grid.corners(n as f64);
        let step_px = largest_move_px(&next, &corners_px);
        if pass > 1 && step_px >= last_step_px {
            // Not converging (a hard image): keep the pass before.
            break;
        }
        (grid, obs, corners_px, last_step_px) = (next_grid, pass_obs, next, step_px);
        if !scan && step_px <= SETTLED_PX {
            break;
        }
    }
    let module_px = (ppm_u + ppm_v) / 2.0;
    let moved = largest_move_px(&corners_px, backend_corners);
    if moved.is_nan() || moved > MAX_MOVE_MODULES * module_px.max(1.5) {
        return unrefined(RefineStatus::MovedTooFar, Some(n));
    }
    Refinement {
        corners_px,
        // The finder sides are straight lines in ideal pixels; their corners go back
        // into the photo.
        finder_corners_px: finder_corners(&obs).map(|c| c.map(|p| grid.photo_from_ideal(p))),
        module_count: Some(n),
        status: RefineStatus::Refined,
        observations: obs.len(),
    }
}
