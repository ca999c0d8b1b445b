//! Logging: `tracing` to standard error, as text or one JSON object per line.
//!
//! The level comes from `RUST_LOG` (default `info`). Every line written while a request is
//! handled carries the request's span: `request_id`, `method` and `path` (see
//! `http::middleware`). Tests stay quiet unless they install a subscriber themselves.
//!
//! [`log_panics`] sends panics to the same log: the decoders and detectors run under
//! `catch_unwind` (rqrr panics on some real photos, a bug upstream), and the default
//! hook would print a multi-line message to standard error in the middle of JSON logs.

use crate::config::LogFormat;
use std::io::IsTerminal;
use tracing_subscriber::{
    EnvFilter, fmt::MakeWriter, layer::SubscriberExt, util::SubscriberInitExt,
};

/// The filter used when `RUST_LOG` is unset or unparseable.
pub const DEFAULT_FILTER: &str = "info";

/// A global subscriber was already installed.
#[derive(Debug, thiserror::Error)]
#[error("cannot install the log subscriber: {0}")]
pub struct TelemetryError(#[from] tracing_subscriber::util::TryInitError);

/// Installs the global subscriber writing to standard error.
///
/// # Errors
/// [`TelemetryError`] when a subscriber is already installed.
pub fn init(format: LogFormat) -> Result<(), TelemetryError> {
    let ansi = std::io::stderr().is_terminal();
    init_with_writer(format, std::io::stderr, ansi)
}

/// Installs the global subscriber writing to `writer` (tests pass their own), with colours
/// in text lines when `ansi`.
///
/// # Errors
/// [`TelemetryError`] when a subscriber is already installed.
pub fn init_with_writer<W>(format: LogFormat, writer: W, ansi: bool) -> Result<(), TelemetryError>
where
    W: for<'w> MakeWriter<'w> + Send + Sync + 'static,
{
    let filter =
        EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(DEFAULT_FILTER));
    let registry = tracing_subscriber::registry().with(filter);
    match format {
        LogFormat::Text => registry
            .with(
                tracing_subscriber::fmt::layer()
                    .with_ansi(ansi)
                    .with_writer(writer),
            )
            .try_init()?,
        LogFormat::Json => registry
            .with(
                tracing_subscriber::fmt::layer()
                    .json()
                    .with_current_span(true)
                    .with_span_list(false)
                    .with_writer(writer),
            )
            .try_init()?,
    }
    Ok(())
}

/// Replaces the panic hook with one that logs the panic as one `error` event (message and
/// location, inside the current request's span) instead of printing it to standard error.
/// Panics stay contained where they were ([`contain`](qrpose_detect::contain::contain) in
/// the detectors and the worker queue); this only changes where the report goes.
pub fn log_panics() {
    std::panic::set_hook(Box::new(|info| {
        let location = info
            .location()
            .map(|l| format!("{}:{}", l.file(), l.line()));
        tracing::error!(
            location = location.as_deref().unwrap_or("unknown"),
            "contained panic: {}",
            qrpose_detect::contain::panic_message(info.payload())
        );
    }));
}
