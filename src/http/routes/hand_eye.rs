//! `POST /v1/calibrate/hand-eye`: the camera's pose on a robot arm from 4 to 100 photos of a
//! printed QR code and the flange pose of each (`docs/hand-eye.md`). The body is the
//! calibration's multipart form ([`CalibrateInput`]: parts `image`, repeated, and
//! `request`); parsing the request, [`crate::api::hand_eye::respond`] (decoding, detection
//! and the solve) and serialising run on an estimation worker, which first takes the pixel
//! budget of the largest photo.

use super::calibrate::CalibrateInput;
use crate::api::hand_eye::{HandEyeRequest, HandEyeResponse, respond};
use crate::api::problem::{Problem, parse_json};
use crate::app::{CancelFlag, ImageLimits, Site};
use crate::http::{error::ApiError, extract::JsonBytes, state::AppState};
use axum::extract::State;
use std::sync::Arc;
use utoipa::ToSchema;

/// The route.
pub const PATH: &str = "/v1/calibrate/hand-eye";

// Documentation only: the handler reads the parts itself (as `POST /v1/calibrate` does).
/// The multipart form of `POST /v1/calibrate/hand-eye`: the photos and the request.
#[derive(Debug, ToSchema)]
pub struct HandEyeForm {
    /// The photos, one part `image` each, 4 to 100, from one camera at one resolution, in
    /// the order of `flange_poses`.
    #[schema(schema_with = photos_schema)]
    pub image: Vec<Vec<u8>>,
    /// The request as JSON (`application/json`).
    pub request: HandEyeRequest,
}

/// The `image` parts: 4 to 100 files of bytes.
fn photos_schema() -> utoipa::openapi::schema::Array {
    super::calibrate::photos_array(
        crate::app::MIN_HAND_EYE_VIEWS,
        crate::app::MAX_HAND_EYE_PHOTOS,
        "The photos, one part `image` each, 4 to 100, from one camera at one resolution, in \
         the order of `flange_poses`: JPEG or PNG bytes.",
    )
}

/// Calibrate where the camera sits on the robot (hand-eye).
///
/// Send 4 to 100 photos of one printed QR code (parts `image`), each taken with the robot
/// at another pose, and a part `request` (JSON: `setup` — `eye_in_hand`, the camera on the
/// flange, or `eye_to_hand`, the camera still and the code on the flange —, the `camera`,
/// the code's `marker.size_mm`, and `flange_poses`: T_robot←flange of each photo, as the
/// controller reports it, with a quaternion, a rotation vector or Z-Y-X Euler angles).
/// The answer: `camera_pose` (T_flange←camera or T_robot←camera), `target_pose`, one
/// standard deviation per axis, per-view residuals, warnings and `site_mount`, the YAML to
/// paste into the site file's camera. The same JSON as `qrpose calibrate hand-eye`.
#[utoipa::path(
    post,
    path = "/v1/calibrate/hand-eye",
    tag = "calibration",
    operation_id = "calibrate_hand_eye",
    request_body(
        description = "A multipart form with 4 to 100 parts `image` and one part `request`.",
        content((inline(HandEyeForm) = "multipart/form-data")),
    ),
    responses(
        (status = 200, description = "The camera's pose on the robot, the code's, their \
            standard deviations, every photo's residuals, the warnings and the site snippet.",
            body = HandEyeResponse),
        (status = 400, description = "`malformed_multipart`, `malformed_json`: as \
            `POST /v1/calibrate`.",
            body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "`payload_too_large`, `image_too_large`: as \
            `POST /v1/calibrate`.",
            body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "`unsupported_media_type`: the Content-Type is not \
            `multipart/form-data`.",
            body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "A well-formed request that gives no calibration \
            (`flange_poses_mismatch`: not one flange pose per photo; `degenerate_motion`: the \
            motions between the views turn about fewer than two distinct axes; \
            `too_few_views`: fewer than 4 photos with the code read; `invalid_robot_pose`: no \
            rotation or two, or a quaternion whose norm is off 1 by more than 1e-3, `field` \
            `/flange_poses/K`).",
            body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:qrpose:problem:degenerate_motion",
                "title": "Degenerate motion", "status": 422,
                "detail": "the flange turns about one axis only (spread 0.01 rad): turn it about at least two different axes",
                "code": "degenerate_motion", "field": "/flange_poses"})),
        (status = 503, description = "`overloaded`, `timeout`: retry after `Retry-After` \
            seconds.",
            body = Problem, content_type = "application/problem+json",
            headers(("Retry-After" = u32, description = "Seconds to wait before retrying"))),
        (status = 500, description = "`internal`: a fault of the service, never of the \
            request; the cause is logged under the response's `x-request-id`.",
            body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn calibrate_hand_eye(
    State(state): State<AppState>,
    input: CalibrateInput,
) -> Result<JsonBytes, ApiError> {
    let limits = state.image_limits();
    let site = state.site.current();
    let pixels = input.admission_pixels(&limits);
    let json = state
        .queue
        .run_image(pixels, move |cancel| {
            answer_as_json(&input, &limits, site.as_ref(), &cancel)
        })
        .await??;
    Ok(JsonBytes(json))
}

/// Parses the request part, calibrates and serialises, on the estimation worker.
fn answer_as_json(
    input: &CalibrateInput,
    limits: &ImageLimits,
    site: Option<&Arc<Site>>,
    cancel: &CancelFlag,
) -> Result<Vec<u8>, ApiError> {
    let request = parse_json::<HandEyeRequest>(&input.request_json)?;
    let response = respond(&request, limits, site, &input.photos, cancel)?;
    serde_json::to_vec(&response).map_err(ApiError::internal)
}
