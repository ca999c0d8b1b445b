//! Rotation ⇄ Euler angles: the only place the angle convention is defined.
//!
//! Paper Eqs. 14-17: R = Rx(α) · Ry(β) · Rz(γ), each a counter-clockwise (right-handed)
//! elementary rotation about the camera axes. The inverse (docs/conventions.md) reads the angles
//! from the matrix, not from the paper's closed forms (Eqs. 22-24, which divide by sin γ):
//!
//! - β = asin(R13), α = atan2(−R23, R33), γ = atan2(−R12, R11);
//! - α, γ ∈ (−π, π], β ∈ [−π/2, π/2];
//! - at gimbal lock (|R13| > 1 − [`GIMBAL_LOCK_EPS`]) γ = 0 and α = atan2(R32, R22).
//!
//! Angles are radians here; `_deg` exists only at the wire edge.

use nalgebra::{Rotation3, UnitQuaternion, Vector3};
use std::f64::consts::PI;

/// |R13| above `1 − GIMBAL_LOCK_EPS` counts as gimbal lock (β = ±90°), docs/conventions.md.
pub const GIMBAL_LOCK_EPS: f64 = 1e-9;

/// Euler angles of R = Rx(α) · Ry(β) · Rz(γ), radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EulerXyz {
    /// Rotation about the camera x axis, radians, in (−π, π].
    pub alpha: f64,
    /// Rotation about the camera y axis, radians, in [−π/2, π/2].
    pub beta: f64,
    /// Rotation about the camera z axis, radians, in (−π, π].
    pub gamma: f64,
}

impl EulerXyz {
    /// Angles from radians.
    pub fn new(alpha: f64, beta: f64, gamma: f64) -> Self {
        Self { alpha, beta, gamma }
    }

    /// Angles from degrees.
    pub fn from_degrees(alpha_deg: f64, beta_deg: f64, gamma_deg: f64) -> Self {
        Self::new(
            alpha_deg.to_radians(),
            beta_deg.to_radians(),
            gamma_deg.to_radians(),
        )
    }

    /// The rotation matrix of paper Eq. 17.
    pub fn to_rotation(&self) -> Rotation3<f64> {
        let rx = Rotation3::from_axis_angle(&Vector3::x_axis(), self.alpha); // Eq. 14
        let ry = Rotation3::from_axis_angle(&Vector3::y_axis(), self.beta); // Eq. 15
        let rz = Rotation3::from_axis_angle(&Vector3::z_axis(), self.gamma); // Eq. 16
        rx * ry * rz // Eq. 17
    }

    /// The angles of a rotation, with the ranges of `docs/conventions.md` (Euler angles) and gimbal-lock rule.
    pub fn from_rotation(r: &Rotation3<f64>) -> Self {
        let m = r.matrix();
        let r13 = m[(0, 2)].clamp(-1.0, 1.0);
        let beta = r13.asin();
        if r13.abs() > 1.0 - GIMBAL_LOCK_EPS {
            let alpha = wrap_half_open(m[(2, 1)].atan2(m[(1, 1)]));
            return Self::new(alpha, beta, 0.0);
        }
        let alpha = wrap_half_open((-m[(1, 2)]).atan2(m[(2, 2)]));
        let gamma = wrap_half_open((-m[(0, 1)]).atan2(m[(0, 0)]));
        Self::new(alpha, beta, gamma)
    }

    /// The angles in degrees, as `[alpha, beta, gamma]`.
    pub fn to_degrees(&self) -> [f64; 3] {
        [
            self.alpha.to_degrees(),
            self.beta.to_degrees(),
            self.gamma.to_degrees(),
        ]
    }
}

/// Maps atan2's −π onto π so that angles lie in (−π, π].
fn wrap_half_open(angle: f64) -> f64 {
    if angle <= -PI {
        angle + 2.0 * PI
    } else {
        angle
    }
}

/// The rotation as a unit quaternion (w, x, y, z) with w ≥ 0.
pub fn quaternion_wxyz(r: &Rotation3<f64>) -> [f64; 4] {
    let q = UnitQuaternion::from_rotation_matrix(r);
    let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
    [sign * q.w, sign * q.i, sign * q.j, sign * q.k]
}

/// The angle of the rotation that takes `a` onto `b`, radians, in [0, π].
///
/// Computed as atan2(|sin|, cos) from the relative rotation, so that it stays accurate near
/// zero (the `acos` of the trace loses half the digits there).
pub fn angle_between(a: &Rotation3<f64>, b: &Rotation3<f64>) -> f64 {
    let rel = a.matrix().transpose() * b.matrix();
    let sin_axis = Vector3::new(
        rel[(2, 1)] - rel[(1, 2)],
        rel[(0, 2)] - rel[(2, 0)],
        rel[(1, 0)] - rel[(0, 1)],
    );
    let cos = (rel.trace() - 1.0) / 2.0;
    (sin_axis.norm() / 2.0).atan2(cos)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn matrix_matches_paper_eq_17_element_by_element() {
        let (a, b, g) = (0.3_f64, -0.4_f64, 1.2_f64);
        let m = *EulerXyz::new(a, b, g).to_rotation().matrix();
        let (sa, ca, sb, cb, sg, cg) = (a.sin(), a.cos(), b.sin(), b.cos(), g.sin(), g.cos());
        #[rustfmt::skip]
        let eq17 = nalgebra::Matrix3::new(
            cb * cg,                  -cb * sg,                  sb,
            sa * sb * cg + ca * sg,   ca * cg - sa * sb * sg,    -sa * cb,
            sa * sg - ca * sb * cg,   ca * sb * sg + sa * cg,    ca * cb,
        );
        assert_relative_eq!(m, eq17, epsilon = 1e-15);
    }

    #[test]
    fn angles_round_trip_through_the_matrix() {
        let cases = [
            ("zero", 0.0, 0.0, 0.0),
            ("paper set 5-5-Z", 5.0, 5.0, 25.0),
            ("all negative", -170.0, -80.0, -179.0),
            ("alpha at 180", 180.0, 10.0, 20.0),
            ("gamma at 180", 10.0, 10.0, 180.0),
        ];
        for (name, a, b, g) in cases {
            let e = EulerXyz::from_degrees(a, b, g);
            let back = EulerXyz::from_rotation(&e.to_rotation()).to_degrees();
            for (got, want, axis) in [
                (back[0], a, "alpha"),
                (back[1], b, "beta"),
                (back[2], g, "gamma"),
            ] {
                assert!(
                    (got - want).abs() < 1e-9,
                    "{name}: {axis} = {got} deg, want {want} deg"
                );
            }
        }
    }

    #[test]
    fn gimbal_lock_sets_gamma_to_zero_and_keeps_the_rotation() {
        for beta_deg in [90.0, -90.0] {
            let r = EulerXyz::from_degrees(30.0, beta_deg, 20.0).to_rotation();
            let e = EulerXyz::from_rotation(&r);
            assert_eq!(e.gamma, 0.0, "gamma at beta = {beta_deg} deg");
            assert_relative_eq!(e.beta.to_degrees(), beta_deg, epsilon = 1e-6);
            assert!(
                angle_between(&e.to_rotation(), &r) < 1e-9,
                "beta = {beta_deg} deg"
            );
        }
    }

    #[test]
    fn quaternion_has_non_negative_w_and_matches_the_rotation() {
        let r = EulerXyz::from_degrees(170.0, 60.0, -150.0).to_rotation();
        let [w, x, y, z] = quaternion_wxyz(&r);
        assert!(w >= 0.0);
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
        assert!(angle_between(&q.to_rotation_matrix(), &r) < 1e-12);
    }
}
