//! [`ApiError`]: the one error type of the HTTP layer, rendered as an RFC 9457
//! `application/problem+json` document from [`api::problem::Problem`](crate::api::problem).
//!
//! Every refusal of the service goes through here: the API's validation problems, axum's own
//! rejections (unknown route, wrong method, body too large, wrong content type), saturation
//! (`overloaded`, `timeout`, `shutting_down`, all 503 with `Retry-After`) and faults of the
//! service (500 `internal`, with a generic detail; the cause is logged once, here).

use crate::api::problem::{ErrorCode, Problem};
use axum::http::{HeaderName, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};

/// The media type of every error body.
pub const PROBLEM_JSON: &str = "application/problem+json";

/// Seconds a client should wait before retrying a 503.
pub const RETRY_AFTER_S: u32 = 1;

/// The detail of every 500: the cause is in the log, never in the response.
pub const INTERNAL_DETAIL: &str =
    "the service failed to handle this request; the cause is logged under its request id";

/// An error answer: a problem document plus the headers its status calls for.
#[derive(Debug, Clone, PartialEq)]
pub struct ApiError {
    problem: Problem,
}

impl ApiError {
    /// A problem with this code and detail.
    pub fn new(code: ErrorCode, detail: impl Into<String>) -> Self {
        Self {
            problem: Problem::new(code, detail),
        }
    }

    /// A fault of the service. Logs `cause` once at error level (inside the request's span)
    /// and answers 500 `internal` with a generic detail.
    pub fn internal(cause: impl std::fmt::Display) -> Self {
        tracing::error!(%cause, "internal error");
        Self::new(ErrorCode::Internal, INTERNAL_DETAIL)
    }

    /// 404: no route for this path.
    pub fn not_found(path: &str) -> Self {
        Self::new(ErrorCode::NotFound, format!("no route for {path}"))
    }

    /// 405: the route exists, but not with this method (axum adds the `Allow` header).
    pub fn method_not_allowed(method: &str, path: &str) -> Self {
        Self::new(
            ErrorCode::MethodNotAllowed,
            format!("{path} does not accept {method}; see the Allow header"),
        )
    }

    /// 413: the body exceeds `limit_bytes`.
    pub fn payload_too_large(limit_bytes: usize) -> Self {
        Self::new(
            ErrorCode::PayloadTooLarge,
            format!("the request body exceeds the limit of {limit_bytes} bytes"),
        )
    }

    /// 415: the body's content type is missing or not one of `expected`.
    pub fn unsupported_media_type(got: Option<&str>, expected: &str) -> Self {
        let detail = match got {
            Some(got) => format!("content type {got} is not accepted here; send {expected}"),
            None => format!("the request has no Content-Type; send {expected}"),
        };
        Self::new(ErrorCode::UnsupportedMediaType, detail)
    }

    /// 503: every estimation worker is busy and the queue is full.
    pub fn overloaded(capacity: usize) -> Self {
        Self::new(
            ErrorCode::Overloaded,
            format!(
                "all {capacity} estimation slots (running and queued) are taken; retry after {RETRY_AFTER_S} s"
            ),
        )
    }

    /// 503 `overloaded`: the images being processed already hold so much of the pixel budget
    /// (`--max-inflight-pixels`) that `pixels` more do not fit.
    pub fn memory_budget_spent(pixels: u64, budget_px: u64) -> Self {
        Self::new(
            ErrorCode::Overloaded,
            format!(
                "the images in progress leave less than the {pixels} pixels of this one free \
                 of the budget of {budget_px} (--max-inflight-pixels); retry after {RETRY_AFTER_S} s"
            ),
        )
    }

    /// 503 `overloaded`: the image bodies held already leave fewer than `bytes` of the body
    /// budget (`--max-inflight-body-bytes`) free.
    pub fn body_budget_spent(bytes: u64, budget_bytes: u64) -> Self {
        Self::new(
            ErrorCode::Overloaded,
            format!(
                "the image bodies in progress leave less than the {bytes} bytes of this one free \
                 of the budget of {budget_bytes} (--max-inflight-body-bytes); retry after {RETRY_AFTER_S} s"
            ),
        )
    }

    /// 503: the request did not finish within `timeout_ms`.
    pub fn timeout(timeout_ms: u64) -> Self {
        Self::new(
            ErrorCode::Timeout,
            format!("the request did not finish within {timeout_ms} ms"),
        )
    }

    /// 503: the service is draining for shutdown.
    pub fn shutting_down() -> Self {
        Self::new(
            ErrorCode::ShuttingDown,
            "the service is shutting down and finishing the requests it has",
        )
    }

    /// The problem document.
    pub fn problem(&self) -> &Problem {
        &self.problem
    }

    /// The stable code.
    pub fn code(&self) -> ErrorCode {
        self.problem.code
    }

