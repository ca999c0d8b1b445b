//! OpenCV's fisheye model (`equidistant`, `cv::fisheye::projectPoints`,
//! `docs/calibration.md`). It distorts the angle θ between a ray and the optical axis. For
//! an ideal normalised point (x, y) = (X/Z, Y/Z), r = √(x² + y²):
//!
//! ```text
//! θ   = atan(r)                                                     (1)
//! θ_d = θ·(1 + k1·θ² + k2·θ⁴ + k3·θ⁶ + k4·θ⁸)                         (2)
//! (x_d, y_d) = (θ_d / r)·(x, y)          ((x, y) itself when r ≤ R_MIN)   (3)
//! ```
//!
//! so the distorted point lies on the same half-line from the centre as the ideal one, at
//! distance θ_d. The inverse solves (2) for θ by Newton's method, bracketed within the
//! first rising branch of (2) (from the axis to where dθ_d/dθ first falls to 0, or to 90°),
//! and returns tan θ along the same half-line. Rays 90° or more from the axis have no point
//! on Z = 1, and points past a fold have no unique ray: both are refused.

use super::{UNDISTORT_MAX_ITERATIONS, UNDISTORT_TOL};
use std::f64::consts::FRAC_PI_2;

/// Below this radius (normalised units) the model is the identity, as in OpenCV's
/// `fisheye::projectPoints` (its 1e-8 threshold), where θ_d / r → 1.
const R_MIN: f64 = 1e-8;

/// Grid steps over [0, 90°] (1.4° each) on which [`Equidistant::branch_end`] looks for
/// the first fold, for lenses whose slope bound does not rule one out. dθ_d/dθ is a quartic
/// in θ²: a dip below 0 narrower than a step would take coefficients far beyond a lens's.
const BRANCH_SCAN_STEPS: u32 = 64;

/// Bisections that place the fold within 90°/64/2⁴⁰ once the scan has found it.
const BRANCH_BISECTIONS: usize = 40;

/// OpenCV's fisheye model: k1 k2 k3 k4 on the angle from the optical axis, radians.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Equidistant {
    /// θ³ term.
    pub k1: f64,
    /// θ⁵ term.
    pub k2: f64,
    /// θ⁷ term.
    pub k3: f64,
    /// θ⁹ term.
    pub k4: f64,
}

