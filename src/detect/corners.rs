//! Sub-pixel corners of a QR symbol, whatever backend found it.
//!
//! Backends return whole-pixel corners (rqrr, rxing, zxing-cpp). Starting from them:
//!
//! 1. **Module count** N: from the backend when it knows the version (every backend's own
//!    reads do), otherwise the N whose function patterns (finders, separators, timing)
//!    match best.
//! 2. **Module map**: the function patterns (three finders, separators, timing) are known;
//!    the other modules are read at their centres through the current homography.
//! 3. **Edge observations**: across every module boundary on the symbol's outer sides and
//!    on the four sides of each finder pattern, a 1-D profile is fitted with the blurred
//!    module pattern it must show ([`super::profile`]); each fit puts one image point on
//!    a known line of the module grid (u = 0, 7, N − 7, N or v = the same).
//! 4. **Homography**: the module-to-image homography that puts every observed point on its
//!    line, by iteratively reweighted linear least squares (Sturm's reweighting turns the
//!    algebraic error into module units; a Huber weight tames misread data modules).
//!    Steps 2-4 run once as a scan (every other site, each edge searched for), then as
//!    final passes (every site) until one moves no corner by more than [`SETTLED_PX`], at
//!    most [`MAX_FINAL_PASSES`] of them.
//! 5. **Corners** are the homography at (0, 0), (N, 0), (N, N), (0, N) (qr order).
//!    **Finder corners**: each finder's four sides are fitted as image lines from their
//!    own observations only and intersected (twelve points, independent of the data area).
//!
//! Refinement never makes things silently worse: with too few observations, a poor
//! finder-pattern match, or corners that moved further than [`MAX_MOVE_MODULES`] from the
//! backend's, the backend corners are kept and [`Refinement::status`] says why.

// Pixel and module indices are floats floored or clamped into the image or the module grid
// (or u8 grey levels clamped to 0..=255) before the cast, so truncation cannot occur.
#![allow(clippy::cast_possible_truncation)]

use super::decode::GrayImage;
use super::homography::{Homography, ModulePoint};
use super::profile::{DarkRun, fit_profile};
use crate::geometry::frames::PixelPoint;
use nalgebra::{DMatrix, Matrix3};

/// Most final refinement passes. The first pass scans (every other site, each edge searched
/// over ±[`super::profile::MAX_SHIFT_MODULES`]) to bring the homography close; final passes
/// (every site, each fit from the current edge) follow, another while the last one still
/// moved a corner by more than [`SETTLED_PX`]. Each final pass leaves about a tenth of the
/// error it started from, so a start a pixel or more off (corners read at half scale, say)
/// gets a second one. A pass that moves the corners further than the pass before (the
/// passes do not converge, as on some hard photos) is dropped and the one before kept.
pub const MAX_FINAL_PASSES: usize = 3;
/// A final pass that moved no corner further than this has settled, px.
pub const SETTLED_PX: f64 = 0.5;
/// Refined corners further than this from the backend's (in modules) mean a failure.
pub const MAX_MOVE_MODULES: f64 = 2.0;
/// Fewest pixels per module the refinement works with.
pub const MIN_PX_PER_MODULE: f64 = 1.2;
/// Huber threshold of the homography fit, px.
const HUBER_PX: f64 = 0.3;
/// The reweighted homography fit stops once no Huber weight changes by more than this.
const WEIGHT_SETTLED: f64 = 1e-3;
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
/// Fewest edge observations on one finder side for its line fit.
const MIN_SIDE_OBSERVATIONS: usize = 3;

/// The four sides of a square, as module-grid lines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Axis {
    /// A line u = c (vertical in module space).
    U,
    /// A line v = c.
    V,
}

/// One measured edge point on a known grid line.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Observation {
    axis: Axis,
    /// The line's coordinate, modules.
    c: f64,
    /// Where along the line (the other coordinate), modules.
    t: f64,
    /// The measured edge point, px.
    point: PixelPoint,
    /// Pixels per module across the edge at this point.
    px_per_module: f64,
    /// Which finder side this observation lies on, if any: (finder 0..3, side 0..4).
    finder_side: Option<(usize, usize)>,
}

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
    /// [`super::finders::finder_model_points`] for their order), when every finder side was measured.
    pub finder_corners_px: Option<[PixelPoint; 12]>,
    /// The module count N (21 for version 1, 4 more per version).
    pub module_count: Option<usize>,
    /// How refinement ended.
    pub status: RefineStatus,
    /// Edge observations used in the final homography.
    pub observations: usize,
}

/// Module colours: `Some(true)` dark, `Some(false)` light, `None` unknown. Outside the
/// symbol everything is light (the quiet zone).
struct ModuleMap {
    n: usize,
    dark: Vec<Option<bool>>,
}

