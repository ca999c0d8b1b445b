//! One Levenberg-Marquardt over the intrinsics and every view's pose, minimising Σ ρ(‖e‖)
//! over all points (Zhang 2000, Eq. 14, with Huber's ρ of [`crate::robust`] and the model of
//! [`crate::model`]), e = projected − measured pixel.
//!
//! The normal equations (JᵀWJ + λ·D)·δ = −JᵀW·e, W the IRLS weights, have the block
//! structure of bundle adjustment: the intrinsics a touch every residual, a view's pose b_i
//! only its own points. With U = Σ J_aᵀWJ_a, W_i = Σ_i J_aᵀWJ_b, V_i = Σ_i J_bᵀWJ_b and
//! g = JᵀW·e, the poses are eliminated by the Schur complement
//!
//! ```text
//! (U − Σ W_i·V_i⁻¹·W_iᵀ)·δa = −g_a + Σ W_i·V_i⁻¹·g_b,i
//! δb_i = V_i⁻¹·(−g_b,i − W_iᵀ·δa)
//! ```
//!
//! so a step costs one (4 + coefficients)² solve and one 6 × 6 solve per view. D is
//! Marquardt's diagonal (each block's own diagonal, floored at [`DIAGONAL_FLOOR`] of its
//! largest entry), λ starts at [`LAMBDA_START`] and moves by [`LAMBDA_FACTOR`]. The same
//! reduced matrix at λ = 0 is the bread of the intrinsics' covariance ([`crate::covariance`]).

use crate::error::SolveFailure;
use crate::model::{Intrinsics, MAX_INTRINSICS, Pose, project, project_with_jacobian};
use crate::robust::Huber;
use nalgebra::{Cholesky, DMatrix, DVector, Matrix6, Point2, SMatrix, SVector, Vector2, Vector6};

/// Initial damping.
const LAMBDA_START: f64 = 1e-3;
/// Damping is divided by this after an accepted step and multiplied after a rejected one.
const LAMBDA_FACTOR: f64 = 10.0;
/// Damping never falls below this. Near-degenerate combinations of parameters (the rational
/// model's numerator against its denominator, the fisheye's k2..k4 over the angles the codes
/// cover) then move by a small fraction of their Gauss-Newton step instead of sliding far
/// along a valley in which the cost hardly changes; well-determined parameters are slowed
/// by a relative 1e-6, nothing. At 1e-9 and below, the rational model's coefficients ran to
/// |k| of 1 to 400 on the wide-angle test sets, twice with a lens that folds over inside the
/// image; at 1e-6 the fisheye takes up to ~130 iterations (instead of ~60) to the same
/// answer.
const LAMBDA_MIN: f64 = 1e-6;
/// Past this damping the step is too small to lower the cost: the minimum is reached to
/// rounding.
const LAMBDA_MAX: f64 = 1e12;
/// An accepted step that lowers Σ ρ by less than this many σ² ends the run: it moved the
/// parameters by about √(2·1e-4) = 0.014 standard deviations along its direction. σ² is the
/// smaller of σ̂² and the current mean Σ ρ per point (≈ the per-axis residual variance), so
/// that exact synthetic data, whose σ̂ is floored, still converge to rounding.
const DECREASE_TOL: f64 = 1e-4;
/// Marquardt's diagonal is floored at this fraction of its block's largest entry, so that a
/// parameter the data barely see is still damped.
const DIAGONAL_FLOOR: f64 = 1e-9;

/// One view's data: target points, mm, and measured pixels, px, in the same order.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ViewData {
    pub target_mm: Vec<Point2<f64>>,
    pub pixel_px: Vec<Vector2<f64>>,
}

/// Everything being fitted.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct State {
    pub intrinsics: Intrinsics,
    pub poses: Vec<Pose>,
}

impl State {
    fn stepped(&self, step: &Step) -> Self {
        Self {
            intrinsics: self.intrinsics.stepped(step.da.as_slice()),
            poses: self
                .poses
                .iter()
                .zip(&step.db)
                .map(|(p, d)| p.stepped(d))
                .collect(),
        }
    }
}

