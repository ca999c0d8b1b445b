//! The OpenAPI document: committed (without and with a site, for the default build),
//! printed by `qrpose openapi [--site]`, served at `/openapi.json` as the server is
//! configured, all identical; and complete.

use crate::helpers::spawn_app;
use qrpose::detect::Backend;
use qrpose::http::openapi::{REGENERATE, Served, openapi_json};
use reqwest::{StatusCode, header};
use serde_json::Value;

const COMMITTED: &str = include_str!("../../openapi/openapi.json");
const COMMITTED_WITH_SITE: &str = include_str!("../../openapi/openapi-site.json");

/// The configuration of the committed documents: the default build.
fn committed(site: bool) -> Served {
    Served {
        site,
        zxing_cpp: false,
        auth: false,
    }
}

/// This build's document without a site.
fn this_build() -> String {
    let served = Served {
        site: false,
        zxing_cpp: Backend::ZxingCpp.is_built(),
        auth: false,
    };
    openapi_json(served).expect("a document")
}

#[test]
fn the_committed_documents_are_current() {
    for (site, document) in [(false, COMMITTED), (true, COMMITTED_WITH_SITE)] {
        let current = openapi_json(committed(site)).expect("a document");
        assert!(
            current == document,
            "openapi/openapi{}.json is out of date; regenerate them with\n\n    {REGENERATE}\n",
            if site { "-site" } else { "" }
        );
    }
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
        served == this_build(),
        "GET /openapi.json differs; {REGENERATE}"
    );
    if !Backend::ZxingCpp.is_built() {
        assert!(
            served == COMMITTED,
            "GET /openapi.json differs; {REGENERATE}"
        );
    }
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
    assert!(
        printed == this_build(),
        "qrpose openapi differs; {REGENERATE}"
    );
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

#[tokio::test]
async fn a_server_with_a_site_serves_the_site_document() {
    // Arrange
    let settings = qrpose::config::Settings {
        site: Some(
            concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/tests/fixtures/site/warehouse.yaml"
            )
            .into(),
        ),
        ..qrpose::config::Settings::default()
    };
    let app = crate::helpers::spawn_app_with(settings).await;

    // Act
    let served = app.get("/openapi.json").await.text().await.expect("text");

    // Assert
    let expected = openapi_json(Served {
        site: true,
        zxing_cpp: Backend::ZxingCpp.is_built(),
        auth: false,
    })
    .expect("a document");
    assert!(served == expected, "GET /openapi.json with a site differs");
    if !Backend::ZxingCpp.is_built() {
        assert!(served == COMMITTED_WITH_SITE, "{REGENERATE}");
    }
}

/// The documents differ only where a site changes what is valid: without one the camera
/// has no site-id form and the marker size is required.
/// A validator of component `name` of the committed document without a site.
fn validator(name: &str) -> jsonschema::Validator {
    let mut root: Value = serde_json::from_str(COMMITTED).expect("JSON");
    root["$ref"] = serde_json::json!(format!("#/components/schemas/{name}"));
    jsonschema::draft202012::new(&root).expect("a valid schema")
}

#[test]
fn the_forms_accept_what_the_server_accepts_and_refuse_the_rest() {
    use serde_json::json;
    let camera = json!({"fx_px": 1000, "fy_px": 1000, "cx_px": 640, "cy_px": 360});
    let corners = validator("CornersRequest");
    let square = json!([[0, 0], [10, 0], [10, 10], [0, 10]]);
    let request = |corners_px: Value| json!({"corners_px": corners_px, "marker": {"size_mm": 50}, "camera": camera});
    assert!(corners.is_valid(&request(square.clone())));
    let mut picking = request(square);
    picking["flange_pose"] =
        json!({"translation_mm": [0, 0, 500], "quaternion_wxyz": [1, 0, 0, 0]});
    picking["min_grasp_probability"] = json!(0.9);
    assert!(
        corners.is_valid(&picking),
        "every field of the request is in its forms"
    );
    for bad in [
        json!([[0, 0], [10, 0], [10, 10], [0, 10, 1]]),
        json!([[0, 0], [10, 0], [10, 10], [0]]),
        json!([[0, 0], [10, 0], [10, 10], [0, 0]]),
        json!([[0, 0], [10, 0], [10, 10]]),
    ] {
        assert!(!corners.is_valid(&request(bad.clone())), "{bad}");
    }
    let image = validator("ImageRequest");
    for (points, solver, valid) in [
        ("finders", json!({}), true),
        ("finders", json!({"method": "reprojection"}), true),
        ("finders", json!({"method": "paper"}), false),
        ("finders", json!({"method": "depth-newton"}), false),
        ("corners", json!({"method": "paper"}), true),
    ] {
        let r = json!({"camera": camera, "marker": {"size_mm": 50}, "points": points,
                       "solver": solver});
        assert_eq!(image.is_valid(&r), valid, "{r}");
    }
    let lens = validator("DistortionDto");
    for (distortion, valid) in [
        (json!({"k1": 0.1, "k4": 0}), true),
        (json!({"k1": 0.1, "k4": 0.5}), false),
        (json!({"model": "equidistant", "k4": 0.5, "p1": 0.0}), true),
        (json!({"model": "equidistant", "p1": 0.1}), false),
        (json!({"model": "rational_polynomial", "k6": 0.5}), true),
    ] {
        assert_eq!(lens.is_valid(&distortion), valid, "{distortion}");
    }
    let prior = validator("PriorDto");
    assert!(prior.is_valid(&json!({"marker_quaternion_wxyz": [1, 0, 0, 0], "sigma_deg": 10})));
    assert!(!prior.is_valid(&json!({"marker_quaternion_wxyz": [0, 0, 0, 0], "sigma_deg": 10})));
    assert!(
        !prior.is_valid(&json!({"marker_quaternion_wxyz": [1, 0, 0, 0],
        "robot_quaternion_wxyz": [1, 0, 0, 0], "sigma_deg": 10}))
    );
}

