//! The joint fit: one robust Levenberg-Marquardt over the mount X (6), the target Y (6) and
//! every used view's true flange pose F_i (6 each), minimising
//!
//! ```text
//! Σ_i Σ_j ρ(‖e_ij‖) / σ²  +  ½ Σ_i ‖S⁻¹·ξ_i‖²
//! e_ij = π(C_i·m_j) − u_ij,   C_i = X⁻¹·G_i⁻¹·Y,   G_i = F_i (eye-in-hand) or F_i⁻¹
//! ξ_i = (log(R_Fi·R̃_Fiᵀ), t_Fi − t̃_Fi),   S = diag(σ_θ, σ_θ, σ_θ, σ_t, σ_t, σ_t)
//! ```
//!
//! π is the camera's projection through its lens ([`crate::model`]), m_j the code's points,
//! u_ij the measured pixels, ρ Huber's loss at the pixel noise σ ([`crate::robust`]), F̃_i
//! the reported flange pose and S the flange noise of the options. Each unknown is stepped
//! as [`crate::model::Pose::stepped`] (rotation on the left, axes of its parent frame); the
//! Jacobian of C_i in each unknown chains the 6 × 6 matrices of [`super::rigid`] with the
//! projection's analytic pose Jacobian, so a view's points enter the normal equations
//! through one 6 × 6 information matrix of C_i. The prior's rotation Jacobian is taken as
//! the identity (exact to the flange correction's angle, ~1e-3 rad, relative).
//!
//! The system is dense (12 + 6n unknowns, n ≤ 100 views): one Cholesky per step. At the
//! minimum, with the last IRLS weights held, (JᵀWJ)⁻¹ is the covariance of every unknown
//! (the pixel residuals are whitened by σ̂, the priors by S); its first 6 × 6 block is the
//! mount's, marginalised over the target and the flange corrections.

use super::input::{FlangeNoise, HandEyeSetup};
use super::rigid::{compose, d_inverse, d_left, d_right, difference, inverse};
use crate::error::SolveFailure;
use crate::lm::ViewData;
use crate::model::{Intrinsics, Pose, project, project_with_jacobian};
use crate::robust::Huber;
use nalgebra::{DMatrix, DVector, Matrix6, SMatrix, Vector2, Vector6};
use qrpose_core::geometry::camera::Distortion;

/// Initial damping.
const LAMBDA_START: f64 = 1e-3;
/// Damping factor after a rejected (×) or accepted (÷) step.
const LAMBDA_FACTOR: f64 = 10.0;
/// Past this damping no step lowers the cost: a minimum to rounding.
const LAMBDA_MAX: f64 = 1e12;
/// An accepted step lowering the (whitened) cost by less than this ends the run: it moved
/// the unknowns by about √(2·1e-6) standard deviations.
const DECREASE_TOL: f64 = 1e-6;

/// Everything the joint fit is given.
pub(crate) struct Problem<'a> {
    pub setup: HandEyeSetup,
    pub k: &'a Intrinsics,
    pub lens: &'a Distortion,
    /// The used views' points.
    pub views: &'a [ViewData],
    /// Their reported flange poses F̃_i.
    pub reported: &'a [Pose],
    /// S's diagonal (σ_θ × 3 rad, σ_t × 3 mm).
    pub prior_std: Vector6<f64>,
}

impl<'a> Problem<'a> {
    /// The fit of `views` with their reported flange poses, the flange noise of `noise`
    /// as the prior's standard deviations.
    pub fn new(
        setup: HandEyeSetup,
        camera: (&'a Intrinsics, &'a Distortion),
        views: &'a [ViewData],
        reported: &'a [Pose],
        noise: FlangeNoise,
    ) -> Self {
        let (sr, st) = (noise.rotation_std_rad, noise.translation_std_mm);
        Self {
            setup,
            k: camera.0,
            lens: camera.1,
            views,
            reported,
            prior_std: Vector6::new(sr, sr, sr, st, st, st),
        }
    }
}

/// The unknowns.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct State {
    pub x: Pose,
    pub y: Pose,
    pub flanges: Vec<Pose>,
}

impl State {
    fn stepped(&self, delta: &DVector<f64>) -> Self {
        let block = |i: usize| Vector6::from_fn(|r, _| delta[6 * i + r]);
        Self {
            x: self.x.stepped(&block(0)),
            y: self.y.stepped(&block(1)),
            flanges: self
                .flanges
                .iter()
                .enumerate()
                .map(|(i, f)| f.stepped(&block(2 + i)))
                .collect(),
        }
    }
}

/// H_i = G_i⁻¹ (F_i⁻¹ eye-in-hand, F_i eye-to-hand) and ∂ξ_H/∂ξ_F.
fn h_of(setup: HandEyeSetup, f: &Pose) -> (Pose, Matrix6<f64>) {
    match setup {
        HandEyeSetup::EyeInHand => (inverse(f), d_inverse(f)),
        HandEyeSetup::EyeToHand => (*f, Matrix6::identity()),
    }
}

