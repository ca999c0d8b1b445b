//! The typed errors, the two deserialisers that make them, and the codes and pointers the
//! API chooses from them.

use super::value::{from_value, parse_first_value};
use super::{ShapeError, ShapeErrorKind};
use crate::api::problem::{ErrorCode, parse_json, parse_json_value};
use serde::Deserialize;
use serde::de::value::Error as Wording;
use serde::de::{Error as _, Unexpected};
use serde_json::{Value, json};
use std::collections::BTreeMap;

#[test]
fn each_constructor_records_its_kind_in_serdes_words() {
    let expected: &'static [&'static str] = &["size_mm", "corners"];
    let cases = [
        (
            ShapeError::missing_field("size_mm"),
            Wording::missing_field("size_mm"),
            ShapeErrorKind::MissingField {
                field: "size_mm".to_owned(),
            },
        ),
        (
            ShapeError::unknown_field("sise", expected),
            Wording::unknown_field("sise", expected),
            ShapeErrorKind::UnknownField {
                field: "sise".to_owned(),
            },
        ),
        (
            ShapeError::unknown_variant("magic", expected),
            Wording::unknown_variant("magic", expected),
            ShapeErrorKind::UnknownVariant {
                variant: "magic".to_owned(),
            },
        ),
        (
            ShapeError::duplicate_field("count"),
            Wording::duplicate_field("count"),
            ShapeErrorKind::DuplicateField {
                field: "count".to_owned(),
            },
        ),
        (
            ShapeError::invalid_type(Unexpected::Str("5"), &"f64"),
            Wording::invalid_type(Unexpected::Str("5"), &"f64"),
            ShapeErrorKind::InvalidType,
        ),
        (
            ShapeError::invalid_value(Unexpected::Signed(-5), &"u64"),
            Wording::invalid_value(Unexpected::Signed(-5), &"u64"),
            ShapeErrorKind::InvalidValue,
        ),
        (
            ShapeError::invalid_length(3, &"an array of 2"),
            Wording::invalid_length(3, &"an array of 2"),
            ShapeErrorKind::InvalidLength,
        ),
        (
            ShapeError::custom("invalid float literal"),
            Wording::custom("invalid float literal"),
            ShapeErrorKind::Custom,
        ),
    ];
    for (error, wording, kind) in cases {
        assert_eq!(error.to_string(), wording.to_string());
        assert_eq!(error.kind(), &kind, "{error}");
    }
    let fields: Vec<Option<String>> = [
        ShapeError::missing_field("a"),
        ShapeError::unknown_field("b", expected),
        ShapeError::duplicate_field("c"),
        ShapeError::unknown_variant("d", expected),
        ShapeError::custom("e"),
    ]
    .iter()
    .map(|e| e.kind().field().map(str::to_owned))
    .collect();
    let named = |s: &str| Some(s.to_owned());
    assert_eq!(fields, [named("a"), named("b"), named("c"), None, None]);
}

#[derive(Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
struct Marker {
    size_mm: f64,
    #[serde(default)]
    label: Option<String>,
}

#[derive(Debug, PartialEq, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
enum Method {
    Paper,
    Reprojection,
    Scaled(f64),
    Pair(u8, u8),
    Tuned { gain: f64 },
}

#[derive(Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
struct Body {
    marker: Marker,
    #[serde(default)]
    markers: Vec<Marker>,
    #[serde(default)]
    corners: Vec<[f64; 2]>,
    #[serde(default)]
    method: Option<Method>,
    #[serde(default)]
    iterations: Option<u8>,
    #[serde(default)]
    flags: BTreeMap<String, bool>,
    #[serde(default)]
    pair: Option<(char, i64)>,
}

const BASE: &str = r#""marker": {"size_mm": 50}"#;

fn body(rest: &str) -> String {
    if rest.is_empty() {
        format!("{{{BASE}}}")
    } else {
        format!("{{{BASE}, {rest}}}")
    }
}

