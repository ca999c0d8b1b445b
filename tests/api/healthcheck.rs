//! `qrpose healthcheck`: exit 0 when `/healthz` answers 200, non-zero otherwise; over
//! HTTPS with the service's own certificate or a CA file, with a client certificate for
//! mutual TLS, and with a bearer token from the environment or a file.

use crate::helpers::{spawn_app, spawn_app_with};
use crate::tls::{Pki, authority, dir, tls_app, write_files};
use qrpose::config::auth::{Scope, entry_line, new_token};
use qrpose::config::{SecuritySettings, Settings};
use std::process::Output;

/// The variables `healthcheck` reads, none of them inherited from the test's environment.
const VARIABLES: [&str; 7] = [
    "QRPOSE_HEALTHCHECK_URL",
    "QRPOSE_ADDR",
    "QRPOSE_TLS_CERT",
    "QRPOSE_HEALTHCHECK_CA_FILE",
    "QRPOSE_HEALTHCHECK_CLIENT_CERT",
    "QRPOSE_HEALTHCHECK_CLIENT_KEY",
    "QRPOSE_HEALTHCHECK_TOKEN_FILE",
];

async fn healthcheck_with(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut command = tokio::process::Command::new(env!("CARGO_BIN_EXE_qrpose"));
    command.arg("healthcheck").args(args);
    for name in VARIABLES.iter().chain(&["QRPOSE_HEALTHCHECK_TOKEN"]) {
        command.env_remove(name);
    }
    command
        .envs(env.iter().copied())
        .output()
        .await
        .expect("qrpose runs")
}

async fn healthcheck(args: &[&str]) -> Output {
    healthcheck_with(args, &[]).await
}

fn path(p: &std::path::Path) -> &str {
    p.to_str().expect("a UTF-8 path")
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
    let https = healthcheck(&["--url", &format!("https://127.0.0.1:{port}/healthz")]).await;

    // Assert
    assert_eq!(refused.status.code(), Some(1), "{refused:?}");
    assert_eq!(https.status.code(), Some(1), "{https:?}");
    let stderr = String::from_utf8_lossy(&https.stderr);
    assert!(stderr.contains("--ca-file"), "nothing to trust: {stderr}");
}

#[tokio::test]
async fn checks_https_against_the_services_own_certificate_or_a_ca_file() {
    // Arrange: a certificate for `localhost` only.
    let pki = Pki::new("healthcheck");
    let dir = dir("healthcheck");
    let files = write_files(&dir, &pki.leaf(&["localhost"]), None);
    let app = tls_app(files.clone(), None).await;
    let addr = authority(&app);
    let port = addr.rsplit(':').next().expect("a port");
    let ca = dir.join("ca.pem");
    std::fs::write(&ca, pki.ca_pem()).expect("written");
    let other = dir.join("other.pem");
    std::fs::write(&other, pki.leaf(&["localhost"]).cert_pem).expect("written");

    // Act
    // The container's way: QRPOSE_ADDR and QRPOSE_TLS_CERT, as `serve` reads them.
    let pinned = healthcheck_with(
        &[],
        &[
            ("QRPOSE_ADDR", &addr),
            ("QRPOSE_TLS_CERT", path(&files.cert)),
        ],
    )
    .await;
    let not_pinned = healthcheck(&["--addr", &addr, "--tls-cert", path(&other)]).await;
    let by_ca = healthcheck(&[
        "--url",
        &format!("https://localhost:{port}/healthz"),
        "--ca-file",
        path(&ca),
    ])
    .await;
    let wrong_name = healthcheck(&["--addr", &addr, "--ca-file", path(&ca)]).await;
    let named = healthcheck(&[
        "--addr",
        &addr,
        "--ca-file",
        path(&ca),
        "--server-name",
        "localhost",
    ])
    .await;
    let plain = healthcheck(&["--url", &format!("http://{addr}/healthz")]).await;

    // Assert
    assert!(pinned.status.success(), "{pinned:?}");
    assert_eq!(not_pinned.status.code(), Some(1), "{not_pinned:?}");
    let stderr = String::from_utf8_lossy(&not_pinned.stderr);
    assert!(stderr.contains("another certificate"), "{stderr}");
    assert!(by_ca.status.success(), "{by_ca:?}");
    assert_eq!(
        wrong_name.status.code(),
        Some(1),
        "127.0.0.1 is not in the certificate: {wrong_name:?}"
    );
    assert!(named.status.success(), "{named:?}");
    assert_eq!(plain.status.code(), Some(1), "{plain:?}");
    let stderr = String::from_utf8_lossy(&plain.stderr);
    assert!(
        stderr.contains("400"),
        "plain HTTP refused with 400: {stderr}"
    );
}

