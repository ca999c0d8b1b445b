//! Rigid transforms for the hand-eye solve and the Jacobians of their compositions.
//!
//! A transform T_ab is a [`Pose`]: p_a = R·p_b + t, mm. Every unknown is stepped as
//! [`Pose::stepped`] does: R ← exp([ω]×)·R, t ← t + δt, with ω (rad) and δt (mm) in the
//! axes of the output frame a — the covariance convention of qrpose-site's `transform`
//! module and of `docs/conventions.md` (Covariance). The 6 × 6 Jacobians below map a step
//! ξ = (ω, δt) of one factor to the step of the product, to first order:
//!
//! - C = A·B, A stepped: ξ_C = [[I, 0], [−[R_A·t_B]×, I]]·ξ_A ([`d_left`]);
//! - C = A·B, B stepped: ξ_C = diag(R_A, R_A)·ξ_B ([`d_right`]);
//! - C = A⁻¹, A stepped: ξ_C = [[−R_Aᵀ, 0], [−R_Aᵀ·[t_A]×, −R_Aᵀ]]·ξ_A ([`d_inverse`]).
//!
//! The tests check each against central differences.

use crate::model::Pose;
use nalgebra::{
    Isometry3, Matrix3, Matrix6, Rotation3, Translation3, UnitQuaternion, Vector3, Vector6,
};

/// The identity transform.
#[cfg(test)]
pub(crate) fn identity() -> Pose {
    Pose {
        r: Rotation3::identity(),
        t_mm: Vector3::zeros(),
    }
}

/// a · b (b applied first).
pub(crate) fn compose(a: &Pose, b: &Pose) -> Pose {
    Pose {
        r: a.r * b.r,
        t_mm: a.r * b.t_mm + a.t_mm,
    }
}

/// a⁻¹.
pub(crate) fn inverse(a: &Pose) -> Pose {
    let r = a.r.inverse();
    Pose {
        r,
        t_mm: -(r * a.t_mm),
    }
}

/// log(R) as a rotation vector, rad, accurate for small angles too (nalgebra's
/// `scaled_axis` takes the angle from an arccosine, which loses half the digits near 0:
/// ~1e-8 rad absolute).
pub(crate) fn log_rotation(r: &Rotation3<f64>) -> Vector3<f64> {
    let q = UnitQuaternion::from_rotation_matrix(r);
    let (w, v) = if q.w < 0.0 {
        (-q.w, -q.imag())
    } else {
        (q.w, q.imag())
    };
    let n = v.norm();
    if n == 0.0 {
        return Vector3::zeros();
    }
    v * (2.0 * n.atan2(w) / n)
}

/// The step ξ = (ω, δt) that takes `from` to `to`: ω = log(R_to·R_fromᵀ), δt = t_to − t_from.
pub(crate) fn difference(to: &Pose, from: &Pose) -> Vector6<f64> {
    let omega = log_rotation(&(to.r * from.r.inverse()));
    let dt = to.t_mm - from.t_mm;
    Vector6::new(omega.x, omega.y, omega.z, dt.x, dt.y, dt.z)
}

/// The transform as a nalgebra isometry.
pub(crate) fn isometry_from_pose(p: &Pose) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(p.t_mm),
        UnitQuaternion::from_rotation_matrix(&p.r),
    )
}

/// A nalgebra isometry as a transform.
pub(crate) fn pose_from_isometry(iso: &Isometry3<f64>) -> Pose {
    Pose {
        r: iso.rotation.to_rotation_matrix(),
        t_mm: iso.translation.vector,
    }
}

/// The 6 × 6 matrix [[a, b], [c, d]].
pub(crate) fn blocks(
    a: Matrix3<f64>,
    b: Matrix3<f64>,
    c: Matrix3<f64>,
    d: Matrix3<f64>,
) -> Matrix6<f64> {
    let mut j = Matrix6::zeros();
    j.fixed_view_mut::<3, 3>(0, 0).copy_from(&a);
    j.fixed_view_mut::<3, 3>(0, 3).copy_from(&b);
    j.fixed_view_mut::<3, 3>(3, 0).copy_from(&c);
    j.fixed_view_mut::<3, 3>(3, 3).copy_from(&d);
    j
}

