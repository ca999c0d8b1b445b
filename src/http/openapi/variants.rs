//! Request bodies whose valid forms are alternatives, written as the alternatives: a
//! `oneOf` of complete schemas, each a component of its own, closed with
//! `additionalProperties: false`. Generators make typed unions of them
//! (`PixelCornersRequest | PlaneCornersRequest`) and validators check them exactly.
//!
//! The wire types are single structs (one deserialiser, the same problem documents as ever),
//! so their derived schema is one object with every field optional. The only thing added here
//! is the cross-field rule: which fields make up each alternative and which of them it
//! requires. Every field's schema (type, description, range, default) is taken from the
//! derived object as the DTO declares it; nothing is restated.

use serde_json::{Map, Value, json};

/// One alternative of a union: a component built from some fields of the derived object.
pub struct Variant {
    /// The component's name.
    pub name: &'static str,
    /// What the alternative is, for people: the first line of its description. Not a
    /// `title`, which generators take for the class name (openapi-python-client would make
    /// `CornersInPixels` of "corners in pixels" instead of `PixelCornersRequest`).
    pub summary: &'static str,
    /// The derived object's fields that make it up.
    pub fields: &'static [&'static str],
    /// The fields it requires (never null).
    pub required: &'static [&'static str],
    /// Fields whose schema differs in this alternative (a narrower camera, a fixed model).
    pub overrides: Vec<(&'static str, Value)>,
}

/// A `$ref` to component `name`.
pub fn reference(name: &str) -> Value {
    json!({"$ref": format!("#/components/schemas/{name}")})
}

/// Replaces component `name` by a `oneOf` of `variants`, each added as a component built
/// from `name`'s derived properties. Nothing happens when the document has no `name`.
pub fn split(doc: &mut Value, name: &str, variants: &[Variant]) {
    let Some(schemas) = doc
        .pointer_mut("/components/schemas")
        .and_then(Value::as_object_mut)
    else {
        return;
    };
    let Some(object) = schemas.get(name).cloned() else {
        return;
    };
    for v in variants {
        schemas.insert(v.name.to_owned(), variant_of(&object, v));
    }
    let mut union = Map::new();
    for key in ["description", "example"] {
        if let Some(value) = object.get(key) {
            union.insert(key.to_owned(), value.clone());
        }
    }
    union.insert(
        "oneOf".to_owned(),
        Value::Array(variants.iter().map(|v| reference(v.name)).collect()),
    );
    schemas.insert(name.to_owned(), Value::Object(union));
}

/// The closed object of one alternative.
fn variant_of(object: &Value, v: &Variant) -> Value {
    let mut properties = Map::new();
    for field in v.fields {
        let derived = object["properties"][*field].clone();
        let schema = match v.overrides.iter().find(|(name, _)| name == field) {
            Some((_, narrower)) => with_description_of(narrower.clone(), &derived),
            None => derived,
        };
        let schema = if v.required.contains(field) {
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
        Some(description) => json!(format!("This alternative: {}.\n\n{description}", v.summary)),
        None => json!(format!("This alternative: {}.", v.summary)),
    };
    if !v.required.is_empty() {
        out["required"] = json!(v.required);
    }
    out
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
pub fn non_null(mut schema: Value) -> Value {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn doc() -> Value {
        json!({"components": {"schemas": {"Thing": {
            "type": "object", "description": "A thing.",
            "properties": {
                "a": {"type": ["number", "null"], "description": "A, mm.", "exclusiveMinimum": 0},
                "b": {"oneOf": [{"$ref": "#/components/schemas/B", "description": "B."},
                                {"type": "null"}]},
                "c": {"type": "string", "description": "C."}
            },
            "additionalProperties": false}}}})
    }

    #[test]
    fn a_split_object_becomes_a_one_of_of_closed_alternatives() {
        let mut d = doc();
        split(
            &mut d,
            "Thing",
            &[
                Variant {
                    name: "ThingA",
                    summary: "with a",
                    fields: &["a", "c"],
                    required: &["a"],
                    overrides: vec![],
                },
                Variant {
                    name: "ThingB",
                    summary: "with b",
                    fields: &["b", "c"],
                    required: &["b"],
                    overrides: vec![("c", json!({"const": "x"}))],
                },
            ],
        );
        let s = &d["components"]["schemas"];
        assert_eq!(
            s["Thing"]["oneOf"],
            json!([reference("ThingA"), reference("ThingB")])
        );
        assert_eq!(s["Thing"]["description"], "A thing.");
        let a = &s["ThingA"];
        assert_eq!(a["description"], "This alternative: with a.\n\nA thing.");
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
        assert!(a["properties"].get("b").is_none());
        let b = &s["ThingB"];
        assert_eq!(b["properties"]["b"], reference_with_description());
        assert_eq!(
            b["properties"]["c"],
            json!({"const": "x", "description": "C."})
        );
    }

    fn reference_with_description() -> Value {
        json!({"$ref": "#/components/schemas/B", "description": "B."})
    }

    #[test]
    fn a_document_without_the_object_is_left_alone() {
        let mut d = json!({"components": {"schemas": {}}});
        split(&mut d, "Thing", &[]);
        assert_eq!(d, json!({"components": {"schemas": {}}}));
    }
}
