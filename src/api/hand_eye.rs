//! The hand-eye calibration on the wire: `POST /v1/calibrate/hand-eye` (the photos as
//! repeated multipart parts `image`, the [`HandEyeRequest`] as the part `request`) and
//! `qrpose calibrate hand-eye`, both through [`respond`], so their JSON is the same field
//! for field (`docs/hand-eye.md`).

use super::calibrate::CalibrationTimingDto;
use super::camera::CameraDto;
use super::context::{MARKER_POINTER, resolve_camera};
use super::problem::{ErrorCode, Problem};
use super::refusal::problem_from_hand_eye_error;
use super::request::{CornersUnit, MarkerDto};
use super::robot::{ParentedPoseDto, RobotPoseDto};
use crate::app::{
    HandEyeAnswer, HandEyeRequestSetup, ImageLimits, Site, Sizing, calibrate_hand_eye_photos,
};
use crate::detect::CancelFlag;
use qrpose_calib::handeye::{FlangeNoise, HandEyeSetup, HandEyeWarning};
use qrpose_site::SizeSource;
use qrpose_site::transform::Rigid;
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use utoipa::ToSchema;

/// Where the camera is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum HandEyeSetupDto {
    /// The camera rides on the flange; the code lies still in the robot's frame.
    EyeInHand,
    /// The camera stands still; the flange holds the code.
    EyeToHand,
}

impl From<HandEyeSetupDto> for HandEyeSetup {
    fn from(s: HandEyeSetupDto) -> Self {
        match s {
            HandEyeSetupDto::EyeInHand => Self::EyeInHand,
            HandEyeSetupDto::EyeToHand => Self::EyeToHand,
        }
    }
}

/// What to calibrate: the setup, the camera, the code's size and the flange pose of each
/// photo.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"setup": "eye_in_hand",
    "camera": {"fx_px": 1000.0, "fy_px": 1000.0, "cx_px": 639.5, "cy_px": 359.5},
    "marker": {"size_mm": 120.0},
    "flange_poses": [{"translation_mm": [412.5, -120.0, 380.2], "quaternion_wxyz": [0.0, 1.0, 0.0, 0.0]}]}))]
pub struct HandEyeRequest {
    /// `eye_in_hand` (camera on the flange) or `eye_to_hand` (camera still, code on the
    /// flange).
    pub setup: HandEyeSetupDto,
    /// The camera that took the photos, as in pose requests (pixel or sensor form, or
    /// `{"id": …}` with a site).
    pub camera: CameraDto,
    /// The printed code; may be omitted when the site sizes its payload.
    #[serde(default)]
    pub marker: Option<MarkerDto>,
    /// T_robot←flange when each photo was taken, one per photo, in order: as the controller
    /// reports it (`docs/hand-eye.md`, Robot poses).
    pub flange_poses: Vec<RobotPoseDto>,
    /// How noisy the controller's flange poses are (its repeatability); default 0.2 mm and
    /// 0.02° per axis.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flange_noise: Option<FlangeNoiseDto>,
}

/// One standard deviation of a reported flange pose, per axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct FlangeNoiseDto {
    /// Of each position coordinate, mm, in [1e-4, 100].
    #[schema(minimum = 1e-4, maximum = 100, example = 0.2)]
    pub translation_mm: f64,
    /// Of the rotation about each axis, degrees, in [1e-5, 10].
    #[schema(minimum = 1e-5, maximum = 10, example = 0.02)]
    pub rotation_deg: f64,
}

impl FlangeNoiseDto {
    /// The calibration's flange noise.
    ///
    /// # Errors
    /// `solver_parameter_out_of_range` at `/flange_noise/…` outside the stated ranges.
    fn to_noise(self) -> Result<FlangeNoise, Problem> {
        for (value, name, (low, high)) in [
            (self.translation_mm, "translation_mm", (1e-4, 100.0)),
            (self.rotation_deg, "rotation_deg", (1e-5, 10.0)),
        ] {
            if !(low..=high).contains(&value) {
                return Err(Problem::new(
                    ErrorCode::SolverParameterOutOfRange,
                    format!("flange_noise.{name} must be in [{low}, {high}], got {value}"),
                )
                .with_field(format!("/flange_noise/{name}")));
            }
        }
        Ok(FlangeNoise {
            translation_std_mm: self.translation_mm,
            rotation_std_rad: self.rotation_deg.to_radians(),
        })
    }
}

