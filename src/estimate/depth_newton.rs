//! `depth-newton`: the paper's unknowns and residuals, solved as least squares.
//!
//! Unknowns z1..z4 (corner depths, mm) and residuals r_j = |P_a − P_b| − L_j over the six
//! edges of Table 1 (the negated condition errors of Eqs. 10-11), with P_i = z_i · q_i and
//! q_i = (x_n,i, y_n,i, 1) (Eq. 6). Instead of Eq. 12's heuristic step, each iteration
//! takes the damped Gauss-Newton (Levenberg-Marquardt) step on Σ r_j²:
//!
//! ∂r_j/∂z_a = (P_a − P_b)·q_a / |P_a − P_b|,   ∂r_j/∂z_b = −(P_a − P_b)·q_b / |P_a − P_b|.
//!
//! **Start.** From equal depths (the paper's start) the tilt directions are second order in
//! the lengths, so the Jacobian is nearly singular there and the first steps are poor (14
//! iterations for a 25° tilt in the test below; the same flat start is what stalls the
//! paper's update). By default the start therefore uses what the paper leaves unused: a
//! square is a parallelogram, so P1 + P3 = P2 + P4, i.e. z1·q1 − z2·q2 + z3·q3 − z4·q4 = 0.
//! Three linear equations fix z1..z4 up to scale (the null vector of [q1 −q2 q3 −q4]),
//! and the known side length fixes the scale. On exact input that start is already the
//! answer; under noise Levenberg-Marquardt takes it to the least-squares depths. Should the
//! null vector not give four positive depths, the start falls back to the similar-triangles
//! depth of paper Eq. 2 (z ≈ L·f / l_image, averaged over the six edges). A caller's
//! `initial_z_mm` replaces both with the paper's equal-depth start.

use super::TraceStep;
use super::iterative::side_errors_mm;
use crate::geometry::{
    frames::NormalizedPoint,
    marker::{EDGES, Marker},
};
use nalgebra::{Matrix3, Matrix4, Vector3, Vector4};

/// A step smaller than this fraction of the mean depth ends the iteration as converged.
pub const STEP_TOL_REL: f64 = 1e-12;

/// A residual RMS below this fraction of the marker size is the floor of double precision:
/// the lengths fit exactly and the search ends as converged. At fronto-parallel views the
/// tilt is second order in the lengths, so JᵀJ is singular there and the steps would creep.
pub const RESIDUAL_FLOOR_REL: f64 = 1e-12;

/// An accepted step lowering the cost by less than this fraction ends the search.
pub const COST_DECREASE_TOL_REL: f64 = 1e-10;

/// Starting Levenberg-Marquardt damping, relative to the diagonal of JᵀJ.
const INITIAL_DAMPING: f64 = 1e-6;

/// Damping beyond which no descent direction is left to find.
const MAX_DAMPING: f64 = 1e12;

/// The depth-newton method's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthNewtonParams {
    /// Starting depth for all four corners, mm; `None` for the similar-triangles start.
    pub initial_z_mm: Option<f64>,
    /// Iteration limit.
    pub max_iterations: u32,
    /// Record z and Σ|Δz| at every iteration.
    pub trace: bool,
}

/// The solved depths and how the solver got there.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthSolution {
    /// Depths z1..z4, mm.
    pub z_mm: [f64; 4],
    /// The step fell below [`STEP_TOL_REL`] of the depth (or no better point exists).
    pub converged: bool,
    /// Iterations run (accepted and rejected steps).
    pub iterations: u32,
    /// Σ|Δz| of the last accepted step, mm; `None` when none was accepted.
    pub convergence_error_mm: Option<f64>,
    /// Depths and Σ|Δz| after each iteration, when asked for.
    pub trace: Option<Vec<TraceStep>>,
}

/// Depth at which a fronto-parallel marker would show the observed edge lengths, averaged
/// over the six edges (paper Eq. 2: L = l·d/f, so d = L·f/l with f = 1 in normalised units).
pub fn similar_triangles_depth_mm(rays: &[NormalizedPoint; 4], marker: &Marker) -> f64 {
    let sum: f64 = EDGES
        .iter()
        .map(|e| marker.edge_length_mm(e) / (rays[e.a].0 - rays[e.b].0).norm())
        .sum();
    sum / EDGES.len() as f64
}

