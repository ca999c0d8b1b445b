//! The paper's iterative estimator (Teoh et al. 2022, Sections 3-5; `docs/paper-method.md`).
//!
//! Legend: `z[i]` depth of corner P(i+1), mm; `e[j]` condition error of edge l(j+1), mm;
//! `k` the updating coefficient (gain); `e_c` the sum of absolute depth changes, mm.
//!
//! 1. z_i(0) = z0 for every corner.
//! 2. P_i = (x_n,i · z_i, y_n,i · z_i, z_i)                                  (Eq. 6)
//! 3. e_j = L_j − |P_a − P_b| for the six edges, L = l or √2·l        (Eqs. 7, 10, 11)
//! 4. z_i(n) = z_i(n−1) + k · mean(e over the three edges at P_i)            (Eq. 12)
//!    — a simultaneous update: all four use the errors of iterate n−1.
//! 5. e_c(n) = Σ_i |z_i(n) − z_i(n−1)|; converged when e_c ≤ e_d.           (Eq. 13)
//!
//! The update moves both ends of an edge by the same amount, so it can only change an
//! edge's length through the perspective spread of the rays; it has no term that turns
//! the square. Tilted markers therefore converge slowly or not at all (see
//! `docs/paper-reproduction.md`); `depth-newton` solves the same equations properly.

use super::result::{EstimateError, TraceStep};
use super::solver::{
    DEFAULT_CORNER_SIGMA_PX, DEFAULT_MAX_ITERATIONS, MAX_INITIAL_Z_MM, SolverParam, check_common,
    check_range,
};
use crate::geometry::{
    frames::{CameraPoint, NormalizedPoint},
    marker::{EDGES, INCIDENT_EDGES, Marker},
};

/// Default starting depth, mm (the paper's z_initial, Section 8).
pub const DEFAULT_INITIAL_Z_MM: f64 = 450.0;
/// Default gain k of Eq. 12.
pub const DEFAULT_GAIN: f64 = 1.0;
/// Default e_d of Eq. 13, mm.
pub const DEFAULT_TOLERANCE_MM: f64 = 1.0;
/// Largest accepted gain.
pub const MAX_GAIN: f64 = 10.0;
/// Largest accepted tolerance, mm.
pub const MAX_TOLERANCE_MM: f64 = 1e6;

/// The paper method's parameters (`docs/paper-method.md`, Inputs and defaults).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperParams {
    /// z0, the starting depth of every corner, mm, in (0, [`MAX_INITIAL_Z_MM`]].
    pub initial_z_mm: f64,
    /// k, the updating coefficient of Eq. 12, in (0, [`MAX_GAIN`]].
    pub gain: f64,
    /// e_d, the convergence threshold on e_c (Eq. 13), mm, in (0, [`MAX_TOLERANCE_MM`]].
    pub tolerance_mm: f64,
    /// n_max, 1 to [`MAX_ITERATIONS_LIMIT`](super::solver::MAX_ITERATIONS_LIMIT).
    pub max_iterations: u32,
    /// Record z and e_c at every iteration.
    pub trace: bool,
    /// Corner noise σ, px per coordinate: the scale of the high-reprojection-error warning.
    pub corner_sigma_px: f64,
}

impl Default for PaperParams {
    fn default() -> Self {
        Self {
            initial_z_mm: DEFAULT_INITIAL_Z_MM,
            gain: DEFAULT_GAIN,
            tolerance_mm: DEFAULT_TOLERANCE_MM,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            trace: false,
            corner_sigma_px: DEFAULT_CORNER_SIGMA_PX,
        }
    }
}

impl PaperParams {
    /// Checks every parameter against its range.
    ///
    /// # Errors
    /// [`EstimateError::ParamOutOfRange`] for the first one outside its range.
    pub fn validate(&self) -> Result<(), EstimateError> {
        check_range(
            self.initial_z_mm,
            SolverParam::InitialZMm,
            0.0,
            MAX_INITIAL_Z_MM,
        )?;
        check_range(self.gain, SolverParam::Gain, 0.0, MAX_GAIN)?;
        check_range(
            self.tolerance_mm,
            SolverParam::ToleranceMm,
            0.0,
            MAX_TOLERANCE_MM,
        )?;
        check_common(self.max_iterations, self.corner_sigma_px)
    }
}

/// Where a depth solver stopped: this iteration, or `depth_newton`'s.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthIteration {
    /// Final depths z1..z4, mm.
    pub z_mm: [f64; 4],
    /// The method's criterion was met: e_c ≤ e_d within n_max here; for `depth-newton`, the
    /// step fell below its tolerance (or no better point exists).
    pub converged: bool,
    /// Updates applied (`depth-newton`: accepted and rejected steps).
    pub iterations: u32,
    /// e_c (Σ|Δz|) of the last applied update, mm; `None` when none was applied.
    pub convergence_error_mm: Option<f64>,
    /// z and e_c per iteration, when asked for.
    pub trace: Option<Vec<TraceStep>>,
}

