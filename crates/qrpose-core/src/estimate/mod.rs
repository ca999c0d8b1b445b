//! Pose of a square marker from its four image corners: three methods behind one call.
//!
//! - [`Method::Paper`]: the paper's iteration as printed (`docs/paper-method.md`,
//!   [`iterative`]), then a rigid (Kabsch) fit of the model onto the iterated corners
//!   ([`fit`]).
//! - [`Method::DepthNewton`]: the same unknowns and residuals solved by Levenberg-Marquardt
//!   ([`depth_newton`]), then the same fit.
//! - [`Method::Reprojection`] (default): both IPPE candidates of the planar ambiguity
//!   ([`ippe`]), each refined on pixel reprojection error ([`refine`]); the better is
//!   reported with the other's error, and a covariance for a given corner noise
//!   ([`reprojection`]).
//!
//! A [`Solver`] names the method and carries its parameters; it is validated once into a
//! [`ValidSolver`], which is what the entry points take. Entry points: [`estimate_pose`] for
//! validated image corners, [`estimate_from_rays`] for corners already normalised,
//! [`estimate_planar_points`] for more than four points of the marker plane.

pub mod depth_newton;
pub mod fit;
pub mod ippe;
pub mod iterative;
pub mod lm;
pub mod refine;
pub mod reprojection;
pub mod result;
pub mod solver;

pub use depth_newton::DepthNewtonParams;
pub use iterative::{
    DEFAULT_GAIN, DEFAULT_INITIAL_Z_MM, DEFAULT_TOLERANCE_MM, MAX_GAIN, MAX_TOLERANCE_MM,
    PaperParams,
};
pub use reprojection::{
    AMBIGUITY_FALLBACK_RATIO, AMBIGUITY_PROBABILITY_THRESHOLD, DISTINCT_ROTATION_DEG,
    ReprojectionParams, estimate_planar_points,
};
pub use result::{
    Ambiguity, Diagnostics, EstimateError, HIGH_RMS_SIGMAS, PoseEstimate, TraceStep, Warning,
};
pub use solver::{
    DEFAULT_CORNER_SIGMA_PX, DEFAULT_MAX_ITERATIONS, MAX_CORNER_SIGMA_PX, MAX_INITIAL_Z_MM,
    MAX_ITERATIONS_LIMIT, Method, Solver, SolverParam, ValidSolver,
};

use crate::geometry::marker::Marker;
use crate::geometry::{
    camera::{Camera, ImageUnit},
    frames::NormalizedPoint,
    quad::ImageQuad,
};

/// Estimates the marker's pose from four validated image corners.
///
/// # Errors
/// [`EstimateError::Undistortion`] when a corner cannot be undistorted,
/// [`EstimateError::NoSolution`] when no pose fits. Non-convergence is not an error: see
/// [`Diagnostics::converged`].
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use qrpose_core::estimate::{estimate_pose, ValidSolver};
/// use qrpose_core::geometry::{camera::Camera, euler::EulerXyz, frames::MarkerToCamera,
///                             marker::{CornerOrder, Marker}, quad::ImageQuad};
///
/// let camera = Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5)?;
/// let marker = Marker::try_new(50.0)?;
/// let truth = MarkerToCamera::new(EulerXyz::from_degrees(20.0, -10.0, 5.0).to_rotation(),
///                                 Vector3::new(60.0, -50.0, 400.0));
/// let corners = marker.object_points().map(|m| camera.project(&truth.transform(&m)).unwrap());
/// let quad = ImageQuad::try_new(corners, CornerOrder::Paper)?;
/// let estimate = estimate_pose(&quad, &camera, &marker, &ValidSolver::default())?;
/// assert!((estimate.pose.translation_mm() - truth.translation_mm()).norm() < 1e-6);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn estimate_pose(
    quad: &ImageQuad,
    camera: &Camera,
    marker: &Marker,
    solver: &ValidSolver,
) -> Result<PoseEstimate, EstimateError> {
    let mut rays = [NormalizedPoint::new(0.0, 0.0); 4];
    for (i, p) in quad.paper_order().iter().enumerate() {
        rays[i] = camera
            .normalize(p)
            .map_err(|source| EstimateError::Undistortion {
                index: quad.order().input_index(i),
                source,
            })?;
    }
    estimate_from_rays(&rays, camera, marker, solver)
}

