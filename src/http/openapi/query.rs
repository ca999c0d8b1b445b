//! The query parameters of the image routes as the server's configuration allows them:
//! without a loaded site there is no `camera_id` to give.
//!
//! Every parameter is optional in the document, as it must be: the routes take their
//! request either as query parameters (a raw image body) or in the multipart `request` part
//! (with any query parameters underneath), and OpenAPI cannot tie parameters to a media
//! type. The raw form's own rule, the camera in one of its forms and (without a site) the
//! marker size, is stated in the operation's description, and the flat parameters keep
//! generated clients simple (one argument each).

use super::alternatives::Served;
use serde_json::Value;

/// The parameter of the site camera's id.
const CAMERA_ID: &str = "camera_id";

/// Leaves out what `served` does not accept.
pub fn parameters_as_served(doc: &mut Value, served: Served) {
    if served.site {
        return;
    }
    let Some(Value::Object(paths)) = doc.get_mut("paths") else {
        return;
    };
    for item in paths.values_mut() {
        if let Some(Value::Array(parameters)) = item.pointer_mut("/post/parameters") {
            parameters.retain(|p| p["name"] != CAMERA_ID);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn without_a_site_there_is_no_camera_id() {
        let doc = json!({"paths": {"/x": {"post": {"parameters": [
            {"name": CAMERA_ID}, {"name": "fx_px"}]}}}});
        for site in [false, true] {
            let mut d = doc.clone();
            parameters_as_served(
                &mut d,
                Served {
                    site,
                    ..Served::default()
                },
            );
            let names: Vec<&Value> = d["paths"]["/x"]["post"]["parameters"]
                .as_array()
                .expect("parameters")
                .iter()
                .map(|p| &p["name"])
                .collect();
            assert_eq!(names.len(), if site { 2 } else { 1 }, "site {site}");
        }
    }
}
