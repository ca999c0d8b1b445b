//! One edge, measured to a fraction of a pixel: a 1-D intensity profile across a module
//! boundary fitted with the blurred module pattern it must show.
//!
//! Model, along the profile coordinate d (modules, across the edge; the edge under test at
//! d = 0): the known colours of the modules the profile crosses, shifted by δ and blurred
//! by a Gaussian of width s (modules):
//!
//! ```text
//! M(d) = W + (D − W) · Σ_dark runs [a, b) ( Φ((d − a − δ)/s) − Φ((d − b − δ)/s) )
//! ```
//!
//! W and D are the light and dark levels. A Gaussian-blurred step has its 50 % point at the
//! edge, but a one-module dark ring next to it pulls gradient peaks and threshold crossings
//! by up to half a pixel at blur σ = 1.4 px and 2 px modules; fitting the whole pattern
//! removes that bias. δ, s, W, D are found by Levenberg-Marquardt after a coarse scan of δ.
//! Module `rows` extends the pattern to the module rows on either side of the profile's, for
//! rows narrow against the blur.

mod normal;
mod rows;

use nalgebra::{Matrix4, Vector4};
use normal::{NORMAL_TABLE, NormalTable, normal};
pub(crate) use rows::fit_profile_rows;

/// One dark run of the pattern, [start, end) in modules along the profile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct DarkRun {
    /// Start, modules.
    pub(crate) start: f64,
    /// End, modules.
    pub(crate) end: f64,
}

/// A fitted profile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ProfileFit {
    /// Shift of the pattern, modules (the edge lies at d = δ).
    pub(crate) delta: f64,
    /// Blur σ, modules.
    pub(crate) sigma: f64,
    /// Light level, grey values.
    pub(crate) light: f64,
    /// Dark level, grey values.
    pub(crate) dark: f64,
    /// RMS residual, grey values.
    pub(crate) rms: f64,
}

/// Largest accepted |δ|, modules: beyond it the fit has locked on to another edge.
pub(crate) const MAX_SHIFT_MODULES: f64 = 0.75;
/// Fewest profile samples worth fitting.
pub(crate) const MIN_SAMPLES: usize = 8;
const LM_ITERATIONS: usize = 8;
/// Levenberg-Marquardt iterations after the δ scan: the pass that scans starts from a
/// backend's whole-pixel corners and is followed by a full pass, so a rough fit will do.
const LM_ITERATIONS_AFTER_SCAN: usize = 3;
/// Spacing of the coarse δ scan, modules.
const SCAN_STEP_MODULES: f64 = 0.25;
/// The fit stops once δ moves less than this, modules (1e-4 module is 0.001 px at 10 px
/// per module).
const MIN_STEP_MODULES: f64 = 1e-3;

/// Most boundaries of a pattern handled without allocation (a profile crosses at most
/// 2 · `PATTERN_MODULES` module boundaries; the refinement uses 4 modules a side), for
/// three rows of them (module `rows`).
const MAX_BOUNDARIES: usize = 48;

/// The dark runs as signed boundaries: S(d) = `base` + Σ sign · Φ((d − position − δ)/s),
/// a run [a, b) of weight w giving +w·Φ at a and −w·Φ at b. Boundaries at infinity (a run open to either
/// end of the profile) are constants, 1 and 0, and are folded into `base`, so that every
/// evaluation looks up only the boundaries the profile can see.
struct Pattern {
    base: f64,
    positions: [f64; MAX_BOUNDARIES],
    signs: [f64; MAX_BOUNDARIES],
    len: usize,
}

impl Pattern {
    /// `None` for more boundaries than [`MAX_BOUNDARIES`].
    fn new(runs: &[DarkRun]) -> Option<Self> {
        Self::weighted(runs.iter().map(|run| (1.0, *run)))
    }

    /// Runs of given weights (their darkness scaled by it); `None` for more boundaries than
    /// [`MAX_BOUNDARIES`].
    fn weighted(runs: impl IntoIterator<Item = (f64, DarkRun)>) -> Option<Self> {
        let mut pattern = Self {
            base: 0.0,
            positions: [0.0; MAX_BOUNDARIES],
            signs: [0.0; MAX_BOUNDARIES],
            len: 0,
        };
        for (weight, run) in runs {
            for (position, sign) in [(run.start, weight), (run.end, -weight)] {
                if position <= -OPEN_END_MODULES {
                    pattern.base += sign; // Φ(+∞) = 1
                } else if position < OPEN_END_MODULES {
                    *pattern.positions.get_mut(pattern.len)? = position;
                    *pattern.signs.get_mut(pattern.len)? = sign;
                    pattern.len += 1;
                } // Φ(−∞) = 0
            }
        }
        Some(pattern)
    }

