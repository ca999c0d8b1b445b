//! What a calibration returns: the camera, the parameters' standard deviations, every view's
//! outcome (its pose, residuals and weights, or why it was dropped), the overall
//! reprojection RMS, the image coverage and the warnings.

use crate::input::ImageSize;
use crate::warnings::{Coverage, Warning};
use nalgebra::{Vector2, Vector3};
use qrpose_core::geometry::camera::Camera;
use qrpose_core::geometry::frames::{MarkerToCamera, PixelPoint};

/// A calibrated camera and how well the data determine it.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraCalibration {
    /// The intrinsics fx, fy, cx, cy (px) and the fitted lens, as qrpose-core's camera: the
    /// same model that the pose service applies.
    pub camera: Camera,
    /// One standard deviation of each parameter (see [`ParameterStd`]).
    pub std: ParameterStd,
    /// RMS of the residual lengths over every point of the used views, px (unweighted).
    pub reprojection_rms_px: f64,
    /// Every view given, in the order given.
    pub views: Vec<ViewReport>,
    /// What the data leave poorly constrained; empty for a good set.
    pub warnings: Vec<Warning>,
    /// Where the used points fall in the image.
    pub coverage: Coverage,
    /// The image size calibrated.
    pub image_size: ImageSize,
    /// The robust per-axis noise estimate σ̂ of the final fit, px (`crate::robust`).
    pub robust_sigma_px: f64,
    /// Levenberg-Marquardt iterations of the final fit, over all its robust rounds.
    pub iterations: usize,
}

impl CameraCalibration {
    /// The views used in the final fit.
    pub fn used_views(&self) -> impl Iterator<Item = &ViewReport> {
        self.views.iter().filter(|v| v.is_used())
    }

    /// The views dropped.
    pub fn dropped_views(&self) -> impl Iterator<Item = &ViewReport> {
        self.views.iter().filter(|v| !v.is_used())
    }
}

/// One standard deviation of each intrinsic parameter, from the cluster-robust covariance
/// S⁻¹·(Σ_g c_g·c_gᵀ)·S⁻¹ at the solution (the crate's `covariance` module): S the
/// intrinsics' block of JᵀWJ with the poses eliminated, c_g the score of the residuals of
/// one patch of one view's target (a cell of a [`crate::BLOCKS_PER_SIDE`]² grid), adjusted
/// for the patch's leverage (CR2), so that errors shared by neighbouring points are counted.
/// `f64::INFINITY` when the data leave the parameters undetermined (the normal matrix is
/// singular, or there are no more residuals than unknowns).
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterStd {
    /// Of fx, px.
    pub fx_px: f64,
    /// Of fy, px.
    pub fy_px: f64,
    /// Of cx, px.
    pub cx_px: f64,
    /// Of cy, px.
    pub cy_px: f64,
    /// Of each distortion coefficient, in the model's order (dimensionless).
    pub coefficients: Vec<f64>,
}

/// One view: its index among those given, its point count, and what became of it.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewReport {
    /// Its index among the views given, 0-based.
    pub index: usize,
    /// How many correspondences it had.
    pub points: usize,
    /// Used, or dropped and why.
    pub outcome: ViewOutcome,
}

impl ViewReport {
    /// Whether it was used in the final fit.
    #[must_use]
    pub fn is_used(&self) -> bool {
        matches!(self.outcome, ViewOutcome::Used(_))
    }

    /// Its fit: in the final fit when used, in the fit that dropped it otherwise (`None`
    /// when its homography failed).
    #[must_use]
    pub fn fit(&self) -> Option<&ViewFit> {
        match &self.outcome {
            ViewOutcome::Used(fit) => Some(fit),
            ViewOutcome::Dropped { fit, .. } => fit.as_ref(),
        }
    }

    /// Why it was dropped, if it was.
    #[must_use]
    pub fn drop_reason(&self) -> Option<DropReason> {
        match &self.outcome {
            ViewOutcome::Used(_) => None,
            ViewOutcome::Dropped { reason, .. } => Some(*reason),
        }
    }
}

