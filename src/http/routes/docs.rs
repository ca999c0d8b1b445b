//! `GET /openapi.json` (the document, as committed in `openapi/openapi.json`) and the
//! Swagger UI at `GET /docs`, served from the binary.

use crate::http::state::AppState;
use axum::extract::State;
use axum::http::header;
use axum::response::IntoResponse;
use utoipa_swagger_ui::{Config, SwaggerUi};

/// Where the OpenAPI document is served.
pub const OPENAPI_PATH: &str = "/openapi.json";
/// Where the interactive documentation is served (`/docs` redirects to `/docs/`).
pub const DOCS_PATH: &str = "/docs";

/// The OpenAPI 3.1 document of this API (identical to `qrpose openapi`).
#[utoipa::path(
    get,
    path = "/openapi.json",
    tag = "operations",
    responses((status = 200, description = "The OpenAPI 3.1 document.", body = Object,
        content_type = "application/json"))
)]
pub async fn openapi_json(State(state): State<AppState>) -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "application/json")],
        state.openapi_json,
    )
}

/// Swagger UI reading [`OPENAPI_PATH`]; its files are compiled into the binary.
pub fn swagger_ui() -> SwaggerUi {
    SwaggerUi::new(DOCS_PATH).config(Config::from(OPENAPI_PATH))
}
