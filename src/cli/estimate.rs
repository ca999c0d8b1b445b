//! `qrpose estimate REQUEST.json|-`: one corners request in, the API's response out.

use super::EXIT_BAD_INPUT;
use clap::Args;
use qrpose::api::{
    estimate_corners,
    problem::{Problem, parse_json},
};
use std::io::Read;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `estimate`.
#[derive(Debug, Args)]
pub struct EstimateArgs {
    /// A `/v1/pose/corners` request body (JSON file), or `-` for standard input.
    pub request: PathBuf,
    /// Indent the output.
    #[arg(long)]
    pub pretty: bool,
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
            println!("{json}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("qrpose: cannot serialise the response: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Runs `estimate`.
pub fn run(args: &EstimateArgs) -> ExitCode {
    let bytes = match read_input(&args.request) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("qrpose: cannot read {}: {e}", args.request.display());
            return ExitCode::FAILURE;
        }
    };
    match parse_json(&bytes).and_then(|request| estimate_corners(&request)) {
        Ok(response) => print_json(&response, args.pretty),
        Err(problem) => report_problem(&problem),
    }
}
