//! A connection's phase (fresh, reading a head, busy, idle) and the three hooks that track
//! it: the socket wrapper `WatchedIo` sees the first byte of a request, the `Tracked`
//! service sees its head complete, and the response body `TrackedBody` sees the response
//! end.

use super::ConnectionLimits;
use crate::http::metrics::CloseReason;
use crate::http::tls::ServerStream;
use axum::Router;
use axum::body::{Body, Bytes};
use axum::http::{Request, Response};
use http_body::{Frame, SizeHint};
use hyper::body::Incoming;
use std::convert::Infallible;
use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::{Arc, Mutex, PoisonError};
use std::task::{Context, Poll};
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::time::Instant;
use tower::ServiceExt;

/// What a connection is doing, and since when.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Phase {
    /// Accepted; no byte received yet.
    Fresh { since: Instant },
    /// Bytes of a request head have arrived; the head is not complete.
    Head { since: Instant },
    /// This many requests are in progress (head in, response not yet written).
    Busy { requests: usize },
    /// No request in progress and no byte of a new one since the last response.
    Idle { since: Instant },
}

impl Phase {
    /// When the connection is closed if nothing happens, and why.
    pub(super) fn deadline(self, limits: &ConnectionLimits) -> Option<(Instant, CloseReason)> {
        match self {
            Phase::Fresh { since } | Phase::Head { since } => Some((
                since + limits.header_read_timeout,
                CloseReason::HeaderTimeout,
            )),
            Phase::Idle { since } => Some((since + limits.idle_timeout, CloseReason::IdleTimeout)),
            Phase::Busy { .. } => None,
        }
    }

    /// Since when a connection without a request in progress has been waiting; `None` for
    /// a busy one, which is never closed to make room.
    pub(super) fn waiting_since(self) -> Option<Instant> {
        match self {
            Phase::Fresh { since } | Phase::Head { since } | Phase::Idle { since } => Some(since),
            Phase::Busy { .. } => None,
        }
    }
}

/// A connection's phase, shared by its socket, its requests and its task (all polled on the
/// connection's own task: the lock is never contended there) and read by the accept loop
/// when it needs room.
#[derive(Debug)]
pub(super) struct Activity(pub(super) Mutex<Phase>);

impl Activity {
    pub(super) fn new() -> Arc<Self> {
        Arc::new(Self(Mutex::new(Phase::Fresh {
            since: Instant::now(),
        })))
    }

    pub(super) fn get(&self) -> Phase {
        *self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    pub(super) fn update(&self, f: impl FnOnce(Phase) -> Phase) {
        let mut phase = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        *phase = f(*phase);
    }
}

/// The socket (after the TLS handshake, its plaintext side), reporting the first byte of a
/// request to the connection's phase.
pub(super) struct WatchedIo {
    pub(super) inner: ServerStream,
    pub(super) activity: Arc<Activity>,
}

impl AsyncRead for WatchedIo {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        let before = buf.filled().len();
        let polled = Pin::new(&mut this.inner).poll_read(cx, buf);
        if matches!(polled, Poll::Ready(Ok(()))) && buf.filled().len() > before {
            this.activity.update(|phase| match phase {
                Phase::Fresh { .. } | Phase::Idle { .. } => Phase::Head {
                    since: Instant::now(),
                },
                Phase::Head { .. } | Phase::Busy { .. } => phase,
            });
        }
        polled
    }
}

impl AsyncWrite for WatchedIo {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.get_mut().inner).poll_write(cx, buf)
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.get_mut().inner).poll_write_vectored(cx, bufs)
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().inner).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().inner).poll_shutdown(cx)
    }
}

/// One request in progress; ends when dropped (with its response body, or unanswered).
pub(super) struct InProgress {
    pub(super) activity: Arc<Activity>,
}

impl InProgress {
    pub(super) fn start(activity: &Arc<Activity>) -> Self {
        activity.update(|phase| match phase {
            Phase::Busy { requests } => Phase::Busy {
                requests: requests + 1,
            },
            _ => Phase::Busy { requests: 1 },
        });
        Self {
            activity: Arc::clone(activity),
        }
    }
}

impl Drop for InProgress {
    fn drop(&mut self) {
        self.activity.update(|phase| match phase {
            Phase::Busy { requests } if requests > 1 => Phase::Busy {
                requests: requests - 1,
            },
            Phase::Busy { .. } => Phase::Idle {
                since: Instant::now(),
            },
            other => other,
        });
    }
}

/// A response body that ends its request's [`InProgress`] when hyper drops it (written, or
/// the connection gone).
pub(super) struct TrackedBody {
    pub(super) body: Body,
    pub(super) _request: InProgress,
}

impl http_body::Body for TrackedBody {
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, axum::Error>>> {
        Pin::new(&mut self.get_mut().body).poll_frame(cx)
    }

    fn is_end_stream(&self) -> bool {
        self.body.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        self.body.size_hint()
    }
}

/// The application as a hyper service that marks each request in progress.
#[derive(Clone)]
pub(super) struct Tracked {
    pub(super) app: Router,
    pub(super) activity: Arc<Activity>,
}

pub(super) type ResponseFuture =
    Pin<Box<dyn Future<Output = Result<Response<TrackedBody>, Infallible>> + Send>>;

impl hyper::service::Service<Request<Incoming>> for Tracked {
    type Response = Response<TrackedBody>;
    type Error = Infallible;
    type Future = ResponseFuture;

    fn call(&self, request: Request<Incoming>) -> Self::Future {
        let in_progress = InProgress::start(&self.activity);
        let app = self.app.clone();
        Box::pin(async move {
            let response = app.oneshot(request.map(Body::new)).await?;
            Ok(response.map(|body| TrackedBody {
                body,
                _request: in_progress,
            }))
        })
    }
}
