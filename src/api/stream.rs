//! The messages of `GET /v1/stream` (docs/stream.md): the optional text message before a
//! frame ([`FrameMetaDto`]), and the answer to each frame ([`StreamAnswer`]: the
//! `POST /v1/pose/image` answer for that frame plus the frame's identity, each code's track
//! and every live track's filtered pose), or the problem of a frame that cannot be read
//! ([`FrameProblem`]); and the tracker's parameters ([`TrackQuery`]: query parameters of the
//! stream, flags of `qrpose track`). The same schemas are published in
//! `openapi/asyncapi.json`.

use super::frames::{FramePoseDto, PriorDto};
use super::image::ImageQuery;
use super::image::ImageResponse;
use super::pick::ObjectDto;
use super::problem::ErrorCode;
use super::problem::Problem;
use super::response::{COVARIANCE_ORDER, CovarianceDto, RotationDto, Vec3Mm};
use super::robot::RobotPoseDto;
use crate::app::{DEFAULT_FULL_SEARCH_EVERY, ImageLimits, ImageSetup, TrackAnswer, TrackSetup};
use qrpose_site::Site;
use qrpose_track::TrackerParams;
use qrpose_track::{TrackReport, TrackStatus};
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use utoipa::IntoParams;
use utoipa::ToSchema;

/// The tracker's parameters of a stream (query parameters of `GET /v1/stream`, flags of
/// `qrpose track`). Each is optional; the defaults are the tracker's (`docs/stream.md`
/// lists them, and a test holds the list to the tracker's values).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, IntoParams, clap::Args)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct TrackQuery {
    /// A track not seen for longer than this is lost, ms.
    #[arg(long, allow_negative_numbers = true)]
    #[param(exclusive_minimum = 0)]
    pub coast_ms: Option<f64>,
    /// Search the whole frame at least every this many frames, also while every code is
    /// tracked: a new code appears within this many frames.
    #[arg(long)]
    #[param(minimum = 1, maximum = 10000)]
    pub full_search_every: Option<u32>,
    /// A frame's measurement of a track whose innovation (its four corners: a squared
    /// Mahalanobis distance with 8 degrees of freedom) exceeds this is not fused.
    #[arg(long, allow_negative_numbers = true)]
    #[param(exclusive_minimum = 0)]
    pub gate_chi2: Option<f64>,
    /// Spectral density of the codes' linear acceleration, mm²/s³: larger follows faster
    /// motion, smooths less.
    #[arg(long, allow_negative_numbers = true)]
    #[param(exclusive_minimum = 0)]
    pub accel_psd_mm2_s3: Option<f64>,
    /// Spectral density of the codes' angular acceleration, rad²/s³.
    #[arg(long, allow_negative_numbers = true)]
    #[param(exclusive_minimum = 0)]
    pub angular_accel_psd_rad2_s3: Option<f64>,
    /// Factor on the variance of each frame's corners before they are fused: of refined
    /// corners, (0.06 px)², the detector's measured corner error (docs/stream.md); of
    /// corners the detector could not refine, `corner_sigma_px`².
    #[arg(long, allow_negative_numbers = true)]
    #[param(exclusive_minimum = 0)]
    pub measurement_inflation: Option<f64>,
    /// Live tracks at most.
    #[arg(long)]
    #[param(minimum = 1)]
    pub max_tracks: Option<usize>,
}

impl TrackQuery {
    /// The names of the parameters, as documented.
    pub fn parameter_names() -> Vec<String> {
        Self::into_params(|| None)
            .into_iter()
            .map(|p| p.name)
            .collect()
    }

    /// The stream's setup: the image request of `image` and these tracker parameters.
    ///
    /// # Errors
    /// The image request's problems (`field` names the parameter); 422
    /// `invalid_tracker_parameter` for a tracker parameter out of its range.
    pub fn setup(
        &self,
        image: ImageQuery,
        limits: &ImageLimits,
        site: Option<Arc<Site>>,
    ) -> Result<TrackSetup, Problem> {
        let image = image.setup(limits, site)?;
        let defaults = TrackerParams::default();
        let tracker = TrackerParams {
            coast_ms: self.coast_ms.unwrap_or(defaults.coast_ms),
            gate_chi2: self.gate_chi2.unwrap_or(defaults.gate_chi2),
            accel_psd_mm2_s3: self.accel_psd_mm2_s3.unwrap_or(defaults.accel_psd_mm2_s3),
            angular_accel_psd_rad2_s3: self
                .angular_accel_psd_rad2_s3
                .unwrap_or(defaults.angular_accel_psd_rad2_s3),
            measurement_inflation: self
                .measurement_inflation
                .unwrap_or(defaults.measurement_inflation),
            max_tracks: self.max_tracks.unwrap_or(defaults.max_tracks),
            ..defaults
        };
        tracker.validate().map_err(|e| {
            Problem::new(ErrorCode::InvalidTrackerParameter, e.to_string())
                .with_field(e.param.name())
        })?;
        let full_search_every = self.full_search_every.unwrap_or(DEFAULT_FULL_SEARCH_EVERY);
        if full_search_every == 0 {
            return Err(Problem::new(
                ErrorCode::InvalidTrackerParameter,
                "full_search_every must be at least 1 frame",
            )
            .with_field("full_search_every"));
        }
        Ok(TrackSetup {
            image,
            tracker,
            full_search_every,
        })
    }
}

