//! `qrpose serve`: the HTTP service on a tokio runtime sized by the settings.
//!
//! Prints `listening on http://ADDR` (`https://` with `--tls-cert`) on standard output once
//! the socket is bound (with `--addr 127.0.0.1:0`, ADDR has the port the system picked);
//! logs go to standard error. SIGTERM or SIGINT starts a graceful shutdown; the exit code is
//! then 0. SIGHUP reloads the site, the auth file and the TLS certificate.

use anyhow::Context;
use qrpose::config::{ServeArgs, Settings};
use qrpose::http::{self, AppState, StateError};
use std::process::ExitCode;
use std::time::Duration;

/// How long the runtime waits for its remaining tasks when it stops.
const RUNTIME_SHUTDOWN_TIMEOUT: Duration = Duration::from_secs(1);

/// A future completing on the first SIGTERM or SIGINT. The handlers are installed now, so a
/// signal arriving right after the address is printed is not lost to the default action.
fn shutdown_signal() -> anyhow::Result<impl std::future::Future<Output = ()>> {
    use tokio::signal::unix::{SignalKind, signal};
    let mut sigterm = signal(SignalKind::terminate()).context("cannot listen for SIGTERM")?;
    let mut sigint = signal(SignalKind::interrupt()).context("cannot listen for SIGINT")?;
    Ok(async move {
        tokio::select! {
            _ = sigterm.recv() => tracing::info!("SIGTERM received"),
            _ = sigint.recv() => tracing::info!("SIGINT received"),
        }
    })
}

/// Reloads the site (`docs/site.md`, Reload), the auth file and the TLS certificate
/// (docs/security.md) on every SIGHUP, off the async threads; each outcome is logged and
/// counted by its reload ([`AppState::reload_site`], `AuthStore::reload`,
/// `TlsStore::reload`), and a refused file keeps the one loaded before. Open connections
/// keep the certificate they started with.
fn reload_on_sighup(state: AppState) -> anyhow::Result<()> {
    use tokio::signal::unix::{SignalKind, signal};
    let mut sighup = signal(SignalKind::hangup()).context("cannot listen for SIGHUP")?;
    tokio::spawn(async move {
        while sighup.recv().await.is_some() {
            tracing::info!("SIGHUP received: reloading the site, the auth file and TLS");
            let state = state.clone();
            // The outcomes are logged and counted inside; a panic is the task's own.
            let _ = tokio::task::spawn_blocking(move || {
                if state.site.path().is_some() {
                    let _ = state.reload_site();
                }
                if state.auth.file().is_some() {
                    let _ = state.auth.reload();
                }
                if let Some(tls) = &state.tls {
                    let _ = tls.reload();
                }
            })
            .await;
        }
    });
    Ok(())
}

async fn serve(state: AppState) -> anyhow::Result<()> {
    let addr = state.settings.addr;
    let shutdown = shutdown_signal()?;
    reload_on_sighup(state.clone())?;
    let listener = tokio::net::TcpListener::bind(addr)
        .await
        .with_context(|| format!("cannot listen on {addr}"))?;
    let bound = listener
        .local_addr()
        .context("cannot read the bound address")?;
    let scheme = if state.tls.is_some() { "https" } else { "http" };
    println!("listening on {scheme}://{bound}");
    tracing::info!(
        addr = %bound,
        max_concurrent_estimations = state.settings.max_concurrent_estimations.get(),
        queue_length = state.settings.queue_length,
        body_limit_bytes = state.settings.body_limit_bytes,
        request_timeout_ms = qrpose::config::millis(state.settings.request_timeout),
        "listening"
    );
    if let Some(clients) = state.auth.current() {
        tracing::info!(
            file = %state.auth.file().map(|f| f.display().to_string()).unwrap_or_default(),
            sha256 = clients.file_sha256_hex(),
            clients = clients.len(),
            "auth file loaded: tokens are checked"
        );
    }
    if let Some(warning) = http::auth::exposure_warning(bound, state.auth.is_on()) {
        tracing::warn!("{warning}");
    }
    if let Some(site) = state.site.current() {
        tracing::info!(
            file = %site.file().display(),
            sha256 = site.sha256_hex(),
            cameras = site.cameras().len(),
            mapped_codes = site.map().len(),
            "site loaded"
        );
    }
    http::serve(listener, state, shutdown)
        .await
        .context("the server failed")
}

/// Runs `serve`.
pub fn run(args: ServeArgs) -> ExitCode {
    let settings = match Settings::try_from(args) {
        Ok(settings) => settings,
        Err(e) => {
            eprintln!("qrpose serve: {e}");
            return ExitCode::from(super::EXIT_BAD_INPUT);
        }
    };
    // A bad site file is refused before anything starts: exit 2 with file, line, reason.
    let site = match super::site::load_optional(settings.site.as_deref()) {
        Ok(site) => site,
        Err(code) => return code,
    };
    // So are a bad auth file and bad TLS files, each loaded and validated once, here.
    let log_format = settings.log_format;
    let worker_threads = settings.worker_threads.get();
    let state = match AppState::with_site(settings, site) {
        Ok(state) => state,
        Err(e @ (StateError::Auth(_) | StateError::Tls(_) | StateError::Site(_))) => {
            eprintln!("qrpose serve: {e}");
            return ExitCode::from(super::EXIT_BAD_INPUT);
        }
        Err(e @ StateError::Workers(_)) => {
            eprintln!("qrpose serve: cannot build the service state: {e}");
            return ExitCode::FAILURE;
        }
    };
    if let Err(e) = qrpose::telemetry::init(log_format) {
        eprintln!("qrpose serve: {e}");
        return ExitCode::FAILURE;
    }
    qrpose::telemetry::log_panics();
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(worker_threads)
        .enable_all()
        .build()
    {
        Ok(runtime) => runtime,
        Err(e) => {
            eprintln!("qrpose serve: cannot start the runtime: {e}");
            return ExitCode::FAILURE;
        }
    };
    let result = runtime.block_on(serve(state));
    runtime.shutdown_timeout(RUNTIME_SHUTDOWN_TIMEOUT);
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            tracing::error!(error = format!("{e:#}"), "stopped");
            eprintln!("qrpose serve: {e:#}");
            ExitCode::FAILURE
        }
    }
}
