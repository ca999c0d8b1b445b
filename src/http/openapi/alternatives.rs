//! The wire model's [`Rule`]s (`api::alternatives`, declared beside the types) applied to the
//! derived schemas, for the server's configuration ([`Served`]). Nothing here knows a type:
//! a split object becomes a `oneOf` of closed components made of its derived fields, a rule
//! becomes the keyword it names.
//!
//! What stays outside any schema (the residue, `docs/service.md`, Fuzzing), each refused
//! with its own code although the request is valid by the document:
//! - a quadrilateral that is not convex or not clockwise, or whose corners nearly coincide
//!   or nearly lie on a line (`non_convex_corners`, `mirrored_corners`,
//!   `duplicate_corners`, `collinear_corners`: relative tolerances no schema can state);
//! - corners no pose fits: the paper's iteration settles only on axis and square on, and
//!   elsewhere can drift until its corners are collinear (`no_solution`); a corner that
//!   cannot be undistorted with the given coefficients (`undistortion_failed`);
//! - magnitudes beyond double precision: corners that overflow once divided by the pixel
//!   size, a quaternion too small to normalise (`numerically_degenerate`, `invalid_prior`;
//!   a robot pose's quaternion whose norm is off 1 by more than 1e-3, `invalid_robot_pose`);
//! - bytes that are not a JPEG or PNG (`undecodable_image`); photos for `POST /v1/calibrate`
//!   that do not show one code, decoded in at least three of them, at one size
//!   (`no_code_found`, `too_few_views`, `mixed_image_sizes`);
//! - a camera id or payload the loaded site does not know (`unknown_camera`,
//!   `unknown_marker_size`);
//! - what OpenAPI cannot tie across the query and the body: with a raw image body the camera
//!   (in one of its forms) and, without a site, `marker_size_mm` are required; and
//!   `points = finders` with another method when one of them comes from the query.
//!
//! And one place where the server accepts more than the document: a multipart `request`
//! part without the camera or marker when the query parameters give them (the document
//! requires them in the part).

use crate::api::alternatives::{Form, Narrowed, Rule, rules};
use serde_json::{Map, Value, json};

/// What the served document says depends on: the server's configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Served {
    /// A site file is loaded (`qrpose serve --site`): cameras by id, sizes by payload.
    pub site: bool,
    /// The zxing-cpp detector is built in (cargo feature `zxing-cpp`).
    pub zxing_cpp: bool,
    /// An auth file is loaded (`qrpose serve --auth-file`): the protected operations need
    /// a bearer token. Without one every operation is open and the document asks for none.
    pub auth: bool,
}

/// Applies every rule of the wire model to `doc`'s schemas, as `served`.
pub fn write_alternatives(doc: &mut Value, served: Served) {
    let Some(schemas) = doc
        .pointer_mut("/components/schemas")
        .and_then(Value::as_object_mut)
    else {
        return;
    };
    for rule in rules(served.site, served.zxing_cpp) {
        apply(schemas, rule);
    }
}

/// Applies `rule`; a rule on a component the document lacks does nothing.
fn apply(schemas: &mut Map<String, Value>, rule: Rule) {
    match rule {
        Rule::Split {
            component,
            forms,
            only_within,
        } => split(schemas, component, &forms, only_within),
        Rule::Require { component, field } => {
            if let Some(schema) = schemas.get_mut(component) {
                require(schema, field);
            }
        }
        Rule::Not { component, schema } => {
            if let Some(object) = schemas.get_mut(component) {
                object["not"] = schema;
            }
        }
        Rule::Without { component, value } => {
            if let Some(Value::Array(values)) =
                schemas.get_mut(component).and_then(|s| s.get_mut("enum"))
            {
                values.retain(|v| v != value);
            }
        }
    }
}

/// A `$ref` to component `name`.
fn reference(name: &str) -> Value {
    json!({"$ref": format!("#/components/schemas/{name}")})
}