/// What became of a view.
#[derive(Debug, Clone, PartialEq)]
pub enum ViewOutcome {
    /// Used in the final fit.
    Used(ViewFit),
    /// Left out of the final fit.
    Dropped {
        /// Why.
        reason: DropReason,
        /// Its fit when it was dropped (`None` when its homography failed).
        fit: Option<ViewFit>,
    },
}

/// Why a view was dropped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DropReason {
    /// Its points admit no homography (collinear or coincident target points, or a
    /// degenerate image of them): the closed form cannot use it.
    HomographyFailed,
    /// Its median residual is far above the other views' (see `crate::DROP_RATIO` and
    /// `crate::DROP_FLOOR_PX`): wrong correspondences, a moved or bent target, motion blur.
    PoorFit {
        /// Its median residual length, px.
        median_px: f64,
        /// Its RMS residual length, px.
        rms_px: f64,
        /// The limit it exceeded, px.
        limit_px: f64,
    },
}

impl DropReason {
    /// The reason's stable name: `homography_failed` or `poor_fit`.
    #[must_use]
    pub const fn name(&self) -> &'static str {
        match self {
            Self::HomographyFailed => "homography_failed",
            Self::PoorFit { .. } => "poor_fit",
        }
    }
}

impl std::fmt::Display for DropReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::HomographyFailed => f.write_str("its points admit no homography"),
            Self::PoorFit {
                median_px,
                rms_px,
                limit_px,
            } => write!(
                f,
                "median residual {median_px:.2} px (RMS {rms_px:.2} px) above the limit of {limit_px:.2} px"
            ),
        }
    }
}

/// A view's pose and residuals under a fit.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewFit {
    /// The target's pose: `p_cam = R · p_target + t`, t in mm.
    pub pose: MarkerToCamera,
    /// RMS of its residual lengths, px.
    pub rms_px: f64,
    /// Median of its residual lengths, px.
    pub median_px: f64,
    /// Each point's measured pixel, px, in the view's order (the view's `pixel_px`).
    pub measured_px: Vec<PixelPoint>,
    /// Each point's residual, projected minus measured, px, in the view's order.
    pub residuals_px: Vec<Vector2<f64>>,
    /// Each point's robust weight in (0, 1] (1: a full inlier), in the view's order.
    pub weights: Vec<f64>,
}

/// One point of a view under a fit: where it was measured, how far the fitted camera and
/// pose put it from there, and how much the robust loss let it count.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointFit {
    /// Where it was measured, px.
    pub measured_px: PixelPoint,
    /// Its residual: the target point projected by the fitted camera and the view's pose,
    /// minus `measured_px`, px.
    pub residual_px: Vector2<f64>,
    /// Its robust weight in (0, 1]: 1 while the residual is within Huber's threshold
    /// ([`crate::HUBER_K`] times the fit's noise estimate), threshold / length beyond it.
    pub weight: f64,
}

impl PointFit {
    /// Where the fit puts it: `measured_px + residual_px`, px.
    #[must_use]
    pub fn projected_px(&self) -> PixelPoint {
        PixelPoint(self.measured_px.0 + self.residual_px)
    }

    /// Whether it counted fully (weight 1): not down-weighted as an outlier.
    #[must_use]
    pub fn is_inlier(&self) -> bool {
        self.weight >= 1.0
    }
}

impl ViewFit {
    /// Each point's measurement, residual and weight, in the view's order.
    pub fn points(&self) -> impl ExactSizeIterator<Item = PointFit> + '_ {
        self.measured_px
            .iter()
            .zip(&self.residuals_px)
            .zip(&self.weights)
            .map(|((measured_px, residual_px), weight)| PointFit {
                measured_px: *measured_px,
                residual_px: *residual_px,
                weight: *weight,
            })
    }

    /// The pose's rotation as a rotation vector (axis × angle), rad.
    #[must_use]
    pub fn rotation_vector_rad(&self) -> Vector3<f64> {
        self.pose.0.rotation.scaled_axis()
    }

    /// The pose's translation (the target origin in the camera frame), mm.
    #[must_use]
    pub fn translation_mm(&self) -> Vector3<f64> {
        self.pose.translation_mm()
    }
}