impl ModuleMap {
    fn get(&self, i: i64, j: i64) -> Option<bool> {
        let n = self.n as i64;
        if i < 0 || j < 0 || i >= n || j >= n {
            return Some(false);
        }
        self.dark[(j as usize) * self.n + i as usize]
    }
}

/// The colour of function-pattern module (i, j), or `None` for a data module.
fn function_module(n: usize, i: usize, j: usize) -> Option<bool> {
    let finder = |di: usize, dj: usize| -> Option<bool> {
        // A finder with its separator: 8 × 8 from its corner.
        if di == 7 || dj == 7 {
            return Some(false);
        }
        let ring = di == 0 || dj == 0 || di == 6 || dj == 6;
        let core = (2..=4).contains(&di) && (2..=4).contains(&dj);
        Some(ring || core)
    };
    if i < 8 && j < 8 {
        return finder(i, j);
    }
    if i + 8 >= n && j < 8 {
        return finder(n - 1 - i, j);
    }
    if i < 8 && j + 8 >= n {
        return finder(i, n - 1 - j);
    }
    if j == 6 {
        return Some(i.is_multiple_of(2));
    }
    if i == 6 {
        return Some(j.is_multiple_of(2));
    }
    None
}

/// Every function-pattern module (i, j, dark) of an N-module symbol: the three finders with
/// their separators, and the two timing patterns between them. The same modules as
/// [`function_module`] marks, without visiting the N² data modules.
fn function_modules(n: usize) -> impl Iterator<Item = (usize, usize, bool)> {
    let origins = [(0, 0), (n - 8, 0), (0, n - 8)];
    let finders = origins.into_iter().flat_map(move |(i0, j0)| {
        (0..64).filter_map(move |k| {
            let (i, j) = (i0 + k % 8, j0 + k / 8);
            function_module(n, i, j).map(|dark| (i, j, dark))
        })
    });
    let timing = (8..n - 8).flat_map(|k| [(k, 6, k % 2 == 0), (6, k, k % 2 == 0)]);
    // The timing patterns first: they tell module counts apart soonest.
    timing.chain(finders)
}

/// How many modules [`function_modules`] lists: three 8 × 8 finders with separators and
/// two timing patterns of N − 16 modules each.
fn function_module_count(n: usize) -> usize {
    3 * 64 + 2 * (n - 16)
}

/// Light and dark reference levels: the quiet zone just outside the symbol and the finder
/// cores. `None` when they cannot be sampled.
fn reference_levels(image: &GrayImage, h: &Homography, n: usize) -> Option<(f64, f64)> {
    let nf = n as f64;
    let mut light = Vec::new();
    for k in 0..(4 * n) {
        let t = (k as f64 + 0.5) / 4.0;
        for p in [
            ModulePoint::new(t, -1.5),
            ModulePoint::new(t, nf + 1.5),
            ModulePoint::new(-1.5, t),
            ModulePoint::new(nf + 1.5, t),
        ] {
            let x = h.map(p);
            if let Some(i) = image.sample(x.u(), x.v()) {
                light.push(i);
            }
        }
    }
    let mut dark = Vec::new();
    for (u0, v0) in [(2.0, 2.0), (nf - 5.0, 2.0), (2.0, nf - 5.0)] {
        for a in 0..3 {
            for b in 0..3 {
                let x = h.map(ModulePoint::new(
                    u0 + f64::from(a) + 0.5,
                    v0 + f64::from(b) + 0.5,
                ));
                if let Some(i) = image.sample(x.u(), x.v()) {
                    dark.push(i);
                }
            }
        }
    }
    Some((median(&mut light)?, median(&mut dark)?))
}

fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    Some(values[values.len() / 2])
}

/// The module map under `h`: function patterns known, data modules read at their centres.
fn module_map(image: &GrayImage, h: &Homography, n: usize, light: f64, dark: f64) -> ModuleMap {
    let threshold = 0.5 * (light + dark);
    let inverted = dark > light;
    let mut map = vec![None; n * n];
    for j in 0..n {
        for i in 0..n {
            map[j * n + i] = function_module(n, i, j).or_else(|| {
                let x = h.map(ModulePoint::new(i as f64 + 0.5, j as f64 + 0.5));
                image
                    .sample(x.u(), x.v())
                    .map(|value| (value < threshold) != inverted)
            });
        }
    }
    ModuleMap { n, dark: map }
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

/// Measures every usable site under `h`.
/// `scan`: the first pass, from a backend's whole-pixel corners: every other site only (it
/// just brings the homography close), each searched over
/// ±[`super::profile::MAX_SHIFT_MODULES`]; later passes measure every site, starting at the
/// current edge.
fn observe(image: &GrayImage, h: &Homography, map: &ModuleMap, scan: bool) -> Vec<Observation> {
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
        let (ppm_u, ppm_v) = h.px_per_module(centre);
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
            let p = h.map(point_on(s.axis, c, t, x));
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
            point: h.map(point_on(s.axis, c, t, fit.delta)),
            px_per_module: across,
            finder_side: s.finder_side,
        });
    }
    out
}

