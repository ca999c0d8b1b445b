//! The `qrpose-sim` binary: `render` and `simulate` ([`qrpose_sim::cli`]).

fn main() -> std::process::ExitCode {
    qrpose_sim::cli::main()
}
