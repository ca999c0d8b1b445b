//! Who may call it (docs/security.md): every route of the OpenAPI document, and the stream,
//! against no token, an unknown token, a client without the route's scope and one with it;
//! the open routes; the WebSocket subprotocol; reloading the auth file; `/readyz`'s warning.

use crate::helpers::{
    PHOTO_QUERY, TestApp, assert_problem, blank_png, spawn_app_with, valid_request,
};
use qrpose::api::problem::ErrorCode;
use qrpose::config::auth::{Scope, entry_line, new_token};
use qrpose::config::{SecuritySettings, Settings};
use qrpose::http::auth::{Access, access_for};
use qrpose::http::openapi::{Served, openapi_json};
use reqwest::{Method, RequestBuilder, StatusCode, header};
use serde_json::Value;
use std::path::PathBuf;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;

const SITE: &str = "cameras:\n  front:\n    intrinsics: {fx_px: 1000, fy_px: 1000, cx_px: 639.5, cy_px: 359.5}\nmarkers:\n  default_size_mm: 50\n";

/// A directory of this test binary's own.
fn write(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("qrpose-auth-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a directory");
    let path = dir.join(name);
    let partial = path.with_extension("partial");
    std::fs::write(&partial, text).expect("written");
    std::fs::rename(&partial, &path).expect("renamed");
    path
}

/// For each scope, a client holding only it (`only-pose`) and one holding all the others
/// (`no-pose`), with their tokens.
struct Tokens {
    only: Vec<(Scope, String)>,
    without: Vec<(Scope, String)>,
}

impl Tokens {
    fn new() -> Self {
        Self {
            only: Scope::ALL.iter().map(|s| (*s, new_token())).collect(),
            without: Scope::ALL.iter().map(|s| (*s, new_token())).collect(),
        }
    }

    fn only(&self, scope: Scope) -> &str {
        &self
            .only
            .iter()
            .find(|(s, _)| *s == scope)
            .expect("a scope")
            .1
    }

    fn without(&self, scope: Scope) -> &str {
        &self
            .without
            .iter()
            .find(|(s, _)| *s == scope)
            .expect("a scope")
            .1
    }

    fn file(&self) -> String {
        let mut lines = vec!["clients:".to_owned()];
        for (scope, token) in &self.only {
            lines.push(entry_line(
                &format!("only-{scope}"),
                token,
                [*scope].into_iter().collect(),
            ));
        }
        for (scope, token) in &self.without {
            let others = Scope::ALL.into_iter().filter(|s| s != scope).collect();
            lines.push(entry_line(&format!("no-{scope}"), token, others));
        }
        lines.join("\n") + "\n"
    }
}

async fn app_with_auth(file_name: &str, tokens: &Tokens) -> (TestApp, PathBuf) {
    let auth_file = write(file_name, &tokens.file());
    let site = write(&format!("{file_name}.site.yaml"), SITE);
    let app = spawn_app_with(Settings {
        site: Some(site),
        security: SecuritySettings {
            auth_file: Some(auth_file.clone()),
            tls: None,
        },
        ..Settings::default()
    })
    .await;
    (app, auth_file)
}

/// A request that the route answers 2xx, for the routes that need a body or a query.
fn valid(app: &TestApp, method: &Method, path: &str) -> RequestBuilder {
    let url = format!("{}{path}", app.address);
    match (method.as_str(), path) {
        ("POST", "/v1/pose/corners") => app.client.post(url).json(&valid_request()),
        ("POST", "/v1/pose/image" | "/v1/pose/image/annotated") => app
            .client
            .post(format!("{url}?{PHOTO_QUERY}"))
            .header(header::CONTENT_TYPE, "image/png")
            .body(blank_png()),
        ("GET", "/v1/stream") => app.client.get(format!("{url}?{PHOTO_QUERY}")),
        _ => app.client.request(method.clone(), url),
    }
}

