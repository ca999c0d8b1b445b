//! Serving connections: the accept loop and one task per connection, with the limits that
//! `axum::serve` does not offer (docs/service.md, "Limits"):
//!
//! - **Header-read timeout** (`--header-read-timeout-ms`): a connection must deliver a
//!   complete request head within it, counted from the accept for its first request and from
//!   the first byte of each later one. Connections that send nothing, or a head a byte at a
//!   time, are closed (without an answer: there is no request to answer).
//! - **Idle timeout** (`--idle-timeout-ms`): a kept-alive connection with no request in
//!   progress and no byte of a new one is closed this long after its last response.
//! - **Connection limit** (`--max-connections`): a semaphore taken after each accept. At the
//!   limit the new connection closes the connection that has been idle (or sending its head)
//!   the longest, so that one client holding many silent sockets cannot lock the others out
//!   (`/healthz` still answers); when every connection has a request in progress, the accept
//!   loop waits for one to end and new connections wait in the kernel's listen backlog. A
//!   connection with a request in progress is never closed for the limit.
//! - **Accept errors** (out of file descriptors, say) back off exponentially from 5 ms to 1 s,
//!   close the longest-idle connection to free a descriptor, and are logged at most once a
//!   minute with the number of failures since the last line: the loop never spins and the log
//!   never floods.
//!
//! A connection's phase (fresh, reading a head, busy, idle) is tracked by three hooks: the
//! socket wrapper `WatchedIo` sees the first byte of a request, the `Tracked` service
//! sees its head complete, and the response body `TrackedBody` sees the response end
//! (dropped once written). The connection's task sleeps until its phase's deadline.
//!
//! With TLS (`super::tls`), the handshake comes first and counts as part of the first
//! request's head: it must complete within the header-read timeout, and a connection in its
//! handshake is fresh (closed to make room or at shutdown like one that has sent nothing).
//!
//! Shutdown: the listener closes, fresh and idle connections are closed at once, the others
//! finish their requests (hyper's graceful shutdown), at most for the grace period; then
//! every connection still open is dropped.

mod phase;
#[cfg(test)]
mod tests;

use super::metrics::{CloseReason, ConnectionMetrics};
use super::tls::TlsStore;
use crate::config::millis;
use axum::Router;
use hyper::server::conn::http1;
use hyper_util::rt::TokioIo;
use phase::{Activity, Phase, Tracked, WatchedIo};
use std::collections::HashMap;
use std::future::Future;
use std::io;
use std::pin::{Pin, pin};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{OwnedSemaphorePermit, Semaphore};
use tokio::time::Instant;
use tokio_util::sync::{CancellationToken, WaitForCancellationFutureOwned};

/// The limits of [`serve_connections`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConnectionLimits {
    /// Time to deliver a complete request head.
    pub header_read_timeout: Duration,
    /// Time a kept-alive connection may stay idle after its last response.
    pub idle_timeout: Duration,
    /// Open connections at most.
    pub max_connections: usize,
    /// Time in-flight requests get after the shutdown signal.
    pub shutdown_grace: Duration,
}

/// Shortest and longest pause after a failed accept.
const ACCEPT_BACKOFF_MIN: Duration = Duration::from_millis(5);
const ACCEPT_BACKOFF_MAX: Duration = Duration::from_secs(1);
/// At most one log line per this period about failing accepts.
const ACCEPT_ERROR_LOG_PERIOD: Duration = Duration::from_secs(60);
/// While the limit is reached and every connection is busy, how often to look for one that
/// has become idle.
const EVICTION_RETRY: Duration = Duration::from_millis(50);
/// Descriptors the process needs besides its client connections (listener, epoll, logs,
/// files), for the start-up warning against the open-file limit.
const FD_RESERVE: u64 = 64;

/// The open connections, for closing the longest-waiting one when room is needed.
#[derive(Debug, Default)]
struct Registry {
    next_id: AtomicU64,
    open: Mutex<HashMap<u64, Entry>>,
}

#[derive(Debug)]
struct Entry {
    phase: Arc<Activity>,
    evict: CancellationToken,
}

