//! Problems from parse failures: codes, pointers and details.

use super::*;
use serde_json::json;
use std::collections::BTreeMap;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
struct Inner {
    size_mm: f64,
}
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
struct Outer {
    marker: Inner,
    corners: Vec<[f64; 2]>,
}

#[test]
fn classifies_json_errors_with_their_field() {
    let cases: [(&str, ErrorCode, Option<&str>); 6] = [
        ("{", ErrorCode::MalformedJson, None),
        ("", ErrorCode::MalformedJson, None),
        (
            r#"{"marker": {}, "corners": []}"#,
            ErrorCode::MissingField,
            Some("/marker/size_mm"),
        ),
        (
            r#"{"marker": {"size_mm": 5, "sise": 1}, "corners": []}"#,
            ErrorCode::UnknownField,
            Some("/marker/sise"),
        ),
        (
            r#"{"marker": {"size_mm": "5"}, "corners": []}"#,
            ErrorCode::InvalidType,
            Some("/marker/size_mm"),
        ),
        (
            r#"{"marker": {"size_mm": 5}, "corners": [[1, 2], [1, "2"]]}"#,
            ErrorCode::InvalidType,
            Some("/corners/1/1"),
        ),
    ];
    for (body, code, field) in cases {
        let p = parse_json::<Outer>(body.as_bytes()).expect_err(body);
        assert_eq!(p.code, code, "{body}: {p:?}");
        assert_eq!(p.field.as_deref(), field, "{body}");
        assert_eq!(p.status, code.status());
    }
}

#[test]
fn trailing_garbage_is_malformed() {
    let p = parse_json::<Inner>(br#"{"size_mm": 1} x"#).expect_err("trailing characters");
    assert_eq!(p.code, ErrorCode::MalformedJson);
}

#[test]
fn problem_type_names_the_code() {
    let p = Problem::new(ErrorCode::MirroredCorners, "reversed");
    assert_eq!(p.type_uri, "urn:qrpose:problem:mirrored_corners");
    assert_eq!(p.status, 422);
    let json = serde_json::to_value(&p).expect("serialisable");
    assert!(
        json.get("field").is_none(),
        "no field key when none is at fault"
    );
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
            // A key given twice is a shape error of the general code.
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
fn trailing_characters_are_malformed_only_after_a_value_that_parses() {
    // Trailing characters do not hide the shape error; they are malformed only when the
    // value itself parses.
    let p = parse_json::<Body>(br#"{"marker": {}} x"#).expect_err("missing");
    assert_eq!(p.code, ErrorCode::MissingField);
    let p = parse_json::<Body>(format!("{} x", body("")).as_bytes()).expect_err("trailing");
    assert_eq!(p.code, ErrorCode::MalformedJson);
}

#[test]
fn a_shape_error_keeps_its_code_when_the_document_is_malformed_further_on() {
    let p = parse_json::<Body>(br#"{"marker": {"sise": 1}, "markers": ["#).expect_err("eof");
    assert_eq!(
        (p.code, p.field.as_deref()),
        (ErrorCode::UnknownField, Some("/marker/sise"))
    );
}

#[test]
fn nesting_past_serde_jsons_limit_after_the_shape_error_keeps_the_code() {
    let nested = |depth: usize| format!("{}{}", "[".repeat(depth), "]".repeat(depth));
    let deep = format!(r#"{{"marker": {{}}, "flags": {}}}"#, nested(200));
    let p = parse_json::<Body>(deep.as_bytes()).expect_err("deep");
    assert_eq!(
        (p.code, p.field.as_deref()),
        (ErrorCode::MissingField, Some("/marker/size_mm"))
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
