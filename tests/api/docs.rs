//! `GET /docs`: the Swagger UI, served from the binary.

use crate::helpers::spawn_app;
use reqwest::{StatusCode, header};

#[tokio::test]
async fn docs_serves_the_swagger_ui_reading_our_document() {
    // Arrange
    let app = spawn_app().await;

    // Act
    let page = app.get("/docs").await;
    let initializer = app.get("/docs/swagger-initializer.js").await;
    let script = app.get("/docs/swagger-ui-bundle.js").await;

    // Assert
    assert_eq!(
        page.status(),
        StatusCode::OK,
        "after the redirect to /docs/"
    );
    assert_eq!(page.url().path(), "/docs/");
    assert!(
        page.headers()[header::CONTENT_TYPE]
            .to_str()
            .expect("ASCII")
            .starts_with("text/html")
    );
    let html = page.text().await.expect("text");
    assert!(html.contains("swagger-ui"), "{html}");
    let config = initializer.text().await.expect("text");
    assert!(config.contains("/openapi.json"), "{config}");
    assert_eq!(script.status(), StatusCode::OK);
}
