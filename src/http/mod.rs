//! The HTTP service (docs/service.md): the only module that names axum.
//!
//! [`router`] builds the whole application from an [`AppState`] without a socket (router
//! tests call it with `tower::ServiceExt::oneshot`); [`serve`] runs it on a listener until a
//! shutdown future completes, then drains in-flight requests for at most the configured grace
//! period.
//!
//! CPU-bound work (parsing, estimating) runs on dedicated worker threads behind the bounded
//! [`queue::EstimationQueue`]; see that module for the admission rules (and
//! [`routes::corners`] for the one exception: short corners estimates run inline while the
//! queue is full). Connections are served by [`conn`]: header-read and idle timeouts, the
//! connection limit, accept back-off.

pub mod auth;
pub mod conn;
pub mod error;
pub mod extract;
pub mod image_input;
pub mod inline;
pub mod metrics;
pub mod middleware;
pub mod negotiate;
pub mod openapi;
pub mod queue;
pub mod reload;
pub mod routes;
pub mod state;
pub mod stream;
pub mod tls;

pub use state::{AppState, StateError};

use crate::config::millis;
use axum::Router;
use axum::extract::{DefaultBodyLimit, Request};
use axum::middleware::{from_fn, from_fn_with_state, map_request};
use error::ApiError;
use std::future::Future;
use std::sync::Arc;
use tokio::net::TcpListener;
use tower::ServiceBuilder;
use tower_http::LatencyUnit;
use tower_http::catch_panic::CatchPanicLayer;
use tower_http::request_id::{MakeRequestUuid, PropagateRequestIdLayer, SetRequestIdLayer};
use tower_http::trace::{DefaultOnResponse, TraceLayer};

/// The application: every route, the Swagger UI, the 404/405 fallbacks and the middleware.
pub fn router(state: AppState) -> Router {
    let (routes, _) = openapi::api_router().split_for_parts();
    // The WebSocket stream is described by the AsyncAPI document, not the OpenAPI one.
    let app = routes
        .route(stream::PATH, axum::routing::get(stream::stream))
        .merge(routes::docs::swagger_ui())
        .merge(routes::page::assets())
        .method_not_allowed_fallback(method_not_allowed)
        .fallback(not_found);
    with_middleware(app, state)
}

/// Wraps `app` in the service's middleware (see [`middleware`]) and attaches the state.
/// [`router`] uses it; so do tests that need a route of their own (a panicking one).
pub fn with_middleware(app: Router<AppState>, state: AppState) -> Router {
    let layers = ServiceBuilder::new()
        .layer(map_request(middleware::sanitize_request_id))
        .layer(SetRequestIdLayer::new(
            middleware::X_REQUEST_ID,
            MakeRequestUuid,
        ))
        .layer(PropagateRequestIdLayer::new(middleware::X_REQUEST_ID))
        .layer(
            TraceLayer::new_for_http()
                .make_span_with(middleware::request_span)
                .on_response(
                    DefaultOnResponse::new()
                        .level(tracing::Level::INFO)
                        .latency_unit(LatencyUnit::Micros),
                )
                .on_failure(()),
        )
        .layer(from_fn_with_state(
            Arc::clone(&state.metrics),
            middleware::record_metrics,
        ))
        .layer(from_fn(middleware::problems_for_bare_errors))
        .layer(from_fn_with_state(state.auth.clone(), auth::require))
        .layer(CatchPanicLayer::custom(middleware::panic_response))
        .layer(from_fn_with_state(
            state.settings.request_timeout,
            middleware::enforce_timeout,
        ))
        .layer(DefaultBodyLimit::max(state.settings.body_limit_bytes));
    app.layer(layers).with_state(state)
}

async fn not_found(request: Request) -> ApiError {
    ApiError::not_found(request.uri().path())
}

async fn method_not_allowed(request: Request) -> ApiError {
    ApiError::method_not_allowed(request.method().as_str(), request.uri().path())
}

