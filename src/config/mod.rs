//! Settings of `qrpose serve`: command-line flags with environment fallbacks, validated once
//! into [`Settings`].
//!
//! Every scalar carries its unit in its name (`--request-timeout-ms`, `--body-limit-bytes`).
//! A flag beats its environment variable, which beats the default. [`Settings`] is only built
//! through [`Settings::try_from`] (or [`Settings::default`], the validated defaults), so the
//! rest of the service never re-checks a value.

pub mod auth;
mod security;
mod stream;

pub use security::{SecurityArgs, SecuritySettings, TlsFiles};
pub use stream::{StreamArgs, StreamSettings};

use crate::app::{DecodeLimits, ImageLimits};
use clap::{Args, ValueEnum};
use std::net::SocketAddr;
use std::num::NonZeroUsize;
use std::time::Duration;

/// Default listen address: loopback only, so that exposing the service is a deliberate act.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8080";
/// Default request body limit, bytes (24 MiB): a 20 MB JPEG plus multipart framing fits.
pub const DEFAULT_BODY_LIMIT_BYTES: usize = 24 * 1024 * 1024;
// A 20 MiB image plus 64 KiB of multipart framing and request JSON fits the default.
const _: () = assert!(DEFAULT_BODY_LIMIT_BYTES > 20 * 1024 * 1024 + 64 * 1024);
/// Smallest accepted body limit, bytes: below this a corners request with a trace fails.
pub const MIN_BODY_LIMIT_BYTES: usize = 1024;
/// Largest accepted body limit, bytes (1 GiB): bodies are buffered in memory.
pub const MAX_BODY_LIMIT_BYTES: usize = 1024 * 1024 * 1024;
/// Default time for a whole request (reading the body, queueing, estimating), ms.
pub const DEFAULT_REQUEST_TIMEOUT_MS: u64 = 10_000;
/// Largest accepted request timeout, ms (10 minutes).
pub const MAX_REQUEST_TIMEOUT_MS: u64 = 600_000;
/// Default number of requests that may wait for an estimation worker.
pub const DEFAULT_QUEUE_LENGTH: usize = 64;
/// Largest accepted queue length.
pub const MAX_QUEUE_LENGTH: usize = 100_000;
/// Largest accepted number of async worker threads or estimation workers.
pub const MAX_THREADS: usize = 1024;
/// Default time that in-flight requests get to finish after SIGTERM or SIGINT, ms.
pub const DEFAULT_SHUTDOWN_GRACE_MS: u64 = 10_000;
/// Largest accepted shutdown grace period, ms (10 minutes).
pub const MAX_SHUTDOWN_GRACE_MS: u64 = 600_000;
/// Default limit on an uploaded image's declared width × height, pixels (50 MP; an 8160 ×
/// 6120 phone photo is 49.9 MP). Larger images get 413 `image_too_large` before any pixel is
/// decoded.
pub const DEFAULT_MAX_IMAGE_PIXELS: u64 = 50_000_000;
/// Largest accepted image pixel limit (1 GP). Memory per image in flight: 1 byte per pixel
/// for a decoded JPEG, up to 8 while a 16-bit RGBA PNG is decoded, plus the detector's copies.
pub const MAX_MAX_IMAGE_PIXELS: u64 = 1_000_000_000;

// ---- Connection limits: header-read timeout, idle keep-alive timeout, open
// connections. Enforced by `http::conn`; see docs/service.md, "Limits".
/// Default time a connection gets to deliver a complete request head, ms: counted from the
/// accept for its first request, and from the first byte of each later one.
pub const DEFAULT_HEADER_READ_TIMEOUT_MS: u64 = 10_000;
/// Largest accepted header-read timeout, ms (10 minutes).
pub const MAX_HEADER_READ_TIMEOUT_MS: u64 = 600_000;
/// Default time a kept-alive connection may stay idle (no request in progress, no byte of
/// a new one) after its last response, ms. Longer than the usual 60 s idle timeout of load
/// balancers, so that the balancer, not the service, closes a pooled connection.
pub const DEFAULT_IDLE_TIMEOUT_MS: u64 = 75_000;
/// Largest accepted idle timeout, ms (1 hour).
pub const MAX_IDLE_TIMEOUT_MS: u64 = 3_600_000;
/// Default limit on open client connections. Keep it below the open-file limit
/// (`ulimit -n`) less about 64 descriptors for the process itself.
pub const DEFAULT_MAX_CONNECTIONS: usize = 1000;
/// Largest accepted connection limit.
pub const MAX_MAX_CONNECTIONS: usize = 1_000_000;
// ---- end of connection limits

