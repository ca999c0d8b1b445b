//! Levenberg-Marquardt refinement of a pose on pixel reprojection error, and its covariance.
//!
//! Parameters: a small rotation δ = (rx, ry, rz) about the camera axes applied on the left
//! of R (R ← exp([δ]×)·R), then the marker centre c in the camera frame (mm). Residuals:
//! for each corner, fx·(X/Z − x_n) and fy·(Y/Z − y_n) in the ideal (undistorted) image, so
//! the cost is squared pixels and the Jacobian J (8×6) is exact:
//!
//! p = R·m + c,  ∂p/∂δ = −[R·m]×,  ∂p/∂c = I,
//! ∂u/∂p = fx·(1/Z, 0, −X/Z²),  ∂v/∂p = fy·(0, 1/Z, −Y/Z²).
//!
//! With independent Gaussian corner noise of σ px per coordinate, the pose covariance is
//! σ²·(JᵀJ)⁻¹ in the same parametrisation (radians, then mm).

use super::{ippe::CentredPose, lm};
use crate::geometry::frames::NormalizedPoint;
use nalgebra::{Matrix3, Matrix6, Rotation3, SMatrix, Vector3, Vector6};

/// A rotation step below this (rad) and a centre step below this fraction of the distance
/// end the refinement as converged.
pub const STEP_TOL: f64 = 1e-12;

/// A residual RMS below this many normalised units (1e-12 rad of viewing angle; 1e-9 px at
/// fx = 1000 px) is the floor of double precision: the fit is exact and the search ends as
/// converged, whatever the step.
pub const RESIDUAL_FLOOR_NORMALISED: f64 = 1e-12;

/// Pixels per normalised unit, horizontally and vertically (fx, fy).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelScale {
    /// fx, image units per normalised unit.
    pub fx: f64,
    /// fy, image units per normalised unit.
    pub fy: f64,
}

/// A refined pose with its fit.
#[derive(Debug, Clone, PartialEq)]
pub struct Refined {
    /// The pose at the minimum.
    pub pose: CentredPose,
    /// √(Σ|Δ|² / N): RMS point distance in image units.
    pub rms: f64,
    /// Iterations run (accepted and rejected steps).
    pub iterations: u32,
    /// The step fell below [`STEP_TOL`], or no lower cost could be found.
    pub converged: bool,
    /// JᵀJ at the minimum (image units² per parameter unit²).
    pub jtj: Matrix6<f64>,
    /// Iteration number and pose after each accepted step, when asked for.
    pub pose_trace: Option<Vec<(u32, CentredPose)>>,
}

/// Sum of squared pixel residuals; infinite when a corner is at or behind the camera.
pub(crate) fn cost(
    pose: &CentredPose,
    model: &[Vector3<f64>],
    rays: &[NormalizedPoint],
    s: PixelScale,
) -> f64 {
    let mut sum = 0.0;
    for (m, n) in model.iter().zip(rays) {
        let p = pose.r * m + pose.centre_mm;
        if p.z <= 0.0 {
            return f64::INFINITY;
        }
        let du = s.fx * (p.x / p.z - n.x());
        let dv = s.fy * (p.y / p.z - n.y());
        sum += du * du + dv * dv;
    }
    sum
}

fn linearise(
    pose: &CentredPose,
    model: &[Vector3<f64>],
    rays: &[NormalizedPoint],
    s: PixelScale,
) -> lm::Linearisation<6> {
    let mut jtj = Matrix6::zeros();
    let mut jtr = Vector6::zeros();
    let mut total = 0.0;
    for (m, n) in model.iter().zip(rays) {
        let q = pose.r * m;
        let p = q + pose.centre_mm;
        let inv_z = 1.0 / p.z;
        let residual = [s.fx * (p.x * inv_z - n.x()), s.fy * (p.y * inv_z - n.y())];
        let dproj = SMatrix::<f64, 2, 3>::new(
            s.fx * inv_z,
            0.0,
            -s.fx * p.x * inv_z * inv_z,
            0.0,
            s.fy * inv_z,
            -s.fy * p.y * inv_z * inv_z,
        );
        let mut dp = SMatrix::<f64, 3, 6>::zeros();
        dp.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(-q.cross_matrix()));
        dp.fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&Matrix3::identity());
        let j = dproj * dp;
        jtj += j.transpose() * j;
        jtr += j.transpose() * nalgebra::Vector2::new(residual[0], residual[1]);
        total += residual[0] * residual[0] + residual[1] * residual[1];
    }
    lm::Linearisation::gauss_newton(total, jtj, jtr)
}

/// √(Σ|Δ|² / N): the RMS distance between measured and projected points.
fn rms_from_cost(cost: f64, points: usize) -> f64 {
    (cost / points.max(1) as f64).sqrt()
}

/// Pixel reprojection error of a pose as a least-squares problem in (δ rotation, centre).
struct PoseProblem<'a> {
    model: &'a [Vector3<f64>],
    rays: &'a [NormalizedPoint],
    scale: PixelScale,
}

