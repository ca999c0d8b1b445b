//! The bodies of the image routes: the raw image as binary (`#[utoipa::path]` gives a media
//! type without a schema, which generators skip), and the multipart form with the media type
//! of each part (OpenAPI's `encoding`, which `#[utoipa::path]` cannot express), closed to
//! other parts (the server refuses any part but `image` and `request`, `unknown_field`).
//! The `image` part is also `format: binary` beside its `contentMediaType`: generators that
//! read only the OpenAPI 3.0 form (openapi-python-client) then send it as a file of bytes,
//! not as text. The calibration's form (`POST /v1/calibrate`, its parts documented on
//! `CalibrateForm`) is closed the same way: the server refuses any part but `image` and
//! `request` there too.

use crate::http::image_input::{IMAGE_PART, JPEG, MULTIPART, PNG, REQUEST_PART};
use crate::http::routes::{annotated, calibrate, hand_eye, image};
use serde_json::{Map, Value, json};

/// The JSON pointer of the body of `POST path` in `media_type`.
fn body_pointer(path: &str, media_type: &str) -> String {
    let escape = |s: &str| s.replace('~', "~0").replace('/', "~1");
    format!(
        "/paths/{}/post/requestBody/content/{}",
        escape(path),
        escape(media_type)
    )
}

/// Closes the multipart form of `POST path` to parts it does not name; the form's schema.
fn close_form<'a>(doc: &'a mut Value, path: &str) -> Option<&'a mut Map<String, Value>> {
    let pointer = format!("{}/schema", body_pointer(path, MULTIPART));
    let schema = doc.pointer_mut(&pointer)?.as_object_mut()?;
    schema.insert("additionalProperties".to_owned(), json!(false));
    Some(schema)
}

/// Documents the raw and multipart bodies of every image route, and closes the
/// calibration's form.
pub fn document_forms(doc: &mut Value) {
    close_form(doc, calibrate::PATH);
    close_form(doc, hand_eye::PATH);
    for path in [image::PATH, annotated::PATH] {
        for media_type in [JPEG, PNG] {
            if let Some(raw) = doc.pointer_mut(&body_pointer(path, media_type)) {
                raw["schema"] = json!({"type": "string", "format": "binary"});
            }
        }
        let Some(form) = doc.pointer_mut(&body_pointer(path, MULTIPART)) else {
            continue;
        };
        form["encoding"] = json!({
            IMAGE_PART: {"contentType": "image/jpeg, image/png"},
            REQUEST_PART: {"contentType": "application/json"},
        });
        if let Some(Value::Object(image)) = close_form(doc, path)
            .and_then(|schema| schema.get_mut("properties")?.get_mut(IMAGE_PART))
        {
            image.insert("format".to_owned(), json!("binary"));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_image_route_s_form_gets_its_part_types_and_every_form_is_closed() {
        let form = json!({"schema": {"type": "object", "required": ["image", "request"],
            "properties": {"image": {"type": "string"}}}});
        let content = json!({MULTIPART: form, JPEG: {}, PNG: {}});
        let calibration = json!({MULTIPART: {"schema": {"type": "object"}}});
        let mut doc = json!({"paths": {
            image::PATH: {"post": {"requestBody": {"content": content.clone()}}},
            annotated::PATH: {"post": {"requestBody": {"content": content}}},
            calibrate::PATH: {"post": {"requestBody": {"content": calibration}}}
        }});
        document_forms(&mut doc);
        let calibration = &doc["paths"][calibrate::PATH]["post"]["requestBody"]["content"];
        assert_eq!(
            calibration[MULTIPART]["schema"]["additionalProperties"],
            false
        );
        for path in [image::PATH, annotated::PATH] {
            let c = &doc["paths"][path]["post"]["requestBody"]["content"];
            let f = &c[MULTIPART];
            assert_eq!(
                f["encoding"][REQUEST_PART]["contentType"],
                "application/json"
            );
            assert_eq!(f["schema"]["additionalProperties"], false);
            assert_eq!(f["schema"]["properties"][IMAGE_PART]["format"], "binary");
            assert_eq!(c[JPEG]["schema"]["format"], "binary");
        }
    }
}