#[test]
fn json_shape_errors_have_their_code_and_pointer() {
    let cases: Vec<(String, ErrorCode, &str)> = vec![
        (
            r#"{"marker": {}}"#.to_owned(),
            ErrorCode::MissingField,
            "/marker/size_mm",
        ),
        ("{}".to_owned(), ErrorCode::MissingField, "/marker"),
        (
            body(r#""markers": [{"size_mm": 1}, {"label": "b"}]"#),
            ErrorCode::MissingField,
            "/markers/1/size_mm",
        ),
        (
            body(r#""markers": [{"size_mm": 1, "sise": 2}]"#),
            ErrorCode::UnknownField,
            "/markers/0/sise",
        ),
        (body(r#""a/b~c": 1"#), ErrorCode::UnknownField, "/a~1b~0c"),
        (
            body(r#""method": "magic""#),
            ErrorCode::UnknownVariant,
            "/method",
        ),
        (
            body(r#""method": {"magic": 1}"#),
            ErrorCode::UnknownVariant,
            "/method",
        ),
        (
            body(r#""method": {"tuned": {"gain": 1, "gian": 2}}"#),
            ErrorCode::UnknownField,
            "/method/tuned/gian",
        ),
        (
            body(r#""method": {"tuned": {}}"#),
            ErrorCode::MissingField,
            "/method/tuned/gain",
        ),
        (
            body(r#""corners": [[1, 2], [1, "2"]]"#),
            ErrorCode::InvalidType,
            "/corners/1/1",
        ),
        (
            body(r#""corners": [[1, 2], [1]]"#),
            ErrorCode::InvalidType,
            "/corners/1",
        ),
        (
            body(r#""iterations": -5"#),
            ErrorCode::InvalidType,
            "/iterations",
        ),
        (
            body(r#""iterations": 300"#),
            ErrorCode::InvalidType,
            "/iterations",
        ),
        (
            body(r#""iterations": 2.5"#),
            ErrorCode::InvalidType,
            "/iterations",
        ),
        (
            body(r#""flags": {"x": 1}"#),
            ErrorCode::InvalidType,
            "/flags/x",
        ),
        (
            body(r#""pair": ["ab", 1]"#),
            ErrorCode::InvalidType,
            "/pair/0",
        ),
        (
            // serde_json refuses the second key; a `Value` keeps it once, so there is no
            // typed error at that path.
            r#"{"marker": {"size_mm": 1, "size_mm": 2}}"#.to_owned(),
            ErrorCode::InvalidType,
            "/marker",
        ),
    ];
    for (json, code, pointer) in cases {
        let p = parse_json::<Body>(json.as_bytes()).expect_err(&json);
        assert_eq!(
            (p.code, p.field.as_deref(), p.status),
            (code, Some(pointer), 422),
            "{json}: {p:?}"
        );
    }
}

#[test]
fn the_detail_is_serde_jsons_message_with_its_position() {
    for json in [
        body(r#""sise": 1"#),
        r#"{"marker": {}}"#.to_owned(),
        body(r#""method": "magic""#),
        body(r#""corners": [[1, "2"]]"#),
        format!("{}\n  x", r#"{"marker": {"size_mm": "5"}}"#),
    ] {
        let p = parse_json::<Body>(json.as_bytes()).expect_err(&json);
        let serde_json = serde_json::from_slice::<Body>(json.as_bytes()).expect_err(&json);
        assert_eq!(p.detail, serde_json.to_string(), "{json}");
        assert!(p.detail.contains(" at line "), "{}", p.detail);
    }
}

#[test]
fn the_typed_run_reads_only_the_value_that_failed() {
    // Trailing characters do not hide the typed error; they are malformed only when the
    // value itself parses.
    let p = parse_json::<Body>(br#"{"marker": {}} x"#).expect_err("missing");
    assert_eq!(p.code, ErrorCode::MissingField);
    let p = parse_json::<Body>(format!("{} x", body("")).as_bytes()).expect_err("trailing");
    assert_eq!(p.code, ErrorCode::MalformedJson);
}

#[test]
fn without_a_typed_error_the_code_is_invalid_type_at_the_first_errors_path() {
    // Malformed after the shape error: no `Value`, so no more specific code is claimed.
    let p = parse_json::<Body>(br#"{"marker": {"sise": 1}, "markers": ["#).expect_err("eof");
    assert_eq!(
        (p.code, p.field.as_deref()),
        (ErrorCode::InvalidType, Some("/marker/sise"))
    );
}

#[test]
fn nesting_past_serde_jsons_limit_after_the_shape_error_keeps_the_typed_code() {
    let nested = |depth: usize| format!("{}{}", "[".repeat(depth), "]".repeat(depth));
    let deep = format!(r#"{{"marker": {{}}, "flags": {}}}"#, nested(200));
    let p = parse_json::<Body>(deep.as_bytes()).expect_err("deep");
    assert_eq!(
        (p.code, p.field.as_deref()),
        (ErrorCode::MissingField, Some("/marker/size_mm"))
    );
    // The first value is serde_json's up to its own limit, `null` only beyond it.
    let within = nested(127);
    let ours = parse_first_value(within.as_bytes()).expect("within the limit");
    let theirs: Value = serde_json::from_str(&within).expect("within the limit");
    assert_eq!(ours, theirs);
    assert!(serde_json::from_str::<Value>(&nested(128)).is_err());
    let pruned = parse_first_value(nested(128).as_bytes()).expect("pruned");
    let innermost = (0..127).try_fold(&pruned, |v, _| v.get(0));
    assert_eq!(innermost, Some(&Value::Null));
    let object = parse_first_value(br#"{"b": 1, "a": [2.5, "x", null, true]} tail"#);
    assert_eq!(
        object.expect("one value").to_string(),
        r#"{"b":1,"a":[2.5,"x",null,true]}"#
    );
}

#[test]
fn syntax_and_end_of_input_errors_are_malformed_json() {
    for json in [
        "",
        "{",
        r#"{"marker": {"size_mm": 5,}}"#,
        r#"{"marker" {}}"#,
        "nul",
    ] {
        let p = parse_json::<Body>(json.as_bytes()).expect_err(json);
        assert_eq!(
            (p.code, p.field.as_deref()),
            (ErrorCode::MalformedJson, None),
            "{json}"
        );
    }
}

#[test]
fn a_parsed_value_gets_the_same_codes_and_serde_jsons_message() {
    let cases = [
        (
            json!({"marker": {}}),
            ErrorCode::MissingField,
            "/marker/size_mm",
        ),
        (
            json!({"marker": {"size_mm": 1}, "sise": 1}),
            ErrorCode::UnknownField,
            "/sise",
        ),
        (
            json!({"marker": {"size_mm": 1}, "method": "magic"}),
            ErrorCode::UnknownVariant,
            "/method",
        ),
        (
            json!({"marker": {"size_mm": null}}),
            ErrorCode::InvalidType,
            "/marker/size_mm",
        ),
    ];
    for (value, code, pointer) in cases {
        let p = parse_json_value::<Body>(&value).expect_err("refused");
        assert_eq!(
            (p.code, p.field.as_deref()),
            (code, Some(pointer)),
            "{value}"
        );
        let serde_json = serde_json::from_value::<Body>(value.clone()).expect_err("refused");
        assert_eq!(p.detail, serde_json.to_string());
    }
    let ok = parse_json_value::<Body>(&json!({"marker": {"size_mm": 1}, "method": "paper"}));
    assert_eq!(ok.map(|b| b.method), Ok(Some(Method::Paper)));
}

/// The kind serde_json's message names, by its first words: the oracle the typed
/// deserialiser must agree with (tests only; the API never reads a message).
fn kind_by_text(message: &str) -> &'static str {
    [
        ("missing field", "missing"),
        ("unknown field", "unknown field"),
        ("unknown variant", "unknown variant"),
        ("invalid type", "type"),
        ("invalid value", "value"),
        ("invalid length", "length"),
        ("duplicate field", "duplicate"),
    ]
    .iter()
    .find(|(prefix, _)| message.starts_with(prefix))
    .map_or("custom", |(_, kind)| kind)
}

fn kind_name(kind: &ShapeErrorKind) -> &'static str {
    match kind {
        ShapeErrorKind::MissingField { .. } => "missing",
        ShapeErrorKind::UnknownField { .. } => "unknown field",
        ShapeErrorKind::UnknownVariant { .. } => "unknown variant",
        ShapeErrorKind::DuplicateField { .. } => "duplicate",
        ShapeErrorKind::InvalidType => "type",
        ShapeErrorKind::InvalidValue => "value",
        ShapeErrorKind::InvalidLength => "length",
        ShapeErrorKind::Custom => "custom",
    }
}

#[test]
fn the_value_deserialiser_agrees_with_serde_jsons_call_for_call() {
    let documents = [
        body(""),
        body(r#""markers": [[2, "x"]], "corners": [[1, 2]]"#),
        body(r#""method": "reprojection", "iterations": 7"#),
        body(r#""method": {"scaled": 1.5}, "pair": ["x", -3]"#),
        body(r#""method": {"pair": [1, 2]}, "flags": {"a": true}"#),
        body(r#""method": {"pair": [1]}"#),
        body(r#""method": {"pair": 1}"#),
        body(r#""method": "scaled""#),
        body(r#""method": {"paper": 1}"#),
        body(r#""method": {}"#),
        body(r#""method": 3"#),
        body(r#""method": {"tuned": [2]}"#),
        body(r#""method": {"tuned": [2, 3]}"#),
        body(r#""corners": [[1, 2, 3]]"#),
        body(r#""corners": {"0": [1, 2]}"#),
        body(r#""iterations": 1e2"#),
        body(r#""iterations": 18446744073709551616"#),
        body(r#""pair": ["xy", 1]"#),
        body(r#""pair": ["x", 1.0]"#),
        body(r#""flags": {"a": null}"#),
        r#"{"marker": [5, "lbl"]}"#.to_owned(),
        r#"{"marker": [5, "lbl", 1]}"#.to_owned(),
        r#"{"marker": "5"}"#.to_owned(),
        "[]".to_owned(),
        "null".to_owned(),
    ];
    for json in documents {
        let value: Value = serde_json::from_str(&json).expect("valid JSON");
        let theirs = serde_path_to_error::deserialize::<_, Body>(&value);
        let ours = from_value::<Body>(&value);
        match (theirs, ours) {
            (Ok(a), Ok(b)) => assert_eq!(a, b, "{json}"),
            (Err(a), Err(b)) => {
                assert_eq!(a.path().to_string(), b.path().to_string(), "{json}");
                assert_eq!(
                    kind_by_text(&a.inner().to_string()),
                    kind_name(b.inner().kind()),
                    "{json}: {} / {}",
                    a.inner(),
                    b.inner()
                );
            }
            (a, b) => panic!("{json}: serde_json {a:?}, ours {b:?}"),
        }
    }
}
