//! Three motion models per hypothesis, interacting: **at rest** (the code does not move in
//! the camera: velocities held at zero, the pose a slow random walk), **steady** (a constant
//! velocity: small process noise) and **manoeuvring** (large), each a constant-velocity
//! filter ([`crate::filter`]), combined by the interacting multiple model (IMM) estimator (H. A. P. Blom and
//! Y. Bar-Shalom, "The interacting multiple model algorithm for systems with Markovian
//! switching coefficients", IEEE TAC 33(8), 1988; Bar-Shalom, Li and Kirubarajan 2001,
//! §11.6.6). A single process noise cannot both smooth a code at rest (which wants it
//! small) and follow one whose motion changes (which wants it large); the IMM weighs the
//! models by how well each predicts the corners. The at-rest model is the one a robot
//! stopped at a shelf needs: a constant-velocity model, however small its noise, lets its
//! velocity wander with the noise of a near code's corners (whose pose noise is a few
//! hundredths of a millimetre), and the wandering velocity carries the pose with it.
//!
//! The at-rest model is the constant-velocity filter whose velocity and angular velocity
//! (and their covariance) are reset to zero before each prediction, so the pose moves only
//! by the process noise fed through one step's velocity (q·dt³/3 per axis).
//!
//! Per frame, with mode probabilities μ and a switch probability s = 1 − exp(−dt/τ)
//! (τ = `mode_hold_ms`), the models in a chain at rest ↔ steady ↔ manoeuvring (a code
//! starts and stops moving through the steady model: a direct switch between rest and a
//! manoeuvre left the manoeuvring model's covariance free to grow while the track coasted,
//! until it passed an outlier): π_ii = 1 − s; from steady, s/2 to each other; from at rest
//! or manoeuvring, s to steady:
//!
//! ```text
//! mixing      c_j = Σ_i π_ij μ_i,  μ_i|j = π_ij μ_i / c_j,
//!             x⁰_j = x_j ⊞ Σ_i μ_i|j (x_i ⊟ x_j),  P⁰_j = Σ_i μ_i|j (P_i + d_ij d_ijᵀ)
//! prediction  each mode with its own Q
//! update      each mode by the iterated update: Λ_j = exp(−½(J_j + ln det S_j))
//!             μ_j ← Λ_j c_j / Σ_k Λ_k c_k;  the frame's likelihood Σ_j Λ_j c_j
//! output      x = x_m ⊞ Σ_j μ_j (x_j ⊟ x_m) (m the most probable mode),
//!             P = Σ_j μ_j (P_j + d_j d_jᵀ)
//! ```

use crate::filter::{Eskf, ProcessNoise};
use crate::measurement::Corners;
use nalgebra::{Rotation3, SMatrix, Vector3};
use qrpose_core::geometry::marker::Marker;

/// The three modes: [`AT_REST`], [`STEADY`], [`MANOEUVRING`].
pub(crate) const MODES: usize = 3;
/// The at-rest mode's index (velocities held at zero).
pub(crate) const AT_REST: usize = 0;
/// The steady mode's index (constant velocity, small process noise).
pub(crate) const STEADY: usize = 1;
/// The manoeuvring mode's index (constant velocity, large process noise).
pub(crate) const MANOEUVRING: usize = 2;

/// Two mode-conditioned filters and their probabilities.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Imm {
    pub modes: [Eskf; MODES],
    pub probs: [f64; MODES],
}

/// The result of an update.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ImmPosterior {
    pub imm: Imm,
    /// The least J over the modes (χ²(8) when consistent).
    pub cost: f64,
    /// ln of the frame's likelihood, Σ_j Λ_j c_j (up to the common constant).
    pub log_likelihood: f64,
}