/// Estimates the pose from undistorted normalised corners P1..P4. The camera supplies the
/// pixel scale of the reprojection error.
///
/// # Errors
/// [`EstimateError::NoSolution`] when no pose fits.
pub fn estimate_from_rays(
    rays: &[NormalizedPoint; 4],
    camera: &Camera,
    marker: &Marker,
    solver: &ValidSolver,
) -> Result<PoseEstimate, EstimateError> {
    let mut estimate = match solver.solver() {
        Solver::Paper(params) => {
            let depths = iterative::iterate(rays, marker, params);
            from_depths(rays, camera, marker, Method::Paper, depths)?
        }
        Solver::DepthNewton(params) => {
            let depths = depth_newton::solve(rays, marker, params);
            from_depths(rays, camera, marker, Method::DepthNewton, depths)?
        }
        Solver::Reprojection(params) => {
            reprojection::by_reprojection(rays, camera, marker, params)?
        }
    };
    add_warnings(&mut estimate, camera, solver.solver().corner_sigma_px());
    Ok(estimate)
}

/// Adds the [`Warning`]s an estimate deserves; `corner_sigma_px` scales the reprojection
/// warning.
fn add_warnings(estimate: &mut PoseEstimate, camera: &Camera, corner_sigma_px: f64) {
    let d = &mut estimate.diagnostics;
    if !d.converged {
        d.warnings.push(Warning::NotConverged);
    }
    if d.ambiguity.is_some_and(|a| a.ambiguous) {
        d.warnings.push(Warning::PoseAmbiguous);
    }
    let behind = estimate
        .corners_cam
        .iter()
        .any(|p| p.0.z.is_nan() || p.0.z <= 0.0);
    if behind || d.reprojection_rms.is_none() {
        d.warnings.push(Warning::BehindCamera);
    }
    let sigma = match camera.unit() {
        ImageUnit::Pixel => Some(corner_sigma_px),
        ImageUnit::ImagePlaneMm => None,
    };
    if let (Some(rms), Some(sigma)) = (d.reprojection_rms, sigma)
        && rms > HIGH_RMS_SIGMAS * sigma
    {
        d.warnings.push(Warning::HighReprojectionError);
    }
}

/// Builds the estimate of the depth-based methods: corners from Eq. 6 and a rigid fit.
fn from_depths(
    rays: &[NormalizedPoint; 4],
    camera: &Camera,
    marker: &Marker,
    method: Method,
    depths: iterative::DepthIteration,
) -> Result<PoseEstimate, EstimateError> {
    let corners_cam = iterative::corners_at_depths(rays, &depths.z_mm);
    let pose = fit::fit_rigid(marker, &corners_cam).ok_or(EstimateError::NoSolution {
        reason: "the solved corners are collinear",
    })?;
    let centre_mm = pose.transform(&marker.centre()).0.coords;
    Ok(PoseEstimate {
        pose,
        centre_mm,
        corners_cam,
        diagnostics: Diagnostics {
            method,
            converged: depths.converged,
            iterations: depths.iterations,
            convergence_error_mm: depths.convergence_error_mm,
            side_residuals_mm: Some(iterative::side_errors_mm(rays, &depths.z_mm, marker)),
            reprojection_rms: fit::reprojection_rms(camera, marker, &pose, rays),
            ambiguity: None,
            covariance: None,
            trace: depths.trace,
            warnings: Vec::new(),
        },
    })
}
