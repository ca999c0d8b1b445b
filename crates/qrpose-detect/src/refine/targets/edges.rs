//! Every module edge of a symbol, measured: each boundary between two modules of different
//! colour (the quiet zone counting as light), on the grid line u = c or v = c, across the
//! middle of its module row or column, by the 1-D profile fit of
//! [`crate::refine::profile`] with the module pattern the profile crosses.
//!
//! Unlike the corner refinement's sites (`refine::corners`), a profile here may end half a
//! module from a corner of its edge (corners need exactly those sites): the modules of the
//! rows beside the profile's bleed into it by the blur's tail at half a module (Φ(−m/2σ):
//! 2 % of the contrast at m = 4σ, 7 % at 3.5 px per module and σ 1 px), which the final
//! pass models (`refine::profile` module `rows`, with the shear of a tilted code's grid).
//! Without it, the module corners of a code seen at 0.65 m tilted by 40° (3.5 px per module
//! along one side, the grid sheared by 50°, blur σ 0.8 px) were off by 0.08 px at the
//! median and 0.3 px at the 95th percentile; with it 0.05 and 0.16
//! (crates/qrpose-sim/tests/calibration_points.rs).

use super::warp::{EdgeOffset, WarpedGrid};
use crate::raster::GrayImage;
use crate::refine::corners::{ModuleMap, is_function_module};
use crate::refine::homography::ModulePoint;
use crate::refine::profile::{DarkRun, fit_profile, fit_profile_rows};

/// Half-length of a profile of the scanning pass, modules (as the corner refinement's):
/// room for an edge up to three quarters of a module off the line.
const SCAN_HALF_MODULES: f64 = 2.5;
/// Most samples in one profile of the scanning pass, which only brings the warp close.
const MAX_SCAN_SAMPLES: usize = 24;
/// Half-length of a profile of the final pass, modules: the grid is then a small fraction
/// of a module off, and a module and a half on each side still shows the edge's
/// neighbours, which the pattern models.
const FINAL_HALF_MODULES: f64 = 1.5;
/// Spacing of a final profile's samples, px: half a pixel, so that a sharp edge (a photo
/// without blur) has samples on its ramp.
const FINAL_STEP_PX: f64 = 0.5;
/// Most samples in one final profile (large modules are sampled more sparsely).
const MAX_FINAL_SAMPLES: usize = 96;
/// Starting blur of a profile fit, px.
const SIGMA0_PX: f64 = 1.0;
/// Module pattern read for a profile, modules on each side of the edge.
const PATTERN_MODULES: i64 = 4;
/// Fewest pixels per module across an edge worth measuring: below it the blur of a
/// neighbouring row reaches the profile (see the module doc).
pub(super) const MIN_PX_PER_MODULE: f64 = 2.5;
/// A run boundary this far out (modules) is at infinity for the profile model.
const OPEN_END_MODULES: f64 = 1e3;

/// A grid line of the symbol: u = c (`along_u`) or v = c.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Line {
    /// u = c when `true`, v = c otherwise.
    pub(super) along_u: bool,
    /// The line's coordinate, modules (0..=N).
    pub(super) c: i64,
}

/// The measured edges of one symbol: for each line and each module row (or column) k
/// along it, the edge's offset from the line, modules, where there is one.
pub(super) struct Edges {
    n: i64,
    /// Indexed by [`Edges::slot`].
    offsets: Vec<Option<f64>>,
}

impl Edges {
    fn slot(n: i64, line: Line, k: i64) -> Option<usize> {
        let inside = (0..=n).contains(&line.c) && (0..n).contains(&k);
        let axis = i64::from(!line.along_u);
        // The indices are in range: checked just above.
        #[allow(clippy::cast_sign_loss, clippy::cast_possible_truncation)]
        inside.then(|| ((axis * (n + 1) + line.c) * n + k) as usize)
    }

    /// The edge's offset on `line` across module row (or column) `k`, modules.
    pub(super) fn offset(&self, line: Line, k: i64) -> Option<f64> {
        Self::slot(self.n, line, k).and_then(|s| self.offsets.get(s).copied().flatten())
    }

    /// Every measured edge, as the warp fit takes them.
    pub(super) fn offsets(&self) -> Vec<EdgeOffset> {
        let mut out = Vec::new();
        for along_u in [true, false] {
            for c in 0..=self.n {
                for k in 0..self.n {
                    let line = Line { along_u, c };
                    if let Some(delta) = self.offset(line, k) {
                        out.push(EdgeOffset {
                            along_u,
                            c: c as f64,
                            t: k as f64 + 0.5,
                            delta,
                        });
                    }
                }
            }
        }
        out
    }
}

/// The colour of the module at `a` across `line`'s direction and `k` along it.
fn colour(map: &ModuleMap, line: Line, a: i64, k: i64) -> Option<bool> {
    if line.along_u {
        map.get(a, k)
    } else {
        map.get(k, a)
    }
}

/// The dark runs a profile across `line` at row `k` crosses, relative to the edge, when the
/// two modules at the line differ in colour.
fn runs_across(map: &ModuleMap, line: Line, k: i64) -> Option<Vec<DarkRun>> {
    let before = colour(map, line, line.c - 1, k)?;
    let after = colour(map, line, line.c, k)?;
    if before == after {
        return None;
    }
    row_runs(map, line, k)
}

