//! The calibration on the wire: `POST /v1/calibrate` (the photos as repeated multipart parts
//! `image`, the [`CalibrateRequest`] as the part `request`) and `qrpose calibrate`, both
//! through [`respond`], so their JSON is the same field for field.
//!
//! The answer ([`CalibrateResponse`]) carries the camera as a pose request takes it (pixel
//! form, the distortion's model and named coefficients), one standard deviation per parameter, every
//! photo's view (used or why not, with each point's measurement, residual and robust
//! weight), the warnings, the image coverage and the two calibration files the site file
//! reads as they are (`opencv_yaml`, `ros_camera_info_yaml`; docs/calibration.md).

use super::camera::{CameraDto, DistortionModelDto};
use super::image::response::ImageSizeDto;
use super::problem::Problem;
use super::refusal::problem_from_calibrate_error;
use super::request::MarkerDto;
use crate::app::{CalibrateAnswer, CalibrateSetup, ImageLimits, PhotoReport, calibrate_photos};
use crate::detect::CancelFlag;
use crate::geometry::camera::DistortionModel;
use qrpose_calib::{ViewReport, Warning};
use qrpose_site::calibration::{opencv_yaml, ros_camera_info_yaml};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use utoipa::ToSchema;

/// The `camera_name` of the ROS file written.
pub const ROS_CAMERA_NAME: &str = "qrpose";

/// What to calibrate: the printed code's size and the lens model to fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"marker": {"size_mm": 100.0}, "model": "plumb_bob"}))]
pub struct CalibrateRequest {
    /// The printed code in every photo.
    pub marker: MarkerDto,
    /// The lens model to fit, as the site file names it: `plumb_bob` (the default),
    /// `rational_polynomial` or `equidistant`.
    #[serde(default)]
    pub model: DistortionModelDto,
}

impl CalibrateRequest {
    /// The request validated into the application's setup, with the image limits and the
    /// detection deadline of a photo request.
    ///
    /// # Errors
    /// `invalid_marker_size` at `/marker/size_mm`.
    pub fn setup(&self, limits: &ImageLimits) -> Result<CalibrateSetup, Problem> {
        Ok(CalibrateSetup {
            marker: self.marker.to_marker()?,
            model: self.model.into(),
            decode: limits.decode,
            max_detect: limits.max_detect,
        })
    }
}

impl From<DistortionModel> for DistortionModelDto {
    fn from(m: DistortionModel) -> Self {
        match m {
            DistortionModel::PlumbBob => Self::PlumbBob,
            DistortionModel::RationalPolynomial => Self::RationalPolynomial,
            DistortionModel::Equidistant => Self::Equidistant,
        }
    }
}

/// One standard deviation of each parameter, from the covariance at the solution; null
/// where the photos leave the parameter undetermined.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CalibrationStdDto {
    /// Of fx, px.
    pub fx_px: Option<f64>,
    /// Of fy, px.
    pub fy_px: Option<f64>,
    /// Of cx, px.
    pub cx_px: Option<f64>,
    /// Of cy, px.
    pub cy_px: Option<f64>,
    /// Of each distortion coefficient of the model, by the name `camera.distortion` gives
    /// it (`k1`, `p1`, …).
    pub distortion: BTreeMap<String, Option<f64>>,
}

/// One calibration point of a photo: where it was measured and, under the fit, its residual
/// and robust weight (for drawing: the point at `image_px`, the fitted camera's projection
/// of it at `image_px + residual_px`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({"image_px": [212.37, 148.91], "residual_px": [0.031, -0.018], "weight": 1.0}))]
pub struct CalibrationPointDto {
    /// Where it was measured in the photo, px (u right, v down, integer coordinates at pixel
    /// centres: docs/conventions.md, Pixels).
    #[schema(min_items = 2, max_items = 2)]
    pub image_px: [f64; 2],
    /// The target point projected by the calibrated camera and the view's pose, minus
    /// `image_px`, px, under the fit that used or dropped the view; null when the view has
    /// no fit (`too_few_points`, `homography_failed`).
    #[schema(min_items = 2, max_items = 2)]
    pub residual_px: Option<[f64; 2]>,
    /// Its robust (Huber) weight in that fit, in (0, 1]: 1 for a full inlier, below 1 for a
    /// point down-weighted as an outlier (its residual beyond 2.5 times the fit's noise
    /// estimate); null without a fit.
    pub weight: Option<f64>,
}

