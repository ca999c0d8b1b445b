//! `POST /v1/pose/image/annotated`: the inputs of `POST /v1/pose/image`, answered with the
//! photo and the overlay drawn on it (src/annotate), JPEG by default or PNG on
//! `Accept: image/png`, and the JSON of `/v1/pose/image` base64url-encoded in the header
//! [`RESULT_HEADER`] (docs/service.md, The annotated image).
//!
//! Detection, estimation, drawing and encoding run on one estimation worker job, behind the
//! same queue and pixel budget as `/v1/pose/image`; the job holds the frame in colour too,
//! so it weighs twice the plain endpoint's pixels.

use crate::annotate::{CodecError, OutputFormat, annotated_image};
use crate::api::image::{ImageQuery, ImageResponse, answer};
use crate::api::problem::{ErrorCode, Problem};
use crate::app::CancelFlag;
use crate::app::ImageLimits;
use crate::app::Site;
use crate::http::{
    error::ApiError, image_input::ImageInput, metrics::PoseOutcome, negotiate::negotiate_format,
    routes::image::ImageForm, state::AppState,
};
use axum::extract::State;
use axum::http::{HeaderMap, HeaderName, HeaderValue, header};
use axum::response::{IntoResponse, Response};
use base64::Engine;
use std::sync::Arc;

/// The route.
pub const PATH: &str = "/v1/pose/image/annotated";
/// The response header with the JSON of `/v1/pose/image`, base64url without padding.
pub const RESULT_HEADER: &str = "x-qrpose-result";
/// Sent instead of [`RESULT_HEADER`] when the encoded JSON is over
/// [`MAX_RESULT_HEADER_BYTES`]: its encoded size, bytes.
pub const RESULT_OMITTED_HEADER: &str = "x-qrpose-result-omitted";
/// The number of codes found (always sent).
pub const MARKERS_HEADER: &str = "x-qrpose-markers";
/// The longest [`RESULT_HEADER`] value, bytes: one code's result takes about 4 KiB, so a
/// dozen codes fit; larger results are left out rather than break a proxy's or client's
/// header limit (curl allows 100 KiB per header, nginx 4-8 KiB by default for all of them:
/// raise its `proxy_buffer_size` to 32k in front of this route).
pub const MAX_RESULT_HEADER_BYTES: usize = 16 * 1024;

/// The result headers: the JSON when it fits, else its encoded size; and the marker count.
fn result_headers(json: &[u8], markers: usize) -> Result<HeaderMap, ApiError> {
    let encoded = base64::engine::general_purpose::URL_SAFE_NO_PAD.encode(json);
    let mut headers = HeaderMap::new();
    let (name, value) = if encoded.len() <= MAX_RESULT_HEADER_BYTES {
        (RESULT_HEADER, encoded)
    } else {
        (RESULT_OMITTED_HEADER, encoded.len().to_string())
    };
    let value = HeaderValue::try_from(value).map_err(ApiError::internal)?;
    headers.insert(HeaderName::from_static(name), value);
    headers.insert(HeaderName::from_static(MARKERS_HEADER), markers.into());
    Ok(headers)
}

/// What the handler gets back from the worker.
struct Annotated {
    image: Vec<u8>,
    json: Vec<u8>,
    response: ImageResponse,
}

/// The client's share of a failure to draw: a colour decoder refusing what the grey one
/// read is the image's fault (422 `undecodable_image`), a frame JPEG cannot hold (over
/// 65535 px a side) is 413 `image_too_large`.
fn refusal_of(err: &CodecError) -> ApiError {
    match err {
        CodecError::Decode(_) => ApiError::new(ErrorCode::UndecodableImage, err.to_string()),
        CodecError::Encode(_) => ApiError::new(
            ErrorCode::ImageTooLarge,
            format!("{err}; JPEG holds at most 65535 px a side, ask for image/png"),
        ),
    }
}

/// Validates, estimates, draws and encodes, on the estimation worker.
fn annotate_job(
    input: &ImageInput,
    limits: &ImageLimits,
    site: Option<Arc<Site>>,
    format: OutputFormat,
    cancel: CancelFlag,
) -> Result<Annotated, ApiError> {
    let setup = input.setup(limits, site)?;
    let (answer, response) = answer(&setup, input.image(), cancel)?;
    let camera = &setup.pose.camera;
    let image =
        annotated_image(input.image(), &answer, camera, format).map_err(|e| refusal_of(&e))?;
    let json = serde_json::to_vec(&response).map_err(ApiError::internal)?;
    Ok(Annotated {
        image,
        json,
        response,
    })
}

