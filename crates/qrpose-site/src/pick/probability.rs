//! The probability that a grasp is within its tolerance: P(|δt| ≤ p ∧ |δθ| ≤ r) for the
//! grasp pose's perturbation (δθ rad, δt mm) ~ N(0, Σ), joint over all six components
//! (rotation and position errors are correlated through the lever arm). |δt| is the tool
//! centre point's distance from its nominal, |δθ| the angle of the rotation error; both are
//! the same in any frame's axes.
//!
//! No closed form exists for a correlated 6-D Gaussian over the intersection of two balls,
//! so the integral is a quasi-Monte Carlo sum over a fixed set of [`SAMPLE_COUNT`] standard
//! normal points (Roberts' R₆ low-discrepancy sequence, Box-Muller in pairs), mapped by a
//! square root of Σ (its eigen-decomposition: a positive semi-definite Σ of any rank works).
//! Deterministic: the same Σ gives the same number on every call. Against plain Monte Carlo
//! with 200 000 draws it agrees within 0.01 (`the_probability_matches_monte_carlo` in
//! tests/pick.rs); a call takes about 0.3 ms in the test build (opt-level 1).

use crate::objects::Tolerance;
use nalgebra::{Matrix6, Vector6};
use std::sync::OnceLock;

/// Points of the quasi-Monte Carlo sum: resolves a probability to about 1/4096.
pub const SAMPLE_COUNT: usize = 4096;

/// An eigenvalue of Σ below −this × its largest is not rounding: Σ is not a covariance.
const NEGATIVE_EIGENVALUE_TOLERANCE: f64 = 1e-9;

/// φ₆, the real root of x⁷ = x + 1 (Roberts' generalised golden ratio in 6-D), by Newton.
fn roberts_phi() -> f64 {
    let mut x = 1.2f64;
    for _ in 0..50 {
        x -= (x.powi(7) - x - 1.0) / (7.0 * x.powi(6) - 1.0);
    }
    x
}

/// The fixed standard normal points (computed once).
fn standard_normal_points() -> &'static [Vector6<f64>] {
    static POINTS: OnceLock<Vec<Vector6<f64>>> = OnceLock::new();
    POINTS.get_or_init(|| {
        let phi = roberts_phi();
        let mut alpha = [0.0; 6];
        let mut power = 1.0;
        for a in &mut alpha {
            power /= phi;
            *a = power.fract();
        }
        (1..=SAMPLE_COUNT)
            .map(|n| {
                let u: [f64; 6] = std::array::from_fn(|i| (0.5 + n as f64 * alpha[i]).fract());
                let mut z = Vector6::zeros();
                for pair in 0..3 {
                    // u in (0, 1): 0.5 + n·α is never an integer for irrational α.
                    let radius = (-2.0 * u[2 * pair].ln()).sqrt();
                    let angle = std::f64::consts::TAU * u[2 * pair + 1];
                    z[2 * pair] = radius * angle.cos();
                    z[2 * pair + 1] = radius * angle.sin();
                }
                z
            })
            .collect()
    })
}

/// A square root S of Σ (S·Sᵀ = Σ), from its eigen-decomposition; `None` when Σ is not
/// finite or has a clearly negative eigenvalue.
fn covariance_root(covariance: &Matrix6<f64>) -> Option<Matrix6<f64>> {
    if !covariance.iter().all(|x| x.is_finite()) {
        return None;
    }
    let symmetric = (covariance + covariance.transpose()) * 0.5;
    let eigen = symmetric.symmetric_eigen();
    let largest = eigen.eigenvalues.amax();
    if eigen
        .eigenvalues
        .iter()
        .any(|&l| l < -NEGATIVE_EIGENVALUE_TOLERANCE * largest)
    {
        return None;
    }
    let roots = eigen.eigenvalues.map(|l| l.max(0.0).sqrt());
    Some(eigen.eigenvectors * Matrix6::from_diagonal(&roots))
}

/// P(|δt| ≤ `tolerance.position_mm` ∧ |δθ| ≤ `tolerance.rotation_rad`) under N(0, Σ), Σ over
/// (δθ rad, δt mm) as in [`crate::transform`]; `None` when Σ is not a covariance (not
/// finite, or not positive semi-definite).
pub fn within_tolerance_probability(
    covariance: &Matrix6<f64>,
    tolerance: &Tolerance,
) -> Option<f64> {
    let s = covariance_root(covariance)?;
    let (r2, p2) = (
        tolerance.rotation_rad * tolerance.rotation_rad,
        tolerance.position_mm * tolerance.position_mm,
    );
    let points = standard_normal_points();
    let inside = points
        .iter()
        .filter(|z| {
            let d = s * *z;
            let rotation2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            let position2 = d[3] * d[3] + d[4] * d[4] + d[5] * d[5];
            rotation2 <= r2 && position2 <= p2
        })
        .count();
    Some(inside as f64 / points.len() as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tolerance(position_mm: f64, rotation_deg: f64) -> Tolerance {
        Tolerance {
            position_mm,
            rotation_rad: rotation_deg.to_radians(),
        }
    }

    #[test]
    fn the_points_are_standard_normal() {
        let points = standard_normal_points();
        let n = points.len() as f64;
        let mean: Vector6<f64> = points.iter().sum::<Vector6<f64>>() / n;
        let second = points
            .iter()
            .map(|z| z * z.transpose())
            .sum::<Matrix6<f64>>()
            / n;
        assert!(mean.amax() < 0.01, "mean {mean}");
        assert!(
            (second - Matrix6::identity()).amax() < 0.03,
            "second moments {second}"
        );
    }

    #[test]
    fn the_limits_are_one_and_zero() {
        let tiny = Matrix6::from_diagonal(&Vector6::new(1e-10, 1e-10, 1e-10, 1e-4, 1e-4, 1e-4));
        let p = within_tolerance_probability(&tiny, &tolerance(5.0, 3.0)).expect("p");
        assert_eq!(p, 1.0);
        let huge = Matrix6::from_diagonal(&Vector6::new(1.0, 1.0, 1.0, 1e4, 1e4, 1e4));
        let p = within_tolerance_probability(&huge, &tolerance(5.0, 3.0)).expect("p");
        assert!(p < 1e-3, "{p}");
    }

    #[test]
    fn a_covariance_that_is_not_one_is_refused() {
        let mut c = Matrix6::identity();
        c[(0, 0)] = -1.0;
        assert_eq!(within_tolerance_probability(&c, &tolerance(5.0, 3.0)), None);
        c[(0, 0)] = f64::NAN;
        assert_eq!(within_tolerance_probability(&c, &tolerance(5.0, 3.0)), None);
    }
}