/// ∂ξ_{A·B}/∂ξ_A (module doc).
pub(crate) fn d_left(a: &Pose, b: &Pose) -> Matrix6<f64> {
    let moved = a.r * b.t_mm;
    blocks(
        Matrix3::identity(),
        Matrix3::zeros(),
        -moved.cross_matrix(),
        Matrix3::identity(),
    )
}

/// ∂ξ_{A·B}/∂ξ_B (module doc).
pub(crate) fn d_right(a: &Pose) -> Matrix6<f64> {
    let r = *a.r.matrix();
    blocks(r, Matrix3::zeros(), Matrix3::zeros(), r)
}

/// ∂ξ_{A⁻¹}/∂ξ_A (module doc).
pub(crate) fn d_inverse(a: &Pose) -> Matrix6<f64> {
    let rt = *a.r.inverse().matrix();
    blocks(-rt, Matrix3::zeros(), -rt * a.t_mm.cross_matrix(), -rt)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A pose from Euler angles (rad) and a translation (mm), for the tests of the module.
    pub(crate) fn pose(rx: f64, ry: f64, rz: f64, t: [f64; 3]) -> Pose {
        Pose {
            r: Rotation3::from_euler_angles(rx, ry, rz),
            t_mm: Vector3::from(t),
        }
    }

    /// Central differences of `f` at the step ξ of its argument.
    fn numeric(f: &dyn Fn(&Pose) -> Pose, at: &Pose) -> Matrix6<f64> {
        let base = f(at);
        let mut j = Matrix6::zeros();
        for k in 0..6 {
            let h = if k < 3 { 1e-6 } else { 1e-4 };
            let mut step = Vector6::zeros();
            step[k] = h;
            let plus = difference(&f(&at.stepped(&step)), &base);
            let minus = difference(&f(&at.stepped(&(-step))), &base);
            j.set_column(k, &((plus - minus) / (2.0 * h)));
        }
        j
    }

    #[test]
    fn composition_and_inverse_jacobians_match_central_differences() {
        let a = pose(0.3, -0.7, 1.1, [120.0, -40.0, 300.0]);
        let b = pose(-1.2, 0.4, 0.2, [-35.0, 80.0, 410.0]);
        let cases: [(&str, Matrix6<f64>, Matrix6<f64>); 3] = [
            ("left", d_left(&a, &b), numeric(&|x| compose(x, &b), &a)),
            ("right", d_right(&a), numeric(&|x| compose(&a, x), &b)),
            ("inverse", d_inverse(&a), numeric(&|x| inverse(x), &a)),
        ];
        for (name, analytic, numeric) in cases {
            let scale = 1.0 + analytic.norm();
            assert!(
                (analytic - numeric).norm() < 1e-5 * scale,
                "{name}: {analytic} vs {numeric}"
            );
        }
    }

    #[test]
    fn the_rotation_log_is_accurate_at_small_angles() {
        let w = Vector3::new(3e-7, -1e-7, 2e-7);
        assert!((log_rotation(&Rotation3::new(w)) - w).norm() < 1e-20);
        let big = Vector3::new(0.0, 3.0, 0.0);
        assert!((log_rotation(&Rotation3::new(big)) - big).norm() < 1e-12);
    }

    #[test]
    fn a_transform_composed_with_its_inverse_is_the_identity() {
        let a = pose(0.3, -0.7, 1.1, [120.0, -40.0, 300.0]);
        let i = compose(&a, &inverse(&a));
        assert!(difference(&i, &identity()).norm() < 1e-12);
        let back = pose_from_isometry(&isometry_from_pose(&a));
        assert!(difference(&back, &a).norm() < 1e-12);
    }
}