/// Default cap of a request's detection deadline, ms (half the default request timeout).
pub const DEFAULT_MAX_DETECT_MS: u64 = 5_000;
/// Largest accepted cap of the detection deadline, ms (10 minutes).
pub const MAX_MAX_DETECT_MS: u64 = 600_000;

/// Log line format.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, ValueEnum)]
pub enum LogFormat {
    /// Human-readable lines.
    #[default]
    Text,
    /// One JSON object per line, with the request span's fields (request id, method, path).
    Json,
}

/// The flags of `qrpose serve`, each with an environment fallback.
#[derive(Debug, Clone, Args)]
pub struct ServeArgs {
    /// Address to listen on; port 0 picks a free port (the bound address is printed).
    #[arg(long, env = "QRPOSE_ADDR", default_value = DEFAULT_ADDR)]
    pub addr: SocketAddr,
    /// Largest request body, bytes; larger bodies get 413 `payload_too_large`.
    #[arg(long, env = "QRPOSE_BODY_LIMIT_BYTES", default_value_t = DEFAULT_BODY_LIMIT_BYTES)]
    pub body_limit_bytes: usize,
    /// Time for a whole request, ms; slower requests get 503 `timeout`.
    #[arg(long, env = "QRPOSE_REQUEST_TIMEOUT_MS", default_value_t = DEFAULT_REQUEST_TIMEOUT_MS)]
    pub request_timeout_ms: u64,
    /// Async runtime threads (network I/O) [default: number of CPUs].
    #[arg(long, env = "QRPOSE_WORKER_THREADS")]
    pub worker_threads: Option<usize>,
    /// Estimations running at once: the number of estimation worker threads [default: number
    /// of CPUs].
    #[arg(long, env = "QRPOSE_MAX_CONCURRENT_ESTIMATIONS")]
    pub max_concurrent_estimations: Option<usize>,
    /// Requests that may wait for an estimation worker; when full, 503 `overloaded` at once.
    #[arg(long, env = "QRPOSE_QUEUE_LENGTH", default_value_t = DEFAULT_QUEUE_LENGTH)]
    pub queue_length: usize,
    /// Log format (log level: `RUST_LOG`, default `info`).
    #[arg(long, env = "QRPOSE_LOG_FORMAT", value_enum, default_value_t = LogFormat::Text)]
    pub log_format: LogFormat,
    /// Time in-flight requests get to finish after SIGTERM or SIGINT, ms.
    #[arg(long, env = "QRPOSE_SHUTDOWN_GRACE_MS", default_value_t = DEFAULT_SHUTDOWN_GRACE_MS)]
    pub shutdown_grace_ms: u64,
    /// Largest image (declared width × height, pixels) that `POST /v1/pose/image` decodes;
    /// larger ones get 413 `image_too_large`.
    #[arg(long, env = "QRPOSE_MAX_IMAGE_PIXELS", default_value_t = DEFAULT_MAX_IMAGE_PIXELS)]
    pub max_image_pixels: u64,
    /// Largest detection deadline, ms: a request's `max_detect_ms` above it is lowered to
    /// it, and so is the effort's default deadline.
    #[arg(long, env = "QRPOSE_MAX_DETECT_MS", default_value_t = DEFAULT_MAX_DETECT_MS)]
    pub max_detect_ms: u64,

    // ---- Connection limits
    /// Time a connection gets to send a complete request head, ms: from the accept for its
    /// first request, from the first byte for later ones; then it is closed.
    #[arg(long, env = "QRPOSE_HEADER_READ_TIMEOUT_MS", default_value_t = DEFAULT_HEADER_READ_TIMEOUT_MS)]
    pub header_read_timeout_ms: u64,
    /// Time a kept-alive connection may stay idle after its last response, ms; then it is
    /// closed.
    #[arg(long, env = "QRPOSE_IDLE_TIMEOUT_MS", default_value_t = DEFAULT_IDLE_TIMEOUT_MS)]
    pub idle_timeout_ms: u64,
    /// Open client connections at most. At the limit a new connection closes the
    /// longest-idle one (idle, or still sending its head); when every connection has a
    /// request in progress, new ones wait in the listen backlog.
    #[arg(long, env = "QRPOSE_MAX_CONNECTIONS", default_value_t = DEFAULT_MAX_CONNECTIONS)]
    pub max_connections: usize,
    // ---- end of connection limits