/// Replaces component `name` by a `oneOf` of `forms` (but those `only_within`), each added
/// as a component built from `name`'s derived properties.
fn split(schemas: &mut Map<String, Value>, name: &str, forms: &[Form], only_within: &[&str]) {
    let Some(object) = schemas.get(name).cloned() else {
        return;
    };
    for form in forms {
        schemas.insert(form.name.to_owned(), form_of(&object, form));
    }
    let mut union = Map::new();
    for key in ["description", "example"] {
        if let Some(value) = object.get(key) {
            union.insert(key.to_owned(), value.clone());
        }
    }
    let members = forms.iter().filter(|f| !only_within.contains(&f.name));
    union.insert(
        "oneOf".to_owned(),
        members.map(|f| reference(f.name)).collect(),
    );
    schemas.insert(name.to_owned(), Value::Object(union));
}

/// The closed object of one form. Not a `title`, which generators take for the class name
/// (openapi-python-client would make `CornersInPixels` of "corners in pixels" instead of
/// `PixelCornersRequest`): the summary opens the description.
fn form_of(object: &Value, form: &Form) -> Value {
    let mut properties = Map::new();
    for field in form.fields {
        let derived = object["properties"][*field].clone();
        let schema = match form.narrowed.iter().find(|(name, _)| name == field) {
            Some((_, Narrowed::To(narrower))) => with_description_of(narrower.clone(), &derived),
            Some((_, Narrowed::With(keywords))) => with_keywords(derived, keywords),
            None => derived,
        };
        let schema = if form.required.contains(field) {
            non_null(schema)
        } else {
            schema
        };
        properties.insert((*field).to_owned(), schema);
    }
    let mut out = json!({
        "type": "object",
        "properties": properties,
        "additionalProperties": false,
    });
    out["description"] = match object.get("description").and_then(Value::as_str) {
        Some(description) => json!(format!(
            "This alternative: {}.\n\n{description}",
            form.summary
        )),
        None => json!(format!("This alternative: {}.", form.summary)),
    };
    if !form.required.is_empty() {
        out["required"] = json!(form.required);
    }
    out
}

/// `schema` with `keywords` added.
fn with_keywords(mut schema: Value, keywords: &Value) -> Value {
    if let (Some(map), Some(keywords)) = (schema.as_object_mut(), keywords.as_object()) {
        for (k, v) in keywords {
            map.insert(k.clone(), v.clone());
        }
    }
    schema
}

/// `narrower` with the derived field's description (or that of its `oneOf` branch, for an
/// optional reference).
fn with_description_of(mut narrower: Value, derived: &Value) -> Value {
    let description = derived.get("description").cloned().or_else(|| {
        derived["oneOf"]
            .as_array()?
            .iter()
            .find_map(|b| b.get("description").cloned())
    });
    if let (Some(d), Some(map)) = (description, narrower.as_object_mut()) {
        map.entry("description").or_insert(d);
    }
    narrower
}

/// `schema` without `null` among its values: `type: [T, "null"]` becomes `type: T`, and an
/// optional reference (`oneOf: [{$ref}, {type: null}]`) becomes the reference.
fn non_null(mut schema: Value) -> Value {
    if let Some(types) = schema.get("type").and_then(Value::as_array) {
        let kept: Vec<Value> = types.iter().filter(|t| *t != "null").cloned().collect();
        schema["type"] = match kept.as_slice() {
            [one] => one.clone(),
            _ => Value::Array(kept),
        };
    }
    if let Some(branches) = schema.get("oneOf").and_then(Value::as_array) {
        let kept: Vec<Value> = branches
            .iter()
            .filter(|b| b.get("type") != Some(&json!("null")))
            .cloned()
            .collect();
        if let [one] = kept.as_slice() {
            return one.clone();
        }
    }
    schema
}