impl Equidistant {
    /// Eq. (2): the distorted angle θ_d of the angle θ, and dθ_d/dθ, radians.
    fn theta_d_with_derivative(&self, theta: f64) -> (f64, f64) {
        let Self { k1, k2, k3, k4 } = *self;
        let t2 = theta * theta;
        let theta_d = theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))));
        let slope = 1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)));
        (theta_d, slope)
    }

    /// Eqs. (1)-(3): ideal (x, y) to distorted, normalised units.
    pub(super) fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r = x.hypot(y);
        if r <= R_MIN {
            return (x, y);
        }
        let (theta_d, _) = self.theta_d_with_derivative(r.atan());
        let scale = theta_d / r;
        (x * scale, y * scale)
    }

    /// A lower bound of dθ_d/dθ over [0, 90°]: 1 minus every term of it that can be
    /// negative, each at 90°. Positive for mild lenses, which then skip the scan of
    /// [`Self::branch_end`].
    fn slope_lower_bound(&self) -> f64 {
        let s_max = FRAC_PI_2 * FRAC_PI_2;
        let terms = [3.0 * self.k1, 5.0 * self.k2, 7.0 * self.k3, 9.0 * self.k4];
        let (bound, _) = terms.iter().fold((1.0, 1.0), |(bound, power), c| {
            let power = power * s_max;
            (bound + c.min(0.0) * power, power)
        });
        bound
    }

    /// The end of eq. (2)'s first rising branch: the smallest θ in (0, 90°] where
    /// dθ_d/dθ falls to 0, or 90°. Below it θ ↦ θ_d is one-to-one.
    fn branch_end(&self) -> f64 {
        if self.slope_lower_bound() > 0.0 {
            return FRAC_PI_2;
        }
        let step = FRAC_PI_2 / f64::from(BRANCH_SCAN_STEPS);
        let falls = |theta: f64| self.theta_d_with_derivative(theta).1 <= 0.0;
        let Some(i) = (1..=BRANCH_SCAN_STEPS).find(|&i| falls(f64::from(i) * step)) else {
            return FRAC_PI_2;
        };
        let (mut lo, mut hi) = (f64::from(i - 1) * step, f64::from(i) * step);
        for _ in 0..BRANCH_BISECTIONS {
            let mid = 0.5 * (lo + hi);
            if falls(mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        lo
    }

    /// θ in [0, [`Self::branch_end`]) with θ_d(θ) = `theta_d` (eq. 2), by Newton's
    /// method within a bracket that bisection takes over whenever a step would leave it.
    /// `None` when θ_d lies at or beyond the branch's end (a ray 90° or more off the axis,
    /// or past the point where the model folds over), or the iteration does not reach
    /// [`UNDISTORT_TOL`].
    fn theta_from_theta_d(&self, theta_d: f64) -> Option<f64> {
        let (mut lo, mut hi) = (0.0, self.branch_end());
        // θ_d(0) = 0 < θ_d, and θ_d rises up to the branch's end.
        let (at_end, _) = self.theta_d_with_derivative(hi);
        if at_end <= theta_d || !at_end.is_finite() {
            return None;
        }
        let mut theta = theta_d.min(0.5 * hi);
        for _ in 0..UNDISTORT_MAX_ITERATIONS {
            let (value, slope) = self.theta_d_with_derivative(theta);
            let residual = value - theta_d;
            if residual < 0.0 {
                lo = theta;
            } else {
                hi = theta;
            }
            let newton = theta - residual / slope;
            let inside = newton > lo && newton < hi;
            if residual.abs() <= UNDISTORT_TOL {
                // One Newton step past the tolerance is exact to rounding.
                return Some(if inside { newton } else { theta });
            }
            theta = if inside { newton } else { 0.5 * (lo + hi) };
        }
        None
    }

    /// The inverse of eqs. (1)-(3); `None` as [`super::Distortion::undistort`].
    pub(super) fn undistort(&self, xd: f64, yd: f64) -> Option<(f64, f64)> {
        let theta_d = xd.hypot(yd);
        if theta_d <= R_MIN {
            return Some((xd, yd));
        }
        let theta = self.theta_from_theta_d(theta_d)?;
        let scale = theta.tan() / theta_d;
        scale.is_finite().then_some((xd * scale, yd * scale))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lens() -> Equidistant {
        Equidistant {
            k1: -0.0139,
            k2: 0.0047,
            k3: -0.0051,
            k4: 0.0012,
        }
    }

    #[test]
    fn forward_model_matches_the_formula_at_a_known_point() {
        let d = lens();
        let (x, y) = (0.6, -0.8);
        let theta: f64 = 1.0f64.atan();
        let t2 = theta * theta;
        let theta_d =
            theta * (1.0 + d.k1 * t2 + d.k2 * t2 * t2 + d.k3 * t2.powi(3) + d.k4 * t2.powi(4));
        let (xd, yd) = d.distort(x, y);
        assert!((xd - 0.6 * theta_d).abs() < 1e-15 && (yd + 0.8 * theta_d).abs() < 1e-15);
    }

    #[test]
    fn inverts_up_to_near_ninety_degrees_off_axis() {
        let d = lens();
        for deg in [0.001, 1.0, 30.0, 60.0, 80.0, 89.0] {
            let r = f64::to_radians(deg).tan();
            let (x, y) = (r * 0.28, r * 0.96);
            let (xd, yd) = d.distort(x, y);
            let (bx, by) = d.undistort(xd, yd).expect("invertible");
            let rel = (bx - x).hypot(by - y) / r.max(1.0);
            assert!(rel < 1e-10, "{deg}°: relative error {rel}");
        }
    }

    #[test]
    fn refuses_a_distorted_radius_beyond_ninety_degrees() {
        let d = lens();
        let (at_ninety, _) = d.theta_d_with_derivative(FRAC_PI_2);
        assert!(d.undistort(at_ninety * 1.01, 0.0).is_none());
    }

    #[test]
    fn inverts_only_the_first_branch_of_a_lens_that_folds_over() {
        // θ_d = θ − 0.6 θ³ + 0.12 θ⁵ rises to 0.535 at θ = 0.858, falls to 0.386 at
        // θ = 1.505 and rises again to 0.393 at 90°.
        let d = Equidistant {
            k1: -0.6,
            k2: 0.12,
            k3: 0.0,
            k4: 0.0,
        };
        let end = d.branch_end();
        assert!((end - 0.8580).abs() < 1e-3, "branch end {end} rad");
        // θ_d = 0.45 lies above θ_d(90°) but has its one root on the first branch.
        let theta = d.theta_from_theta_d(0.45).expect("on the first branch");
        assert!(theta < end && (d.theta_d_with_derivative(theta).0 - 0.45).abs() < 1e-12);
        // θ_d = 0.39 also meets the falling and the last branch: the first root is taken.
        let theta = d.theta_from_theta_d(0.39).expect("on the first branch");
        assert!(theta < end, "{theta} rad");
        // θ_d = 0.55 is beyond the fold: no ray.
        assert!(d.undistort(0.55, 0.0).is_none());
    }
}
