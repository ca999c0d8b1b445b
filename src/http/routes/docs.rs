//! The Swagger UI at `GET /docs`, served from the binary, reading `GET /openapi.json`
//! (served by [`openapi`](crate::http::openapi)).

use crate::http::openapi::OPENAPI_PATH;
use utoipa_swagger_ui::{Config, SwaggerUi};

/// Where the interactive documentation is served (`/docs` redirects to `/docs/`).
pub const DOCS_PATH: &str = "/docs";

/// Swagger UI reading [`OPENAPI_PATH`]; its files are compiled into the binary.
pub fn swagger_ui() -> SwaggerUi {
    SwaggerUi::new(DOCS_PATH).config(Config::from(OPENAPI_PATH))
}
