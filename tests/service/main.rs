//! The real `qrpose` binary, run as a user runs it: `qrpose serve` on a free port under
//! the curl suite, generated clients, a small open-file limit and a memory budget; the
//! annotated image; and the CLI's subcommands (`estimate`, `calibrate`, `site`, `track`,
//! `render`, `simulate`) with their JSON and exit codes.

#[path = "../support/mod.rs"]
mod support;

mod annotated;
mod cli;
mod cli_calibrate;
mod cli_hand_eye;
mod cli_pick;
mod curl_suite;
mod fd_exhaustion;
mod generated_clients;
mod memory_budget;
mod site_cli;
mod track_cli;
