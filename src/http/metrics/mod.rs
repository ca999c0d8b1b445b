//! Prometheus metrics (OpenMetrics text, `GET /metrics`), all prefixed `qrpose_`.
//!
//! | metric | type | labels | meaning |
//! |---|---|---|---|
//! | `http_requests_total` | counter | route, method, status | answered requests |
//! | `http_request_duration_seconds` | histogram | route | time to the response head |
//! | `estimator_iterations` | histogram | method | iterations of each successful estimate |
//! | `estimator_not_converged_total` | counter | method | estimates that hit `max_iterations` |
//! | `estimation_queue_depth` | gauge | | requests waiting for an estimation worker |
//! | `estimations_running` | gauge | | estimations running now |
//! | `estimation_rejections_total` | counter | | requests refused with 503 `overloaded` |
//! | `image_codes_detected` | histogram | | QR codes found per image answered 200 |
//! | `http_connections_open` | gauge | | client connections open now |
//! | `http_connections_closed_total` | counter | reason | connections closed by a limit |
//! | `http_connection_limit_reached_total` | counter | | accepts that found the limit reached |
//! | `http_accept_errors_total` | counter | | failed accepts (e.g. out of descriptors) |
//! | `site_reloads_total` | counter | outcome | site reloads: `ok`, or `failed` (old site kept) |
//! | `stream_sessions_open` | gauge | | stream sessions open now |
//! | `stream_sessions_refused_total` | counter | | sessions closed with 1013 at the limit |
//! | `stream_frames_answered_total` | counter | | stream frames answered |
//! | `stream_frames_dropped_total` | counter | | stream frames dropped unanswered |
//! | `stream_frame_duration_seconds` | histogram | | a frame's arrival to its answer |
//! | `stream_tracks` | gauge | status | live tracks: `new`, `tracking`, `coasting` |
//! | `stream_tracks_lost_total` | counter | | tracks lost |
//! | `auth_requests_total` | counter | client, scope, outcome | protected requests: `allowed`, `unauthorized`, `forbidden` |
//! | `auth_clients` | gauge | | clients in the loaded auth file |
//! | `auth_reloads_total` | counter | outcome | auth file reloads: `ok`, or `failed` (old file kept) |
//! | `tls_reloads_total` | counter | outcome | certificate reloads: `ok`, or `failed` (old one kept) |
//! | `tls_connections_refused_total` | counter | reason | `plain_http`, `handshake`, `timeout` |
//!
//! `route` is the route template (`/v1/pose/corners`), or `unmatched` for unknown paths, so
//! that scanning clients cannot create unbounded label values. A new per-endpoint metric is
//! one field here, registered in [`Metrics::new`].

mod auth;
mod stream;

pub use auth::{ANONYMOUS_CLIENT, AuthMetrics, AuthOutcome, TlsRefusal};
pub use stream::StreamMetrics;

use crate::api::response::PoseResponse;
use axum::http::{Method, StatusCode};
use prometheus_client::encoding::EncodeLabelSet;
use prometheus_client::metrics::{
    counter::Counter,
    family::Family,
    gauge::Gauge,
    histogram::{Histogram, exponential_buckets},
};
use prometheus_client::registry::{Registry, Unit};
use std::time::Duration;

/// What the metrics need to know of one answered pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PoseOutcome {
    /// The method that produced it.
    pub method: crate::app::Method,
    /// Iterations run.
    pub iterations: u32,
    /// Whether the method converged.
    pub converged: bool,
}

impl From<&PoseResponse> for PoseOutcome {
    fn from(pose: &PoseResponse) -> Self {
        Self {
            method: pose.method(),
            iterations: pose.diagnostics.iterations,
            converged: pose.diagnostics.converged,
        }
    }
}

/// The content type of `GET /metrics`.
pub const OPENMETRICS_TEXT: &str = "application/openmetrics-text; version=1.0.0; charset=utf-8";

/// Route label of requests that matched no route.
pub const UNMATCHED_ROUTE: &str = "unmatched";