/// Every point's residual (projected − measured), px, view by view; `None` when a point is
/// at or behind the camera or the camera is invalid.
pub(crate) fn residuals(state: &State, views: &[ViewData]) -> Option<Vec<Vec<Vector2<f64>>>> {
    let k = &state.intrinsics;
    k.camera()?;
    let lens = k.distortion()?;
    views
        .iter()
        .zip(&state.poses)
        .map(|(view, pose)| {
            view.target_mm
                .iter()
                .zip(&view.pixel_px)
                .map(|(m, uv)| project(k, &lens, pose, m).map(|p| p - uv))
                .collect()
        })
        .collect()
}

/// Σ ρ(‖e‖) over every point; `None` as [`residuals`].
fn cost(state: &State, views: &[ViewData], loss: Huber) -> Option<f64> {
    let total = residuals(state, views)?
        .iter()
        .flatten()
        .map(|e| loss.rho(e.norm()))
        .sum::<f64>();
    total.is_finite().then_some(total)
}

/// The blocks of JᵀWJ and JᵀW·e (module doc), and Σ ρ.
pub(crate) struct Normal {
    pub n_a: usize,
    u: SMatrix<f64, MAX_INTRINSICS, MAX_INTRINSICS>,
    g_a: SVector<f64, MAX_INTRINSICS>,
    /// Each view's W_i = Σ_i J_aᵀWJ_b.
    pub w: Vec<SMatrix<f64, MAX_INTRINSICS, 6>>,
    v: Vec<Matrix6<f64>>,
    g_b: Vec<Vector6<f64>>,
    cost: f64,
}

pub(crate) fn normal_equations(state: &State, views: &[ViewData], loss: Huber) -> Option<Normal> {
    let k = &state.intrinsics;
    k.camera()?;
    let lens = k.distortion()?;
    let mut n = Normal {
        n_a: k.count(),
        u: SMatrix::zeros(),
        g_a: SVector::zeros(),
        w: Vec::with_capacity(views.len()),
        v: Vec::with_capacity(views.len()),
        g_b: Vec::with_capacity(views.len()),
        cost: 0.0,
    };
    for (view, pose) in views.iter().zip(&state.poses) {
        let mut w_i = SMatrix::<f64, MAX_INTRINSICS, 6>::zeros();
        let mut v_i = Matrix6::zeros();
        let mut g_i = Vector6::zeros();
        for (m, uv) in view.target_mm.iter().zip(&view.pixel_px) {
            let p = project_with_jacobian(k, &lens, pose, m)?;
            let e = p.uv - uv;
            let length = e.norm();
            let weight = loss.weight(length);
            n.cost += loss.rho(length);
            let ja_t_w = p.d_intrinsics.transpose() * weight;
            let jb_t_w = p.d_pose.transpose() * weight;
            n.u += ja_t_w * p.d_intrinsics;
            n.g_a += ja_t_w * e;
            w_i += ja_t_w * p.d_pose;
            v_i += jb_t_w * p.d_pose;
            g_i += jb_t_w * e;
        }
        n.w.push(w_i);
        n.v.push(v_i);
        n.g_b.push(g_i);
    }
    n.cost.is_finite().then_some(n)
}

/// `m` with λ·max(m_ii, floor) added to its first `count` diagonal entries.
fn damped<const N: usize>(m: &SMatrix<f64, N, N>, count: usize, lambda: f64) -> SMatrix<f64, N, N> {
    let largest = (0..count).map(|i| m[(i, i)]).fold(0.0, f64::max);
    let mut out = *m;
    for i in 0..count {
        out[(i, i)] += lambda * m[(i, i)].max(DIAGONAL_FLOOR * largest);
    }
    out
}

/// A step of every unknown.
struct Step {
    da: DVector<f64>,
    db: Vec<Vector6<f64>>,
}