impl HandEyeRequest {
    /// The request validated against `site` into the application's setup.
    ///
    /// # Errors
    /// The camera's problems, `unknown_marker_size` without a size from the request or the
    /// site, each flange pose's problems (`/flange_poses/K`).
    pub fn setup(
        &self,
        limits: &ImageLimits,
        site: Option<&Arc<Site>>,
    ) -> Result<HandEyeRequestSetup, Problem> {
        let camera = resolve_camera(&self.camera, CornersUnit::Px, site.map(Arc::as_ref))?.camera;
        let sizing = match (&self.marker, site) {
            (Some(marker), _) => Sizing::Fixed {
                marker: marker.to_marker()?,
                source: SizeSource::Request,
            },
            (None, Some(_)) => Sizing::BySite,
            (None, None) => {
                return Err(Problem::new(
                    ErrorCode::UnknownMarkerSize,
                    "give marker.size_mm (no site is loaded to size the code by its payload)",
                )
                .with_field(MARKER_POINTER));
            }
        };
        let flange_poses = self
            .flange_poses
            .iter()
            .enumerate()
            .map(|(k, pose)| pose.to_rigid(&format!("/flange_poses/{k}")))
            .collect::<Result<_, _>>()?;
        let flange_noise = self
            .flange_noise
            .map(FlangeNoiseDto::to_noise)
            .transpose()?
            .unwrap_or_default();
        Ok(HandEyeRequestSetup {
            setup: self.setup.into(),
            camera,
            sizing,
            site: site.cloned(),
            flange_poses,
            flange_noise,
            decode: limits.decode,
            max_detect: limits.max_detect,
        })
    }
}

/// One standard deviation of `camera_pose`, about and along the camera's own axes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct HandEyeStdDto {
    /// About the camera's x, y, z, degrees.
    pub rotation_deg: [f64; 3],
    /// Along the camera's x, y, z, mm.
    pub translation_mm: [f64; 3],
}

/// One photo's outcome.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct HandEyeViewDto {
    /// The photo, 0-based.
    pub index: usize,
    /// Whether its view took part in the fit (false: no code read, or left out as an
    /// outlier).
    pub used: bool,
    /// Calibration points measured on its code.
    pub points: usize,
    /// The payload of its code, if one was read.
    pub payload: Option<String>,
    /// RMS reprojection error of its points under the fit, px.
    pub rms_px: Option<f64>,
    /// Angle between the flange rotation the fit implies and the one reported, degrees.
    pub rotation_residual_deg: Option<f64>,
    /// Distance between the flange position the fit implies and the one reported, mm.
    pub translation_residual_mm: Option<f64>,
}

/// A warning's code.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum HandEyeWarningDto {
    /// Fewer views used than recommended.
    FewViews,
    /// The views turn little between them: the mount is poorly constrained.
    SmallRotations,
    /// A view disagreed with the others and was left out.
    OutlierView,
    /// The code is small in some views.
    LittleImageCoverage,
    /// The fit stopped on its iteration budget.
    NotConverged,
}

impl From<&HandEyeWarning> for HandEyeWarningDto {
    fn from(w: &HandEyeWarning) -> Self {
        match w {
            HandEyeWarning::FewViews { .. } => Self::FewViews,
            HandEyeWarning::SmallRotations { .. } => Self::SmallRotations,
            HandEyeWarning::OutlierView { .. } => Self::OutlierView,
            HandEyeWarning::LittleImageCoverage { .. } => Self::LittleImageCoverage,
            HandEyeWarning::NotConverged { .. } => Self::NotConverged,
        }
    }
}

