//! `GET /metrics`.

use crate::helpers::{spawn_app, valid_request};
use reqwest::{StatusCode, header};
use serde_json::json;

#[tokio::test]
async fn metrics_count_requests_latency_and_estimates() {
    // Arrange
    let app = spawn_app().await;
    let mut not_converging = valid_request();
    not_converging["solver"] = json!({"method": "paper", "max_iterations": 1});
    assert_eq!(app.post_corners(&valid_request()).await.status(), 200);
    assert_eq!(app.post_corners(&not_converging).await.status(), 200);
    assert_eq!(app.post_corners(&json!({})).await.status(), 422);
    assert_eq!(app.get("/no-such-route").await.status(), 404);

    // Act
    let response = app.get("/metrics").await;

    // Assert
    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(
        response.headers()[header::CONTENT_TYPE],
        "application/openmetrics-text; version=1.0.0; charset=utf-8"
    );
    let text = response.text().await.expect("text");
    for line in [
        r#"qrpose_http_requests_total{route="/v1/pose/corners",method="POST",status="200"} 2"#,
        r#"qrpose_http_requests_total{route="/v1/pose/corners",method="POST",status="422"} 1"#,
        r#"qrpose_http_requests_total{route="unmatched",method="GET",status="404"} 1"#,
        r#"qrpose_http_request_duration_seconds_count{route="/v1/pose/corners"} 3"#,
        r#"qrpose_estimator_iterations_count{method="paper"} 1"#,
        r#"qrpose_estimator_iterations_count{method="reprojection"} 1"#,
        r#"qrpose_estimator_not_converged_total{method="paper"} 1"#,
        "qrpose_estimation_queue_depth 0",
        "qrpose_estimations_running 0",
        "qrpose_estimation_rejections_total 0",
    ] {
        assert!(text.contains(line), "missing `{line}` in\n{text}");
    }
    assert!(text.ends_with("# EOF\n"), "OpenMetrics ends with # EOF");
}
