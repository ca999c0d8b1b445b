//! Extreme but finite inputs through `estimate_corners` (what `POST /v1/pose/corners` and
//! `qrpose estimate` call): magnitudes from 1e-300 to 1e300 with random signs, in the
//! corners, the intrinsics and the marker size, for every method. Every answer is either a
//! pose whose JSON validates against the committed OpenAPI schema (the `jsonschema` crate;
//! serde_json writes NaN and ±∞ as `null`, which the schema's numbers refuse), or a 4xx
//! problem, never a 500 or a panic.

use proptest::prelude::*;
use qrpose::api::{
    estimate_corners, problem::ErrorCode, problem::parse_json, request::CornersRequest,
};
use serde_json::{Value, json};
use std::sync::LazyLock;

/// The committed OpenAPI document's `PoseResponse` as a JSON Schema (2020-12, which OpenAPI
/// 3.1 uses), validated by the `jsonschema` crate: the document itself is the root, so that
/// every `$ref` into `#/components/schemas` resolves.
static POSE_SCHEMA: LazyLock<jsonschema::Validator> = LazyLock::new(|| {
    let mut root: Value = serde_json::from_str(include_str!("../../openapi/openapi.json"))
        .expect("the committed document");
    root["$ref"] = json!("#/components/schemas/PoseResponse");
    jsonschema::draft202012::new(&root).expect("the committed document is a valid schema")
});

/// Every way `value` breaks the committed `PoseResponse` schema, as "pointer: error".
fn schema_errors(value: &Value) -> Vec<String> {
    POSE_SCHEMA
        .iter_errors(value)
        .map(|e| format!("{}: {e}", e.instance_path()))
        .collect()
}

/// A number `sign × mantissa × 10^exponent` with exponent in -300..=300.
fn extreme() -> impl Strategy<Value = f64> {
    (any::<bool>(), 1.0f64..10.0, -300i32..=300).prop_map(|(negative, mantissa, exponent)| {
        let magnitude = mantissa * 10f64.powi(exponent);
        if negative { -magnitude } else { magnitude }
    })
}

/// A scalar that is either ordinary or extreme (half the time each), so that extreme values
/// meet ordinary ones as well as each other.
fn maybe_extreme(ordinary: f64) -> impl Strategy<Value = f64> {
    prop_oneof![Just(ordinary), extreme()]
}

/// Four corners: either any four extreme points, or a square (clockwise on screen, top-left
/// first) at an extreme scale and offset, which gets past validation to the solvers.
fn corners() -> impl Strategy<Value = Vec<[f64; 2]>> {
    let free = prop::collection::vec((extreme(), extreme()).prop_map(|(u, v)| [u, v]), 4);
    let square = (
        extreme(),
        maybe_extreme(600.0),
        maybe_extreme(300.0),
        0.8f64..1.25,
    )
        .prop_map(|(side, u0, v0, aspect)| {
            let (w, h) = (side.abs(), side.abs() * aspect);
            vec![[u0, v0], [u0 + w, v0], [u0 + w, v0 + h], [u0, v0 + h]]
        });
    prop_oneof![free, square]
}

fn request() -> impl Strategy<Value = Value> {
    (
        corners(),
        maybe_extreme(1000.0),
        maybe_extreme(1000.0),
        maybe_extreme(639.5),
        maybe_extreme(359.5),
        maybe_extreme(50.0),
        prop_oneof![Just("reprojection"), Just("depth-newton"), Just("paper")],
        any::<bool>(),
    )
        .prop_map(|(corners, fx, fy, cx, cy, size, method, trace)| {
            json!({
                "corners_px": corners,
                "camera": {"fx_px": fx, "fy_px": fy, "cx_px": cx, "cy_px": cy},
                "marker": {"size_mm": size},
                "solver": {"method": method, "trace": trace}
            })
        })
}

/// Runs one request as the service does (JSON bytes in) and checks the property.
fn check(body: &Value) -> Result<(), TestCaseError> {
    let bytes = serde_json::to_vec(body).expect("finite numbers serialise");
    let answer = parse_json::<CornersRequest>(&bytes).and_then(|r| estimate_corners(&r, None));
    match answer {
        Ok(pose) => {
            let json = serde_json::to_value(&pose).expect("a pose serialises");
            let found = schema_errors(&json);
            prop_assert!(
                found.is_empty(),
                "{found:?}\nrequest {body}\nresponse {json}"
            );
        }
        Err(problem) => {
            prop_assert!(
                (400..500).contains(&problem.status) && problem.code != ErrorCode::Internal,
                "{problem:?}\nrequest {body}"
            );
            prop_assert_eq!(problem.status, problem.code.status());
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

    #[test]
    fn every_answer_to_extreme_inputs_is_a_schema_valid_pose_or_a_4xx(body in request()) {
        check(&body)?;
    }
}

#[test]
fn the_issues_examples_are_refused_for_what_they_are() {
    let base = |corners: Value| {
        json!({
            "corners_px": corners,
            "camera": {"fx_px": 1000.0, "fy_px": 1000.0, "cx_px": 639.5, "cy_px": 359.5},
            "marker": {"size_mm": 50.0}
        })
    };
    // Corners at ±1e150 px: a 200 with z = 2.5e-146 mm and a covariance of nulls before.
    let far = base(json!([
        [-1e150, -1e150],
        [1e150, -1e150],
        [1e150, 1e150],
        [-1e150, 1e150]
    ]));
    // A square of side 1e200 px: 422 duplicate_corners ("corners 1 and 2 coincide") before.
    let huge = base(json!([
        [0.0, 0.0],
        [1e200, 0.0],
        [1e200, 1e200],
        [0.0, 1e200]
    ]));
    for body in [far, huge] {
        check(&body).expect("a valid pose or a 4xx");
        let bytes = serde_json::to_vec(&body).expect("serialises");
        let request = parse_json::<CornersRequest>(&bytes).expect("parses");
        match estimate_corners(&request, None) {
            Ok(pose) => panic!("{body}: a pose {pose:?}"),
            Err(problem) => {
                assert_eq!(
                    problem.code,
                    ErrorCode::NumericallyDegenerate,
                    "{body}: {problem:?}"
                );
                assert_eq!(problem.status, 422);
                assert_eq!(problem.field.as_deref(), Some("/corners_px"));
            }
        }
    }
}

#[test]
fn the_schema_check_sees_a_null_in_a_number_field() {
    let body = json!({
        "corners_px": [[589.2, 309.8], [689.9, 311.4], [688.1, 411.6], [588.0, 409.5]],
        "camera": {"fx_px": 1000.0, "fy_px": 1000.0, "cx_px": 639.5, "cy_px": 359.5},
        "marker": {"size_mm": 50.0}
    });
    let bytes = serde_json::to_vec(&body).expect("serialises");
    let request = parse_json::<CornersRequest>(&bytes).expect("parses");
    let mut pose = estimate_corners(&request, None).expect("the README's example");
    let found = schema_errors(&serde_json::to_value(&pose).expect("json"));
    assert!(found.is_empty(), "{found:?}");
    pose.distance_mm = f64::NAN;
    if let Some(c) = pose.diagnostics.covariance.as_mut() {
        c.matrix[2][3] = f64::INFINITY;
    }
    let found = schema_errors(&serde_json::to_value(&pose).expect("json"));
    let pointers: Vec<&str> = found.iter().filter_map(|f| f.split(':').next()).collect();
    assert!(pointers.contains(&"/distance_mm"), "{found:?}");
    assert!(
        pointers
            .iter()
            .any(|p| p.starts_with("/diagnostics/covariance")),
        "{found:?}"
    );
}