/// Depths z1..z4 (mm) of the parallelogram through the four rays whose edges best match
/// the marker's, or `None` when the rays admit no parallelogram in front of the camera.
pub fn parallelogram_depths_mm(rays: &[NormalizedPoint; 4], marker: &Marker) -> Option<[f64; 4]> {
    let q = rays.map(|n| Vector3::new(n.x(), n.y(), 1.0));
    let cols = [q[0], -q[1], q[2], -q[3]];
    // Null vector of the 3×4 matrix [q1 −q2 q3 −q4]: its signed 3×3 minors.
    let minor = |skip: usize| {
        let m: Vec<Vector3<f64>> = (0..4).filter(|&c| c != skip).map(|c| cols[c]).collect();
        Matrix3::from_columns(&m).determinant()
    };
    let mut n = [minor(0), -minor(1), minor(2), -minor(3)];
    if n[0] < 0.0 {
        n = n.map(|v| -v);
    }
    if !n.iter().all(|v| *v > 0.0) {
        return None;
    }
    let (mut known, mut seen) = (0.0, 0.0);
    for e in &EDGES {
        known += marker.edge_length_mm(e);
        seen += (q[e.a] * n[e.a] - q[e.b] * n[e.b]).norm();
    }
    let scale = known / seen;
    let z = n.map(|v| v * scale);
    z.iter().all(|v| v.is_finite() && *v > 0.0).then_some(z)
}

/// Sum of squared residuals and the normal equations JᵀJ, Jᵀr at depths `z`.
struct Linearisation {
    cost: f64,
    jtj: Matrix4<f64>,
    jtr: Vector4<f64>,
}

fn linearise(rays: &[NormalizedPoint; 4], z: &[f64; 4], marker: &Marker) -> Linearisation {
    let q = rays.map(|n| Vector3::new(n.x(), n.y(), 1.0));
    let mut jtj = Matrix4::zeros();
    let mut jtr = Vector4::zeros();
    let mut cost = 0.0;
    for edge in &EDGES {
        let d = q[edge.a] * z[edge.a] - q[edge.b] * z[edge.b];
        let len = d.norm();
        let r = len - marker.edge_length_mm(edge);
        cost += r * r;
        if len == 0.0 {
            continue;
        }
        let mut row = Vector4::zeros();
        row[edge.a] = d.dot(&q[edge.a]) / len;
        row[edge.b] = -d.dot(&q[edge.b]) / len;
        jtj += row * row.transpose();
        jtr += row * r;
    }
    Linearisation { cost, jtj, jtr }
}

fn cost_at(rays: &[NormalizedPoint; 4], z: &[f64; 4], marker: &Marker) -> f64 {
    side_errors_mm(rays, z, marker).iter().map(|e| e * e).sum()
}

