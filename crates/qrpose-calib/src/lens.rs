//! Analytic derivatives of qrpose-core's three lens models, for the Levenberg-Marquardt
//! Jacobian: ∂(x_d, y_d)/∂(x, y) and ∂(x_d, y_d)/∂(coefficients), in OpenCV's coefficient
//! order. The distorted point itself always comes from qrpose-core's
//! [`Distortion::distort`], so the fitted model is exactly the one the pose service applies;
//! only its derivatives are written out here, from the formulas of
//! `qrpose_core::geometry::distortion` (`docs/calibration.md`, Lens models), and checked
//! against central differences of `distort` in this module's tests.
//!
//! - `plumb_bob`, `rational_polynomial`, with r² = x² + y², n = 1 + k1·r² + k2·r⁴ + k3·r⁶,
//!   m = 1 + k4·r² + k5·r⁴ + k6·r⁶ (m = 1 for plumb_bob):
//!   x_d = x·n/m + 2·p1·x·y + p2·(r² + 2x²), y_d = y·n/m + p1·(r² + 2y²) + 2·p2·x·y.
//! - `equidistant`, with r = √(x² + y²), θ = atan r,
//!   θ_d = θ·(1 + k1·θ² + k2·θ⁴ + k3·θ⁶ + k4·θ⁸): (x_d, y_d) = (θ_d / r)·(x, y), and the
//!   identity for r ≤ 1e-8 (qrpose-core's and OpenCV's threshold).

use nalgebra::{Matrix2, SMatrix};
use qrpose_core::geometry::camera::{Distortion, Equidistant, PlumbBob, RationalPolynomial};

/// Most coefficients a model has (`rational_polynomial`).
pub(crate) const MAX_COEFFICIENTS: usize = 8;

/// Below this radius the fisheye model is the identity (qrpose-core's `R_MIN`).
const FISHEYE_R_MIN: f64 = 1e-8;

/// The derivatives of the distortion at one ideal normalised point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LensJacobian {
    /// ∂(x_d, y_d)/∂(x, y).
    pub d_point: Matrix2<f64>,
    /// ∂(x_d, y_d)/∂(coefficients), OpenCV's order; columns past the model's count are 0.
    pub d_coefficients: SMatrix<f64, 2, MAX_COEFFICIENTS>,
}

/// The derivatives of `lens` at the ideal normalised point (x, y).
pub(crate) fn lens_jacobian(lens: &Distortion, x: f64, y: f64) -> LensJacobian {
    match lens {
        Distortion::PlumbBob(PlumbBob { k1, k2, p1, p2, k3 }) => {
            let rational = RationalPolynomial {
                k1: *k1,
                k2: *k2,
                p1: *p1,
                p2: *p2,
                k3: *k3,
                ..RationalPolynomial::NONE
            };
            // plumb_bob's five coefficients are the rational model's first five, in order.
            let mut j = rational_jacobian(&rational, x, y);
            j.d_coefficients.columns_mut(5, 3).fill(0.0);
            j
        }
        Distortion::RationalPolynomial(d) => rational_jacobian(d, x, y),
        Distortion::Equidistant(d) => equidistant_jacobian(d, x, y),
    }
}

fn rational_jacobian(d: &RationalPolynomial, x: f64, y: f64) -> LensJacobian {
    let RationalPolynomial {
        k1,
        k2,
        p1,
        p2,
        k3,
        k4,
        k5,
        k6,
    } = *d;
    let r2 = x * x + y * y;
    let (r4, r6) = (r2 * r2, r2 * r2 * r2);
    let n = 1.0 + k1 * r2 + k2 * r4 + k3 * r6;
    let m = 1.0 + k4 * r2 + k5 * r4 + k6 * r6;
    let radial = n / m;
    // ∂radial/∂(r²), the quotient rule.
    let dn = k1 + 2.0 * k2 * r2 + 3.0 * k3 * r4;
    let dm = k4 + 2.0 * k5 * r2 + 3.0 * k6 * r4;
    let dradial = (dn * m - n * dm) / (m * m);
    #[rustfmt::skip]
    let d_point = Matrix2::new(
        radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x,
        2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y,
        2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y,
        radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x,
    );
    // ∂radial/∂k: r^(2i)/m for the numerator, −n·r^(2i)/m² for the denominator.
    let num = [r2 / m, r4 / m, r6 / m];
    let den = [r2, r4, r6].map(|p| -n * p / (m * m));
    #[rustfmt::skip]
    let d_coefficients = SMatrix::<f64, 2, MAX_COEFFICIENTS>::from_row_slice(&[
        // k1        k2          p1                 p2                 k3          k4          k5          k6
        x * num[0], x * num[1], 2.0 * x * y,       r2 + 2.0 * x * x,  x * num[2], x * den[0], x * den[1], x * den[2],
        y * num[0], y * num[1], r2 + 2.0 * y * y,  2.0 * x * y,       y * num[2], y * den[0], y * den[1], y * den[2],
    ]);
    LensJacobian {
        d_point,
        d_coefficients,
    }
}

