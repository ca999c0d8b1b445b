//! `qrpose openapi`: prints the OpenAPI document (what `openapi/openapi.json` holds).

use qrpose::http::openapi::openapi_json;
use std::process::ExitCode;

/// Runs `openapi`.
pub fn run() -> ExitCode {
    match openapi_json() {
        Ok(json) => {
            print!("{json}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("qrpose openapi: cannot serialise the document: {e}");
            ExitCode::FAILURE
        }
    }
}