/// Solves the six length equations for z1..z4 by Levenberg-Marquardt.
pub fn solve(
    rays: &[NormalizedPoint; 4],
    marker: &Marker,
    params: &DepthNewtonParams,
) -> DepthSolution {
    let mut z = match params.initial_z_mm {
        Some(z0) => [z0; 4],
        None => parallelogram_depths_mm(rays, marker)
            .unwrap_or([similar_triangles_depth_mm(rays, marker); 4]),
    };
    let mut lin = linearise(rays, &z, marker);
    let mut damping = INITIAL_DAMPING;
    let mut trace = params.trace.then(Vec::new);
    let mut last_step = None;
    let mut converged = false;
    let mut iterations = 0;
    let floor_cost = (RESIDUAL_FLOOR_REL * marker.size_mm()).powi(2) * EDGES.len() as f64;
    while iterations < params.max_iterations {
        if lin.cost <= floor_cost {
            converged = true;
            break;
        }
        iterations += 1;
        let mut a = lin.jtj;
        for i in 0..4 {
            a[(i, i)] += damping * lin.jtj[(i, i)].max(f64::MIN_POSITIVE);
        }
        let Some(step) = a.cholesky().map(|c| c.solve(&(-lin.jtr))) else {
            break;
        };
        let z_new = [0, 1, 2, 3].map(|i| z[i] + step[i]);
        let cost_new = cost_at(rays, &z_new, marker);
        let mean_z = z.iter().sum::<f64>() / 4.0;
        let small_step = step.amax() <= STEP_TOL_REL * mean_z.abs();
        if cost_new.is_finite() && cost_new <= lin.cost {
            let stalled = lin.cost - cost_new <= COST_DECREASE_TOL_REL * lin.cost;
            let e_c: f64 = step.iter().map(|s| s.abs()).sum();
            z = z_new;
            lin = linearise(rays, &z, marker);
            damping = (damping / 10.0).max(INITIAL_DAMPING * 1e-6);
            last_step = Some(e_c);
            if let Some(steps) = trace.as_mut() {
                steps.push(TraceStep {
                    iteration: iterations,
                    z_mm: z,
                    convergence_error_mm: e_c,
                });
            }
            if small_step || stalled {
                converged = true;
                break;
            }
        } else {
            // A step too small to lower the cost means rounding noise: we are at the minimum.
            if small_step {
                converged = true;
                break;
            }
            damping *= 10.0;
            if damping > MAX_DAMPING {
                break;
            }
        }
    }
    DepthSolution {
        z_mm: z,
        converged,
        iterations,
        convergence_error_mm: last_step,
        trace,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{euler::EulerXyz, frames::MarkerToCamera};
    use nalgebra::Vector3;

    #[test]
    fn recovers_true_depths_of_a_tilted_marker_in_a_few_iterations() {
        let marker = Marker::try_new(50.0).expect("valid size");
        let pose = MarkerToCamera::new(
            EulerXyz::from_degrees(25.0, 5.0, 5.0).to_rotation(),
            Vector3::new(-100.0, 100.0, 100.0),
        );
        let rays = marker
            .object_points()
            .map(|m| pose.transform(&m).normalized().expect("in front"));
        let truth = marker.object_points().map(|m| pose.transform(&m).0.z);
        for (start, max_iterations) in [(None, 3), (Some(450.0), 16)] {
            let params = DepthNewtonParams {
                initial_z_mm: start,
                max_iterations: 30,
                trace: true,
            };
            let out = solve(&rays, &marker, &params);
            assert!(out.converged, "start {start:?}: {out:?}");
            assert!(
                out.iterations <= max_iterations,
                "start {start:?}: {} iterations",
                out.iterations
            );
            for (i, (got, want)) in out.z_mm.iter().zip(&truth).enumerate() {
                assert!(
                    (got - want).abs() < 1e-9,
                    "start {start:?}, z{}: {got} vs {want} mm",
                    i + 1
                );
            }
        }
    }

    #[test]
    fn parallelogram_start_is_exact_on_exact_input() {
        let marker = Marker::try_new(50.0).expect("valid size");
        let pose = MarkerToCamera::new(
            EulerXyz::from_degrees(40.0, -30.0, 100.0).to_rotation(),
            Vector3::new(90.0, -70.0, 150.0),
        );
        let rays = marker
            .object_points()
            .map(|m| pose.transform(&m).normalized().expect("in front"));
        let z = parallelogram_depths_mm(&rays, &marker).expect("a parallelogram exists");
        for (i, m) in marker.object_points().iter().enumerate() {
            let truth = pose.transform(m).0.z;
            assert!(
                (z[i] - truth).abs() < 1e-9,
                "z{}: {} vs {truth} mm",
                i + 1,
                z[i]
            );
        }
    }

    #[test]
    fn trace_records_each_accepted_step() {
        let marker = Marker::try_new(50.0).expect("valid size");
        let pose = MarkerToCamera::new(
            EulerXyz::from_degrees(10.0, 0.0, 0.0).to_rotation(),
            Vector3::new(0.0, 0.0, 300.0),
        );
        let rays = marker
            .object_points()
            .map(|m| pose.transform(&m).normalized().expect("in front"));
        let out = solve(
            &rays,
            &marker,
            &DepthNewtonParams {
                initial_z_mm: Some(450.0),
                max_iterations: 30,
                trace: true,
            },
        );
        let trace = out.trace.expect("trace requested");
        assert!(!trace.is_empty() && trace.len() <= out.iterations as usize);
        assert_eq!(trace.last().map(|s| s.z_mm), Some(out.z_mm));
        assert_eq!(
            trace.last().map(|s| s.convergence_error_mm),
            out.convergence_error_mm
        );
    }

    #[test]
    fn similar_triangles_start_is_exact_for_a_fronto_parallel_marker() {
        let marker = Marker::try_new(50.0).expect("valid size");
        let pose = MarkerToCamera::new(
            EulerXyz::new(0.0, 0.0, 0.0).to_rotation(),
            Vector3::new(30.0, 40.0, 777.0),
        );
        let rays = marker
            .object_points()
            .map(|m| pose.transform(&m).normalized().expect("in front"));
        assert!((similar_triangles_depth_mm(&rays, &marker) - 777.0).abs() < 1e-9);
    }
}
