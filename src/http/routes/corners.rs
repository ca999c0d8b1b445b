//! `POST /v1/pose/corners`: the pose of one QR code from its four image corners.

use crate::api::{
    estimate_corners_in,
    problem::{Problem, parse_json},
    request::CornersRequest,
    response::PoseResponse,
};
use crate::detect::contain::contain;
use crate::http::{
    error::ApiError,
    extract::{JsonBody, JsonBytes},
    metrics::PoseOutcome,
    state::AppState,
};
use axum::extract::State;
use qrpose_site::Site;

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
            the culprit. Codes: `missing_field`, `unknown_field`, `invalid_type`, \
            `unknown_variant`, `non_finite_number`, `corners_missing_or_conflicting`, \
            `corner_count`, `duplicate_corners`, `collinear_corners`, \
            `self_intersecting_corners`, `non_convex_corners`, `mirrored_corners`, \
            `incomplete_camera`, `invalid_camera_parameter`, `undistortion_failed`, \
            `invalid_marker_size`, `solver_parameter_out_of_range`, `no_solution`, \
            `unknown_camera` (`camera.id` not in the loaded site, or no site), \
            `unknown_marker_size` (no `marker` and no site size for `payload`), \
            `invalid_prior`, \
            `numerically_degenerate` (magnitudes such as corners at 1e150 px, beyond double \
            precision: no number of a 200 is ever NaN, infinite or a null in its place).",
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
    let (json, outcome) = match inline_request(&state, &body)? {
        Some(request) => contained(|| estimate_to_json(&request, site.as_deref()))??,
        None => {
            state
                .queue
                .run(move || {
                    let request = parse_json::<CornersRequest>(&body)?;
                    estimate_to_json(&request, site.as_deref())
                })
                .await??
        }
    };
    state.metrics.observe_estimate(outcome);
    Ok(JsonBytes(json))
}

/// Bodies up to this size may be parsed on the async thread (a few µs); larger ones, which
/// only padding or a long unknown field can make, are parsed on an estimation worker.
pub const INLINE_MAX_BODY_BYTES: usize = 16 * 1024;

/// Estimates with at most this many iterations and no trace may run on the async thread.
/// Measured at the limit: 35 µs for `paper` running all 1000 iterations (`docs/service.md`,
/// "Saturation").
pub const INLINE_MAX_ITERATIONS: u64 = 1000;

/// The request to estimate right here, on the async thread, instead of behind the
/// estimation queue: only when the queue has no free place (so that corners requests are
/// answered while image jobs fill every worker and waiting place) and the estimate is short
/// ([`runs_inline`]). Otherwise `None`: the request goes to the queue, which on this 2-core
/// machine costs less CPU per request than running inline (`docs/service.md`, "Load test":
/// the workers keep the estimator's code and data in their caches, the async threads the
/// network's).
///
/// # Errors
/// The request's parse problem, when it was parsed here.
fn inline_request(state: &AppState, body: &[u8]) -> Result<Option<CornersRequest>, ApiError> {
    let o = state.queue.occupancy();
    if o.running + o.waiting < o.capacity || body.len() > INLINE_MAX_BODY_BYTES {
        return Ok(None);
    }
    let request = contained(|| parse_json::<CornersRequest>(body))??;
    Ok(runs_inline(&request).then_some(request))
}

/// Whether a parsed request's estimate is short enough to run on an async thread: at most
/// [`INLINE_MAX_ITERATIONS`] and no trace to serialise. Long ones (up to 10 000 iterations)
/// always go to the workers, so that no request blocks an async thread for long.
pub fn runs_inline(request: &CornersRequest) -> bool {
    request.solver.max_iterations <= INLINE_MAX_ITERATIONS && !request.solver.trace
}

/// Runs `f` with panics contained: a panic is a 500 `internal` (logged), as on a worker.
fn contained<T>(f: impl FnOnce() -> T) -> Result<T, ApiError> {
    contain(f).map_err(|panic| ApiError::internal(format!("estimation panicked: {panic}")))
}

/// Estimates (against the loaded site, if any) and serialises.
fn estimate_to_json(
    request: &CornersRequest,
    site: Option<&Site>,
) -> Result<(Vec<u8>, PoseOutcome), ApiError> {
    let response = estimate_corners_in(request, site)?;
    let json = serde_json::to_vec(&response).map_err(ApiError::internal)?;
    Ok((json, PoseOutcome::from(&response)))
}
