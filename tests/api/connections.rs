//! Connection limits: the header-read timeout, the idle keep-alive timeout and the
//! connection limit (docs/service.md, "Limits"), with raw TCP clients that do what no HTTP
//! library would: send nothing, send a head a byte at a time, declare a huge body and send
//! none of it.

use crate::helpers::{PATIENCE, TestApp, eventually, occupy_worker, one_worker, spawn_app_with};
use qrpose::config::Settings;
use qrpose::http::metrics::CloseReason;
use std::num::NonZeroUsize;
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

async fn connect(app: &TestApp) -> TcpStream {
    let address = app.address.trim_start_matches("http://");
    TcpStream::connect(address)
        .await
        .expect("the server accepts")
}

/// Reads until the server closes the connection (end of stream or reset); returns what was
/// read. Panics after [`PATIENCE`].
async fn read_until_closed(stream: &mut TcpStream) -> Vec<u8> {
    let mut received = Vec::new();
    let read = tokio::time::timeout(PATIENCE, async {
        let mut buf = [0u8; 4096];
        loop {
            match stream.read(&mut buf).await {
                Ok(0) | Err(_) => return,
                Ok(n) => received.extend_from_slice(&buf[..n]),
            }
        }
    })
    .await;
    assert!(read.is_ok(), "the server never closed the connection");
    received
}

/// Reads one response whose body is a JSON object (`/healthz`, a problem) without waiting
/// for the connection to close.
async fn read_json_response(stream: &mut TcpStream) -> String {
    let mut received = Vec::new();
    let mut buf = [0u8; 4096];
    let read = tokio::time::timeout(PATIENCE, async {
        loop {
            let n = stream.read(&mut buf).await.expect("the connection is open");
            assert!(n > 0, "closed before the response was complete");
            received.extend_from_slice(&buf[..n]);
            let text = String::from_utf8_lossy(&received);
            if let Some(head_end) = text.find("\r\n\r\n")
                && text[head_end..].contains('}')
            {
                return text.into_owned();
            }
        }
    })
    .await;
    read.expect("a response within the test's patience")
}

const HEALTHZ: &[u8] = b"GET /healthz HTTP/1.1\r\nHost: qrpose.test\r\n\r\n";

fn with_timeouts(header_ms: u64, idle_ms: u64) -> Settings {
    Settings {
        header_read_timeout: Duration::from_millis(header_ms),
        idle_timeout: Duration::from_millis(idle_ms),
        ..Settings::default()
    }
}

async fn open_connections_reach(app: &TestApp, n: i64) {
    let metrics = app.state.metrics.connections();
    eventually(&format!("{n} connections open"), || {
        let open = metrics.open.get();
        async move { open == n }
    })
    .await;
}

#[tokio::test]
async fn a_connection_that_sends_nothing_is_closed_at_the_header_read_timeout() {
    // Arrange
    let app = spawn_app_with(with_timeouts(300, 60_000)).await;
    let mut silent = connect(&app).await;
    let started = Instant::now();

    // Act
    let received = read_until_closed(&mut silent).await;

    // Assert: closed without an answer, after the timeout and long before the idle one.
    let waited = started.elapsed();
    assert!(
        received.is_empty(),
        "{:?}",
        String::from_utf8_lossy(&received)
    );
    assert!(
        waited >= Duration::from_millis(250) && waited < Duration::from_secs(10),
        "{waited:?}"
    );
    let metrics = app.state.metrics.connections();
    assert_eq!(metrics.closed_count(CloseReason::HeaderTimeout), 1);
    app.assert_up("a silent connection").await;
}

