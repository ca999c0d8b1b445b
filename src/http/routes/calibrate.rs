//! `POST /v1/calibrate`: the camera calibrated from 3 to 100 photos of a printed QR code.
//! The multipart body (parts `image`, repeated, and `request`) is read whole, within the
//! body limit, by [`CalibrateInput`]; parsing the request, [`crate::api::calibrate::respond`]
//! (decoding, detection and the solve) and serialising run on an estimation worker, which
//! first takes the pixel budget of the largest photo (they are decoded one at a time).

use crate::api::calibrate::{CalibrateRequest, CalibrateResponse, respond};
use crate::api::problem::{ErrorCode, Problem, parse_json};
use crate::app::CancelFlag;
use crate::app::ImageLimits;
use crate::http::{
    error::ApiError,
    extract::{self, JsonBytes},
    image_input::{self, ImageParts, MULTIPART},
    state::AppState,
};
use axum::body::Bytes;
use axum::extract::{FromRequest, Request, State};
use utoipa::ToSchema;

/// The route.
pub const PATH: &str = "/v1/calibrate";

// Documentation only: the handler reads the parts itself, so that every mistake is answered
// with a problem document.
/// The multipart form of `POST /v1/calibrate`: the photos and the request.
#[derive(Debug, ToSchema)]
pub struct CalibrateForm {
    /// The photos, one part `image` each, 3 to 100, from one camera at one resolution: JPEG
    /// or PNG bytes (the format is read from the bytes).
    #[schema(schema_with = photos_schema)]
    pub image: Vec<Vec<u8>>,
    /// The request as JSON (`application/json`): the printed code's size and the lens model.
    pub request: CalibrateRequest,
}

/// The `image` parts: 3 to 100 files of bytes.
fn photos_schema() -> utoipa::openapi::schema::Array {
    photos_array(
        crate::app::MIN_PHOTOS,
        crate::app::MAX_PHOTOS,
        "The photos, one part `image` each, 3 to 100, from one camera at one resolution: \
         JPEG or PNG bytes (the format is read from the bytes).",
    )
}

/// `min` to `max` `image` parts of bytes (`format: binary` beside the 3.1
/// `contentMediaType`, for generators that read only the OpenAPI 3.0 form).
pub(super) fn photos_array(
    min: usize,
    max: usize,
    description: &str,
) -> utoipa::openapi::schema::Array {
    use utoipa::openapi::schema::{ArrayBuilder, KnownFormat, ObjectBuilder, SchemaFormat, Type};
    let photo = ObjectBuilder::new()
        .schema_type(Type::String)
        .format(Some(SchemaFormat::KnownFormat(KnownFormat::Binary)))
        .content_media_type("application/octet-stream");
    ArrayBuilder::new()
        .items(photo)
        .min_items(Some(min))
        .max_items(Some(max))
        .description(Some(description))
        .build()
}

