//! Grid points from measured edges: each module corner (i, j) is where the symbol's lines
//! u = i and v = j cross, each line fitted locally to the edges measured on it within
//! [`WINDOW_MODULES`] of the corner; each alignment pattern's centre is where the diagonals
//! of the square around its centre module cross. Lines and crossings are in the warped
//! grid's module coordinates (`super::warp`), in which the symbol's lines are straight to a
//! small fraction of a module whatever the lens, and the points then go to the photo through
//! the grid.

use super::edges::{Edges, Line};
use super::warp::WarpedGrid;
use crate::refine::homography::ModulePoint;
use qrpose_core::geometry::frames::PixelPoint;

/// Module rows (or columns) on each side of a corner whose edges fit its lines: two, so that
/// a corner with edges on one side only (an L corner, as on the symbol's outer sides) still
/// has two, and a line fitted over four modules bends by a negligible amount under the
/// warp's residual.
const WINDOW_MODULES: i64 = 2;

/// Fewest edges a corner's line is fitted to.
const MIN_LINE_EDGES: usize = 2;

/// Largest RMS residual of a line fitted to three or more edges, modules: more means an
/// edge of the line was misread or misfitted, and the corner is not reported.
const MAX_LINE_RMS_MODULES: f64 = 0.04;

/// Largest slope of a corner's line against the warped grid: the warp follows the symbol's
/// lines, so a steeper one was fitted to wrong edges.
const MAX_LINE_SLOPE: f64 = 0.1;

/// Largest distance of a corner from the warped grid's point, modules.
const MAX_OFFSET_MODULES: f64 = 0.3;

/// A local line x = a + b·y near a corner: x the offset across the line from its grid
/// position, y the distance along it from the corner, modules.
#[derive(Debug, Clone, Copy, PartialEq)]
struct LocalLine {
    a: f64,
    b: f64,
}

/// The line `line` near position `at` along it, from the edges within [`WINDOW_MODULES`].
fn local_line(edges: &Edges, line: Line, at: i64) -> Option<LocalLine> {
    let points: Vec<(f64, f64)> = (at - WINDOW_MODULES..at + WINDOW_MODULES)
        .filter_map(|k| {
            let y = k as f64 + 0.5 - at as f64;
            edges.offset(line, k).map(|x| (y, x))
        })
        .collect();
    if points.len() < MIN_LINE_EDGES {
        return None;
    }
    let count = points.len() as f64;
    let (my, mx) = points.iter().fold((0.0, 0.0), |(sy, sx), (y, x)| {
        (sy + y / count, sx + x / count)
    });
    let syy: f64 = points.iter().map(|(y, _)| (y - my).powi(2)).sum();
    let sxy: f64 = points.iter().map(|(y, x)| (y - my) * (x - mx)).sum();
    if syy <= 0.0 {
        return None;
    }
    let b = sxy / syy;
    let a = mx - b * my;
    let rms = (points
        .iter()
        .map(|(y, x)| (x - a - b * y).powi(2))
        .sum::<f64>()
        / count)
        .sqrt();
    (b.abs() <= MAX_LINE_SLOPE && rms <= MAX_LINE_RMS_MODULES).then_some(LocalLine { a, b })
}

/// The corner (i, j) in the warped grid's module coordinates: the crossing of the local
/// lines u = i + a + b·(v − j) and v = j + a′ + b′·(u − i).
pub(super) fn corner_modules(edges: &Edges, i: i64, j: i64) -> Option<ModulePoint> {
    let lu = local_line(
        edges,
        Line {
            along_u: true,
            c: i,
        },
        j,
    )?;
    let lv = local_line(
        edges,
        Line {
            along_u: false,
            c: j,
        },
        i,
    )?;
    let det = 1.0 - lu.b * lv.b;
    if det.abs() < 0.5 {
        return None;
    }
    let x = (lu.a + lu.b * lv.a) / det;
    let y = lv.a + lv.b * x;
    (x.hypot(y) <= MAX_OFFSET_MODULES).then(|| ModulePoint::new(i as f64 + x, j as f64 + y))
}

/// A measured point of the symbol: its ideal module coordinates (where it lies on the
/// printed grid) and where the photo shows it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct GridPoint {
    /// On the printed symbol, modules.
    pub(super) module: ModulePoint,
    /// In the photo, px.
    pub(super) pixel_px: PixelPoint,
}

/// Every measurable module corner of the N-module symbol, row by row.
pub(super) fn module_corners(edges: &Edges, grid: &WarpedGrid, n: i64) -> Vec<GridPoint> {
    let mut out = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            if let Some(m) = corner_modules(edges, i, j) {
                out.push(GridPoint {
                    module: ModulePoint::new(i as f64, j as f64),
                    pixel_px: grid.map(m),
                });
            }
        }
    }
    out
}

/// The crossing of the diagonals of a quad (qr order), module coordinates.
fn diagonal_crossing(q: [ModulePoint; 4]) -> Option<ModulePoint> {
    let (p, r) = (q[0], q[2]);
    let (s, t) = (q[1], q[3]);
    let (d1u, d1v) = (r.u - p.u, r.v - p.v);
    let (d2u, d2v) = (t.u - s.u, t.v - s.v);
    let det = d1u * d2v - d1v * d2u;
    if det.abs() < 1e-9 {
        return None;
    }
    let a = ((s.u - p.u) * d2v - (s.v - p.v) * d2u) / det;
    Some(ModulePoint::new(p.u + a * d1u, p.v + a * d1v))
}

/// The centre of the alignment pattern whose centre module is (x, y): the crossing of the
/// diagonals of the square of grid points (x − 1, y − 1) … (x + 2, y + 2) around it (the
/// inner side of its dark ring), a projective invariant. `None` unless all four corners
/// were measured.
pub(super) fn alignment_centre(
    edges: &Edges,
    grid: &WarpedGrid,
    (x, y): (i64, i64),
) -> Option<GridPoint> {
    let corner = |i, j| corner_modules(edges, i, j);
    let square = [
        corner(x - 1, y - 1)?,
        corner(x + 2, y - 1)?,
        corner(x + 2, y + 2)?,
        corner(x - 1, y + 2)?,
    ];
    let centre = diagonal_crossing(square)?;
    Some(GridPoint {
        module: ModulePoint::new(x as f64 + 0.5, y as f64 + 0.5),
        pixel_px: grid.map(centre),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_diagonals_of_a_square_cross_at_its_centre() {
        let q = [
            ModulePoint::new(1.0, 2.0),
            ModulePoint::new(4.0, 2.0),
            ModulePoint::new(4.0, 5.0),
            ModulePoint::new(1.0, 5.0),
        ];
        let c = diagonal_crossing(q).expect("a square");
        assert!((c.u - 2.5).abs() < 1e-12 && (c.v - 3.5).abs() < 1e-12);
    }
}
