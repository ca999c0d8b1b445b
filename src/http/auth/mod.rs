//! Who may call which route (docs/security.md): bearer tokens with scopes, checked by the
//! layer [`require`] when an auth file is loaded ([`AuthStore`]); without one every route is
//! open.
//!
//! The scope a route needs is decided by a rule on its path ([`access_for`]), not by a list
//! of handlers, so a new route under a protected prefix is protected from its first line:
//! `/v1/pose/*`, `/v1/stream`, `/v1/calibrate` need `pose`; `/v1/site` `site`;
//! `/v1/site/reload` `admin`; `/metrics` `metrics`; any other path under `/v1/` a known
//! token; everything else (`/healthz`, `/readyz`, the page and its assets, `/docs`, the
//! OpenAPI and AsyncAPI documents) is open.
//!
//! The token: `Authorization: Bearer TOKEN`, or, for a browser's WebSocket (which cannot
//! set headers), the subprotocol `bearer.TOKEN` in `Sec-WebSocket-Protocol` (the page offers
//! `qrpose` beside it, and the `101` answer selects `qrpose`). Never the query string, which
//! lands in access logs. Missing or unknown: 401 `unauthorized` with `WWW-Authenticate:
//! Bearer` (RFC 6750, `error="invalid_token"` for an unknown one); known but without the
//! scope: 403 `forbidden` with `error="insufficient_scope"`. The client's name (never its
//! token) is recorded in the request's span (`client`) and in `qrpose_auth_requests_total`.

mod store;
#[cfg(test)]
mod tests;

pub use store::{AuthReloadError, AuthStore};

use super::error::ApiError;
use super::metrics::{ANONYMOUS_CLIENT, AuthOutcome};
use crate::api::problem::ErrorCode;
use crate::config::auth::Scope;
use axum::extract::{Request, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

/// The WebSocket subprotocol the page offers beside `bearer.TOKEN`, and the one a `101`
/// answer selects when it is offered.
pub const STREAM_SUBPROTOCOL: &str = "qrpose";

/// The prefix of a token carried as a WebSocket subprotocol.
pub const BEARER_SUBPROTOCOL_PREFIX: &str = "bearer.";

/// The realm of `WWW-Authenticate`.
const REALM: &str = "qrpose";

/// What a route needs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// Anyone: health probes, the page, the documentation.
    Open,
    /// A client holding this scope.
    Scope(Scope),
    /// Any known client (an unknown path under `/v1/`: answered 404 only to a client).
    AnyClient,
}

/// The protected prefixes and their scopes, first match wins (so the longer prefix first).
/// A prefix covers the path itself and everything below it (`/v1/pose` covers
/// `/v1/pose/image`, not `/v1/poses`).
pub const RULES: [(&str, Scope); 6] = [
    ("/v1/site/reload", Scope::Admin),
    ("/v1/site", Scope::Site),
    ("/v1/pose", Scope::Pose),
    ("/v1/stream", Scope::Pose),
    ("/v1/calibrate", Scope::Pose),
    ("/metrics", Scope::Metrics),
];

/// Whether `path` is `prefix` or below it.
fn under(path: &str, prefix: &str) -> bool {
    path.strip_prefix(prefix)
        .is_some_and(|rest| rest.is_empty() || rest.starts_with('/'))
}

/// What the route at `path` needs. The router matches paths as sent (no percent-decoding,
/// no dot-segment removal), so a path that escapes every rule here also matches no
/// protected route.
pub fn access_for(path: &str) -> Access {
    if let Some((_, scope)) = RULES.iter().find(|(prefix, _)| under(path, prefix)) {
        Access::Scope(*scope)
    } else if under(path, "/v1") {
        Access::AnyClient
    } else {
        Access::Open
    }
}

/// Where a request's token came from.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Presented<'a> {
    /// No token.
    None,
    /// A token (`Authorization: Bearer`, or a `bearer.` subprotocol of a WebSocket upgrade).
    Token(&'a str),
    /// Something that is not a bearer token (another scheme, two `Authorization` headers).
    Malformed,
}

/// The comma-separated entries of every `Sec-WebSocket-Protocol` header.
fn offered_subprotocols(headers: &HeaderMap) -> impl Iterator<Item = &str> {
    headers
        .get_all(header::SEC_WEBSOCKET_PROTOCOL)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .map(str::trim)
}

fn is_websocket_upgrade(headers: &HeaderMap) -> bool {
    headers
        .get(header::UPGRADE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.eq_ignore_ascii_case("websocket"))
}

