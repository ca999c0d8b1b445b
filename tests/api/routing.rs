//! Service-wide behaviour: unknown routes, wrong methods, request ids.

use crate::helpers::{assert_problem, spawn_app, valid_request};
use qrpose::api::problem::ErrorCode;
use reqwest::{Method, header};

#[tokio::test]
async fn unknown_routes_get_404_not_found() {
    // Arrange
    let app = spawn_app().await;

    // (`/` is the setup page.)
    for path in [
        "/index.html",
        "/v1/pose",
        "/v1/pose/corners/extra",
        "/v2/pose/corners",
        "/healthz/",
    ] {
        // Act
        let response = app.get(path).await;

        // Assert
        let problem = assert_problem(response, 404, ErrorCode::NotFound).await;
        assert!(problem.detail.contains(path), "{path}: {}", problem.detail);
    }
}

#[tokio::test]
async fn known_routes_with_another_method_get_405_with_allow() {
    // Arrange
    let app = spawn_app().await;
    let cases = [
        (Method::GET, "/v1/pose/corners", "POST"),
        (Method::PUT, "/v1/pose/corners", "POST"),
        (Method::GET, "/v1/pose/image", "POST"),
        (Method::DELETE, "/healthz", "GET,HEAD"),
        (Method::POST, "/metrics", "GET,HEAD"),
        (Method::POST, "/openapi.json", "GET,HEAD"),
    ];

    for (method, path, allow) in cases {
        // Act
        let response = app.request(method.clone(), path).await;

        // Assert
        assert_eq!(response.headers()[header::ALLOW], allow, "{method} {path}");
        assert_problem(response, 405, ErrorCode::MethodNotAllowed).await;
    }
}

#[tokio::test]
async fn every_response_carries_a_fresh_request_id() {
    // Arrange
    let app = spawn_app().await;

    // Act
    let ok = app.post_corners(&valid_request()).await;
    let not_found = app.get("/nope").await;

    // Assert
    let id = |r: &reqwest::Response| {
        r.headers()["x-request-id"]
            .to_str()
            .expect("ASCII")
            .to_owned()
    };
    let (a, b) = (id(&ok), id(&not_found));
    assert_eq!(a.len(), 36, "a UUID: {a}");
    assert_ne!(a, b);
}

#[tokio::test]
async fn a_clients_request_id_is_echoed_unless_it_is_unsafe() {
    // Arrange
    let app = spawn_app().await;
    let send = |id: &'static str| {
        app.client
            .get(format!("{}/healthz", app.address))
            .header("x-request-id", id)
            .send()
    };

    // Act
    let kept = send("robot-7:req.42").await.expect("an answer");
    let replaced = send("two words").await.expect("an answer");

    // Assert
    assert_eq!(kept.headers()["x-request-id"], "robot-7:req.42");
    let fresh = replaced.headers()["x-request-id"].to_str().expect("ASCII");
    assert_ne!(fresh, "two words");
    assert_eq!(fresh.len(), 36, "a UUID: {fresh}");
}