/// The reduced system of the module doc at some damping.
pub(crate) struct Reduced {
    /// The Schur complement S = U − Σ W_i·V_i⁻¹·W_iᵀ (intrinsics × intrinsics).
    pub s: DMatrix<f64>,
    /// Its right-hand side −g_a + Σ W_i·V_i⁻¹·g_b,i.
    rhs: DVector<f64>,
    /// Each view's factored V_i.
    pub factors: Vec<Cholesky<f64, nalgebra::U6>>,
}

/// The reduced system at damping λ; `None` when a pose block is not positive definite.
pub(crate) fn reduced(n: &Normal, lambda: f64) -> Option<Reduced> {
    let u = damped(&n.u, n.n_a, lambda);
    let mut s = DMatrix::from_fn(n.n_a, n.n_a, |i, j| u[(i, j)]);
    let mut rhs = DVector::from_fn(n.n_a, |i, _| -n.g_a[i]);
    let mut factors = Vec::with_capacity(n.v.len());
    for ((w, v), g) in n.w.iter().zip(&n.v).zip(&n.g_b) {
        let chol = Cholesky::new(damped(v, 6, lambda))?;
        let w_v_inv_w_t = w * chol.solve(&w.transpose());
        let w_v_inv_g = w * chol.solve(g);
        for i in 0..n.n_a {
            rhs[i] += w_v_inv_g[i];
            for j in 0..n.n_a {
                s[(i, j)] -= w_v_inv_w_t[(i, j)];
            }
        }
        factors.push(chol);
    }
    Some(Reduced { s, rhs, factors })
}

/// The damped step, `None` when the system cannot be factored at this λ.
fn solve_step(n: &Normal, lambda: f64) -> Option<Step> {
    let Reduced { s, rhs, factors } = reduced(n, lambda)?;
    let da = Cholesky::new(s)?.solve(&rhs);
    let mut da_full = SVector::<f64, MAX_INTRINSICS>::zeros();
    da_full.rows_mut(0, n.n_a).copy_from(&da);
    let db = factors
        .iter()
        .zip(&n.w)
        .zip(&n.g_b)
        .map(|((chol, w), g)| chol.solve(&(-g - w.transpose() * da_full)))
        .collect();
    let finite = da.iter().all(|x| x.is_finite());
    finite.then_some(Step { da, db })
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Outcome {
    pub state: State,
    /// Normal-equation builds (iterations).
    pub iterations: usize,
    /// Whether it stopped on [`DECREASE_TOL`] or at a minimum, not on the iteration budget.
    pub converged: bool,
}

/// Minimises Σ ρ(‖e‖) from `start` (module doc).
///
/// # Errors
/// [`SolveFailure::NonFiniteStart`] when `start` does not project every point,
/// [`SolveFailure::SingularSystem`] when no damping gives a solvable system.
pub(crate) fn minimise(
    views: &[ViewData],
    start: State,
    loss: Huber,
    max_iterations: usize,
) -> Result<Outcome, SolveFailure> {
    let mut state = start;
    let mut normal = normal_equations(&state, views, loss).ok_or(SolveFailure::NonFiniteStart)?;
    let mut lambda = LAMBDA_START;
    let mut iterations = 0;
    let points = views
        .iter()
        .map(|v| v.target_mm.len())
        .sum::<usize>()
        .max(1) as f64;
    while iterations < max_iterations {
        iterations += 1;
        let mut solvable = false;
        let mut accepted = None;
        while lambda <= LAMBDA_MAX {
            if let Some(step) = solve_step(&normal, lambda) {
                solvable = true;
                let trial = state.stepped(&step);
                if let Some(c) = cost(&trial, views, loss).filter(|&c| c < normal.cost) {
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
            // No damping lowers the cost: a minimum, to rounding.
            return Ok(Outcome {
                state,
                iterations,
                converged: true,
            });
        };
        let sigma2 = (loss.sigma_px * loss.sigma_px).min(normal.cost / points);
        let small = normal.cost - trial_cost <= DECREASE_TOL * sigma2;
        state = trial;
        lambda = (lambda / LAMBDA_FACTOR).max(LAMBDA_MIN);
        normal = normal_equations(&state, views, loss).ok_or(SolveFailure::NonFiniteStart)?;
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
