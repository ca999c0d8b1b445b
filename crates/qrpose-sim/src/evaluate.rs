//! Whether a method solves one simulated case (docs/paper-method.md, The paper's simulation).
//!
//! A case is solved when the method converged **and** max(|Δα|, |Δβ|, |Δγ|) ≤ 2° **and**
//! max_i |z_i − z_i,true| ≤ 5 mm, with z_i the depths the method produced (for `paper` and
//! `depth-newton` from the iteration, before the rigid fit; for `reprojection` the model
//! corners under the pose). The paper method is given the paper's gain sweep: solved if any
//! k ∈ {0.8, …, 2.0} solves it.

use super::grid::{Case, GAINS};
use qrpose_core::estimate::{
    DEFAULT_GAIN, Method, PaperParams, PoseEstimate, Solver, ValidSolver, estimate_from_rays,
};
use qrpose_core::geometry::{
    camera::Camera,
    euler::EulerXyz,
    frames::{NormalizedPoint, PixelPoint},
    marker::Marker,
};
use std::f64::consts::PI;

/// Largest angle error of a solved case, degrees (the paper's 2°).
pub const MAX_ANGLE_ERROR_DEG: f64 = 2.0;
/// Largest corner depth error of a solved case, mm (the paper's 5 mm).
pub const MAX_DEPTH_ERROR_MM: f64 = 5.0;

/// How one method did on one case.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// Converged within tolerance of the truth (docs/paper-method.md, The paper's simulation).
    pub solved: bool,
    /// For `paper`: the first gain that solved the case, if any.
    pub gain: Option<f64>,
    /// The estimate judged: the solving one, else the one at the default gain; `None` when
    /// the estimator refused the input.
    pub estimate: Option<PoseEstimate>,
    /// max(|Δα|, |Δβ|, |Δγ|) of that estimate, degrees (∞ without an estimate).
    pub angle_error_deg: f64,
    /// max_i |z_i − z_i,true| of that estimate, mm (∞ without an estimate).
    pub depth_error_mm: f64,
}

/// Difference of two angles wrapped into (−π, π].
fn wrapped(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(2.0 * PI);
    if d > PI { d - 2.0 * PI } else { d }
}

/// max(|Δα|, |Δβ|, |Δγ|), degrees.
pub fn euler_error_deg(estimate: &EulerXyz, truth: &EulerXyz) -> f64 {
    [
        wrapped(estimate.alpha, truth.alpha),
        wrapped(estimate.beta, truth.beta),
        wrapped(estimate.gamma, truth.gamma),
    ]
    .iter()
    .map(|d| d.abs().to_degrees())
    .fold(0.0, f64::max)
}

/// Angle and depth errors of an estimate against a case's truth.
pub fn errors(estimate: &PoseEstimate, case: &Case, marker: &Marker) -> (f64, f64) {
    let angle = euler_error_deg(
        &EulerXyz::from_rotation(&estimate.pose.rotation()),
        &case.euler(),
    );
    let truth = case.true_depths_mm(marker);
    let depth = estimate
        .corners_cam
        .iter()
        .zip(truth)
        .map(|(p, z)| (p.0.z - z).abs())
        .fold(0.0, f64::max);
    (angle, if depth.is_nan() { f64::INFINITY } else { depth })
}

fn judge(estimate: PoseEstimate, case: &Case, marker: &Marker, gain: Option<f64>) -> Outcome {
    let (angle_error_deg, depth_error_mm) = errors(&estimate, case, marker);
    let solved = estimate.diagnostics.converged
        && angle_error_deg <= MAX_ANGLE_ERROR_DEG
        && depth_error_mm <= MAX_DEPTH_ERROR_MM;
    Outcome {
        solved,
        gain: gain.filter(|_| solved),
        estimate: Some(estimate),
        angle_error_deg,
        depth_error_mm,
    }
}

