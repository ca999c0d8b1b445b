//! `POST /v1/pose/image`: every QR code in a photo, with its payload, sub-pixel corners and
//! pose.
//!
//! Two request forms (SPEC section 4):
//! - the image as the raw body (`image/jpeg` or `image/png`) and the request as query
//!   parameters ([`ImageQuery`]); a problem's `field` names the query parameter;
//! - `multipart/form-data` with the parts `image` (the image bytes) and `request` (JSON,
//!   [`ImageRequest`]); a problem's `field` names the part, or is a JSON pointer into the
//!   `request` part.
//!
//! The body is read whole (at most the body limit, as every body) before anything is judged,
//! so that a client still sending a large upload reads its answer instead of a connection
//! reset; a 415 drains the body for the same reason. The image format is sniffed from the
//! bytes, so the content type only chooses the form. Parsing the request part, decoding,
//! detecting, estimating and serialising run on an estimation worker, as for
//! `/v1/pose/corners`.

use crate::api::{
    image::{ImageQuery, ImageRequest, ImageResponse, estimate_image},
    problem::{ErrorCode, Problem, parse_json},
};
use crate::detect::decode::DecodeLimits;
use crate::http::{
    error::ApiError,
    extract::{self, BodyError, JsonBytes},
    state::AppState,
};
use axum::body::Bytes;
use axum::extract::{FromRequest, Multipart, Request, State, multipart::MultipartError};
use axum::http::StatusCode;
use utoipa::ToSchema;
use utoipa::openapi::{OpenApi, RefOr, encoding::Encoding};

/// The route.
pub const PATH: &str = "/v1/pose/image";
/// The raw-body media type of a JPEG.
pub const JPEG: &str = "image/jpeg";
/// The raw-body media type of a PNG.
pub const PNG: &str = "image/png";
/// The media type of the multipart form.
pub const MULTIPART: &str = "multipart/form-data";
/// What a 415 tells the client to send.
pub const ACCEPTED: &str = "image/jpeg, image/png or multipart/form-data";
/// The multipart part with the image bytes.
pub const IMAGE_PART: &str = "image";
/// The multipart part with the JSON request.
pub const REQUEST_PART: &str = "request";

// Documentation only: the handler reads the parts itself, so that every mistake is answered
// with a problem document.
/// The multipart form of `POST /v1/pose/image`: the photo and the request.
#[derive(Debug, ToSchema)]
pub struct ImageForm {
    /// The photo: JPEG or PNG bytes (the format is read from the bytes, whatever the part's
    /// content type says).
    #[schema(value_type = String, content_media_type = "application/octet-stream")]
    pub image: Vec<u8>,
    /// The request as JSON (`application/json`): camera, marker, optional solver,
    /// detector and points; the corners request without corners.
    pub request: ImageRequest,
}

/// Adds to `doc` the media type of each part of the multipart form (OpenAPI's `encoding`,
/// which `#[utoipa::path]` cannot express).
pub fn document_part_media_types(doc: &mut OpenApi) {
    let content = doc
        .paths
        .paths
        .get_mut(PATH)
        .and_then(|item| item.post.as_mut())
        .and_then(|operation| operation.request_body.as_mut())
        .and_then(|body| match body {
            RefOr::T(body) => body.content.get_mut(MULTIPART),
            RefOr::Ref(_) => None,
        });
    if let Some(RefOr::T(content)) = content {
        for (part, media_type) in [
            (IMAGE_PART, "image/jpeg, image/png"),
            (REQUEST_PART, "application/json"),
        ] {
            content.encoding.insert(
                part.to_owned(),
                Encoding::builder().content_type(Some(media_type)).build(),
            );
        }
    }
}

/// The request as the async side leaves it for the worker.
enum Input {
    /// A raw image body; the query parameters, already parsed.
    Raw { image: Bytes, request: ImageRequest },
    /// A multipart body: the image part and the request part's JSON, not yet parsed.
    Multipart { image: Bytes, request_json: Bytes },
}