/// One photo's view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CalibrationViewDto {
    /// The photo's index among the `image` parts, 0-based.
    pub index: usize,
    /// Whether its view is in the final fit.
    pub used: bool,
    /// Its calibration points (0 without a code).
    pub points: usize,
    /// RMS of its residuals under the fit that used or dropped it, px; null without one.
    pub rms_px: Option<f64>,
    /// Median of its residual lengths, px; null without a fit.
    pub median_px: Option<f64>,
    /// QR codes decoded in the photo.
    pub codes_decoded: usize,
    /// The payload of the code used.
    pub payload: Option<String>,
    /// Why it is not used: `no_code` (no code decoded), `too_few_points`,
    /// `homography_failed`, `poor_fit` (its residuals far above the other views'); null
    /// when used.
    pub dropped: Option<String>,
    /// The reason in words; null when used.
    pub detail: Option<String>,
    /// Its calibration points, as many as `points`, in the order measured: each with its
    /// residual and weight when the view has a fit.
    pub image_points: Vec<CalibrationPointDto>,
}

/// Something the photos leave poorly constrained (docs/calibration.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum CalibrationWarningDto {
    /// Fewer than 6 views used.
    TooFewViews,
    /// Every view sees the code from about one angle (normals within 15°).
    SingleAngle,
    /// No points near some image corners: the distortion there is extrapolated.
    CornersNotCovered,
    /// The standard deviation of fx or fy is above 0.5 % of it.
    FocalLengthUncertain,
    /// Zhang's closed form needed an assumption to start.
    ClosedFormFallback,
    /// The refinement spent its iteration budget.
    NotConverged,
}

impl From<&Warning> for CalibrationWarningDto {
    fn from(w: &Warning) -> Self {
        match w {
            Warning::TooFewViews { .. } => Self::TooFewViews,
            Warning::SingleAngle { .. } => Self::SingleAngle,
            Warning::CornersNotCovered { .. } => Self::CornersNotCovered,
            Warning::FocalLengthUncertain { .. } => Self::FocalLengthUncertain,
            Warning::ClosedFormFallback { .. } => Self::ClosedFormFallback,
            Warning::NotConverged { .. } => Self::NotConverged,
        }
    }
}

/// A warning with its numbers, in words.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CalibrationWarningDetailDto {
    /// The warning.
    pub code: CalibrationWarningDto,
    /// What it means for these photos.
    pub detail: String,
}

/// Used points per cell of a grid over the image.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct CoverageDto {
    /// Cells per side.
    pub grid: usize,
    /// Points per cell, row-major from the top-left cell.
    pub counts: Vec<usize>,
}

/// Time per stage, ms.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CalibrationTimingDto {
    /// Decoding every photo, finding its codes and measuring their points, ms.
    pub detect: f64,
    /// The solve, ms.
    pub solve: f64,
}

/// The calibrated camera and how well the photos determine it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CalibrateResponse {
    /// The camera: use it as it is in a pose request's `camera`, or through the files below
    /// in a site file.
    pub camera: CameraDto,
    /// One standard deviation of each parameter.
    pub std: CalibrationStdDto,
    /// RMS of the residual lengths over every point of the used views, px.
    pub reprojection_rms_px: f64,
    /// The photos' size.
    pub image: ImageSizeDto,
    /// Every photo, in the order given.
    pub views: Vec<CalibrationViewDto>,
    /// What the photos leave poorly constrained; empty for a good set.
    pub warnings: Vec<CalibrationWarningDto>,
    /// The warnings with their numbers, in words, in the same order.
    pub warning_details: Vec<CalibrationWarningDetailDto>,
    /// Where the used points fall in the image.
    pub coverage: CoverageDto,
    /// The camera as an OpenCV `FileStorage` YAML file (`cameras.ID.calibration` of a site
    /// file reads it as it is).
    pub opencv_yaml: String,
    /// The camera as a ROS `camera_info` YAML file (read as it is too).
    pub ros_camera_info_yaml: String,
    /// Time per stage, ms.
    pub timing_ms: CalibrationTimingDto,
}

