//! The layers around every route, outermost first:
//!
//! 1. [`sanitize_request_id`]: drops a client's `x-request-id` unless it is a short token;
//! 2. tower-http's `SetRequestId` (a UUID when absent) and `PropagateRequestId` (echoed on
//!    the response);
//! 3. `Trace`: one span per request ([`request_span`]: `request_id`, `method`, `path`, and
//!    `client` once the auth layer knows it), so every log line of the request carries its
//!    id, and one line per response;
//! 4. [`record_metrics`]: request count and latency by route template and status;
//! 5. [`problems_for_bare_errors`]: any error response without a problem body (axum's own,
//!    Swagger UI's) gets one, keeping `Allow` and `Retry-After`;
//! 6. [`super::auth::require`]: the bearer token and its scope, when an auth file is loaded
//!    (401 `unauthorized`, 403 `forbidden`);
//! 7. `CatchPanic` ([`panic_response`]): a panicking handler answers 500 `internal`;
//! 8. [`enforce_timeout`]: 503 `timeout` after `request_timeout`, body reading included.

use super::error::{ApiError, KEPT_HEADERS, is_problem};
use super::metrics::{Metrics, UNMATCHED_ROUTE};
use crate::config::millis;
use axum::extract::{MatchedPath, Request, State};
use axum::http::{HeaderName, HeaderValue};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use std::any::Any;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tracing::Span;

/// The request id header, set on every request and response.
pub const X_REQUEST_ID: HeaderName = HeaderName::from_static("x-request-id");

/// Longest client-supplied request id kept, characters.
pub const MAX_REQUEST_ID_LEN: usize = 128;

/// Whether a client's request id is safe to log and echo: 1 to 128 characters out of
/// letters, digits and `-_.:`.
fn is_acceptable_request_id(value: &HeaderValue) -> bool {
    let bytes = value.as_bytes();
    (1..=MAX_REQUEST_ID_LEN).contains(&bytes.len())
        && bytes
            .iter()
            .all(|b| b.is_ascii_alphanumeric() || b"-_.:".contains(b))
}

/// Removes an unacceptable `x-request-id`, so that a fresh one is generated.
pub async fn sanitize_request_id(mut request: Request) -> Request {
    if request
        .headers()
        .get(&X_REQUEST_ID)
        .is_some_and(|v| !is_acceptable_request_id(v))
    {
        request.headers_mut().remove(&X_REQUEST_ID);
    }
    request
}

/// The span of one request.
pub fn request_span(request: &Request) -> Span {
    let request_id = request
        .headers()
        .get(&X_REQUEST_ID)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("-");
    tracing::info_span!(
        "request",
        request_id = %request_id,
        method = %request.method(),
        path = %request.uri().path(),
        client = tracing::field::Empty,
    )
}

/// Counts the request by route template, method and status, and observes its latency.
pub async fn record_metrics(
    State(metrics): State<Arc<Metrics>>,
    request: Request,
    next: Next,
) -> Response {
    let route = request
        .extensions()
        .get::<MatchedPath>()
        .map_or(UNMATCHED_ROUTE, MatchedPath::as_str)
        .to_owned();
    let method = request.method().clone();
    let started = Instant::now();
    let response = next.run(request).await;
    metrics.observe_request(&route, &method, response.status(), started.elapsed());
    response
}

/// Gives every error response a problem body.
pub async fn problems_for_bare_errors(request: Request, next: Next) -> Response {
    let path = request.uri().path().to_owned();
    let method = request.method().clone();
    let response = next.run(request).await;
    let status = response.status();
    if !(status.is_client_error() || status.is_server_error()) || is_problem(&response) {
        return response;
    }
    let Some(error) = ApiError::for_bare_status(status, &path, method.as_str()) else {
        return response;
    };
    let mut replacement = error.into_response();
    for name in KEPT_HEADERS {
        if let Some(value) = response.headers().get(&name) {
            replacement.headers_mut().insert(name, value.clone());
        }
    }
    replacement
}

/// The answer to a panicking handler: 500 `internal`, the panic message logged.
pub fn panic_response(panic: Box<dyn Any + Send + 'static>) -> Response {
    let message = panic
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".to_owned());
    ApiError::internal(format!("handler panicked: {message}")).into_response()
}

/// Answers 503 `timeout` when the request takes longer than `timeout`.
pub async fn enforce_timeout(
    State(timeout): State<Duration>,
    request: Request,
    next: Next,
) -> Response {
    match tokio::time::timeout(timeout, next.run(request)).await {
        Ok(response) => response,
        Err(_) => {
            tracing::warn!(timeout_ms = millis(timeout), "request timed out");
            ApiError::timeout(millis(timeout)).into_response()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_short_token_request_ids_only() {
        let cases = [
            ("abc-123", true),
            ("0f8fad5b-d9cb-469f-a165-70867728950e", true),
            ("trace:1.2_3", true),
            ("", false),
            ("has space", false),
            ("quote\"", false),
            ("é", false),
        ];
        for (id, ok) in cases {
            let value = HeaderValue::from_bytes(id.as_bytes()).expect("header bytes");
            assert_eq!(is_acceptable_request_id(&value), ok, "{id:?}");
        }
        let long = HeaderValue::from_str(&"a".repeat(MAX_REQUEST_ID_LEN + 1)).expect("ascii");
        assert!(!is_acceptable_request_id(&long));
    }
}
