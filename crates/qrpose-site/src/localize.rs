//! The robot's pose in the warehouse from several mapped codes: an information-weighted
//! mean on SE(3), by Gauss-Newton, with per-code residuals and a chi-square outlier gate
//! (`docs/site.md`, Localisation).
//!
//! Each code i gives an estimate T_i of T_world←robot with covariance Σ_i (convention of
//! [`crate::transform`]: δθ, δt in world axes). The fused T minimises Σ_i r_iᵀ Σ_i⁻¹ r_i
//! with r_i the perturbation that takes T to T_i: r_i = (log(R_i·Rᵀ), t_i − t). Its
//! covariance is (Σ_i J_iᵀ Σ_i⁻¹ J_i)⁻¹ at the solution, with J_i = ∂r_i/∂δ = −blockdiag(
//! J_r⁻¹(log(R_i·Rᵀ)), I) (J_r: SO(3)'s right Jacobian).
//!
//! A code is an outlier when its squared Mahalanobis distance to the fused pose, with the
//! covariance of the difference (Σ_i − Σ for a code in the fusion, Σ_i + Σ for one left
//! out), exceeds [`CHI2_GATE_6DOF`]. While an inlier fails the gate and more than two
//! inliers remain, the worst is left out and the rest fused again; with two codes that
//! disagree both are flagged (there is no telling which is wrong) and both stay fused.

use crate::transform::{PoseWithCovariance, Rigid, log_rotation, perturbation_between};
use nalgebra::{Matrix3, Matrix6, Rotation3, Vector3, Vector6};
use thiserror::Error;

/// The 99.9 % quantile of χ² with 6 degrees of freedom: a consistent code fails it once in
/// a thousand.
pub const CHI2_GATE_6DOF: f64 = 22.458;
/// Gauss-Newton stops when a step moves less than this (rad and mm alike).
pub const STEP_TOL: f64 = 1e-12;
/// Gauss-Newton iterations at most; it converges in 2-4 on consistent codes.
pub const MAX_ITERATIONS: usize = 20;

/// Why no fused pose exists.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum FuseError {
    /// Fewer than two estimates.
    #[error("localisation needs at least two mapped codes, got {got}")]
    TooFew {
        /// Estimates given.
        got: usize,
    },
    /// An estimate without a covariance, or with one that is not positive definite.
    #[error("code {index} has no positive-definite covariance")]
    NoCovariance {
        /// Its index.
        index: usize,
    },
}

/// One code's fit to the fused pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CodeResidual {
    /// r_i = (log(R_i·Rᵀ) rad, t_i − t mm), world axes.
    pub residual: Vector6<f64>,
    /// Squared Mahalanobis distance of r_i.
    pub chi2: f64,
    /// Left out of the fused pose: `chi2` > [`CHI2_GATE_6DOF`].
    pub outlier: bool,
}

/// The fused pose and every code's residual.
#[derive(Debug, Clone, PartialEq)]
pub struct Fusion {
    /// T_world←robot and its covariance.
    pub pose: PoseWithCovariance,
    /// One per estimate, in the given order.
    pub codes: Vec<CodeResidual>,
    /// Gauss-Newton iterations of the last fusion.
    pub iterations: usize,
}

/// J_r⁻¹(φ) of SO(3): I + ½[φ]× + (1/θ² − (1 + cos θ)/(2θ·sin θ))·[φ]×².
fn right_jacobian_inverse(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let k = phi.cross_matrix();
    if theta < 1e-6 {
        return Matrix3::identity() + 0.5 * k + k * k / 12.0;
    }
    let c = 1.0 / (theta * theta) - (1.0 + theta.cos()) / (2.0 * theta * theta.sin());
    Matrix3::identity() + 0.5 * k + c * k * k
}

fn residual_jacobian(residual: &Vector6<f64>) -> Matrix6<f64> {
    let mut j = -Matrix6::identity();
    let phi = Vector3::new(residual[0], residual[1], residual[2]);
    j.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-right_jacobian_inverse(&phi)));
    j
}

fn apply_step(pose: &Rigid, step: &Vector6<f64>) -> Rigid {
    Rigid {
        rotation: Rotation3::new(Vector3::new(step[0], step[1], step[2])) * pose.rotation,
        translation_mm: pose.translation_mm + Vector3::new(step[3], step[4], step[5]),
    }
}

