//! A decoded symbol as a calibration target: many points of known position on the printed
//! code, each measured in the photo to a fraction of a pixel.
//!
//! [`calibration_points`] starts from a refined [`DetectedCode`] (its sub-pixel corners and
//! module count N, from which the version and so every function pattern is known) and:
//!
//! 1. **Grid.** Takes the module-to-image homography through the refined corners and reads
//!    the module map through it (function patterns known, data modules read at their
//!    centres; `refine::corners`).
//! 2. **Edges, anchored pass.** Measures the symbol's outline and the edges between finder
//!    and timing modules (module edges are the boundaries between two modules of different
//!    colour, on the lines u = c and v = c), each by the 1-D profile fit of
//!    `refine::profile`, searching ± three quarters of a module (module `edges`): the
//!    edges whose place does not hang on data modules read through a grid that may be
//!    more than half a module off.
//! 3. **Warp.** Fits a cubic warp of module coordinates that puts the measured edges on
//!    their lines (module `warp`): the homography and the warp together follow the bend of
//!    an unknown lens over the symbol.
//! 4. **Edges, scanning pass.** Reads the module map through the warped grid, measures
//!    every other row's edges, searching as before, and fits the warp again to them.
//! 5. **Edges, final pass.** Reads the module map again and measures every edge through the
//!    warped grid, starting each fit at its line.
//! 6. **Points** (module `points`): every module corner (i, j) where the lines u = i and
//!    v = j have at least two measured edges each within two modules: the crossing of the
//!    two local line fits. Among them the twelve outer corners of the three finder patterns
//!    (the 7 × 7 squares), the twelve corners of their inner light squares (5 × 5) and the
//!    twelve of their dark cores (3 × 3); the module corners along the symbol's outer
//!    sides, along the timing patterns, and through the data area. Each alignment pattern
//!    (the positions of the symbol's version, ISO/IEC 18004 Annex E) contributes its centre:
//!    the crossing of the diagonals of the square around its centre module, whose four
//!    corners are then not reported on their own.
//!
//! Each point carries its marker-frame position in mm (docs/conventions.md, Marker frame:
//! the symbol's top-left corner P3 = (−l, 0, 0), u along +x, v along +y, l the printed side
//! without the quiet zone). No point depends on a camera model: the lines are fitted over
//! four modules at most, through a warp fitted to the photo itself, so that a calibration
//! can use them to find the lens.

mod edges;
mod points;
mod warp;

use crate::DetectedCode;
use crate::raster::{GrayImage, sharpen};
use crate::refine::corners::{module_map, reference_levels};
use crate::refine::finders::marker_point_of_module;
use crate::refine::homography::{Homography, ModulePoint};
use crate::search::region::{Crop, Region};
use edges::{Pass, measure_edges};
use points::{GridPoint, alignment_centre, module_corners};
use qrpose_core::geometry::frames::{MarkerPoint, PixelPoint};
use qrpose_core::geometry::marker::Marker;
use std::collections::HashMap;
use warp::{Warp, WarpedGrid};

/// Fewest pixels per module across an edge that is measured for calibration points: below
/// it the blur of a neighbouring module row reaches the profile.
pub const MIN_TARGET_PX_PER_MODULE: f64 = edges::MIN_PX_PER_MODULE;

/// What a calibration point is on the symbol.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TargetPointKind {
    /// A corner of a finder pattern's outer 7 × 7 dark square.
    FinderOuter,
    /// A corner of a finder pattern's 5 × 5 light square (the inner side of its dark ring).
    FinderInner,
    /// A corner of a finder pattern's 3 × 3 dark core.
    FinderCore,
    /// The centre of an alignment pattern.
    AlignmentCentre,
    /// Any other module corner: along the outer sides, the timing patterns, the data area.
    ModuleCorner,
}

impl TargetPointKind {
    /// Every kind, in the order [`calibration_points`] lists them.
    pub const ALL: [Self; 5] = [
        Self::FinderOuter,
        Self::FinderInner,
        Self::FinderCore,
        Self::AlignmentCentre,
        Self::ModuleCorner,
    ];

    /// The kind's stable snake_case name.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::FinderOuter => "finder_outer",
            Self::FinderInner => "finder_inner",
            Self::FinderCore => "finder_core",
            Self::AlignmentCentre => "alignment_centre",
            Self::ModuleCorner => "module_corner",
        }
    }
}

/// One point of the printed symbol and where the photo shows it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetPoint {
    /// What it is.
    pub kind: TargetPointKind,
    /// Where it lies on the symbol, modules (right and down from its top-left corner).
    pub module: ModulePoint,
    /// Where it lies on the marker, mm (z = 0).
    pub marker: MarkerPoint,
    /// Where the photo shows it, px (docs/conventions.md, Pixels).
    pub pixel_px: PixelPoint,
}

