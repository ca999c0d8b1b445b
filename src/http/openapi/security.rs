//! Who may call each operation, written into the documents (docs/security.md): the bearer
//! scheme in `components.securitySchemes`, and on every protected operation its scope as a
//! security requirement (`[{"bearer": ["pose"]}]`, OpenAPI 3.1 allows role names for any
//! scheme) with the 401 and 403 answers. The scope of an operation comes from the same rule
//! that the auth layer applies ([`access_for`]), so the document cannot disagree with it;
//! the open operations carry no requirement.
//!
//! Tokens are checked only when the server runs with `--auth-file`; the document describes
//! such a server (a token sent to a server without one is ignored).

use crate::http::auth::{Access, access_for};
use serde_json::{Value, json};

/// The name of the scheme in `components.securitySchemes`.
pub const SCHEME: &str = "bearer";

pub(crate) fn scheme_description() -> String {
    "A client's token from the auth file (`qrpose serve --auth-file`, docs/security.md): \
     `Authorization: Bearer TOKEN`. Each protected operation names the scope its client \
     needs: `pose` (/v1/pose/*, /v1/stream, /v1/calibrate), `site` (GET /v1/site), `admin` \
     (POST /v1/site/reload), `metrics` (GET /metrics). Health probes, the page and the \
     documents are open. Without `--auth-file` nothing is checked."
        .to_owned()
}

fn problem(description: &str) -> Value {
    json!({
        "description": description,
        "content": {"application/problem+json": {"schema": {"$ref": "#/components/schemas/Problem"}}},
    })
}

/// Declares the bearer scheme and each protected operation's scope, 401 and 403.
pub fn declare_security(doc: &mut Value) {
    if let Some(components) = doc.get_mut("components").and_then(Value::as_object_mut) {
        components.insert(
            "securitySchemes".to_owned(),
            json!({SCHEME: {"type": "http", "scheme": "bearer", "description": scheme_description()}}),
        );
    }
    let Some(paths) = doc.get_mut("paths").and_then(Value::as_object_mut) else {
        return;
    };
    for (path, item) in paths.iter_mut() {
        let roles = match access_for(path) {
            Access::Open => continue,
            Access::Scope(scope) => vec![scope.as_str()],
            Access::AnyClient => Vec::new(),
        };
        let Some(item) = item.as_object_mut() else {
            continue;
        };
        for operation in item.values_mut().filter_map(Value::as_object_mut) {
            if !operation.contains_key("responses") {
                continue;
            }
            operation.insert("security".to_owned(), json!([{SCHEME: roles}]));
            if let Some(responses) = operation
                .get_mut("responses")
                .and_then(Value::as_object_mut)
            {
                responses.entry("401").or_insert_with(|| {
                    problem(
                        "`unauthorized`: no bearer token, or one that no client of the auth \
                         file holds (with `WWW-Authenticate: Bearer`).",
                    )
                });
                responses.entry("403").or_insert_with(|| {
                    problem("`forbidden`: the client lacks the scope this operation needs.")
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::http::openapi::{Served, openapi_json};

    fn document(auth: bool) -> Value {
        let served = Served {
            auth,
            ..Served::default()
        };
        serde_json::from_str(&openapi_json(served).expect("renders")).expect("JSON")
    }

    #[test]
    fn without_an_auth_file_no_operation_asks_for_a_token() {
        let doc = document(false);
        let text = doc.to_string();
        assert!(!text.contains("\"security\""), "a security requirement");
        assert!(!text.contains("securitySchemes"));
        assert!(doc["paths"]["/v1/pose/image"]["post"]["responses"]["401"].is_null());
    }

    #[test]
    fn protected_operations_name_their_scope_and_open_ones_none() {
        let doc = document(true);
        let scope = |path: &str, method: &str| doc["paths"][path][method]["security"].clone();
        assert_eq!(
            scope("/v1/pose/corners", "post"),
            json!([{"bearer": ["pose"]}])
        );
        assert_eq!(scope("/v1/site", "get"), json!([{"bearer": ["site"]}]));
        assert_eq!(
            scope("/v1/site/reload", "post"),
            json!([{"bearer": ["admin"]}])
        );
        assert_eq!(scope("/metrics", "get"), json!([{"bearer": ["metrics"]}]));
        assert_eq!(scope("/healthz", "get"), Value::Null);
        assert_eq!(scope("/openapi.json", "get"), Value::Null);
        let forbidden = &doc["paths"]["/v1/pose/image"]["post"]["responses"]["403"];
        assert!(
            forbidden["description"]
                .as_str()
                .is_some_and(|d| d.contains("forbidden"))
        );
        assert_eq!(
            doc["components"]["securitySchemes"]["bearer"]["scheme"],
            "bearer"
        );
    }
}