/// Gauss-Newton over the estimates `used` (with their information matrices), from the
/// first one. Returns the pose, its covariance and the iterations run.
fn gauss_newton(
    estimates: &[Rigid],
    information: &[Matrix6<f64>],
    used: &[usize],
) -> Option<(Rigid, Matrix6<f64>, usize)> {
    let mut pose = estimates[*used.first()?];
    let mut iterations = 0;
    loop {
        let mut h = Matrix6::zeros();
        let mut g = Vector6::zeros();
        for &i in used {
            let r = perturbation_between(&pose, &estimates[i]);
            let j = residual_jacobian(&r);
            h += j.transpose() * information[i] * j;
            g += j.transpose() * information[i] * r;
        }
        let h_inv = h.cholesky()?.inverse();
        if iterations == MAX_ITERATIONS {
            return Some((pose, h_inv, iterations));
        }
        let step = -(h_inv * g);
        pose = apply_step(&pose, &step);
        iterations += 1;
        if step.amax() < STEP_TOL {
            return Some((pose, h_inv, iterations));
        }
    }
}

/// r·Σ⁻¹·r, or `None` when Σ is not positive definite.
fn mahalanobis_sq(r: &Vector6<f64>, covariance: &Matrix6<f64>) -> Option<f64> {
    covariance.cholesky().map(|c| r.dot(&c.solve(r)))
}

/// Each code's residual against `fused`, with the gate applied.
fn residuals(
    estimates: &[Rigid],
    covariances: &[Matrix6<f64>],
    used: &[usize],
    fused: &Rigid,
    fused_cov: &Matrix6<f64>,
) -> Vec<CodeResidual> {
    estimates
        .iter()
        .zip(covariances)
        .enumerate()
        .map(|(i, (estimate, cov))| {
            let residual = perturbation_between(fused, estimate);
            let difference = if used.contains(&i) {
                cov - fused_cov
            } else {
                cov + fused_cov
            };
            // Σ_i − Σ is singular when one code carries all the information; fall back to Σ_i.
            let chi2 = mahalanobis_sq(&residual, &difference)
                .or_else(|| mahalanobis_sq(&residual, cov))
                .unwrap_or(f64::INFINITY);
            CodeResidual {
                residual,
                chi2,
                outlier: chi2 > CHI2_GATE_6DOF,
            }
        })
        .collect()
}

/// Fuses robot-pose-in-world estimates of one photo.
///
/// # Errors
/// [`FuseError::TooFew`] for fewer than two estimates; [`FuseError::NoCovariance`] for one
/// without a positive-definite covariance.
pub fn fuse(estimates: &[PoseWithCovariance]) -> Result<Fusion, FuseError> {
    if estimates.len() < 2 {
        return Err(FuseError::TooFew {
            got: estimates.len(),
        });
    }
    let mut poses = Vec::with_capacity(estimates.len());
    let mut covariances = Vec::with_capacity(estimates.len());
    let mut information = Vec::with_capacity(estimates.len());
    for (index, e) in estimates.iter().enumerate() {
        let cov = e.covariance.ok_or(FuseError::NoCovariance { index })?;
        let info = cov
            .cholesky()
            .ok_or(FuseError::NoCovariance { index })?
            .inverse();
        poses.push(e.pose);
        covariances.push(cov);
        information.push(info);
    }
    let mut used: Vec<usize> = (0..estimates.len()).collect();
    loop {
        let (pose, covariance, iterations) = gauss_newton(&poses, &information, &used)
            .ok_or(FuseError::NoCovariance { index: used[0] })?;
        let mut codes = residuals(&poses, &covariances, &used, &pose, &covariance);
        let worst = used
            .iter()
            .copied()
            .filter(|&i| codes[i].outlier)
            .max_by(|&a, &b| codes[a].chi2.total_cmp(&codes[b].chi2));
        match worst {
            Some(w) if used.len() > 2 => used.retain(|&i| i != w),
            _ => {
                for (i, c) in codes.iter_mut().enumerate() {
                    c.outlier = c.chi2 > CHI2_GATE_6DOF || !used.contains(&i);
                }
                return Ok(Fusion {
                    pose: PoseWithCovariance {
                        pose,
                        covariance: Some(covariance),
                    },
                    codes,
                    iterations,
                });
            }
        }
    }
}