/// The square sides of a finder pattern, from its corner, modules, with their kind.
const FINDER_SQUARES: [(i64, i64, TargetPointKind); 3] = [
    (0, 7, TargetPointKind::FinderOuter),
    (1, 6, TargetPointKind::FinderInner),
    (2, 5, TargetPointKind::FinderCore),
];

/// The origins (top-left modules) of the three finder patterns of an N-module symbol.
fn finder_origins(n: i64) -> [(i64, i64); 3] {
    [(0, 0), (n - 7, 0), (0, n - 7)]
}

/// The kind of module corner (i, j) of an N-module symbol.
fn kind_of(i: i64, j: i64, n: i64) -> TargetPointKind {
    for (fi, fj) in finder_origins(n) {
        for (a, b, kind) in FINDER_SQUARES {
            if [a, b].contains(&(i - fi)) && [a, b].contains(&(j - fj)) {
                return kind;
            }
        }
    }
    TargetPointKind::ModuleCorner
}

/// The centre modules (x, y) of the alignment patterns of an N-module symbol, from its
/// version's table (ISO/IEC 18004 Annex E, as rxing carries it), less the three places
/// the finder patterns take.
fn alignment_modules(n: i64) -> Vec<(i64, i64)> {
    let version = u32::try_from((n - 17) / 4).unwrap_or(0);
    let Ok(v) = rxing::qrcode::common::Version::getVersionForNumber(version) else {
        return Vec::new();
    };
    let centres: Vec<i64> = v
        .getAlignmentPatternCenters()
        .iter()
        .map(|&c| i64::from(c))
        .collect();
    let (first, last) = (6, n - 7);
    let mut out = Vec::new();
    for &y in &centres {
        for &x in &centres {
            let on_finder = [(first, first), (last, first), (first, last)].contains(&(x, y));
            if !on_finder {
                out.push((x, y));
            }
        }
    }
    out
}

/// Passes of edge measurement, a warp fitted after each but the last (module `edges`,
/// [`Pass`]).
const PASSES: [Pass; 3] = [Pass::Anchored, Pass::Scan, Pass::Final];

/// Gaussian blur σ applied to the symbol's pixels before its edges are measured, as a share
/// of the symbol's smallest module, px per px. The profiles sample the photo by bilinear
/// interpolation, whose response to a sharp edge depends on where the edge falls between
/// pixel centres (up to 0.04 px of bias on a render without blur); a blur makes the
/// response nearly shift-invariant, and the profile model takes it into its width. A
/// tenth of a module keeps what a blurred module corner adds to the profiles half a module
/// away negligible.
const PREBLUR_MODULES: f64 = 0.1;

/// Largest pre-blur σ, px: beyond it the bias of a sharp edge is gone (0.003 px on the
/// rendered test set at 7 px per module).
const MAX_PREBLUR_PX: f64 = 1.0;

/// Room around the symbol's corners for the quiet zone the profiles and reference levels
/// read, modules.
const CROP_MARGIN_MODULES: f64 = 4.0;

/// The symbol's edges, measured, with the grid they were measured under, in the pixels of a
/// blurred crop of the photo whose pixel (0, 0) is the photo's `origin_px`.
struct Measured {
    edges: edges::Edges,
    grid: WarpedGrid,
    origin_px: PixelPoint,
}

/// Measures the edges of the N-module symbol with corners `corners_px` (module doc, steps
/// 1-5).
fn measure(image: &GrayImage, corners_px: &[PixelPoint; 4], n: usize) -> Option<Measured> {
    let sides_px = (0..4).map(|i| (corners_px[i].0 - corners_px[(i + 1) % 4].0).norm());
    let (shortest_px, longest_px) = sides_px.fold((f64::INFINITY, 0.0_f64), |(lo, hi), s| {
        (lo.min(s), hi.max(s))
    });
    let preblur_px = (PREBLUR_MODULES * shortest_px / n as f64).min(MAX_PREBLUR_PX);
    let margin_px = CROP_MARGIN_MODULES * longest_px / n as f64 + 3.0 * preblur_px;
    let crop = Crop::with_margin(image, &Region::around(corners_px, 0.0)?, margin_px)?;
    let patch = sharpen(crop.image.as_ref()?, preblur_px, -1.0)?;
    let corners = corners_px.map(|p| crop.to_crop(&p));
    let origin = crop.to_crop(&PixelPoint::new(0.0, 0.0));
    let mut grid = WarpedGrid {
        h: Homography::from_corners(&corners, n as f64)?,
        warp: Warp::identity(n as f64),
    };
    let (light, dark) = reference_levels(&patch, |m| grid.map(m), n)?;
    let mut measured = None;
    for (k, pass) in PASSES.into_iter().enumerate() {
        let map = module_map(&patch, |m| grid.map(m), n, light, dark);
        let found = measure_edges(&patch, &grid, &map, pass);
        if k + 1 < PASSES.len() {
            grid.warp = grid.warp.fit(&found.offsets())?;
        }
        measured = Some(found);
    }
    Some(Measured {
        edges: measured?,
        grid,
        origin_px: PixelPoint::new(-origin.u(), -origin.v()),
    })
}

