//! `qrpose render` and `qrpose simulate`: the developer tools (test photos with their truth,
//! the paper's simulation) are the `qrpose-sim` binary, so that the service binary links
//! neither the renderer nor its plotting; these two subcommands run it with the same
//! arguments, as `qrpose-sim render …` and `qrpose-sim simulate …`.
//!
//! `qrpose-sim` is looked for in `$QRPOSE_SIM`, then beside this executable (`cargo build
//! -p qrpose-sim` puts it there), then on `PATH`.

use std::ffi::OsString;
use std::path::PathBuf;
use std::process::{Command, ExitCode};

/// The developer binary's name.
const SIM: &str = "qrpose-sim";

/// Arguments passed through to `qrpose-sim SUBCOMMAND`, `--help` included.
#[derive(Debug, clap::Args)]
#[command(disable_help_flag = true)]
pub struct SimArgs {
    /// What `qrpose-sim SUBCOMMAND --help` lists.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub args: Vec<OsString>,
}

/// Where `qrpose-sim` is, by the order above.
fn sim_binary() -> PathBuf {
    if let Some(path) = std::env::var_os("QRPOSE_SIM") {
        return PathBuf::from(path);
    }
    let beside = std::env::current_exe()
        .ok()
        .and_then(|exe| Some(exe.parent()?.join(SIM)))
        .filter(|path| path.is_file());
    beside.unwrap_or_else(|| PathBuf::from(SIM))
}

/// Runs `qrpose-sim subcommand args…` with this process's standard streams; its exit code.
pub fn run(subcommand: &str, args: &SimArgs) -> ExitCode {
    let binary = sim_binary();
    match Command::new(&binary)
        .arg(subcommand)
        .args(&args.args)
        .status()
    {
        Ok(status) => ExitCode::from(
            status
                .code()
                .and_then(|c| u8::try_from(c).ok())
                .unwrap_or(1),
        ),
        Err(e) => {
            eprintln!(
                "qrpose {subcommand}: cannot run {} ({e}); `qrpose {subcommand}` is \
                 `qrpose-sim {subcommand}`: build it with `cargo build --release -p qrpose-sim` \
                 (it goes beside qrpose) or set QRPOSE_SIM to its path",
                binary.display()
            );
            ExitCode::FAILURE
        }
    }
}
