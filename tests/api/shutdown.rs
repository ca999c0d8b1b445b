//! Graceful shutdown: stop accepting, finish in-flight requests, at most for the grace
//! period. (SIGTERM and SIGINT on the real binary are exercised by `tests/service/curl_suite.rs`.)

use crate::helpers::{eventually, occupy_worker, one_worker, queue_reaches, spawn_app_with};
use qrpose::config::Settings;
use reqwest::StatusCode;
use std::time::Duration;

#[tokio::test]
async fn in_flight_requests_finish_after_shutdown_begins() {
    // Arrange: a request waiting for the only worker, which the test holds.
    let app = spawn_app_with(one_worker(1)).await;
    let gate = occupy_worker(&app).await;
    let in_flight = app.post_queued_in_background();
    queue_reaches(&app, 1, 1).await;

    // Act
    app.trigger_shutdown();
    let lifecycle = app.state.lifecycle.clone();
    eventually("the service drains", || {
        let draining = lifecycle.is_draining();
        async move { draining }
    })
    .await;
    gate.release().await;

    // Assert
    let response = in_flight.await.expect("the task").expect("an answer");
    assert_eq!(response.status(), StatusCode::OK);
    let address = app.address.clone();
    app.stopped().await.expect("a clean stop");
    crate::support::tls_provider();
    let refused = reqwest::Client::builder()
        .no_proxy()
        .build()
        .expect("a client")
        .get(format!("{address}/healthz"))
        .send()
        .await;
    assert!(refused.is_err(), "no new connections after the stop");
}

#[tokio::test]
async fn the_grace_period_bounds_the_wait_for_stuck_requests() {
    // Arrange: a request that cannot finish (the test holds the only worker), a short grace.
    let app = spawn_app_with(Settings {
        shutdown_grace: Duration::from_millis(100),
        ..one_worker(1)
    })
    .await;
    let gate = occupy_worker(&app).await;
    let stuck = app.post_queued_in_background();
    queue_reaches(&app, 1, 1).await;

    // Act
    app.trigger_shutdown();

    // Assert: the server stops although the request is still stuck.
    app.stopped().await.expect("a clean stop");
    assert!(!stuck.is_finished(), "the stuck request was still waiting");
    stuck.abort();
    drop(gate);
}
