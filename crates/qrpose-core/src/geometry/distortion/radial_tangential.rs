//! The two radial-tangential models of OpenCV (`cv::projectPoints`, `docs/calibration.md`):
//! `plumb_bob` ([`PlumbBob`]) and `rational_polynomial` ([`RationalPolynomial`]). With
//! r² = x² + y², an ideal normalised point (x, y) goes to
//!
//! ```text
//! radial = (1 + k1·r² + k2·r⁴ + k3·r⁶) / (1 + k4·r² + k5·r⁴ + k6·r⁶)        (1)
//! x_d = x·radial + 2·p1·x·y + p2·(r² + 2·x²)                                 (2)
//! y_d = y·radial + p1·(r² + 2·y²) + 2·p2·x·y                                 (3)
//! ```
//!
//! `plumb_bob` is (1)-(3) with k4 = k5 = k6 = 0, so its denominator is exactly 1 and it
//! gives the same bits as the plain polynomial. The inverse is Newton's method on (2)-(3)
//! with their 2 × 2 Jacobian, started at the distorted point.

use super::{UNDISTORT_MAX_ITERATIONS, UNDISTORT_TOL};

/// Brown-Conrady lens distortion, OpenCV's 5 coefficients and meaning (`plumb_bob`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlumbBob {
    /// Radial, r² term.
    pub k1: f64,
    /// Radial, r⁴ term.
    pub k2: f64,
    /// Tangential.
    pub p1: f64,
    /// Tangential.
    pub p2: f64,
    /// Radial, r⁶ term.
    pub k3: f64,
}

/// OpenCV's rational model, 8 coefficients in OpenCV's order (`rational_polynomial`):
/// k1 k2 k3 over the numerator of the radial factor, k4 k5 k6 over its denominator.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RationalPolynomial {
    /// Radial numerator, r² term.
    pub k1: f64,
    /// Radial numerator, r⁴ term.
    pub k2: f64,
    /// Tangential.
    pub p1: f64,
    /// Tangential.
    pub p2: f64,
    /// Radial numerator, r⁶ term.
    pub k3: f64,
    /// Radial denominator, r² term.
    pub k4: f64,
    /// Radial denominator, r⁴ term.
    pub k5: f64,
    /// Radial denominator, r⁶ term.
    pub k6: f64,
}

/// A distorted normalised point and the Jacobian of the distortion there.
struct DistortedWithJacobian {
    xd: f64,
    yd: f64,
    /// ∂(x_d, y_d)/∂(x, y), row-major.
    j: [[f64; 2]; 2],
}

impl PlumbBob {
    /// No distortion.
    pub const NONE: Self = Self {
        k1: 0.0,
        k2: 0.0,
        p1: 0.0,
        p2: 0.0,
        k3: 0.0,
    };

    /// The same lens as a rational model with a denominator of 1.
    const fn as_rational(&self) -> RationalPolynomial {
        RationalPolynomial {
            k1: self.k1,
            k2: self.k2,
            p1: self.p1,
            p2: self.p2,
            k3: self.k3,
            k4: 0.0,
            k5: 0.0,
            k6: 0.0,
        }
    }

    /// Eqs. (1)-(3) with k4 = k5 = k6 = 0: ideal (x, y) to distorted, normalised units.
    pub(super) fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        self.as_rational().distort(x, y)
    }

    /// The inverse of [`PlumbBob::distort`]; `None` as [`super::Distortion::undistort`].
    pub(super) fn undistort(&self, xd: f64, yd: f64) -> Option<(f64, f64)> {
        self.as_rational().undistort(xd, yd)
    }
}

impl RationalPolynomial {
    /// No distortion.
    pub const NONE: Self = Self {
        k1: 0.0,
        k2: 0.0,
        p1: 0.0,
        p2: 0.0,
        k3: 0.0,
        k4: 0.0,
        k5: 0.0,
        k6: 0.0,
    };

