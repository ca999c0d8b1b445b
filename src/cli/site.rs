//! `qrpose site check FILE`: validates a site file (and its calibration files) as
//! `qrpose serve --site` would, and prints what it resolved, as `GET /v1/site` answers it.
//! A refused file: `FILE:LINE: reason` on stderr and the bad-input exit code.

use super::EXIT_BAD_INPUT;
use super::estimate::print_json;
use clap::{Args, Subcommand};
use qrpose::api::site::SiteDto;
use qrpose_site::Site;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `site`.
#[derive(Debug, Args)]
pub struct SiteArgs {
    /// What to do with a site file.
    #[command(subcommand)]
    pub command: SiteCommand,
}

/// The subcommands of `site`.
#[derive(Debug, Subcommand)]
pub enum SiteCommand {
    /// Validate a site file and print the cameras, sizes and map it resolves to.
    Check {
        /// The site file (YAML).
        file: PathBuf,
        /// Indent the output.
        #[arg(long)]
        pretty: bool,
    },
}

/// Loads `path` when given; a refusal is printed (`FILE:LINE: reason`) and becomes the
/// bad-input exit code.
///
/// # Errors
/// The exit code to return.
pub fn load_optional(path: Option<&Path>) -> Result<Option<Site>, ExitCode> {
    path.map(|p| {
        Site::load(p).map_err(|e| {
            eprintln!("qrpose: site {e}");
            ExitCode::from(EXIT_BAD_INPUT)
        })
    })
    .transpose()
}

/// Runs `site`.
pub fn run(args: &SiteArgs) -> ExitCode {
    match &args.command {
        SiteCommand::Check { file, pretty } => match load_optional(Some(file)) {
            Ok(Some(site)) => print_json(&SiteDto::from(&site), *pretty),
            Ok(None) => ExitCode::FAILURE,
            Err(code) => code,
        },
    }
}