    // ---- Memory budget
    /// Image pixels admitted at once (running and queued image requests, by declared width
    /// × height; WebP counts twice): beyond it 503 `overloaded`. Bounds the image path's
    /// memory (about 3 bytes a pixel, docs/deploy.md) [default: estimation workers ×
    /// --max-image-pixels].
    #[arg(long, env = "QRPOSE_MAX_INFLIGHT_PIXELS")]
    pub max_inflight_pixels: Option<u64>,
    /// Image request bodies held at once, bytes (being read, waiting and running; by
    /// declared `Content-Length`, the body limit when none): beyond it 503 `overloaded`
    /// before the body is read [default: (estimation workers + 2) × --body-limit-bytes].
    #[arg(long, env = "QRPOSE_MAX_INFLIGHT_BODY_BYTES")]
    pub max_inflight_body_bytes: Option<u64>,
    // ---- end of memory budget

    // ---- Site
    /// A site file (YAML, docs/site.md): cameras by id, marker sizes by payload, mounts and
    /// the map. Validated at start (a bad file: exit 2 with file, line and reason); reloaded
    /// on SIGHUP and `POST /v1/site/reload`.
    #[arg(long, env = "QRPOSE_SITE")]
    pub site: Option<std::path::PathBuf>,
    // ---- end of site
    /// The limits of stream sessions (`GET /v1/stream`).
    #[command(flatten)]
    pub stream: StreamArgs,
    /// Who may call it: the auth file and TLS (docs/security.md).
    #[command(flatten)]
    pub security: SecurityArgs,
}

impl Default for ServeArgs {
    fn default() -> Self {
        Self {
            addr: SocketAddr::from(([127, 0, 0, 1], 8080)),
            body_limit_bytes: DEFAULT_BODY_LIMIT_BYTES,
            request_timeout_ms: DEFAULT_REQUEST_TIMEOUT_MS,
            worker_threads: None,
            max_concurrent_estimations: None,
            queue_length: DEFAULT_QUEUE_LENGTH,
            log_format: LogFormat::Text,
            shutdown_grace_ms: DEFAULT_SHUTDOWN_GRACE_MS,
            max_image_pixels: DEFAULT_MAX_IMAGE_PIXELS,
            max_detect_ms: DEFAULT_MAX_DETECT_MS,
            // Connection limits.
            header_read_timeout_ms: DEFAULT_HEADER_READ_TIMEOUT_MS,
            idle_timeout_ms: DEFAULT_IDLE_TIMEOUT_MS,
            max_connections: DEFAULT_MAX_CONNECTIONS,
            // Memory budget.
            max_inflight_pixels: None,
            max_inflight_body_bytes: None,
            // Site.
            site: None,
            stream: StreamArgs::default(),
            security: SecurityArgs::default(),
        }
    }
}

/// A flag whose value is outside its documented range.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("--{flag} must be between {min} and {max}, got {value}")]
pub struct ConfigError {
    /// The flag's name, without dashes.
    pub flag: &'static str,
    /// The refused value.
    pub value: u64,
    /// Smallest accepted value.
    pub min: u64,
    /// Largest accepted value.
    pub max: u64,
}

/// The validated configuration of the service.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Settings {
    /// Address to listen on.
    pub addr: SocketAddr,
    /// Largest request body, bytes.
    pub body_limit_bytes: usize,
    /// Time for a whole request.
    pub request_timeout: Duration,
    /// Async runtime threads.
    pub worker_threads: NonZeroUsize,
    /// Estimations running at once.
    pub max_concurrent_estimations: NonZeroUsize,
    /// Requests that may wait for an estimation worker (0: none wait).
    pub queue_length: usize,
    /// Log format.
    pub log_format: LogFormat,
    /// Time in-flight requests get to finish after a shutdown signal.
    pub shutdown_grace: Duration,
    /// Largest declared width × height of an uploaded image, pixels. The largest encoded
    /// image is the body limit.
    pub max_image_pixels: u64,
    /// Largest detection deadline.
    pub max_detect: Duration,

    // ---- Connection limits
    /// Time a connection gets to send a complete request head.
    pub header_read_timeout: Duration,
    /// Time a kept-alive connection may stay idle after its last response.
    pub idle_timeout: Duration,
    /// Open client connections at most.
    pub max_connections: NonZeroUsize,
    // ---- end of connection limits

    // ---- Memory budget
    /// Image pixels admitted at once (weighted: WebP twice).
    pub max_inflight_pixels: u64,
    /// Image request bodies held at once, bytes.
    pub max_inflight_body_bytes: u64,
    // ---- end of memory budget

    // ---- Site
    /// The site file, loaded at start and on reload.
    pub site: Option<std::path::PathBuf>,
    // ---- end of site
    /// The limits of stream sessions.
    pub stream: StreamSettings,
    /// The auth file and TLS.
    pub security: SecuritySettings,
}

