//! Command-line interface: argument definitions in `args`, the commands in `run` (and
//! `simulate`, `bench`, `render`).

mod args;
mod backend_options;
mod bench;
mod output;
mod ranks;
mod render;
mod run;
mod simulate;
mod view;
mod walls;

use clap::Parser;
use std::process::ExitCode;

/// Parses the arguments, runs the command, prints any error as one line.
pub fn main() -> ExitCode {
    let cli = args::Cli::parse();
    match run::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
