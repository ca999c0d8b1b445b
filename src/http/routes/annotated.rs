//! `POST /v1/pose/image/annotated`: the inputs of `POST /v1/pose/image`, answered with the
//! photo and the overlay drawn on it (src/annotate), JPEG by default or PNG on
//! `Accept: image/png`, and the JSON of `/v1/pose/image` base64url-encoded in the header
//! [`RESULT_HEADER`] (docs/service.md, The annotated image).
//!
//! Detection, estimation, drawing and encoding run on one estimation worker job, behind the
//! same queue and pixel budget as `/v1/pose/image`; the job holds the frame in colour too,
//! so it weighs twice the plain endpoint's pixels.

use crate::annotate::{CodecError, OutputFormat, annotated_image};
use crate::api::image::{ImageLimits, ImageQuery, ImageResponse};
use crate::api::problem::{ErrorCode, Problem};
use crate::detect::decode::DecodeLimits;
use crate::http::{
    error::ApiError,
    image_input::{ImageInput, MULTIPART},
    metrics::PoseOutcome,
    routes::image::{self, ImageForm, estimate_with_camera_in},
    state::AppState,
};
use axum::extract::State;
use axum::http::{HeaderMap, HeaderName, HeaderValue, header};
use axum::response::{IntoResponse, Response};
use base64::Engine;
use qrpose_site::Site;
use std::collections::BTreeMap;
use utoipa::openapi::{OpenApi, RefOr, encoding::Encoding};

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

/// The encoding an `Accept` header asks for: PNG when it prefers `image/png` to
/// `image/jpeg` (by q-value, the most specific matching range deciding each); JPEG
/// otherwise, including when it names neither (the route then answers as if no `Accept`
/// was sent, RFC 9110 §12.5.1, rather than 406).
pub fn negotiate_format(accept: Option<&HeaderValue>) -> OutputFormat {
    let Some(accept) = accept.and_then(|v| v.to_str().ok()) else {
        return OutputFormat::Jpeg;
    };
    let quality = |media_type: &str| quality_of(accept, media_type);
    if quality("image/png") > quality("image/jpeg") {
        OutputFormat::Png
    } else {
        OutputFormat::Jpeg
    }
}

/// The q-value `accept` gives `media_type` (`type/subtype`, lower case): that of the most
/// specific range matching it (exact, then `type/*`, then `*/*`), 0 when none does.
fn quality_of(accept: &str, media_type: &str) -> f64 {
    let main_type = media_type.split('/').next().unwrap_or_default();
    let mut best: Option<(u8, f64)> = None;
    for range in accept.split(',') {
        let mut parts = range.split(';');
        let name = parts.next().unwrap_or_default().trim().to_ascii_lowercase();
        let specificity = if name == media_type {
            3
        } else if name.strip_suffix("/*") == Some(main_type) {
            2
        } else if name == "*/*" {
            1
        } else {
            continue;
        };
        let q = parts
            .filter_map(|p| p.trim().strip_prefix("q="))
            .find_map(|q| q.trim().parse::<f64>().ok())
            .filter(|q| (0.0..=1.0).contains(q))
            .unwrap_or(1.0);
        if best.is_none_or(|(s, _)| specificity > s) {
            best = Some((specificity, q));
        }
    }
    best.map_or(0.0, |(_, q)| q)
}

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

/// Gives the multipart form of this route the part media types of `POST /v1/pose/image`'s
/// (call after [`super::image::document_part_media_types`]): the two take the same parts.
pub fn document_part_media_types(doc: &mut OpenApi) {
    let Some(encoding) = multipart_encoding(doc, image::PATH).map(|e| e.clone()) else {
        return;
    };
    if let Some(target) = multipart_encoding(doc, PATH) {
        *target = encoding;
    }
}

/// The part media types of the multipart request body of `POST path`, if documented.
fn multipart_encoding<'a>(
    doc: &'a mut OpenApi,
    path: &str,
) -> Option<&'a mut BTreeMap<String, Encoding>> {
    let body = doc
        .paths
        .paths
        .get_mut(path)?
        .post
        .as_mut()?
        .request_body
        .as_mut()?;
    let RefOr::T(body) = body else { return None };
    match body.content.get_mut(MULTIPART)? {
        RefOr::T(content) => Some(&mut content.encoding),
        RefOr::Ref(_) => None,
    }
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

/// Estimates, draws and encodes, on the estimation worker.
fn annotate_job(
    input: &ImageInput,
    limits: &ImageLimits,
    site: Option<&Site>,
    format: OutputFormat,
) -> Result<Annotated, ApiError> {
    let (response, camera) = estimate_with_camera_in(input, limits, site)?;
    let image =
        annotated_image(input.image(), &response, &camera, format).map_err(|e| refusal_of(&e))?;
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
        (status = 422, description = "As `POST /v1/pose/image`; e.g. `undecodable_image`, \
            `missing_field`, `incomplete_camera`.",
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
    let limits = ImageLimits {
        decode: DecodeLimits {
            max_encoded_bytes: state.settings.body_limit_bytes,
            max_pixels: state.settings.max_image_pixels,
        },
        max_detect_ms: state.settings.max_detect.as_secs_f64() * 1e3,
    };
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
        .run_image(pixels, move || {
            annotate_job(&input, &limits, site.as_deref(), format)
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

    fn format_for(accept: &str) -> OutputFormat {
        negotiate_format(Some(
            &HeaderValue::from_str(accept).expect("a header value"),
        ))
    }

    #[test]
    fn accept_chooses_png_only_when_it_prefers_png() {
        assert_eq!(negotiate_format(None), OutputFormat::Jpeg);
        for (accept, expected) in [
            ("image/png", OutputFormat::Png),
            ("IMAGE/PNG", OutputFormat::Png),
            ("image/png, image/jpeg", OutputFormat::Jpeg),
            ("image/jpeg;q=0.5, image/png", OutputFormat::Png),
            ("image/*;q=0.2, image/png;q=0.9", OutputFormat::Png),
            ("image/png;q=0.4, image/*", OutputFormat::Jpeg),
            ("image/png, */*;q=0.1", OutputFormat::Png),
            ("*/*", OutputFormat::Jpeg),
            ("application/json", OutputFormat::Jpeg),
            ("image/png;q=nonsense", OutputFormat::Png),
        ] {
            assert_eq!(format_for(accept), expected, "Accept: {accept}");
        }
    }

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
