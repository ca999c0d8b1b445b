//! The response of `POST /v1/pose/image`: every code found, with its payload, corners,
//! refinement and pose, and the time per stage.

use super::PointsDto;
use super::per_marker::{MarkerContext, MarkerPose, marker_pose};
use crate::api::frames::{LocalizationDto, localization};
use crate::api::problem::Problem;
use crate::api::response::PoseResponse;
use crate::detect::{
    corners::RefineStatus,
    pipeline::{Located, LocatedMarker},
};
use crate::geometry::frames::PixelPoint;
use base64::Engine;
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
    /// The wire form of a code of a photo and its pose.
    pub fn new(located: &LocatedMarker, solved: MarkerPose) -> Self {
        let code = &located.code;
        let c = &code.candidate;
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
            points_used: solved.points_used.into(),
            pose: solved.pose,
            problem: solved.problem,
        }
    }
}

impl ImageResponse {
    /// The wire form of what [`locate_markers`](crate::detect::pipeline::locate_markers)
    /// found in an image of `image` size, decoded in `decode_ms`: each code sized, solved
    /// and carried into the site's frames by `context`, and the fused localisation.
    pub fn new(
        located: &Located,
        context: &MarkerContext<'_>,
        image: ImageSizeDto,
        decode_ms: f64,
    ) -> Self {
        let mut mapped = Vec::new();
        let markers = located
            .markers
            .iter()
            .enumerate()
            .map(|(index, m)| {
                let solved = marker_pose(m, index, context);
                if let (Some(in_world), Some(payload)) =
                    (solved.robot_in_world, &m.code.candidate.text)
                {
                    mapped.push((index, payload.clone(), in_world));
                }
                MarkerResultDto::new(m, solved)
            })
            .collect();
        Self {
            image,
            markers,
            localization: localization(&mapped),
            warnings: if located.budget_exhausted {
                vec![ImageWarningDto::DetectionBudgetExhausted]
            } else {
                Vec::new()
            },
            timing_ms: TimingDto {
                decode: decode_ms,
                detect: located.detect_ms,
                estimate: located.estimate_ms,
                detect_passes: located
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
