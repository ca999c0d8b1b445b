//! The `qrpose` command line: one subcommand per file, each printing the same JSON as the
//! HTTP API.
//!
//! Exit codes: 0 success; 2 the input was refused (the problem+json document is on
//! stderr); 1 anything else (I/O, internal).

mod auth;
mod calibrate;
mod estimate;
mod healthcheck;
mod openapi;
mod serve;
mod sim;
mod site;
mod track;

use clap::{Parser, Subcommand};
use qrpose::api::{
    image::ImageQuery,
    problem::{ErrorCode, Problem},
};
use std::process::ExitCode;

/// Exit code for input the API would answer with a 4xx problem.
pub const EXIT_BAD_INPUT: u8 = 2;
/// Exit code when the reader of standard output went away (128 + SIGPIPE, as a shell
/// reports a process that a closed pipe killed).
pub const EXIT_BROKEN_PIPE: u8 = 141;

/// qrpose: where a QR code is in 3D and how it is turned, from one camera image.
#[derive(Debug, Parser)]
#[command(name = "qrpose", version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Estimate a pose: prints what `POST /v1/pose/corners` would return.
    Estimate(estimate::EstimateArgs),
    /// Calibrate the camera from 3 to 100 photos of a printed QR code: prints what
    /// `POST /v1/calibrate` returns; `--out FILE.yaml` writes the OpenCV file a site file
    /// reads.
    Calibrate(calibrate::CalibrateArgs),
    /// Run the HTTP service (docs/service.md) until SIGTERM or SIGINT.
    Serve(qrpose::config::ServeArgs),
    /// Print the OpenAPI document (what `openapi/openapi.json` holds).
    Openapi(openapi::OpenapiArgs),
    /// Print the AsyncAPI document of the stream's messages (what `openapi/asyncapi.json`
    /// holds).
    Asyncapi(openapi::OpenapiArgs),
    /// Exit 0 when the service's /healthz answers 200 (for container health checks).
    Healthcheck(healthcheck::HealthcheckArgs),
    /// Site files (docs/site.md): `qrpose site check FILE` validates one and prints what it
    /// resolves to.
    Site(site::SiteArgs),
    /// Track codes over a sequence of frames: one JSON line per frame, what `GET /v1/stream`
    /// answers for it.
    Track(track::TrackArgs),
    /// Clients of the auth file (docs/security.md): `qrpose auth add NAME --scopes pose`
    /// prints a new token once and the file's entry.
    Auth(auth::AuthArgs),
    /// A synthetic photo of a code with its ground truth: runs `qrpose-sim render` (the
    /// developer binary, `cargo build --release -p qrpose-sim`) with these arguments.
    Render(sim::SimArgs),
    /// The paper's simulation (its Figures 8-12): runs `qrpose-sim simulate` with these
    /// arguments.
    Simulate(sim::SimArgs),
}

/// A command-line mistake in one of `estimate --image`'s parameters as the problem document
/// the same mistake in the query string gets (`unknown_variant` or `malformed_query`, with
/// the parameter's name as `field`), on stderr with the bad-input exit code; any other
/// mistake as clap reports it.
pub fn report_parse_error(err: &clap::Error) -> ExitCode {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    let parameter = match err.get(ContextKind::InvalidArg) {
        Some(ContextValue::String(arg)) => arg
            .split_whitespace()
            .next()
            .and_then(|flag| flag.strip_prefix("--"))
            .map(|flag| flag.replace('-', "_"))
            .filter(|name| ImageQuery::parameter_names().contains(name)),
        _ => None,
    };
    let value_error = matches!(
        err.kind(),
        ErrorKind::InvalidValue | ErrorKind::ValueValidation
    );
    let Some(parameter) = parameter.filter(|_| value_error) else {
        // Help and version go to stdout with exit 0; usage errors to stderr with exit 2.
        let _ = err.print();
        return ExitCode::from(u8::try_from(err.exit_code()).unwrap_or(EXIT_BAD_INPUT));
    };
    let code = if err.get(ContextKind::ValidValue).is_some() {
        ErrorCode::UnknownVariant
    } else {
        ErrorCode::MalformedQuery
    };
    let rendered = err.render().to_string();
    let detail = rendered
        .lines()
        .next()
        .unwrap_or_default()
        .trim_start_matches("error: ")
        .to_owned();
    estimate::report_problem(&Problem::new(code, detail).with_field(parameter))
}

/// Runs the parsed command line.
pub fn run(cli: Cli) -> ExitCode {
    match cli.command {
        Command::Estimate(args) => estimate::run(&args),
        Command::Calibrate(args) => calibrate::run(&args),
        Command::Serve(args) => serve::run(args),
        Command::Openapi(args) => openapi::run(&args),
        Command::Asyncapi(args) => openapi::run_asyncapi(&args),
        Command::Healthcheck(args) => healthcheck::run(&args),
        Command::Site(args) => site::run(&args),
        Command::Track(args) => track::run(&args),
        Command::Auth(args) => auth::run(&args),
        Command::Render(args) => sim::run("render", &args),
        Command::Simulate(args) => sim::run("simulate", &args),
    }
}
