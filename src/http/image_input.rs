//! [`ImageInput`]: the body of `POST /v1/pose/image` in either of its forms, as an axum
//! extractor whose rejection is the API's own problem document (axum's
//! "customize-extractor-error" pattern), so that the handler sees only a well-formed input.
//!
//! - A raw image body (`image/jpeg` or `image/png`) with the request as query parameters
//!   ([`ImageQuery`]); a problem's `field` names the query parameter.
//! - `multipart/form-data` with the parts `image` (the bytes) and `request` (JSON,
//!   `ImageRequest`); a problem's `field` names the part, or is a JSON pointer into the
//!   `request` part. Its JSON is parsed later, on the estimation worker. Query parameters
//!   may come with it: a field given in both is the part's (`api::image::merge`).
//!
//! The body is read whole (at most the body limit, as every body) before anything is judged,
//! so that a client still sending a large upload reads its answer instead of a connection
//! reset; a 415 drains the body for the same reason. The image format is sniffed from the
//! bytes, so the content type only chooses the form.

use super::{
    error::ApiError,
    extract::{self, BodyError},
    queue::BudgetPermit,
    state::AppState,
};
use crate::api::{
    image::{ImageQuery, merge::request_of_parts},
    problem::{ErrorCode, Problem},
};
use crate::app::Site;
use crate::app::{ImageLimits, ImageSetup};
use axum::body::Bytes;
use axum::extract::{FromRequest, Multipart, Request, multipart::MultipartError};
use axum::http::StatusCode;
use std::sync::Arc;

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

/// An image request as read from the body, before the worker parses, decodes and detects.
#[derive(Debug, Clone)]
pub enum ImageInput {
    /// A raw image body and its query parameters, parsed.
    Raw {
        /// The image bytes.
        image: Bytes,
        /// The query parameters.
        query: Box<ImageQuery>,
    },
    /// A multipart body: the image part and the request part's JSON, not yet parsed, and
    /// the query parameters, if the URL has any (merged under the part, [`merge`]).
    Multipart {
        /// The `image` part.
        image: Bytes,
        /// The `request` part.
        request_json: Bytes,
        /// The query parameters, parsed.
        query: Option<Box<ImageQuery>>,
    },
}

impl ImageInput {
    /// The image bytes, whichever form the body had.
    pub fn image(&self) -> &Bytes {
        match self {
            Self::Raw { image, .. } | Self::Multipart { image, .. } => image,
        }
    }

    /// The request validated against `site` into the application's setup: the query
    /// parameters of a raw body, or the multipart `request` part (with any query parameters
    /// under it). Parsing the part's JSON is CPU work: call it on an estimation worker.
    ///
    /// # Errors
    /// The request's problems; `field` names a query parameter when the value came from
    /// the query.
    pub fn setup(
        &self,
        limits: &ImageLimits,
        site: Option<Arc<Site>>,
    ) -> Result<ImageSetup, Problem> {
        match self {
            Self::Raw { query, .. } => ImageQuery::clone(query).setup(limits, site),
            Self::Multipart {
                request_json,
                query,
                ..
            } => {
                let parts = request_of_parts(request_json, query.as_deref())?;
                parts
                    .request
                    .setup(limits, site)
                    .map_err(|problem| parts.problem_as_sent(problem))
            }
        }
    }

    /// What this image weighs against the pixel budget of the estimation queue
    /// ([`crate::app::admission_pixels`]: its declared size, WebP twice).
    pub fn admission_pixels(&self, max_pixels: u64) -> u64 {
        crate::app::admission_pixels(self.image(), max_pixels)
    }
}

impl FromRequest<AppState> for ImageInput {
    type Rejection = ApiError;

    async fn from_request(request: Request, state: &AppState) -> Result<Self, ApiError> {
        let limit_bytes = state.settings.body_limit_bytes;
        match extract::media_type(request.headers()).as_deref() {
            Some(JPEG | PNG) => {
                let permit = take_body_bytes(&request, state)?;
                raw_input(request, limit_bytes, permit).await
            }
            Some(MULTIPART) => {
                let permit = take_body_bytes(&request, state)?;
                multipart_input(request, state, permit).await
            }
            got => {
                let refusal = ApiError::unsupported_media_type(got, ACCEPTED);
                extract::discard_body(request, limit_bytes).await;
                Err(refusal)
            }
        }
    }
}

/// The share of the body budget ([`crate::http::queue::EstimationQueue::take_body_bytes`])
/// that `request`'s body may need: its declared length, or the body limit when it declares
/// none (chunked). Taken before a byte is read, so that bodies being read count too.
pub(crate) fn take_body_bytes(
    request: &Request,
    state: &AppState,
) -> Result<BudgetPermit, ApiError> {
    let limit_bytes = state.settings.body_limit_bytes;
    let bytes =
        extract::declared_length(request.headers()).map_or(limit_bytes, |n| n.min(limit_bytes));
    state
        .queue
        .take_body_bytes(u64::try_from(bytes).unwrap_or(u64::MAX))
}

/// Body bytes that give their share of the body budget back when the last reference to them
/// is dropped (the parts of a multipart body refer into it too).
struct Budgeted {
    bytes: Bytes,
    _permit: BudgetPermit,
}

impl AsRef<[u8]> for Budgeted {
    fn as_ref(&self) -> &[u8] {
        &self.bytes
    }
}

/// `bytes` holding `permit` until the last reference to them is dropped.
pub(crate) fn budgeted(bytes: Bytes, permit: BudgetPermit) -> Bytes {
    Bytes::from_owner(Budgeted {
        bytes,
        _permit: permit,
    })
}