/// Find every QR code in a photo and estimate its pose.
///
/// Send the photo (JPEG or PNG) either as the raw body with the camera, marker and solver as
/// query parameters, or as `multipart/form-data` with a part `image` (the photo) and a part
/// `request` (JSON: `camera`, `marker`, optional `solver`, `detector` and `points`, as in
/// the corners request). The query parameters apply to the raw form only; with multipart
/// they are refused (422 `unknown_field`). Every code found is returned with its payload,
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
            `request` part. Codes: `undecodable_image` (not a JPEG or PNG, corrupt, \
            truncated, empty), `detector_unavailable` (`zxing-cpp` in a build without it), \
            `points_need_reprojection` (`points = finders` with another method), \
            `missing_field` (`marker_size_mm`, or the part `image` or `request`), \
            `unknown_field`, `invalid_type`, `unknown_variant`, `non_finite_number`, \
            `incomplete_camera`, `invalid_camera_parameter`, `invalid_marker_size`, \
            `solver_parameter_out_of_range`.",
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
    request: Request,
) -> Result<JsonBytes, ApiError> {
    let limit_bytes = state.settings.body_limit_bytes;
    let media_type = extract::media_type(request.headers());
    let input = match media_type.as_deref() {
        Some(JPEG | PNG) => raw_input(request, limit_bytes).await?,
        Some(MULTIPART) => multipart_input(request, &state).await?,
        got => {
            let refusal = ApiError::unsupported_media_type(got, ACCEPTED);
            extract::discard_body(request, limit_bytes).await;
            return Err(refusal);
        }
    };
    let limits = DecodeLimits {
        max_encoded_bytes: limit_bytes,
        max_pixels: state.settings.max_image_pixels,
    };
    let (json, outcome) = state
        .queue
        .run(move || estimate_to_json(input, &limits))
        .await??;
    state.metrics.observe_codes_detected(outcome.codes);
    for pose in &outcome.poses {
        state
            .metrics
            .observe_estimate(&pose.method, pose.iterations, pose.converged);
    }
    Ok(JsonBytes(json))
}

/// The raw-body form: the image bytes and the query parameters.
async fn raw_input(request: Request, limit_bytes: usize) -> Result<Input, ApiError> {
    let query = request.uri().query().map(str::to_owned);
    let image = extract::read_body(request, limit_bytes)
        .await
        .map_err(|e| body_error(e, ErrorCode::UndecodableImage))?;
    let request = extract::parse_query::<ImageQuery>(query.as_deref())?
        .into_request()
        .map_err(ApiError::from)?;
    Ok(Input::Raw { image, request })
}

/// The multipart form: the `image` and `request` parts, each exactly once.
async fn multipart_input(request: Request, state: &AppState) -> Result<Input, ApiError> {
    let limit_bytes = state.settings.body_limit_bytes;
    if let Some(parameter) = first_query_parameter(request.uri().query()) {
        extract::discard_body(request, limit_bytes).await;
        return Err(Problem::new(
            ErrorCode::UnknownField,
            format!(
                "query parameters are read only with a raw image body; with {MULTIPART} put \
                 {parameter} into the `{REQUEST_PART}` part"
            ),
        )
        .with_field(parameter)
        .into());
    }
    let request = extract::buffer_body(request, limit_bytes)
        .await
        .map_err(|e| body_error(e, ErrorCode::MalformedMultipart))?;
    let mut multipart = Multipart::from_request(request, state)
        .await
        .map_err(|rejection| malformed_multipart(rejection.body_text(), None))?;
    let (mut image, mut request_json) = (None, None);
    while let Some(part) = multipart
        .next_field()
        .await
        .map_err(|e| multipart_error(&e, limit_bytes, None))?
    {
        let Some(name) = part.name().map(str::to_owned) else {
            return Err(malformed_multipart(
                format!("a part has no name; send the parts `{IMAGE_PART}` and `{REQUEST_PART}`"),
                None,
            ));
        };
        let slot = match name.as_str() {
            IMAGE_PART => &mut image,
            REQUEST_PART => &mut request_json,
            _ => {
                return Err(Problem::new(
                    ErrorCode::UnknownField,
                    format!(
                        "unknown part `{name}`; send the parts `{IMAGE_PART}` and `{REQUEST_PART}`"
                    ),
                )
                .with_field(name)
                .into());
            }
        };
        if slot.is_some() {
            return Err(malformed_multipart(
                format!("the part `{name}` is given twice"),
                Some(name),
            ));
        }
        let bytes = part
            .bytes()
            .await
            .map_err(|e| multipart_error(&e, limit_bytes, Some(&name)))?;
        *slot = Some(bytes);
    }
    let image = image.ok_or_else(|| missing_part(IMAGE_PART))?;
    let request_json = request_json.ok_or_else(|| missing_part(REQUEST_PART))?;
    Ok(Input::Multipart {
        image,
        request_json,
    })
}

