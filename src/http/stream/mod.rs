//! `GET /v1/stream`: a WebSocket session of frames in, one answer per frame out, with tracks
//! (docs/stream.md). The query string configures the session ([`query`]); a bad parameter
//! refuses the upgrade with the problem `POST /v1/pose/image` would give for it. Each frame
//! goes through the application layer (`app::TrackSession::frame`) on an estimation worker,
//! behind the same queue and pixel budget as a photo ([`session`]).

pub mod asyncapi;
pub mod query;
pub mod session;

use super::error::ApiError;
use super::state::AppState;
use crate::api::problem::{ErrorCode, Problem};
use crate::app::TrackSession;
use axum::extract::ws::{WebSocketUpgrade, rejection::WebSocketUpgradeRejection};
use axum::extract::{RawQuery, State};
use axum::response::Response;

/// The route.
pub const PATH: &str = "/v1/stream";

/// Open a stream of frames (WebSocket, RFC 6455); not in the OpenAPI document, which cannot
/// describe a WebSocket: its messages and query parameters are in `openapi/asyncapi.json`.
///
/// Upgrades to a WebSocket session. The query string is that of `POST /v1/pose/image`
/// (camera or `camera_id`, `marker_size_mm`, solver, `detector`, `effort`, `max_detect_ms`,
/// …) plus the tracker's parameters. Then send frames as binary messages (JPEG or PNG), each
/// optionally preceded by a text message `{"frame_id", "capture_time_ms", "prior"}`; every
/// frame is answered, in order, by a text message: the `POST /v1/pose/image` answer plus
/// `frame`, each marker's `track_id` and every live track's filtered pose. The messages are
/// described in `openapi/asyncapi.json`.
pub async fn stream(
    State(state): State<AppState>,
    RawQuery(raw_query): RawQuery,
    upgrade: Result<WebSocketUpgrade, WebSocketUpgradeRejection>,
) -> Result<Response, ApiError> {
    let (image, track) = query::split_query(raw_query.as_deref())?;
    let setup = track.setup(image, &state.image_limits(), state.site.current())?;
    let session = TrackSession::new(setup).map_err(|e| {
        ApiError::from(Problem::new(
            ErrorCode::InvalidTrackerParameter,
            e.to_string(),
        ))
    })?;
    let upgrade = upgrade.map_err(|rejection| {
        ApiError::from(Problem::new(
            ErrorCode::UpgradeRequired,
            format!("{PATH} is a WebSocket: {}", rejection.body_text()),
        ))
    })?;
    let limit = state.settings.body_limit_bytes;
    Ok(upgrade
        .max_message_size(limit)
        .max_frame_size(limit)
        .on_upgrade(move |socket| session::run(socket, session, state)))
}