/// The homography (module → image) that best puts each observation on its grid line.
fn fit_homography(obs: &[Observation], start: &Homography) -> Option<Homography> {
    if obs.len() < 8 {
        return None;
    }
    // Normalise image coordinates.
    let n = obs.len() as f64;
    let (mx, my) = obs.iter().fold((0.0, 0.0), |(a, b), o| {
        (a + o.point.u() / n, b + o.point.v() / n)
    });
    let scale = obs
        .iter()
        .map(|o| (o.point.u() - mx).hypot(o.point.v() - my))
        .sum::<f64>()
        / n;
    if scale <= 0.0 {
        return None;
    }
    let s = 1.0 / scale;
    let t = Matrix3::new(s, 0.0, -s * mx, 0.0, s, -s * my, 0.0, 0.0, 1.0);
    let t_inv = t.try_inverse()?;
    // G maps normalised image points to module coordinates: G = H⁻¹ · T⁻¹.
    let mut g = start.matrix().try_inverse()? * t_inv;
    let mut weights = vec![1.0; obs.len()];
    for _ in 0..6 {
        let mut a = DMatrix::<f64>::zeros(obs.len(), 9);
        for (k, o) in obs.iter().enumerate() {
            let x = t * nalgebra::Vector3::new(o.point.u(), o.point.v(), 1.0);
            let w3 = g.row(2).dot(&x.transpose());
            if w3.abs() < 1e-12 {
                return None;
            }
            // Module-unit residual = row · g / w3; times px per module for pixels.
            let wk = weights[k] * o.px_per_module / w3;
            let base = match o.axis {
                Axis::U => 0,
                Axis::V => 3,
            };
            for c in 0..3 {
                a[(k, base + c)] = wk * x[c];
                a[(k, 6 + c)] = -wk * o.c * x[c];
            }
        }
        let svd = (a.transpose() * &a).symmetric_eigen();
        let (imin, _) = svd
            .eigenvalues
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))?;
        let v = svd.eigenvectors.column(imin);
        g = Matrix3::new(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8]);
        // Huber weights from the pixel residuals; once they stop changing, so does G.
        let mut largest_change: f64 = 0.0;
        for (k, o) in obs.iter().enumerate() {
            let r = residual_px(&g, &t, o).abs();
            let w = if r <= HUBER_PX { 1.0 } else { HUBER_PX / r };
            largest_change = largest_change.max((w - weights[k]).abs());
            weights[k] = w;
        }
        if largest_change < WEIGHT_SETTLED {
            break;
        }
    }
    let h = (g * t).try_inverse()?;
    Homography::from_matrix(h / h[(2, 2)])
}

fn residual_px(g: &Matrix3<f64>, t: &Matrix3<f64>, o: &Observation) -> f64 {
    let x = t * nalgebra::Vector3::new(o.point.u(), o.point.v(), 1.0);
    let m = g * x;
    let coord = match o.axis {
        Axis::U => m.x / m.z,
        Axis::V => m.y / m.z,
    };
    (coord - o.c) * o.px_per_module
}

/// A line a·u + b·v = c in the image, (a, b) unit.
#[derive(Debug, Clone, Copy)]
struct Line {
    a: f64,
    b: f64,
    c: f64,
}

/// Total-least-squares line through points, with one Huber reweighting.
fn fit_line(points: &[PixelPoint]) -> Option<Line> {
    if points.len() < 2 {
        return None;
    }
    let mut w = vec![1.0; points.len()];
    let mut line = None;
    for _ in 0..3 {
        let sw: f64 = w.iter().sum();
        let (mu, mv) = points.iter().zip(&w).fold((0.0, 0.0), |(a, b), (p, wk)| {
            (a + wk * p.u() / sw, b + wk * p.v() / sw)
        });
        let (mut suu, mut suv, mut svv) = (0.0, 0.0, 0.0);
        for (p, wk) in points.iter().zip(&w) {
            let (du, dv) = (p.u() - mu, p.v() - mv);
            suu += wk * du * du;
            suv += wk * du * dv;
            svv += wk * dv * dv;
        }
        // Normal = eigenvector of the smaller eigenvalue of the scatter matrix.
        let angle = 0.5 * (2.0 * suv).atan2(suu - svv);
        let (a, b) = (-angle.sin(), angle.cos());
        let l = Line {
            a,
            b,
            c: a * mu + b * mv,
        };
        for (p, wk) in points.iter().zip(w.iter_mut()) {
            let r = (l.a * p.u() + l.b * p.v() - l.c).abs();
            *wk = if r <= HUBER_PX { 1.0 } else { HUBER_PX / r };
        }
        line = Some(l);
    }
    line
}

