//! `GET /v1/stream`: a WebSocket session of rendered video frames, answered in
//! order with each code's track and every live track; its refusals, limits and close codes.

use crate::helpers::{PATIENCE, TestApp, spawn_app_with};
use futures_util::{SinkExt, StreamExt};
use qrpose::api::problem::ErrorCode;
use qrpose::config::{Settings, StreamSettings};
use qrpose_sim::render::encode;
use qrpose_sim::render::sequence::{Sequence, builtin_sequence};
use reqwest::StatusCode;
use serde_json::{Value, json};
use std::io::Write;
use std::sync::LazyLock;
use std::time::Duration;
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::protocol::frame::coding::CloseCode;
use tokio_tungstenite::tungstenite::{Message, client::IntoClientRequest};
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream, connect_async};

type Socket = WebSocketStream<MaybeTlsStream<TcpStream>>;

const ASYNCAPI: &str = include_str!("../../openapi/asyncapi.json");

/// A validator of the committed AsyncAPI document's schema `name` (the document is the
/// root, so that every `$ref` into `#/components/schemas` resolves).
fn message_schema(name: &str) -> jsonschema::Validator {
    let mut root: Value = serde_json::from_str(ASYNCAPI).expect("JSON");
    root["$ref"] = json!(format!("#/components/schemas/{name}"));
    jsonschema::draft202012::new(&root).expect("a valid schema")
}

/// Asserts that `message` is valid by the committed document's schema `name`.
fn assert_valid(name: &str, message: &Value) {
    let validator = message_schema(name);
    let errors: Vec<String> = validator
        .iter_errors(message)
        .map(|e| format!("{} at {}", e, e.instance_path()))
        .collect();
    assert!(errors.is_empty(), "{name}: {errors:?}\n{message}");
}

/// The `still` video's first frames, JPEG, and their capture times (ms): four codes of 50 and
/// 80 mm at 0.4-1.5 m, the camera standing still.
static FRAMES: LazyLock<Vec<(Vec<u8>, f64)>> = LazyLock::new(|| {
    let spec = builtin_sequence("still").expect("a built-in video");
    let sequence = Sequence::new(spec).expect("a valid video");
    (0..6)
        .map(|k| {
            let frame = sequence.render_frame(k).expect("renders");
            let jpeg = encode(&frame.image, sequence.encoding()).expect("encodes");
            (jpeg, frame.truth.capture_time_ms)
        })
        .collect()
});

/// A site that sizes the `still` video's codes by their payloads.
static SITE: LazyLock<tempfile_path::Path> = LazyLock::new(|| {
    tempfile_path::write(
        "stream-site.yaml",
        "cameras:\n  cam:\n    intrinsics: {fx_px: 1000, fy_px: 1000, cx_px: 639.5, cy_px: 359.5}\n\
         markers:\n  default_size_mm: 50\n  sizes:\n    - {prefix: \"MID-\", size_mm: 80}\n\
         \x20   - {prefix: \"FAR-1500\", size_mm: 80}\n",
    )
});

/// Files for the tests, under the target directory.
mod tempfile_path {
    pub type Path = std::path::PathBuf;