/// C_i = X⁻¹·H_i·Y, the camera's pose of the code (paper marker frame) in view i.
pub(crate) fn camera_pose_of(setup: HandEyeSetup, x: &Pose, y: &Pose, f: &Pose) -> Pose {
    let (h, _) = h_of(setup, f);
    compose(&compose(&inverse(x), &h), y)
}

/// C_i and its Jacobians in the steps of X, Y and F_i (module doc).
struct Chained {
    c: Pose,
    d_x: Matrix6<f64>,
    d_y: Matrix6<f64>,
    d_f: Matrix6<f64>,
}

fn chained(setup: HandEyeSetup, x: &Pose, y: &Pose, f: &Pose) -> Chained {
    let a = inverse(x);
    let (h, d_h) = h_of(setup, f);
    let d = compose(&h, y);
    Chained {
        c: compose(&a, &d),
        d_x: d_left(&a, &d) * d_inverse(x),
        d_y: d_right(&compose(&a, &h)),
        d_f: d_right(&a) * d_left(&h, y) * d_h,
    }
}

/// Every used view's residuals, px, at `state`; `None` when a point does not project.
pub(crate) fn residuals(p: &Problem, state: &State) -> Option<Vec<Vec<Vector2<f64>>>> {
    p.views
        .iter()
        .zip(&state.flanges)
        .map(|(view, f)| {
            let c = camera_pose_of(p.setup, &state.x, &state.y, f);
            view.target_mm
                .iter()
                .zip(&view.pixel_px)
                .map(|(m, uv)| project(p.k, p.lens, &c, m).map(|q| q - uv))
                .collect()
        })
        .collect()
}

/// The flange prior's whitened residual S⁻¹·ξ_i.
pub(crate) fn prior_residual(p: &Problem, f: &Pose, reported: &Pose) -> Vector6<f64> {
    difference(f, reported).component_div(&p.prior_std)
}

fn cost(p: &Problem, state: &State, loss: Huber) -> Option<f64> {
    let sigma2 = loss.sigma_px * loss.sigma_px;
    let pixels: f64 = residuals(p, state)?
        .iter()
        .flatten()
        .map(|e| loss.rho(e.norm()) / sigma2)
        .sum();
    let priors: f64 = state
        .flanges
        .iter()
        .zip(p.reported)
        .map(|(f, r)| 0.5 * prior_residual(p, f, r).norm_squared())
        .sum();
    let total = pixels + priors;
    total.is_finite().then_some(total)
}

/// JᵀWJ and JᵀW·e (whitened), and the cost.
struct Normal {
    h: DMatrix<f64>,
    g: DVector<f64>,
    cost: f64,
}

fn add_block(h: &mut DMatrix<f64>, row: usize, col: usize, m: &Matrix6<f64>) {
    let mut view = h.view_mut((6 * row, 6 * col), (6, 6));
    view += m;
}