/// The outcome of a case the estimator refused (or that could not be projected).
pub fn refused() -> Outcome {
    Outcome {
        solved: false,
        gain: None,
        estimate: None,
        angle_error_deg: f64::INFINITY,
        depth_error_mm: f64::INFINITY,
    }
}

/// Runs `method` on the image-plane corners P1..P4 of `case` (exact or noisy) and judges the
/// result, with the method's default parameters (for `paper`, every gain of [`GAINS`]).
pub fn evaluate(
    case: &Case,
    corners_mm: &[PixelPoint; 4],
    camera: &Camera,
    marker: &Marker,
    method: Method,
) -> Outcome {
    let mut rays = [NormalizedPoint::new(0.0, 0.0); 4];
    for (r, p) in rays.iter_mut().zip(corners_mm) {
        match camera.normalize(p) {
            Ok(n) => *r = n,
            Err(_) => return refused(),
        }
    }
    if method != Method::Paper {
        return match estimate_from_rays(&rays, camera, marker, &ValidSolver::default_for(method)) {
            Ok(e) => judge(e, case, marker, None),
            Err(_) => refused(),
        };
    }
    let mut fallback = None;
    for k in GAINS {
        let solver = Solver::Paper(PaperParams {
            gain: k,
            ..PaperParams::default()
        });
        let Ok(estimate) = solver
            .validate()
            .and_then(|solver| estimate_from_rays(&rays, camera, marker, &solver))
        else {
            continue;
        };
        let outcome = judge(estimate, case, marker, Some(k));
        if outcome.solved {
            return outcome;
        }
        if (k - DEFAULT_GAIN).abs() < 1e-12 {
            fallback = Some(outcome);
        }
    }
    fallback.unwrap_or_else(refused)
}

#[cfg(test)]
mod tests {
    use super::super::grid::{FOCAL_LENGTH_MM, MARKER_SIZE_MM, rotation_set};
    use super::*;
    use nalgebra::Vector3;

    fn paper_setup() -> (Camera, Marker) {
        (
            Camera::image_plane_mm(FOCAL_LENGTH_MM).expect("valid camera"),
            Marker::try_new(MARKER_SIZE_MM).expect("valid size"),
        )
    }

    #[test]
    fn angle_errors_wrap_around() {
        let a = EulerXyz::from_degrees(179.0, 0.0, -179.0);
        let b = EulerXyz::from_degrees(-179.0, 0.0, 179.0);
        assert!((euler_error_deg(&a, &b) - 2.0).abs() < 1e-9);
    }

    #[test]
    fn exact_methods_solve_a_tilted_case_the_paper_method_may_not() {
        let (camera, marker) = paper_setup();
        let set = rotation_set("5-Y-5").expect("known set");
        let case = Case {
            p2_mm: Vector3::new(-100.0, 100.0, 100.0),
            set,
            angle_deg: 25.0,
        };
        let corners = case
            .image_plane_corners_mm(&marker, FOCAL_LENGTH_MM)
            .expect("in front");
        for method in [Method::DepthNewton, Method::Reprojection] {
            let o = evaluate(&case, &corners, &camera, &marker, method);
            assert!(
                o.solved && o.angle_error_deg < 1e-6 && o.depth_error_mm < 1e-6,
                "{method:?}: {o:?}"
            );
        }
    }

    #[test]
    fn paper_method_reports_the_first_solving_gain() {
        let (camera, marker) = paper_setup();
        let set = rotation_set("0-0-Z").expect("known set");
        let case = Case {
            p2_mm: Vector3::new(0.0, 0.0, 300.0),
            set,
            angle_deg: 10.0,
        };
        let corners = case
            .image_plane_corners_mm(&marker, FOCAL_LENGTH_MM)
            .expect("in front");
        let o = evaluate(&case, &corners, &camera, &marker, Method::Paper);
        assert!(o.solved, "{o:?}");
        assert_eq!(
            o.gain,
            Some(0.8),
            "rotation in the image plane leaves the lengths alone"
        );
    }
}