impl lm::Problem<6> for PoseProblem<'_> {
    type Point = CentredPose;
    fn linearise(&self, pose: &CentredPose) -> lm::Linearisation<6> {
        linearise(pose, self.model, self.rays, self.scale)
    }
    fn cost(&self, pose: &CentredPose) -> f64 {
        cost(pose, self.model, self.rays, self.scale)
    }
    fn apply(&self, pose: &CentredPose, h: &Vector6<f64>) -> CentredPose {
        CentredPose {
            r: Rotation3::new(Vector3::new(h[0], h[1], h[2])) * pose.r,
            centre_mm: pose.centre_mm + Vector3::new(h[3], h[4], h[5]),
        }
    }
    fn is_small_step(&self, pose: &CentredPose, h: &Vector6<f64>) -> bool {
        let rotation = h.fixed_rows::<3>(0).amax();
        let centre = h.fixed_rows::<3>(3).amax();
        rotation <= STEP_TOL && centre <= STEP_TOL * pose.centre_mm.norm()
    }
}

/// Refines `start` by Levenberg-Marquardt on the pixel reprojection error of the centred
/// model points `model` against the measured `rays` (same length, at least 4).
pub fn refine(
    start: CentredPose,
    model: &[Vector3<f64>],
    rays: &[NormalizedPoint],
    scale: PixelScale,
    max_iterations: u32,
    trace: bool,
) -> Refined {
    let floor_cost =
        (RESIDUAL_FLOOR_NORMALISED * scale.fx.max(scale.fy)).powi(2) * rays.len() as f64;
    let settings = lm::Settings {
        max_iterations,
        floor_cost,
        trace,
    };
    let out = lm::minimise(&PoseProblem { model, rays, scale }, start, &settings);
    let rms = if out.lin.cost.is_finite() {
        rms_from_cost(out.lin.cost, rays.len())
    } else {
        f64::INFINITY
    };
    Refined {
        pose: out.point,
        rms,
        iterations: out.iterations,
        converged: out.converged,
        jtj: out.lin.jtj,
        pose_trace: out.steps,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::ippe::centred_model;
    use crate::geometry::{
        euler::{EulerXyz, angle_between},
        marker::Marker,
    };

    #[test]
    fn jacobian_matches_finite_differences() {
        let marker = Marker::try_new(50.0).expect("valid size");
        let model = centred_model(&marker);
        let pose = CentredPose {
            r: EulerXyz::from_degrees(20.0, -10.0, 30.0).to_rotation(),
            centre_mm: Vector3::new(40.0, -30.0, 350.0),
        };
        let rays = [0.0, 1.0, 2.0, 3.0]
            .map(|k| NormalizedPoint::new(0.1 + 0.01 * k, -0.08 + 0.013 * k * k));
        let s = PixelScale {
            fx: 1000.0,
            fy: 1010.0,
        };
        let lin = linearise(&pose, &model, &rays, s);
        // Gradient of the cost is 2·Jᵀr: compare with central differences.
        let h = 1e-6;
        for k in 0..6 {
            let shifted = |sign: f64| {
                let mut d = Vector6::zeros();
                d[k] = sign * h;
                let p = CentredPose {
                    r: Rotation3::new(Vector3::new(d[0], d[1], d[2])) * pose.r,
                    centre_mm: pose.centre_mm + Vector3::new(d[3], d[4], d[5]),
                };
                cost(&p, &model, &rays, s)
            };
            let numeric = (shifted(1.0) - shifted(-1.0)) / (2.0 * h);
            let analytic = 2.0 * lin.jtr[k];
            assert!(
                (numeric - analytic).abs() <= 1e-5 * analytic.abs().max(1.0),
                "param {k}: {numeric} vs {analytic}"
            );
        }
    }

    #[test]
    fn converges_back_to_the_true_pose_from_a_perturbed_start() {
        let marker = Marker::try_new(50.0).expect("valid size");
        let model = centred_model(&marker);
        let truth = CentredPose {
            r: EulerXyz::from_degrees(35.0, 10.0, -60.0).to_rotation(),
            centre_mm: Vector3::new(-20.0, 15.0, 600.0),
        };
        let rays = model.map(|m| {
            let p = truth.r * m + truth.centre_mm;
            NormalizedPoint::new(p.x / p.z, p.y / p.z)
        });
        let start = CentredPose {
            r: Rotation3::new(Vector3::new(0.05, -0.03, 0.02)) * truth.r,
            centre_mm: truth.centre_mm + Vector3::new(5.0, -4.0, 20.0),
        };
        let out = refine(
            start,
            &model,
            &rays,
            PixelScale {
                fx: 1000.0,
                fy: 1000.0,
            },
            50,
            false,
        );
        assert!(out.converged, "{out:?}");
        assert!(angle_between(&out.pose.r, &truth.r) < 1e-10);
        assert!((out.pose.centre_mm - truth.centre_mm).norm() < 1e-8);
        assert!(out.rms < 1e-8, "rms {} px", out.rms);
    }
}
