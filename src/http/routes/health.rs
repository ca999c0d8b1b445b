//! `GET /healthz` (liveness) and `GET /readyz` (readiness).

use crate::api::problem::Problem;
use crate::http::{error::ApiError, queue::Occupancy, state::AppState};
use axum::{Json, extract::State};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// The process is up and serving HTTP.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({"status": "ok", "version": "0.1.0"}))]
pub struct Health {
    /// Always `ok`.
    pub status: String,
    /// The service's version.
    pub version: String,
}

/// The estimation queue right now.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct QueueStatus {
    /// Estimations running.
    pub running: usize,
    /// Requests waiting for a worker.
    pub waiting: usize,
    /// Running + waiting at most; beyond it requests get 503 `overloaded`.
    pub capacity: usize,
}

impl From<Occupancy> for QueueStatus {
    fn from(o: Occupancy) -> Self {
        Self {
            running: o.running,
            waiting: o.waiting,
            capacity: o.capacity,
        }
    }
}

/// The service takes new work.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({"status": "ready", "queue": {"running": 1, "waiting": 0, "capacity": 66}}))]
pub struct Readiness {
    /// Always `ready`.
    pub status: String,
    /// The estimation queue.
    pub queue: QueueStatus,
    /// What an operator should know and the service still serves with: today only that it
    /// listens on a non-loopback address without an auth file (docs/security.md). Absent
    /// when there is nothing to say.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// Liveness: 200 while the process serves HTTP.
///
/// For a container HEALTHCHECK without curl use `qrpose healthcheck`.
#[utoipa::path(
    get,
    path = "/healthz",
    tag = "operations",
    responses((status = 200, description = "The process is up.", body = Health))
)]
pub async fn healthz() -> Json<Health> {
    Json(Health {
        status: "ok".to_owned(),
        version: env!("CARGO_PKG_VERSION").to_owned(),
    })
}

/// Readiness: 200 while the service takes new work, 503 once it is shutting down.
///
/// Still 200, with `warnings`, when the service listens on a non-loopback address without
/// an auth file: every endpoint is open to the network (docs/security.md).
#[utoipa::path(
    get,
    path = "/readyz",
    tag = "operations",
    responses(
        (status = 200, description = "Ready; the queue's occupancy.", body = Readiness),
        (status = 503, description = "`shutting_down`: draining after SIGTERM or SIGINT.",
            body = Problem, content_type = "application/problem+json",
            headers(("Retry-After" = u32, description = "Seconds to wait before retrying"))),
    )
)]
pub async fn readyz(State(state): State<AppState>) -> Result<Json<Readiness>, ApiError> {
    if state.lifecycle.is_draining() {
        return Err(ApiError::shutting_down());
    }
    let warnings = crate::http::auth::exposure_warning(state.settings.addr, state.auth.is_on());
    Ok(Json(Readiness {
        status: "ready".to_owned(),
        queue: state.queue.occupancy().into(),
        warnings: warnings.into_iter().collect(),
    }))
}
