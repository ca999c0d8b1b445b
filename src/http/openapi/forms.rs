//! The bodies of the image routes: the raw image as binary (`#[utoipa::path]` gives a media
//! type without a schema, which generators skip), and the multipart form with the media type
//! of each part (OpenAPI's `encoding`, which `#[utoipa::path]` cannot express), closed to
//! other parts (the server refuses any part but `image` and `request`, `unknown_field`).

use crate::http::image_input::{IMAGE_PART, JPEG, MULTIPART, PNG, REQUEST_PART};
use crate::http::routes::{annotated, image};
use serde_json::{Value, json};

/// The JSON pointer of the body of `POST path` in `media_type`.
fn body_pointer(path: &str, media_type: &str) -> String {
    let escape = |s: &str| s.replace('~', "~0").replace('/', "~1");
    format!(
        "/paths/{}/post/requestBody/content/{}",
        escape(path),
        escape(media_type)
    )
}

/// Documents the raw and multipart bodies of every image route.
pub fn document_forms(doc: &mut Value) {
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
        if let Some(schema) = form.get_mut("schema").and_then(Value::as_object_mut) {
            schema.insert("additionalProperties".to_owned(), json!(false));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_image_route_s_form_gets_its_part_types_and_is_closed() {
        let form = json!({"schema": {"type": "object", "required": ["image", "request"]}});
        let content = json!({MULTIPART: form, JPEG: {}, PNG: {}});
        let mut doc = json!({"paths": {
            image::PATH: {"post": {"requestBody": {"content": content.clone()}}},
            annotated::PATH: {"post": {"requestBody": {"content": content}}}
        }});
        document_forms(&mut doc);
        for path in [image::PATH, annotated::PATH] {
            let c = &doc["paths"][path]["post"]["requestBody"]["content"];
            let f = &c[MULTIPART];
            assert_eq!(
                f["encoding"][REQUEST_PART]["contentType"],
                "application/json"
            );
            assert_eq!(f["schema"]["additionalProperties"], false);
            assert_eq!(c[JPEG]["schema"]["format"], "binary");
        }
    }
}