    /// Eqs. (1)-(3): ideal (x, y) to distorted, normalised units.
    pub(super) fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let d = self.distort_with_jacobian(x, y);
        (d.xd, d.yd)
    }

    /// Eqs. (1)-(3) and their Jacobian.
    fn distort_with_jacobian(&self, x: f64, y: f64) -> DistortedWithJacobian {
        let Self {
            k1,
            k2,
            p1,
            p2,
            k3,
            k4,
            k5,
            k6,
        } = *self;
        let r2 = x * x + y * y;
        // Eq. (1): numerator n, denominator m, and their derivatives in r².
        let n = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        let m = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6));
        let dn = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3);
        let dm = k4 + r2 * (2.0 * k5 + 3.0 * r2 * k6);
        let radial = n / m;
        // ∂radial/∂(r²), the quotient rule.
        let dradial = (dn * m - n * dm) / (m * m);
        // Eqs. (2), (3).
        let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        let j = [
            [
                radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x,
                2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y,
            ],
            [
                2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y,
                radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x,
            ],
        ];
        DistortedWithJacobian { xd, yd, j }
    }

    /// The inverse of eqs. (1)-(3) by Newton's method from the distorted point, one step past
    /// [`UNDISTORT_TOL`] (so exact to rounding, which the pose of a small, distant marker
    /// needs: its tilt amplifies a ray's error about (distance / size)² times); `None` as
    /// [`super::Distortion::undistort`] (no convergence, or a Jacobian that is not positive,
    /// i.e. the model folds over, at an iterate).
    pub(super) fn undistort(&self, xd: f64, yd: f64) -> Option<(f64, f64)> {
        let (mut x, mut y) = (xd, yd);
        for _ in 0..UNDISTORT_MAX_ITERATIONS {
            let d = self.distort_with_jacobian(x, y);
            let (ex, ey) = (d.xd - xd, d.yd - yd);
            let det = d.j[0][0] * d.j[1][1] - d.j[0][1] * d.j[1][0];
            if !det.is_finite() || det <= 0.0 {
                return None;
            }
            x -= (d.j[1][1] * ex - d.j[0][1] * ey) / det;
            y -= (-d.j[1][0] * ex + d.j[0][0] * ey) / det;
            // Within tolerance the step just taken is quadratically small: its result is
            // exact to rounding, where the iterate before it was only within 1e-12.
            if ex.abs().max(ey.abs()) <= UNDISTORT_TOL {
                return Some((x, y));
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wide_angle() -> RationalPolynomial {
        RationalPolynomial {
            k1: 1.57,
            k2: -0.32,
            p1: 4e-4,
            p2: -3e-4,
            k3: -0.012,
            k4: 1.92,
            k5: 0.073,
            k6: -0.042,
        }
    }

    /// The Jacobian against central differences, so that Newton's method gets the true
    /// derivative.
    #[test]
    fn jacobian_matches_central_differences() {
        let d = wide_angle();
        let h = 1e-6;
        for (x, y) in [(0.3, -0.2), (-0.7, 0.4), (0.05, 0.9)] {
            let j = d.distort_with_jacobian(x, y).j;
            let (xp, yp) = d.distort(x + h, y);
            let (xm, ym) = d.distort(x - h, y);
            let (xq, yq) = d.distort(x, y + h);
            let (xn, yn) = d.distort(x, y - h);
            let numeric = [
                [(xp - xm) / (2.0 * h), (xq - xn) / (2.0 * h)],
                [(yp - ym) / (2.0 * h), (yq - yn) / (2.0 * h)],
            ];
            for (row, want) in j.iter().zip(numeric) {
                for (a, b) in row.iter().zip(want) {
                    assert!((a - b).abs() < 1e-8, "({x}, {y}): {a} vs {b}");
                }
            }
        }
    }

    #[test]
    fn plumb_bob_is_the_rational_model_with_a_unit_denominator_to_the_bit() {
        let p = PlumbBob {
            k1: -0.28,
            k2: 0.09,
            p1: 0.0012,
            p2: -0.0009,
            k3: -0.012,
        };
        let (x, y) = (0.3, -0.2);
        let r2: f64 = x * x + y * y;
        let radial = 1.0 + r2 * (p.k1 + r2 * (p.k2 + r2 * p.k3));
        let xd = x * radial + 2.0 * p.p1 * x * y + p.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + p.p1 * (r2 + 2.0 * y * y) + 2.0 * p.p2 * x * y;
        assert_eq!(p.distort(x, y), (xd, yd));
    }
}
