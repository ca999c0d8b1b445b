//! The `qrpose` binary: parses the command line and hands over to [`cli::run`].

mod cli;

use clap::Parser;

fn main() -> std::process::ExitCode {
    match cli::Cli::try_parse() {
        Ok(cli) => cli::run(cli),
        Err(err) => cli::report_parse_error(&err),
    }
}
