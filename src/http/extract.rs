//! Request bodies: content-type checks and size-limited reading, with every refusal an
//! [`ApiError`].
//!
//! Bodies are read here rather than with axum's `Json` or `Bytes` extractors for two
//! reasons: parsing happens later on an estimation worker (with
//! [`parse_json`](crate::api::problem::parse_json), which names the field at fault), and a
//! body over the limit is drained (up to [`DRAIN_LIMIT_BYTES`]) before the 413 is sent, so
//! that a client still writing its body reads the answer instead of a connection reset.

use super::error::ApiError;
use super::state::AppState;
use crate::api::problem::{ErrorCode, Problem, ShapeKind};
use axum::body::{Body, Bytes, HttpBody};
use axum::extract::{FromRequest, Request};
use axum::http::{HeaderMap, header};
use axum::response::{IntoResponse, Response};
use serde::de::DeserializeOwned;
use std::pin::Pin;
use std::time::Duration;

/// The media type `POST` bodies of the JSON endpoints must declare.
pub const JSON: &str = "application/json";

/// At most this many bytes of an oversized body are read and discarded before the 413.
pub const DRAIN_LIMIT_BYTES: usize = 64 * 1024 * 1024;

/// A body declared over the limit is discarded in the background, after the 413 has been
/// sent, for at most this long.
pub const BACKGROUND_DRAIN_TIMEOUT: Duration = Duration::from_secs(10);

/// At most this much is reserved before the body arrives, whatever `Content-Length` claims.
const INITIAL_CAPACITY_BYTES: usize = 64 * 1024;

/// Why a body could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BodyError {
    /// The body is longer than the configured limit.
    #[error("the request body exceeds the limit of {limit_bytes} bytes")]
    TooLarge {
        /// The configured limit, bytes.
        limit_bytes: usize,
    },
    /// The connection failed or the framing was invalid while reading.
    #[error("the request body could not be read: {reason}")]
    Unreadable {
        /// What the transport reported.
        reason: String,
    },
}

/// The media type of a request without its parameters, lower-case (`application/json`).
pub fn media_type(headers: &HeaderMap) -> Option<String> {
    let value = headers.get(header::CONTENT_TYPE)?;
    let text = String::from_utf8_lossy(value.as_bytes());
    let essence = text.split(';').next().unwrap_or_default().trim();
    Some(essence.to_ascii_lowercase())
}

/// Whether `media_type` is JSON: `application/json` or a structured `application/*+json`.
fn is_json(media_type: &str) -> bool {
    media_type == JSON
        || media_type
            .strip_prefix("application/")
            .is_some_and(|sub| sub.ends_with("+json"))
}

/// Refuses a request whose content type is not JSON.
///
/// # Errors
/// 415 `unsupported_media_type`, also when the header is missing.
pub fn require_json(headers: &HeaderMap) -> Result<(), ApiError> {
    match media_type(headers) {
        Some(m) if is_json(&m) => Ok(()),
        got => Err(ApiError::unsupported_media_type(got.as_deref(), JSON)),
    }
}

/// The body length a request declares (`Content-Length`), if any.
pub fn declared_length(headers: &HeaderMap) -> Option<usize> {
    headers
        .get(header::CONTENT_LENGTH)?
        .to_str()
        .ok()?
        .parse()
        .ok()
}

fn expects_continue(headers: &HeaderMap) -> bool {
    headers
        .get(header::EXPECT)
        .is_some_and(|v| v.as_bytes().eq_ignore_ascii_case(b"100-continue"))
}

async fn next_data(body: &mut Body) -> Option<Result<Option<Bytes>, axum::Error>> {
    let frame = std::future::poll_fn(|cx| Pin::new(&mut *body).poll_frame(cx)).await?;
    Some(frame.map(|f| f.into_data().ok()))
}

/// Reads and discards what is left of `body`, at most `budget` bytes.
async fn drain(mut body: Body, mut budget: usize) {
    while let Some(Ok(data)) = next_data(&mut body).await {
        let len = data.map_or(0, |d| d.len());
        if len > budget {
            return;
        }
        budget -= len;
    }
}