#[test]
fn the_site_changes_the_camera_forms_and_the_marker_s_required_ness() {
    let without: Value = serde_json::from_str(COMMITTED).expect("JSON");
    let with: Value = serde_json::from_str(COMMITTED_WITH_SITE).expect("JSON");
    let schemas = |d: &Value| d["components"]["schemas"].clone();
    assert!(schemas(&without).get("CameraSiteId").is_none());
    assert!(schemas(&with)["CameraSiteId"].is_object());
    for name in ["PixelCornersRequest", "PlaneCornersRequest", "ImageRequest"] {
        let required = |d: &Value| schemas(d)[name]["required"].clone();
        let marker = Value::from("marker");
        let has = |v: Value| v.as_array().is_some_and(|r| r.contains(&marker));
        assert!(has(required(&without)), "{name} without a site");
        assert!(!has(required(&with)), "{name} with a site");
    }
}

/// Every bound the document states is the one the server validates with (the DTO
/// attributes hold literals; this ties them to the constants).
#[test]
fn documented_ranges_are_the_validators_own() {
    use qrpose::estimate::{
        MAX_CORNER_SIGMA_PX, MAX_GAIN, MAX_INITIAL_Z_MM, MAX_ITERATIONS_LIMIT, MAX_TOLERANCE_MM,
    };
    let doc = document();
    let solver = &doc["components"]["schemas"]["SolverDto"]["properties"];
    let maximum = |field: &str| solver[field]["maximum"].as_f64().expect(field);
    assert_eq!(maximum("initial_z_mm"), MAX_INITIAL_Z_MM);
    assert_eq!(maximum("gain"), MAX_GAIN);
    assert_eq!(maximum("tolerance_mm"), MAX_TOLERANCE_MM);
    assert_eq!(maximum("corner_sigma_px"), MAX_CORNER_SIGMA_PX);
    assert_eq!(maximum("max_iterations"), f64::from(MAX_ITERATIONS_LIMIT));
    assert_eq!(solver["max_iterations"]["minimum"], 1);
    for field in ["initial_z_mm", "gain", "tolerance_mm", "corner_sigma_px"] {
        assert_eq!(solver[field]["exclusiveMinimum"], 0, "{field}");
    }
    let defaults = qrpose::api::request::SolverDto::default();
    assert_eq!(solver["gain"]["default"], defaults.gain);
    assert_eq!(solver["tolerance_mm"]["default"], defaults.tolerance_mm);
    assert_eq!(solver["max_iterations"]["default"], defaults.max_iterations);
    assert_eq!(
        solver["corner_sigma_px"]["default"],
        defaults.corner_sigma_px
    );
    let prior = &doc["components"]["schemas"]["MarkerPrior"]["properties"]["sigma_deg"];
    assert_eq!(
        prior["maximum"].as_f64(),
        Some(qrpose::api::frames::MAX_PRIOR_SIGMA_DEG)
    );
    let image = &doc["paths"]["/v1/pose/image"]["post"]["parameters"];
    let parameter = |name: &str| {
        image
            .as_array()
            .and_then(|ps| ps.iter().find(|p| p["name"] == name))
            .cloned()
            .unwrap_or_else(|| panic!("{name}"))
    };
    assert_eq!(
        parameter("gain")["schema"]["maximum"].as_f64(),
        Some(MAX_GAIN)
    );
    assert_eq!(
        parameter("max_iterations")["schema"]["maximum"].as_f64(),
        Some(f64::from(MAX_ITERATIONS_LIMIT))
    );
}

const COMMITTED_ASYNCAPI: &str = include_str!("../../openapi/asyncapi.json");

#[tokio::test]
async fn the_asyncapi_document_is_committed_printed_and_served() {
    // Arrange
    let app = spawn_app().await;
    let current =
        qrpose::http::stream::asyncapi::asyncapi_json(committed(false)).expect("a document");
    let this_build = qrpose::http::stream::asyncapi::asyncapi_json(Served {
        site: false,
        zxing_cpp: Backend::ZxingCpp.is_built(),
        auth: false,
    })
    .expect("a document");

    // Act
    let served = app.get("/asyncapi.json").await.text().await.expect("text");
    let printed = tokio::process::Command::new(env!("CARGO_BIN_EXE_qrpose"))
        .arg("asyncapi")
        .output()
        .await
        .expect("qrpose runs");

    // Assert
    assert!(
        current == COMMITTED_ASYNCAPI,
        "openapi/asyncapi.json is out of date: cargo run -- asyncapi > openapi/asyncapi.json"
    );
    assert!(served == this_build, "GET /asyncapi.json differs");
    assert!(
        String::from_utf8_lossy(&printed.stdout) == this_build,
        "qrpose asyncapi differs"
    );
}