/// The dark runs of row `k` across `line`, relative to the line, whether or not the row
/// has an edge there; `None` when a module's colour is unknown.
fn row_runs(map: &ModuleMap, line: Line, k: i64) -> Option<Vec<DarkRun>> {
    let mut runs = Vec::new();
    let mut start: Option<f64> = None;
    for a in -PATTERN_MODULES..PATTERN_MODULES {
        let dark = colour(map, line, line.c + a, k)?;
        let x = a as f64;
        match (dark, start) {
            (true, None) => {
                start = Some(if a == -PATTERN_MODULES {
                    -OPEN_END_MODULES
                } else {
                    x
                });
            }
            (false, Some(s)) => {
                runs.push(DarkRun { start: s, end: x });
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        runs.push(DarkRun {
            start: s,
            end: OPEN_END_MODULES,
        });
    }
    Some(runs)
}

/// The module point `d` modules across `line` from it, at `t` along it.
fn across(line: Line, t: f64, d: f64) -> ModulePoint {
    let c = line.c as f64;
    if line.along_u {
        ModulePoint::new(c + d, t)
    } else {
        ModulePoint::new(t, c + d)
    }
}

/// Measures the edge on `line` across row `k` under `grid`: the profile is sampled along the
/// grid's image of the module segment across the line, and fitted with the pattern the map
/// gives (in the final pass with the rows on either side too, `refine::profile` module
/// `rows`: modules of a few pixels bleed into their neighbours). `scan`: search the edge over ±`MAX_SHIFT_MODULES` (a grid that may be a fraction
/// of a module off) rather than start at the line.
fn measure(
    image: &GrayImage,
    grid: &WarpedGrid,
    map: &ModuleMap,
    (line, k): (Line, i64),
    scan: bool,
    (d, intensity): (&mut Vec<f64>, &mut Vec<f64>),
) -> Option<f64> {
    let runs = runs_across(map, line, k)?;
    let t = k as f64 + 0.5;
    let (ppm_u, ppm_v, cos_shear) = grid.px_per_module(across(line, t, 0.0));
    let (px_per_module, ppm_along) = if line.along_u {
        (ppm_u, ppm_v)
    } else {
        (ppm_v, ppm_u)
    };
    if px_per_module < MIN_PX_PER_MODULE {
        return None;
    }
    let (half, max_samples) = if scan {
        (SCAN_HALF_MODULES, MAX_SCAN_SAMPLES)
    } else {
        (FINAL_HALF_MODULES, MAX_FINAL_SAMPLES)
    };
    let step = (FINAL_STEP_PX / px_per_module).max(2.0 * half / max_samples as f64);
    // A positive count of at most `max_samples`.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let samples = (2.0 * half / step).ceil() as usize;
    d.clear();
    intensity.clear();
    for q in 0..=samples {
        let x = -half + q as f64 * step;
        let p = grid.map(across(line, t, x));
        if let Some(i) = image.sample(p.u(), p.v()) {
            d.push(x);
            intensity.push(i);
        }
    }
    if d.len() <= samples {
        // The profile leaves the image: its pattern would be cut.
        return None;
    }
    let sigma0 = SIGMA0_PX / px_per_module;
    if scan {
        return fit_profile(&runs, d, intensity, sigma0, true).map(|fit| fit.delta);
    }
    let (Some(before), Some(after)) = (row_runs(map, line, k - 1), row_runs(map, line, k + 1))
    else {
        return fit_profile(&runs, d, intensity, sigma0, false).map(|fit| fit.delta);
    };
    fit_profile_rows(
        [&before, &runs, &after],
        (d, intensity),
        sigma0,
        (px_per_module / ppm_along, cos_shear),
    )
    .map(|fit| fit.delta)
}

/// Which edges a pass measures, and how.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Pass {
    /// The edges whose place does not hang on data modules read through a grid that may be
    /// more than half a module off (a strong lens near the image's edge bends a symbol's
    /// far corner that much from the homography of its corners): the symbol's outline
    /// (the quiet zone on one side) and the edges between finder or timing modules, each
    /// searched for. A data module read through such a grid is its neighbour's, and the
    /// pattern read with it fits the edge one module off, a fit the warp would then follow.
    Anchored,
    /// Every other row, each edge searched for, from a grid the anchored edges brought
    /// close.
    Scan,
    /// Every row, from the line.
    Final,
}

/// Whether the edge on `line` across row `k` of an N-module symbol is anchored
/// ([`Pass::Anchored`]).
fn anchored(n: i64, line: Line, k: i64) -> bool {
    let module = |a: i64| if line.along_u { (a, k) } else { (k, a) };
    let known = |(i, j): (i64, i64)| {
        // Module counts are at most 177.
        #[allow(clippy::cast_sign_loss, clippy::cast_possible_truncation)]
        is_function_module(n as usize, i, j)
    };
    line.c == 0 || line.c == n || (known(module(line.c - 1)) && known(module(line.c)))
}

/// Measures the module edges of the N-module symbol under `grid` that `pass` measures,
/// colours from `map`.
pub(super) fn measure_edges(
    image: &GrayImage,
    grid: &WarpedGrid,
    map: &ModuleMap,
    pass: Pass,
) -> Edges {
    let scan = pass != Pass::Final;
    // Module counts are at most 177.
    #[allow(clippy::cast_possible_wrap)]
    let n = map.n as i64;
    let mut offsets = vec![None; 2 * (n as usize + 1) * map.n];
    let (mut d, mut intensity) = (Vec::new(), Vec::new());
    for along_u in [true, false] {
        for c in 0..=n {
            let line = Line { along_u, c };
            let wanted = |k: &i64| match pass {
                Pass::Anchored => anchored(n, line, *k),
                Pass::Scan => k % 2 == 0,
                Pass::Final => true,
            };
            for k in (0..n).filter(wanted) {
                let Some(delta) =
                    measure(image, grid, map, (line, k), scan, (&mut d, &mut intensity))
                else {
                    continue;
                };
                if let Some(slot) = Edges::slot(n, line, k).and_then(|s| offsets.get_mut(s)) {
                    *slot = Some(delta);
                }
            }
        }
    }
    Edges { n, offsets }
}