/// Calibrate the camera from photos of a printed QR code.
///
/// Send 3 to 100 photos of one printed QR code (JPEG or PNG, one camera, one resolution),
/// each a part `image` of a `multipart/form-data` body, and a part `request` (JSON: the
/// code's `marker.size_mm`, and the lens `model`: `plumb_bob`, `rational_polynomial` or
/// `equidistant`). Each photo's decoded code gives its finder corners, alignment centres
/// and module corners; Zhang's method and one robust Levenberg-Marquardt give the camera,
/// one standard deviation per parameter, each photo's fit (views that do not fit are
/// dropped, with the reason) and warnings when the photos do not constrain the solution
/// (too few views, one angle only, image corners never covered, a focal length uncertain
/// by more than 0.5 %). `opencv_yaml` and `ros_camera_info_yaml` are files that a site
/// file's `calibration:` reads as they are. The same JSON as `qrpose calibrate`. Many large
/// photos may need a longer `--request-timeout-ms` than the default.
#[utoipa::path(
    post,
    path = "/v1/calibrate",
    tag = "calibration",
    operation_id = "calibrate",
    request_body(
        description = "A multipart form with 3 to 100 parts `image` and one part `request`.",
        content((inline(CalibrateForm) = "multipart/form-data")),
    ),
    responses(
        (status = 200, description = "The camera, its standard deviations, every photo's \
            view, the warnings and the calibration files.", body = CalibrateResponse),
        (status = 400, description = "`malformed_multipart`: the multipart body cannot be \
            parsed (no boundary, broken framing, a part without a name, `request` twice); \
            `malformed_json`: the `request` part is not JSON.",
            body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "`payload_too_large`: the body exceeds the configured \
            limit (`--body-limit-bytes`); `image_too_large`: a photo declares more pixels \
            than the configured limit (`--max-image-pixels`); `field` is `image/K`, K the \
            photo's index.",
            body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "`unsupported_media_type`: the Content-Type is not \
            `multipart/form-data`.",
            body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "A well-formed request that gives no calibration \
            (`too_few_views`: fewer than 3 photos, fewer than 3 with a code giving enough \
            points, or fewer left once the views that do not fit are dropped; \
            `mixed_image_sizes` and `undecodable_image` name the photo, `image/K`; \
            `calibration_failed`: the solve failed, e.g. every photo facing the code \
            squarely).",
            body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:qrpose:problem:too_few_views",
                "title": "Too few usable views", "status": 422,
                "detail": "2 of 4 photos show a code with at least 8 calibration points; a calibration needs at least 3 (photos without a code: 1, 3)",
                "code": "too_few_views", "field": "image"})),
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
pub async fn calibrate(
    State(state): State<AppState>,
    input: CalibrateInput,
) -> Result<JsonBytes, ApiError> {
    let limits = state.image_limits();
    let pixels = input.admission_pixels(&limits);
    let json = state
        .queue
        .run_image(pixels, move |cancel| {
            answer_as_json(&input, &limits, &cancel)
        })
        .await??;
    Ok(JsonBytes(json))
}

/// Parses the request part, calibrates and serialises, on the estimation worker.
fn answer_as_json(
    input: &CalibrateInput,
    limits: &ImageLimits,
    cancel: &CancelFlag,
) -> Result<Vec<u8>, ApiError> {
    let request = parse_json::<CalibrateRequest>(&input.request_json)?;
    let response = respond(&request, limits, &input.photos, cancel)?;
    serde_json::to_vec(&response).map_err(ApiError::internal)
}

/// The body of `POST /v1/calibrate`: the photos and the `request` part, not yet parsed.
#[derive(Debug, Clone)]
pub struct CalibrateInput {
    /// The `image` parts, in order.
    pub photos: Vec<Bytes>,
    /// The `request` part.
    pub request_json: Bytes,
}

impl CalibrateInput {
    /// The pixel budget the photos take on a worker: that of the largest, since they are
    /// decoded one at a time.
    pub fn admission_pixels(&self, limits: &ImageLimits) -> u64 {
        self.photos
            .iter()
            .map(|p| crate::app::admission_pixels(p, limits.decode.max_pixels))
            .max()
            .unwrap_or(0)
    }
}

impl FromRequest<AppState> for CalibrateInput {
    type Rejection = ApiError;

    async fn from_request(request: Request, state: &AppState) -> Result<Self, ApiError> {
        let limit_bytes = state.settings.body_limit_bytes;
        if extract::media_type(request.headers()).as_deref() != Some(MULTIPART) {
            let refusal = ApiError::unsupported_media_type(
                extract::media_type(request.headers()).as_deref(),
                MULTIPART,
            );
            extract::discard_body(request, limit_bytes).await;
            return Err(refusal);
        }
        let permit = image_input::take_body_bytes(&request, state)?;
        let request = extract::buffer_body(request, limit_bytes, |bytes| {
            image_input::budgeted(bytes, permit)
        })
        .await
        .map_err(|e| image_input::body_error(e, ErrorCode::MalformedMultipart))?;
        let (photos, request_json) =
            image_input::read_form(request, state, limit_bytes, ImageParts::Many).await?;
        Ok(Self {
            photos,
            request_json,
        })
    }
}