/// The name of the first query parameter, if the query has any.
fn first_query_parameter(query: Option<&str>) -> Option<String> {
    form_urlencoded::parse(query?.as_bytes())
        .next()
        .map(|(name, _)| name.into_owned())
}

fn body_error(err: BodyError, unreadable: ErrorCode) -> ApiError {
    match err {
        BodyError::TooLarge { limit_bytes } => ApiError::payload_too_large(limit_bytes),
        BodyError::Unreadable { .. } => ApiError::new(unreadable, err.to_string()),
    }
}

fn malformed_multipart(detail: impl Into<String>, part: Option<String>) -> ApiError {
    let problem = Problem::new(ErrorCode::MalformedMultipart, detail);
    ApiError::from(match part {
        Some(part) => problem.with_field(part),
        None => problem,
    })
}

/// A multipart parse error: 413 when a size limit was hit, else 400 (axum would answer 500
/// for some stream errors; none of them is a fault of the service here, the body being in
/// memory already).
fn multipart_error(err: &MultipartError, limit_bytes: usize, part: Option<&str>) -> ApiError {
    if err.status() == StatusCode::PAYLOAD_TOO_LARGE {
        return ApiError::payload_too_large(limit_bytes);
    }
    malformed_multipart(err.body_text(), part.map(str::to_owned))
}

fn missing_part(name: &str) -> ApiError {
    Problem::new(
        ErrorCode::MissingField,
        format!("the multipart body has no part `{name}`"),
    )
    .with_field(name)
    .into()
}

/// What the metrics need to know of an answered image.
struct Outcome {
    codes: usize,
    poses: Vec<PoseOutcome>,
}

/// What the metrics need to know of one marker's pose.
struct PoseOutcome {
    method: String,
    iterations: u32,
    converged: bool,
}

/// Parses the request part (multipart), decodes, detects, estimates and serialises, all on
/// the estimation worker.
fn estimate_to_json(input: Input, limits: &DecodeLimits) -> Result<(Vec<u8>, Outcome), ApiError> {
    let response: ImageResponse = match input {
        Input::Raw { image, request } => {
            estimate_image(&image, &request, limits).map_err(ImageQuery::problem_in_query_terms)?
        }
        Input::Multipart {
            image,
            request_json,
        } => {
            let request = parse_json::<ImageRequest>(&request_json)?;
            estimate_image(&image, &request, limits)?
        }
    };
    let json = serde_json::to_vec(&response).map_err(ApiError::internal)?;
    let poses = response
        .markers
        .iter()
        .filter_map(|m| m.pose.as_ref())
        .map(|pose| PoseOutcome {
            method: pose.diagnostics.method.clone(),
            iterations: pose.diagnostics.iterations,
            converged: pose.diagnostics.converged,
        })
        .collect();
    Ok((
        json,
        Outcome {
            codes: response.markers.len(),
            poses,
        },
    ))
}