/// Reads the whole body of `request`, at most `limit_bytes`.
///
/// A body declared longer (`Content-Length`) is refused at once, without waiting for it: what
/// the client still sends is read and discarded in the background (up to
/// [`DRAIN_LIMIT_BYTES`], for at most [`BACKGROUND_DRAIN_TIMEOUT`]) while the 413 goes out,
/// so that a client still uploading reads the answer rather than a connection reset, and one
/// that sends only the headers gets it without delay. A body found to be longer while
/// reading is drained the same way before the refusal. With `Expect: 100-continue` the
/// client has not sent the body yet, so nothing is read.
///
/// # Errors
/// [`BodyError::TooLarge`] over the limit, [`BodyError::Unreadable`] on a transport error.
pub async fn read_body(request: Request, limit_bytes: usize) -> Result<Bytes, BodyError> {
    let (parts, body) = request.into_parts();
    read_limited(&parts.headers, body, limit_bytes).await
}

/// `request` with its body read into memory (at most `limit_bytes`, as [`read_body`]), for
/// extractors that parse a body of their own (axum's `Multipart`) and should meet the same
/// limit and the same drained 413 as every other body. Headers and extensions are kept. The
/// bytes pass through `wrap` before they become the body again (to tie something to their
/// lifetime, as [`Bytes::from_owner`] does; `|bytes| bytes` for nothing).
///
/// # Errors
/// As [`read_body`].
pub async fn buffer_body(
    request: Request,
    limit_bytes: usize,
    wrap: impl FnOnce(Bytes) -> Bytes,
) -> Result<Request, BodyError> {
    let (parts, body) = request.into_parts();
    let bytes = read_limited(&parts.headers, body, limit_bytes).await?;
    Ok(Request::from_parts(parts, Body::from(wrap(bytes))))
}

/// Reads and discards the body of a request that is refused without it (415), at most
/// `limit_bytes` and never with `Expect: 100-continue`, so that a client still sending a
/// large body reads the answer instead of a connection reset.
pub async fn discard_body(request: Request, limit_bytes: usize) {
    if !expects_continue(request.headers()) {
        drain(request.into_body(), limit_bytes.min(DRAIN_LIMIT_BYTES)).await;
    }
}

async fn read_limited(
    headers: &HeaderMap,
    mut body: Body,
    limit_bytes: usize,
) -> Result<Bytes, BodyError> {
    let too_large = BodyError::TooLarge { limit_bytes };
    let declared = declared_length(headers);
    if declared.is_some_and(|n| n > limit_bytes) {
        if !expects_continue(headers) {
            tokio::spawn(async move {
                let _ =
                    tokio::time::timeout(BACKGROUND_DRAIN_TIMEOUT, drain(body, DRAIN_LIMIT_BYTES))
                        .await;
            });
        }
        return Err(too_large);
    }
    // A declared length is only a claim: reserve at most a small amount up front.
    let mut buf = Vec::with_capacity(declared.unwrap_or(0).min(INITIAL_CAPACITY_BYTES));
    while let Some(frame) = next_data(&mut body).await {
        let data = frame
            .map_err(|e| BodyError::Unreadable {
                reason: e.to_string(),
            })?
            .unwrap_or_default();
        if buf.len() + data.len() > limit_bytes {
            drain(body, DRAIN_LIMIT_BYTES.saturating_sub(buf.len())).await;
            return Err(too_large);
        }
        buf.extend_from_slice(&data);
    }
    Ok(Bytes::from(buf))
}

