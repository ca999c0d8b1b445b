//! The `qrpose-sim` command line: `render` (synthetic photos and videos of QR codes with
//! their ground truth) and `simulate` (the paper's Section 8 experiment). Developer tools,
//! kept out of the service binary: `qrpose` links neither the renderer nor the plotting.
//!
//! Exit codes as `qrpose`'s: 0 success; 2 the input was refused (a problem document on
//! stderr, the API's shape); 1 anything else (I/O).

mod problem;
mod render;
mod simulate;

pub use problem::Problem;
pub use render::RenderArgs;
pub use simulate::SimulateArgs;

use clap::{Parser, Subcommand};
use std::io::Write;
use std::process::ExitCode;

/// Exit code for refused input.
pub const EXIT_BAD_INPUT: u8 = 2;
/// Exit code when the reader of standard output went away (128 + SIGPIPE).
pub const EXIT_BROKEN_PIPE: u8 = 141;

/// qrpose-sim: synthetic QR-code photos with ground truth, and the paper's simulation.
#[derive(Debug, Parser)]
#[command(name = "qrpose-sim", version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render a synthetic photo of a QR code at a given pose, or a video of a camera moving
    /// past codes (--sequence); prints its ground truth.
    Render(Box<RenderArgs>),
    /// Reproduce the paper's simulation (Table 10, Figures 8-12, Tables 5-9).
    Simulate(SimulateArgs),
}

/// Why a command failed: refused input (exit 2) or anything else (exit 1).
#[derive(Debug)]
pub enum Failure {
    /// The input was refused.
    Refused(Problem),
    /// I/O or another failure, as text.
    Other(String),
}

impl From<Problem> for Failure {
    fn from(problem: Problem) -> Self {
        Self::Refused(problem)
    }
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Refused(problem) => write!(f, "{} ({})", problem.detail, problem.code),
            Self::Other(message) => f.write_str(message),
        }
    }
}

/// Parses `std::env::args` and runs the command.
#[must_use]
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Render(args) => report(render::run(&args).map(|json| (json, args.pretty))),
        Command::Simulate(args) => match simulate::run(&args) {
            Ok(code) => code,
            Err(e) => {
                eprintln!("qrpose-sim simulate: {e:#}");
                ExitCode::FAILURE
            }
        },
    }
}

/// `render` with `args` (as on the command line, without the program and subcommand
/// names): the JSON it prints. For tests and tools that render in-process.
///
/// # Errors
/// Flags clap refuses, refused input, or I/O.
pub fn render(args: &[&std::ffi::OsStr]) -> Result<serde_json::Value, Failure> {
    let argv = ["qrpose-sim".as_ref(), "render".as_ref()]
        .into_iter()
        .chain(args.iter().copied());
    match Cli::try_parse_from(argv)
        .map_err(|e| Failure::Other(e.to_string()))?
        .command
    {
        Command::Render(args) => render::run(&args),
        Command::Simulate(_) => Err(Failure::Other("not a render command".to_owned())),
    }
}

/// Prints a command's JSON on stdout, or its failure on stderr; the exit code.
fn report(result: Result<(serde_json::Value, bool), Failure>) -> ExitCode {
    match result {
        Ok((json, pretty)) => print_json(&json, pretty),
        Err(Failure::Refused(problem)) => {
            eprintln!("{}", problem.to_json_pretty());
            ExitCode::from(EXIT_BAD_INPUT)
        }
        Err(Failure::Other(message)) => {
            eprintln!("qrpose-sim: {message}");
            ExitCode::FAILURE
        }
    }
}

/// Prints a value as JSON on stdout; a closed pipe is the reader's choice, not an error.
fn print_json(value: &serde_json::Value, pretty: bool) -> ExitCode {
    let json = if pretty {
        serde_json::to_string_pretty(value)
    } else {
        serde_json::to_string(value)
    };
    let Ok(json) = json else {
        return ExitCode::FAILURE;
    };
    let mut stdout = std::io::stdout().lock();
    match writeln!(stdout, "{json}").and_then(|()| stdout.flush()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::from(EXIT_BROKEN_PIPE),
        Err(e) => {
            eprintln!("qrpose-sim: cannot write to stdout: {e}");
            ExitCode::FAILURE
        }
    }
}
