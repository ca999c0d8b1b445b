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

use nalgebra::{Matrix4, Vector4};

/// One dark run of the pattern, [start, end) in modules along the profile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DarkRun {
    /// Start, modules.
    pub start: f64,
    /// End, modules.
    pub end: f64,
}

/// A fitted profile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProfileFit {
    /// Shift of the pattern, modules (the edge lies at d = δ).
    pub delta: f64,
    /// Blur σ, modules.
    pub sigma: f64,
    /// Light level, grey values.
    pub light: f64,
    /// Dark level, grey values.
    pub dark: f64,
    /// RMS residual, grey values.
    pub rms: f64,
}

/// Largest accepted |δ|, modules: beyond it the fit has locked on to another edge.
pub const MAX_SHIFT_MODULES: f64 = 0.75;
/// Fewest profile samples worth fitting.
pub const MIN_SAMPLES: usize = 8;
const LM_ITERATIONS: usize = 8;

/// erf, Abramowitz & Stegun 7.1.26 (|error| < 1.5e-7).
fn erf(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
    let y = 1.0
        - (((((1.061_405_429 * t - 1.453_152_027) * t) + 1.421_413_741) * t - 0.284_496_736) * t
            + 0.254_829_592)
            * t
            * (-x * x).exp();
    if x >= 0.0 { y } else { -y }
}

fn cdf(z: f64) -> f64 {
    0.5 * (1.0 + erf(z / std::f64::consts::SQRT_2))
}

fn pdf(z: f64) -> f64 {
    (-0.5 * z * z).exp() / (2.0 * std::f64::consts::PI).sqrt()
}

/// Darkness S(d) of the blurred pattern and its derivatives by δ and s.
fn darkness(runs: &[DarkRun], d: f64, delta: f64, s: f64) -> (f64, f64, f64) {
    let (mut value, mut d_delta, mut d_s) = (0.0, 0.0, 0.0);
    for run in runs {
        let za = (d - run.start - delta) / s;
        let zb = (d - run.end - delta) / s;
        value += cdf(za) - cdf(zb);
        d_delta += (-pdf(za) + pdf(zb)) / s;
        d_s += (-pdf(za) * za + pdf(zb) * zb) / s;
    }
    (value, d_delta, d_s)
}

fn cost(runs: &[DarkRun], d: &[f64], intensity: &[f64], p: &Vector4<f64>) -> f64 {
    d.iter()
        .zip(intensity)
        .map(|(&x, &i)| {
            let (s, _, _) = darkness(runs, x, p[0], p[1]);
            let m = p[2] + (p[3] - p[2]) * s;
            (m - i) * (m - i)
        })
        .sum()
}

/// Light and dark levels by linear least squares for fixed δ and s.
fn levels(runs: &[DarkRun], d: &[f64], intensity: &[f64], delta: f64, s: f64) -> (f64, f64) {
    // M = W (1 − S) + D S
    let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (&x, &i) in d.iter().zip(intensity) {
        let (sv, _, _) = darkness(runs, x, delta, s);
        let (f1, f2) = (1.0 - sv, sv);
        a11 += f1 * f1;
        a12 += f1 * f2;
        a22 += f2 * f2;
        b1 += f1 * i;
        b2 += f2 * i;
    }
    let det = a11 * a22 - a12 * a12;
    if det.abs() < 1e-12 {
        let mean = intensity.iter().sum::<f64>() / intensity.len().max(1) as f64;
        return (mean, mean);
    }
    ((a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det)
}

/// Fits the pattern `runs` to samples `intensity` taken at profile positions `d` (modules).
/// `sigma0` is the starting blur (modules). `None` when there are too few samples, the fit
/// does not settle, the contrast vanishes, or δ leaves ±[`MAX_SHIFT_MODULES`].
pub fn fit_profile(
    runs: &[DarkRun],
    d: &[f64],
    intensity: &[f64],
    sigma0: f64,
) -> Option<ProfileFit> {
    if d.len() < MIN_SAMPLES || d.len() != intensity.len() || runs.is_empty() {
        return None;
    }
    // Coarse scan of δ with the levels solved exactly, so that LM starts in the right basin.
    let mut best: Option<(f64, Vector4<f64>)> = None;
    for k in -3..=3 {
        let delta = f64::from(k) * 0.25;
        let (w, dk) = levels(runs, d, intensity, delta, sigma0);
        let p = Vector4::new(delta, sigma0, w, dk);
        let c = cost(runs, d, intensity, &p);
        if best.as_ref().is_none_or(|(bc, _)| c < *bc) {
            best = Some((c, p));
        }
    }
    let (mut c, mut p) = best?;
    let mut lambda = 1e-3;
    for _ in 0..LM_ITERATIONS {
        let mut jtj = Matrix4::<f64>::zeros();
        let mut jtr = Vector4::<f64>::zeros();
        for (&x, &i) in d.iter().zip(intensity) {
            let (sv, ds_delta, ds_s) = darkness(runs, x, p[0], p[1]);
            let contrast = p[3] - p[2];
            let r = p[2] + contrast * sv - i;
            let j = Vector4::new(contrast * ds_delta, contrast * ds_s, 1.0 - sv, sv);
            jtj += j * j.transpose();
            jtr += j * r;
        }
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
            let cq = cost(runs, d, intensity, &q);
            if cq < c {
                improved = step[0].abs() > 1e-5;
                p = q;
                c = cq;
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
                    let (s, _, _) = darkness(&runs, x, true_delta, sigma);
                    220.0 + (30.0 - 220.0) * s
                })
                .collect();
            let fit = fit_profile(&runs, &d, &intensity, 0.5).expect("fits");
            assert!(
                (fit.delta - true_delta).abs() < 1e-3,
                "δ {} vs {true_delta} at σ {sigma}",
                fit.delta
            );
            assert!(
                (fit.sigma - sigma).abs() < 1e-2,
                "σ {} vs {sigma}",
                fit.sigma
            );
        }
    }

    #[test]
    fn refuses_a_flat_profile() {
        let d: Vec<f64> = (0..20).map(|k| -2.5 + 0.25 * f64::from(k)).collect();
        let flat = vec![128.0; 20];
        assert!(fit_profile(&finder_runs(), &d, &flat, 0.5).is_none());
    }

    #[test]
    fn erf_matches_known_values() {
        assert!((erf(0.5) - 0.520_499_877_8).abs() < 2e-7);
        assert!((erf(-1.5) + 0.966_105_146_5).abs() < 2e-7);
    }
}