/// Parses a query string (without the `?`; `None` is an empty one) into `T`, as
/// serde_urlencoded reads it.
///
/// # Errors
/// 422 `unknown_field` for a parameter `T` does not have and `unknown_variant` for a value
/// outside an enumerated set (the codes of the same mistakes in a JSON body); 400
/// `malformed_query` for a value that does not parse as its type, a parameter given twice or
/// missing. `field` names the parameter.
pub fn parse_query<T: DeserializeOwned>(query: Option<&str>) -> Result<T, ApiError> {
    let pairs = form_urlencoded::parse(query.unwrap_or_default().as_bytes());
    serde_path_to_error::deserialize(serde_urlencoded::Deserializer::new(pairs))
        .map_err(|e| ApiError::from(query_problem(e.path(), &e.inner().to_string())))
}

/// The problem of a query refused with serde's `message` at `path` (the parameter whose
/// value failed; empty when the message names the parameter itself: a missing, unknown or
/// duplicate one).
fn query_problem(path: &serde_path_to_error::Path, message: &str) -> Problem {
    let kind = ShapeKind::of(message);
    let code = match kind {
        ShapeKind::UnknownField(_) => ErrorCode::UnknownField,
        ShapeKind::UnknownVariant => ErrorCode::UnknownVariant,
        _ => ErrorCode::MalformedQuery,
    };
    let path = path.to_string();
    let field = match kind.field() {
        Some(name) => Some(name.to_owned()),
        None if path.is_empty() || path == "." => None,
        None => Some(path),
    };
    let detail = match &field {
        Some(name) if !message.contains(name.as_str()) => {
            format!("query parameter {name}: {message}")
        }
        _ => message.to_owned(),
    };
    let problem = Problem::new(code, detail);
    match field {
        Some(name) => problem.with_field(name),
        None => problem,
    }
}

/// A JSON body serialised elsewhere (on an estimation worker), sent as `application/json`.
#[derive(Debug, Clone)]
pub struct JsonBytes(pub Vec<u8>);

impl IntoResponse for JsonBytes {
    fn into_response(self) -> Response {
        ([(header::CONTENT_TYPE, JSON)], self.0).into_response()
    }
}

/// The raw body of a JSON request: content type checked and size limited. Parsing is left
/// to the estimation worker.
#[derive(Debug, Clone)]
pub struct JsonBody(pub Bytes);

impl FromRequest<AppState> for JsonBody {
    type Rejection = ApiError;