fn intersect(l1: &Line, l2: &Line) -> Option<PixelPoint> {
    let det = l1.a * l2.b - l1.b * l2.a;
    if det.abs() < 1e-9 {
        return None;
    }
    Some(PixelPoint::new(
        (l1.c * l2.b - l1.b * l2.c) / det,
        (l1.a * l2.c - l1.c * l2.a) / det,
    ))
}

/// Finder corners from per-side line fits: `None` unless all twelve sides were measured.
fn finder_corners(obs: &[Observation]) -> Option<[PixelPoint; 12]> {
    let mut out = [PixelPoint::new(0.0, 0.0); 12];
    for f in 0..3 {
        let mut lines = [None; 4];
        for (side, line) in lines.iter_mut().enumerate() {
            let points: Vec<PixelPoint> = obs
                .iter()
                .filter(|o| o.finder_side == Some((f, side)))
                .map(|o| o.point)
                .collect();
            if points.len() < MIN_SIDE_OBSERVATIONS {
                return None;
            }
            *line = fit_line(&points);
        }
        let [top, right, bottom, left] = lines.map(|l| l.ok_or(()));
        let (top, right, bottom, left) = (top.ok()?, right.ok()?, bottom.ok()?, left.ok()?);
        out[4 * f] = intersect(&top, &left)?;
        out[4 * f + 1] = intersect(&top, &right)?;
        out[4 * f + 2] = intersect(&bottom, &right)?;
        out[4 * f + 3] = intersect(&bottom, &left)?;
    }
    Some(out)
}

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
pub fn estimate_module_count(image: &GrayImage, corners: &[PixelPoint; 4]) -> Option<usize> {
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

/// The largest distance between corresponding corners of two quads, px.
fn largest_move_px(a: &[PixelPoint; 4], b: &[PixelPoint; 4]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p.0 - q.0).norm())
        .fold(0.0, f64::max)
}

/// Refines a backend's corners (qr order). `module_count` is N when the backend knows it.
pub fn refine_corners(
    image: &GrayImage,
    backend_corners: &[PixelPoint; 4],
    module_count: Option<usize>,
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
    let Some(mut h) = Homography::from_corners(backend_corners, n as f64) else {
        return unrefined(RefineStatus::TooFewEdges, Some(n));
    };
    let (ppm_u, ppm_v) = h.px_per_module(ModulePoint::new(n as f64 / 2.0, n as f64 / 2.0));
    if ppm_u.min(ppm_v) < MIN_PX_PER_MODULE {
        return unrefined(RefineStatus::TooSmall, Some(n));
    }
    let mut obs = Vec::new();
    let mut corners_px = h.corners(n as f64);
    let mut last_step_px = f64::INFINITY;
    for pass in 0..=MAX_FINAL_PASSES {
        let scan = pass == 0;
        let Some((light, dark)) = reference_levels(image, &h, n) else {
            return unrefined(RefineStatus::TooFewEdges, Some(n));
        };
        let map = module_map(image, &h, n, light, dark);
        let pass_obs = observe(image, &h, &map, scan);
        let Some(next_h) = fit_homography(&pass_obs, &h) else {
            return unrefined(RefineStatus::TooFewEdges, Some(n));
        };
        let next = next_h.corners(n as f64);
        let step_px = largest_move_px(&next, &corners_px);
        if pass > 1 && step_px >= last_step_px {
            // Not converging (a hard image): keep the pass before.
            break;
        }
        (h, obs, corners_px, last_step_px) = (next_h, pass_obs, next, step_px);
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
        finder_corners_px: finder_corners(&obs),
        module_count: Some(n),
        status: RefineStatus::Refined,
        observations: obs.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn function_modules_lists_exactly_the_function_patterns() {
        for n in [21, 25, 57, 177] {
            let mut listed: Vec<_> = function_modules(n).collect();
            listed.sort_unstable();
            let mut scanned: Vec<_> = (0..n)
                .flat_map(|j| (0..n).map(move |i| (i, j)))
                .filter_map(|(i, j)| function_module(n, i, j).map(|dark| (i, j, dark)))
                .collect();
            scanned.sort_unstable();
            assert_eq!(listed.len(), function_module_count(n), "N = {n}");
            assert_eq!(listed, scanned, "N = {n}");
        }
    }
}
