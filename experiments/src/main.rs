//! `tridem`: the command-line tool of the tridem project.

mod bounds;
mod checkpoint_file;
mod cli;
mod distance_cmd;
mod error;
mod info;
mod kernels;
mod output;
mod pairs_csv;
mod parallel;
mod partition_cmd;
mod pingpong;
mod plot;
mod plot_cmd;
mod raster;
mod render_cmd;
mod run;
mod run_summary;
mod scaling_cmd;
mod sections;
mod stats;
mod study;

use clap::Parser;

/// This process's rank when an MPI launcher started it (read from the
/// launcher's environment, before MPI is initialised).
fn launched_rank() -> Option<u32> {
    ["OMPI_COMM_WORLD_RANK", "PMIX_RANK", "PMI_RANK"]
        .iter()
        .find_map(|v| std::env::var(v).ok()?.parse().ok())
}
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = match cli::Cli::try_parse() {
        Ok(cli) => cli,
        // Under an MPI launcher every rank parses the same command line:
        // rank 0 alone says what is wrong with it (or prints the help),
        // and its exit code is the run's. The others end quietly and with
        // success: a rank ending in failure first would make the launcher
        // kill rank 0 before its message is out.
        Err(_) if launched_rank().is_some_and(|r| r != 0) => return ExitCode::SUCCESS,
        Err(e) => e.exit(),
    };
    let result = match cli.command {
        cli::Command::Info(args) => info::run(&args),
        cli::Command::Distance(args) => distance_cmd::run(&args),
        cli::Command::Kernels(args) => kernels::run(&args),
        cli::Command::Partition(args) => partition_cmd::run(&args),
        cli::Command::Pingpong(args) => pingpong::run(&args),
        cli::Command::Run(args) => run::run(&args),
        cli::Command::Scaling(args) => scaling_cmd::run(&args),
        cli::Command::PartitionPlot(args) => partition_cmd::plot(&args),
        cli::Command::Plot(args) => plot_cmd::run(&args),
        cli::Command::Chart(args) => plot_cmd::chart(&args),
        cli::Command::Render(args) => render_cmd::run(&args),
        cli::Command::Study(args) => study::run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if e.is_reported_here() {
                eprintln!("tridem: error: {e:#}");
            }
            ExitCode::from(e.exit_code())
        }
    }
}