impl Default for Settings {
    fn default() -> Self {
        let cpus = default_threads();
        Self {
            addr: SocketAddr::from(([127, 0, 0, 1], 8080)),
            body_limit_bytes: DEFAULT_BODY_LIMIT_BYTES,
            request_timeout: Duration::from_millis(DEFAULT_REQUEST_TIMEOUT_MS),
            worker_threads: cpus,
            max_concurrent_estimations: cpus,
            queue_length: DEFAULT_QUEUE_LENGTH,
            log_format: LogFormat::Text,
            shutdown_grace: Duration::from_millis(DEFAULT_SHUTDOWN_GRACE_MS),
            max_image_pixels: DEFAULT_MAX_IMAGE_PIXELS,
            max_detect: Duration::from_millis(DEFAULT_MAX_DETECT_MS),
            // Connection limits.
            header_read_timeout: Duration::from_millis(DEFAULT_HEADER_READ_TIMEOUT_MS),
            idle_timeout: Duration::from_millis(DEFAULT_IDLE_TIMEOUT_MS),
            max_connections: NonZeroUsize::new(DEFAULT_MAX_CONNECTIONS)
                .unwrap_or(NonZeroUsize::MIN),
            // Memory budget.
            max_inflight_pixels: default_inflight_pixels(cpus, DEFAULT_MAX_IMAGE_PIXELS),
            max_inflight_body_bytes: default_inflight_body_bytes(cpus, DEFAULT_BODY_LIMIT_BYTES),
            // Site.
            site: None,
            stream: StreamSettings::default(),
            security: SecuritySettings::default(),
        }
    }
}

/// The default pixel budget: one largest image per estimation worker.
fn default_inflight_pixels(workers: NonZeroUsize, max_image_pixels: u64) -> u64 {
    u64::try_from(workers.get())
        .unwrap_or(u64::MAX)
        .saturating_mul(max_image_pixels)
}

/// The default body budget: a largest body for each estimation worker and two more (being
/// read while the workers are busy).
fn default_inflight_body_bytes(workers: NonZeroUsize, body_limit_bytes: usize) -> u64 {
    u64::try_from(
        workers
            .get()
            .saturating_add(2)
            .saturating_mul(body_limit_bytes),
    )
    .unwrap_or(u64::MAX)
}

/// `duration` in whole milliseconds, for logs and messages (saturates at `u64::MAX`).
pub fn millis(duration: Duration) -> u64 {
    u64::try_from(duration.as_millis()).unwrap_or(u64::MAX)
}

/// The number of CPUs this process may use, 1 when unknown.
fn default_threads() -> NonZeroUsize {
    std::thread::available_parallelism().unwrap_or(NonZeroUsize::MIN)
}

