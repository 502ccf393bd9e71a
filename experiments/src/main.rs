//! `tridem`: the command-line tool of the tridem project.

mod cli;
mod error;
mod info;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = cli::Cli::parse();
    let result = match cli.command {
        cli::Command::Info(args) => info::run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("tridem: error: {e:#}");
            ExitCode::from(e.exit_code())
        }
    }
}