/// Upper bounds of the iteration histogram: the default limit (30) and the largest (10000)
/// are bucket edges, so "ran to the limit" is visible.
const ITERATION_BUCKETS: [f64; 13] = [
    1.0, 2.0, 3.0, 5.0, 8.0, 13.0, 20.0, 30.0, 50.0, 100.0, 300.0, 1000.0, 10000.0,
];

/// Upper bounds of the codes-per-image histogram: 0 (nothing found, still a 200) to 8, then
/// `+Inf`.
const CODES_BUCKETS: [f64; 9] = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0];

/// Latency buckets: 50 µs doubling to about 3.3 s.
fn latency_buckets() -> impl Iterator<Item = f64> {
    exponential_buckets(50e-6, 2.0, 17)
}

/// Labels of one request.
#[derive(Debug, Clone, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct RequestLabels {
    /// Route template or [`UNMATCHED_ROUTE`].
    pub route: String,
    /// HTTP method.
    pub method: String,
    /// Response status code.
    pub status: u16,
}

/// Labels of per-route series.
#[derive(Debug, Clone, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct RouteLabels {
    /// Route template or [`UNMATCHED_ROUTE`].
    pub route: String,
}

/// Labels of per-estimator series.
#[derive(Debug, Clone, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct MethodLabels {
    /// `paper`, `depth-newton` or `reprojection`.
    pub method: String,
}

type HistogramFamily<L> = Family<L, Histogram, fn() -> Histogram>;

/// The queue's gauges and counter, shared with [`super::queue::EstimationQueue`].
#[derive(Debug, Clone, Default)]
pub struct QueueMetrics {
    /// Requests waiting for a worker.
    pub waiting: Gauge,
    /// Jobs running.
    pub running: Gauge,
    /// Requests refused because the queue was full.
    pub rejected: Counter,
}

/// Why the server closed a connection (label `reason` of `http_connections_closed_total`).
#[derive(Debug, Clone, Copy, Hash, PartialEq, Eq)]
pub enum CloseReason {
    /// No complete request head within `--header-read-timeout-ms`.
    HeaderTimeout,
    /// Idle for `--idle-timeout-ms` after its last response.
    IdleTimeout,
    /// Closed to make room for a new connection at `--max-connections`.
    Evicted,
}

impl CloseReason {
    /// The label value.
    pub fn as_str(self) -> &'static str {
        match self {
            CloseReason::HeaderTimeout => "header_timeout",
            CloseReason::IdleTimeout => "idle_timeout",
            CloseReason::Evicted => "evicted",
        }
    }
}

/// Labels of `http_connections_closed_total`.
#[derive(Debug, Clone, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct CloseLabels {
    /// `header_timeout`, `idle_timeout` or `evicted`.
    pub reason: String,
}

/// The connection metrics, shared with the accept loop ([`super::conn`]).
#[derive(Debug, Clone, Default)]
pub struct ConnectionMetrics {
    /// Client connections open now.
    pub open: Gauge,
    /// Connections closed by a limit, by reason.
    pub closed: Family<CloseLabels, Counter>,
    /// Accepts that found `--max-connections` reached.
    pub limit_reached: Counter,
    /// Failed accepts.
    pub accept_errors: Counter,
}

impl ConnectionMetrics {
    /// Counts one connection closed for `reason`.
    pub fn closed(&self, reason: CloseReason) {
        self.closed
            .get_or_create(&CloseLabels {
                reason: reason.as_str().to_owned(),
            })
            .inc();
    }

    /// Connections closed for `reason` so far.
    pub fn closed_count(&self, reason: CloseReason) -> u64 {
        self.closed
            .get_or_create(&CloseLabels {
                reason: reason.as_str().to_owned(),
            })
            .get()
    }
}

/// Every metric of the service and the registry that exposes them.
#[derive(Debug)]
pub struct Metrics {
    registry: Registry,
    requests: Family<RequestLabels, Counter>,
    latency: HistogramFamily<RouteLabels>,
    iterations: HistogramFamily<MethodLabels>,
    not_converged: Family<MethodLabels, Counter>,
    codes_detected: Histogram,
    queue: QueueMetrics,
    connections: ConnectionMetrics,
    site_reloads: Family<OutcomeLabels, Counter>,
    stream: StreamMetrics,
    auth: AuthMetrics,
}

