//! The wire model's [`Rule`]s (`api::alternatives`, declared beside the types) applied to the
//! derived schemas, for the server's configuration ([`Served`]). Nothing here knows a type:
//! a split object becomes a `oneOf` of closed components made of its derived fields, a rule
//! becomes the keyword it names.
//!
//! What no schema can say (the residue) is listed in `docs/service.md`, Fuzzing: each part
//! of it is refused with its own code although the request is valid by the document.

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

/// Applies every rule of the wire model to `doc`, as `served`.
pub fn write_alternatives(doc: &mut Value, served: Served) {
    for rule in rules(served.site, served.zxing_cpp) {
        if let Rule::NoParameter(name) = rule {
            without_parameter(doc, name);
        } else if let Some(schemas) = doc
            .pointer_mut("/components/schemas")
            .and_then(Value::as_object_mut)
        {
            apply(schemas, rule);
        }
    }
}

/// Leaves query parameter `name` out of every operation. Every parameter is optional in the
/// document: the image routes take their request either as query parameters (a raw image
/// body) or in the multipart `request` part, and OpenAPI cannot tie parameters to a media
/// type; the raw form's own rule is stated in the operation's description.
fn without_parameter(doc: &mut Value, name: &str) {
    let Some(Value::Object(paths)) = doc.get_mut("paths") else {
        return;
    };
    for item in paths.values_mut() {
        if let Some(Value::Array(parameters)) = item.pointer_mut("/post/parameters") {
            parameters.retain(|p| p["name"] != name);
        }
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
        Rule::NoParameter(_) => {}
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
    for field in &form.fields {
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
            fields: fields.to_vec(),
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
        let mut doc = json!({"paths": {"/x": {"post": {"parameters": [{"name": "camera_id"}, {"name": "fx_px"}]}}}});
        without_parameter(&mut doc, "camera_id");
        assert_eq!(
            doc["paths"]["/x"]["post"]["parameters"],
            json!([{"name": "fx_px"}])
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
