//! The OpenAPI 3.1 document: one source with the routes (`OpenApiRouter` + `routes!`), so a
//! route cannot exist without its documentation.
//!
//! The document says what the server accepts, exactly: ranges, defaults and required-ness
//! come from the DTOs' own attributes; the request bodies whose valid forms are alternatives
//! are unions of closed schemas, from the forms the wire types declare ([`alternatives`]);
//! the image routes' query parameters are flat and optional. Where the server's configuration
//! changes what is valid ([`Served`]: a site loaded or not, the zxing-cpp detector built in
//! or not), the served document says so.
//!
//! `openapi/openapi.json` in the repository is the document of a server without a site
//! (`qrpose openapi`), and `openapi/openapi-site.json` that of a server with one (`qrpose
//! openapi --site`), both for the default build; a test fails when either drifts.
//!
//! `GET /openapi.json` is served from here, rendered once per configuration: the document is
//! made from the routes, so the route that serves it lives with it rather than among them.

mod alternatives;
mod forms;
mod problems;
pub(crate) mod security;

pub use alternatives::{Served, write_alternatives};

use super::error::ApiError;
use super::routes::{annotated, calibrate, corners, hand_eye, health, image, metrics, page, site};
use super::state::AppState;
use super::stream::asyncapi;
use crate::app::Backend;
use axum::body::Bytes;
use axum::extract::State;
use axum::http::header;
use axum::response::IntoResponse;
use std::sync::OnceLock;
use utoipa::OpenApi;
use utoipa_axum::{router::OpenApiRouter, routes};

/// Where the OpenAPI document is served.
pub const OPENAPI_PATH: &str = "/openapi.json";

/// One document per configuration, rendered on first use.
pub(crate) type Rendered = [OnceLock<Result<Bytes, String>>; 8];

/// The document `render` makes for `served`, from `cache` once rendered.
pub(crate) fn rendered(
    cache: &'static Rendered,
    served: Served,
    render: fn(Served) -> Result<String, serde_json::Error>,
) -> &'static Result<Bytes, String> {
    cache[served.slot()].get_or_init(|| render(served).map(Bytes::from).map_err(|e| e.to_string()))
}

/// The document `render` makes for `served`, from `cache` once rendered, as the answer.
pub(crate) fn serve_document(
    cache: &'static Rendered,
    served: Served,
    render: fn(Served) -> Result<String, serde_json::Error>,
) -> Result<impl IntoResponse + use<>, ApiError> {
    let json = rendered(cache, served, render)
        .as_ref()
        .map_err(ApiError::internal)?;
    Ok(([(header::CONTENT_TYPE, "application/json")], json.clone()))
}

/// The OpenAPI documents, one per configuration.
static OPENAPI_DOCUMENTS: Rendered = [const { OnceLock::new() }; 8];

/// The commands that regenerate the committed documents.
pub const REGENERATE: &str = "cargo run -- openapi > openapi/openapi.json && \
    cargo run -- openapi --site > openapi/openapi-site.json";

impl Served {
    /// The configuration of the server `state` belongs to.
    pub fn by(state: &AppState) -> Self {
        Self {
            site: state.site.path().is_some(),
            zxing_cpp: Backend::ZxingCpp.is_built(),
            auth: state.auth.is_on(),
        }
    }

    /// This configuration's place among the eight.
    fn slot(self) -> usize {
        usize::from(self.site) * 4 + usize::from(self.zxing_cpp) * 2 + usize::from(self.auth)
    }
}

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
        (name = "calibration", description = "The camera calibrated from photos of a printed QR code (docs/calibration.md)."),
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
        .routes(routes!(calibrate::calibrate))
        .routes(routes!(hand_eye::calibrate_hand_eye))
        .routes(routes!(page::setup_page))
        .routes(routes!(health::healthz))
        .routes(routes!(health::readyz))
        .routes(routes!(site::site))
        .routes(routes!(site::reload_site))
        .routes(routes!(metrics::metrics))
        .routes(routes!(serve_openapi_json))
        .routes(routes!(asyncapi::serve_asyncapi_json))
}

/// The OpenAPI document as utoipa derives it from the routes and the DTOs; what is served
/// and committed is this with the alternatives and the configuration written in
/// ([`openapi_json`]).
pub fn openapi() -> utoipa::openapi::OpenApi {
    api_router().into_openapi()
}

/// The OpenAPI document of a server configured as `served`, as pretty JSON with a final
/// newline: what `qrpose openapi [--site]` prints, `GET /openapi.json` serves and
/// `openapi/openapi.json` (no site) and `openapi/openapi-site.json` hold.
///
/// # Errors
/// Only if the document cannot be serialised, which a derived document always can.
pub fn openapi_json(served: Served) -> Result<String, serde_json::Error> {
    let mut doc = serde_json::to_value(openapi())?;
    forms::document_forms(&mut doc);
    problems::write_problem_codes(&mut doc);
    write_alternatives(&mut doc, served);
    if served.auth {
        security::declare_security(&mut doc);
    }
    serde_json::to_string_pretty(&doc).map(|json| json + "\n")
}

/// The OpenAPI 3.1 document of this API as this server is configured (identical to
/// `qrpose openapi`, or `qrpose openapi --site` when a site is loaded).
#[utoipa::path(
    get,
    path = "/openapi.json",
    tag = "operations",
    operation_id = "openapi_json",
    responses((status = 200, description = "The OpenAPI 3.1 document.", body = Object,
        content_type = "application/json"))
)]
pub async fn serve_openapi_json(
    State(state): State<AppState>,
) -> Result<impl IntoResponse, ApiError> {
    serve_document(&OPENAPI_DOCUMENTS, Served::by(&state), openapi_json)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_configuration_is_rendered_once_as_it_is_rendered() {
        for slot in 0..8 {
            let (site, zxing_cpp, auth) = (slot & 4 != 0, slot & 2 != 0, slot & 1 != 0);
            let served = Served {
                site,
                zxing_cpp,
                auth,
            };
            assert_eq!(served.slot(), slot, "{served:?}");
            let cached = rendered(&OPENAPI_DOCUMENTS, served, openapi_json);
            let fresh = openapi_json(served).expect("renders");
            assert_eq!(cached.as_ref().expect("renders"), fresh.as_bytes());
        }
    }
}
