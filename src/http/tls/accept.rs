//! The TLS handshake of one accepted connection, within the connection's limits, and the
//! refusal of plain HTTP on the TLS port.

use super::{ServerStream, TlsStore};
use crate::api::problem::{ErrorCode, Problem};
use crate::http::metrics::TlsRefusal;
use std::future::Future;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio::time::Instant;

/// The first byte of every TLS connection: the record type of a handshake (RFC 8446,
/// section 5.1).
const TLS_HANDSHAKE_RECORD: u8 = 0x16;

/// How much of a plain-HTTP request head is read before answering it (so that closing the
/// socket does not reset the answer away), bytes.
const PLAIN_HEAD_MAX_BYTES: usize = 16 * 1024;

/// How long the refusal waits for the client to close after the answer.
const PLAIN_LINGER: Duration = Duration::from_millis(500);

/// What the first byte of a connection says it speaks.
enum Opening {
    /// A TLS handshake record.
    Tls,
    /// A letter: the method of a plain-HTTP request.
    PlainHttp,
    /// Neither.
    Other,
}

/// The connection's stream once it may carry HTTP: `tcp` itself without TLS, else after a
/// completed handshake. `None` when the connection is to close: a failed handshake, plain
/// HTTP (answered `400 tls_required` first), no complete handshake by `deadline` (the
/// connection's header-read deadline), a client that closed before a byte, or `stop`
/// completing first (the connection closed to make room, or the shutdown). Each refusal is
/// counted in `qrpose_tls_connections_refused_total{reason}` as soon as it is known (a
/// plain-HTTP client is counted before its answer is written).
pub async fn handshake(
    tcp: TcpStream,
    tls: Option<&TlsStore>,
    deadline: Instant,
    stop: impl Future<Output = ()>,
) -> Option<ServerStream> {
    let Some(tls) = tls else {
        return Some(ServerStream::Plain(tcp));
    };
    let acceptor = tls.acceptor();
    // Set once a refusal is counted, so that a plain-HTTP client stalling its head after
    // being counted is not counted again as a timeout.
    let counted = AtomicBool::new(false);
    let refuse = |refusal: TlsRefusal| {
        if !counted.swap(true, Ordering::Relaxed) {
            tracing::debug!(reason = refusal.as_str(), "TLS connection refused");
            tls.metrics().observe_tls_refusal(refusal);
        }
    };
    let work = async {
        let mut first = [0u8; 1];
        let opening = match tcp.peek(&mut first).await {
            Ok(0) | Err(_) => return None,
            Ok(_) if first[0] == TLS_HANDSHAKE_RECORD => Opening::Tls,
            Ok(_) if first[0].is_ascii_alphabetic() => Opening::PlainHttp,
            Ok(_) => Opening::Other,
        };
        match opening {
            Opening::Tls => match acceptor.accept(tcp).await {
                Ok(stream) => Some(ServerStream::Tls(Box::new(stream))),
                Err(e) => {
                    tracing::debug!(error = %e, "TLS handshake failed");
                    refuse(TlsRefusal::Handshake);
                    None
                }
            },
            Opening::PlainHttp => {
                refuse(TlsRefusal::PlainHttp);
                refuse_plain_http(tcp).await;
                None
            }
            Opening::Other => {
                refuse(TlsRefusal::Handshake);
                None
            }
        }
    };
    tokio::select! {
        biased;
        () = stop => None,
        outcome = tokio::time::timeout_at(deadline, work) => outcome.unwrap_or_else(|_elapsed| {
            refuse(TlsRefusal::Timeout);
            None
        }),
    }
}

/// Answers a plain-HTTP request on the TLS port with `400 tls_required` (in plain HTTP,
/// which is all such a client reads) and closes: the head is read first and the close
/// waits briefly for the client's, so that the answer is not lost to a reset.
async fn refuse_plain_http(mut tcp: TcpStream) {
    let mut head = Vec::with_capacity(1024);
    let mut chunk = [0u8; 1024];
    while head.len() < PLAIN_HEAD_MAX_BYTES && !head.windows(4).any(|w| w == b"\r\n\r\n") {
        match tcp.read(&mut chunk).await {
            Ok(0) | Err(_) => return,
            Ok(n) => head.extend_from_slice(&chunk[..n]),
        }
    }
    let problem = Problem::new(
        ErrorCode::TlsRequired,
        "this port speaks TLS: use https:// (wss:// for the stream)",
    );
    let body = serde_json::to_string(&problem).unwrap_or_default();
    let answer = format!(
        "HTTP/1.1 400 Bad Request\r\ncontent-type: application/problem+json\r\n\
         content-length: {}\r\nconnection: close\r\n\r\n{body}",
        body.len()
    );
    if tcp.write_all(answer.as_bytes()).await.is_err() || tcp.shutdown().await.is_err() {
        return;
    }
    let _ = tokio::time::timeout(PLAIN_LINGER, async {
        while matches!(tcp.read(&mut chunk).await, Ok(n) if n > 0) {}
    })
    .await;
}
