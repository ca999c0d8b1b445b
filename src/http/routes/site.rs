//! `GET /v1/site` and `POST /v1/site/reload`: the loaded site, and reloading it from its file
//! (`docs/site.md`, Reload). A reload that fails keeps the site loaded before.

use crate::api::problem::{ErrorCode, Problem};
use crate::api::site::SiteDto;
use crate::http::{
    error::ApiError,
    state::{AppState, ReloadError},
};
use axum::Json;
use axum::extract::State;

fn no_site() -> ApiError {
    ApiError::from(Problem::new(
        ErrorCode::NoSite,
        "the service runs without a site: start it with --site FILE (QRPOSE_SITE)",
    ))
}

/// The loaded site.
///
/// Every camera with the intrinsics and distortion in use (read from its calibration file
/// or inline) and its mount, the marker size rules in their order, the map, and the SHA-256
/// of the site file's bytes (compare it with `sha256sum` of the file to know which version
/// is loaded).
#[utoipa::path(
    get,
    path = "/v1/site",
    tag = "site",
    operation_id = "site",
    responses(
        (status = 200, description = "The loaded site.", body = SiteDto),
        (status = 404, description = "`no_site`: the service runs without `--site`.",
            body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn site(State(state): State<AppState>) -> Result<Json<SiteDto>, ApiError> {
    let site = state.site.current().ok_or_else(no_site)?;
    Ok(Json(SiteDto::from(site.as_ref())))
}

/// Reload the site file.
///
/// Reads and validates the site file (and its calibration files) again; when valid, swaps
/// it in whole: a request in flight finishes with the site it started with, the next one
/// gets the new one. When refused, the site loaded before stays in use, the refusal is
/// logged and counted (`qrpose_site_reloads_total{outcome="failed"}`), and the answer says
/// why. SIGHUP does the same.
#[utoipa::path(
    post,
    path = "/v1/site/reload",
    tag = "site",
    operation_id = "reload_site",
    responses(
        (status = 200, description = "The site now loaded.", body = SiteDto),
        (status = 404, description = "`no_site`: the service runs without `--site`.",
            body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "The file on disk was refused; the previous site stays \
            loaded. `detail` is `FILE:LINE: reason`.",
            body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:qrpose:problem:invalid_site",
                "title": "Invalid site file", "status": 422,
                "detail": "/etc/qrpose/site.yaml:14: markers.sizes[1]: a marker size must be a positive number of mm, got -40 at line 14 column 8",
                "code": "invalid_site"})),
        (status = 500, description = "`internal`: a fault of the service.",
            body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn reload_site(State(state): State<AppState>) -> Result<Json<SiteDto>, ApiError> {
    let reloaded = tokio::task::spawn_blocking(move || state.reload_site())
        .await
        .map_err(|e| ApiError::internal(format!("site reload panicked: {e}")))?;
    match reloaded {
        Ok(site) => Ok(Json(SiteDto::from(site.as_ref()))),
        Err(ReloadError::NoSite) => Err(no_site()),
        Err(ReloadError::Invalid(e)) => Err(ApiError::from(Problem::new(
            ErrorCode::InvalidSite,
            format!("{e}; the previous site stays loaded"),
        ))),
    }
}