    /// Writes `text` to a file named `name` of this test binary's own directory.
    pub fn write(name: &str, text: &str) -> Path {
        let dir = std::env::temp_dir().join(format!("qrpose-stream-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a directory");
        let path = dir.join(name);
        let mut file = std::fs::File::create(&path).expect("a file");
        super::Write::write_all(&mut file, text.as_bytes()).expect("written");
        path
    }
}

/// The service with a site and `stream`'s limits.
async fn app_with(stream: StreamSettings, body_limit_bytes: Option<usize>) -> TestApp {
    let defaults = Settings::default();
    spawn_app_with(Settings {
        site: Some(SITE.clone()),
        stream,
        body_limit_bytes: body_limit_bytes.unwrap_or(defaults.body_limit_bytes),
        ..defaults
    })
    .await
}

/// The `ws://` address of the stream with `query`.
fn stream_url(app: &TestApp, query: &str) -> String {
    format!(
        "{}/v1/stream?{query}",
        app.address.replacen("http", "ws", 1)
    )
}

async fn connect(app: &TestApp, query: &str) -> Socket {
    let request = stream_url(app, query)
        .into_client_request()
        .expect("a request");
    connect_async(request).await.expect("the upgrade").0
}

/// The next text message as JSON (pings skipped).
async fn next_json(socket: &mut Socket) -> Value {
    loop {
        let message = tokio::time::timeout(PATIENCE, socket.next())
            .await
            .expect("an answer in time")
            .expect("the session is open")
            .expect("a message");
        match message {
            Message::Text(text) => return serde_json::from_str(&text).expect("JSON"),
            Message::Ping(_) | Message::Pong(_) => {}
            other => panic!("expected an answer, got {other:?}"),
        }
    }
}

/// The close code the session ends with.
async fn close_code(socket: &mut Socket) -> CloseCode {
    loop {
        let message = tokio::time::timeout(PATIENCE, socket.next())
            .await
            .expect("closed in time");
        match message {
            Some(Ok(Message::Close(Some(frame)))) => return frame.code,
            Some(Ok(Message::Close(None))) => panic!("a close without a code"),
            Some(Ok(_)) => {}
            other => panic!("expected a close frame, got {other:?}"),
        }
    }
}

const QUERY: &str = "camera_id=cam";

#[tokio::test]
async fn every_frame_is_answered_in_order_with_stable_tracks() {
    // Arrange
    let app = app_with(StreamSettings::default(), None).await;
    let mut socket = connect(&app, QUERY).await;

    // Act
    let mut answers = Vec::new();
    for (k, (jpeg, t_ms)) in FRAMES.iter().enumerate() {
        let meta = json!({"frame_id": format!("f{k}"), "capture_time_ms": t_ms});
        socket
            .send(Message::text(meta.to_string()))
            .await
            .expect("sent");
        socket
            .send(Message::binary(jpeg.clone()))
            .await
            .expect("sent");
        answers.push(next_json(&mut socket).await);
    }
    socket.close(None).await.expect("closed");

    // Assert
    let mut ids_of_first: Vec<(String, String)> = Vec::new();
    for (k, answer) in answers.iter().enumerate() {
        assert_eq!(answer["frame"]["index"], k, "{answer}");
        assert_eq!(answer["frame"]["id"], format!("f{k}"));
        assert_eq!(answer["frame"]["dropped_before"], 0);
        let markers = answer["markers"].as_array().expect("markers");
        assert!(markers.len() >= 3, "frame {k}: {} codes", markers.len());
        let pairs: Vec<(String, String)> = markers
            .iter()
            .filter_map(|m| {
                Some((
                    m["payload"].as_str()?.to_owned(),
                    m["track_id"].as_str()?.to_owned(),
                ))
            })
            .collect();
        if k == 0 {
            ids_of_first = pairs.clone();
            assert!(
                answer["tracks"]
                    .as_array()
                    .expect("tracks")
                    .iter()
                    .all(|t| t["status"] == "new")
            );
        } else {
            for pair in &pairs {
                assert!(
                    ids_of_first.contains(pair),
                    "frame {k}: {pair:?} not in {ids_of_first:?}"
                );
            }
        }
        for track in answer["tracks"].as_array().expect("tracks") {
            assert!(track["pose"]["covariance"]["matrix"].is_array(), "{track}");
            assert!(
                track["pose"]["velocity_mm_per_s"]["x"].is_number(),
                "{track}"
            );
        }
    }
    for answer in &answers {
        assert_valid("StreamAnswer", answer);
    }
    let last = answers.last().expect("answers");
    let tracking = last["tracks"]
        .as_array()
        .expect("tracks")
        .iter()
        .filter(|t| t["status"] == "tracking")
        .count();
    assert!(tracking >= 3, "{last}");
    let metrics = app.get("/metrics").await.text().await.expect("text");
    assert!(
        metrics.contains("qrpose_stream_frames_answered_total 6"),
        "{metrics}"
    );
}

#[tokio::test]
async fn a_bad_parameter_or_a_plain_get_is_refused_before_the_upgrade() {
    // Arrange
    let app = app_with(StreamSettings::default(), None).await;
    let cases = [
        (
            "camera_id=cam&fx_px=-5",
            StatusCode::UNPROCESSABLE_ENTITY,
            ErrorCode::IncompleteCamera,
            None,
        ),
        (
            "fx_px=1000&fy_px=1000&cx_px=1&cy_px=1&marker_size_mm=-1",
            StatusCode::UNPROCESSABLE_ENTITY,
            ErrorCode::InvalidMarkerSize,
            Some("marker_size_mm"),
        ),
        (
            "camera_id=cam&coast_ms=-3",
            StatusCode::UNPROCESSABLE_ENTITY,
            ErrorCode::InvalidTrackerParameter,
            Some("coast_ms"),
        ),
        (
            "camera_id=cam&coast=3",
            StatusCode::UNPROCESSABLE_ENTITY,
            ErrorCode::UnknownField,
            Some("coast"),
        ),
        (
            "camera_id=cam&max_detect_ms=soon",
            StatusCode::BAD_REQUEST,
            ErrorCode::MalformedQuery,
            Some("max_detect_ms"),
        ),
    ];
    for (query, status, code, field) in cases {
        // Act
        let refused = connect_async(stream_url(&app, query))
            .await
            .expect_err("refused");

        // Assert
        let tokio_tungstenite::tungstenite::Error::Http(response) = refused else {
            panic!("{query}: {refused:?}");
        };
        assert_eq!(response.status().as_u16(), status.as_u16(), "{query}");
        let body: Value = serde_json::from_slice(response.body().as_deref().unwrap_or_default())
            .expect("a problem");
        assert_eq!(
            body["code"],
            serde_json::to_value(code).expect("a code"),
            "{query}: {body}"
        );
        if let Some(field) = field {
            assert_eq!(body["field"], field, "{query}");
        }
    }
    let plain = app.get(&format!("/v1/stream?{QUERY}")).await;
    assert_eq!(plain.status(), StatusCode::UPGRADE_REQUIRED);
    let problem: Value = plain.json().await.expect("a problem");
    assert_eq!(problem["code"], "upgrade_required");
}

#[tokio::test]
async fn a_bad_frame_or_message_is_answered_by_its_problem_and_the_session_goes_on() {
    // Arrange
    let app = app_with(StreamSettings::default(), None).await;
    let mut socket = connect(&app, QUERY).await;

    // Act
    socket
        .send(Message::binary(b"not an image".to_vec()))
        .await
        .expect("sent");
    let not_an_image = next_json(&mut socket).await;
    socket
        .send(Message::text("{\"frame_id\": 1, \"bogus\": 2}"))
        .await
        .expect("sent");
    let bad_meta = next_json(&mut socket).await;
    socket
        .send(Message::binary(FRAMES[0].0.clone()))
        .await
        .expect("sent");
    let good = next_json(&mut socket).await;

    // Assert
    assert_valid("FrameProblem", &not_an_image);
    assert_valid("FrameProblem", &bad_meta);
    assert_valid("StreamAnswer", &good);
    assert_eq!(not_an_image["code"], "undecodable_image", "{not_an_image}");
    assert_eq!(not_an_image["frame"]["index"], 0);
    assert_eq!(bad_meta["code"], "unknown_field", "{bad_meta}");
    assert_eq!(bad_meta["field"], "/bogus");
    assert_eq!(good["frame"]["index"], 1, "{good}");
    assert!(!good["markers"].as_array().expect("markers").is_empty());
}

#[tokio::test]
async fn limits_close_the_session_with_their_codes() {
    // Arrange: one session at a time, a short idle time, small messages.
    let stream = StreamSettings {
        max_sessions: 1,
        idle_timeout: Duration::from_millis(300),
        ..StreamSettings::default()
    };
    let app = app_with(stream, Some(64 * 1024)).await;
    let mut first = connect(&app, QUERY).await;

    // Act / Assert: a second session is closed with 1013 (try again later).
    let mut second = connect(&app, QUERY).await;
    assert_eq!(u16::from(close_code(&mut second).await), 1013);
    // The first, silent, is closed with 1008 when its idle time is over.
    assert_eq!(close_code(&mut first).await, CloseCode::Policy);
    // A message over the size limit: 1008.
    let mut third = connect(&app, QUERY).await;
    let _ = third.send(Message::binary(vec![0u8; 100 * 1024])).await;
    assert_eq!(close_code(&mut third).await, CloseCode::Policy);
}

#[tokio::test]
async fn a_client_faster_than_the_service_gets_the_newest_frames_and_the_drop_count() {
    // Arrange: two frames in flight.
    let stream = StreamSettings {
        frames_in_flight: 2,
        ..StreamSettings::default()
    };
    let app = app_with(stream, None).await;
    let mut socket = connect(&app, QUERY).await;
    let sent = 12;

    // Act: every frame at once.
    for k in 0..sent {
        let jpeg = FRAMES[k % FRAMES.len()].0.clone();
        socket.send(Message::binary(jpeg)).await.expect("sent");
    }
    let mut answered = Vec::new();
    let mut dropped = 0;
    while answered.len() + dropped < sent {
        let answer = next_json(&mut socket).await;
        dropped += usize::try_from(answer["frame"]["dropped_before"].as_u64().expect("a count"))
            .expect("small");
        answered.push(answer["frame"]["index"].as_u64().expect("an index"));
    }

    // Assert
    assert!(
        dropped > 0,
        "the client sent faster than frames are answered"
    );
    assert!(
        answered.windows(2).all(|w| w[0] < w[1]),
        "in order: {answered:?}"
    );
    assert_eq!(
        answered.last(),
        Some(&u64::try_from(sent - 1).expect("small")),
        "the newest is answered"
    );
    let metrics = app.get("/metrics").await.text().await.expect("text");
    assert!(
        metrics.contains(&format!("qrpose_stream_frames_dropped_total {dropped}")),
        "{metrics}"
    );
}

#[tokio::test]
async fn a_shutdown_closes_open_sessions_with_1001() {
    // Arrange
    let app = app_with(StreamSettings::default(), None).await;
    let mut socket = connect(&app, QUERY).await;
    socket
        .send(Message::binary(FRAMES[0].0.clone()))
        .await
        .expect("sent");
    let _ = next_json(&mut socket).await;

    // Act
    app.trigger_shutdown();

    // Assert
    assert_eq!(close_code(&mut socket).await, CloseCode::Away);
}