/// Every calibration point of `code` in `image` (module doc), the symbol printed with side
/// `marker`: finder corners (outer, inner, core, each finder in qr order: top-left,
/// top-right, bottom-left finder), then alignment centres, then the other module corners
/// row by row. Empty when the code's corners were not refined, its module count is unknown,
/// or too few of its edges could be measured.
#[must_use]
pub fn calibration_points(
    image: &GrayImage,
    code: &DetectedCode,
    marker: &Marker,
) -> Vec<TargetPoint> {
    let Some(n) = code.refinement.module_count.filter(|_| code.is_refined()) else {
        return Vec::new();
    };
    let Some(Measured {
        edges,
        grid,
        origin_px,
    }) = measure(image, code.corners_px(), n)
    else {
        return Vec::new();
    };
    // Module counts are at most 177.
    #[allow(clippy::cast_possible_wrap)]
    let ni = n as i64;
    let point = |kind, p: GridPoint| TargetPoint {
        kind,
        module: p.module,
        marker: marker_point_of_module(p.module, marker, n),
        pixel_px: PixelPoint::new(
            p.pixel_px.u() + origin_px.u(),
            p.pixel_px.v() + origin_px.v(),
        ),
    };
    let corners: HashMap<(i64, i64), GridPoint> = module_corners(&edges, &grid, ni)
        .into_iter()
        // Whole module coordinates, 0..=N.
        .map(|p| ((p.module.u as i64, p.module.v as i64), p))
        .collect();
    let mut out = Vec::new();
    for (a, b, kind) in FINDER_SQUARES {
        for (fi, fj) in finder_origins(ni) {
            for at in [
                (fi + a, fj + a),
                (fi + b, fj + a),
                (fi + b, fj + b),
                (fi + a, fj + b),
            ] {
                if let Some(p) = corners.get(&at) {
                    out.push(point(kind, *p));
                }
            }
        }
    }
    let mut replaced = Vec::new();
    for (x, y) in alignment_modules(ni) {
        if let Some(centre) = alignment_centre(&edges, &grid, (x, y)) {
            out.push(point(TargetPointKind::AlignmentCentre, centre));
            replaced.extend([
                (x - 1, y - 1),
                (x + 2, y - 1),
                (x + 2, y + 2),
                (x - 1, y + 2),
            ]);
        }
    }
    let mut rest: Vec<_> = corners
        .into_iter()
        .filter(|((i, j), _)| {
            kind_of(*i, *j, ni) == TargetPointKind::ModuleCorner && !replaced.contains(&(*i, *j))
        })
        .collect();
    rest.sort_by_key(|((i, j), _)| (*j, *i));
    out.extend(
        rest.into_iter()
            .map(|(_, p)| point(TargetPointKind::ModuleCorner, p)),
    );
    out
}

/// How many points of each kind, in [`TargetPointKind::ALL`] order.
#[must_use]
pub fn count_by_kind(points: &[TargetPoint]) -> [(TargetPointKind, usize); 5] {
    TargetPointKind::ALL.map(|kind| (kind, points.iter().filter(|p| p.kind == kind).count()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alignment_patterns_follow_the_version_table() {
        assert!(alignment_modules(21).is_empty(), "version 1 has none");
        assert_eq!(alignment_modules(25), vec![(18, 18)]);
        // Version 7 (45 modules): 6, 22, 38, less the three finder places.
        let v7 = alignment_modules(45);
        assert_eq!(v7.len(), 6);
        assert!(v7.contains(&(22, 6)) && v7.contains(&(38, 38)) && !v7.contains(&(6, 6)));
    }

    #[test]
    fn finder_squares_are_told_apart() {
        assert_eq!(kind_of(0, 0, 25), TargetPointKind::FinderOuter);
        assert_eq!(kind_of(25, 7, 25), TargetPointKind::FinderOuter);
        assert_eq!(kind_of(19, 1, 25), TargetPointKind::FinderInner);
        // The bottom-left finder spans rows 18..25; its core's corners are at rows 20 and 23.
        assert_eq!(kind_of(5, 23, 25), TargetPointKind::FinderCore);
        assert_eq!(kind_of(2, 20, 25), TargetPointKind::FinderCore);
        assert_eq!(kind_of(5, 22, 25), TargetPointKind::ModuleCorner);
        assert_eq!(kind_of(24, 6, 25), TargetPointKind::FinderInner);
        assert_eq!(kind_of(10, 0, 25), TargetPointKind::ModuleCorner);
        assert_eq!(kind_of(3, 3, 25), TargetPointKind::ModuleCorner);
    }
}