/// The photo with every QR code found drawn on it.
///
/// The same inputs as `POST /v1/pose/image` (raw body with query parameters, or multipart
/// with parts `image` and `request`), the same detection and poses, and the same problem
/// documents on error. The answer is the photo with, per code: its outline (yellow), a
/// magenta square on each refined corner, its payload (white on black), and the marker
/// frame's axes projected from its pose and drawn from the marker centre, x red, y green,
/// z blue (into the printed face), each as long as the marker's side. JPEG unless `Accept`
/// prefers `image/png`. The JSON of `/v1/pose/image` is in the header `X-Qrpose-Result`,
/// base64url-encoded without padding, when that takes at most 16384 bytes; otherwise
/// `X-Qrpose-Result-Omitted` gives its encoded size (ask `/v1/pose/image` for it).
/// `qrpose estimate --image … --annotate OUT` writes the same picture.
#[utoipa::path(
    post,
    path = "/v1/pose/image/annotated",
    tag = "pose",
    operation_id = "pose_from_image_annotated",
    params(ImageQuery),
    request_body(
        description = "As `POST /v1/pose/image`: the photo as the raw body (`image/jpeg` or \
            `image/png`, with query parameters), or a multipart form with the parts `image` \
            and `request`.",
        content(
            ("image/jpeg"),
            ("image/png"),
            (inline(ImageForm) = "multipart/form-data"),
        ),
    ),
    responses(
        (status = 200, description = "The photo with the overlay, at its own size: JPEG by \
            default, PNG when `Accept` prefers `image/png` (an `Accept` naming neither gets \
            JPEG).",
            content(("image/jpeg"), ("image/png")),
            headers(
                ("X-Qrpose-Result" = String, description = "The JSON of `POST /v1/pose/image` \
                    for this photo, base64url without padding (RFC 4648 §5); absent when the \
                    encoding would be longer than 16384 bytes."),
                ("X-Qrpose-Result-Omitted" = u64, description = "Instead of \
                    `X-Qrpose-Result` when the result is too long for a header: its encoded \
                    size, bytes."),
                ("X-Qrpose-Markers" = u32, description = "The number of codes found."),
            )),
        (status = 400, description = "As `POST /v1/pose/image`: `malformed_query`, \
            `malformed_multipart`, `malformed_json`.",
            body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "As `POST /v1/pose/image`: `payload_too_large`, \
            `image_too_large`.",
            body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "`unsupported_media_type`: the Content-Type is missing or \
            not `image/jpeg`, `image/png` or `multipart/form-data`.",
            body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "As `POST /v1/pose/image`.",
            body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:qrpose:problem:undecodable_image",
                "title": "Undecodable image", "status": 422,
                "detail": "unsupported image format: expected JPEG, PNG or WebP",
                "code": "undecodable_image"})),
        (status = 503, description = "`overloaded` or `timeout`, as `POST /v1/pose/image`.",
            body = Problem, content_type = "application/problem+json",
            headers(("Retry-After" = u32, description = "Seconds to wait before retrying"))),
        (status = 500, description = "`internal`: a fault of the service.",
            body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn pose_from_image_annotated(
    State(state): State<AppState>,
    request_headers: HeaderMap,
    input: ImageInput,
) -> Result<Response, ApiError> {
    let format = negotiate_format(request_headers.get(header::ACCEPT));
    let limits = state.image_limits();
    // Twice the plain route's weight (the frame is held in colour too), but never more than
    // the largest image, which the pixel budget always admits.
    let plain_pixels = input.admission_pixels(limits.decode.max_pixels);
    let pixels = plain_pixels
        .saturating_mul(2)
        .min(limits.decode.max_pixels.max(plain_pixels));
    // One snapshot of the site for the whole request, as `/v1/pose/image`.
    let site = state.site.current();
    let annotated = state
        .queue
        .run_image(pixels, move |cancel| {
            annotate_job(&input, &limits, site, format, cancel)
        })
        .await??;
    let markers = &annotated.response.markers;
    state.metrics.observe_codes_detected(markers.len());
    for pose in markers.iter().filter_map(|m| m.pose.as_ref()) {
        state.metrics.observe_estimate(PoseOutcome::from(pose));
    }
    let headers = result_headers(&annotated.json, markers.len())?;
    Ok((
        [
            (header::CONTENT_TYPE, format.media_type()),
            (header::VARY, "accept"),
        ],
        headers,
        annotated.image,
    )
        .into_response())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_result_too_long_for_a_header_is_left_out_with_its_size() {
        let small = result_headers(b"{\"markers\":[]}", 0).expect("headers");
        let decoded = base64::engine::general_purpose::URL_SAFE_NO_PAD
            .decode(small[RESULT_HEADER].as_bytes())
            .expect("base64url");
        assert_eq!(decoded, b"{\"markers\":[]}");
        assert_eq!(small[MARKERS_HEADER], "0");
        let large = result_headers(&vec![b'x'; MAX_RESULT_HEADER_BYTES], 3).expect("headers");
        assert!(!large.contains_key(RESULT_HEADER));
        let expected = (MAX_RESULT_HEADER_BYTES * 4).div_ceil(3);
        assert_eq!(large[RESULT_OMITTED_HEADER], expected.to_string().as_str());
    }
}