    /// The HTTP status, from the code.
    pub fn status(&self) -> StatusCode {
        StatusCode::from_u16(self.problem.status).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR)
    }

    /// The problem for a bare error response of another component (a status and no
    /// problem body), or `None` when its status has no code of its own.
    pub fn for_bare_status(status: StatusCode, path: &str, method: &str) -> Option<Self> {
        match status {
            StatusCode::NOT_FOUND => Some(Self::not_found(path)),
            StatusCode::METHOD_NOT_ALLOWED => Some(Self::method_not_allowed(method, path)),
            StatusCode::PAYLOAD_TOO_LARGE => Some(Self::new(
                ErrorCode::PayloadTooLarge,
                "the request body exceeds the configured limit",
            )),
            StatusCode::UNSUPPORTED_MEDIA_TYPE => Some(Self::new(
                ErrorCode::UnsupportedMediaType,
                "this content type is not accepted here",
            )),
            s if s.is_server_error() => Some(Self::internal(format!(
                "a component answered {status} without a problem document"
            ))),
            _ => None,
        }
    }
}

impl From<Problem> for ApiError {
    fn from(problem: Problem) -> Self {
        if problem.code == ErrorCode::Internal {
            tracing::error!(detail = %problem.detail, "internal error");
            return Self::new(ErrorCode::Internal, INTERNAL_DETAIL);
        }
        Self { problem }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let status = self.status();
        let body = match serde_json::to_vec(&self.problem) {
            Ok(body) => body,
            Err(e) => {
                tracing::error!(error = %e, "cannot serialise a problem document");
                br#"{"type":"urn:qrpose:problem:internal","title":"Internal error","status":500,"detail":"","code":"internal"}"#.to_vec()
            }
        };
        let mut response = (status, body).into_response();
        let headers = response.headers_mut();
        headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(PROBLEM_JSON));
        if status == StatusCode::SERVICE_UNAVAILABLE {
            headers.insert(header::RETRY_AFTER, HeaderValue::from(RETRY_AFTER_S));
        }
        if status == StatusCode::PAYLOAD_TOO_LARGE {
            // The rest of an oversized body may still be on its way: the connection is not
            // reused (and is closed once the answer is out).
            headers.insert(header::CONNECTION, HeaderValue::from_static("close"));
        }
        response
    }
}

/// Whether a response already carries a problem document.
pub fn is_problem(response: &Response) -> bool {
    response
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v.as_bytes().starts_with(PROBLEM_JSON.as_bytes()))
}

/// The headers of a bare error response worth keeping on its problem replacement.
pub const KEPT_HEADERS: [HeaderName; 2] = [header::ALLOW, header::RETRY_AFTER];

#[cfg(test)]
mod tests {
    use super::*;
    use axum::body::to_bytes;

    async fn render(err: ApiError) -> (StatusCode, axum::http::HeaderMap, Problem) {
        let response = err.into_response();
        let (parts, body) = response.into_parts();
        let bytes = to_bytes(body, 1 << 16).await.expect("a small body");
        let problem = serde_json::from_slice(&bytes).expect("a problem document");
        (parts.status, parts.headers, problem)
    }

    #[tokio::test]
    async fn renders_problem_json_with_the_codes_status() {
        let (status, headers, problem) = render(ApiError::payload_too_large(10)).await;
        assert_eq!(status, StatusCode::PAYLOAD_TOO_LARGE);
        assert_eq!(headers[header::CONTENT_TYPE], PROBLEM_JSON);
        assert_eq!(problem.code, ErrorCode::PayloadTooLarge);
        assert_eq!(problem.status, 413);
        assert!(headers.get(header::RETRY_AFTER).is_none());
    }

    #[tokio::test]
    async fn every_503_says_when_to_retry() {
        for err in [
            ApiError::overloaded(3),
            ApiError::timeout(5),
            ApiError::shutting_down(),
        ] {
            let code = err.code();
            let (status, headers, _) = render(err).await;
            assert_eq!(status, StatusCode::SERVICE_UNAVAILABLE, "{code:?}");
            assert_eq!(
                headers[header::RETRY_AFTER],
                RETRY_AFTER_S.to_string(),
                "{code:?}"
            );
        }
    }

    #[tokio::test]
    async fn internal_problems_never_leak_their_detail() {
        let leaked = Problem::new(ErrorCode::Internal, "secret stack trace");
        let (status, _, problem) = render(ApiError::from(leaked)).await;
        assert_eq!(status, StatusCode::INTERNAL_SERVER_ERROR);
        assert_eq!(problem.detail, INTERNAL_DETAIL);
        let (_, _, problem) = render(ApiError::internal("disk on fire")).await;
        assert_eq!(problem.detail, INTERNAL_DETAIL);
    }

    #[test]
    fn bare_statuses_map_to_their_codes() {
        let cases = [
            (StatusCode::NOT_FOUND, Some(ErrorCode::NotFound)),
            (
                StatusCode::METHOD_NOT_ALLOWED,
                Some(ErrorCode::MethodNotAllowed),
            ),
            (
                StatusCode::PAYLOAD_TOO_LARGE,
                Some(ErrorCode::PayloadTooLarge),
            ),
            (
                StatusCode::UNSUPPORTED_MEDIA_TYPE,
                Some(ErrorCode::UnsupportedMediaType),
            ),
            (StatusCode::BAD_GATEWAY, Some(ErrorCode::Internal)),
            (StatusCode::UNAUTHORIZED, None),
        ];
        for (status, code) in cases {
            let mapped = ApiError::for_bare_status(status, "/x", "GET").map(|e| e.code());
            assert_eq!(mapped, code, "{status}");
        }
    }
}
