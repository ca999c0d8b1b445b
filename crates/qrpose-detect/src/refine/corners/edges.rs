//! Edge observations (stage 3 of [`super::refine_corners`]): the edge sites of a symbol
//! (every module boundary on its outer sides and on the four sides of each finder), the
//! module pattern across each, and one 1-D profile fit per site ([`crate::refine::profile`]) that
//! puts an image point on a known line of the module grid.

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

use super::MIN_PX_PER_MODULE;
use super::lens::Grid;
use super::modules::ModuleMap;
use crate::raster::GrayImage;
use crate::refine::homography::ModulePoint;
use crate::refine::profile::{DarkRun, fit_profile};
use qrpose_core::geometry::frames::PixelPoint;

/// Half-length of a profile across an edge, modules.
const PROFILE_HALF_MODULES: f64 = 2.5;
/// Most samples in one profile (cost grows with it; 24 keeps ≥ 4 per module).
const MAX_PROFILE_SAMPLES: usize = 24;
/// Most samples in one profile of the first, scanning pass, which only brings the homography
/// close: 16 keeps ≥ 3 per module. (Capping the final pass at 16 as well lost one code of
/// the real photos, whose re-read goes through the refined grid.)
const MAX_SCAN_PROFILE_SAMPLES: usize = 16;
/// Starting blur of a profile fit, px.
const SIGMA0_PX: f64 = 1.0;

/// The four sides of a square, as module-grid lines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Axis {
    /// A line u = c (vertical in module space).
    U,
    /// A line v = c.
    V,
}

/// One measured edge point on a known grid line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Observation {
    pub(super) axis: Axis,
    /// The line's coordinate, modules.
    pub(super) c: f64,
    /// Where along the line (the other coordinate), modules.
    pub(super) t: f64,
    /// The measured edge point in ideal pixels ([`super::lens`]): the photo's pixels when
    /// the camera does not distort, else where a distortion-free camera would see it.
    pub(super) point: PixelPoint,
    /// The photo's pixels per module across the edge at this point.
    pub(super) px_per_module: f64,
    /// Which finder side this observation lies on, if any: (finder 0..3, side 0..4).
    pub(super) finder_side: Option<(usize, usize)>,
}

/// An edge site: the boundary between modules c − 1 and c along `axis`, in row/column k.
#[derive(Debug, Clone, Copy)]
struct Site {
    axis: Axis,
    c: i64,
    k: i64,
    finder_side: Option<(usize, usize)>,
}

/// The module colour at position `a` along the profile axis and `k` across it.
fn colour_at(map: &ModuleMap, axis: Axis, a: i64, k: i64) -> Option<bool> {
    match axis {
        Axis::U => map.get(a, k),
        Axis::V => map.get(k, a),
    }
}

/// Edge sites: every module of the outer sides and of each finder's four sides.
fn sites(n: usize) -> Vec<Site> {
    let n = n as i64;
    let mut out = Vec::new();
    // Finders: (origin u, origin v); sides 0 top, 1 right, 2 bottom, 3 left.
    let finders = [(0, 0), (n - 7, 0), (0, n - 7)];
    for (f, &(u0, v0)) in finders.iter().enumerate() {
        for k in 0..7 {
            out.push(Site {
                axis: Axis::V,
                c: v0,
                k: u0 + k,
                finder_side: Some((f, 0)),
            });
            out.push(Site {
                axis: Axis::U,
                c: u0 + 7,
                k: v0 + k,
                finder_side: Some((f, 1)),
            });
            out.push(Site {
                axis: Axis::V,
                c: v0 + 7,
                k: u0 + k,
                finder_side: Some((f, 2)),
            });
            out.push(Site {
                axis: Axis::U,
                c: u0,
                k: v0 + k,
                finder_side: Some((f, 3)),
            });
        }
    }
    // Outer sides beyond the finders: top and left between the finders, right and bottom
    // from the finder to the bottom-right corner.
    for k in 7..(n - 7) {
        out.push(Site {
            axis: Axis::V,
            c: 0,
            k,
            finder_side: None,
        });
        out.push(Site {
            axis: Axis::U,
            c: 0,
            k,
            finder_side: None,
        });
    }
    for k in 7..n {
        out.push(Site {
            axis: Axis::U,
            c: n,
            k,
            finder_side: None,
        });
        out.push(Site {
            axis: Axis::V,
            c: n,
            k,
            finder_side: None,
        });
    }
    out
}

