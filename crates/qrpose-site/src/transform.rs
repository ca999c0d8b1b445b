//! Rigid transforms between the camera, robot, marker and warehouse (world) frames, and the
//! first-order propagation of a pose covariance through them (`docs/site.md`, Frames).
//!
//! A [`Rigid`] `T_ab` maps points of frame b into frame a: p_a = R·p_b + t, so t is b's
//! origin in a. Composition reads right to left: T_ac = T_ab · T_bc.
//!
//! **Covariance convention** (the core's, `docs/conventions.md`, Covariance): a pose T_ab
//! is perturbed as R → exp([δθ]×)·R and t → t + δt, with δθ (rad) and δt (mm) both in the
//! axes of the *output* frame a. Its 6×6 covariance is over (δθx, δθy, δθz, δtx, δty, δtz),
//! units rad², rad·mm, mm². The core's pose covariance is this for T_camera←marker with the
//! marker frame's origin at the symbol's centre ([`marker_in_camera`]), which is the map's
//! marker frame too. Mounts and map poses are taken as exact: they add no uncertainty.
//!
//! Each map's Jacobian J gives Σ' = J·Σ·Jᵀ:
//! - fixed on the left, T' = A·T: δθ' = R_A·δθ, δt' = R_A·δt ([`fixed_then`]);
//! - fixed on the right, T' = T·B: δθ' = δθ, δt' = −[R·t_B]×·δθ + δt ([`then_fixed`]);
//! - inverse, T' = T⁻¹: δθ' = −Rᵀ·δθ, δt' = −Rᵀ·[t]×·δθ − Rᵀ·δt ([`inverse`]);
//! - both uncertain and independent, T' = A·T ([`compose`]): A's perturbation gives
//!   δθ' = δθ_A, δt' = δt_A − [R_A·t_T]×·δθ_A (a turn of A moves T's origin at the lever arm
//!   R_A·t_T); T's as in [`fixed_then`]; Σ' = J_A·Σ_A·J_Aᵀ + J_T·Σ_T·J_Tᵀ.
//!
//! A mount with a standard deviation ([`crate::mount`]) is such an uncertain left factor.

use nalgebra::{Isometry3, Matrix3, Matrix6, Rotation3, Translation3, UnitQuaternion, Vector3};
use qrpose_core::estimate::PoseEstimate;

/// A rigid transform T_ab: p_a = R·p_b + t, t in mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rigid {
    /// R, b's axes in a.
    pub rotation: Rotation3<f64>,
    /// t, b's origin in a, mm.
    pub translation_mm: Vector3<f64>,
}

impl Rigid {
    /// The identity.
    pub fn identity() -> Self {
        Self {
            rotation: Rotation3::identity(),
            translation_mm: Vector3::zeros(),
        }
    }

    /// T_ab⁻¹ = T_ba.
    pub fn inverse(&self) -> Self {
        let r_inv = self.rotation.inverse();
        Self {
            rotation: r_inv,
            translation_mm: -(r_inv * self.translation_mm),
        }
    }

    /// self · other (apply `other` first).
    pub fn then(&self, other: &Rigid) -> Self {
        Self {
            rotation: self.rotation * other.rotation,
            translation_mm: self.rotation * other.translation_mm + self.translation_mm,
        }
    }

    /// p_a for p_b, mm.
    pub fn transform_point(&self, p_b_mm: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * p_b_mm + self.translation_mm
    }

    /// The same transform as nalgebra's isometry (what qrpose-calib and qrpose-sim take).
    pub fn to_isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(self.translation_mm),
            UnitQuaternion::from_rotation_matrix(&self.rotation),
        )
    }
}

impl From<&Isometry3<f64>> for Rigid {
    fn from(pose: &Isometry3<f64>) -> Self {
        Self {
            rotation: pose.rotation.to_rotation_matrix(),
            translation_mm: pose.translation.vector,
        }
    }
}