#[tokio::test]
async fn a_head_sent_a_byte_at_a_time_is_cut_off_at_the_header_read_timeout() {
    // Arrange: a head that takes 3 s to send at one byte per 50 ms, against a 500 ms limit.
    let app = spawn_app_with(with_timeouts(500, 60_000)).await;
    let stream = connect(&app).await;
    let (mut reader, mut writer) = stream.into_split();
    let head = format!(
        "GET /healthz HTTP/1.1\r\nHost: qrpose.test\r\nX-Slow: {}\r\n\r\n",
        "a".repeat(20)
    );
    let started = Instant::now();
    let slowloris = tokio::spawn(async move {
        let mut sent = 0;
        for byte in head.bytes() {
            if writer.write_all(&[byte]).await.is_err() {
                break;
            }
            sent += 1;
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        (sent, head.len())
    });

    // Act: wait for the server to close the connection.
    let mut received = Vec::new();
    let closed = tokio::time::timeout(PATIENCE, reader.read_to_end(&mut received)).await;

    // Assert: closed at about the timeout, although a byte arrived every 50 ms, unanswered.
    let waited = started.elapsed();
    assert!(closed.is_ok(), "never closed");
    assert!(
        waited >= Duration::from_millis(450) && waited < Duration::from_millis(2500),
        "{waited:?}"
    );
    assert!(
        received.is_empty(),
        "{:?}",
        String::from_utf8_lossy(&received)
    );
    let (sent, total) = slowloris.await.expect("the writer");
    assert!(
        sent < total,
        "the head was never completed ({sent} of {total} bytes)"
    );
    assert_eq!(
        app.state
            .metrics
            .connections()
            .closed_count(CloseReason::HeaderTimeout),
        1
    );
}

#[tokio::test]
async fn an_idle_keep_alive_connection_is_closed_at_the_idle_timeout() {
    // Arrange: a long header-read timeout, a short idle timeout.
    let app = spawn_app_with(with_timeouts(30_000, 300)).await;
    let mut stream = connect(&app).await;
    stream.write_all(HEALTHZ).await.expect("sent");
    let response = read_json_response(&mut stream).await;
    assert!(response.starts_with("HTTP/1.1 200"), "{response}");
    let answered = Instant::now();

    // Act
    let rest = read_until_closed(&mut stream).await;

    // Assert
    let waited = answered.elapsed();
    assert!(rest.is_empty());
    assert!(
        waited >= Duration::from_millis(250) && waited < Duration::from_secs(10),
        "{waited:?}"
    );
    assert_eq!(
        app.state
            .metrics
            .connections()
            .closed_count(CloseReason::IdleTimeout),
        1
    );
}

#[tokio::test]
async fn a_kept_alive_connection_outlives_the_header_read_timeout_while_idle() {
    // Arrange: the idle timeout is longer than the header-read timeout, and it governs.
    let app = spawn_app_with(with_timeouts(200, 30_000)).await;
    let mut stream = connect(&app).await;
    stream.write_all(HEALTHZ).await.expect("sent");
    assert!(
        read_json_response(&mut stream)
            .await
            .starts_with("HTTP/1.1 200")
    );

    // Act: stay idle for three header-read timeouts, then send another request.
    tokio::time::sleep(Duration::from_millis(600)).await;
    stream.write_all(HEALTHZ).await.expect("still open");

    // Assert
    let second = read_json_response(&mut stream).await;
    assert!(second.starts_with("HTTP/1.1 200"), "{second}");
}

#[tokio::test]
async fn healthz_answers_while_silent_and_slow_connections_hold_the_limit() {
    // Arrange: 3 connections at most, timeouts far away; two silent connections and one
    // sending its head a byte at a time take every place.
    let app = spawn_app_with(Settings {
        max_connections: NonZeroUsize::new(3).expect("nonzero"),
        ..with_timeouts(60_000, 60_000)
    })
    .await;
    let mut oldest = connect(&app).await;
    open_connections_reach(&app, 1).await;
    let _silent = connect(&app).await;
    open_connections_reach(&app, 2).await;
    let slow = connect(&app).await;
    let (_slow_reader, mut slow_writer) = slow.into_split();
    let dripping = tokio::spawn(async move {
        for byte in b"GET /healthz HTTP/1.1\r\nHost: a\r\n"
            .iter()
            .cycle()
            .take(100)
        {
            if slow_writer.write_all(&[*byte]).await.is_err() {
                return;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    });
    open_connections_reach(&app, 3).await;

    // Act: a fourth client.
    let started = Instant::now();
    let health = tokio::time::timeout(Duration::from_secs(5), app.healthz()).await;

    // Assert: answered at once; the connection silent the longest made room.
    let health = health.expect("/healthz answers while the limit is reached");
    assert_eq!(health.status(), 200);
    assert!(
        started.elapsed() < Duration::from_secs(2),
        "{:?}",
        started.elapsed()
    );
    assert!(read_until_closed(&mut oldest).await.is_empty());
    let metrics = app.state.metrics.connections();
    assert_eq!(metrics.closed_count(CloseReason::Evicted), 1);
    assert!(metrics.limit_reached.get() >= 1);
    assert!(
        !dripping.is_finished(),
        "the slow client is still being served"
    );
    dripping.abort();
}

#[tokio::test]
async fn at_the_limit_a_connection_with_a_request_in_progress_is_never_closed() {
    // Arrange: one connection at most, and it carries a request that waits for the only
    // estimation worker, which the test holds.
    let app = spawn_app_with(Settings {
        max_connections: NonZeroUsize::MIN,
        ..one_worker(1)
    })
    .await;
    let gate = occupy_worker(&app).await;
    let in_flight = app.post_queued_in_background();
    crate::helpers::queue_reaches(&app, 1, 1).await;

    // Act: another client waits in the listen backlog instead of displacing it.
    crate::support::tls_provider();
    let other = reqwest::Client::builder()
        .no_proxy()
        .timeout(Duration::from_millis(500))
        .build()
        .expect("a client");
    let waited = other.get(format!("{}/healthz", app.address)).send().await;

    // Assert
    assert!(waited.is_err(), "no room: the second client waits");
    gate.release().await;
    let answered = in_flight.await.expect("the task").expect("an answer");
    assert_eq!(answered.status(), 200);
    assert_eq!(
        app.state
            .metrics
            .connections()
            .closed_count(CloseReason::Evicted),
        0
    );
    crate::support::tls_provider();
    let fresh = reqwest::Client::builder()
        .no_proxy()
        .build()
        .expect("a client");
    let health = fresh
        .get(format!("{}/healthz", app.address))
        .send()
        .await
        .expect("room again once the request is answered");
    assert_eq!(health.status(), 200);
}

#[tokio::test]
async fn a_declared_body_over_the_limit_is_refused_at_once_without_the_body() {
    // Arrange: each endpoint that reads a body; the client sends its headers only.
    let app = spawn_app_with(Settings {
        body_limit_bytes: 1024,
        ..Settings::default()
    })
    .await;
    for (path, content_type) in [
        ("/v1/pose/corners", "application/json"),
        (
            "/v1/pose/image?fx_px=1000&fy_px=1000&cx_px=0&cy_px=0&marker_size_mm=50",
            "image/jpeg",
        ),
    ] {
        let mut stream = connect(&app).await;
        let head = format!(
            "POST {path} HTTP/1.1\r\nHost: qrpose.test\r\nContent-Type: {content_type}\r\n\
             Content-Length: 1000000000\r\n\r\n"
        );
        stream.write_all(head.as_bytes()).await.expect("sent");
        let started = Instant::now();

        // Act
        let answer = read_json_response(&mut stream).await;

        // Assert: a 413 within a second (it used to wait for the request timeout, 10 s);
        // the connection is not reused and is closed (at the latest when the server stops
        // waiting for the body it was promised).
        assert!(answer.starts_with("HTTP/1.1 413"), "{path}: {answer}");
        assert!(
            answer.contains("\"code\":\"payload_too_large\""),
            "{path}: {answer}"
        );
        assert!(
            answer.to_ascii_lowercase().contains("connection: close"),
            "{answer}"
        );
        assert!(
            started.elapsed() < Duration::from_secs(1),
            "{path}: {:?}",
            started.elapsed()
        );
        drop(stream);
    }
    app.assert_up("oversized declared bodies").await;
}

#[tokio::test]
async fn a_declared_body_over_the_limit_that_is_sent_still_gets_its_413() {
    // Arrange: a client that sends its oversized body in full, without waiting.
    let app = spawn_app_with(Settings {
        body_limit_bytes: 1024,
        ..Settings::default()
    })
    .await;
    let body = vec![b' '; 256 * 1024];

    // Act
    let response = app.post_corners_raw(body, Some("application/json")).await;

    // Assert: the answer, not a reset.
    assert_eq!(response.status(), 413);
    app.assert_up("an oversized body sent in full").await;
}