/// A frame's id, as the client gave it: a string or a number.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(untagged)]
pub enum FrameIdDto {
    /// A string id.
    Text(String),
    /// A numeric id.
    Number(f64),
}

/// The optional text message before a binary frame; it applies to that frame only.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct FrameMetaDto {
    /// The client's id of the frame, echoed in its answer.
    #[serde(default)]
    pub frame_id: Option<FrameIdDto>,
    /// When the frame was captured, ms on the client's clock (any epoch, increasing).
    /// Without it the server's receive time is used.
    #[serde(default)]
    #[schema(example = 1_700_000_000_000.0)]
    pub capture_time_ms: Option<f64>,
    /// An expected orientation for this frame's codes, as in `POST /v1/pose/image`.
    #[serde(default)]
    pub prior: Option<PriorDto>,
    /// The arm's pose (T_robot←flange) when this frame was captured, as in
    /// `POST /v1/pose/image`: with a camera on the flange, the frame's codes and each
    /// track's product are in the robot frame only with it (`docs/pick.md`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flange_pose: Option<RobotPoseDto>,
}

/// Which frame an answer is for.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct FrameDto {
    /// 0-based count of frames received in the session.
    pub index: u64,
    /// The client's `frame_id`, or null.
    pub id: Option<FrameIdDto>,
    /// The capture time used, ms: the client's, or the server's receive time on the session's
    /// clock (ms since the session opened).
    pub capture_time_ms: f64,
    /// Frames dropped unanswered since the previous answer (the client sent faster than the
    /// service answers; the oldest waiting frames go first).
    pub dropped_before: u64,
}

/// A track's state after a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum TrackStatusDto {
    /// Created by this frame.
    New,
    /// Updated by this frame.
    Tracking,
    /// Not seen in this frame: the pose is predicted.
    Coasting,
    /// Given up: reported once, then dropped.
    Lost,
}

/// A track's filtered pose at the frame's capture time, in the camera frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TrackPoseDto {
    /// The marker centre, mm.
    pub position_mm: Vec3Mm,
    /// The marker's rotation, as in a pose.
    pub rotation: RotationDto,
    /// 6×6 covariance of the filtered pose, in the order of a pose's covariance: the filter's
    /// plus the latest fused frame's own (the error frames of one scene share, which
    /// averaging does not remove; docs/stream.md, Covariance).
    pub covariance: CovarianceDto,
    /// The marker centre's velocity in the camera frame, mm/s.
    pub velocity_mm_per_s: Vec3Mm,
}

/// A track's code in the robot frame, fused over its latest frames (`docs/pick.md`,
/// Streams).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TrackInRobotDto {
    /// T_robot←marker: the fused pose of the code's centre, with the covariance of the
    /// sharpest single frame fused (not the fusion's own: the frames share errors).
    pub pose: FramePoseDto,
    /// Robot-frame poses fused (at most 30).
    pub frames_fused: usize,
    /// The product the payload names, planned from the fused pose; null without a rule.
    pub object: Option<ObjectDto>,
}

/// One live track.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TrackDto {
    /// Stable id for the session (`t1`, `t2`, …).
    #[schema(example = "t1")]
    pub id: String,
    /// The code's payload.
    pub payload: String,
    /// `new`, `tracking`, `coasting` or `lost`.
    pub status: TrackStatusDto,
    /// Frames that updated the track.
    pub frames_seen: u64,
    /// The filtered pose.
    pub pose: TrackPoseDto,
    /// The track, not the single frame, chose between the two planar poses in this frame.
    pub ambiguity_resolved: bool,
    /// The code in the robot frame, fused over the track's frames, and its product; null
    /// when the camera's pose in the robot frame is unknown on this frame (no mount, or a
    /// camera on the flange and no `flange_pose`).
    pub in_robot: Option<TrackInRobotDto>,
}

/// The answer to one frame: the `POST /v1/pose/image` answer for it (each marker with its
/// `track_id`), the frame, and every live track.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct StreamAnswer {
    /// Which frame this answers.
    pub frame: FrameDto,
    /// As `POST /v1/pose/image` answers this frame; each marker also has its `track_id`.
    #[serde(flatten)]
    pub response: ImageResponse,
    /// Every live track after this frame (lost ones reported once).
    pub tracks: Vec<TrackDto>,
}