#[tokio::test]
async fn shows_a_client_certificate_to_a_service_with_mutual_tls() {
    // Arrange
    let server_pki = Pki::new("healthcheck-mtls");
    let client_pki = Pki::new("healthcheck-mtls-clients");
    let dir = dir("healthcheck-mtls");
    let files = write_files(&dir, &server_pki.leaf(&["localhost"]), Some(&client_pki));
    let app = tls_app(files.clone(), None).await;
    let addr = authority(&app);
    let probe = client_pki.leaf(&["probe"]);
    let (probe_cert, probe_key) = (dir.join("probe.pem"), dir.join("probe.key"));
    std::fs::write(&probe_cert, &probe.cert_pem).expect("written");
    std::fs::write(&probe_key, &probe.key_pem).expect("written");

    // Act
    let pinned = ["--addr", addr.as_str(), "--tls-cert", path(&files.cert)];
    let without = healthcheck(&pinned).await;
    let with = healthcheck_with(
        &pinned,
        &[
            ("QRPOSE_HEALTHCHECK_CLIENT_CERT", path(&probe_cert)),
            ("QRPOSE_HEALTHCHECK_CLIENT_KEY", path(&probe_key)),
        ],
    )
    .await;

    // Assert
    assert_eq!(without.status.code(), Some(1), "{without:?}");
    assert!(with.status.success(), "{with:?}");
}

#[tokio::test]
async fn sends_a_bearer_token_from_the_environment_or_a_file() {
    // Arrange: a client allowed to read the metrics.
    let token = new_token();
    let dir = dir("healthcheck-token");
    let auth_file = dir.join("auth.yaml");
    let entry = entry_line("probe", &token, [Scope::Metrics].into_iter().collect());
    std::fs::write(&auth_file, format!("clients:\n{entry}\n")).expect("written");
    let token_file = dir.join("token");
    std::fs::write(&token_file, format!("{token}\n")).expect("written");
    let app = spawn_app_with(Settings {
        security: SecuritySettings {
            auth_file: Some(auth_file),
            tls: None,
        },
        ..Settings::default()
    })
    .await;
    let metrics = format!("{}/metrics", app.address);
    let healthz = format!("{}/healthz", app.address);

    // Act
    let open = healthcheck(&["--url", &healthz]).await;
    let without = healthcheck(&["--url", &metrics]).await;
    let by_env = healthcheck_with(
        &["--url", &metrics],
        &[("QRPOSE_HEALTHCHECK_TOKEN", &token)],
    )
    .await;
    let by_file = healthcheck(&["--url", &metrics, "--token-file", path(&token_file)]).await;
    let smuggled = healthcheck_with(
        &["--url", &metrics],
        &[("QRPOSE_HEALTHCHECK_TOKEN", &format!("{token}\r\nX-Evil: 1"))],
    )
    .await;

    // Assert
    assert!(open.status.success(), "/healthz needs no token: {open:?}");
    assert_eq!(without.status.code(), Some(1), "{without:?}");
    assert!(
        String::from_utf8_lossy(&without.stderr).contains("401"),
        "{without:?}"
    );
    assert!(by_env.status.success(), "{by_env:?}");
    assert!(by_file.status.success(), "{by_file:?}");
    assert_eq!(smuggled.status.code(), Some(1), "{smuggled:?}");
}

/// Over TLS with the service's own certificate pinned, a token reaches a protected URL: it
/// goes out after a tokenless request on a connection whose certificate was checked; with
/// another certificate pinned nothing is answered 200.
#[tokio::test]
async fn a_token_reaches_a_protected_url_over_a_pinned_certificate() {
    // Arrange: TLS and an auth file with a client allowed to read the metrics.
    let pki = Pki::new("healthcheck-pinned-token");
    let dir = dir("healthcheck-pinned-token");
    let files = write_files(&dir, &pki.leaf(&["localhost"]), None);
    let other = dir.join("other.pem");
    std::fs::write(&other, pki.leaf(&["localhost"]).cert_pem).expect("written");
    let token = new_token();
    let auth_file = dir.join("auth.yaml");
    let entry = entry_line("probe", &token, [Scope::Metrics].into_iter().collect());
    std::fs::write(&auth_file, format!("clients:\n{entry}\n")).expect("written");
    let app = spawn_app_with(Settings {
        security: SecuritySettings {
            auth_file: Some(auth_file),
            tls: Some(files.clone()),
        },
        ..Settings::default()
    })
    .await;
    let metrics = format!("https://{}/metrics", authority(&app));
    let token_env = [("QRPOSE_HEALTHCHECK_TOKEN", token.as_str())];

    // Act
    let pinned = ["--url", metrics.as_str(), "--tls-cert", path(&files.cert)];
    let with_token = healthcheck_with(&pinned, &token_env).await;
    let without = healthcheck(&pinned).await;
    let wrong = ["--url", metrics.as_str(), "--tls-cert", path(&other)];
    let wrong_pin = healthcheck_with(&wrong, &token_env).await;

    // Assert
    assert!(with_token.status.success(), "{with_token:?}");
    assert_eq!(without.status.code(), Some(1), "{without:?}");
    assert!(String::from_utf8_lossy(&without.stderr).contains("401"));
    assert_eq!(wrong_pin.status.code(), Some(1), "{wrong_pin:?}");
    let stderr = String::from_utf8_lossy(&wrong_pin.stderr);
    assert!(stderr.contains("another certificate"), "{stderr}");
}