/// Serves `state`'s application on `listener` until `shutdown` completes, then stops
/// accepting, marks the service as draining (`/readyz` answers 503) and waits for in-flight
/// requests, at most `settings.shutdown_grace`; connections still open then are dropped.
/// Connections are served by [`conn`], which enforces the header-read and idle timeouts and
/// the connection limit of the settings, over TLS when `state.tls` is set ([`tls`]).
///
/// # Errors
/// An I/O error of the listener.
pub async fn serve<F>(listener: TcpListener, state: AppState, shutdown: F) -> std::io::Result<()>
where
    F: Future<Output = ()> + Send + 'static,
{
    let settings = &state.settings;
    let limits = conn::ConnectionLimits {
        header_read_timeout: settings.header_read_timeout,
        idle_timeout: settings.idle_timeout,
        max_connections: settings.max_connections.get(),
        shutdown_grace: settings.shutdown_grace,
    };
    let lifecycle = state.lifecycle.clone();
    let metrics = state.metrics.connections();
    let streams = state.streams.clone();
    let tls = state.tls.clone();
    let on_shutdown = move || {
        lifecycle.start_draining();
        tracing::info!(
            grace_ms = millis(limits.shutdown_grace),
            "shutting down: no new connections, finishing in-flight requests"
        );
    };
    conn::serve_connections(
        listener,
        router(state),
        limits,
        metrics,
        tls,
        shutdown,
        on_shutdown,
    )
    .await?;
    // Upgraded connections (stream sessions) left the connection loop when they upgraded;
    // the shutdown closed them (1001): wait for their last answers and close frames.
    if tokio::time::timeout(limits.shutdown_grace, streams.all_closed())
        .await
        .is_err()
    {
        tracing::warn!(
            open = streams.open(),
            "stream sessions still open after the grace period"
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::problem::{ErrorCode, Problem};
    use crate::config::Settings;
    use axum::body::{Body, to_bytes};
    use axum::extract::State;
    use axum::http::{Request as HttpRequest, StatusCode, header};
    use axum::routing::{get, post};
    use tower::ServiceExt;

    fn state() -> AppState {
        AppState::new(Settings::default()).expect("state")
    }

    async fn problem_of(response: axum::response::Response) -> (StatusCode, Problem) {
        let status = response.status();
        assert_eq!(
            response.headers()[header::CONTENT_TYPE],
            error::PROBLEM_JSON,
            "{status}"
        );
        assert!(
            response.headers().contains_key("x-request-id"),
            "{status}: no request id"
        );
        let bytes = to_bytes(response.into_body(), 1 << 16)
            .await
            .expect("a small body");
        (status, serde_json::from_slice(&bytes).expect("a problem"))
    }

    fn get_request(path: &str) -> HttpRequest<Body> {
        HttpRequest::get(path).body(Body::empty()).expect("request")
    }

    #[tokio::test]
    async fn a_panicking_handler_answers_500_internal_without_the_message() {
        async fn panics() -> &'static str {
            panic!("secret detail")
        }
        let app = Router::new().route("/panic", get(panics));
        let response = with_middleware(app, state())
            .oneshot(get_request("/panic"))
            .await
            .expect("infallible");
        let (status, problem) = problem_of(response).await;
        assert_eq!(status, StatusCode::INTERNAL_SERVER_ERROR);
        assert_eq!(problem.code, ErrorCode::Internal);
        assert!(!problem.detail.contains("secret"), "{}", problem.detail);
    }

    #[tokio::test]
    async fn a_panicking_estimation_job_answers_500_internal_and_frees_its_slot() {
        async fn panicking_job(State(state): State<AppState>) -> Result<String, ApiError> {
            state
                .queue
                .run(|| -> String { panic!("secret detail") })
                .await
        }
        let state = state();
        let app = Router::new().route("/job", post(panicking_job));
        let response = with_middleware(app, state.clone())
            .oneshot(
                HttpRequest::post("/job")
                    .body(Body::empty())
                    .expect("request"),
            )
            .await
            .expect("infallible");
        let (status, problem) = problem_of(response).await;
        assert_eq!(status, StatusCode::INTERNAL_SERVER_ERROR);
        assert!(!problem.detail.contains("secret"), "{}", problem.detail);
        let occupancy = state.queue.occupancy();
        assert_eq!((occupancy.running, occupancy.waiting), (0, 0));
    }

    #[tokio::test]
    async fn readyz_answers_503_shutting_down_once_draining() {
        let state = state();
        let ready = router(state.clone())
            .oneshot(get_request("/readyz"))
            .await
            .expect("infallible");
        assert_eq!(ready.status(), StatusCode::OK);
        state.lifecycle.start_draining();
        let response = router(state)
            .oneshot(get_request("/readyz"))
            .await
            .expect("infallible");
        assert_eq!(response.headers()[header::RETRY_AFTER], "1");
        let (status, problem) = problem_of(response).await;
        assert_eq!(status, StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(problem.code, ErrorCode::ShuttingDown);
    }

    #[tokio::test]
    async fn a_bare_404_of_the_swagger_ui_becomes_a_problem() {
        let response = router(state())
            .oneshot(get_request("/docs/no-such-file.js"))
            .await
            .expect("infallible");
        let (status, problem) = problem_of(response).await;
        assert_eq!(status, StatusCode::NOT_FOUND);
        assert_eq!(problem.code, ErrorCode::NotFound);
    }

    #[tokio::test]
    async fn a_wrong_method_answers_405_with_allow() {
        let response = router(state())
            .oneshot(get_request("/v1/pose/corners"))
            .await
            .expect("infallible");
        assert_eq!(response.headers()[header::ALLOW], "POST");
        let (status, problem) = problem_of(response).await;
        assert_eq!(status, StatusCode::METHOD_NOT_ALLOWED);
        assert_eq!(problem.code, ErrorCode::MethodNotAllowed);
    }
}
