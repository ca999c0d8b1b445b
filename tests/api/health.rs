//! `GET /healthz` and `GET /readyz`.

use crate::helpers::spawn_app;
use reqwest::{StatusCode, header};
use serde_json::Value;

#[tokio::test]
async fn healthz_answers_ok_with_the_version() {
    // Arrange
    let app = spawn_app().await;

    // Act
    let response = app.healthz().await;

    // Assert
    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(response.headers()[header::CONTENT_TYPE], "application/json");
    let body: Value = response.json().await.expect("JSON");
    assert_eq!(body["status"], "ok");
    assert_eq!(body["version"], env!("CARGO_PKG_VERSION"));
}

#[tokio::test]
async fn readyz_reports_the_queue_while_ready() {
    // Arrange
    let app = spawn_app().await;
    let settings = &app.state.settings;
    let capacity = settings.max_concurrent_estimations.get() + settings.queue_length;

    // Act
    let response = app.get("/readyz").await;

    // Assert
    assert_eq!(response.status(), StatusCode::OK);
    let body: Value = response.json().await.expect("JSON");
    assert_eq!(body["status"], "ready");
    assert_eq!(body["queue"]["running"], 0);
    assert_eq!(body["queue"]["waiting"], 0);
    assert_eq!(body["queue"]["capacity"], capacity);
}

#[tokio::test]
async fn head_requests_are_answered_like_get_without_a_body() {
    // Arrange
    let app = spawn_app().await;

    // Act
    let response = app.request(reqwest::Method::HEAD, "/healthz").await;

    // Assert
    assert_eq!(response.status(), StatusCode::OK);
    assert!(response.bytes().await.expect("a body").is_empty());
}