/// A pose with its covariance in the convention of this module (`None` when the estimate
/// had none: methods other than `reprojection`, image-plane cameras).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Rigid,
    /// 6×6 over (δθ rad, δt mm), output-frame axes.
    pub covariance: Option<Matrix6<f64>>,
}

fn propagate(j: &Matrix6<f64>, covariance: Option<Matrix6<f64>>) -> Option<Matrix6<f64>> {
    covariance.map(|c| {
        let p = j * c * j.transpose();
        // Symmetric to the last bit, so that a consumer's Cholesky does not see rounding.
        (p + p.transpose()) * 0.5
    })
}

fn block_jacobian(
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

/// A·T for an exact A.
pub fn fixed_then(a: &Rigid, t: &PoseWithCovariance) -> PoseWithCovariance {
    let r = *a.rotation.matrix();
    let j = block_jacobian(r, Matrix3::zeros(), Matrix3::zeros(), r);
    PoseWithCovariance {
        pose: a.then(&t.pose),
        covariance: propagate(&j, t.covariance),
    }
}

/// T·B for an exact B.
pub fn then_fixed(t: &PoseWithCovariance, b: &Rigid) -> PoseWithCovariance {
    let moved = t.pose.rotation * b.translation_mm;
    let j = block_jacobian(
        Matrix3::identity(),
        Matrix3::zeros(),
        -moved.cross_matrix(),
        Matrix3::identity(),
    );
    PoseWithCovariance {
        pose: t.pose.then(b),
        covariance: propagate(&j, t.covariance),
    }
}

/// A·T for an uncertain A independent of T (module docs); the covariance is `None` when
/// either factor has none.
pub fn compose(a: &PoseWithCovariance, t: &PoseWithCovariance) -> PoseWithCovariance {
    let r = *a.pose.rotation.matrix();
    let lever = a.pose.rotation * t.pose.translation_mm;
    let j_a = block_jacobian(
        Matrix3::identity(),
        Matrix3::zeros(),
        -lever.cross_matrix(),
        Matrix3::identity(),
    );
    let j_t = block_jacobian(r, Matrix3::zeros(), Matrix3::zeros(), r);
    let covariance = match (propagate(&j_a, a.covariance), propagate(&j_t, t.covariance)) {
        (Some(ca), Some(ct)) => Some(ca + ct),
        _ => None,
    };
    PoseWithCovariance {
        pose: a.pose.then(&t.pose),
        covariance,
    }
}

/// T⁻¹.
pub fn inverse(t: &PoseWithCovariance) -> PoseWithCovariance {
    let rt = t.pose.rotation.inverse().into_inner();
    let j = block_jacobian(
        -rt,
        Matrix3::zeros(),
        -rt * t.pose.translation_mm.cross_matrix(),
        -rt,
    );
    PoseWithCovariance {
        pose: t.pose.inverse(),
        covariance: propagate(&j, t.covariance),
    }
}

/// T_camera←marker of an estimate, with the marker frame's origin at the symbol's centre
/// (the map's convention), and the estimate's covariance, which is of exactly this pose.
pub fn marker_in_camera(estimate: &PoseEstimate) -> PoseWithCovariance {
    PoseWithCovariance {
        pose: Rigid {
            rotation: estimate.pose.rotation(),
            translation_mm: estimate.centre_mm,
        },
        covariance: estimate.diagnostics.covariance,
    }
}

/// T_robot←marker = T_robot←camera (the mount) · T_camera←marker.
pub fn pose_in_robot(mount: &Rigid, marker_in_camera: &PoseWithCovariance) -> PoseWithCovariance {
    fixed_then(mount, marker_in_camera)
}

/// T_world←robot = T_world←marker (the map) · T_marker←camera · T_camera←robot (the mount's
/// inverse): the robot's pose in the warehouse from one mapped code.
pub fn robot_pose_in_world(
    marker_in_world: &Rigid,
    marker_in_camera: &PoseWithCovariance,
    mount: &Rigid,
) -> PoseWithCovariance {
    let camera_in_marker = inverse(marker_in_camera);
    fixed_then(
        marker_in_world,
        &then_fixed(&camera_in_marker, &mount.inverse()),
    )
}

/// The rotation vector (rad) of R: R = exp([v]×).
pub fn log_rotation(r: &Rotation3<f64>) -> Vector3<f64> {
    r.scaled_axis()
}

/// The perturbation (δθ, δt) that takes `reference` to `pose` in this module's convention:
/// exp([δθ]×)·R_ref = R, t_ref + δt = t.
pub fn perturbation_between(reference: &Rigid, pose: &Rigid) -> nalgebra::Vector6<f64> {
    let d_theta = log_rotation(&(pose.rotation * reference.rotation.inverse()));
    let d_t = pose.translation_mm - reference.translation_mm;
    nalgebra::Vector6::new(d_theta.x, d_theta.y, d_theta.z, d_t.x, d_t.y, d_t.z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector6;

    fn pose(rx: f64, ry: f64, rz: f64, t: [f64; 3]) -> Rigid {
        Rigid {
            rotation: Rotation3::from_euler_angles(rx, ry, rz),
            translation_mm: Vector3::from(t),
        }
    }

    /// exp of a perturbation applied to `p` in this module's convention.
    fn perturbed(p: &Rigid, d: &Vector6<f64>) -> Rigid {
        Rigid {
            rotation: Rotation3::new(Vector3::new(d[0], d[1], d[2])) * p.rotation,
            translation_mm: p.translation_mm + Vector3::new(d[3], d[4], d[5]),
        }
    }

    /// The Jacobian of `f` at `p`, by central differences of the perturbation.
    fn numeric_jacobian(p: &Rigid, f: impl Fn(&Rigid) -> Rigid) -> Matrix6<f64> {
        let base = f(p);
        let mut j = Matrix6::zeros();
        let h = 1e-4;
        for k in 0..6 {
            let mut d = Vector6::zeros();
            d[k] = h;
            let plus = perturbation_between(&base, &f(&perturbed(p, &d)));
            let minus = perturbation_between(&base, &f(&perturbed(p, &-d)));
            j.set_column(k, &((plus - minus) / (2.0 * h)));
        }
        j
    }

    fn analytic_jacobian(
        p: &Rigid,
        f: impl Fn(&PoseWithCovariance) -> PoseWithCovariance,
    ) -> Matrix6<f64> {
        // With Σ = I, Σ' = J·Jᵀ; compare that, which fixes J up to an orthogonal factor, and
        // the propagated pose. Σ = e_k e_kᵀ picks J's column k up to sign.
        let mut j = Matrix6::zeros();
        for k in 0..6 {
            let mut c = Matrix6::zeros();
            c[(k, k)] = 1.0;
            let out = f(&PoseWithCovariance {
                pose: *p,
                covariance: Some(c),
            });
            let cov = out.covariance.expect("propagated");
            let col = Vector6::from_fn(|i, _| cov[(i, i)].sqrt());
            j.set_column(k, &col);
        }
        j
    }

    #[test]
    fn an_isometry_round_trip_keeps_the_transform() {
        let rigid = Rigid {
            rotation: Rotation3::from_euler_angles(0.3, -1.1, 2.0),
            translation_mm: Vector3::new(12.5, -300.0, 845.0),
        };
        let iso = rigid.to_isometry();
        let p = Vector3::new(1.0, 2.0, 3.0);
        assert!((iso.transform_point(&p.into()).coords - rigid.transform_point(&p)).norm() < 1e-12);
        let back = Rigid::from(&iso);
        assert!((back.rotation.matrix() - rigid.rotation.matrix()).norm() < 1e-12);
        assert_eq!(back.translation_mm, rigid.translation_mm);
    }

    #[test]
    fn each_jacobian_matches_central_differences() {
        let p = pose(0.3, -0.2, 0.9, [120.0, -40.0, 800.0]);
        let a = pose(-1.0, 0.4, 2.0, [300.0, 20.0, -50.0]);
        let cases: Vec<(&str, Matrix6<f64>, Matrix6<f64>)> = vec![
            (
                "fixed_then",
                numeric_jacobian(&p, |x| a.then(x)),
                analytic_jacobian(&p, |x| fixed_then(&a, x)),
            ),
            (
                "then_fixed",
                numeric_jacobian(&p, |x| x.then(&a)),
                analytic_jacobian(&p, |x| then_fixed(x, &a)),
            ),
            (
                "inverse",
                numeric_jacobian(&p, Rigid::inverse),
                analytic_jacobian(&p, inverse),
            ),
        ];
        for (name, numeric, analytic) in cases {
            let numeric_abs = numeric.map(f64::abs);
            assert!(
                (numeric_abs - analytic).amax() < 1e-5 * (1.0 + numeric_abs.amax()),
                "{name}: numeric |J| {numeric_abs} vs analytic {analytic}"
            );
        }
    }

    #[test]
    fn compose_adds_both_factors_jacobians_as_central_differences_give_them() {
        let a = pose(0.4, -0.7, 1.9, [350.0, -80.0, 620.0]);
        let t = pose(-0.2, 0.3, 0.5, [40.0, 110.0, 700.0]);
        let sigma = |scale: f64| {
            let l = Matrix6::from_fn(|i, k| {
                if i >= k {
                    scale * (0.5 + 0.1 * (i + 2 * k) as f64)
                } else {
                    0.0
                }
            });
            l * l.transpose()
        };
        let (sigma_a, sigma_t) = (sigma(0.002), sigma(0.01));
        let j_a = numeric_jacobian(&a, |x| x.then(&t));
        let j_t = numeric_jacobian(&t, |x| a.then(x));
        let expected = j_a * sigma_a * j_a.transpose() + j_t * sigma_t * j_t.transpose();
        let out = compose(
            &PoseWithCovariance {
                pose: a,
                covariance: Some(sigma_a),
            },
            &PoseWithCovariance {
                pose: t,
                covariance: Some(sigma_t),
            },
        );
        let got = out.covariance.expect("propagated");
        assert!(
            (got - expected).amax() < 1e-6 * expected.amax(),
            "{got} vs {expected}"
        );
        assert!((out.pose.translation_mm - a.then(&t).translation_mm).norm() < 1e-12);
        // Either factor without a covariance: none.
        let unknown = PoseWithCovariance {
            pose: t,
            covariance: None,
        };
        let known = PoseWithCovariance {
            pose: a,
            covariance: Some(sigma_a),
        };
        assert!(compose(&known, &unknown).covariance.is_none());
        assert!(compose(&unknown, &known).covariance.is_none());
    }

    #[test]
    fn a_full_covariance_propagates_as_j_sigma_jt() {
        let p = pose(0.1, 0.5, -0.3, [10.0, 20.0, 600.0]);
        let m = pose(0.0, 0.2, 1.5, [100.0, 0.0, 300.0]);
        let w = pose(0.0, 0.0, 0.7, [5000.0, 2000.0, 0.0]);
        let l = Matrix6::from_fn(|i, k| {
            if i >= k {
                0.01 * (1 + i + k) as f64
            } else {
                0.0
            }
        });
        let sigma = l * l.transpose() + Matrix6::identity() * 1e-3;
        let out = robot_pose_in_world(
            &w,
            &PoseWithCovariance {
                pose: p,
                covariance: Some(sigma),
            },
            &m,
        );
        let j = numeric_jacobian(&p, |x| w.then(&x.inverse()).then(&m.inverse()));
        let expected = j * sigma * j.transpose();
        let got = out.covariance.expect("propagated");
        assert!(
            (got - expected).amax() < 1e-6 * expected.amax(),
            "{got} vs {expected}"
        );
        let direct = w.then(&p.inverse()).then(&m.inverse());
        assert!((out.pose.translation_mm - direct.translation_mm).norm() < 1e-9);
    }
}