    async fn from_request(request: Request, state: &AppState) -> Result<Self, ApiError> {
        require_json(request.headers())?;
        read_body(request, state.settings.body_limit_bytes)
            .await
            .map(Self)
            .map_err(|e| match e {
                BodyError::TooLarge { limit_bytes } => ApiError::payload_too_large(limit_bytes),
                BodyError::Unreadable { .. } => {
                    ApiError::new(ErrorCode::MalformedJson, e.to_string())
                }
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    fn headers(content_type: &str) -> HeaderMap {
        let mut h = HeaderMap::new();
        h.insert(
            header::CONTENT_TYPE,
            HeaderValue::from_str(content_type).expect("a header value"),
        );
        h
    }

    #[test]
    fn accepts_json_media_types_with_parameters() {
        for ok in [
            "application/json",
            "Application/JSON; charset=utf-8",
            "application/merge-patch+json",
        ] {
            assert!(require_json(&headers(ok)).is_ok(), "{ok}");
        }
    }

    #[test]
    fn refuses_other_and_missing_media_types() {
        for bad in ["text/plain", "application/xml", "image/jpeg", "json", ""] {
            let err = require_json(&headers(bad)).expect_err(bad);
            assert_eq!(err.code(), ErrorCode::UnsupportedMediaType, "{bad}");
        }
        let err = require_json(&HeaderMap::new()).expect_err("no header");
        assert_eq!(err.code(), ErrorCode::UnsupportedMediaType);
    }

    fn request(body: &'static [u8], declared: Option<usize>) -> Request {
        let mut builder = Request::builder().method("POST").uri("/");
        if let Some(n) = declared {
            builder = builder.header(header::CONTENT_LENGTH, n);
        }
        builder.body(Body::from(body)).expect("a request")
    }

    #[tokio::test]
    async fn reads_bodies_up_to_the_limit() {
        let body = read_body(request(b"0123456789", None), 10).await;
        assert_eq!(body, Ok(Bytes::from_static(b"0123456789")));
    }

    #[tokio::test]
    async fn refuses_bodies_over_the_limit_declared_or_not() {
        for declared in [None, Some(11)] {
            let err = read_body(request(b"0123456789x", declared), 10).await;
            assert_eq!(
                err,
                Err(BodyError::TooLarge { limit_bytes: 10 }),
                "{declared:?}"
            );
        }
    }

    #[tokio::test]
    async fn a_buffered_request_keeps_its_headers_and_meets_the_same_limit() {
        let mut original = request(b"0123456789", Some(10));
        original.headers_mut().insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("text/x-test"),
        );
        let buffered = buffer_body(original, 10, |b| b)
            .await
            .expect("within the limit");
        assert_eq!(buffered.headers()[header::CONTENT_TYPE], "text/x-test");
        let body = read_body(buffered, 10).await;
        assert_eq!(body, Ok(Bytes::from_static(b"0123456789")));
        let err = buffer_body(request(b"0123456789x", None), 10, |b| b).await;
        assert_eq!(
            err.map(|_| ()),
            Err(BodyError::TooLarge { limit_bytes: 10 })
        );
    }

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Query {
        size_mm: Option<f64>,
        count: Option<u32>,
        mode: Option<Mode>,
    }

    #[derive(Debug, serde::Deserialize)]
    #[serde(rename_all = "lowercase")]
    enum Mode {
        Fast,
    }

    #[test]
    fn query_errors_name_their_parameter() {
        let cases = [
            ("size_mm=wide", ErrorCode::MalformedQuery, Some("size_mm")),
            ("size_mm=", ErrorCode::MalformedQuery, Some("size_mm")),
            ("count=-1", ErrorCode::MalformedQuery, Some("count")),
            ("count=1&count=2", ErrorCode::MalformedQuery, Some("count")),
            ("size=5", ErrorCode::UnknownField, Some("size")),
            ("mode=slow", ErrorCode::UnknownVariant, Some("mode")),
        ];
        for (query, code, field) in cases {
            let err = parse_query::<Query>(Some(query)).expect_err(query);
            let problem = err.problem();
            assert_eq!(
                (problem.code, problem.field.as_deref()),
                (code, field),
                "{query}: {problem:?}"
            );
        }
    }

    #[derive(Debug, serde::Deserialize)]
    #[allow(dead_code)]
    struct Required {
        size_mm: f64,
    }

    #[test]
    fn query_details_name_the_parameter_and_say_what_is_wrong() {
        let cases = [
            (
                "size_mm=wide",
                "query parameter size_mm: invalid float literal",
            ),
            ("count=1&count=2", "duplicate field `count`"),
            ("size=5", "unknown field `size`, expected one of"),
            (
                "mode=slow",
                "query parameter mode: unknown variant `slow`, expected `fast`",
            ),
        ];
        for (query, detail) in cases {
            let err = parse_query::<Query>(Some(query)).expect_err(query);
            assert!(
                err.problem().detail.starts_with(detail),
                "{query}: {:?}",
                err.problem()
            );
        }
        let err = parse_query::<Required>(None).expect_err("a required parameter");
        let problem = err.problem();
        assert_eq!(
            (
                problem.code,
                problem.field.as_deref(),
                problem.detail.as_str()
            ),
            (
                ErrorCode::MalformedQuery,
                Some("size_mm"),
                "missing field `size_mm`"
            )
        );
    }

    #[test]
    fn queries_parse_with_percent_encoding_and_without_a_query() {
        let q: Query = parse_query(Some("size_mm=%35%30&mode=fast")).expect("valid");
        assert_eq!(q.size_mm, Some(50.0));
        let q: Query = parse_query(None).expect("no query is an empty one");
        assert!(q.size_mm.is_none() && q.count.is_none() && q.mode.is_none());
    }
}