/// Makes `field` of `schema` required (and never null).
fn require(schema: &mut Value, field: &str) {
    if let Some(property) = schema.pointer_mut(&format!("/properties/{field}")) {
        *property = non_null(property.take());
    }
    match schema.get_mut("required").and_then(Value::as_array_mut) {
        Some(required) if !required.contains(&json!(field)) => required.push(json!(field)),
        Some(_) => {}
        None => schema["required"] = json!([field]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn schemas() -> Map<String, Value> {
        let doc = json!({"Thing": {
            "type": "object", "description": "A thing.",
            "properties": {
                "a": {"type": ["number", "null"], "description": "A, mm.", "exclusiveMinimum": 0},
                "b": {"oneOf": [{"$ref": "#/components/schemas/B", "description": "B."},
                                {"type": "null"}]},
                "c": {"type": "string", "description": "C."}
            },
            "additionalProperties": false}});
        doc.as_object().cloned().expect("an object")
    }

    fn form(
        name: &'static str,
        fields: &'static [&'static str],
        narrowed: Vec<(&'static str, Narrowed)>,
    ) -> Form {
        Form {
            name,
            summary: name,
            fields,
            required: &fields[..1],
            narrowed,
        }
    }

    #[test]
    fn a_split_object_becomes_a_one_of_of_closed_forms_of_its_derived_fields() {
        let mut s = schemas();
        let forms = [
            form(
                "ThingA",
                &["a", "c"],
                vec![("c", Narrowed::With(json!({"minLength": 1})))],
            ),
            form(
                "ThingB",
                &["b", "c"],
                vec![("c", Narrowed::To(json!({"const": "x"})))],
            ),
            form("ThingC", &["c"], vec![]),
        ];
        split(&mut s, "Thing", &forms, &["ThingC"]);
        assert_eq!(
            s["Thing"]["oneOf"],
            json!([reference("ThingA"), reference("ThingB")])
        );
        assert_eq!(s["Thing"]["description"], "A thing.");
        assert!(
            s.contains_key("ThingC"),
            "kept out of the union, not out of the document"
        );
        let a = &s["ThingA"];
        assert_eq!(a["description"], "This alternative: ThingA.\n\nA thing.");
        assert!(
            a.get("title").is_none(),
            "no title: generators name classes by it"
        );
        assert_eq!(a["additionalProperties"], false);
        assert_eq!(a["required"], json!(["a"]));
        assert_eq!(a["properties"]["a"]["type"], "number", "required: not null");
        assert_eq!(
            a["properties"]["a"]["exclusiveMinimum"], 0,
            "the DTO's range"
        );
        assert_eq!(
            a["properties"]["c"],
            json!({"type": "string", "description": "C.", "minLength": 1})
        );
        assert!(a["properties"].get("b").is_none());
        let b = &s["ThingB"];
        assert_eq!(
            b["properties"]["b"],
            json!({"$ref": "#/components/schemas/B", "description": "B."})
        );
        assert_eq!(
            b["properties"]["c"],
            json!({"const": "x", "description": "C."})
        );
    }

    #[test]
    fn rules_on_a_missing_component_do_nothing_and_a_required_field_loses_its_null() {
        let mut s = Map::new();
        split(&mut s, "Thing", &[], &[]);
        apply(
            &mut s,
            Rule::Require {
                component: "Thing",
                field: "a",
            },
        );
        assert!(s.is_empty());
        let mut s = schemas();
        apply(
            &mut s,
            Rule::Require {
                component: "Thing",
                field: "b",
            },
        );
        apply(
            &mut s,
            Rule::Require {
                component: "Thing",
                field: "b",
            },
        );
        assert_eq!(s["Thing"]["required"], json!(["b"]));
        assert_eq!(
            s["Thing"]["properties"]["b"],
            json!({"$ref": "#/components/schemas/B", "description": "B."})
        );
        s.insert("E".to_owned(), json!({"enum": ["x", "y"]}));
        apply(
            &mut s,
            Rule::Without {
                component: "E",
                value: "y",
            },
        );
        assert_eq!(s["E"]["enum"], json!(["x"]));
    }
}