/// Labels of `site_reloads_total`.
#[derive(Debug, Clone, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct OutcomeLabels {
    /// `ok` or `failed`.
    pub outcome: String,
}

impl Default for Metrics {
    fn default() -> Self {
        Self::new()
    }
}

impl Metrics {
    /// A fresh registry with every metric at zero.
    pub fn new() -> Self {
        let mut registry = Registry::with_prefix("qrpose");
        let requests = Family::<RequestLabels, Counter>::default();
        let latency: HistogramFamily<RouteLabels> =
            Family::new_with_constructor(|| Histogram::new(latency_buckets()));
        let iterations: HistogramFamily<MethodLabels> =
            Family::new_with_constructor(|| Histogram::new(ITERATION_BUCKETS));
        let not_converged = Family::<MethodLabels, Counter>::default();
        let codes_detected = Histogram::new(CODES_BUCKETS);
        let queue = QueueMetrics::default();
        registry.register(
            "http_requests",
            "HTTP requests answered, by route template, method and status",
            requests.clone(),
        );
        registry.register_with_unit(
            "http_request_duration",
            "Time from request to response head, by route template",
            Unit::Seconds,
            latency.clone(),
        );
        registry.register(
            "estimator_iterations",
            "Iterations of each estimate, by method",
            iterations.clone(),
        );
        registry.register(
            "estimator_not_converged",
            "Estimates that ended without converging, by method",
            not_converged.clone(),
        );
        registry.register(
            "image_codes_detected",
            "QR codes found per image (POST /v1/pose/image answered 200)",
            codes_detected.clone(),
        );
        registry.register(
            "estimation_queue_depth",
            "Requests waiting for an estimation worker",
            queue.waiting.clone(),
        );
        registry.register(
            "estimations_running",
            "Estimations running now",
            queue.running.clone(),
        );
        registry.register(
            "estimation_rejections",
            "Requests refused with 503 overloaded because the estimation queue was full",
            queue.rejected.clone(),
        );
        let connections = ConnectionMetrics::default();
        registry.register(
            "http_connections_open",
            "Client connections open now",
            connections.open.clone(),
        );
        registry.register(
            "http_connections_closed",
            "Connections closed by a limit: header_timeout, idle_timeout, evicted (to make room at --max-connections)",
            connections.closed.clone(),
        );
        registry.register(
            "http_connection_limit_reached",
            "Accepted connections that found --max-connections reached",
            connections.limit_reached.clone(),
        );
        registry.register(
            "http_accept_errors",
            "Failed accepts (e.g. out of file descriptors), each followed by a back-off",
            connections.accept_errors.clone(),
        );
        let site_reloads = Family::<OutcomeLabels, Counter>::default();
        registry.register(
            "site_reloads",
            "Site file reloads (SIGHUP, POST /v1/site/reload): ok, or failed (the previous site stays loaded)",
            site_reloads.clone(),
        );
        let stream = StreamMetrics::default();
        stream.register(&mut registry);
        let auth = AuthMetrics::default();
        auth.register(&mut registry);
        Self {
            auth,
            registry,
            stream,
            site_reloads,
            requests,
            latency,
            iterations,
            not_converged,
            codes_detected,
            queue,
            connections,
        }
    }

    /// The stream's metrics, for its sessions.
    pub fn stream(&self) -> StreamMetrics {
        self.stream.clone()
    }

    /// The security metrics, for the auth layer and the TLS acceptor.
    pub fn auth(&self) -> AuthMetrics {
        self.auth.clone()
    }

    /// The connection metrics, for the accept loop.
    pub fn connections(&self) -> ConnectionMetrics {
        self.connections.clone()
    }

    /// Counts a site reload: `ok`, or `failed` (the file was refused).
    pub fn observe_site_reload(&self, ok: bool) {
        let outcome = if ok { "ok" } else { "failed" };
        self.site_reloads
            .get_or_create(&OutcomeLabels {
                outcome: outcome.to_owned(),
            })
            .inc();
    }

