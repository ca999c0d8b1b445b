//! One Levenberg-Marquardt driver for the two least-squares problems of qrpose (corner depths
//! in `depth-newton`, the pose in `reprojection`).
//!
//! Cost C(x) = Σ r², gradient g = Jᵀr, step h from (H + μ·D) h = −g, where H is JᵀJ
//! (Gauss-Newton) or the full Hessian JᵀJ + Σ r·∇²r (Newton), and D = diag(JᵀJ) (Marquardt's
//! scaling, so parameters in radians and millimetres mix). A Newton step is taken where
//! H + μ·D is positive definite; elsewhere (far from the minimum) the Gauss-Newton step with
//! JᵀJ, which always is. The damping μ follows
//! Nielsen's rule (Madsen, Nielsen & Tingleff, *Methods for Non-Linear Least Squares
//! Problems*, 2004, Section 3.2): with the gain ratio ρ = (C(x) − C(x+h)) / hᵀ(μ·D·h − g), a
//! step is accepted when ρ > 0 and then μ ← μ·max(1/3, 1 − (2ρ − 1)³), ν ← 2; otherwise
//! μ ← μ·ν, ν ← 2ν. On the depth problem this needs a third of the iterations of the plain
//! ×10 / ÷10 rule (see `docs/accuracy.md`).
//!
//! The search ends as **converged** when the fit is exact to double precision (cost below the
//! problem's floor), the gradient vanishes, a step is negligible, an accepted step lowers
//! the cost by less than [`COST_DECREASE_TOL_REL`], or a rejected step's predicted and
//! actual changes are both below that fraction; otherwise at `max_iterations`, not
//! converged.

use nalgebra::{SMatrix, SVector};

/// An accepted step that lowers the cost by less than this fraction ends the search: the
/// remaining parameter error is then ~1e-5 of its standard deviation.
pub const COST_DECREASE_TOL_REL: f64 = 1e-10;

/// |gᵢ| ≤ this × √(C · (JᵀJ)ᵢᵢ) for every i (the cosine between the residual and each
/// Jacobian column) means the gradient vanishes.
pub const GRADIENT_TOL: f64 = 1e-10;

/// Starting damping, relative to the diagonal of JᵀJ; both starts are close to the answer.
const INITIAL_DAMPING: f64 = 1e-6;

/// Cost, curvature and gradient at a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Linearisation<const N: usize> {
    /// Σ r².
    pub cost: f64,
    /// JᵀJ, Gauss-Newton's curvature.
    pub jtj: SMatrix<f64, N, N>,
    /// The full Hessian JᵀJ + Σ r·∇²r, when the problem provides it.
    pub newton: Option<SMatrix<f64, N, N>>,
    /// Jᵀr.
    pub jtr: SVector<f64, N>,
}

impl<const N: usize> Linearisation<N> {
    /// The Gauss-Newton linearisation.
    pub fn gauss_newton(cost: f64, jtj: SMatrix<f64, N, N>, jtr: SVector<f64, N>) -> Self {
        Self {
            cost,
            jtj,
            newton: None,
            jtr,
        }
    }

    /// The step for damping μ with scale `d`, and the curvature it used: Newton's where that
    /// system is positive definite, else Gauss-Newton's.
    fn step(&self, mu: f64, d: &SVector<f64, N>) -> Option<SVector<f64, N>> {
        let damping = SMatrix::<f64, N, N>::from_diagonal(&(d * mu));
        let rhs = -self.jtr;
        self.newton
            .and_then(|h| solve_spd(&(h + damping), &rhs))
            .or_else(|| solve_spd(&(self.jtj + damping), &rhs))
    }
}