/// The raw-body form: the image bytes and the query parameters.
async fn raw_input(
    request: Request,
    limit_bytes: usize,
    permit: BudgetPermit,
) -> Result<ImageInput, ApiError> {
    let query = request.uri().query().map(str::to_owned);
    let image = extract::read_body(request, limit_bytes)
        .await
        .map_err(|e| body_error(e, ErrorCode::UndecodableImage))?;
    let image = budgeted(image, permit);
    let query = extract::parse_query::<ImageQuery>(query.as_deref())?;
    Ok(ImageInput::Raw {
        image,
        query: Box::new(query),
    })
}

/// The multipart form: the `image` and `request` parts, each exactly once.
async fn multipart_input(
    request: Request,
    state: &AppState,
    permit: BudgetPermit,
) -> Result<ImageInput, ApiError> {
    let limit_bytes = state.settings.body_limit_bytes;
    let query = match request.uri().query() {
        Some(q) if !q.is_empty() => match extract::parse_query::<ImageQuery>(Some(q)) {
            Ok(query) => Some(Box::new(query)),
            Err(refusal) => {
                extract::discard_body(request, limit_bytes).await;
                return Err(refusal);
            }
        },
        _ => None,
    };
    let request = extract::buffer_body(request, limit_bytes, |body| budgeted(body, permit))
        .await
        .map_err(|e| body_error(e, ErrorCode::MalformedMultipart))?;
    let (images, request_json) = read_form(request, state, limit_bytes, ImageParts::One).await?;
    let image = images
        .into_iter()
        .next()
        .ok_or_else(|| missing_part(IMAGE_PART))?;
    Ok(ImageInput::Multipart {
        image,
        request_json,
        query,
    })
}

/// How many `image` parts a form takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ImageParts {
    /// Exactly one (`POST /v1/pose/image`); a second is `malformed_multipart`.
    One,
    /// One or more, in order (`POST /v1/calibrate`).
    Many,
}

/// The one multipart reader of the service: the `image` parts (as `images` says) and the
/// `request` part, exactly once, from a body already buffered; any other part is refused
/// (`unknown_field`), a missing one is `missing_field`, broken framing `malformed_multipart`.
pub(crate) async fn read_form(
    request: Request,
    state: &AppState,
    limit_bytes: usize,
    images: ImageParts,
) -> Result<(Vec<Bytes>, Bytes), ApiError> {
    let mut multipart = Multipart::from_request(request, state)
        .await
        .map_err(|rejection| malformed_multipart(rejection.body_text(), None))?;
    let expected = match images {
        ImageParts::One => format!("`{IMAGE_PART}` and `{REQUEST_PART}`"),
        ImageParts::Many => format!("`{IMAGE_PART}` (repeated) and `{REQUEST_PART}`"),
    };
    let (mut photos, mut request_json) = (Vec::new(), None);
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
        let twice = match name.as_str() {
            IMAGE_PART => images == ImageParts::One && !photos.is_empty(),
            REQUEST_PART => request_json.is_some(),
            _ => {
                let detail = format!("unknown part `{name}`; send the parts {expected}");
                let problem = Problem::new(ErrorCode::UnknownField, detail).with_field(name);
                return Err(problem.into());
            }
        };
        if twice {
            let detail = format!("the part `{name}` is given twice");
            return Err(malformed_multipart(detail, Some(name)));
        }
        let bytes = part
            .bytes()
            .await
            .map_err(|e| multipart_error(&e, limit_bytes, Some(&name)))?;
        match name.as_str() {
            IMAGE_PART => photos.push(bytes),
            _ => request_json = Some(bytes),
        }
    }
    if photos.is_empty() {
        return Err(missing_part(IMAGE_PART));
    }
    let request_json = request_json.ok_or_else(|| missing_part(REQUEST_PART))?;
    Ok((photos, request_json))
}

/// A body that could not be buffered: 413 over the limit, else `unreadable`.
pub(crate) fn body_error(err: BodyError, unreadable: ErrorCode) -> ApiError {
    match err {
        BodyError::TooLarge { limit_bytes } => ApiError::payload_too_large(limit_bytes),
        BodyError::Unreadable { .. } => ApiError::new(unreadable, err.to_string()),
    }
}

/// 400 `malformed_multipart`, naming the part when there is one.
pub(crate) fn malformed_multipart(detail: impl Into<String>, part: Option<String>) -> ApiError {
    let problem = Problem::new(ErrorCode::MalformedMultipart, detail);
    ApiError::from(match part {
        Some(part) => problem.with_field(part),
        None => problem,
    })
}

/// A multipart parse error: 413 when a size limit was hit, else 400 (axum would answer 500
/// for some stream errors; none of them is a fault of the service here, the body being in
/// memory already).
pub(crate) fn multipart_error(
    err: &MultipartError,
    limit_bytes: usize,
    part: Option<&str>,
) -> ApiError {
    if err.status() == StatusCode::PAYLOAD_TOO_LARGE {
        return ApiError::payload_too_large(limit_bytes);
    }
    malformed_multipart(err.body_text(), part.map(str::to_owned))
}

/// 422 `missing_field` for a multipart part not sent.
pub(crate) fn missing_part(name: &str) -> ApiError {
    Problem::new(
        ErrorCode::MissingField,
        format!("the multipart body has no part `{name}`"),
    )
    .with_field(name)
    .into()
}