    /// Site reloads so far with this outcome.
    pub fn site_reload_count(&self, ok: bool) -> u64 {
        let outcome = if ok { "ok" } else { "failed" };
        self.site_reloads
            .get_or_create(&OutcomeLabels {
                outcome: outcome.to_owned(),
            })
            .get()
    }

    /// The queue's share, for [`super::queue::EstimationQueue::new`].
    pub fn queue(&self) -> QueueMetrics {
        self.queue.clone()
    }

    /// Counts one answered request and its latency.
    pub fn observe_request(
        &self,
        route: &str,
        method: &Method,
        status: StatusCode,
        elapsed: Duration,
    ) {
        self.requests
            .get_or_create(&RequestLabels {
                route: route.to_owned(),
                method: method.as_str().to_owned(),
                status: status.as_u16(),
            })
            .inc();
        self.latency
            .get_or_create(&RouteLabels {
                route: route.to_owned(),
            })
            .observe(elapsed.as_secs_f64());
    }

    /// Records one estimate's iterations and whether it converged.
    pub fn observe_estimate(&self, outcome: PoseOutcome) {
        let (method, iterations, converged) = (
            outcome.method.as_str(),
            outcome.iterations,
            outcome.converged,
        );
        let labels = MethodLabels {
            method: method.to_owned(),
        };
        self.iterations
            .get_or_create(&labels)
            .observe(f64::from(iterations));
        if !converged {
            self.not_converged.get_or_create(&labels).inc();
        }
    }

    /// Records the number of QR codes found in one image.
    pub fn observe_codes_detected(&self, codes: usize) {
        // Exact up to 2^53 codes; an image holds a handful.
        #[allow(clippy::cast_precision_loss)]
        self.codes_detected.observe(codes as f64);
    }

    /// The OpenMetrics text exposition.
    ///
    /// # Errors
    /// Only if formatting into a `String` fails, which it does not.
    pub fn encode(&self) -> Result<String, std::fmt::Error> {
        let mut text = String::new();
        prometheus_client::encoding::text::encode(&mut text, &self.registry)?;
        Ok(text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exposes_requests_estimates_and_the_queue() {
        let metrics = Metrics::new();
        metrics.observe_request(
            "/v1/pose/corners",
            &Method::POST,
            StatusCode::OK,
            Duration::from_micros(300),
        );
        metrics.observe_estimate(PoseOutcome {
            method: crate::app::Method::Paper,
            iterations: 30,
            converged: false,
        });
        metrics.observe_estimate(PoseOutcome {
            method: crate::app::Method::Reprojection,
            iterations: 4,
            converged: true,
        });
        metrics.queue().rejected.inc();
        metrics.observe_codes_detected(0);
        metrics.observe_codes_detected(2);
        metrics.observe_codes_detected(20);
        let text = metrics.encode().expect("encodes");
        for line in [
            r#"qrpose_http_requests_total{route="/v1/pose/corners",method="POST",status="200"} 1"#,
            r#"qrpose_http_request_duration_seconds_count{route="/v1/pose/corners"} 1"#,
            r#"qrpose_estimator_iterations_bucket{le="30.0",method="paper"} 1"#,
            r#"qrpose_estimator_not_converged_total{method="paper"} 1"#,
            "qrpose_estimation_queue_depth 0",
            "qrpose_estimations_running 0",
            "qrpose_estimation_rejections_total 1",
            r#"qrpose_image_codes_detected_bucket{le="0.0"} 1"#,
            r#"qrpose_image_codes_detected_bucket{le="1.0"} 1"#,
            r#"qrpose_image_codes_detected_bucket{le="2.0"} 2"#,
            r#"qrpose_image_codes_detected_bucket{le="8.0"} 2"#,
            r#"qrpose_image_codes_detected_bucket{le="+Inf"} 3"#,
            "qrpose_image_codes_detected_sum 22.0",
            "# EOF",
        ] {
            assert!(text.contains(line), "missing `{line}` in\n{text}");
        }
        assert!(
            !text.contains(r#"qrpose_estimator_not_converged_total{method="reprojection"}"#),
            "a converged estimate is not counted as non-converged"
        );
    }
}
