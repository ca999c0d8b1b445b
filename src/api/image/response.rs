//! The response of `POST /v1/pose/image`: every code found, with its payload, corners,
//! refinement and pose, and the time per stage.

use super::PointsDto;
use crate::api::frames::LocalizationDto;
use crate::api::problem::Problem;
use crate::api::refusal::problem_from_marker_error;
use crate::api::response::PoseResponse;
use crate::app::{ImageAnswer, ImageSetup, MarkerAnswer};
use crate::detect::{
    pipeline::{MarkerError, Points},
    refine::RefineStatus,
};
use crate::geometry::{camera::Camera, frames::PixelPoint};
use base64::Engine;
use qrpose_site::Site;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// The image's size.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct ImageSizeDto {
    /// Width, px.
    pub width_px: usize,
    /// Height, px.
    pub height_px: usize,
}

/// Time per stage, ms.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TimingDto {
    /// Image decoding, ms.
    pub decode: f64,
    /// Detection, reading and corner refinement, ms.
    pub detect: f64,
    /// Pose estimation of every marker, ms.
    pub estimate: f64,
    /// The detection passes that ran, in order (part of `detect`).
    pub detect_passes: Vec<PassDto>,
}

/// One detection pass.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PassDto {
    /// What ran: `rxing full`, `rxing half`, `zxing-cpp full`, `region K VARIANT` (a crop
    /// around the K-th unread finder-pattern triple), `whole VARIANT` (`thorough`), or the
    /// single detector asked for.
    #[schema(example = "rxing full")]
    pub pass: String,
    /// Its time, ms.
    pub ms: f64,
    /// Symbols it decoded.
    pub decoded: usize,
}

/// A condition of the whole image response.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum ImageWarningDto {
    /// The detection deadline (`max_detect_ms`, or the effort's default) passed before
    /// every pass had run: codes may have been missed. Raise `max_detect_ms` or `effort`.
    DetectionBudgetExhausted,
}

/// One QR code found in the image.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct MarkerResultDto {
    /// The content as text; null when the symbol was found but not decoded, or its bytes
    /// are not text.
    #[schema(example = "SKU-1")]
    pub payload: Option<String>,
    /// The raw content bytes, standard base64 with padding; null when not decoded.
    #[schema(example = "U0tVLTE=")]
    pub payload_base64: Option<String>,
    /// The symbol's corners, px, `"qr"` order (top-left, top-right, bottom-right,
    /// bottom-left), sub-pixel when `corners_refined` is true.
    pub corners_px: [[f64; 2]; 4],
    /// Whether the corners were refined from the image (false: the detector's whole-pixel
    /// corners, see `refinement`).
    pub corners_refined: bool,
    /// How corner refinement ended: `refined`, or why the detector's corners were kept
    /// (`too_few_edges`, `moved_too_far`, `too_small`, `unknown_module_count`).
    #[schema(example = "refined")]
    pub refinement: String,
    /// The twelve outer corners of the three finder patterns, px: top-left finder (its TL,
    /// TR, BR, BL), then the top-right finder, then the bottom-left finder; null when not
    /// all were measured.
    #[schema(value_type = Option<Vec<[f64; 2]>>)]
    pub finder_corners_px: Option<Vec<[f64; 2]>>,
    /// Modules per side (21 for version 1, 4 more per version).
    pub module_count: Option<usize>,
    /// The detector library that found the symbol: `rqrr`, `rxing` or `zxing-cpp`.
    #[schema(example = "rxing")]
    pub detector: String,
    /// The points the pose was solved from.
    pub points_used: PointsDto,
    /// The marker's pose; null when it could not be computed (see `problem`).
    pub pose: Option<PoseResponse>,
    /// Why `pose` is null: the problem document of this marker alone.
    pub problem: Option<Problem>,
    /// Stream answers only (`GET /v1/stream`): the track this code was assigned to, null if
    /// none. Absent from `POST /v1/pose/image` answers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<String>, example = "t1")]
    pub track_id: Option<Option<String>>,
}