    fn boundaries(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.positions[..self.len]
            .iter()
            .copied()
            .zip(self.signs[..self.len].iter().copied())
    }

    /// Darkness S(d) and its derivatives by δ and s, for 1/s = `inv_s`.
    #[inline]
    fn darkness(&self, table: &NormalTable, d: f64, delta: f64, inv_s: f64) -> (f64, f64, f64) {
        let (mut value, mut d_delta, mut d_s) = (self.base, 0.0, 0.0);
        for (position, sign) in self.boundaries() {
            let z = (d - position - delta) * inv_s;
            let (c, p) = normal(table, z);
            value += sign * c;
            d_delta -= sign * p;
            d_s -= sign * p * z;
        }
        (value, d_delta * inv_s, d_s * inv_s)
    }

    /// Darkness S(d) alone.
    #[inline]
    fn darkness_value(&self, table: &NormalTable, d: f64, delta: f64, inv_s: f64) -> f64 {
        self.boundaries()
            .map(|(position, sign)| sign * normal(table, (d - position - delta) * inv_s).0)
            .sum::<f64>()
            + self.base
    }
}

/// A run boundary this far out (modules) is at infinity: the profile spans ±2.5 modules
/// and s ≤ 3, so Φ there is exactly 0 or 1 in the table.
const OPEN_END_MODULES: f64 = 100.0;

/// Cost Σ r², JᵀJ and Jᵀr of the model at `p` = (δ, s, W, D), in one pass over the samples.
fn linearise(
    table: &NormalTable,
    pattern: &Pattern,
    d: &[f64],
    intensity: &[f64],
    p: &Vector4<f64>,
) -> (f64, Matrix4<f64>, Vector4<f64>) {
    let inv_s = 1.0 / p[1];
    let contrast = p[3] - p[2];
    let mut cost = 0.0;
    // The ten distinct entries of the symmetric JᵀJ, row by row, and Jᵀr.
    let mut a = [0.0; 10];
    let mut g = [0.0; 4];
    for (&x, &i) in d.iter().zip(intensity) {
        let (sv, ds_delta, ds_s) = pattern.darkness(table, x, p[0], inv_s);
        let r = p[2] + contrast * sv - i;
        let j = [contrast * ds_delta, contrast * ds_s, 1.0 - sv, sv];
        cost += r * r;
        let mut k = 0;
        for m in 0..4 {
            g[m] += j[m] * r;
            for n in m..4 {
                a[k] += j[m] * j[n];
                k += 1;
            }
        }
    }
    #[rustfmt::skip]
    let jtj = Matrix4::new(
        a[0], a[1], a[2], a[3],
        a[1], a[4], a[5], a[6],
        a[2], a[5], a[7], a[8],
        a[3], a[6], a[8], a[9],
    );
    (cost, jtj, Vector4::from(g))
}

/// Light and dark levels by linear least squares for fixed δ and s, and the cost at them:
/// (W, D, cost), over every `stride`-th sample. With f1 = 1 − S and f2 = S the model is
/// M = W·f1 + D·f2, and the cost Σ (M − I)² follows from the same sums as the normal
/// equations, in one pass and without storing S.
fn levels_and_cost(
    table: &NormalTable,
    pattern: &Pattern,
    (d, intensity): (&[f64], &[f64]),
    stride: usize,
    delta: f64,
    s: f64,
) -> (f64, f64, f64) {
    let inv_s = 1.0 / s;
    let (mut a11, mut a12, mut a22, mut b1, mut b2, mut ii) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut sum_i, mut count) = (0.0, 0.0);
    for (&x, &i) in d.iter().zip(intensity).step_by(stride) {
        let sv = pattern.darkness_value(table, x, delta, inv_s);
        let (f1, f2) = (1.0 - sv, sv);
        a11 += f1 * f1;
        a12 += f1 * f2;
        a22 += f2 * f2;
        b1 += f1 * i;
        b2 += f2 * i;
        ii += i * i;
        sum_i += i;
        count += 1.0;
    }
    let det = a11 * a22 - a12 * a12;
    let (w, dk) = if det.abs() < 1e-12 {
        let mean = sum_i / f64::max(count, 1.0);
        (mean, mean)
    } else {
        ((a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det)
    };
    let c = w * w * a11 + 2.0 * w * dk * a12 + dk * dk * a22 - 2.0 * (w * b1 + dk * b2) + ii;
    (w, dk, c.max(0.0))
}