/// Camera-frame corners on their rays at depths `z_mm` (Eq. 6).
pub fn corners_at_depths(rays: &[NormalizedPoint; 4], z_mm: &[f64; 4]) -> [CameraPoint; 4] {
    [0, 1, 2, 3].map(|i| rays[i].at_depth(z_mm[i]))
}

/// Condition errors e1..e6 = known − computed length, mm (Eqs. 7, 10, 11).
///
/// Written over plain scalars: this is the inner loop of the paper grid (9 million solves of
/// up to 30 iterations), where array adaptors cost half the time.
pub fn side_errors_mm(rays: &[NormalizedPoint; 4], z_mm: &[f64; 4], marker: &Marker) -> [f64; 6] {
    let mut p = [[0.0; 3]; 4];
    for ((p, ray), z) in p.iter_mut().zip(rays).zip(z_mm) {
        *p = [ray.x() * z, ray.y() * z, *z]; // Eq. 6
    }
    let mut e = [0.0; 6];
    for (e, edge) in e.iter_mut().zip(&EDGES) {
        let (a, b) = (&p[edge.a], &p[edge.b]);
        let length = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt(); // Eq. 7
        *e = marker.edge_length_mm(edge) - length; // Eqs. 10, 11
    }
    e
}

/// One simultaneous update of all four depths (Eq. 12).
fn updated_depths(z_mm: &[f64; 4], e: &[f64; 6], gain: f64) -> [f64; 4] {
    let mut next = *z_mm;
    for (z, incident) in next.iter_mut().zip(&INCIDENT_EDGES) {
        *z += gain * (e[incident[0]] + e[incident[1]] + e[incident[2]]) / 3.0;
    }
    next
}

/// e_c = Σ |z_i(n) − z_i(n−1)| (Eq. 13).
fn convergence_error_mm(z_new: &[f64; 4], z_old: &[f64; 4]) -> f64 {
    z_new.iter().zip(z_old).map(|(a, b)| (a - b).abs()).sum()
}

/// Runs the iteration of docs/paper-method.md on the four rays P1..P4.
///
/// Non-convergence is a result: `converged` is false and the last iterate is returned.
/// Should an update overflow (possible only with large gains and many iterations), the
/// iteration stops at the last finite iterate, unconverged.
pub fn iterate(
    rays: &[NormalizedPoint; 4],
    marker: &Marker,
    params: &PaperParams,
) -> DepthIteration {
    if params.trace {
        let mut steps = Vec::new();
        let mut out = run(rays, marker, params, |step| steps.push(step));
        out.trace = Some(steps);
        out
    } else {
        // A no-op observer, monomorphised away: the depths stay in registers.
        run(rays, marker, params, |_| {})
    }
}