fn equidistant_jacobian(d: &Equidistant, x: f64, y: f64) -> LensJacobian {
    let r = x.hypot(y);
    let mut d_coefficients = SMatrix::<f64, 2, MAX_COEFFICIENTS>::zeros();
    if r <= FISHEYE_R_MIN {
        return LensJacobian {
            d_point: Matrix2::identity(),
            d_coefficients,
        };
    }
    let Equidistant { k1, k2, k3, k4 } = *d;
    let theta = r.atan();
    let t2 = theta * theta;
    let theta_d = theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))));
    let slope = 1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)));
    // s = θ_d / r; ds/dr = (θ_d'·dθ/dr − s) / r with dθ/dr = 1 / (1 + r²).
    let s = theta_d / r;
    let ds_dr = (slope / (1.0 + r * r) - s) / r;
    let (cx, cy) = (x / r, y / r);
    #[rustfmt::skip]
    let d_point = Matrix2::new(
        s + x * ds_dr * cx, x * ds_dr * cy,
        y * ds_dr * cx,     s + y * ds_dr * cy,
    );
    // ∂θ_d/∂k_i = θ^(2i+1), along the point's own direction.
    let mut power = theta;
    for i in 0..4 {
        power *= t2;
        d_coefficients[(0, i)] = cx * power;
        d_coefficients[(1, i)] = cy * power;
    }
    LensJacobian {
        d_point,
        d_coefficients,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use qrpose_core::geometry::camera::DistortionModel;
    use qrpose_core::geometry::frames::NormalizedPoint;

    fn lenses() -> Vec<Distortion> {
        let make = |model, c: &[f64]| Distortion::from_coefficients(model, c).expect("valid");
        vec![
            make(
                DistortionModel::PlumbBob,
                &[-0.25, 0.08, 1e-3, -5e-4, -0.01],
            ),
            make(
                DistortionModel::RationalPolynomial,
                &[1.57, -0.32, 4e-4, -3e-4, -0.012, 1.92, 0.073, -0.042],
            ),
            make(
                DistortionModel::Equidistant,
                &[-0.0139, 0.0047, -0.0051, 0.0012],
            ),
        ]
    }

    fn distorted(lens: &Distortion, x: f64, y: f64) -> [f64; 2] {
        let p = lens.distort(&NormalizedPoint::new(x, y));
        [p.x(), p.y()]
    }

    /// Every derivative against central differences of qrpose-core's own `distort`.
    #[test]
    fn derivatives_match_central_differences_of_the_core_models() {
        let h = 1e-6;
        for lens in lenses() {
            let model = lens.model();
            let coefficients = lens.coefficients();
            for (x, y) in [(0.3, -0.2), (-0.6, 0.35), (0.02, 0.7), (1e-3, -2e-3)] {
                let j = lens_jacobian(&lens, x, y);
                for axis in 0..2 {
                    let (dx, dy) = if axis == 0 { (h, 0.0) } else { (0.0, h) };
                    let plus = distorted(&lens, x + dx, y + dy);
                    let minus = distorted(&lens, x - dx, y - dy);
                    for row in 0..2 {
                        let numeric = (plus[row] - minus[row]) / (2.0 * h);
                        let analytic = j.d_point[(row, axis)];
                        assert!(
                            (numeric - analytic).abs() < 1e-7,
                            "{model} at ({x}, {y}): d{row}/d{axis} {analytic} vs {numeric}"
                        );
                    }
                }
                for c in 0..coefficients.len() {
                    let shifted = |delta: f64| {
                        let mut k = coefficients.clone();
                        k[c] += delta;
                        let lens = Distortion::from_coefficients(model, &k).expect("valid");
                        distorted(&lens, x, y)
                    };
                    let (plus, minus) = (shifted(h), shifted(-h));
                    for row in 0..2 {
                        let numeric = (plus[row] - minus[row]) / (2.0 * h);
                        let analytic = j.d_coefficients[(row, c)];
                        assert!(
                            (numeric - analytic).abs() < 1e-7,
                            "{model} at ({x}, {y}): d{row}/dk[{c}] {analytic} vs {numeric}"
                        );
                    }
                }
                let unused = j
                    .d_coefficients
                    .columns(coefficients.len(), 8 - coefficients.len());
                assert!(unused.iter().all(|v| *v == 0.0), "{model}");
            }
        }
    }
}
