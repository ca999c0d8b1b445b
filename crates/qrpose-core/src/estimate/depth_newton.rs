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
//! the lengths, so the Jacobian is nearly singular there and the first steps are poor (18
//! iterations for a 25° tilt in the test below; the same flat start is what stalls the
//! paper's update). By default the search therefore starts from the closed-form planar pose
//! of [`super::ippe`]: of its two candidates (the planar ambiguity), the one whose corners
//! reproject closer to the rays, and the depths of its corners. On exact input that start
//! is already the answer; under noise it lies in the basin of the least-squares depths,
//! which Levenberg-Marquardt then reaches in two or three steps (mean 3.8 iterations on
//! `examples/corner_accuracy`'s 2000 noisy views, against 9.4 from the start below).
//!
//! Should the homography be degenerate, the start uses what the paper leaves unused: a
//! square is a parallelogram, so P1 + P3 = P2 + P4, i.e. z1·q1 − z2·q2 + z3·q3 − z4·q4 = 0.
//! Three linear equations fix z1..z4 up to scale (the null vector of [q1 −q2 q3 −q4]), and
//! the known side length fixes the scale. That start is also exact on exact input, but
//! under noise it is poor for small or distant codes, whose outlines barely constrain the
//! tilt. Should the null vector not give four positive depths either, the start falls back
//! to the similar-triangles depth of paper Eq. 2 (z ≈ L·f / l_image, averaged over the six
//! edges). A caller's `initial_z_mm` replaces all of them with the paper's equal-depth start.

use super::iterative::{DepthIteration, side_errors_mm};
use super::result::{EstimateError, TraceStep};
use super::solver::{
    DEFAULT_CORNER_SIGMA_PX, DEFAULT_MAX_ITERATIONS, MAX_INITIAL_Z_MM, SolverParam, check_common,
    check_range,
};
use super::{ippe, lm, refine};
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

/// The depth-newton method's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthNewtonParams {
    /// Starting depth for all four corners, mm, in (0, [`MAX_INITIAL_Z_MM`]]; `None` for the
    /// planar-pose start.
    pub initial_z_mm: Option<f64>,
    /// Iteration limit, 1 to [`MAX_ITERATIONS_LIMIT`](super::solver::MAX_ITERATIONS_LIMIT).
    pub max_iterations: u32,
    /// Record z and Σ|Δz| at every iteration.
    pub trace: bool,
    /// Corner noise σ, px per coordinate: the scale of the high-reprojection-error warning.
    pub corner_sigma_px: f64,
}

impl Default for DepthNewtonParams {
    fn default() -> Self {
        Self {
            initial_z_mm: None,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            trace: false,
            corner_sigma_px: DEFAULT_CORNER_SIGMA_PX,
        }
    }
}

