//! `GET /`: the setup page for integrators (README, Setup page), and its scripts and style
//! sheet. All six are compiled into the binary from `assets/page/`; the page fetches
//! nothing but these and the API of the same server (its live camera mode opens the
//! WebSocket `GET /v1/stream` of the same host and port), which its Content-Security-Policy
//! enforces, so it works on a machine without network.

use crate::http::state::AppState;
use axum::Router;
use axum::http::header;
use axum::response::IntoResponse;
use axum::routing::get;

/// The page's path.
pub const PAGE_PATH: &str = "/";
/// The script's path.
pub const SCRIPT_PATH: &str = "/page/app.js";
/// The live camera mode's script (streams the browser's camera to `GET /v1/stream`).
pub const CAMERA_SCRIPT_PATH: &str = "/page/camera.js";
/// The calibration tab's script (sends photos to `POST /v1/calibrate`, shows the answer).
pub const CALIBRATE_SCRIPT_PATH: &str = "/page/calibrate.js";
/// The hand-eye tab's script (sends photos and robot poses to `POST /v1/calibrate/hand-eye`,
/// shows the answer).
pub const HAND_EYE_SCRIPT_PATH: &str = "/page/handeye.js";
/// The style sheet's path.
pub const STYLE_PATH: &str = "/page/app.css";

const PAGE_HTML: &str = include_str!("../../../assets/page/index.html");
const SCRIPT_JS: &str = include_str!("../../../assets/page/app.js");
const CAMERA_SCRIPT_JS: &str = include_str!("../../../assets/page/camera.js");
const CALIBRATE_SCRIPT_JS: &str = include_str!("../../../assets/page/calibrate.js");
const HAND_EYE_SCRIPT_JS: &str = include_str!("../../../assets/page/handeye.js");
const STYLE_CSS: &str = include_str!("../../../assets/page/app.css");

/// Same-origin only: the page, its scripts and style, the API; photos are drawn from a
/// `blob:` bitmap. `connect-src 'self'` also admits the WebSocket of the same host and port
/// (`ws:` for an `http:` page, `wss:` for `https:`; CSP Level 3, "self" matching), which is
/// all the live camera mode opens; the camera's picture is a `MediaStream`, not a fetched
/// URL, so `media-src` stays `'none'`.
pub const CONTENT_SECURITY_POLICY: &str = "default-src 'none'; script-src 'self'; \
    style-src 'self'; img-src 'self' blob: data:; connect-src 'self'; form-action 'none'; \
    base-uri 'none'; frame-ancestors 'none'";

/// The headers every page asset carries: its type, revalidation on every load (the binary
/// may have been replaced), no type sniffing.
fn asset(media_type: &'static str, body: &'static str) -> impl IntoResponse {
    (
        [
            (header::CONTENT_TYPE, media_type),
            (header::CACHE_CONTROL, "no-cache"),
            (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
        ],
        body,
    )
}

/// The setup page.
///
/// A page for people setting up a camera: choose or drop a photo, give the camera and the
/// marker size, and see each code's corners, outline, payload and axes drawn on the photo,
/// with its position, distance, angles, error bars, ambiguity and warnings, the time per
/// stage, the raw JSON of `POST /v1/pose/image` and a `curl` command that repeats the
/// request. Its calibration tab sends photos of a printed code to `POST /v1/calibrate` and
/// shows the camera, each view's points and residuals, the image's coverage and the files
/// to download. Served from the binary; it loads nothing from elsewhere.
#[utoipa::path(
    get,
    path = "/",
    tag = "page",
    operation_id = "setup_page",
    responses((status = 200, description = "The setup page (HTML).", body = String,
        content_type = "text/html; charset=utf-8"))
)]
pub async fn setup_page() -> impl IntoResponse {
    (
        [(header::CONTENT_SECURITY_POLICY, CONTENT_SECURITY_POLICY)],
        asset("text/html; charset=utf-8", PAGE_HTML),
    )
}

async fn script() -> impl IntoResponse {
    asset("text/javascript; charset=utf-8", SCRIPT_JS)
}

async fn camera_script() -> impl IntoResponse {
    asset("text/javascript; charset=utf-8", CAMERA_SCRIPT_JS)
}

async fn calibrate_script() -> impl IntoResponse {
    asset("text/javascript; charset=utf-8", CALIBRATE_SCRIPT_JS)
}

async fn hand_eye_script() -> impl IntoResponse {
    asset("text/javascript; charset=utf-8", HAND_EYE_SCRIPT_JS)
}

async fn style() -> impl IntoResponse {
    asset("text/css; charset=utf-8", STYLE_CSS)
}

/// The page's scripts and style sheet (undocumented in OpenAPI, like the Swagger UI's files).
pub fn assets() -> Router<AppState> {
    Router::new()
        .route(SCRIPT_PATH, get(script))
        .route(CAMERA_SCRIPT_PATH, get(camera_script))
        .route(CALIBRATE_SCRIPT_PATH, get(calibrate_script))
        .route(HAND_EYE_SCRIPT_PATH, get(hand_eye_script))
        .route(STYLE_PATH, get(style))
}