/// Weighted mean ⊞ and spread of filters about the one at `reference`.
fn moment_match(filters: &[&Eskf], weights: &[f64], reference: usize) -> Eskf {
    let base = filters[reference];
    let diffs: Vec<SMatrix<f64, 12, 1>> = filters.iter().map(|f| f.minus(base)).collect();
    let mean: SMatrix<f64, 12, 1> = diffs.iter().zip(weights).map(|(d, w)| d * *w).sum();
    let mut out = base.plus(&mean);
    let mut p = SMatrix::<f64, 12, 12>::zeros();
    for ((f, d), w) in filters.iter().zip(&diffs).zip(weights) {
        let e = d - mean;
        p += (f.covariance + e * e.transpose()) * *w;
    }
    out.covariance = (p + p.transpose()) * 0.5;
    out
}

fn argmax(p: &[f64; MODES]) -> usize {
    let mut best = 0;
    for (i, x) in p.iter().enumerate() {
        if *x > p[best] {
            best = i;
        }
    }
    best
}

impl Imm {
    /// Every mode at one filter, equally probable.
    pub fn new(filter: Eskf) -> Self {
        Self {
            modes: [filter.clone(), filter.clone(), filter],
            probs: [1.0 / MODES as f64; MODES],
        }
    }

    /// The combined estimate (module docs).
    pub fn combined(&self) -> Eskf {
        let filters: Vec<&Eskf> = self.modes.iter().collect();
        moment_match(&filters, &self.probs, argmax(&self.probs))
    }

    /// Mixing, then each mode predicted `dt_s` ahead with its noise; nothing for dt ≤ 0.
    pub fn predict(&mut self, dt_s: f64, noises: &[ProcessNoise; MODES], hold_s: f64) {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return;
        }
        let s = 1.0 - (-dt_s / hold_s).exp();
        let pi = |i: usize, j: usize| match (i, j) {
            _ if i == j => 1.0 - s,
            (STEADY, _) => s / 2.0,
            (_, STEADY) => s,
            _ => 0.0,
        };
        let filters: Vec<&Eskf> = self.modes.iter().collect();
        let mut mixed = self.modes.clone();
        let mut c = [0.0; MODES];
        for j in 0..MODES {
            c[j] = (0..MODES).map(|i| pi(i, j) * self.probs[i]).sum();
            let w: Vec<f64> = (0..MODES)
                .map(|i| pi(i, j) * self.probs[i] / c[j].max(f64::MIN_POSITIVE))
                .collect();
            mixed[j] = moment_match(&filters, &w, j);
        }
        mixed[AT_REST].hold_still();
        for j in 0..MODES {
            self.modes[j] = mixed[j].predicted(dt_s, &noises[j]);
        }
        self.probs = c;
    }

    /// Each mode updated with the corners from `start` (module docs); `None` when no mode
    /// could be updated.
    pub fn update(
        &self,
        corners: &Corners,
        marker: &Marker,
        inflation: f64,
        start: Option<(&Rotation3<f64>, &Vector3<f64>)>,
    ) -> Option<ImmPosterior> {
        let mut modes = self.modes.clone();
        let mut log_terms = [f64::NEG_INFINITY; MODES];
        let mut cost = f64::INFINITY;
        for j in 0..MODES {
            if let Some(post) = self.modes[j].iterated_update(corners, marker, inflation, start) {
                log_terms[j] = self.probs[j].max(1e-300).ln() - 0.5 * (post.cost + post.ln_det_s);
                cost = cost.min(post.cost);
                modes[j] = post.filter;
            }
        }
        let max = log_terms.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if !max.is_finite() {
            return None;
        }
        let total: f64 = log_terms.iter().map(|l| (l - max).exp()).sum();
        let mut probs = [0.0; MODES];
        for j in 0..MODES {
            probs[j] = (log_terms[j] - max).exp() / total;
        }
        Some(ImmPosterior {
            imm: Self { modes, probs },
            cost,
            log_likelihood: max + total.ln(),
        })
    }

    /// Whether every number is finite.
    pub fn is_finite(&self) -> bool {
        self.modes.iter().all(Eskf::is_finite) && self.probs.iter().all(|p| p.is_finite())
    }
}