impl DepthNewtonParams {
    /// Checks every parameter against its range.
    ///
    /// # Errors
    /// [`EstimateError::ParamOutOfRange`] for the first one outside its range.
    pub fn validate(&self) -> Result<(), EstimateError> {
        if let Some(z) = self.initial_z_mm {
            check_range(z, SolverParam::InitialZMm, 0.0, MAX_INITIAL_Z_MM)?;
        }
        check_common(self.max_iterations, self.corner_sigma_px)
    }
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

/// Depths z1..z4 (mm) of the corners under the closed-form planar pose (IPPE candidate) whose
/// corners reproject closer to `rays`, or `None` when the homography is degenerate or that
/// pose puts a corner at or behind the camera.
pub fn planar_pose_depths_mm(rays: &[NormalizedPoint; 4], marker: &Marker) -> Option<[f64; 4]> {
    let model = ippe::centred_model(marker);
    // Reprojection error in normalised units (the candidates' ranking needs no focal length).
    let unit = refine::PixelScale { fx: 1.0, fy: 1.0 };
    let [a, b] = ippe::candidates(rays, marker)?;
    let error = |pose: &ippe::CentredPose| refine::cost(pose, &model, rays, unit);
    let best = if error(&a) <= error(&b) { a } else { b };
    let z = model.map(|m| (best.r * m + best.centre_mm).z);
    z.iter().all(|v| v.is_finite() && *v > 0.0).then_some(z)
}

/// Depths z1..z4 (mm) of the parallelogram through the four rays whose edges best match
/// the marker's, or `None` when the rays admit no parallelogram in front of the camera.
pub fn parallelogram_depths_mm(rays: &[NormalizedPoint; 4], marker: &Marker) -> Option<[f64; 4]> {
    let q = rays.map(|n| Vector3::new(n.x(), n.y(), 1.0));
    let cols = [q[0], -q[1], q[2], -q[3]];
    // Null vector of the 3×4 matrix [q1 −q2 q3 −q4]: its signed 3×3 minors.
    let minor = |skip: usize| {
        let [a, b, c] = match skip {
            0 => [1, 2, 3],
            1 => [0, 2, 3],
            2 => [0, 1, 3],
            _ => [0, 1, 2],
        };
        Matrix3::from_columns(&[cols[a], cols[b], cols[c]]).determinant()
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

/// The Gram matrix G_ab = q_a·q_b of the rays q_i = (x_n,i, y_n,i, 1): with it every dot
/// product of the derivatives below is two products and a difference.
fn ray_gram(rays: &[NormalizedPoint; 4]) -> [[f64; 4]; 4] {
    let q = rays.map(|n| Vector3::new(n.x(), n.y(), 1.0));
    let mut g = [[0.0; 4]; 4];
    for (a, row) in g.iter_mut().enumerate() {
        for (b, v) in row.iter_mut().enumerate() {
            *v = q[a].dot(&q[b]);
        }
    }
    g
}

/// Cost, Newton Hessian and gradient at depths `z`.
///
/// For edge j between corners a and b, with A = [q_a, −q_b] and d = z_a·q_a − z_b·q_b, the
/// length |d| has gradient ∇ = Aᵀd/|d| and Hessian (AᵀA − ∇∇ᵀ)/|d| in (z_a, z_b). The cost
/// Σ r_j² then has Hessian 2·Σ (∇∇ᵀ + r_j·∇²); the factor 2 cancels against the gradient's,
/// so the curvature used is Σ ∇∇ᵀ (Gauss-Newton's JᵀJ) plus Σ r_j·∇² (the term Gauss-Newton
/// drops). Under noise the residuals stay non-zero and in the weakly observed tilt
/// directions that term is as large as JᵀJ: without it convergence is only linear (5.7 %
/// of the noisy cases in `examples/corner_accuracy` needed more than 30 iterations).
///
/// AᵀA and Aᵀd come from the Gram matrix `g` (Aᵀd = (z_a·G_aa − z_b·G_ab,
/// z_b·G_bb − z_a·G_ab)); |d| itself is computed from the difference of the points, which
/// keeps full precision when the marker is small against its distance.
fn linearise(
    rays: &[NormalizedPoint; 4],
    g: &[[f64; 4]; 4],
    z: &[f64; 4],
    marker: &Marker,
) -> lm::Linearisation<4> {
    let mut jtj = [[0.0; 4]; 4];
    let mut hessian = [[0.0; 4]; 4];
    let mut jtr = [0.0; 4];
    let mut cost = 0.0;
    for edge in &EDGES {
        let (a, b) = (edge.a, edge.b);
        let (za, zb) = (z[a], z[b]);
        let dx = rays[a].x() * za - rays[b].x() * zb;
        let dy = rays[a].y() * za - rays[b].y() * zb;
        let dz = za - zb;
        let len = (dx * dx + dy * dy + dz * dz).sqrt();
        let r = len - marker.edge_length_mm(edge);
        cost += r * r;
        if len == 0.0 {
            continue;
        }
        let inv_len = 1.0 / len;
        let grad = [
            (za * g[a][a] - zb * g[a][b]) * inv_len,
            (zb * g[b][b] - za * g[a][b]) * inv_len,
        ];
        // AᵀA for A = [q_a, −q_b].
        let ata = [[g[a][a], -g[a][b]], [-g[a][b], g[b][b]]];
        let idx = [a, b];
        for m in 0..2 {
            jtr[idx[m]] += grad[m] * r;
            for n in 0..2 {
                let gn = grad[m] * grad[n];
                jtj[idx[m]][idx[n]] += gn;
                hessian[idx[m]][idx[n]] += gn + r * (ata[m][n] - gn) * inv_len;
            }
        }
    }
    let matrix = |m: [[f64; 4]; 4]| Matrix4::from_fn(|i, k| m[i][k]);
    lm::Linearisation {
        cost,
        jtj: matrix(jtj),
        newton: Some(matrix(hessian)),
        jtr: Vector4::from(jtr),
    }
}

fn cost_at(rays: &[NormalizedPoint; 4], z: &[f64; 4], marker: &Marker) -> f64 {
    side_errors_mm(rays, z, marker).iter().map(|e| e * e).sum()
}

/// The six length residuals as a least-squares problem in z1..z4.
struct DepthProblem<'a> {
    rays: &'a [NormalizedPoint; 4],
    gram: [[f64; 4]; 4],
    marker: &'a Marker,
}

impl lm::Problem<4> for DepthProblem<'_> {
    type Point = [f64; 4];
    fn linearise(&self, z: &[f64; 4]) -> lm::Linearisation<4> {
        linearise(self.rays, &self.gram, z, self.marker)
    }
    fn cost(&self, z: &[f64; 4]) -> f64 {
        cost_at(self.rays, z, self.marker)
    }
    fn apply(&self, z: &[f64; 4], h: &Vector4<f64>) -> [f64; 4] {
        [0, 1, 2, 3].map(|i| z[i] + h[i])
    }
    fn is_small_step(&self, z: &[f64; 4], h: &Vector4<f64>) -> bool {
        h.amax() <= STEP_TOL_REL * (z.iter().sum::<f64>() / 4.0).abs()
    }
}

/// Σ|z(b) − z(a)|, mm.
fn depth_change_mm(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum()
}

/// Solves the six length equations for z1..z4 by Levenberg-Marquardt.
pub fn solve(
    rays: &[NormalizedPoint; 4],
    marker: &Marker,
    params: &DepthNewtonParams,
) -> DepthIteration {
    let start = match params.initial_z_mm {
        Some(z0) => [z0; 4],
        None => planar_pose_depths_mm(rays, marker)
            .or_else(|| parallelogram_depths_mm(rays, marker))
            .unwrap_or([similar_triangles_depth_mm(rays, marker); 4]),
    };
    let settings = lm::Settings {
        max_iterations: params.max_iterations,
        floor_cost: (RESIDUAL_FLOOR_REL * marker.size_mm()).powi(2) * EDGES.len() as f64,
        trace: params.trace,
    };
    let problem = DepthProblem {
        rays,
        gram: ray_gram(rays),
        marker,
    };
    let out = lm::minimise(&problem, start, &settings);
    let trace = out.steps.map(|accepted| {
        let mut previous = start;
        accepted
            .iter()
            .map(|(iteration, z)| {
                let e_c = depth_change_mm(z, &previous);
                previous = *z;
                TraceStep {
                    iteration: *iteration,
                    z_mm: *z,
                    convergence_error_mm: e_c,
                }
            })
            .collect()
    });
    DepthIteration {
        z_mm: out.point,
        converged: out.converged,
        iterations: out.iterations,
        convergence_error_mm: out.previous.map(|p| depth_change_mm(&out.point, &p)),
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
        for (start, max_iterations) in [(None, 3), (Some(450.0), 20)] {
            let params = DepthNewtonParams {
                initial_z_mm: start,
                max_iterations: 30,
                trace: true,
                ..DepthNewtonParams::default()
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
                ..DepthNewtonParams::default()
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