fn in_range<T>(flag: &'static str, value: T, min: T, max: T) -> Result<T, ConfigError>
where
    T: Copy + PartialOrd + TryInto<u64>,
{
    let wide = |v: T| v.try_into().unwrap_or(u64::MAX);
    if (min..=max).contains(&value) {
        Ok(value)
    } else {
        Err(ConfigError {
            flag,
            value: wide(value),
            min: wide(min),
            max: wide(max),
        })
    }
}

fn threads(flag: &'static str, value: Option<usize>) -> Result<NonZeroUsize, ConfigError> {
    match value {
        None => Ok(default_threads()),
        Some(n) => {
            let n = in_range(flag, n, 1, MAX_THREADS)?;
            Ok(NonZeroUsize::new(n).unwrap_or(NonZeroUsize::MIN))
        }
    }
}

impl TryFrom<ServeArgs> for Settings {
    type Error = ConfigError;

    fn try_from(args: ServeArgs) -> Result<Self, ConfigError> {
        Self {
            addr: args.addr,
            body_limit_bytes: in_range(
                "body-limit-bytes",
                args.body_limit_bytes,
                MIN_BODY_LIMIT_BYTES,
                MAX_BODY_LIMIT_BYTES,
            )?,
            request_timeout: Duration::from_millis(in_range(
                "request-timeout-ms",
                args.request_timeout_ms,
                1,
                MAX_REQUEST_TIMEOUT_MS,
            )?),
            worker_threads: threads("worker-threads", args.worker_threads)?,
            max_concurrent_estimations: threads(
                "max-concurrent-estimations",
                args.max_concurrent_estimations,
            )?,
            queue_length: in_range("queue-length", args.queue_length, 0, MAX_QUEUE_LENGTH)?,
            log_format: args.log_format,
            shutdown_grace: Duration::from_millis(in_range(
                "shutdown-grace-ms",
                args.shutdown_grace_ms,
                0,
                MAX_SHUTDOWN_GRACE_MS,
            )?),
            max_image_pixels: in_range(
                "max-image-pixels",
                args.max_image_pixels,
                1,
                MAX_MAX_IMAGE_PIXELS,
            )?,
            max_detect: Duration::from_millis(in_range(
                "max-detect-ms",
                args.max_detect_ms,
                1,
                MAX_MAX_DETECT_MS,
            )?),
            // Connection limits.
            header_read_timeout: Duration::from_millis(in_range(
                "header-read-timeout-ms",
                args.header_read_timeout_ms,
                1,
                MAX_HEADER_READ_TIMEOUT_MS,
            )?),
            idle_timeout: Duration::from_millis(in_range(
                "idle-timeout-ms",
                args.idle_timeout_ms,
                1,
                MAX_IDLE_TIMEOUT_MS,
            )?),
            max_connections: NonZeroUsize::new(in_range(
                "max-connections",
                args.max_connections,
                1,
                MAX_MAX_CONNECTIONS,
            )?)
            .unwrap_or(NonZeroUsize::MIN),
            // Memory budget: set from the other settings just below.
            max_inflight_pixels: 0,
            max_inflight_body_bytes: 0,
            // Site: the file is read by the caller, which owns the exit code.
            site: args.site,
            stream: StreamSettings::try_from(&args.stream)?,
            security: SecuritySettings::from(&args.security),
        }
        .with_memory_budget(args.max_inflight_pixels, args.max_inflight_body_bytes)
    }
}

impl Settings {
    /// The memory budget: pixels as given (at least one largest image, so that every
    /// accepted image can run) or one largest image per estimation worker; body bytes as
    /// given (at least one largest body) or [`default_inflight_body_bytes`].
    fn with_memory_budget(
        mut self,
        max_inflight_pixels: Option<u64>,
        max_inflight_body_bytes: Option<u64>,
    ) -> Result<Self, ConfigError> {
        let body_limit = u64::try_from(self.body_limit_bytes).unwrap_or(u64::MAX);
        self.max_inflight_body_bytes = match max_inflight_body_bytes {
            Some(bytes) => in_range("max-inflight-body-bytes", bytes, body_limit, u64::MAX / 8)?,
            None => {
                default_inflight_body_bytes(self.max_concurrent_estimations, self.body_limit_bytes)
            }
        };
        self.max_inflight_pixels = match max_inflight_pixels {
            Some(pixels) => in_range(
                "max-inflight-pixels",
                pixels,
                self.max_image_pixels,
                u64::MAX / 8,
            )?,
            None => default_inflight_pixels(self.max_concurrent_estimations, self.max_image_pixels),
        };
        Ok(self)
    }
}

/// The service's defaults (`qrpose serve` without flags), also the command line's limits.
impl Default for ImageLimits {
    fn default() -> Self {
        Self::from(&Settings::default())
    }
}

impl From<&Settings> for ImageLimits {
    fn from(settings: &Settings) -> Self {
        Self {
            decode: DecodeLimits {
                max_encoded_bytes: settings.body_limit_bytes,
                max_pixels: settings.max_image_pixels,
            },
            max_detect: settings.max_detect,
        }
    }
}

#[cfg(test)]
mod tests;