impl Registry {
    fn add(self: &Arc<Self>, phase: Arc<Activity>) -> Registered {
        let id = self.next_id.fetch_add(1, Ordering::Relaxed);
        let evict = CancellationToken::new();
        let entry = Entry {
            phase,
            evict: evict.clone(),
        };
        self.lock().insert(id, entry);
        Registered {
            registry: Arc::clone(self),
            id,
            evict,
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<u64, Entry>> {
        self.open.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Asks the connection that has waited longest without a request in progress to close;
    /// false when every connection has one.
    fn evict_longest_waiting(&self) -> bool {
        let open = self.lock();
        let victim = open
            .values()
            .filter(|e| !e.evict.is_cancelled())
            .filter_map(|e| e.phase.get().waiting_since().map(|since| (since, e)))
            .min_by_key(|(since, _)| *since);
        match victim {
            Some((_, entry)) => {
                entry.evict.cancel();
                true
            }
            None => false,
        }
    }
}

/// A connection's place in the [`Registry`]; removed when dropped.
struct Registered {
    registry: Arc<Registry>,
    id: u64,
    evict: CancellationToken,
}

impl Drop for Registered {
    fn drop(&mut self) {
        self.registry.lock().remove(&self.id);
    }
}

/// Shared by the accept loop and every connection task.
struct Shared {
    app: Router,
    limits: ConnectionLimits,
    registry: Arc<Registry>,
    metrics: ConnectionMetrics,
    /// TLS, when configured: each connection's handshake with the configuration in use.
    tls: Option<TlsStore>,
    /// Cancelled at the shutdown signal: finish in-flight requests, then close.
    draining: CancellationToken,
    /// Cancelled when the grace period is over: close now.
    closing: CancellationToken,
}

/// A connection that may be upgraded (`GET /v1/stream`): once the `101 Switching
/// Protocols` is written, the connection's future ends and the socket belongs to the
/// session, which has its own limits (`--max-stream-sessions`, its idle timeout) and closes
/// at shutdown; it no longer counts against `--max-connections`.
type Http1Connection = http1::UpgradeableConnection<TokioIo<WatchedIo>, Tracked>;

/// Drives one connection and closes it when a limit says so. Everything is checked on each
/// poll of the connection's task (a few uncontended operations), so a request costs no
/// extra wake-up: its phase changes happen while hyper is polled, here. The timer is reset
/// only when the deadline moves earlier (a head starting on an idle connection); when it
/// fires early (the deadline moved later) it is re-armed.
struct Driver {
    connection: Pin<Box<Http1Connection>>,
    activity: Arc<Activity>,
    limits: ConnectionLimits,
    metrics: ConnectionMetrics,
    timer: Pin<Box<tokio::time::Sleep>>,
    armed_for: Option<Instant>,
    evict: Pin<Box<WaitForCancellationFutureOwned>>,
    evicted: bool,
    draining: Pin<Box<WaitForCancellationFutureOwned>>,
    shutting_down: bool,
    closing: Pin<Box<WaitForCancellationFutureOwned>>,
}

impl Future for Driver {
    /// Why the connection was closed by a limit; `None` when it ended otherwise.
    type Output = Option<CloseReason>;

    fn poll(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<CloseReason>> {
        let this = self.get_mut();
        if let Poll::Ready(result) = this.connection.as_mut().poll(cx) {
            if let Err(e) = result {
                tracing::debug!(error = %e, "connection ended with an error");
            }
            return Poll::Ready(None);
        }
        if this.closing.as_mut().poll(cx).is_ready() {
            return Poll::Ready(None);
        }
        let phase = this.activity.get();
        if !this.shutting_down && this.draining.as_mut().poll(cx).is_ready() {
            this.shutting_down = true;
            if matches!(phase, Phase::Fresh { .. } | Phase::Idle { .. }) {
                return Poll::Ready(None);
            }
            this.connection.as_mut().graceful_shutdown();
            cx.waker().wake_by_ref();
        }
        if !this.evicted && this.evict.as_mut().poll(cx).is_ready() {
            this.evicted = true;
            if phase.waiting_since().is_some() {
                return Poll::Ready(Some(CloseReason::Evicted));
            }
            // Became busy meanwhile: close once its request is answered.
            this.metrics.closed(CloseReason::Evicted);
            this.connection.as_mut().graceful_shutdown();
            cx.waker().wake_by_ref();
        }
        let deadline = phase.deadline(&this.limits);
        if let Some((at, _)) = deadline
            && this.armed_for.is_none_or(|armed| at < armed)
        {
            this.timer.as_mut().reset(at);
            this.armed_for = Some(at);
        }
        while this.armed_for.is_some() && this.timer.as_mut().poll(cx).is_ready() {
            match deadline {
                // (Fired for this very deadline counts even if the clock reads a hair less.)
                Some((at, reason)) if at <= Instant::now() || this.armed_for == Some(at) => {
                    return Poll::Ready(Some(reason));
                }
                // Fired for an earlier phase: wait for this one's deadline.
                Some((at, _)) => {
                    this.timer.as_mut().reset(at);
                    this.armed_for = Some(at);
                }
                // Busy: no deadline until the phase changes (which happens in this task).
                None => this.armed_for = None,
            }
        }
        Poll::Pending
    }
}

/// Serves one connection until it ends, a limit closes it, or shutdown does.
async fn serve_connection(tcp: TcpStream, shared: Arc<Shared>, permit: OwnedSemaphorePermit) {
    let activity = Activity::new();
    let registered = shared.registry.add(Arc::clone(&activity));
    let deadline = Instant::now() + shared.limits.header_read_timeout;
    let stop = async {
        tokio::select! {
            () = registered.evict.cancelled() => {}
            () = shared.draining.cancelled() => {}
        }
    };
    let Some(stream) = super::tls::handshake(tcp, shared.tls.as_ref(), deadline, stop).await else {
        return;
    };
    let io = TokioIo::new(WatchedIo {
        inner: stream,
        activity: Arc::clone(&activity),
    });
    let service = Tracked {
        app: shared.app.clone(),
        activity: Arc::clone(&activity),
    };
    let mut builder = http1::Builder::new();
    // The timeouts are this module's (hyper's header timer also runs while a kept-alive
    // connection is idle, so it cannot tell the two apart).
    builder.header_read_timeout(Option::<Duration>::None);
    let driver = Driver {
        connection: Box::pin(builder.serve_connection(io, service).with_upgrades()),
        activity,
        limits: shared.limits,
        metrics: shared.metrics.clone(),
        timer: Box::pin(tokio::time::sleep(Duration::ZERO)),
        armed_for: None,
        evict: Box::pin(registered.evict.clone().cancelled_owned()),
        evicted: false,
        draining: Box::pin(shared.draining.clone().cancelled_owned()),
        shutting_down: false,
        closing: Box::pin(shared.closing.clone().cancelled_owned()),
    };
    shared.metrics.open.inc();
    if let Some(reason) = driver.await {
        tracing::debug!(reason = reason.as_str(), "closing a connection");
        shared.metrics.closed(reason);
    }
    shared.metrics.open.dec();
    // The driver (and with it the socket) is gone before the place is given back.
    drop(registered);
    drop(permit);
}

/// Whether an accept error concerns only the connection being accepted.
fn is_connection_error(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::ConnectionRefused
            | io::ErrorKind::ConnectionAborted
            | io::ErrorKind::ConnectionReset
    )
}

/// Failed accepts in a row, their pause, and the rate-limited log line.
#[derive(Debug, Default)]
struct AcceptBackoff {
    failures_in_a_row: u32,
    unlogged: u64,
    last_logged: Option<Instant>,
}

impl AcceptBackoff {
    /// Records a failure and returns how long to pause.
    fn failed(&mut self, error: &io::Error) -> Duration {
        self.failures_in_a_row = self.failures_in_a_row.saturating_add(1);
        self.unlogged += 1;
        let now = Instant::now();
        if self
            .last_logged
            .is_none_or(|at| now.duration_since(at) >= ACCEPT_ERROR_LOG_PERIOD)
        {
            tracing::error!(
                %error,
                failures = self.unlogged,
                "cannot accept connections; backing off (logged at most once a minute)"
            );
            self.unlogged = 0;
            self.last_logged = Some(now);
        }
        let doublings = self.failures_in_a_row.saturating_sub(1).min(16);
        ACCEPT_BACKOFF_MIN
            .saturating_mul(1 << doublings)
            .min(ACCEPT_BACKOFF_MAX)
    }

    fn succeeded(&mut self) {
        self.failures_in_a_row = 0;
    }
}

/// The soft open-file limit of this process (Linux: `/proc/self/limits`).
fn open_file_limit() -> Option<u64> {
    let limits = std::fs::read_to_string("/proc/self/limits").ok()?;
    let line = limits.lines().find(|l| l.starts_with("Max open files"))?;
    line.split_whitespace().nth(3)?.parse().ok()
}

/// Serves `app` on `listener` with `limits` (over TLS when `tls` is given) until `shutdown`
/// completes; `on_shutdown` runs once at that moment (before the wait for in-flight
/// requests).
///
/// # Errors
/// None today: accept errors are retried with a back-off. The `Result` keeps the signature
/// of a server that may fail to serve.
pub async fn serve_connections<F, G>(
    listener: TcpListener,
    app: Router,
    limits: ConnectionLimits,
    metrics: ConnectionMetrics,
    tls: Option<TlsStore>,
    shutdown: F,
    on_shutdown: G,
) -> io::Result<()>
where
    F: Future<Output = ()> + Send + 'static,
    G: FnOnce(),
{
    if let Some(fds) = open_file_limit()
        && fds < limits.max_connections as u64 + FD_RESERVE
    {
        tracing::warn!(
            open_file_limit = fds,
            max_connections = limits.max_connections,
            "the open-file limit is below --max-connections plus {FD_RESERVE}: accepts may fail \
             before the connection limit is reached (raise `ulimit -n` or lower \
             --max-connections)"
        );
    }
    let places = Arc::new(Semaphore::new(limits.max_connections));
    let shared = Arc::new(Shared {
        app,
        limits,
        registry: Arc::default(),
        metrics,
        tls,
        draining: CancellationToken::new(),
        closing: CancellationToken::new(),
    });
    let mut shutdown = pin!(shutdown);
    let mut backoff = AcceptBackoff::default();
    'accept: loop {
        let accepted = tokio::select! {
            biased;
            () = &mut shutdown => break,
            accepted = listener.accept() => accepted,
        };
        let tcp = match accepted {
            Ok((tcp, _)) => {
                backoff.succeeded();
                tcp
            }
            Err(e) if is_connection_error(&e) => continue,
            Err(e) => {
                shared.metrics.accept_errors.inc();
                let pause = backoff.failed(&e);
                // Out of descriptors, most likely: free one held by a waiting connection.
                shared.registry.evict_longest_waiting();
                tokio::select! {
                    biased;
                    () = &mut shutdown => break,
                    () = tokio::time::sleep(pause) => continue,
                }
            }
        };
        if let Err(e) = tcp.set_nodelay(true) {
            tracing::debug!(error = %e, "cannot set TCP_NODELAY");
        }
        let permit = match Arc::clone(&places).try_acquire_owned() {
            Ok(permit) => permit,
            Err(_) => {
                shared.metrics.limit_reached.inc();
                // Make room: close the longest-waiting connection, or, while every one has a
                // request in progress, the first to become idle.
                let mut evicted = shared.registry.evict_longest_waiting();
                loop {
                    let retry = async {
                        if evicted {
                            std::future::pending().await
                        } else {
                            tokio::time::sleep(EVICTION_RETRY).await;
                        }
                    };
                    tokio::select! {
                        biased;
                        () = &mut shutdown => break 'accept,
                        permit = Arc::clone(&places).acquire_owned() => match permit {
                            Ok(permit) => break permit,
                            Err(_) => break 'accept,
                        },
                        () = retry => evicted = shared.registry.evict_longest_waiting(),
                    }
                }
            }
        };
        tokio::spawn(serve_connection(tcp, Arc::clone(&shared), permit));
    }
    drop(listener);
    on_shutdown();
    shared.draining.cancel();
    let grace = limits.shutdown_grace;
    let all = u32::try_from(limits.max_connections).unwrap_or(u32::MAX);
    let finished = tokio::time::timeout(grace, places.acquire_many(all)).await;
    if finished.is_ok() {
        tracing::info!("all requests finished; stopped");
    } else {
        tracing::warn!(
            grace_ms = millis(grace),
            "grace period over; dropping the connections still open"
        );
        shared.closing.cancel();
        // The tasks drop their sockets at once; wait for that, briefly.
        let _ = tokio::time::timeout(Duration::from_secs(1), places.acquire_many(all)).await;
    }
    Ok(())
}
