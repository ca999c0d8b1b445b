//! `POST /v1/pose/corners`: a catalogue of bad requests. Each gets its 4xx problem+json with
//! the right code (and field, where one is at fault), and the server stays up.

use crate::helpers::{assert_problem, spawn_app, spawn_app_with, valid_request};
use qrpose::api::problem::ErrorCode::{self, *};
use qrpose::api::problem::Problem;
use qrpose::config::Settings;
use reqwest::header;
use serde_json::{Value, json};

/// One bad request: its body, content type, and the expected answer.
struct Case {
    name: &'static str,
    body: Vec<u8>,
    content_type: Option<&'static str>,
    status: u16,
    code: ErrorCode,
    field: Option<&'static str>,
}

fn json_case(
    name: &'static str,
    body: Value,
    code: ErrorCode,
    field: Option<&'static str>,
) -> Case {
    Case {
        name,
        body: serde_json::to_vec(&body).expect("serialisable"),
        content_type: Some("application/json"),
        status: code.status(),
        code,
        field,
    }
}

fn raw_case(name: &'static str, body: impl Into<Vec<u8>>, code: ErrorCode) -> Case {
    Case {
        name,
        body: body.into(),
        content_type: Some("application/json"),
        status: code.status(),
        code,
        field: None,
    }
}

/// The valid request with the value at `pointer` replaced (or removed, for `Null`).
fn with(pointer: &str, value: Value) -> Value {
    let mut body = valid_request();
    let (parent, key) = pointer.rsplit_once('/').expect("a pointer with a parent");
    let target = if parent.is_empty() {
        &mut body
    } else {
        body.pointer_mut(parent).expect("the parent exists")
    };
    match (target, value) {
        (Value::Object(map), Value::Null) => {
            map.remove(key);
        }
        (Value::Object(map), v) => {
            map.insert(key.to_owned(), v);
        }
        (Value::Array(items), v) => {
            items[key.parse::<usize>().expect("an index")] = v;
        }
        _ => panic!("cannot set {pointer}"),
    }
    body
}

fn valid_text() -> String {
    serde_json::to_string(&valid_request()).expect("serialisable")
}