/// Solves A·x = b for a symmetric positive-definite A by its Cholesky factor A = L·Lᵀ, or
/// `None` when A is not positive definite (a pivot ≤ 0 or NaN). Only the lower triangle of
/// A is read. Written over fixed-size arrays for the small systems here (N ≤ 6), where it
/// takes a fraction of the time of nalgebra's general decomposition.
pub fn solve_spd<const N: usize>(
    a: &SMatrix<f64, N, N>,
    b: &SVector<f64, N>,
) -> Option<SVector<f64, N>> {
    let mut l = [[0.0; N]; N];
    let mut inv_diag = [0.0; N];
    for j in 0..N {
        let pivot = a[(j, j)] - l[j][..j].iter().map(|v| v * v).sum::<f64>();
        if pivot.is_nan() || pivot <= 0.0 {
            return None;
        }
        inv_diag[j] = 1.0 / pivot.sqrt();
        for i in j + 1..N {
            let dot: f64 = l[i][..j].iter().zip(&l[j][..j]).map(|(x, y)| x * y).sum();
            l[i][j] = (a[(i, j)] - dot) * inv_diag[j];
        }
    }
    // L·y = b, then Lᵀ·x = y.
    let mut y = [0.0; N];
    for i in 0..N {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i][k] * y[k];
        }
        y[i] = s * inv_diag[i];
    }
    let mut x = [0.0; N];
    for i in (0..N).rev() {
        let mut s = y[i];
        for k in i + 1..N {
            s -= l[k][i] * x[k];
        }
        x[i] = s * inv_diag[i];
    }
    Some(SVector::from(x))
}

/// A least-squares problem in N parameters.
pub trait Problem<const N: usize> {
    /// A point of the search space.
    type Point: Copy;
    /// Cost and normal equations at `x`.
    fn linearise(&self, x: &Self::Point) -> Linearisation<N>;
    /// Σ r² at `x`; ∞ where the point is infeasible (e.g. behind the camera).
    fn cost(&self, x: &Self::Point) -> f64;
    /// `x` moved by `h`.
    fn apply(&self, x: &Self::Point, h: &SVector<f64, N>) -> Self::Point;
    /// Whether `h` is too small to matter at `x`.
    fn is_small_step(&self, x: &Self::Point, h: &SVector<f64, N>) -> bool;
}

/// Limits of one search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Iteration limit (accepted and rejected steps).
    pub max_iterations: u32,
    /// A cost at or below this is an exact fit.
    pub floor_cost: f64,
    /// Keep every accepted point.
    pub trace: bool,
}

/// Where a search ended.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome<P, const N: usize> {
    /// The final point.
    pub point: P,
    /// Cost and normal equations there.
    pub lin: Linearisation<N>,
    /// Iterations run.
    pub iterations: u32,
    /// Whether a convergence criterion was met.
    pub converged: bool,
    /// The point before the last accepted step, if any step was accepted.
    pub previous: Option<P>,
    /// Iteration number and point after each accepted step, when asked for.
    pub steps: Option<Vec<(u32, P)>>,
}

fn gradient_vanishes<const N: usize>(lin: &Linearisation<N>) -> bool {
    (0..N).all(|i| lin.jtr[i].abs() <= GRADIENT_TOL * (lin.cost * lin.jtj[(i, i)]).sqrt())
}