/// The answer to a frame that cannot be read (not an image, too large) or a text message
/// that cannot be used: the problem document, with the frame it concerns.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct FrameProblem {
    /// The frame (for a bad text message: the frame it would have applied to).
    pub frame: FrameDto,
    /// The problem.
    #[serde(flatten)]
    pub problem: Problem,
}

impl From<TrackStatus> for TrackStatusDto {
    fn from(s: TrackStatus) -> Self {
        match s {
            TrackStatus::New => Self::New,
            TrackStatus::Tracking => Self::Tracking,
            TrackStatus::Coasting => Self::Coasting,
            TrackStatus::Lost => Self::Lost,
        }
    }
}

impl From<&TrackReport> for TrackDto {
    fn from(t: &TrackReport) -> Self {
        let p = &t.pose;
        Self {
            id: t.id.clone(),
            payload: t.payload.clone(),
            status: t.status.into(),
            frames_seen: u64::from(t.frames_seen),
            pose: TrackPoseDto {
                position_mm: p.centre_mm.into(),
                rotation: RotationDto::from_rotation(&p.rotation),
                covariance: CovarianceDto {
                    order: COVARIANCE_ORDER.map(str::to_owned),
                    matrix: std::array::from_fn(|i| std::array::from_fn(|j| p.covariance[(i, j)])),
                },
                velocity_mm_per_s: p.velocity_mm_s.into(),
            },
            ambiguity_resolved: t.ambiguity_resolved,
            in_robot: None,
        }
    }
}

impl StreamAnswer {
    /// The wire form of a frame's answer (`frame` says which frame).
    pub fn from_answer(answer: &TrackAnswer, setup: &ImageSetup, frame: FrameDto) -> Self {
        let mut response = ImageResponse::from_answer(&answer.image, setup);
        for (marker, track_id) in response.markers.iter_mut().zip(&answer.track_ids) {
            marker.track_id = Some(track_id.clone());
        }
        Self {
            frame,
            response,
            tracks: answer
                .tracks
                .iter()
                .map(|t| {
                    let mut dto = TrackDto::from(t);
                    dto.in_robot = answer.in_robot.get(&t.id).map(|r| TrackInRobotDto {
                        pose: FramePoseDto::from(&r.marker),
                        frames_fused: r.frames_fused,
                        object: r.object.as_ref().map(ObjectDto::from),
                    });
                    dto
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tracker_parameters_are_range_checked_with_their_name() {
        let limits = ImageLimits::default();
        let image = ImageQuery {
            fx_px: Some(1000.0),
            fy_px: Some(1000.0),
            cx_px: Some(639.5),
            cy_px: Some(359.5),
            marker_size_mm: Some(50.0),
            ..ImageQuery::default()
        };
        let valid = TrackQuery::default()
            .setup(image.clone(), &limits, None)
            .expect("defaults");
        assert_eq!(valid.full_search_every, DEFAULT_FULL_SEARCH_EVERY);
        for (query, field) in [
            (
                TrackQuery {
                    coast_ms: Some(-1.0),
                    ..TrackQuery::default()
                },
                "coast_ms",
            ),
            (
                TrackQuery {
                    full_search_every: Some(0),
                    ..TrackQuery::default()
                },
                "full_search_every",
            ),
        ] {
            let p = query
                .setup(image.clone(), &limits, None)
                .expect_err("refused");
            assert_eq!(
                (p.code, p.field.as_deref()),
                (ErrorCode::InvalidTrackerParameter, Some(field))
            );
        }
    }

    /// docs/stream.md's table of the tracker's parameters says the tracker's defaults.
    #[test]
    fn the_documented_defaults_are_the_tracker_s() {
        let doc = include_str!("../../docs/stream.md");
        let d = TrackerParams::default();
        let expected = [
            ("coast_ms", d.coast_ms),
            ("full_search_every", f64::from(DEFAULT_FULL_SEARCH_EVERY)),
            ("gate_chi2", d.gate_chi2),
            ("accel_psd_mm2_s3", d.accel_psd_mm2_s3),
            ("angular_accel_psd_rad2_s3", d.angular_accel_psd_rad2_s3),
            ("measurement_inflation", d.measurement_inflation),
            (
                "max_tracks",
                f64::from(u32::try_from(d.max_tracks).unwrap_or(u32::MAX)),
            ),
        ];
        for name in TrackQuery::parameter_names() {
            let row = doc
                .lines()
                .find(|l| l.starts_with(&format!("| `{name}` |")))
                .unwrap_or_else(|| panic!("docs/stream.md has no row for {name}"));
            let documented: f64 = row
                .split('|')
                .nth(2)
                .unwrap_or_default()
                .trim()
                .parse()
                .expect("a number");
            let (_, value) = expected
                .iter()
                .find(|(n, _)| *n == name)
                .expect("a known parameter");
            assert!(
                (documented - value).abs() <= 1e-9 * value.abs(),
                "{name}: {documented} vs {value}"
            );
        }
    }
}