/// Fits the pattern `runs` to samples `intensity` taken at profile positions `d` (modules).
/// `sigma0` is the starting blur (modules). With `scan`, δ is first searched on a coarse
/// grid over ±[`MAX_SHIFT_MODULES`] (for a start that may be a module fraction off) and
/// refined by a few iterations only; without, the fit starts at δ = 0 and iterates to
/// convergence. `None` when there are too few samples, the fit does not settle, the
/// contrast vanishes, or δ leaves ±[`MAX_SHIFT_MODULES`].
pub(crate) fn fit_profile(
    runs: &[DarkRun],
    d: &[f64],
    intensity: &[f64],
    sigma0: f64,
    scan: bool,
) -> Option<ProfileFit> {
    if runs.is_empty() {
        return None;
    }
    fit_pattern(&Pattern::new(runs)?, (d, intensity), (0.0, sigma0), scan)
}

/// [`fit_profile`] of a built pattern, starting at δ = `delta0`, s = `sigma0`.
fn fit_pattern(
    pattern: &Pattern,
    (d, intensity): (&[f64], &[f64]),
    (delta0, sigma0): (f64, f64),
    scan: bool,
) -> Option<ProfileFit> {
    if d.len() < MIN_SAMPLES || d.len() != intensity.len() {
        return None;
    }
    let table = &*NORMAL_TABLE;
    // Coarse scan of δ with the levels solved exactly, so that LM starts in the right basin.
    let mut best: Option<(f64, Vector4<f64>)> = None;
    // The scan only has to find the basin: every other sample will do, at half the cost.
    let (scan_steps, stride) = if scan { (-3..=3, 2) } else { (0..=0, 1) };
    for k in scan_steps {
        let delta = delta0 + f64::from(k) * SCAN_STEP_MODULES;
        let (w, dk, c) = levels_and_cost(table, pattern, (d, intensity), stride, delta, sigma0);
        let p = Vector4::new(delta, sigma0, w, dk);
        if best.as_ref().is_none_or(|(bc, _)| c < *bc) {
            best = Some((c, p));
        }
    }
    let (_, mut p) = best?;
    // Each trial point is linearised in the same pass that gives its cost, so an accepted
    // step costs one pass over the samples, not two.
    let (mut c, mut jtj, mut jtr) = linearise(table, pattern, d, intensity, &p);
    let mut lambda = 1e-3;
    let iterations = if scan {
        LM_ITERATIONS_AFTER_SCAN
    } else {
        LM_ITERATIONS
    };
    for _ in 0..iterations {
        let mut improved = false;
        for _ in 0..4 {
            let mut a = jtj;
            for k in 0..4 {
                a[(k, k)] *= 1.0 + lambda;
                a[(k, k)] += 1e-12;
            }
            let Some(step) = a.lu().solve(&(-jtr)) else {
                lambda *= 10.0;
                continue;
            };
            let mut q = p + step;
            q[1] = q[1].clamp(0.02, 3.0);
            let (cq, jtj_q, jtr_q) = linearise(table, pattern, d, intensity, &q);
            if cq < c {
                improved = step[0].abs() > MIN_STEP_MODULES;
                (p, c, jtj, jtr) = (q, cq, jtj_q, jtr_q);
                lambda = (lambda * 0.3).max(1e-9);
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    let contrast = (p[2] - p[3]).abs();
    let rms = (c / d.len() as f64).sqrt();
    let spread = intensity.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b))
        - intensity.iter().fold(f64::INFINITY, |a, &b| a.min(b));
    let ok = p.iter().all(|x| x.is_finite())
        && p[0].abs() <= MAX_SHIFT_MODULES
        && contrast > 0.25 * spread
        && contrast > 8.0
        && rms < 0.35 * contrast;
    ok.then_some(ProfileFit {
        delta: p[0],
        sigma: p[1],
        light: p[2],
        dark: p[3],
        rms,
    })
}

#[cfg(test)]
mod tests {
    use super::normal::cdf_exact;
    use super::*;

    /// The finder's outer edge at d = 0: quiet zone, one dark module, one light, three dark.
    fn finder_runs() -> Vec<DarkRun> {
        vec![
            DarkRun {
                start: 0.0,
                end: 1.0,
            },
            DarkRun {
                start: 2.0,
                end: 5.0,
            },
        ]
    }

    #[test]
    fn recovers_the_shift_of_a_blurred_finder_edge_without_bias() {
        let runs = finder_runs();
        for (true_delta, sigma) in [(0.0, 0.7), (0.23, 0.7), (-0.31, 0.35), (0.12, 0.9)] {
            let d: Vec<f64> = (0..40).map(|k| -2.5 + 0.125 * f64::from(k)).collect();
            let intensity: Vec<f64> = d
                .iter()
                .map(|&x| {
                    let s: f64 = runs
                        .iter()
                        .map(|r| {
                            cdf_exact((x - r.start - true_delta) / sigma)
                                - cdf_exact((x - r.end - true_delta) / sigma)
                        })
                        .sum();
                    220.0 + (30.0 - 220.0) * s
                })
                .collect();
            // As the refinement does it: a scanning pass from the rough start, then a full
            // fit around the edge that pass found (the profile recentred there).
            let coarse = fit_profile(&runs, &d, &intensity, 0.5, true).expect("fits");
            assert!(
                (coarse.delta - true_delta).abs() < 0.1,
                "coarse δ {} vs {true_delta} at σ {sigma}",
                coarse.delta
            );
            let recentred: Vec<f64> = d.iter().map(|x| x - coarse.delta).collect();
            let fine =
                fit_profile(&runs, &recentred, &intensity, coarse.sigma, false).expect("fits");
            let delta = coarse.delta + fine.delta;
            assert!(
                (delta - true_delta).abs() < 1e-3,
                "δ {delta} vs {true_delta} at σ {sigma}"
            );
            assert!(
                (fine.sigma - sigma).abs() < 1e-2,
                "σ {} vs {sigma}",
                fine.sigma
            );
        }
    }

    /// A run open to either end of the profile, as the refinement builds them.
    fn open_runs() -> Vec<DarkRun> {
        vec![
            DarkRun {
                start: -1e3,
                end: -1.0,
            },
            DarkRun {
                start: 0.0,
                end: 1.0,
            },
            DarkRun {
                start: 2.0,
                end: 1e3,
            },
        ]
    }

    fn darkness_exact(runs: &[DarkRun], d: f64, delta: f64, s: f64) -> f64 {
        runs.iter()
            .map(|r| cdf_exact((d - r.start - delta) / s) - cdf_exact((d - r.end - delta) / s))
            .sum()
    }

    #[test]
    fn pattern_folds_open_ends_into_constants_and_keeps_the_darkness() {
        let runs = open_runs();
        let pattern = Pattern::new(&runs).expect("few boundaries");
        assert_eq!(pattern.len, 4, "only the finite boundaries are looked up");
        assert_eq!(pattern.base, 1.0, "the run from −∞ contributes Φ(+∞) = 1");
        let table = &*NORMAL_TABLE;
        for k in -25..=25 {
            let d = 0.1 * f64::from(k);
            for (delta, s) in [(0.0, 0.4), (0.3, 0.8), (-0.5, 1.5)] {
                let want = darkness_exact(&runs, d, delta, s);
                let got = pattern.darkness_value(table, d, delta, 1.0 / s);
                assert!((got - want).abs() < 1e-6, "S({d}) = {got} vs {want}");
                let (value, ..) = pattern.darkness(table, d, delta, 1.0 / s);
                assert!((value - got).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn levels_and_cost_match_a_direct_least_squares_fit() {
        let runs = open_runs();
        let pattern = Pattern::new(&runs).expect("few boundaries");
        let table = &*NORMAL_TABLE;
        let d: Vec<f64> = (0..21).map(|k| -2.5 + 0.25 * f64::from(k)).collect();
        let intensity: Vec<f64> = d
            .iter()
            .enumerate()
            .map(|(k, &x)| 200.0 - 150.0 * darkness_exact(&runs, x, 0.1, 0.6) + (k % 3) as f64)
            .collect();
        let (w, dk, cost) = levels_and_cost(table, &pattern, (&d, &intensity), 1, 0.0, 0.5);
        // The same fit by nalgebra's least squares on the columns (1 − S, S).
        let s: Vec<f64> = d
            .iter()
            .map(|&x| darkness_exact(&runs, x, 0.0, 0.5))
            .collect();
        let a =
            nalgebra::DMatrix::from_fn(d.len(), 2, |i, j| if j == 0 { 1.0 - s[i] } else { s[i] });
        let b = nalgebra::DVector::from_column_slice(&intensity);
        let x = a
            .clone()
            .svd(true, true)
            .solve(&b, 1e-12)
            .expect("solvable");
        let direct_cost = (a * &x - b).norm_squared();
        assert!(
            (w - x[0]).abs() < 1e-3 && (dk - x[1]).abs() < 1e-3,
            "{w}, {dk} vs {x}"
        );
        assert!(
            (cost - direct_cost).abs() < 1e-3 * direct_cost.max(1.0),
            "{cost} vs {direct_cost}"
        );
    }

    #[test]
    fn refuses_a_flat_profile() {
        let d: Vec<f64> = (0..20).map(|k| -2.5 + 0.25 * f64::from(k)).collect();
        let flat = vec![128.0; 20];
        assert!(fit_profile(&finder_runs(), &d, &flat, 0.5, true).is_none());
    }
}
