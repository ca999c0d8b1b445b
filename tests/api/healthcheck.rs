//! `qrpose healthcheck`: exit 0 when `/healthz` answers 200, non-zero otherwise.

use crate::helpers::spawn_app;
use std::process::Output;

async fn healthcheck(args: &[&str]) -> Output {
    tokio::process::Command::new(env!("CARGO_BIN_EXE_qrpose"))
        .arg("healthcheck")
        .args(args)
        .env_remove("QRPOSE_HEALTHCHECK_URL")
        .env_remove("QRPOSE_ADDR")
        .output()
        .await
        .expect("qrpose runs")
}

#[tokio::test]
async fn exits_0_when_the_service_is_healthy() {
    // Arrange
    let app = spawn_app().await;

    // Act
    let by_url = healthcheck(&["--url", &format!("{}/healthz", app.address)]).await;
    let addr = app.address.trim_start_matches("http://");
    let by_addr = healthcheck(&["--addr", addr]).await;

    // Assert
    assert!(by_url.status.success(), "{by_url:?}");
    assert!(by_addr.status.success(), "{by_addr:?}");
}

#[tokio::test]
async fn exits_non_zero_when_the_endpoint_does_not_answer_200() {
    // Arrange
    let app = spawn_app().await;

    // Act
    let not_found = healthcheck(&["--url", &format!("{}/nope", app.address)]).await;

    // Assert
    assert_eq!(not_found.status.code(), Some(1), "{not_found:?}");
    let stderr = String::from_utf8_lossy(&not_found.stderr);
    assert!(stderr.contains("404"), "{stderr}");
}

#[tokio::test]
async fn exits_non_zero_when_nothing_listens() {
    // Arrange: a port that was free a moment ago.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .expect("a free port")
        .local_addr()
        .expect("an address")
        .port();

    // Act
    let refused = healthcheck(&["--url", &format!("http://127.0.0.1:{port}/healthz")]).await;
    let https = healthcheck(&["--url", "https://127.0.0.1/healthz"]).await;

    // Assert
    assert_eq!(refused.status.code(), Some(1), "{refused:?}");
    assert_eq!(https.status.code(), Some(1), "{https:?}");
}
