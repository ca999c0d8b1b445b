//! `POST /v1/pose/image`: every QR code in a photo, with its payload, sub-pixel corners and
//! pose. The body comes in either form through [`ImageInput`]; validating the request,
//! [`crate::app::estimate_image`] and serialising run on an estimation worker, as for
//! `/v1/pose/corners`.

use crate::api::{
    image::{ImageQuery, ImageRequest, ImageResponse, respond},
    problem::Problem,
};
use crate::app::CancelFlag;
use crate::app::ImageLimits;
use crate::app::Site;
use crate::http::{
    error::ApiError, extract::JsonBytes, image_input::ImageInput, metrics::PoseOutcome,
    state::AppState,
};
use axum::extract::State;
use std::sync::Arc;
use utoipa::ToSchema;

/// The route.
pub const PATH: &str = "/v1/pose/image";

// Documentation only: the handler reads the parts itself, so that every mistake is answered
// with a problem document.
/// The multipart form of `POST /v1/pose/image`: the photo and the request.
#[derive(Debug, ToSchema)]
pub struct ImageForm {
    /// The photo: JPEG or PNG bytes (the format is read from the bytes, whatever the part's
    /// content type says).
    #[schema(value_type = String, content_media_type = "application/octet-stream", min_length = 1)]
    pub image: Vec<u8>,
    /// The request as JSON (`application/json`): camera, marker, optional solver,
    /// detector and points; the corners request without corners.
    pub request: ImageRequest,
}

/// Find every QR code in a photo and estimate its pose.
///
/// Send the photo (JPEG or PNG) either as the raw body with the camera, marker and solver as
/// query parameters, or as `multipart/form-data` with a part `image` (the photo) and a part
/// `request` (JSON: `camera`, `marker`, optional `solver`, `detector` and `points`, as in
/// the corners request). With a raw body the query must give the camera in one of its forms
/// (`fx_px`, `fy_px`, `cx_px`, `cy_px`; or `focal_length_mm`, `pixel_size_um`, `cx_px`,
/// `cy_px`; or, with a site loaded, `camera_id`) and, unless a site sizes the codes,
/// `marker_size_mm`. With multipart, query parameters are read too: a field given in both is
/// the part's (the camera is taken whole from the part when it has one, the solver field by
/// field). Every code found is returned with its payload,
/// its sub-pixel corners in `"qr"` order and its pose. No code found is a 200 with
/// `markers: []`; a code whose pose cannot be computed has `pose: null` and its own
/// `problem`. The same JSON as `qrpose estimate --image`.
#[utoipa::path(
    post,
    path = "/v1/pose/image",
    tag = "pose",
    operation_id = "pose_from_image",
    params(ImageQuery),
    request_body(
        description = "The photo as the raw body (`image/jpeg` or `image/png`, with query \
            parameters), or a multipart form with the parts `image` and `request`.",
        content(
            ("image/jpeg"),
            ("image/png"),
            (inline(ImageForm) = "multipart/form-data"),
        ),
    ),
    responses(
        (status = 200, description = "Every QR code found (none: `markers: []`), with its \
            payload, corners and pose, and the time per stage.", body = ImageResponse),
        (status = 400, description = "`malformed_query`: a query parameter does not parse as \
            its type or is given twice; `malformed_multipart`: the multipart body cannot be \
            parsed (no boundary, broken framing, a part without a name or given twice); \
            `malformed_json`: the `request` part is not JSON.",
            body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:qrpose:problem:malformed_query",
                "title": "Malformed query string", "status": 400,
                "detail": "query parameter fx_px: invalid float literal",
                "code": "malformed_query", "field": "fx_px"})),
        (status = 413, description = "`payload_too_large`: the body exceeds the configured \
            limit (`--body-limit-bytes`); `image_too_large`: the image's header declares more \
            pixels than the configured limit (`--max-image-pixels`), refused before decoding.",
            body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:qrpose:problem:image_too_large",
                "title": "Image too large", "status": 413,
                "detail": "the image declares 100000 × 100000 pixels, more than the limit of 50000000",
                "code": "image_too_large"})),
        (status = 415, description = "`unsupported_media_type`: the Content-Type is missing or \
            not `image/jpeg`, `image/png` or `multipart/form-data`.",
            body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "A well-formed request that cannot be used; `field` names \
            the query parameter, the multipart part or (a JSON pointer) the field of the \
            `request` part (`undecodable_image`: not a JPEG or PNG, corrupt, truncated, empty; \
            `detector_unavailable`: `zxing-cpp` in a build without it; \
            `points_need_reprojection`: `points = finders` with another method; \
            `missing_field`: `marker_size_mm`, or the part `image` or `request`). A code the \
            site cannot size is not a refusal: its `pose` is null and its `problem` is \
            `unknown_marker_size`.",
            body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:qrpose:problem:undecodable_image",
                "title": "Undecodable image", "status": 422,
                "detail": "unsupported image format: expected JPEG, PNG or WebP",
                "code": "undecodable_image"})),
        (status = 503, description = "`overloaded`: every estimation worker is busy and the \
            queue is full; `timeout`: the request did not finish within the configured time. \
            Retry after `Retry-After` seconds.",
            body = Problem, content_type = "application/problem+json",
            headers(("Retry-After" = u32, description = "Seconds to wait before retrying"))),
        (status = 500, description = "`internal`: a fault of the service, never of the \
            request; the cause is logged under the response's `x-request-id`.",
            body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn pose_from_image(
    State(state): State<AppState>,
    input: ImageInput,
) -> Result<JsonBytes, ApiError> {
    let limits = state.image_limits();
    // One snapshot of the site for the whole request: a reload cannot change it midway.
    let site = state.site.current();
    let (json, outcome) = state
        .queue
        .run_image(
            input.admission_pixels(limits.decode.max_pixels),
            move |cancel| answer_as_json(&input, &limits, site, cancel),
        )
        .await??;
    state.metrics.observe_codes_detected(outcome.codes);
    for pose in &outcome.poses {
        state.metrics.observe_estimate(*pose);
    }
    Ok(JsonBytes(json))
}

/// What the metrics need to know of an answered image.
struct Outcome {
    codes: usize,
    poses: Vec<PoseOutcome>,
}

/// Validates the request (parsing the multipart part), then decodes, detects, estimates and
/// serialises, all on the estimation worker.
fn answer_as_json(
    input: &ImageInput,
    limits: &ImageLimits,
    site: Option<Arc<Site>>,
    cancel: CancelFlag,
) -> Result<(Vec<u8>, Outcome), ApiError> {
    let setup = input.setup(limits, site)?;
    let response = respond(&setup, input.image(), cancel)?;
    let json = serde_json::to_vec(&response).map_err(ApiError::internal)?;
    let poses = response
        .markers
        .iter()
        .filter_map(|m| m.pose.as_ref())
        .map(PoseOutcome::from)
        .collect();
    Ok((
        json,
        Outcome {
            codes: response.markers.len(),
            poses,
        },
    ))
}