/// Every (method, path) of the served OpenAPI document, and the stream.
fn routes() -> Vec<(Method, String)> {
    let served = Served {
        site: true,
        zxing_cpp: false,
        auth: true,
    };
    let doc: Value = serde_json::from_str(&openapi_json(served).expect("renders")).expect("JSON");
    let mut routes = vec![(Method::GET, "/v1/stream".to_owned())];
    for (path, item) in doc["paths"].as_object().expect("paths") {
        for method in item.as_object().expect("a path item").keys() {
            if let Ok(method) = Method::from_bytes(method.to_uppercase().as_bytes()) {
                routes.push((method, path.clone()));
            }
        }
    }
    routes
}

fn challenge(response: &reqwest::Response) -> String {
    response
        .headers()
        .get(header::WWW_AUTHENTICATE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or_default()
        .to_owned()
}

#[tokio::test]
async fn every_route_answers_401_401_403_and_2xx_by_token_and_scope() {
    let tokens = Tokens::new();
    let (app, _) = app_with_auth("matrix.yaml", &tokens).await;
    let routes = routes();
    let protected = routes
        .iter()
        .filter(|(_, p)| matches!(access_for(p), Access::Scope(_)))
        .count();
    assert!(protected >= 6, "{routes:?}");
    for (method, path) in &routes {
        let what = format!("{method} {path}");
        let Access::Scope(scope) = access_for(path) else {
            let response = valid(&app, method, path).send().await.expect("answers");
            assert!(
                response.status().is_success(),
                "{what} is open: {}",
                response.status()
            );
            continue;
        };
        let none = valid(&app, method, path).send().await.expect("answers");
        assert_eq!(challenge(&none), "Bearer realm=\"qrpose\"", "{what}");
        assert_problem(none, 401, ErrorCode::Unauthorized).await;

        let unknown = valid(&app, method, path)
            .bearer_auth(new_token())
            .send()
            .await
            .expect("answers");
        assert!(
            challenge(&unknown).contains("error=\"invalid_token\""),
            "{what}"
        );
        assert_problem(unknown, 401, ErrorCode::Unauthorized).await;

        let wrong = valid(&app, method, path)
            .bearer_auth(tokens.without(scope))
            .send()
            .await
            .expect("answers");
        assert!(
            challenge(&wrong).contains(&format!("error=\"insufficient_scope\", scope=\"{scope}\"")),
            "{what}: {}",
            challenge(&wrong)
        );
        let problem = assert_problem(wrong, 403, ErrorCode::Forbidden).await;
        assert!(
            problem.detail.contains(&format!("no-{scope}")),
            "{}",
            problem.detail
        );

        let right = valid(&app, method, path)
            .bearer_auth(tokens.only(scope))
            .send()
            .await
            .expect("answers");
        let status = right.status();
        if path == "/v1/stream" {
            // A plain GET of the WebSocket route: past the token, refused for the upgrade.
            assert_problem(right, 426, ErrorCode::UpgradeRequired).await;
        } else if [
            "/v1/pose/corners",
            "/v1/pose/image",
            "/v1/pose/image/annotated",
            "/v1/site",
            "/v1/site/reload",
            "/metrics",
        ]
        .contains(&path.as_str())
        {
            assert!(status.is_success(), "{what} with `{scope}`: {status}");
        } else {
            // A route added later without a valid request here: past the token at least.
            assert!(
                ![401, 403].contains(&status.as_u16()),
                "{what} with `{scope}`: {status}"
            );
        }
    }
}

#[tokio::test]
async fn health_probes_the_page_and_the_documents_stay_open() {
    let tokens = Tokens::new();
    let (app, _) = app_with_auth("open.yaml", &tokens).await;
    for path in [
        "/healthz",
        "/readyz",
        "/",
        "/page/app.js",
        "/page/camera.js",
        "/page/calibrate.js",
        "/page/app.css",
        "/docs/",
        "/openapi.json",
        "/asyncapi.json",
    ] {
        let response = app.get(path).await;
        assert_eq!(response.status(), StatusCode::OK, "{path}");
    }
}

#[tokio::test]
async fn paths_that_dodge_the_rules_match_no_route() {
    let tokens = Tokens::new();
    let (app, _) = app_with_auth("dodge.yaml", &tokens).await;
    for path in [
        "/%6Detrics",
        "/Metrics",
        "//metrics",
        "/metrics/",
        "/v1/./site/reload",
        "/v1/site/../site/reload",
        "/v1/pose%2Fcorners",
        "/v1//pose/corners",
        "/v1/unknown",
    ] {
        for method in ["GET", "POST"] {
            let status = raw_status(&app, method, path).await;
            assert!(
                [401, 404, 405].contains(&status),
                "{method} {path}: {status}"
            );
        }
    }
}

/// The status of `METHOD PATH` sent as is (an HTTP client would normalise the path).
async fn raw_status(app: &TestApp, method: &str, path: &str) -> u16 {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let authority = app.address.trim_start_matches("http://");
    let mut socket = tokio::net::TcpStream::connect(authority)
        .await
        .expect("connects");
    let request = format!(
        "{method} {path} HTTP/1.1\r\nHost: {authority}\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
    );
    socket.write_all(request.as_bytes()).await.expect("written");
    let mut answer = Vec::new();
    socket.read_to_end(&mut answer).await.expect("an answer");
    let answer = String::from_utf8_lossy(&answer);
    answer
        .split_whitespace()
        .nth(1)
        .and_then(|code| code.parse().ok())
        .unwrap_or_else(|| panic!("{method} {path}: no status in {answer:?}"))
}

#[tokio::test]
async fn a_browser_websocket_carries_its_token_as_a_subprotocol() {
    let tokens = Tokens::new();
    let (app, _) = app_with_auth("ws.yaml", &tokens).await;
    let url = format!(
        "{}/v1/stream?fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50",
        app.address.replacen("http", "ws", 1)
    );
    let with = |protocols: String| {
        let mut request = url.clone().into_client_request().expect("a request");
        request.headers_mut().insert(
            header::SEC_WEBSOCKET_PROTOCOL,
            protocols.parse().expect("a header value"),
        );
        request
    };
    let allowed = format!("qrpose, bearer.{}", tokens.only(Scope::Pose));
    let (_socket, response) = tokio_tungstenite::connect_async(with(allowed))
        .await
        .expect("the upgrade");
    assert_eq!(response.headers()[header::SEC_WEBSOCKET_PROTOCOL], "qrpose");

    for (protocols, status) in [
        ("qrpose".to_owned(), 401),
        (format!("qrpose, bearer.{}", new_token()), 401),
        (
            format!("qrpose, bearer.{}", tokens.without(Scope::Pose)),
            403,
        ),
    ] {
        match tokio_tungstenite::connect_async(with(protocols.clone())).await {
            Err(tokio_tungstenite::tungstenite::Error::Http(response)) => {
                assert_eq!(response.status().as_u16(), status, "{protocols}");
            }
            other => panic!("{protocols}: {other:?}"),
        }
    }
    // The token never rides in the query string.
    let query = format!("{url}&access_token={}", tokens.only(Scope::Pose));
    match tokio_tungstenite::connect_async(query).await {
        Err(tokio_tungstenite::tungstenite::Error::Http(response)) => {
            assert_eq!(response.status().as_u16(), 401);
        }
        other => panic!("a token in the query string: {other:?}"),
    }
}

#[tokio::test]
async fn a_reload_swaps_the_clients_and_a_refused_file_keeps_the_old_ones() {
    let tokens = Tokens::new();
    let (app, file) = app_with_auth("reload.yaml", &tokens).await;
    let metrics_status = |token: String| {
        let request = app
            .client
            .get(format!("{}/metrics", app.address))
            .bearer_auth(token);
        async move { request.send().await.expect("answers").status().as_u16() }
    };
    let old = tokens.only(Scope::Metrics).to_owned();
    assert_eq!(metrics_status(old.clone()).await, 200);

    let newcomer = new_token();
    write(
        "reload.yaml",
        &format!(
            "clients:\n{}\n",
            entry_line(
                "newcomer",
                &newcomer,
                [Scope::Metrics].into_iter().collect()
            )
        ),
    );
    app.state.auth.reload().expect("a valid file");
    assert_eq!(metrics_status(newcomer.clone()).await, 200);
    assert_eq!(
        metrics_status(old).await,
        401,
        "the old file's clients are gone"
    );

    std::fs::write(&file, "clients:\n  - name: broken\n").expect("written");
    let refused = app.state.auth.reload().expect_err("a refused file");
    assert!(refused.to_string().contains("reload.yaml"), "{refused}");
    assert_eq!(
        metrics_status(newcomer.clone()).await,
        200,
        "the previous clients stay"
    );

    let text = app
        .client
        .get(format!("{}/metrics", app.address))
        .bearer_auth(&newcomer)
        .send()
        .await
        .expect("answers")
        .text()
        .await
        .expect("text");
    for line in [
        "qrpose_auth_reloads_total{outcome=\"ok\"} 1",
        "qrpose_auth_reloads_total{outcome=\"failed\"} 1",
        "qrpose_auth_clients 1",
        "qrpose_auth_requests_total{client=\"newcomer\",scope=\"metrics\",outcome=\"allowed\"}",
        "qrpose_auth_requests_total{client=\"-\",scope=\"metrics\",outcome=\"unauthorized\"} 1",
    ] {
        assert!(text.contains(line), "missing {line} in\n{text}");
    }
    assert!(!text.contains(&newcomer), "a token in the metrics");
}

#[tokio::test]
async fn readyz_warns_about_an_open_service_on_the_network() {
    let exposed = |auth_file: Option<PathBuf>| Settings {
        addr: "0.0.0.0:8080".parse().expect("an address"),
        security: SecuritySettings {
            auth_file,
            tls: None,
        },
        ..Settings::default()
    };
    let open = spawn_app_with(exposed(None)).await;
    let body: Value = open.get("/readyz").await.json().await.expect("JSON");
    let warning = body["warnings"][0].as_str().expect("a warning");
    assert!(warning.contains("without an auth file"), "{body}");

    let file = write("readyz.yaml", "clients: []\n");
    let guarded = spawn_app_with(exposed(Some(file))).await;
    let body: Value = guarded.get("/readyz").await.json().await.expect("JSON");
    assert!(body.get("warnings").is_none(), "{body}");

    let loopback = spawn_app_with(Settings::default()).await;
    let body: Value = loopback.get("/readyz").await.json().await.expect("JSON");
    assert!(body.get("warnings").is_none(), "{body}");
}

/// The served documents describe the running server: the bearer scheme and the scopes only
/// when it has an auth file.
#[tokio::test]
async fn the_documents_ask_for_a_token_only_when_the_server_has_an_auth_file() {
    let tokens = Tokens::new();
    let (guarded, _) = app_with_auth("documents.yaml", &tokens).await;
    let open = spawn_app_with(Settings::default()).await;
    for (app, auth) in [(&guarded, true), (&open, false)] {
        for path in ["/openapi.json", "/asyncapi.json"] {
            let document: Value = app.get(path).await.json().await.expect("JSON");
            let text = document.to_string();
            assert_eq!(
                text.contains("securitySchemes"),
                auth,
                "{path}, auth {auth}"
            );
            assert_eq!(text.contains("\"security\""), auth, "{path}, auth {auth}");
        }
    }
    let document: Value = guarded
        .get("/openapi.json")
        .await
        .json()
        .await
        .expect("JSON");
    assert_eq!(
        document["paths"]["/v1/pose/corners"]["post"]["security"],
        serde_json::json!([{"bearer": ["pose"]}])
    );
}