/// `POST /v1/pose/image` response.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ImageResponse {
    /// The decoded image's size.
    pub image: ImageSizeDto,
    /// Every QR code found (empty when none).
    pub markers: Vec<MarkerResultDto>,
    /// The robot's pose in the warehouse frame, fused over the mapped codes of the photo
    /// (two or more with a covariance, seen by a site camera with a mount); else null.
    pub localization: Option<LocalizationDto>,
    /// Conditions of the whole response; empty when there are none.
    pub warnings: Vec<ImageWarningDto>,
    /// Time per stage, ms.
    pub timing_ms: TimingDto,
}

fn pairs<const K: usize>(points: &[PixelPoint; K]) -> [[f64; 2]; K] {
    points.map(|p| [p.u(), p.v()])
}

impl MarkerResultDto {
    /// The wire form of code `index` of a photo and its pose (`site`: the loaded site, for
    /// the problem of a code it cannot size).
    pub fn new(m: &MarkerAnswer, index: usize, camera: &Camera, site: Option<&Site>) -> Self {
        let code = &m.code;
        let c = &code.candidate;
        let (pose, problem) = marker_pose_or_problem(m, index, camera, site);
        Self {
            payload: c.text.clone(),
            payload_base64: c
                .payload
                .as_ref()
                .map(|b| base64::engine::general_purpose::STANDARD.encode(b)),
            corners_px: pairs(code.corners_px()),
            corners_refined: code.refinement.status == RefineStatus::Refined,
            refinement: code.refinement.status.as_str().to_owned(),
            finder_corners_px: code
                .refinement
                .finder_corners_px
                .as_ref()
                .map(|f| pairs(f).to_vec()),
            module_count: code.refinement.module_count,
            detector: c.backend.as_str().to_owned(),
            points_used: m.points_used.into(),
            pose,
            problem,
            track_id: None,
        }
    }
}

/// The `pose` and `problem` of code `index`: the wire pose with what the site adds when it
/// was solved and every number of it is finite; otherwise `pose: null` and the code's own
/// problem (why it has no pose, or 422 `numerically_degenerate` naming its corners).
fn marker_pose_or_problem(
    m: &MarkerAnswer,
    index: usize,
    camera: &Camera,
    site: Option<&Site>,
) -> (Option<PoseResponse>, Option<Problem>) {
    let payload = m.code.candidate.text.as_deref();
    let (estimate, (marker, source)) = match (&m.pose, &m.marker) {
        (Ok(estimate), Some(sized)) => (estimate, sized),
        (Err(e), _) => {
            return (
                None,
                Some(problem_from_marker_error(*e, index, site, payload)),
            );
        }
        (Ok(_), None) => {
            let e = MarkerError::UnknownSize;
            return (
                None,
                Some(problem_from_marker_error(e, index, site, payload)),
            );
        }
    };
    let list = match m.points_used {
        Points::Corners => "corners_px",
        Points::Finders => "finder_corners_px",
    };
    let pointer = format!("/markers/{index}/{list}");
    let pose =
        PoseResponse::try_new(estimate, camera, marker, m.estimate_us, &pointer).and_then(|pose| {
            pose.with_site((*source).into(), &m.frames, m.resolved_by_prior, &pointer)
        });
    match pose {
        Ok(pose) => (Some(pose), None),
        Err(problem) => (None, Some(problem)),
    }
}

