//! Robust weighting of outlying points: Huber's loss on each point's residual length e (px),
//!
//! ```text
//! ρ(e) = e² / 2            for e ≤ c
//! ρ(e) = c·(e − c / 2)     for e > c,        weight w(e) = ρ'(e) / e = min(1, c / e)
//! ```
//!
//! minimised by iteratively reweighted least squares inside the Levenberg-Marquardt (each
//! normal-equation build takes w at the current residuals, each step is judged on Σ ρ).
//! The threshold is c = [`HUBER_K`]·σ̂, with σ̂ the robust per-axis noise estimate
//! median(e) / √(2·ln 2) (for isotropic Gaussian noise of σ per axis, e is Rayleigh with
//! median σ·√(2·ln 2)), floored at [`SCALE_FLOOR_PX`]. σ̂ is re-estimated after each
//! Levenberg-Marquardt run until it settles ([`crate::fit`]). Huber's loss is convex, so it
//! cannot lock onto a wrong minimum the way a redescending loss (Cauchy, Tukey) can from
//! the rough closed-form start; a gross outlier keeps a bounded pull of c.

/// Huber's threshold in units of the robust noise estimate σ̂: a point is fully weighted
/// while its residual is within 2.5 σ̂, which exp(−2.5²/2) = 4.4 % of Gaussian inliers
/// exceed (and they are only mildly down-weighted).
pub const HUBER_K: f64 = 2.5;

/// Floor of σ̂, px: below the accuracy of any sub-pixel corner, so it never down-weights
/// real points, but keeps the weights defined on exact synthetic data.
pub const SCALE_FLOOR_PX: f64 = 0.05;

/// Median of a Rayleigh distribution of unit scale, √(2·ln 2).
const RAYLEIGH_MEDIAN: f64 = 1.177_410_022_515_474_7;

/// Huber's loss with threshold `threshold_px`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Huber {
    /// σ̂, px.
    pub sigma_px: f64,
    /// c = [`HUBER_K`]·σ̂, px.
    pub threshold_px: f64,
}

impl Huber {
    /// The loss for robust noise estimate `sigma_px`.
    pub fn for_scale(sigma_px: f64) -> Self {
        Self {
            sigma_px,
            threshold_px: HUBER_K * sigma_px,
        }
    }

    /// ρ(e).
    pub fn rho(&self, e: f64) -> f64 {
        let c = self.threshold_px;
        if e <= c {
            0.5 * e * e
        } else {
            c * (e - 0.5 * c)
        }
    }

    /// w(e) = ρ'(e) / e, in (0, 1].
    pub fn weight(&self, e: f64) -> f64 {
        if e <= self.threshold_px {
            1.0
        } else {
            self.threshold_px / e
        }
    }
}

/// The median of `values` (the mean of the middle two for an even count); `None` when empty.
pub(crate) fn median(values: &[f64]) -> Option<f64> {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => None,
        _ if n % 2 == 1 => Some(v[n / 2]),
        _ => Some(0.5 * (v[n / 2 - 1] + v[n / 2])),
    }
}

/// σ̂ of the module doc from residual lengths, px.
pub(crate) fn robust_sigma_px(residual_lengths_px: &[f64]) -> f64 {
    median(residual_lengths_px)
        .map_or(SCALE_FLOOR_PX, |m| m / RAYLEIGH_MEDIAN)
        .max(SCALE_FLOOR_PX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn huber_is_quadratic_inside_and_linear_outside_with_matching_weights() {
        let h = Huber::for_scale(0.4);
        assert!((h.threshold_px - 1.0).abs() < 1e-15);
        assert_eq!(h.rho(0.5), 0.125);
        assert_eq!(h.rho(3.0), 2.5);
        assert_eq!(h.weight(0.9), 1.0);
        assert_eq!(h.weight(4.0), 0.25);
        // w = ρ'(e)/e: ρ'(3) = c = 1.
        assert!((h.weight(3.0) * 3.0 - 1.0).abs() < 1e-15);
    }

    #[test]
    fn the_scale_of_rayleigh_lengths_is_their_per_axis_sigma() {
        // Lengths at the Rayleigh quantiles of σ = 0.3: their median is σ·√(2 ln 2).
        let lengths: Vec<f64> = (1..1000)
            .map(|i| {
                let p = f64::from(i) / 1000.0;
                0.3 * (-2.0 * (1.0 - p).ln()).sqrt()
            })
            .collect();
        assert!((robust_sigma_px(&lengths) - 0.3).abs() < 1e-3);
        assert_eq!(robust_sigma_px(&[0.0; 5]), SCALE_FLOOR_PX);
        assert_eq!(median(&[3.0, 1.0, 2.0, 10.0]), Some(2.5));
    }
}