/// The loop of [`iterate`], handing every applied update to `on_step`; `trace` is `None`.
fn run(
    rays: &[NormalizedPoint; 4],
    marker: &Marker,
    params: &PaperParams,
    mut on_step: impl FnMut(TraceStep),
) -> DepthIteration {
    let mut z = [params.initial_z_mm; 4];
    let mut last_e_c = None;
    let mut iterations = 0;
    let mut converged = false;
    for n in 1..=params.max_iterations {
        let e = side_errors_mm(rays, &z, marker);
        let z_next = updated_depths(&z, &e, params.gain);
        let e_c = convergence_error_mm(&z_next, &z);
        if !e_c.is_finite() {
            break;
        }
        z = z_next;
        iterations = n;
        last_e_c = Some(e_c);
        on_step(TraceStep {
            iteration: n,
            z_mm: z,
            convergence_error_mm: e_c,
        });
        if e_c <= params.tolerance_mm {
            converged = true;
            break;
        }
    }
    DepthIteration {
        z_mm: z,
        converged,
        iterations,
        convergence_error_mm: last_e_c,
        trace: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{euler::EulerXyz, frames::MarkerToCamera};
    use nalgebra::Vector3;

    fn rays_for(marker: &Marker, pose: &MarkerToCamera) -> [NormalizedPoint; 4] {
        marker
            .object_points()
            .map(|m| pose.transform(&m).normalized().expect("in front"))
    }

    fn params(gain: f64) -> PaperParams {
        PaperParams {
            initial_z_mm: 450.0,
            gain,
            tolerance_mm: 1.0,
            max_iterations: 30,
            trace: true,
            corner_sigma_px: DEFAULT_CORNER_SIGMA_PX,
        }
    }

    #[test]
    fn side_errors_vanish_at_the_true_depths() {
        let marker = Marker::try_new(50.0).expect("valid size");
        let pose = MarkerToCamera::new(
            EulerXyz::from_degrees(10.0, 5.0, 20.0).to_rotation(),
            Vector3::new(60.0, -50.0, 300.0),
        );
        let rays = rays_for(&marker, &pose);
        let z = marker.object_points().map(|m| pose.transform(&m).0.z);
        for (j, e) in side_errors_mm(&rays, &z, &marker).iter().enumerate() {
            assert!(e.abs() < 1e-12, "e{} = {e} mm", j + 1);
        }
    }

    #[test]
    fn first_update_follows_eq_12_by_hand() {
        // Fronto-parallel marker at 500 mm seen from z0 = 450: every computed length is
        // 450/500 of the true one, so e_j = L_j · (1 − 0.9) and P1's update is
        // k · (l·0.1 + l·0.1 + √2·l·0.1) / 3.
        let marker = Marker::try_new(50.0).expect("valid size");
        let pose = MarkerToCamera::new(
            EulerXyz::new(0.0, 0.0, 0.0).to_rotation(),
            Vector3::new(10.0, 20.0, 500.0),
        );
        let rays = rays_for(&marker, &pose);
        let out = iterate(
            &rays,
            &marker,
            &PaperParams {
                max_iterations: 1,
                ..params(1.0)
            },
        );
        let step = 5.0 * (2.0 + std::f64::consts::SQRT_2) / 3.0;
        for (i, z) in out.z_mm.iter().enumerate() {
            assert!((z - (450.0 + step)).abs() < 1e-9, "z{} = {z} mm", i + 1);
        }
        assert!((out.convergence_error_mm.expect("one step") - 4.0 * step).abs() < 1e-9);
        assert_eq!(out.iterations, 1);
        assert!(!out.converged);
    }

    #[test]
    fn tracing_does_not_change_the_iterates() {
        let marker = Marker::try_new(50.0).expect("valid size");
        for (alpha_deg, gain, max_iterations) in [(0.0, 1.0, 30), (35.0, 1.0, 30), (20.0, 0.7, 200)]
        {
            let pose = MarkerToCamera::new(
                EulerXyz::from_degrees(alpha_deg, 10.0, 15.0).to_rotation(),
                Vector3::new(60.0, -50.0, 300.0),
            );
            let rays = rays_for(&marker, &pose);
            let traced_params = PaperParams {
                max_iterations,
                ..params(gain)
            };
            let traced = iterate(&rays, &marker, &traced_params);
            let plain = iterate(
                &rays,
                &marker,
                &PaperParams {
                    trace: false,
                    ..traced_params
                },
            );
            assert_eq!(plain.trace, None);
            assert_eq!(
                DepthIteration {
                    trace: None,
                    ..traced
                },
                plain,
                "α = {alpha_deg}°, k = {gain}"
            );
        }
    }

    #[test]
    fn converges_on_a_fronto_parallel_marker_and_traces_every_step() {
        let marker = Marker::try_new(50.0).expect("valid size");
        let pose = MarkerToCamera::new(
            EulerXyz::new(0.0, 0.0, 0.0).to_rotation(),
            Vector3::new(0.0, 0.0, 300.0),
        );
        let rays = rays_for(&marker, &pose);
        let out = iterate(&rays, &marker, &params(1.0));
        assert!(out.converged, "{out:?}");
        for z in out.z_mm {
            assert!((z - 300.0).abs() < 5.0, "z = {z} mm");
        }
        let trace = out.trace.expect("trace requested");
        assert_eq!(trace.len(), out.iterations as usize);
        assert_eq!(trace.last().map(|s| s.z_mm), Some(out.z_mm));
        assert!(
            trace
                .last()
                .map(|s| s.convergence_error_mm <= 1.0)
                .unwrap_or(false)
        );
    }

    #[test]
    fn reports_non_convergence_with_the_last_iterate() {
        let marker = Marker::try_new(50.0).expect("valid size");
        let pose = MarkerToCamera::new(
            EulerXyz::from_degrees(60.0, 0.0, 0.0).to_rotation(),
            Vector3::new(80.0, -90.0, 100.0),
        );
        let rays = rays_for(&marker, &pose);
        let out = iterate(
            &rays,
            &marker,
            &PaperParams {
                trace: false,
                ..params(2.0)
            },
        );
        assert!(!out.converged);
        assert_eq!(out.iterations, 30);
        assert!(out.z_mm.iter().all(|z| z.is_finite()));
        assert!(out.trace.is_none());
    }
}