/// The rotation part of a residual, degrees: the angle between a code's and the fused
/// rotation.
pub fn residual_rotation_deg(residual: &Vector6<f64>) -> f64 {
    Vector3::new(residual[0], residual[1], residual[2])
        .norm()
        .to_degrees()
}

/// The angle of a rotation, rad.
pub fn rotation_angle_rad(r: &Rotation3<f64>) -> f64 {
    log_rotation(r).norm()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng, rngs::StdRng};
    use rand_distr::StandardNormal;

    fn truth() -> Rigid {
        Rigid {
            rotation: Rotation3::from_euler_angles(0.02, -0.01, 1.2),
            translation_mm: Vector3::new(5000.0, 3000.0, 0.0),
        }
    }

    fn covariance(scale: f64) -> Matrix6<f64> {
        let l = Matrix6::from_fn(|i, k| {
            if i == k {
                if i < 3 { 0.01 } else { 5.0 }
            } else if i > k {
                0.002 * (i + k) as f64
            } else {
                0.0
            }
        });
        l * l.transpose() * scale
    }

    fn draw(rng: &mut StdRng, truth: &Rigid, cov: &Matrix6<f64>) -> Rigid {
        let l = cov.cholesky().expect("spd").l();
        let z = Vector6::from_fn(|_, _| rng.sample::<f64, _>(StandardNormal));
        apply_step(truth, &(l * z))
    }

    #[test]
    fn identical_estimates_fuse_to_themselves_with_the_combined_information() {
        let c = covariance(1.0);
        let e = PoseWithCovariance {
            pose: truth(),
            covariance: Some(c),
        };
        let f = fuse(&[e, e]).expect("fused");
        assert!(perturbation_between(&truth(), &f.pose.pose).amax() < 1e-12);
        let fused = f.pose.covariance.expect("covariance");
        assert!((fused - c * 0.5).amax() < 1e-9 * c.amax());
        assert!(f.codes.iter().all(|c| !c.outlier && c.chi2 < 1e-12));
    }

    #[test]
    fn the_fused_covariance_is_consistent_over_many_draws() {
        let mut rng = StdRng::seed_from_u64(14);
        let covs = [covariance(1.0), covariance(4.0), covariance(0.5)];
        let trials = 2000;
        let mut nees = 0.0;
        for _ in 0..trials {
            let estimates: Vec<PoseWithCovariance> = covs
                .iter()
                .map(|c| PoseWithCovariance {
                    pose: draw(&mut rng, &truth(), c),
                    covariance: Some(*c),
                })
                .collect();
            let f = fuse(&estimates).expect("fused");
            let e = perturbation_between(&truth(), &f.pose.pose);
            nees += mahalanobis_sq(&e, &f.pose.covariance.expect("cov")).expect("spd");
        }
        let mean = nees / f64::from(trials);
        assert!((mean - 6.0).abs() < 0.6, "mean NEES {mean}, expected 6");
    }

    #[test]
    fn a_code_far_off_is_flagged_and_left_out() {
        let c = covariance(1.0);
        let good = PoseWithCovariance {
            pose: truth(),
            covariance: Some(c),
        };
        let mut off = good;
        off.pose.translation_mm.x += 200.0;
        let f = fuse(&[good, good, off]).expect("fused");
        assert_eq!(
            f.codes.iter().map(|c| c.outlier).collect::<Vec<_>>(),
            [false, false, true]
        );
        assert!(perturbation_between(&truth(), &f.pose.pose).amax() < 1e-9);
        assert!((f.codes[2].residual[3] - 200.0).abs() < 1e-6);
    }

    #[test]
    fn two_codes_that_disagree_are_both_flagged() {
        let c = covariance(1.0);
        let a = PoseWithCovariance {
            pose: truth(),
            covariance: Some(c),
        };
        let mut b = a;
        b.pose.translation_mm.y += 300.0;
        let f = fuse(&[a, b]).expect("fused");
        assert!(f.codes.iter().all(|c| c.outlier), "{:?}", f.codes);
    }

    #[test]
    fn refuses_fewer_than_two_or_a_missing_covariance() {
        let a = PoseWithCovariance {
            pose: truth(),
            covariance: Some(covariance(1.0)),
        };
        assert_eq!(fuse(&[a]), Err(FuseError::TooFew { got: 1 }));
        let b = PoseWithCovariance {
            covariance: None,
            ..a
        };
        assert_eq!(fuse(&[a, b]), Err(FuseError::NoCovariance { index: 1 }));
    }
}