/// Minimises the problem's cost from `start`.
pub fn minimise<Q: Problem<N>, const N: usize>(
    problem: &Q,
    start: Q::Point,
    settings: &Settings,
) -> Outcome<Q::Point, N> {
    let mut x = start;
    let mut lin = problem.linearise(&x);
    let mut mu = INITIAL_DAMPING;
    let mut nu = 2.0;
    let mut steps = settings.trace.then(Vec::new);
    let mut iterations = 0;
    let mut converged = false;
    let mut previous = None;
    if !lin.cost.is_finite() {
        return Outcome {
            point: x,
            lin,
            iterations,
            converged,
            previous,
            steps,
        };
    }
    while iterations < settings.max_iterations {
        if lin.cost <= settings.floor_cost || gradient_vanishes(&lin) {
            converged = true;
            break;
        }
        iterations += 1;
        let d = lin.jtj.diagonal().map(|s| s.max(f64::MIN_POSITIVE));
        let Some(h) = lin.step(mu, &d) else {
            mu *= nu;
            nu *= 2.0;
            continue;
        };
        let small = problem.is_small_step(&x, &h);
        let candidate = problem.apply(&x, &h);
        let cost_new = problem.cost(&candidate);
        let predicted = h.dot(&(d.component_mul(&h) * mu - lin.jtr));
        let rho = if predicted > 0.0 {
            (lin.cost - cost_new) / predicted
        } else {
            -1.0
        };
        if cost_new.is_finite() && rho > 0.0 {
            let stalled = lin.cost - cost_new <= COST_DECREASE_TOL_REL * lin.cost;
            previous = Some(x);
            x = candidate;
            lin = problem.linearise(&x);
            mu *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
            nu = 2.0;
            if let Some(s) = steps.as_mut() {
                s.push((iterations, x));
            }
            if small || stalled {
                converged = true;
                break;
            }
        } else {
            // A step too small to lower the cost is rounding noise, and so is one whose
            // predicted and actual reductions are both below the tolerance (MINPACK's `ftol`
            // test): this is the minimum. Raising the damping would only shrink the step
            // until `small` holds, up to ten rejected steps later.
            let tol = COST_DECREASE_TOL_REL * lin.cost;
            let negligible = predicted <= tol && (lin.cost - cost_new).abs() <= tol;
            if small || negligible {
                converged = true;
                break;
            }
            mu *= nu;
            nu *= 2.0;
        }
    }
    Outcome {
        point: x,
        lin,
        iterations,
        converged,
        previous,
        steps,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rosenbrock's valley as residuals r = (10(y − x²), 1 − x): minimum (1, 1), cost 0.
    struct Rosenbrock;

    impl Problem<2> for Rosenbrock {
        type Point = [f64; 2];
        fn linearise(&self, p: &[f64; 2]) -> Linearisation<2> {
            let r = SVector::<f64, 2>::new(10.0 * (p[1] - p[0] * p[0]), 1.0 - p[0]);
            let j = SMatrix::<f64, 2, 2>::new(-20.0 * p[0], 10.0, -1.0, 0.0);
            Linearisation::gauss_newton(r.norm_squared(), j.transpose() * j, j.transpose() * r)
        }
        fn cost(&self, p: &[f64; 2]) -> f64 {
            (10.0 * (p[1] - p[0] * p[0])).powi(2) + (1.0 - p[0]).powi(2)
        }
        fn apply(&self, p: &[f64; 2], h: &SVector<f64, 2>) -> [f64; 2] {
            [p[0] + h[0], p[1] + h[1]]
        }
        fn is_small_step(&self, _: &[f64; 2], h: &SVector<f64, 2>) -> bool {
            h.amax() < 1e-15
        }
    }

    #[test]
    fn finds_the_bottom_of_rosenbrocks_valley() {
        let settings = Settings {
            max_iterations: 100,
            floor_cost: 1e-28,
            trace: true,
        };
        let out = minimise(&Rosenbrock, [-1.2, 1.0], &settings);
        assert!(out.converged, "{out:?}");
        assert!(
            (out.point[0] - 1.0).abs() < 1e-9 && (out.point[1] - 1.0).abs() < 1e-9,
            "{:?}",
            out.point
        );
        let steps = out.steps.expect("trace");
        assert!(!steps.is_empty() && steps.windows(2).all(|w| w[0].0 < w[1].0));
    }

    #[test]
    fn solve_spd_matches_nalgebras_cholesky_and_refuses_indefinite_systems() {
        #[rustfmt::skip]
        let a = SMatrix::<f64, 4, 4>::new(
            4.0, 1.0, 0.5, 0.2,
            1.0, 3.0, 0.3, 0.1,
            0.5, 0.3, 2.0, 0.4,
            0.2, 0.1, 0.4, 1.5,
        );
        let b = SVector::<f64, 4>::new(1.0, -2.0, 0.5, 3.0);
        let x = solve_spd(&a, &b).expect("positive definite");
        let want = a.cholesky().expect("positive definite").solve(&b);
        assert!((x - want).amax() < 1e-14, "{x} vs {want}");
        assert!((a * x - b).amax() < 1e-14);
        let mut indefinite = a;
        indefinite[(3, 3)] = -1.0;
        assert_eq!(solve_spd(&indefinite, &b), None);
        let mut nan = a;
        nan[(0, 0)] = f64::NAN;
        assert_eq!(solve_spd(&nan, &b), None);
    }

    #[test]
    fn stops_unconverged_at_the_iteration_limit() {
        let settings = Settings {
            max_iterations: 2,
            floor_cost: 0.0,
            trace: false,
        };
        let out = minimise(&Rosenbrock, [-1.2, 1.0], &settings);
        assert!(!out.converged);
        assert_eq!(out.iterations, 2);
    }
}
