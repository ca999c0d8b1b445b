//! The metrics of who called (docs/security.md): requests to protected routes by client and
//! outcome, auth file and TLS certificate reloads, and refused TLS connections.
//!
//! The `client` label is a name from the auth file, or `-` for a request without a token or
//! with one that no client holds: names start with a letter or digit, so `-` is no client's,
//! and the label values are bounded by the names the files have held.

use crate::config::auth::Scope;
use prometheus_client::encoding::EncodeLabelSet;
use prometheus_client::metrics::{counter::Counter, family::Family, gauge::Gauge};
use prometheus_client::registry::Registry;

/// The `client` label of a request without a known token.
pub const ANONYMOUS_CLIENT: &str = "-";

/// What the auth layer decided for one request to a protected route.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AuthOutcome {
    /// The client holds the route's scope.
    Allowed,
    /// No token, or an unknown one: 401.
    Unauthorized,
    /// A known client without the route's scope: 403.
    Forbidden,
}

impl AuthOutcome {
    /// The label value.
    pub fn as_str(self) -> &'static str {
        match self {
            AuthOutcome::Allowed => "allowed",
            AuthOutcome::Unauthorized => "unauthorized",
            AuthOutcome::Forbidden => "forbidden",
        }
    }
}

/// Labels of `auth_requests_total`.
#[derive(Debug, Clone, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct AuthLabels {
    /// The client's name, or [`ANONYMOUS_CLIENT`].
    pub client: String,
    /// The scope the route needs (`any` for an unknown `/v1/` path).
    pub scope: String,
    /// `allowed`, `unauthorized` or `forbidden`.
    pub outcome: String,
}

/// Labels of the reload counters.
#[derive(Debug, Clone, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct ReloadLabels {
    /// `ok`, or `failed` (the previous version stays in use).
    pub outcome: String,
}

/// Labels of `tls_connections_refused_total`.
#[derive(Debug, Clone, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct RefusalLabels {
    /// `plain_http`, `handshake` (a failed handshake, a missing client certificate
    /// included) or `timeout`.
    pub reason: String,
}

/// Why a TLS connection ended before its first request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TlsRefusal {
    /// Plain HTTP on the TLS port (answered 400 `tls_required`).
    PlainHttp,
    /// The handshake failed (no shared version or cipher, a bad or missing client
    /// certificate, not TLS at all).
    Handshake,
    /// No complete handshake within the header-read timeout.
    Timeout,
}

impl TlsRefusal {
    /// The label value.
    pub fn as_str(self) -> &'static str {
        match self {
            TlsRefusal::PlainHttp => "plain_http",
            TlsRefusal::Handshake => "handshake",
            TlsRefusal::Timeout => "timeout",
        }
    }
}

/// The security metrics; cheap to clone (clones share the values).
#[derive(Debug, Clone, Default)]
pub struct AuthMetrics {
    /// Requests to protected routes by client, scope and outcome.
    pub requests: Family<AuthLabels, Counter>,
    /// Clients in the loaded auth file.
    pub clients: Gauge,
    /// Auth file reloads by outcome.
    pub auth_reloads: Family<ReloadLabels, Counter>,
    /// TLS certificate reloads by outcome.
    pub tls_reloads: Family<ReloadLabels, Counter>,
    /// TLS connections refused before a request, by reason.
    pub tls_refused: Family<RefusalLabels, Counter>,
}

impl AuthMetrics {
    /// Registers every metric in `registry`.
    pub fn register(&self, registry: &mut Registry) {
        registry.register(
            "auth_requests",
            "Requests to protected routes by client (- without a known token), scope and outcome: allowed, unauthorized (401), forbidden (403)",
            self.requests.clone(),
        );
        registry.register(
            "auth_clients",
            "Clients in the loaded auth file",
            self.clients.clone(),
        );
        registry.register(
            "auth_reloads",
            "Auth file reloads (SIGHUP): ok, or failed (the previous clients stay loaded)",
            self.auth_reloads.clone(),
        );
        registry.register(
            "tls_reloads",
            "TLS certificate reloads (SIGHUP): ok, or failed (the previous certificate stays in use)",
            self.tls_reloads.clone(),
        );
        registry.register(
            "tls_connections_refused",
            "TLS connections closed before a request: plain_http (answered 400), handshake, timeout",
            self.tls_refused.clone(),
        );
    }

    /// Counts one decision for a request needing `scope` (`None`: any client).
    pub fn observe(&self, client: &str, scope: Option<Scope>, outcome: AuthOutcome) {
        self.requests
            .get_or_create(&AuthLabels {
                client: client.to_owned(),
                scope: scope.map_or("any", Scope::as_str).to_owned(),
                outcome: outcome.as_str().to_owned(),
            })
            .inc();
    }

    /// Counts an auth file reload.
    pub fn observe_auth_reload(&self, ok: bool) {
        reload(&self.auth_reloads, ok);
    }

    /// Counts a TLS certificate reload.
    pub fn observe_tls_reload(&self, ok: bool) {
        reload(&self.tls_reloads, ok);
    }

    /// Counts a TLS connection refused before its first request.
    pub fn observe_tls_refusal(&self, refusal: TlsRefusal) {
        self.tls_refused
            .get_or_create(&RefusalLabels {
                reason: refusal.as_str().to_owned(),
            })
            .inc();
    }
}

fn reload(family: &Family<ReloadLabels, Counter>, ok: bool) {
    let outcome = if ok { "ok" } else { "failed" };
    family
        .get_or_create(&ReloadLabels {
            outcome: outcome.to_owned(),
        })
        .inc();
}