/// A warning with its numbers in words and the views it concerns.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct HandEyeWarningDetailDto {
    /// The warning.
    pub code: HandEyeWarningDto,
    /// In words.
    pub detail: String,
    /// The photos it is about (empty: the whole set).
    pub views: Vec<usize>,
}

/// The camera's pose on the robot, the code's, how sure they are, and the site snippet.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct HandEyeResponse {
    /// The setup calibrated.
    pub setup: HandEyeSetupDto,
    /// T_flange←camera (eye-in-hand) or T_robot←camera (eye-to-hand).
    pub camera_pose: ParentedPoseDto,
    /// T_robot←marker (eye-in-hand) or T_flange←marker (eye-to-hand); the marker frame's
    /// origin at the symbol's centre.
    pub target_pose: ParentedPoseDto,
    /// One standard deviation of `camera_pose` about its own axes.
    pub std: HandEyeStdDto,
    /// RMS reprojection error over every point of the used views, px.
    pub reprojection_rms_px: f64,
    /// Every photo, in the order given.
    pub views: Vec<HandEyeViewDto>,
    /// What the views leave poorly constrained; empty for a good set.
    pub warnings: Vec<HandEyeWarningDto>,
    /// The warnings with their numbers, in words, in the same order.
    pub warning_details: Vec<HandEyeWarningDetailDto>,
    /// The camera's `mount` for the site file, as it is (with its `std`).
    pub site_mount: String,
    /// Time per stage, ms.
    pub timing_ms: CalibrationTimingDto,
}

impl From<&HandEyeAnswer> for HandEyeResponse {
    fn from(answer: &HandEyeAnswer) -> Self {
        let c = &answer.calibration;
        let setup = c.setup;
        let views = answer
            .photos
            .iter()
            .map(|photo| {
                let view = c.views.iter().find(|v| v.index == photo.index);
                HandEyeViewDto {
                    index: photo.index,
                    used: view.is_some_and(|v| v.used),
                    points: photo.points.len(),
                    payload: photo.payload.clone(),
                    rms_px: view.and_then(|v| v.rms_px),
                    rotation_residual_deg: view
                        .and_then(|v| v.rotation_residual_rad)
                        .map(f64::to_degrees),
                    translation_residual_mm: view.and_then(|v| v.translation_residual_mm),
                }
            })
            .collect();
        Self {
            setup: match setup {
                HandEyeSetup::EyeInHand => HandEyeSetupDto::EyeInHand,
                HandEyeSetup::EyeToHand => HandEyeSetupDto::EyeToHand,
            },
            camera_pose: ParentedPoseDto::new(setup.camera_parent(), &Rigid::from(&c.camera_pose)),
            target_pose: ParentedPoseDto::new(setup.target_parent(), &Rigid::from(&c.target_pose)),
            std: HandEyeStdDto {
                rotation_deg: c.std_rotation_deg(),
                translation_mm: c.std_translation_mm,
            },
            reprojection_rms_px: c.reprojection_rms_px,
            views,
            warnings: c.warnings.iter().map(HandEyeWarningDto::from).collect(),
            warning_details: c
                .warnings
                .iter()
                .map(|w| HandEyeWarningDetailDto {
                    code: w.into(),
                    detail: w.to_string(),
                    views: w.views(),
                })
                .collect(),
            site_mount: c.site_mount(),
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
/// The request's problems and the calibration's refusals ([`problem_from_hand_eye_error`]).
pub fn respond<B: AsRef<[u8]>>(
    request: &HandEyeRequest,
    limits: &ImageLimits,
    site: Option<&Arc<Site>>,
    photos: &[B],
    cancel: &CancelFlag,
) -> Result<HandEyeResponse, Problem> {
    let setup = request.setup(limits, site)?;
    let answer = calibrate_hand_eye_photos(&setup, photos, cancel)
        .map_err(|e| problem_from_hand_eye_error(&e))?;
    Ok(HandEyeResponse::from(&answer))
}
