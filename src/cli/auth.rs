//! `qrpose auth add NAME --scopes pose,site [--file FILE]`: a new client of the auth file
//! (docs/security.md).
//!
//! Prints a fresh token on the first line of standard output, once (the file keeps only its
//! SHA-256: it cannot be shown again), and the file's entry on the second. With `--file`,
//! the entry is appended to the file (created with `clients:` when missing) and only the
//! token is printed. What to do with both goes to standard error.

use clap::{Args, Subcommand};
use qrpose::config::auth::{self, Clients, Scope, Scopes};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `auth`.
#[derive(Debug, Args)]
pub struct AuthArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: AuthCommand,
}

/// The subcommands of `auth`.
#[derive(Debug, Subcommand)]
pub enum AuthCommand {
    /// Make a token for a new client: prints the token once and the auth file's entry.
    Add(AddArgs),
}

/// Arguments of `auth add`.
#[derive(Debug, Args)]
pub struct AddArgs {
    /// The client's name, shown in logs and metrics (letters, digits, `.`, `_`, `-`).
    pub name: String,
    /// What it may call, comma-separated: pose, site, admin, metrics.
    #[arg(long, value_enum, value_delimiter = ',', required = true)]
    pub scopes: Vec<Scope>,
    /// Append the entry to this auth file (created when missing) instead of printing it;
    /// refused when the file is invalid or already has a client of this name.
    #[arg(long)]
    pub file: Option<PathBuf>,
}

/// Runs `auth`.
pub fn run(args: &AuthArgs) -> ExitCode {
    match &args.command {
        AuthCommand::Add(add) => match run_add(add) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("qrpose auth add: {e}");
                ExitCode::from(super::EXIT_BAD_INPUT)
            }
        },
    }
}

fn run_add(args: &AddArgs) -> Result<(), String> {
    auth::check_name(&args.name)?;
    let scopes: Scopes = args.scopes.iter().copied().collect();
    let token = auth::new_token();
    let entry = auth::entry_line(&args.name, &token, scopes);
    match &args.file {
        Some(file) => {
            append_entry(file, &args.name, &entry)?;
            println!("{token}");
            eprintln!(
                "The line above is {}'s token, shown only now: give it to the client \
                 (Authorization: Bearer TOKEN). {} has its entry; send the service SIGHUP to \
                 load it.",
                args.name,
                file.display()
            );
        }
        None => {
            println!("{token}");
            println!("{entry}");
            eprintln!(
                "The first line is {}'s token, shown only now: give it to the client \
                 (Authorization: Bearer TOKEN). Put the second line under `clients:` in the \
                 auth file and send the service SIGHUP.",
                args.name
            );
        }
    }
    Ok(())
}

/// Appends `entry` to the auth file `file` after checking that the result loads.
fn append_entry(file: &Path, name: &str, entry: &str) -> Result<(), String> {
    let existing = match std::fs::read_to_string(file) {
        Ok(text) => Some(text),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        Err(e) => return Err(format!("{}: cannot read: {e}", file.display())),
    };
    let mut text = existing.clone().unwrap_or_else(|| "clients:\n".to_owned());
    if let Some(current) = &existing {
        let clients = Clients::parse(current, file).map_err(|e| e.to_string())?;
        if clients.iter().any(|c| c.name() == name) {
            return Err(format!("{}: already has a client {name:?}", file.display()));
        }
        if clients.is_empty() {
            // `clients: []` cannot take a block entry after it (the check below refuses a
            // file written otherwise).
            text = current.replacen("clients: []", "clients:", 1);
        }
        if !text.ends_with('\n') {
            text.push('\n');
        }
    }
    text.push_str(entry);
    text.push('\n');
    Clients::parse(&text, file).map_err(|e| format!("the entry does not fit the file: {e}"))?;
    // Written beside and renamed over, so that a reload never reads half a file.
    let partial = file.with_extension("partial");
    let write = |e: std::io::Error| format!("{}: cannot write: {e}", partial.display());
    let mut out = std::fs::File::create(&partial).map_err(write)?;
    out.write_all(text.as_bytes()).map_err(write)?;
    out.sync_all().map_err(write)?;
    std::fs::rename(&partial, file).map_err(|e| format!("{}: cannot write: {e}", file.display()))
}
