//! `host-sim`: the command line of the host tools. Parsing and exit codes only; every command
//! is a call into a library crate (`pbm-lab`, `pbm-ml`, `pbm-demo`, `pbm-fleet`) with its options struct.
//!
//! Exit status: 0 when everything was done, 1 when the command failed, 2 for a usage error,
//! [`pbm_io::error::SKIPPED_EXIT_CODE`] (3) when the command completed and wrote its outputs but
//! skipped bad inputs (each named on stderr with its file and line),
//! [`pbm_io::error::CHECK_FAILED_EXIT_CODE`] (4) when a check read its input to the end and found
//! it wrong (`can decode --strict`).

mod cli;

use clap::Parser;
use pbm_io::error::{CheckFailed, Skipped, CHECK_FAILED_EXIT_CODE, SKIPPED_EXIT_CODE};
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = cli::Cli::parse();
    match cli::run(cli.command) {
        Ok(skipped) => exit_code(&skipped),
        Err(e) => {
            eprintln!("error: {e:#}");
            if e.downcast_ref::<CheckFailed>().is_some() {
                ExitCode::from(CHECK_FAILED_EXIT_CODE)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}

/// Reports what was skipped (stderr) and says so in the exit status.
fn exit_code(skipped: &Skipped) -> ExitCode {
    if skipped.is_empty() {
        ExitCode::SUCCESS
    } else {
        eprintln!("{skipped}; everything else completed");
        ExitCode::from(SKIPPED_EXIT_CODE)
    }
}