/// Pattern half-width read for a profile, modules on each side of the edge.
const PATTERN_MODULES: i64 = 4;

/// The dark runs across site `s` relative to the edge (d = 0), if the site is a real edge
/// whose neighbourhood is one-dimensional enough for the 1-D model.
fn site_runs(map: &ModuleMap, s: &Site) -> Option<Vec<DarkRun>> {
    let before = colour_at(map, s.axis, s.c - 1, s.k)?;
    let after = colour_at(map, s.axis, s.c, s.k)?;
    if before == after {
        return None;
    }
    // The two modules at the edge must continue along the edge on both sides, or the 2-D
    // blur of a corner would bend the profile.
    for dk in [-1, 1] {
        if colour_at(map, s.axis, s.c - 1, s.k + dk)? != before
            || colour_at(map, s.axis, s.c, s.k + dk)? != after
        {
            return None;
        }
    }
    let mut runs = Vec::new();
    let mut start: Option<f64> = None;
    let lo = -PATTERN_MODULES;
    let hi = PATTERN_MODULES;
    for a in lo..hi {
        let dark = colour_at(map, s.axis, s.c + a, s.k)?;
        let x = a as f64;
        match (dark, start) {
            (true, None) => start = Some(if a == lo { -1e3 } else { x }),
            (false, Some(st)) => {
                runs.push(DarkRun { start: st, end: x });
                start = None;
            }
            _ => {}
        }
    }
    if let Some(st) = start {
        runs.push(DarkRun {
            start: st,
            end: 1e3,
        });
    }
    Some(runs)
}

fn point_on(axis: Axis, c: f64, t: f64, d: f64) -> ModulePoint {
    match axis {
        Axis::U => ModulePoint::new(c + d, t),
        Axis::V => ModulePoint::new(t, c + d),
    }
}

/// Measures every usable site under `grid`: the profiles are sampled in the photo, along
/// the lens's image of a straight module-grid segment across the edge.
/// `scan`: the first pass, from a backend's whole-pixel corners: every other site only (it
/// just brings the homography close), each searched over
/// ±[`crate::refine::profile::MAX_SHIFT_MODULES`]; later passes measure every site, starting at the
/// current edge.
pub(super) fn observe(
    image: &GrayImage,
    grid: &Grid,
    map: &ModuleMap,
    scan: bool,
) -> Vec<Observation> {
    let n = map.n;
    let mut out = Vec::new();
    // One pair of sample buffers for every profile.
    let (mut d, mut intensity) = (Vec::new(), Vec::new());
    for s in sites(n).into_iter().filter(|s| !scan || s.k % 2 == 0) {
        let Some(runs) = site_runs(map, &s) else {
            continue;
        };
        let c = s.c as f64;
        let centre = point_on(s.axis, c, s.k as f64 + 0.5, 0.0);
        let (ppm_u, ppm_v) = grid.px_per_module(centre);
        let across = match s.axis {
            Axis::U => ppm_u,
            Axis::V => ppm_v,
        };
        if across < MIN_PX_PER_MODULE {
            continue;
        }
        // One profile across the middle of each module (a second one on modules over 4 px
        // cost a fifth of the refinement's time for a median corner error 0.002 px lower on
        // the rendered set); samples every 0.5 px, at most MAX_PROFILE_SAMPLES
        // (MAX_SCAN_PROFILE_SAMPLES when scanning).
        let max_samples = if scan {
            MAX_SCAN_PROFILE_SAMPLES
        } else {
            MAX_PROFILE_SAMPLES
        };
        let step_d = (0.5 / across).max(2.0 * PROFILE_HALF_MODULES / max_samples as f64);
        let samples = (2.0 * PROFILE_HALF_MODULES / step_d).ceil() as usize;
        let t = s.k as f64 + 0.5;
        d.clear();
        intensity.clear();
        for q in 0..=samples {
            let x = -PROFILE_HALF_MODULES + q as f64 * step_d;
            let p = grid.map(point_on(s.axis, c, t, x));
            if let Some(i) = image.sample(p.u(), p.v()) {
                d.push(x);
                intensity.push(i);
            }
        }
        if d.len() <= samples / 2 {
            continue;
        }
        let Some(fit) = fit_profile(&runs, &d, &intensity, SIGMA0_PX / across, scan) else {
            continue;
        };
        out.push(Observation {
            axis: s.axis,
            c,
            t,
            point: grid.ideal(point_on(s.axis, c, t, fit.delta)),
            px_per_module: across,
            finder_side: s.finder_side,
        });
    }
    out
}
