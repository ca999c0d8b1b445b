//! The OpenAPI 3.1 document: one source with the routes (`OpenApiRouter` + `routes!`), so a
//! route cannot exist without its documentation.
//!
//! `openapi/openapi.json` in the repository is [`openapi_json`]'s output, written only by
//! `cargo run -- openapi > openapi/openapi.json`; a test fails when the two drift.
//!
//! `GET /openapi.json` is served from here, from a static rendered once: the document is
//! made from the routes, so the route that serves it lives with it rather than among them.

use super::error::ApiError;
use super::routes::{annotated, corners, health, image, metrics, page, site};
use super::state::AppState;
use axum::body::Bytes;
use axum::http::header;
use axum::response::IntoResponse;
use std::sync::LazyLock;
use utoipa::OpenApi;
use utoipa_axum::{router::OpenApiRouter, routes};

/// Where the OpenAPI document is served.
pub const OPENAPI_PATH: &str = "/openapi.json";

/// The document as served, rendered on first use.
static OPENAPI_JSON: LazyLock<Result<Bytes, String>> =
    LazyLock::new(|| openapi_json().map(Bytes::from).map_err(|e| e.to_string()));

/// The command that regenerates the committed document.
pub const REGENERATE: &str = "cargo run -- openapi > openapi/openapi.json";

/// Document-level information; the paths come from [`api_router`].
#[derive(OpenApi)]
#[openapi(
    info(
        title = "qrpose",
        description = "Where a QR code is in 3D and how it is turned, from one image of one \
camera.\n\nUnits: lengths in millimetres, image coordinates in pixels (u right, v down, \
integer = pixel centre), angles in degrees. Camera frame: x right, y down, z forward (OpenCV). \
Pose: p_cam = R·p_marker + t, with the marker frame's origin at corner P2 (the symbol's \
top-right corner).\n\nEvery error is an RFC 9457 `application/problem+json` document with a \
stable snake_case `code` and, when one field is at fault, `field` (a JSON pointer). Every \
response carries `x-request-id` (the client's, when it sends a short token, else a fresh \
UUID); log lines of the request carry the same id. Unknown routes answer 404 `not_found`, \
known routes with another method 405 `method_not_allowed` (with `Allow`). The interactive \
documentation is at `/docs`.",
        license(name = "Apache-2.0", identifier = "Apache-2.0"),
    ),
    tags(
        (name = "pose", description = "Pose estimation."),
        (name = "operations", description = "Health, readiness, metrics and this document."),
        (name = "site", description = "The loaded site: cameras, marker sizes, mounts, map (docs/site.md)."),
        (name = "page", description = "The setup page for people (HTML)."),
    )
)]
pub struct ApiDoc;

/// Every documented route with its handler, before state is attached.
pub fn api_router() -> OpenApiRouter<AppState> {
    OpenApiRouter::with_openapi(ApiDoc::openapi())
        .routes(routes!(corners::pose_from_corners))
        .routes(routes!(image::pose_from_image))
        .routes(routes!(annotated::pose_from_image_annotated))
        .routes(routes!(page::setup_page))
        .routes(routes!(health::healthz))
        .routes(routes!(health::readyz))
        .routes(routes!(site::site))
        .routes(routes!(site::reload_site))
        .routes(routes!(metrics::metrics))
        .routes(routes!(serve_openapi_json))
}

/// The OpenAPI document as utoipa derives it; what is served and committed is this made
/// strict by [`super::openapi_strict::tighten`] ([`openapi_json`]).
pub fn openapi() -> utoipa::openapi::OpenApi {
    let mut doc = api_router().into_openapi();
    image::document_part_media_types(&mut doc);
    annotated::document_part_media_types(&mut doc);
    doc
}

/// The OpenAPI document as pretty JSON with a final newline: what `qrpose openapi` prints,
/// `GET /openapi.json` serves and `openapi/openapi.json` holds.
///
/// # Errors
/// Only if the document cannot be serialised, which a derived document always can.
pub fn openapi_json() -> Result<String, serde_json::Error> {
    let mut doc = serde_json::to_value(openapi())?;
    super::openapi_strict::tighten(&mut doc);
    serde_json::to_string_pretty(&doc).map(|json| json + "\n")
}

/// The OpenAPI 3.1 document of this API (identical to `qrpose openapi`).
#[utoipa::path(
    get,
    path = "/openapi.json",
    tag = "operations",
    operation_id = "openapi_json",
    responses((status = 200, description = "The OpenAPI 3.1 document.", body = Object,
        content_type = "application/json"))
)]
pub async fn serve_openapi_json() -> Result<impl IntoResponse, ApiError> {
    let json = OPENAPI_JSON.as_ref().map_err(ApiError::internal)?;
    Ok(([(header::CONTENT_TYPE, "application/json")], json.clone()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_served_document_is_the_rendered_one() {
        let served = OPENAPI_JSON.as_ref().expect("renders");
        let rendered = openapi_json().expect("renders");
        assert_eq!(served.as_ref(), rendered.as_bytes());
    }
}
