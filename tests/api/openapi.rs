//! The OpenAPI document: committed, printed by `qrpose openapi`, served at `/openapi.json`,
//! all identical; and complete.

use crate::helpers::spawn_app;
use qrpose::http::openapi::{REGENERATE, openapi_json};
use reqwest::{StatusCode, header};
use serde_json::Value;

const COMMITTED: &str = include_str!("../../openapi/openapi.json");

#[test]
fn the_committed_document_is_current() {
    let current = openapi_json().expect("a document");
    assert!(
        current == COMMITTED,
        "openapi/openapi.json is out of date; regenerate it with\n\n    {REGENERATE}\n"
    );
}

#[tokio::test]
async fn the_served_document_is_the_committed_one() {
    // Arrange
    let app = spawn_app().await;

    // Act
    let response = app.get("/openapi.json").await;

    // Assert
    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(response.headers()[header::CONTENT_TYPE], "application/json");
    let served = response.text().await.expect("text");
    assert!(
        served == COMMITTED,
        "GET /openapi.json differs; {REGENERATE}"
    );
}

#[tokio::test]
async fn the_cli_prints_the_committed_document() {
    // Act
    let output = tokio::process::Command::new(env!("CARGO_BIN_EXE_qrpose"))
        .arg("openapi")
        .output()
        .await
        .expect("qrpose runs");

    // Assert
    assert!(output.status.success(), "{output:?}");
    let printed = String::from_utf8(output.stdout).expect("UTF-8");
    assert!(printed == COMMITTED, "qrpose openapi differs; {REGENERATE}");
}

fn document() -> Value {
    serde_json::from_str(COMMITTED).expect("JSON")
}

#[test]
fn the_document_is_openapi_3_1_and_lists_every_route() {
    let doc = document();
    assert_eq!(doc["openapi"], "3.1.0");
    for (path, method) in [
        ("/v1/pose/corners", "post"),
        ("/v1/pose/image", "post"),
        ("/healthz", "get"),
        ("/readyz", "get"),
        ("/metrics", "get"),
        ("/openapi.json", "get"),
    ] {
        assert!(doc["paths"][path][method].is_object(), "{method} {path}");
    }
}

#[test]
fn every_error_response_is_a_problem_document() {
    let doc = document();
    let corners = &doc["paths"]["/v1/pose/corners"]["post"]["responses"];
    for status in ["400", "413", "415", "422", "500", "503"] {
        let schema = &corners[status]["content"]["application/problem+json"]["schema"];
        assert_eq!(schema["$ref"], "#/components/schemas/Problem", "{status}");
    }
    assert!(corners["503"]["headers"]["Retry-After"].is_object());
    for (path, operation) in doc["paths"].as_object().expect("paths") {
        for (method, op) in operation.as_object().expect("operations") {
            for (status, response) in op["responses"].as_object().expect("responses") {
                if status.starts_with('4') || status.starts_with('5') {
                    let content = &response["content"]["application/problem+json"];
                    assert!(content.is_object(), "{method} {path} {status}");
                }
            }
        }
    }
}

#[test]
fn the_image_operation_documents_both_forms_and_every_parameter() {
    let doc = document();
    let image = &doc["paths"]["/v1/pose/image"]["post"];
    let content = &image["requestBody"]["content"];
    for media_type in ["image/jpeg", "image/png", "multipart/form-data"] {
        assert!(content[media_type].is_object(), "{media_type}");
    }
    let form = &content["multipart/form-data"];
    assert_eq!(
        form["schema"]["required"],
        serde_json::json!(["image", "request"])
    );
    assert_eq!(
        form["encoding"]["request"]["contentType"],
        "application/json"
    );
    let mut parameters: Vec<&str> = Vec::new();
    for p in image["parameters"].as_array().expect("parameters") {
        assert_eq!(p["in"], "query");
        assert!(p["description"].is_string(), "{p}");
        parameters.push(p["name"].as_str().expect("a name"));
        // The camera: one object parameter exploded into its forms' fields.
        for form in p["schema"]["oneOf"].as_array().into_iter().flatten() {
            for (name, field) in form["properties"].as_object().expect("properties") {
                assert!(field["description"].is_string(), "{name}: {field}");
                parameters.push(name);
            }
        }
    }
    for name in ["fx_px", "marker_size_mm", "method", "detector", "points"] {
        assert!(parameters.contains(&name), "{name} in {parameters:?}");
    }
    for status in ["400", "413", "415", "422", "500", "503"] {
        let schema = &image["responses"][status]["content"]["application/problem+json"]["schema"];
        assert_eq!(schema["$ref"], "#/components/schemas/Problem", "{status}");
    }
    assert_eq!(
        image["responses"]["200"]["content"]["application/json"]["schema"]["$ref"],
        "#/components/schemas/ImageResponse"
    );
}

#[test]
fn every_schema_and_field_is_described() {
    let doc = document();
    let mut undocumented = Vec::new();
    for (name, schema) in doc["components"]["schemas"].as_object().expect("schemas") {
        let is_enum = schema.get("enum").is_some();
        if schema.get("description").is_none() && !is_enum {
            undocumented.push(name.clone());
        }
        if let Some(properties) = schema.get("properties").and_then(Value::as_object) {
            for (field, property) in properties {
                // An optional reference is `oneOf: [{$ref, description}, {type: null}]`.
                let described = property.get("description").is_some()
                    || property["oneOf"]
                        .as_array()
                        .is_some_and(|v| v.iter().any(|b| b.get("description").is_some()));
                if !described {
                    undocumented.push(format!("{name}.{field}"));
                }
            }
        }
    }
    assert!(undocumented.is_empty(), "undocumented: {undocumented:?}");
}