fn catalogue() -> Vec<Case> {
    let deeply_nested = format!(
        r#"{{"corners_px": {}{}}}"#,
        "[".repeat(100_000),
        "]".repeat(100_000)
    );
    let deeply_nested_objects = format!(
        r#"{{"camera": {}1{}}}"#,
        r#"{"camera": "#.repeat(100_000),
        "}".repeat(100_000)
    );
    let nan_corner = valid_text().replacen("589.2", "NaN", 1);
    let infinite_corner = valid_text().replacen("589.2", "1e999", 1);
    let single_quotes = valid_text().replace('"', "'");
    vec![
        raw_case("unclosed object", "{", MalformedJson),
        raw_case("empty body", "", MalformedJson),
        raw_case("whitespace only", "  \n ", MalformedJson),
        // Every field is typed, so nesting fails at the first level too deep for its type.
        Case {
            field: Some("/corners_px/0/0"),
            ..raw_case("deeply nested arrays", deeply_nested, InvalidType)
        },
        Case {
            field: Some("/camera/camera"),
            ..raw_case("deeply nested objects", deeply_nested_objects, UnknownField)
        },
        raw_case("NaN literal", nan_corner, MalformedJson),
        raw_case("number out of range", infinite_corner, MalformedJson),
        raw_case("single-quoted JSON", single_quotes, MalformedJson),
        raw_case(
            "trailing garbage",
            format!("{} x", valid_text()),
            MalformedJson,
        ),
        raw_case(
            "two documents",
            format!("{0}{0}", valid_text()),
            MalformedJson,
        ),
        raw_case(
            "invalid UTF-8",
            b"{\"marker\": \"\xff\xfe\"}".to_vec(),
            MalformedJson,
        ),
        raw_case(
            "random binary",
            (0..=255u8).cycle().take(4096).collect::<Vec<u8>>(),
            MalformedJson,
        ),
        json_case("a bare string", json!("corners"), InvalidType, Some("")),
        json_case("an empty object", json!({}), MissingField, Some("/camera")),
        json_case(
            "missing camera",
            with("/camera", Value::Null),
            MissingField,
            Some("/camera"),
        ),
        json_case(
            "missing marker",
            with("/marker", Value::Null),
            MissingField,
            Some("/marker"),
        ),
        json_case(
            "missing marker size",
            with("/marker/size_mm", Value::Null),
            MissingField,
            Some("/marker/size_mm"),
        ),
        json_case(
            "no corners",
            with("/corners_px", Value::Null),
            CornersMissingOrConflicting,
            Some("/corners_px"),
        ),
        json_case(
            "both corner forms",
            with("/corners_mm", json!([[0, 0], [1, 0], [1, 1], [0, 1]])),
            CornersMissingOrConflicting,
            Some("/corners_mm"),
        ),
        json_case(
            "corners as a string",
            with("/corners_px", json!("four corners")),
            InvalidType,
            Some("/corners_px"),
        ),
        json_case(
            "a corner coordinate as a string",
            with("/corners_px/1", json!(["689.9", 311.4])),
            InvalidType,
            Some("/corners_px/1/0"),
        ),
        json_case(
            "marker size as a string",
            with("/marker/size_mm", json!("50")),
            InvalidType,
            Some("/marker/size_mm"),
        ),
        json_case(
            "three corners",
            with("/corners_px", json!([[100, 100], [200, 100], [200, 200]])),
            CornerCount,
            Some("/corners_px"),
        ),
        json_case(
            "five corners",
            with(
                "/corners_px",
                json!([[100, 100], [200, 100], [200, 200], [100, 200], [150, 150]]),
            ),
            CornerCount,
            Some("/corners_px"),
        ),
        json_case(
            "a corner with three numbers",
            with("/corners_px/1", json!([689.9, 311.4, 1.0])),
            InvalidType,
            Some("/corners_px/1"),
        ),
        json_case(
            "duplicate corners",
            with("/corners_px/2", json!([589.2, 309.8])),
            DuplicateCorners,
            Some("/corners_px/2"),
        ),
        json_case(
            "collinear corners",
            with("/corners_px", json!([[0, 0], [100, 0], [200, 0], [0, 100]])),
            CollinearCorners,
            Some("/corners_px/2"),
        ),
        json_case(
            "crossed corners",
            with(
                "/corners_px",
                json!([[100, 100], [200, 200], [200, 100], [100, 200]]),
            ),
            SelfIntersectingCorners,
            Some("/corners_px"),
        ),
        json_case(
            "non-convex corners",
            with(
                "/corners_px",
                json!([[100, 100], [200, 100], [130, 130], [100, 200]]),
            ),
            NonConvexCorners,
            Some("/corners_px/2"),
        ),
        json_case(
            "mirrored corner order",
            with(
                "/corners_px",
                json!([[100, 100], [100, 200], [200, 200], [200, 100]]),
            ),
            MirroredCorners,
            Some("/corners_px"),
        ),
        json_case(
            "zero focal length",
            with("/camera/fx_px", json!(0.0)),
            InvalidCameraParameter,
            Some("/camera/fx_px"),
        ),
        json_case(
            "negative focal length",
            with("/camera/fy_px", json!(-1000.0)),
            InvalidCameraParameter,
            Some("/camera/fy_px"),
        ),
        json_case(
            "zero pixel size",
            with(
                "/camera",
                json!({"focal_length_mm": 4.0, "pixel_size_um": 0.0, "cx_px": 640, "cy_px": 360}),
            ),
            InvalidCameraParameter,
            Some("/camera/pixel_size_um"),
        ),
        json_case(
            "missing principal point",
            with("/camera/cy_px", Value::Null),
            IncompleteCamera,
            Some("/camera/cy_px"),
        ),
        json_case(
            "two camera forms",
            with("/camera/focal_length_mm", json!(4.0)),
            IncompleteCamera,
            Some("/camera"),
        ),
        json_case(
            "undistortion beyond the fold",
            json!({
                "corners_px": [[1000.0, 300.0], [1200.0, 300.0], [1200.0, 500.0], [1000.0, 500.0]],
                "camera": {"fx_px": 1000.0, "fy_px": 1000.0, "cx_px": 639.5, "cy_px": 359.5, "distortion": {"k1": -2.0}},
                "marker": {"size_mm": 50.0}
            }),
            UndistortionFailed,
            Some("/corners_px/2"),
        ),
        json_case(
            "zero marker size",
            with("/marker/size_mm", json!(0.0)),
            InvalidMarkerSize,
            Some("/marker/size_mm"),
        ),
        json_case(
            "negative marker size",
            with("/marker/size_mm", json!(-50.0)),
            InvalidMarkerSize,
            Some("/marker/size_mm"),
        ),
        json_case(
            "unknown method",
            with("/solver", json!({"method": "magic"})),
            UnknownVariant,
            Some("/solver/method"),
        ),
        json_case(
            "unknown corner order",
            with("/corner_order", json!("clockwise")),
            UnknownVariant,
            Some("/corner_order"),
        ),
        json_case(
            "unknown field",
            with("/solver", json!({"max_iteration": 5})),
            UnknownField,
            Some("/solver/max_iteration"),
        ),
        json_case(
            "absurd iteration count",
            with("/solver", json!({"max_iterations": 1_000_000_000_000_u64})),
            SolverParameterOutOfRange,
            Some("/solver/max_iterations"),
        ),
        json_case(
            "zero iterations",
            with("/solver", json!({"max_iterations": 0})),
            SolverParameterOutOfRange,
            Some("/solver/max_iterations"),
        ),
        json_case(
            "negative iterations",
            with("/solver", json!({"max_iterations": -5})),
            InvalidType,
            Some("/solver/max_iterations"),
        ),
        json_case(
            "fractional iterations",
            with("/solver", json!({"max_iterations": 2.5})),
            InvalidType,
            Some("/solver/max_iterations"),
        ),
        json_case(
            "huge gain",
            with("/solver", json!({"method": "paper", "gain": 1e300})),
            SolverParameterOutOfRange,
            Some("/solver/gain"),
        ),
        Case {
            name: "wrong content type",
            body: valid_text().into_bytes(),
            content_type: Some("text/plain"),
            status: 415,
            code: UnsupportedMediaType,
            field: None,
        },
        Case {
            name: "form content type",
            body: valid_text().into_bytes(),
            content_type: Some("application/x-www-form-urlencoded"),
            status: 415,
            code: UnsupportedMediaType,
            field: None,
        },
        Case {
            name: "no content type",
            body: valid_text().into_bytes(),
            content_type: None,
            status: 415,
            code: UnsupportedMediaType,
            field: None,
        },
        Case {
            name: "a 30 MB body",
            body: vec![b' '; 30_000_000],
            content_type: Some("application/json"),
            status: 413,
            code: PayloadTooLarge,
            field: None,
        },
    ]
}