fn normal_equations(p: &Problem, state: &State, loss: Huber) -> Option<Normal> {
    let n = 6 * (2 + state.flanges.len());
    let mut h = DMatrix::zeros(n, n);
    let mut g = DVector::zeros(n);
    let mut total = 0.0;
    let sigma2 = loss.sigma_px * loss.sigma_px;
    for (i, (view, f)) in p.views.iter().zip(&state.flanges).enumerate() {
        let ch = chained(p.setup, &state.x, &state.y, f);
        // The view's information about C_i: Λ = Σ JᵀwJ / σ², γ = Σ Jᵀw·e / σ².
        let mut lambda = Matrix6::zeros();
        let mut gamma = Vector6::zeros();
        for (m, uv) in view.target_mm.iter().zip(&view.pixel_px) {
            let q = project_with_jacobian(p.k, p.lens, &ch.c, m)?;
            let e = q.uv - uv;
            let length = e.norm();
            let w = loss.weight(length) / sigma2;
            total += loss.rho(length) / sigma2;
            let jt: SMatrix<f64, 6, 2> = q.d_pose.transpose();
            lambda += jt * q.d_pose * w;
            gamma += jt * e * w;
        }
        let blocks = [(0, ch.d_x), (1, ch.d_y), (2 + i, ch.d_f)];
        for &(r, m_r) in &blocks {
            let g_r = m_r.transpose() * gamma;
            let mut rows = g.rows_mut(6 * r, 6);
            rows += g_r;
            for &(c, m_c) in &blocks {
                add_block(&mut h, r, c, &(m_r.transpose() * lambda * m_c));
            }
        }
        // The flange prior.
        let r = prior_residual(p, f, &p.reported[i]);
        total += 0.5 * r.norm_squared();
        let s_inv = p.prior_std.map(|s| 1.0 / s);
        let prior_h = Matrix6::from_diagonal(&s_inv.component_mul(&s_inv));
        add_block(&mut h, 2 + i, 2 + i, &prior_h);
        let mut rows = g.rows_mut(6 * (2 + i), 6);
        rows += r.component_mul(&s_inv);
    }
    total.is_finite().then_some(Normal { h, g, cost: total })
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Outcome {
    pub state: State,
    pub iterations: usize,
    pub converged: bool,
}

/// Minimises the module doc's cost from `start` at the pixel noise of `loss`.
///
/// # Errors
/// [`SolveFailure::NonFiniteStart`] when `start` does not project every point,
/// [`SolveFailure::SingularSystem`] when no damping gives a solvable system.
pub(crate) fn minimise(
    p: &Problem,
    start: State,
    loss: Huber,
    max_iterations: usize,
) -> Result<Outcome, SolveFailure> {
    let mut state = start;
    let mut normal = normal_equations(p, &state, loss).ok_or(SolveFailure::NonFiniteStart)?;
    let mut lambda = LAMBDA_START;
    let mut iterations = 0;
    while iterations < max_iterations {
        iterations += 1;
        let mut solvable = false;
        let mut accepted = None;
        while lambda <= LAMBDA_MAX {
            let mut damped = normal.h.clone();
            for i in 0..damped.nrows() {
                damped[(i, i)] *= 1.0 + lambda;
            }
            if let Some(chol) = damped.cholesky() {
                solvable = true;
                let delta = chol.solve(&(-&normal.g));
                let trial = state.stepped(&delta);
                if let Some(c) = cost(p, &trial, loss).filter(|&c| c < normal.cost) {
                    accepted = Some((trial, c));
                    break;
                }
            }
            lambda *= LAMBDA_FACTOR;
        }
        if !solvable {
            return Err(SolveFailure::SingularSystem);
        }
        let Some((trial, trial_cost)) = accepted else {
            return Ok(Outcome {
                state,
                iterations,
                converged: true,
            });
        };
        let small = normal.cost - trial_cost <= DECREASE_TOL;
        state = trial;
        lambda /= LAMBDA_FACTOR;
        normal = normal_equations(p, &state, loss).ok_or(SolveFailure::NonFiniteStart)?;
        if small {
            return Ok(Outcome {
                state,
                iterations,
                converged: true,
            });
        }
    }
    Ok(Outcome {
        state,
        iterations,
        converged: false,
    })
}

/// The mount's covariance (module doc), 6 × 6 over its step (ω rad, δt mm; parent axes);
/// `None` when the normal equations are singular.
pub(crate) fn mount_covariance(p: &Problem, state: &State, loss: Huber) -> Option<Matrix6<f64>> {
    let normal = normal_equations(p, state, loss)?;
    let inv = normal.h.cholesky()?.inverse();
    let c = Matrix6::from_fn(|r, col| inv[(r, col)]);
    let c = (c + c.transpose()) * 0.5;
    c.iter().all(|x| x.is_finite()).then_some(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::handeye::rigid::tests::pose;

    #[test]
    fn the_chained_jacobians_match_central_differences() {
        let x = pose(0.1, -0.2, 1.4, [30.0, -12.0, 80.0]);
        let y = pose(3.0, 0.1, -0.5, [600.0, 150.0, -20.0]);
        let f = pose(0.3, 0.2, -0.1, [500.0, 100.0, 400.0]);
        for setup in [HandEyeSetup::EyeInHand, HandEyeSetup::EyeToHand] {
            let ch = chained(setup, &x, &y, &f);
            let base = camera_pose_of(setup, &x, &y, &f);
            assert!(difference(&ch.c, &base).norm() < 1e-12);
            let numeric = |which: usize| {
                let mut j = Matrix6::zeros();
                for k in 0..6 {
                    let h = if k < 3 { 1e-6 } else { 1e-4 };
                    let mut s = Vector6::zeros();
                    s[k] = h;
                    let at = |s: &Vector6<f64>| match which {
                        0 => camera_pose_of(setup, &x.stepped(s), &y, &f),
                        1 => camera_pose_of(setup, &x, &y.stepped(s), &f),
                        _ => camera_pose_of(setup, &x, &y, &f.stepped(s)),
                    };
                    let d =
                        (difference(&at(&s), &base) - difference(&at(&(-s)), &base)) / (2.0 * h);
                    j.set_column(k, &d);
                }
                j
            };
            for (which, analytic) in [(0, ch.d_x), (1, ch.d_y), (2, ch.d_f)] {
                let n = numeric(which);
                assert!(
                    (analytic - n).norm() < 1e-5 * (1.0 + analytic.norm()),
                    "{setup:?} unknown {which}: {analytic} vs {n}"
                );
            }
        }
    }
}