/// The token of a request: `Authorization: Bearer TOKEN` (scheme case-insensitive, RFC
/// 7235), else for a WebSocket upgrade the first `bearer.TOKEN` subprotocol.
fn presented_token(headers: &HeaderMap) -> Presented<'_> {
    let mut authorization = headers.get_all(header::AUTHORIZATION).iter();
    match (authorization.next(), authorization.next()) {
        (Some(_), Some(_)) => return Presented::Malformed,
        (Some(value), None) => {
            let Ok(value) = value.to_str() else {
                return Presented::Malformed;
            };
            return match value.split_once(' ') {
                Some((scheme, token))
                    if scheme.eq_ignore_ascii_case("bearer") && !token.trim().is_empty() =>
                {
                    Presented::Token(token.trim())
                }
                _ => Presented::Malformed,
            };
        }
        (None, _) => {}
    }
    if !is_websocket_upgrade(headers) {
        return Presented::None;
    }
    offered_subprotocols(headers)
        .find_map(|p| p.strip_prefix(BEARER_SUBPROTOCOL_PREFIX))
        .map_or(Presented::None, Presented::Token)
}

/// 401 or 403 with its `WWW-Authenticate` challenge.
fn refusal(code: ErrorCode, detail: String, challenge: String) -> Response {
    let mut response = ApiError::new(code, detail).into_response();
    if let Ok(value) = HeaderValue::from_str(&challenge) {
        response
            .headers_mut()
            .insert(header::WWW_AUTHENTICATE, value);
    }
    response
}

fn what_it_needs(access: Access) -> String {
    match access {
        Access::Scope(scope) => format!("a bearer token with the `{scope}` scope"),
        Access::Open | Access::AnyClient => "a bearer token".to_owned(),
    }
}

/// Checks the request's token against the loaded clients (see the module's documentation);
/// passes every request when no auth file is loaded. On a `101 Switching Protocols` it
/// selects the subprotocol `qrpose` when the client offered it.
pub async fn require(State(store): State<AuthStore>, request: Request, next: Next) -> Response {
    let offers_stream_protocol =
        offered_subprotocols(request.headers()).any(|p| p == STREAM_SUBPROTOCOL);
    let access = access_for(request.uri().path());
    if let (Some(clients), Access::Scope(_) | Access::AnyClient) = (store.current(), access) {
        let needed = match access {
            Access::Scope(scope) => Some(scope),
            Access::Open | Access::AnyClient => None,
        };
        let client = match presented_token(request.headers()) {
            Presented::None => {
                store
                    .metrics()
                    .observe(ANONYMOUS_CLIENT, needed, AuthOutcome::Unauthorized);
                return refusal(
                    ErrorCode::Unauthorized,
                    format!(
                        "{} needs {}: send `Authorization: Bearer TOKEN` (docs/security.md)",
                        request.uri().path(),
                        what_it_needs(access)
                    ),
                    format!("Bearer realm=\"{REALM}\""),
                );
            }
            Presented::Token(token) => clients.identify(token),
            Presented::Malformed => None,
        };
        let Some(client) = client else {
            store
                .metrics()
                .observe(ANONYMOUS_CLIENT, needed, AuthOutcome::Unauthorized);
            return refusal(
                ErrorCode::Unauthorized,
                "the bearer token is not one of this service's clients' (or the Authorization \
                 header is not `Bearer TOKEN`)"
                    .to_owned(),
                format!("Bearer realm=\"{REALM}\", error=\"invalid_token\""),
            );
        };
        tracing::Span::current().record("client", client.name());
        if let Some(scope) = needed.filter(|s| !client.scopes().contains(*s)) {
            store
                .metrics()
                .observe(client.name(), needed, AuthOutcome::Forbidden);
            return refusal(
                ErrorCode::Forbidden,
                format!(
                    "client {} holds the scopes [{}]; {} {} needs `{scope}`",
                    client.name(),
                    client.scopes(),
                    request.method(),
                    request.uri().path()
                ),
                format!(
                    "Bearer realm=\"{REALM}\", error=\"insufficient_scope\", scope=\"{scope}\""
                ),
            );
        }
        store
            .metrics()
            .observe(client.name(), needed, AuthOutcome::Allowed);
    }
    let mut response = next.run(request).await;
    if offers_stream_protocol
        && response.status() == StatusCode::SWITCHING_PROTOCOLS
        && !response
            .headers()
            .contains_key(header::SEC_WEBSOCKET_PROTOCOL)
    {
        response.headers_mut().insert(
            header::SEC_WEBSOCKET_PROTOCOL,
            HeaderValue::from_static(STREAM_SUBPROTOCOL),
        );
    }
    response
}

/// The warning of a service that listens on `addr`, not a loopback address, without an auth
/// file (`auth_on` false): logged at start and shown by `/readyz`.
pub fn exposure_warning(addr: std::net::SocketAddr, auth_on: bool) -> Option<String> {
    (!auth_on && !addr.ip().is_loopback()).then(|| {
        format!(
            "listening on {addr} without an auth file: anyone who can reach the port may call \
             every endpoint, reload the site and read the metrics (qrpose serve --auth-file; \
             docs/security.md)"
        )
    })
}
