//! `qrpose openapi [--site] [--auth]`: prints the OpenAPI document of a server without a
//! site (what `openapi/openapi.json` holds) or with one (`openapi/openapi-site.json`), with
//! an auth file or without (the committed ones); `qrpose asyncapi [--site] [--auth]` the
//! AsyncAPI document of its stream (`openapi/asyncapi.json`).

use clap::Args;
use qrpose::app::Backend;
use qrpose::http::openapi::{Served, openapi_json};
use std::process::ExitCode;

/// Arguments of `openapi` and `asyncapi`.
#[derive(Debug, Args)]
pub struct OpenapiArgs {
    /// The document of a server with a site loaded (`qrpose serve --site`): cameras by id,
    /// marker sizes optional.
    #[arg(long)]
    pub site: bool,
    /// The document of a server with an auth file (`qrpose serve --auth-file`): the bearer
    /// scheme, each protected operation's scope, 401 and 403.
    #[arg(long)]
    pub auth: bool,
}

/// Runs `asyncapi`: the stream's AsyncAPI document of this build.
pub fn run_asyncapi(args: &OpenapiArgs) -> ExitCode {
    let served = Served {
        site: args.site,
        zxing_cpp: Backend::ZxingCpp.is_built(),
        auth: args.auth,
    };
    match qrpose::http::stream::asyncapi::asyncapi_json(served) {
        Ok(json) => {
            print!("{json}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("qrpose asyncapi: cannot serialise the document: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Runs `openapi`: the document of this build.
pub fn run(args: &OpenapiArgs) -> ExitCode {
    let served = Served {
        site: args.site,
        zxing_cpp: Backend::ZxingCpp.is_built(),
        auth: args.auth,
    };
    match openapi_json(served) {
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
