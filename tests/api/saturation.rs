//! Saturation: a full estimation queue answers 503 `overloaded` at once, a request that
//! waits too long 503 `timeout`, both with `Retry-After`. The test takes the workers itself
//! through the server's own queue, so nothing depends on how fast an estimate is.

use crate::helpers::{assert_problem, eventually, one_worker, spawn_app_with, valid_request};
use qrpose::api::problem::ErrorCode;
use qrpose::config::Settings;
use reqwest::{StatusCode, header};
use std::time::Duration;

#[tokio::test]
async fn a_full_queue_answers_503_overloaded_with_retry_after() {
    // Arrange: one worker, no waiting places, and the worker taken.
    let app = spawn_app_with(one_worker(0)).await;
    let slot = app
        .state
        .queue
        .try_admit()
        .expect("a free place")
        .start()
        .await
        .expect("a free worker");

    // Act
    let refused = app.post_corners(&valid_request()).await;

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

    drop(slot);
    let served = app.post_corners(&valid_request()).await;
    assert_eq!(
        served.status(),
        StatusCode::OK,
        "served once the worker is free"
    );
}

#[tokio::test]
async fn a_request_waiting_past_the_timeout_answers_503_timeout_and_leaves_the_queue() {
    // Arrange: one worker (taken) and one waiting place; a short timeout.
    let app = spawn_app_with(Settings {
        request_timeout: Duration::from_millis(200),
        ..one_worker(1)
    })
    .await;
    let slot = app
        .state
        .queue
        .try_admit()
        .expect("a free place")
        .start()
        .await
        .expect("a free worker");

    // Act
    let timed_out = app.post_corners(&valid_request()).await;

    // Assert
    assert_eq!(timed_out.headers()[header::RETRY_AFTER], "1");
    let problem = assert_problem(timed_out, 503, ErrorCode::Timeout).await;
    assert!(problem.detail.contains("200 ms"), "{}", problem.detail);
    let queue = app.state.queue.clone();
    eventually("the timed-out request leaves the queue", || {
        let waiting = queue.occupancy().waiting;
        async move { waiting == 0 }
    })
    .await;

    drop(slot);
    let served = app.post_corners(&valid_request()).await;
    assert_eq!(
        served.status(),
        StatusCode::OK,
        "served once the worker is free"
    );
}

#[tokio::test]
async fn queued_requests_are_served_in_turn_once_a_worker_frees() {
    // Arrange: one worker (taken) and two waiting places.
    let app = spawn_app_with(one_worker(2)).await;
    let slot = app
        .state
        .queue
        .try_admit()
        .expect("a free place")
        .start()
        .await
        .expect("a free worker");
    let send = || {
        let client = app.client.clone();
        let url = format!("{}/v1/pose/corners", app.address);
        tokio::spawn(async move { client.post(url).json(&valid_request()).send().await })
    };
    let first = send();
    let second = send();
    let queue = app.state.queue.clone();
    eventually("both requests wait", || {
        let waiting = queue.occupancy().waiting;
        async move { waiting == 2 }
    })
    .await;
    let readiness: serde_json::Value = app.get("/readyz").await.json().await.expect("JSON");
    assert_eq!(readiness["queue"]["waiting"], 2);
    assert_problem(
        app.post_corners(&valid_request()).await,
        503,
        ErrorCode::Overloaded,
    )
    .await;

    // Act
    drop(slot);

    // Assert
    for request in [first, second] {
        let response = request.await.expect("the task").expect("an answer");
        assert_eq!(response.status(), StatusCode::OK);
    }
}