impl ImageResponse {
    /// The wire form of the application's answer for a photo, validated as `setup`.
    pub fn from_answer(answer: &ImageAnswer, setup: &ImageSetup) -> Self {
        let site = setup.pose.site.as_deref();
        let markers = answer
            .markers
            .iter()
            .enumerate()
            .map(|(index, m)| MarkerResultDto::new(m, index, &setup.pose.camera, site))
            .collect();
        Self {
            image: ImageSizeDto {
                width_px: answer.width_px,
                height_px: answer.height_px,
            },
            markers,
            localization: answer.localization.as_ref().map(LocalizationDto::from),
            warnings: if answer.budget_exhausted {
                vec![ImageWarningDto::DetectionBudgetExhausted]
            } else {
                Vec::new()
            },
            timing_ms: TimingDto {
                decode: answer.timing.decode_ms,
                detect: answer.timing.detect_ms,
                estimate: answer.timing.estimate_ms,
                detect_passes: answer
                    .timing
                    .passes
                    .iter()
                    .map(|p| PassDto {
                        pass: p.name.clone(),
                        ms: p.ms,
                        decoded: p.decoded,
                    })
                    .collect(),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::problem::ErrorCode;
    use crate::app::InFrames;
    use crate::detect::refine::Refinement;
    use crate::detect::{Backend, Candidate, DetectedCode};
    use crate::estimate::{PoseEstimate, ValidSolver, estimate_pose};
    use crate::geometry::{
        marker::{CornerOrder, Marker},
        quad::ImageQuad,
    };
    use qrpose_site::SizeSource;

    fn answer(pose: Result<PoseEstimate, MarkerError>, points_used: Points) -> MarkerAnswer {
        let corners = [
            (589.2, 309.8),
            (689.9, 311.4),
            (688.1, 411.6),
            (588.0, 409.5),
        ]
        .map(|(u, v)| PixelPoint::new(u, v));
        MarkerAnswer {
            code: DetectedCode {
                candidate: Candidate {
                    corners_px: corners,
                    payload: Some(b"SKU-1".to_vec()),
                    text: Some("SKU-1".to_owned()),
                    module_count: Some(21),
                    backend: Backend::Rxing,
                },
                refinement: Refinement {
                    corners_px: corners,
                    finder_corners_px: None,
                    module_count: Some(21),
                    status: RefineStatus::Refined,
                    observations: 0,
                },
            },
            marker: Some((Marker::try_new(50.0).expect("marker"), SizeSource::Request)),
            points_used,
            pose,
            resolved_by_prior: false,
            frames: InFrames::default(),
            estimate_us: 1.0,
        }
    }

    #[test]
    fn a_marker_pose_with_a_non_finite_number_is_null_with_its_problem() {
        let camera = Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("camera");
        let marker = Marker::try_new(50.0).expect("marker");
        let good = answer(Err(MarkerError::UnknownSize), Points::Corners);
        let quad = ImageQuad::try_new(*good.code.corners_px(), CornerOrder::Qr).expect("quad");
        let estimate =
            estimate_pose(&quad, &camera, &marker, &ValidSolver::default()).expect("a pose");
        let good = answer(Ok(estimate.clone()), Points::Corners);
        let (pose, problem) = marker_pose_or_problem(&good, 0, &camera, None);
        assert!(pose.is_some() && problem.is_none());

        let mut spoiled_estimate = estimate;
        spoiled_estimate.centre_mm.z = f64::NAN;
        let spoiled = answer(Ok(spoiled_estimate), Points::Finders);
        let (pose, problem) = marker_pose_or_problem(&spoiled, 3, &camera, None);
        assert!(pose.is_none());
        let problem = problem.expect("a problem");
        assert_eq!(problem.code, ErrorCode::NumericallyDegenerate);
        assert_eq!(
            problem.field.as_deref(),
            Some("/markers/3/finder_corners_px")
        );
        assert!(
            problem.detail.contains("/position_mm/z"),
            "{}",
            problem.detail
        );
    }

    #[test]
    fn a_code_without_a_size_is_null_with_unknown_marker_size_at_its_payload() {
        let camera = Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("camera");
        let unsized_code = MarkerAnswer {
            marker: None,
            ..answer(Err(MarkerError::UnknownSize), Points::Corners)
        };
        let (pose, problem) = marker_pose_or_problem(&unsized_code, 2, &camera, None);
        assert!(pose.is_none());
        let problem = problem.expect("a problem");
        assert_eq!(problem.code, ErrorCode::UnknownMarkerSize);
        assert_eq!(problem.field.as_deref(), Some("/markers/2/payload"));
        assert!(problem.detail.contains("SKU-1"), "{}", problem.detail);
    }
}
