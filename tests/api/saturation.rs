//! Saturation: a full estimation queue answers 503 `overloaded` at once, a request that
//! waits too long 503 `timeout`, both with `Retry-After`. The test occupies the workers
//! itself through the server's own queue, so nothing depends on how fast an estimate is.
//! Queued requests are image requests: short corners estimates run inline and never queue
//! (`a_corners_request_is_answered_while_every_worker_is_busy`). Image bodies are admitted
//! against a byte budget before they are read.

use crate::helpers::{
    assert_problem, occupy_worker, one_worker, queue_reaches, spawn_app_with, valid_request,
};
use qrpose::api::problem::ErrorCode;
use qrpose::config::Settings;
use reqwest::{StatusCode, header};
use serde_json::json;
use std::time::Duration;

#[tokio::test]
async fn a_full_queue_answers_503_overloaded_with_retry_after() {
    // Arrange: one worker, no waiting places, and the worker taken.
    let app = spawn_app_with(one_worker(0)).await;
    let gate = occupy_worker(&app).await;

    // Act
    let refused = app.post_queued().await;

    // Assert
    assert_eq!(refused.headers()[header::RETRY_AFTER], "1");
    assert_problem(refused, 503, ErrorCode::Overloaded).await;
    let metrics = app.get("/metrics").await.text().await.expect("text");
    assert!(
        metrics.contains("qrpose_estimation_rejections_total 1"),
        "{metrics}"
    );
    assert!(
        metrics.contains("qrpose_estimations_running 1"),
        "{metrics}"
    );
    app.assert_up("an overload").await;

    gate.release().await;
    app.assert_serves_corners("the worker is free").await;
}

#[tokio::test]
async fn a_request_waiting_past_the_timeout_answers_503_timeout() {
    // Arrange: one worker (taken) and one waiting place; a short timeout.
    let app = spawn_app_with(Settings {
        request_timeout: Duration::from_millis(200),
        ..one_worker(1)
    })
    .await;
    let gate = occupy_worker(&app).await;

    // Act
    let timed_out = app.post_queued().await;

    // Assert
    assert_eq!(timed_out.headers()[header::RETRY_AFTER], "1");
    let problem = assert_problem(timed_out, 503, ErrorCode::Timeout).await;
    assert!(problem.detail.contains("200 ms"), "{}", problem.detail);

    // The abandoned job keeps its place until a worker reaches it and drops it unrun.
    queue_reaches(&app, 1, 1).await;
    gate.release().await;
    queue_reaches(&app, 0, 0).await;
    app.assert_serves_corners("the worker is free").await;
}

#[tokio::test]
async fn queued_requests_are_served_in_turn_once_a_worker_frees() {
    // Arrange: one worker (taken) and two waiting places, both filled.
    let app = spawn_app_with(one_worker(2)).await;
    let gate = occupy_worker(&app).await;
    let first = app.post_queued_in_background();
    let second = app.post_queued_in_background();
    queue_reaches(&app, 1, 2).await;
    let readiness: serde_json::Value = app.get("/readyz").await.json().await.expect("JSON");
    assert_eq!(readiness["queue"]["waiting"], 2);
    assert_problem(app.post_queued().await, 503, ErrorCode::Overloaded).await;

    // Act
    gate.release().await;

    // Assert
    for request in [first, second] {
        let response = request.await.expect("the task").expect("an answer");
        assert_eq!(response.status(), StatusCode::OK);
    }
}

#[tokio::test]
async fn a_corners_request_is_answered_while_every_worker_is_busy() {
    // Arrange: the only worker taken and no waiting place: a queued request is refused.
    let app = spawn_app_with(one_worker(0)).await;
    let gate = occupy_worker(&app).await;
    assert_problem(app.post_queued().await, 503, ErrorCode::Overloaded).await;

    // Act: a short estimate runs inline, on the async thread.
    let inline = app.post_corners(&valid_request()).await;

    // Assert
    assert_eq!(inline.status(), StatusCode::OK);
    let metrics = app.get("/metrics").await.text().await.expect("text");
    assert!(
        metrics.contains("qrpose_estimator_iterations_count{method=\"reprojection\"} 1"),
        "the inline estimate is counted: {metrics}"
    );
    // A long one (a trace to serialise) still goes to the workers, which are full.
    let mut long = valid_request();
    long["solver"] = json!({"method": "paper", "trace": true});
    assert_problem(app.post_corners(&long).await, 503, ErrorCode::Overloaded).await;
    gate.release().await;
    assert_eq!(app.post_corners(&long).await.status(), StatusCode::OK);
}

#[tokio::test]
async fn image_bodies_beyond_the_body_budget_are_refused_before_they_are_read() {
    use tokio::io::AsyncWriteExt;

    // Arrange: room for one 40 KiB body at a time; a first client declares one and sends
    // only its first bytes, so the server holds its share while it waits for the rest.
    let body_bytes: usize = 40 * 1024;
    let app = spawn_app_with(Settings {
        body_limit_bytes: 64 * 1024,
        max_inflight_body_bytes: 64 * 1024,
        ..Settings::default()
    })
    .await;
    let host = app.address.trim_start_matches("http://").to_owned();
    let mut slow = tokio::net::TcpStream::connect(&host)
        .await
        .expect("connects");
    let head = format!(
        "POST /v1/pose/image?fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50 \
         HTTP/1.1\r\nHost: {host}\r\nContent-Type: image/jpeg\r\nContent-Length: {body_bytes}\r\n\r\n"
    );
    slow.write_all(head.as_bytes()).await.expect("writes");
    slow.write_all(&[0xFF, 0xD8]).await.expect("writes");
    tokio::time::sleep(Duration::from_millis(200)).await;

    // Act: a second body of the same size does not fit beside it.
    let refused = app
        .post_image(
            "fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50",
            vec![0u8; body_bytes],
            Some("image/jpeg"),
        )
        .await;

    // Assert: refused at once, naming the budget; once the first client is gone its share
    // is free again (the same request is read and judged: not an image).
    assert_eq!(refused.headers()[header::RETRY_AFTER], "1");
    let problem = assert_problem(refused, 503, ErrorCode::Overloaded).await;
    assert!(
        problem.detail.contains("max-inflight-body-bytes"),
        "{}",
        problem.detail
    );
    drop(slow);
    let mut answered = None;
    for _ in 0..100 {
        let response = app
            .post_image(
                "fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50",
                vec![0u8; body_bytes],
                Some("image/jpeg"),
            )
            .await;
        if response.status() != StatusCode::SERVICE_UNAVAILABLE {
            answered = Some(response);
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let answered = answered.expect("the budget is free once the first body is dropped");
    assert_problem(answered, 422, ErrorCode::UndecodableImage).await;
}
