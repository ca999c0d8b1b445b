//! `GET /metrics`: Prometheus metrics in the OpenMetrics text format.

use crate::api::problem::Problem;
use crate::http::{error::ApiError, metrics::OPENMETRICS_TEXT, state::AppState};
use axum::extract::State;
use axum::http::header;
use axum::response::IntoResponse;

/// Prometheus metrics (OpenMetrics text): requests by route and status, latency histograms,
/// estimator iterations and non-convergence, the estimation queue.
#[utoipa::path(
    get,
    path = "/metrics",
    tag = "operations",
    responses(
        (status = 200, description = "The metrics, OpenMetrics text format.", body = String,
            content_type = "application/openmetrics-text; version=1.0.0; charset=utf-8"),
        (status = 500, description = "`internal`: the metrics could not be encoded.",
            body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn metrics(State(state): State<AppState>) -> Result<impl IntoResponse, ApiError> {
    let text = state.metrics.encode().map_err(ApiError::internal)?;
    Ok(([(header::CONTENT_TYPE, OPENMETRICS_TEXT)], text))
}
