//! The rotation group SO(3): the logarithm map and the left Jacobian, in the form the filter
//! needs. The exponential map is nalgebra's `Rotation3::new(φ)` (the Rodrigues formula
//! R = I + sin θ·[u]× + (1 − cos θ)·[u]×², θ = |φ|, u = φ/θ; Solà 2017 §2.3.1) and [v]× is
//! nalgebra's `Vector3::cross_matrix`.
//!
//! Convention: a rotation error is a small rotation δθ (rad) about the **camera** axes
//! applied on the **left**, R_true = Exp(δθ)·R, as in qrpose-core's per-frame covariance
//! (`docs/conventions.md`, Covariance). This is Solà's "global" angular error.
//!
//! References:
//! - J. Solà, "Quaternion kinematics for the error-state Kalman filter", arXiv:1711.02508,
//!   2017: §2.3 (the rotation matrix, the exponential map as the Rodrigues formula and its
//!   logarithm), §2.4 (the rotation vector), §4 (perturbations and Jacobians on SO(3)).
//! - T. D. Barfoot, "State Estimation for Robotics", Cambridge University Press, 2017,
//!   §7.1 (SO(3): exponential map, left Jacobian J and its closed form).

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// Below this angle (rad) the series form of the left Jacobian is used: its truncation
/// error (θ⁴ terms) is below double precision there.
const SMALL_ANGLE_RAD: f64 = 1e-5;

/// Log(R): the rotation vector φ with Exp(φ) = R, |φ| ≤ π: nalgebra's
/// `UnitQuaternion::scaled_axis` of R's unit quaternion q = (w, v), θ = 2·atan2(|v|, |w|),
/// φ = θ·v/|v| with v's sign flipped when w < 0 (Solà 2017 §2.4), which keeps full
/// precision from tiny angles to π. Not `Rotation3::scaled_axis`: its θ = acos((tr R − 1)/2)
/// loses half the digits at small angles (a rotation by 1e-9 rad reads as none) and its
/// axis, from R − Rᵀ, vanishes at π (a half turn reads as none).
pub fn log(r: &Rotation3<f64>) -> Vector3<f64> {
    UnitQuaternion::from_rotation_matrix(r).scaled_axis()
}

/// The left Jacobian of SO(3), J_l(φ), with Exp(φ + δ) ≈ Exp(J_l(φ)·δ)·Exp(φ)
/// (Barfoot 2017 §7.1.3; J_l(φ) = J_r(−φ), Solà 2017 §4):
///
/// J_l(φ) = I + (1 − cos θ)/θ²·[φ]× + (θ − sin θ)/θ³·[φ]×²,  θ = |φ|;
/// near θ = 0, J_l ≈ I + ½[φ]× + ⅙[φ]×².
pub fn left_jacobian(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let k = phi.cross_matrix();
    if theta < SMALL_ANGLE_RAD {
        return Matrix3::identity() + 0.5 * k + k * k / 6.0;
    }
    let t2 = theta * theta;
    Matrix3::identity()
        + (1.0 - theta.cos()) / t2 * k
        + (theta - theta.sin()) / (t2 * theta) * k * k
}

/// The angle between two rotations, rad: |Log(a·bᵀ)|.
pub fn angle_between(a: &Rotation3<f64>, b: &Rotation3<f64>) -> f64 {
    log(&(a * b.inverse())).norm()
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// The Rodrigues formula written out, the filter's model of Exp; near θ = 0 its series
    /// R ≈ I + [φ]× + ½[φ]×².
    fn rodrigues(phi: &Vector3<f64>) -> Matrix3<f64> {
        let theta = phi.norm();
        let k = phi.cross_matrix();
        if theta < SMALL_ANGLE_RAD {
            return Matrix3::identity() + k + 0.5 * k * k;
        }
        let (a, b) = (theta.sin() / theta, (1.0 - theta.cos()) / (theta * theta));
        Matrix3::identity() + a * k + b * k * k
    }

    #[test]
    fn log_inverts_exp_from_tiny_angles_to_nearly_pi() {
        for phi in [
            Vector3::new(1e-9, -2e-9, 3e-9),
            Vector3::new(3e-6, 1e-6, -2e-6),
            Vector3::new(0.3, -0.2, 0.1),
            Vector3::new(0.0, 3.1, 0.0),
            Vector3::new(-1.2, 1.5, 2.0),
        ] {
            let r = Rotation3::new(phi);
            assert_relative_eq!(log(&r), phi, max_relative = 1e-9, epsilon = 1e-15);
            assert_relative_eq!(*r.matrix(), rodrigues(&phi), epsilon = 1e-12);
        }
    }

    #[test]
    fn log_of_a_half_turn_has_length_pi_about_its_axis() {
        let axis = Vector3::new(1.0, -2.0, 2.0) / 3.0;
        for theta in [std::f64::consts::PI, std::f64::consts::PI - 1e-7] {
            let phi = log(&Rotation3::new(axis * theta));
            assert_relative_eq!(phi.norm(), theta, epsilon = 1e-12);
            // At π exactly, −π·u is the same rotation.
            assert_relative_eq!(phi.normalize().dot(&axis).abs(), 1.0, epsilon = 1e-12);
        }
        assert_eq!(log(&Rotation3::identity()), Vector3::zeros());
    }

    #[test]
    fn the_left_jacobian_maps_a_small_increment_to_the_left_perturbation() {
        for phi in [Vector3::new(2e-6, -1e-6, 0.0), Vector3::new(0.4, -0.7, 0.2)] {
            let delta = Vector3::new(1e-7, 2e-7, -1.5e-7);
            let exact = log(&(Rotation3::new(phi + delta) * Rotation3::new(phi).inverse()));
            let linear = left_jacobian(&phi) * delta;
            assert_relative_eq!(exact, linear, epsilon = 1e-13);
        }
    }

    #[test]
    fn the_angle_between_two_rotations_is_the_norm_of_their_difference() {
        let a = Rotation3::new(Vector3::new(0.1, 0.2, -0.3));
        let d = Vector3::new(0.0, 0.05, 0.0);
        assert_relative_eq!(
            angle_between(&(Rotation3::new(d) * a), &a),
            0.05,
            epsilon = 1e-12
        );
    }
}