/// A finite number, or null.
fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// A photo's view on the wire: from its calibration view when it gave one.
fn view_dto(photo: &PhotoReport, views: &[ViewReport]) -> CalibrationViewDto {
    let view = photo.view.and_then(|k| views.get(k));
    let fit = view.and_then(ViewReport::fit);
    let (dropped, detail) = match view {
        Some(v) => match v.drop_reason() {
            Some(reason) => (Some(reason.name().to_owned()), Some(reason.to_string())),
            None => (None, None),
        },
        None if photo.codes_decoded == 0 => (
            Some("no_code".to_owned()),
            Some("no QR code was decoded in the photo".to_owned()),
        ),
        None => (
            Some("too_few_points".to_owned()),
            Some(format!(
                "its code gave {} calibration points, fewer than {}: too small, too blurred or cut off",
                photo.points.len(),
                qrpose_calib::MIN_POINTS_PER_VIEW
            )),
        ),
    };
    let image_points = match fit {
        Some(f) => f
            .points()
            .map(|p| CalibrationPointDto {
                image_px: [p.measured_px.u(), p.measured_px.v()],
                residual_px: Some([p.residual_px.x, p.residual_px.y]),
                weight: Some(p.weight),
            })
            .collect(),
        None => photo
            .points
            .iter()
            .map(|p| CalibrationPointDto {
                image_px: [p.pixel_px.u(), p.pixel_px.v()],
                residual_px: None,
                weight: None,
            })
            .collect(),
    };
    CalibrationViewDto {
        index: photo.index,
        used: view.is_some_and(ViewReport::is_used),
        points: photo.points.len(),
        rms_px: fit.map(|f| f.rms_px),
        median_px: fit.map(|f| f.median_px),
        codes_decoded: photo.codes_decoded,
        payload: photo.payload.clone(),
        dropped,
        detail,
        image_points,
    }
}

impl From<&CalibrateAnswer> for CalibrateResponse {
    fn from(answer: &CalibrateAnswer) -> Self {
        let c = &answer.calibration;
        let size = c.image_size;
        let std = &c.std;
        CalibrateResponse {
            camera: CameraDto::from(&c.camera),
            std: CalibrationStdDto {
                fx_px: finite(std.fx_px),
                fy_px: finite(std.fy_px),
                cx_px: finite(std.cx_px),
                cy_px: finite(std.cy_px),
                distortion: c
                    .camera
                    .distortion()
                    .model()
                    .params()
                    .iter()
                    .zip(&std.coefficients)
                    .map(|(param, s)| (param.name().to_owned(), finite(*s)))
                    .collect(),
            },
            reprojection_rms_px: c.reprojection_rms_px,
            image: ImageSizeDto {
                width_px: size.width_px as usize,
                height_px: size.height_px as usize,
            },
            views: answer
                .photos
                .iter()
                .map(|p| view_dto(p, &c.views))
                .collect(),
            warnings: c.warnings.iter().map(CalibrationWarningDto::from).collect(),
            warning_details: c
                .warnings
                .iter()
                .map(|w| CalibrationWarningDetailDto {
                    code: w.into(),
                    detail: w.to_string(),
                })
                .collect(),
            coverage: CoverageDto {
                grid: c.coverage.grid,
                counts: c.coverage.counts.clone(),
            },
            opencv_yaml: opencv_yaml(
                &c.camera,
                Some((size.width_px, size.height_px)),
                Some(c.reprojection_rms_px),
            ),
            ros_camera_info_yaml: ros_camera_info_yaml(
                &c.camera,
                (size.width_px, size.height_px),
                ROS_CAMERA_NAME,
            ),
            timing_ms: CalibrationTimingDto {
                detect: answer.detect_ms,
                solve: answer.solve_ms,
            },
        }
    }
}

/// Validates `request`, calibrates from `photos` and maps the answer: what the route and
/// the command line both call.
///
/// # Errors
/// The request's problems, and the calibration's refusals
/// ([`problem_from_calibrate_error`]).
pub fn respond<B: AsRef<[u8]>>(
    request: &CalibrateRequest,
    limits: &ImageLimits,
    photos: &[B],
    cancel: &CancelFlag,
) -> Result<CalibrateResponse, Problem> {
    let setup = request.setup(limits)?;
    let answer =
        calibrate_photos(&setup, photos, cancel).map_err(|e| problem_from_calibrate_error(&e))?;
    Ok(CalibrateResponse::from(&answer))
}
