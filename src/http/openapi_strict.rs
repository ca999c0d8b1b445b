//! The OpenAPI document made as strict as the server (issue 16): the rules that the derived
//! schemas cannot say by themselves, added to the generated document in one place, so that
//! a client generator, a validator or a fuzzer built from the document sends what the server
//! accepts.
//!
//! - exactly one of `corners_px` / `corners_mm`, each four distinct `[u, v]` pairs;
//! - the camera in exactly one of its forms (pixels, sensor, image plane, site id), and the
//!   image-plane form with `corners_mm` only;
//! - exclusive minima and the ranges of every number the server checks (focal lengths,
//!   pixel pitch, marker size, the solver's parameters, deadlines, the prior);
//! - quaternions of four numbers, not all zero; the distortion coefficients of the lens
//!   model named (a `plumb_bob` lens has no k4-k6); non-empty image bodies and parts; a
//!   multipart form of exactly the parts `image` and `request`.
//!
//! What stays outside any schema, the *residue*: a quadrilateral that is not convex or whose
//! corners coincide, a pose behind the camera, magnitudes beyond double precision
//! (`numerically_degenerate`), bytes that are not a JPEG or PNG, a camera id or payload the
//! loaded site does not know, a marker size left out without a site default, and the camera
//! of the raw image form, whose query parameters OpenAPI can only describe one by one (its
//! forms are a rule across parameters, and so is the lens model's set of coefficients),
//! query parameters sent with a multipart body (OpenAPI cannot tie parameters to a media
//! type), and the `zxing-cpp` detector on a server built without it (`detector_unavailable`:
//! the document lists the detectors of every build). `docs/service.md`, Fuzzing, gives the figures.
//!
//! The ranges come from the constants the server validates with, never restated.

use qrpose_core::estimate::solver::{MAX_CORNER_SIGMA_PX, MAX_INITIAL_Z_MM, MAX_ITERATIONS_LIMIT};
use serde_json::{Value, json};

/// Largest `gain` of the paper's method (its validation's range, (0, 10]).
const MAX_GAIN: f64 = qrpose_core::estimate::iterative::MAX_GAIN;
/// Largest `tolerance_mm` of the paper's method ((0, 1e6]).
const MAX_TOLERANCE_MM: f64 = qrpose_core::estimate::iterative::MAX_TOLERANCE_MM;
/// Largest `sigma_deg` of a prior.
const MAX_PRIOR_SIGMA_DEG: f64 = 180.0;