#[tokio::test]
async fn every_bad_request_gets_its_4xx_problem_and_the_server_stays_up() {
    // Arrange
    let app = spawn_app().await;
    let cases = catalogue();
    assert!(cases.len() >= 25, "the catalogue has {} cases", cases.len());

    for case in cases {
        // Act
        let response = app.post_corners_raw(case.body, case.content_type).await;

        // Assert
        let name = case.name;
        let status = response.status().as_u16();
        assert!((400..500).contains(&status), "{name}: {status}");
        let content_type = response.headers()[header::CONTENT_TYPE].clone();
        assert_eq!(content_type, "application/problem+json", "{name}");
        let problem: Problem = response.json().await.expect("a problem document");
        assert_eq!(
            (status, problem.code, problem.field.as_deref()),
            (case.status, case.code, case.field),
            "{name}: {problem:?}"
        );
        assert_eq!(problem.status, status, "{name}");
        app.assert_up(name).await;
    }
}

#[tokio::test]
async fn a_body_over_a_configured_limit_gets_413_naming_the_limit() {
    // Arrange
    let app = spawn_app_with(Settings {
        body_limit_bytes: 1024,
        ..Settings::default()
    })
    .await;
    let mut body = valid_request();
    body["padding"] = json!("x".repeat(2000));

    // Act
    let response = app.post_corners(&body).await;

    // Assert
    let problem = assert_problem(response, 413, PayloadTooLarge).await;
    assert!(problem.detail.contains("1024 bytes"), "{}", problem.detail);
    app.assert_up("an oversized body").await;
}

#[tokio::test]
async fn a_body_at_the_limit_is_read_and_judged_on_its_content() {
    // Arrange: a valid request padded with whitespace to exactly the limit.
    let limit = 4096;
    let app = spawn_app_with(Settings {
        body_limit_bytes: limit,
        ..Settings::default()
    })
    .await;
    let mut body = serde_json::to_vec(&valid_request()).expect("serialisable");
    body.resize(limit, b' ');

    // Act
    let response = app.post_corners_raw(body, Some("application/json")).await;

    // Assert
    assert_eq!(response.status(), 200);
}

#[tokio::test]
async fn magnitudes_beyond_double_precision_get_422_numerically_degenerate() {
    // Arrange: the issue's two requests. Corners at ±1e150 px were a 200 with z = 2.5e-146 mm
    // and a covariance of nulls; a square of side 1e200 px was "corners 1 and 2 coincide".
    let app = spawn_app().await;
    let cases = [
        json!([
            [-1e150, -1e150],
            [1e150, -1e150],
            [1e150, 1e150],
            [-1e150, 1e150]
        ]),
        json!([[0.0, 0.0], [1e200, 0.0], [1e200, 1e200], [0.0, 1e200]]),
    ];
    for corners in cases {
        let mut body = valid_request();
        body["corners_px"] = corners.clone();

        // Act
        let response = app.post_corners(&body).await;

        // Assert
        let problem = assert_problem(response, 422, NumericallyDegenerate).await;
        assert_eq!(problem.field.as_deref(), Some("/corners_px"), "{corners}");
    }
    // Finite millimetres that overflow only once divided by the smallest pixel pitch the
    // schema allows (1e-3 µm) were `non_finite_number` ("corner 2 has a coordinate that is
    // not a finite number").
    let mut body = json!({
        "corners_mm": [[0.0, 0.0], [1e306, 0.0], [1e306, 1e306], [0.0, 1e306]],
        "camera": {"focal_length_mm": 4.0, "pixel_size_um": 1e-3},
        "marker": {"size_mm": 50.0}
    });
    let problem = assert_problem(app.post_corners(&body).await, 422, NumericallyDegenerate).await;
    assert_eq!(problem.field.as_deref(), Some("/corners_mm"));
    // A pitch below the stated range is the camera's fault, named.
    body["camera"]["pixel_size_um"] = json!(1e-300);
    let problem = assert_problem(app.post_corners(&body).await, 422, InvalidCameraParameter).await;
    assert_eq!(problem.field.as_deref(), Some("/camera/pixel_size_um"));
    app.assert_up("extreme magnitudes").await;
}
