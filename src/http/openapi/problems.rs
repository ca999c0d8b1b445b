//! Each operation's 422 answer, written from the one list of its codes
//! ([`Operation::unprocessable`]): the description ends with the codes, and
//! `x-problem-codes` lists them for generators and tests.

use crate::api::problem::operations::{OPERATIONS, Operation};
use serde_json::{Value, json};

/// The 422 response of `operation`'s `POST`.
fn unprocessable(doc: &mut Value, operation: Operation) -> Option<&mut Value> {
    let path = operation.path().replace('~', "~0").replace('/', "~1");
    doc.pointer_mut(&format!("/paths/{path}/post/responses/422"))
}

/// Writes every operation's codes into its 422 response.
pub fn write_problem_codes(doc: &mut Value) {
    for operation in OPERATIONS {
        let codes = json!(operation.unprocessable());
        let Some(response) = unprocessable(doc, operation) else {
            continue;
        };
        let names: Vec<String> = codes
            .as_array()
            .into_iter()
            .flatten()
            .map(|c| format!("`{}`", c.as_str().unwrap_or_default()))
            .collect();
        let description = response["description"].as_str().unwrap_or_default();
        response["description"] = json!(format!("{description} Codes: {}.", names.join(", ")));
        response["x-problem-codes"] = codes;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::http::openapi::{Served, openapi_json};

    #[test]
    fn every_operation_of_the_list_has_its_422_codes_in_the_document() {
        let json = openapi_json(Served::default()).expect("a document");
        let mut doc: Value = serde_json::from_str(&json).expect("JSON");
        for operation in OPERATIONS {
            let want = json!(operation.unprocessable());
            let response = unprocessable(&mut doc, operation).expect("a 422 response");
            assert_eq!(response["x-problem-codes"], want, "{operation:?}");
            let description = response["description"].as_str().expect("a description");
            assert!(description.contains(&format!("`{}`", want[0].as_str().expect("a code"))));
        }
    }
}