/// The camera's forms, each closed: the fields of the other forms absent (or `null`).
fn camera_forms() -> [(&'static str, Value); 4] {
    let absent = json!({"type": "null"});
    let number = json!({"type": "number"});
    let positive = json!({"type": "number", "exclusiveMinimum": 0});
    [
        (
            "pixels",
            json!({"required": ["fx_px", "fy_px", "cx_px", "cy_px"], "properties": {
                "fx_px": positive, "fy_px": positive, "cx_px": number, "cy_px": number,
                "focal_length_mm": absent, "pixel_size_um": absent, "id": absent}}),
        ),
        (
            "sensor",
            json!({"required": ["focal_length_mm", "pixel_size_um", "cx_px", "cy_px"],
                "properties": {"focal_length_mm": positive, "pixel_size_um": positive,
                "cx_px": number, "cy_px": number, "fx_px": absent, "fy_px": absent, "id": absent}}),
        ),
        (
            "image plane",
            json!({"required": ["focal_length_mm"], "properties": {
                "focal_length_mm": positive, "fx_px": absent, "fy_px": absent, "cx_px": absent,
                "cy_px": absent, "id": absent}}),
        ),
        (
            "site id",
            json!({"required": ["id"], "properties": {"id": {"type": "string", "minLength": 1},
                "fx_px": absent, "fy_px": absent, "cx_px": absent, "cy_px": absent,
                "focal_length_mm": absent, "pixel_size_um": absent, "distortion": absent}}),
        ),
    ]
}

/// The camera forms named, as an `anyOf` (they are disjoint).
fn camera_of(forms: &[&str]) -> Value {
    let chosen: Vec<Value> = camera_forms()
        .into_iter()
        .filter(|(name, _)| forms.contains(name))
        .map(|(name, schema)| with_title(schema, name))
        .collect();
    json!({"anyOf": chosen})
}

fn with_title(mut schema: Value, title: &str) -> Value {
    schema["title"] = json!(title);
    schema
}

/// Four distinct `[u, v]` pairs (or `null`, which is as good as absent); corners that
/// coincide exactly are `duplicate_corners`.
fn four_points() -> Value {
    json!({"type": ["array", "null"], "minItems": 4, "maxItems": 4, "uniqueItems": true,
        "items": {"type": "array", "minItems": 2, "maxItems": 2, "items": {"type": "number"}}})
}

/// A quaternion (w, x, y, z), not all zero (it has no rotation), or `null`.
fn quaternion() -> Value {
    json!({"type": ["array", "null"], "minItems": 4, "maxItems": 4, "items": {"type": "number"},
        "not": {"type": "array", "items": {"const": 0}}})
}

/// The lens models and the coefficients each does not have (zero or absent): one schema
/// per model, `plumb_bob` also when `model` is absent or `null` (the server's default).
fn distortion_models() -> Value {
    let zero = json!({"const": 0});
    let without = |names: &[&str]| -> serde_json::Map<String, Value> {
        names
            .iter()
            .map(|n| ((*n).to_owned(), zero.clone()))
            .collect()
    };
    let mut plumb_bob = without(&["k4", "k5", "k6"]);
    plumb_bob.insert(
        "model".to_owned(),
        json!({"anyOf": [{"type": "null"}, {"const": "plumb_bob"}]}),
    );
    let mut equidistant = without(&["p1", "p2", "k5", "k6"]);
    equidistant.insert("model".to_owned(), json!({"const": "equidistant"}));
    json!({"oneOf": [
        {"title": "plumb_bob", "properties": plumb_bob},
        {"title": "rational_polynomial", "required": ["model"],
            "properties": {"model": {"const": "rational_polynomial"}}},
        {"title": "equidistant", "required": ["model"], "properties": equidistant}
    ]})
}

/// Merges `extra`'s keys into the object at `pointer` (keeping its description and the
/// rest); nothing when the document has no such object.
fn merge(doc: &mut Value, pointer: &str, extra: &Value) {
    if let Some(target) = doc.pointer_mut(pointer) {
        merge_value(target, extra);
    }
}

fn schema(name: &str) -> String {
    format!("/components/schemas/{name}")
}

fn property(name: &str, field: &str) -> String {
    format!("/components/schemas/{name}/properties/{field}")
}

/// A number in (0, max], or `null` when `nullable`.
fn positive_at_most(max: Option<f64>, nullable: bool) -> Value {
    let mut v = json!({"type": if nullable { json!(["number", "null"]) } else { json!("number") },
        "exclusiveMinimum": 0});
    if let Some(max) = max {
        v["maximum"] = json!(max);
    }
    v
}

/// The request schemas: corners, camera, marker, solver, image request, prior.
fn tighten_requests(doc: &mut Value) {
    for unit in ["corners_px", "corners_mm"] {
        merge(doc, &property("CornersRequest", unit), &four_points());
    }
    merge(
        doc,
        &schema("CornersRequest"),
        &json!({"oneOf": [
            {"title": "pixel corners", "required": ["corners_px"], "properties": {
                "corners_px": {"type": "array"},
                "corners_mm": {"type": "null"},
                "camera": camera_of(&["pixels", "sensor", "site id"])}},
            {"title": "image-plane corners", "required": ["corners_mm"], "properties": {
                "corners_mm": {"type": "array"},
                "corners_px": {"type": "null"},
                "camera": camera_of(&["image plane"])}}
        ]}),
    );
    merge(
        doc,
        &property("ImageRequest", "camera"),
        &camera_of(&["pixels", "sensor", "site id"]),
    );
    let forms: Vec<Value> = camera_forms()
        .into_iter()
        .map(|(name, schema)| with_title(schema, name))
        .collect();
    merge(doc, &schema("CameraDto"), &json!({"oneOf": forms}));
    merge(doc, &schema("DistortionDto"), &distortion_models());
    for field in ["fx_px", "fy_px", "focal_length_mm", "pixel_size_um"] {
        merge(
            doc,
            &property("CameraDto", field),
            &positive_at_most(None, true),
        );
    }
    merge(
        doc,
        &property("MarkerDto", "size_mm"),
        &positive_at_most(None, false),
    );
    merge(
        doc,
        &property("SolverDto", "initial_z_mm"),
        &positive_at_most(Some(MAX_INITIAL_Z_MM), true),
    );
    merge(
        doc,
        &property("SolverDto", "gain"),
        &positive_at_most(Some(MAX_GAIN), false),
    );
    merge(
        doc,
        &property("SolverDto", "tolerance_mm"),
        &positive_at_most(Some(MAX_TOLERANCE_MM), false),
    );
    merge(
        doc,
        &property("SolverDto", "corner_sigma_px"),
        &positive_at_most(Some(MAX_CORNER_SIGMA_PX), false),
    );
    merge(
        doc,
        &property("SolverDto", "max_iterations"),
        &json!({"minimum": 1, "maximum": MAX_ITERATIONS_LIMIT}),
    );
    merge(
        doc,
        &property("ImageRequest", "max_detect_ms"),
        &positive_at_most(None, true),
    );
    for field in ["marker_quaternion_wxyz", "robot_quaternion_wxyz"] {
        merge(doc, &property("PriorDto", field), &quaternion());
    }
    merge(
        doc,
        &property("PriorDto", "sigma_deg"),
        &positive_at_most(Some(MAX_PRIOR_SIGMA_DEG), false),
    );
    merge(
        doc,
        &schema("PriorDto"),
        &json!({"oneOf": [
            {"required": ["marker_quaternion_wxyz"], "properties": {
                "marker_quaternion_wxyz": {"type": "array"}, "robot_quaternion_wxyz": {"type": "null"}}},
            {"required": ["robot_quaternion_wxyz"], "properties": {
                "robot_quaternion_wxyz": {"type": "array"}, "marker_quaternion_wxyz": {"type": "null"}}}
        ]}),
    );
}

/// The query parameters that give the raw image form's camera.
const CAMERA_QUERY: [&str; 7] = [
    "camera_id",
    "fx_px",
    "fy_px",
    "cx_px",
    "cy_px",
    "focal_length_mm",
    "pixel_size_um",
];

/// The camera forms of the raw image form, by their query parameters.
const CAMERA_QUERY_FORMS: [&[&str]; 3] = [
    &["fx_px", "fy_px", "cx_px", "cy_px"],
    &["focal_length_mm", "pixel_size_um", "cx_px", "cy_px"],
    &["camera_id"],
];

/// Replaces the camera's separate query parameters by one object parameter `camera`
/// (`style: form, explode: true`: each property is its own query parameter, exactly the
/// wire format the server reads) whose schema is `oneOf` the camera's forms. OpenAPI cannot
/// say "these parameters together, or those" of separate parameters; of one object
/// parameter it can.
fn camera_query_object(parameters: &mut Vec<Value>) {
    let mut fields = serde_json::Map::new();
    parameters.retain(|p| {
        let Some(name) = p["name"].as_str().filter(|n| CAMERA_QUERY.contains(n)) else {
            return true;
        };
        let mut schema = p["schema"].clone();
        if schema["type"].is_array() {
            schema["type"] = json!(if name == "camera_id" {
                "string"
            } else {
                "number"
            });
        }
        if name == "camera_id" {
            schema["minLength"] = json!(1);
        }
        schema["description"] = p["description"].clone();
        fields.insert(name.to_owned(), schema);
        false
    });
    if fields.is_empty() {
        return;
    }
    let forms: Vec<Value> = CAMERA_QUERY_FORMS
        .iter()
        .map(|names| {
            let properties: serde_json::Map<String, Value> = names
                .iter()
                .filter_map(|n| fields.get(*n).map(|f| ((*n).to_owned(), f.clone())))
                .collect();
            json!({"type": "object", "required": names, "properties": properties,
                "additionalProperties": false})
        })
        .collect();
    parameters.insert(
        0,
        json!({"name": "camera", "in": "query", "required": true, "style": "form",
            "explode": true,
            "description": "The camera, as separate query parameters in one of three forms: \
                `fx_px`, `fy_px`, `cx_px`, `cy_px` (pixels); `focal_length_mm`, `pixel_size_um`, \
                `cx_px`, `cy_px` (sensor); or `camera_id` (a camera of the loaded site).",
            "schema": {"oneOf": forms}}),
    );
}

/// The query parameters of the raw-body image form: the same minima as the JSON fields, and
/// the camera as one object parameter ([`camera_query_object`]).
fn tighten_query_parameters(doc: &mut Value) {
    let Some(Value::Object(paths)) = doc.get_mut("paths") else {
        return;
    };
    for item in paths.values_mut() {
        let Some(Value::Array(parameters)) = item.pointer_mut("/post/parameters") else {
            continue;
        };
        for parameter in parameters {
            let name = parameter["name"].as_str().unwrap_or_default().to_owned();
            let extra = match name.as_str() {
                "fx_px" | "fy_px" | "focal_length_mm" | "pixel_size_um" | "marker_size_mm"
                | "max_detect_ms" => positive_at_most(None, true),
                "initial_z_mm" => positive_at_most(Some(MAX_INITIAL_Z_MM), true),
                "gain" => positive_at_most(Some(MAX_GAIN), true),
                "tolerance_mm" => positive_at_most(Some(MAX_TOLERANCE_MM), true),
                "corner_sigma_px" => positive_at_most(Some(MAX_CORNER_SIGMA_PX), true),
                "max_iterations" => json!({"minimum": 1, "maximum": MAX_ITERATIONS_LIMIT}),
                _ => continue,
            };
            if let Some(schema) = parameter.get_mut("schema") {
                merge_value(schema, &extra);
            }
        }
    }
    for item in paths.values_mut() {
        if let Some(Value::Array(parameters)) = item.pointer_mut("/post/parameters") {
            camera_query_object(parameters);
        }
    }
}

/// Merges `extra`'s keys into `target` when both are objects.
fn merge_value(target: &mut Value, extra: &Value) {
    if let (Value::Object(target), Value::Object(extra)) = (target, extra) {
        for (key, value) in extra {
            target.insert(key.clone(), value.clone());
        }
    }
}

/// Image bodies and parts: at least one byte.
fn tighten_bodies(doc: &mut Value) {
    let Some(Value::Object(paths)) = doc.get_mut("paths") else {
        return;
    };
    for item in paths.values_mut() {
        let Some(Value::Object(content)) = item.pointer_mut("/post/requestBody/content") else {
            continue;
        };
        for (media_type, body) in content.iter_mut() {
            if let Some(schema) = body
                .get_mut("schema")
                .filter(|_| media_type.starts_with("image/"))
            {
                merge_value(schema, &json!({"minLength": 1}));
            }
        }
    }
    for form in ["ImageForm", "AnnotatedImageForm"] {
        merge(doc, &property(form, "image"), &json!({"minLength": 1}));
        // Exactly the two parts: any other is refused (`unknown_field`).
        merge(
            doc,
            &schema(form),
            &json!({"required": ["image", "request"], "additionalProperties": false}),
        );
    }
}

/// The generated document with every rule above added.
pub fn tighten(doc: &mut Value) {
    tighten_requests(doc);
    tighten_query_parameters(doc);
    tighten_bodies(doc);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_schema_is_left_alone_and_a_present_one_gains_the_rule() {
        let mut doc = json!({"components": {"schemas": {
            "MarkerDto": {"type": "object", "properties": {"size_mm": {"type": "number",
                "description": "kept"}}}}}});
        tighten(&mut doc);
        let size = &doc["components"]["schemas"]["MarkerDto"]["properties"]["size_mm"];
        assert_eq!(size["exclusiveMinimum"], json!(0));
        assert_eq!(size["description"], json!("kept"));
        assert!(doc["components"]["schemas"].get("CornersRequest").is_none());
    }
}
