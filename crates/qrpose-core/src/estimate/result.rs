//! What an estimate returns: the pose, its diagnostics and warnings, and why no pose could be
//! produced ([`EstimateError`]).

use super::solver::{Method, SolverParam};
use crate::geometry::{
    camera::CameraError,
    frames::{CameraPoint, MarkerToCamera},
};
use nalgebra::{Matrix6, Vector3};
use thiserror::Error;

/// A reprojection RMS above this multiple of the stated corner noise raises
/// [`Warning::HighReprojectionError`].
pub const HIGH_RMS_SIGMAS: f64 = 4.0;

/// Why no pose could be produced.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum EstimateError {
    /// A solver parameter is outside its range (or not finite): refused rather than run.
    #[error("solver parameter {param} = {value} is outside ({min_exclusive}, {max}]")]
    ParamOutOfRange {
        /// The parameter.
        param: SolverParam,
        /// The value given.
        value: f64,
        /// Values must be greater than this.
        min_exclusive: f64,
        /// Values must be at most this.
        max: f64,
    },
    /// A corner could not be undistorted: the lens model has no inverse there.
    #[error("corner {index}: {source}")]
    Undistortion {
        /// The corner, as an index into the caller's list.
        index: usize,
        /// What the camera model said.
        source: CameraError,
    },
    /// Fewer than four plane points, or model and image lists of different lengths.
    #[error("need at least 4 matching points, got {model} model and {image} image points")]
    PointCount {
        /// Model points given.
        model: usize,
        /// Image points given.
        image: usize,
    },
    /// The corners admit no pose: the closed-form step or the rigid fit is degenerate (for
    /// `paper`, the iteration collapsed the corners onto a line or a point).
    #[error("no pose fits these corners ({reason})")]
    NoSolution {
        /// Which step failed.
        reason: &'static str,
    },
}

/// One iteration of the trace: corner depths and e_c (Σ|Δz|) after the update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceStep {
    /// 1-based iteration number.
    pub iteration: u32,
    /// z1..z4 after this iteration, mm.
    pub z_mm: [f64; 4],
    /// Σ_i |z_i(n) − z_i(n−1)|, mm (Eq. 13).
    pub convergence_error_mm: f64,
}

/// The other candidate of the planar ambiguity, after its own refinement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ambiguity {
    /// The alternative pose (translation: P2, mm).
    pub alternative: MarkerToCamera,
    /// Its reprojection RMS, image units.
    pub alternative_rms: f64,
    /// Best RMS / alternative RMS, in [0, 1]; near 1 when the two cannot be told apart.
    pub ratio: f64,
    /// Angle between the two rotations, radians.
    pub rotation_difference_rad: f64,
    /// Posterior probability that the alternative is the true pose, for the stated corner
    /// noise (pixel cameras only); 0 when the two candidates are one pose.
    pub alternative_probability: Option<f64>,
    /// The rotations differ by more than [`DISTINCT_ROTATION_DEG`](super::reprojection::DISTINCT_ROTATION_DEG) and the alternative's
    /// probability reaches [`AMBIGUITY_PROBABILITY_THRESHOLD`](super::reprojection::AMBIGUITY_PROBABILITY_THRESHOLD) (or, without pixel units, the
    /// ratio reaches [`AMBIGUITY_FALLBACK_RATIO`](super::reprojection::AMBIGUITY_FALLBACK_RATIO)).
    pub ambiguous: bool,
}

/// Conditions a caller should know about before trusting the pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Warning {
    /// The method stopped at its iteration limit.
    NotConverged,
    /// The two poses of the planar ambiguity fit about equally well.
    PoseAmbiguous,
    /// A solved corner lies at or behind the camera: the pose is not physical.
    BehindCamera,
    /// The reprojection RMS exceeds [`HIGH_RMS_SIGMAS`] × the stated corner noise.
    HighReprojectionError,
}

/// How the estimate was reached and how far to trust it.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnostics {
    /// The method used.
    pub method: Method,
    /// Whether the method met its convergence criterion.
    pub converged: bool,
    /// Iterations run.
    pub iterations: u32,
    /// The last Σ|Δz| (e_c), mm (`paper`, `depth-newton`).
    pub convergence_error_mm: Option<f64>,
    /// e1..e6 = known − computed edge length at the final depths, mm (`paper`,
    /// `depth-newton`).
    pub side_residuals_mm: Option<[f64; 6]>,
    /// RMS corner reprojection error of the reported pose, image units; `None` when a
    /// corner of the pose is at or behind the camera.
    pub reprojection_rms: Option<f64>,
    /// The planar ambiguity (`reprojection`).
    pub ambiguity: Option<Ambiguity>,
    /// 6×6 covariance of (rx, ry, rz rad; x, y, z mm of the centre) for the stated corner
    /// noise (`reprojection` with a pixel camera).
    pub covariance: Option<Matrix6<f64>>,
    /// Per-iteration trace, when asked for.
    pub trace: Option<Vec<TraceStep>>,
    /// What deserves a caller's attention.
    pub warnings: Vec<Warning>,
}

/// A pose and how it was found.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseEstimate {
    /// Marker-to-camera pose; its translation is P2 (the marker origin), mm.
    pub pose: MarkerToCamera,
    /// The marker centre in the camera frame, mm.
    pub centre_mm: Vector3<f64>,
    /// Corners P1..P4 in the camera frame, mm: as the iteration left them (`paper`,
    /// `depth-newton`) or the model under the pose (`reprojection`).
    pub corners_cam: [CameraPoint; 4],
    /// Diagnostics.
    pub diagnostics: Diagnostics,
}
