//! `POST /v1/pose/corners`: the pose of one QR code from its four image corners.

use crate::api::{
    estimate_corners,
    problem::{Problem, parse_json},
    request::CornersRequest,
    response::PoseResponse,
};
use crate::app::Site;
use crate::http::{
    error::ApiError,
    extract::{JsonBody, JsonBytes},
    inline,
    metrics::PoseOutcome,
    state::AppState,
};
use axum::extract::State;
use std::sync::Arc;

/// Estimate the pose of a QR code from its four corners.
///
/// Send the corners in pixels (`corners_px`, in `corner_order`) or in image-plane mm
/// (`corners_mm`), the camera intrinsics and the printed code's side length; get the marker
/// centre (mm), the rotation (Euler angles in degrees, matrix, quaternion) and diagnostics.
/// Non-convergence is a result, not an error: `diagnostics.converged` is false and the last
/// estimate is returned. The same JSON as `qrpose estimate REQUEST.json`.
#[utoipa::path(
    post,
    path = "/v1/pose/corners",
    tag = "pose",
    operation_id = "pose_from_corners",
    request_body(
        content = CornersRequest,
        content_type = "application/json",
        description = "Four corners, the camera and the marker; `solver` is optional.",
    ),
    responses(
        (status = 200, description = "The pose, with diagnostics.", body = PoseResponse),
        (status = 400, description = "`malformed_json`: the body is not JSON (syntax error, \
            empty body, a `NaN` literal, nesting deeper than 128 levels, trailing characters).",
            body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:qrpose:problem:malformed_json", "title": "Malformed JSON",
                "status": 400, "detail": "EOF while parsing an object at line 1 column 1",
                "code": "malformed_json"})),
        (status = 413, description = "`payload_too_large`: the body exceeds the configured \
            limit (`--body-limit-bytes`).",
            body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "`unsupported_media_type`: the Content-Type is missing or \
            not `application/json`.",
            body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Well-formed JSON that cannot be used; `field` points at \
            the culprit (`unknown_camera`: `camera.id` not in the loaded site, or no site; \
            `unknown_marker_size`: no `marker` and no site size for `payload`; \
            `numerically_degenerate`: magnitudes such as corners at 1e150 px, beyond double \
            precision, so that no number of a 200 is ever NaN, infinite or null).",
            body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:qrpose:problem:duplicate_corners",
                "title": "Duplicate corners", "status": 422,
                "detail": "corners 0 and 2 coincide", "code": "duplicate_corners",
                "field": "/corners_px/2"})),
        (status = 503, description = "`overloaded`: every estimation worker is busy and the \
            queue is full; `timeout`: the request did not finish within the configured time. \
            Retry after `Retry-After` seconds.",
            body = Problem, content_type = "application/problem+json",
            headers(("Retry-After" = u32, description = "Seconds to wait before retrying")),
            example = json!({"type": "urn:qrpose:problem:overloaded",
                "title": "Service overloaded", "status": 503,
                "detail": "all 66 estimation slots (running and queued) are taken; retry after 1 s",
                "code": "overloaded"})),
        (status = 500, description = "`internal`: a fault of the service, never of the \
            request; the cause is logged under the response's `x-request-id`.",
            body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn pose_from_corners(
    State(state): State<AppState>,
    JsonBody(body): JsonBody,
) -> Result<JsonBytes, ApiError> {
    // One snapshot of the site for the whole request: a reload cannot change it midway.
    let site = state.site.current();
    let (json, outcome) = match inline::parsed_if_inline(&state.queue, &body)? {
        Some(request) => inline::contained(|| answer_as_json(&request, site))??,
        None => {
            state
                .queue
                .run(move || {
                    let request = parse_json::<CornersRequest>(&body)?;
                    answer_as_json(&request, site)
                })
                .await??
        }
    };
    state.metrics.observe_estimate(outcome);
    Ok(JsonBytes(json))
}

/// Validates, estimates (against the loaded site, if any) and serialises.
fn answer_as_json(
    request: &CornersRequest,
    site: Option<Arc<Site>>,
) -> Result<(Vec<u8>, PoseOutcome), ApiError> {
    let response = estimate_corners(request, site)?;
    let json = serde_json::to_vec(&response).map_err(ApiError::internal)?;
    Ok((json, PoseOutcome::from(&response)))
}
