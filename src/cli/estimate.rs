//! `qrpose estimate REQUEST.json|-`: one corners request in, the API's response out.
//! `qrpose estimate --image photo.jpg --fx-px … --marker-size-mm …`: one photo in, what
//! `POST /v1/pose/image` returns out.

use super::{EXIT_BAD_INPUT, EXIT_BROKEN_PIPE};
use clap::Args;
use qrpose::api::{
    estimate_corners,
    image::{ImageLimits, ImageQuery, estimate_image_from_query},
    problem::{Problem, parse_json},
};
use std::io::{Read, Write};
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `estimate`.
#[derive(Debug, Args)]
pub struct EstimateArgs {
    /// A `/v1/pose/corners` request body (JSON file), or `-` for standard input.
    #[arg(required_unless_present = "image", conflicts_with = "image")]
    pub request: Option<PathBuf>,
    /// Indent the output.
    #[arg(long)]
    pub pretty: bool,
    /// A photo (JPEG, PNG or WebP): find every QR code, print what `POST /v1/pose/image`
    /// returns.
    #[arg(long)]
    pub image: Option<PathBuf>,
    /// The camera, marker, solver and detector of `--image`: the query parameters of
    /// `POST /v1/pose/image`, one flag each, under the same names (`fx_px` is `--fx-px`).
    #[command(flatten)]
    pub params: ImageQuery,
}

fn read_input(path: &PathBuf) -> std::io::Result<Vec<u8>> {
    if path.as_os_str() == "-" {
        let mut buf = Vec::new();
        std::io::stdin().read_to_end(&mut buf)?;
        Ok(buf)
    } else {
        std::fs::read(path)
    }
}

/// Prints a problem document on stderr and returns the bad-input exit code.
pub fn report_problem(problem: &Problem) -> ExitCode {
    match serde_json::to_string_pretty(problem) {
        Ok(json) => eprintln!("{json}"),
        Err(_) => eprintln!("{}: {}", problem.title, problem.detail),
    }
    ExitCode::from(EXIT_BAD_INPUT)
}

/// Prints a value as JSON on stdout.
pub fn print_json<T: serde::Serialize>(value: &T, pretty: bool) -> ExitCode {
    let json = if pretty {
        serde_json::to_string_pretty(value)
    } else {
        serde_json::to_string(value)
    };
    match json {
        Ok(json) => {
            // `println!` panics when stdout is gone (`qrpose estimate … | head -c 10`);
            // a closed pipe is the reader's choice, so stop quietly with its exit code.
            let mut stdout = std::io::stdout().lock();
            match writeln!(stdout, "{json}").and_then(|()| stdout.flush()) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
                    ExitCode::from(EXIT_BROKEN_PIPE)
                }
                Err(e) => {
                    eprintln!("qrpose: cannot write the response: {e}");
                    ExitCode::FAILURE
                }
            }
        }
        Err(e) => {
            eprintln!("qrpose: cannot serialise the response: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Runs `estimate --image`.
fn run_image(path: &PathBuf, args: &EstimateArgs) -> ExitCode {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("qrpose: cannot read {}: {e}", path.display());
            return ExitCode::FAILURE;
        }
    };
    match estimate_image_from_query(&bytes, args.params.clone(), &ImageLimits::default()) {
        Ok(response) => print_json(&response, args.pretty),
        Err(problem) => report_problem(&problem),
    }
}

/// Runs `estimate`.
pub fn run(args: &EstimateArgs) -> ExitCode {
    if let Some(image) = &args.image {
        return run_image(image, args);
    }
    let Some(request) = &args.request else {
        eprintln!("qrpose: give a request file or --image");
        return ExitCode::FAILURE;
    };
    let bytes = match read_input(request) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("qrpose: cannot read {}: {e}", request.display());
            return ExitCode::FAILURE;
        }
    };
    match parse_json(&bytes).and_then(|request| estimate_corners(&request)) {
        Ok(response) => print_json(&response, args.pretty),
        Err(problem) => report_problem(&problem),
    }
}
