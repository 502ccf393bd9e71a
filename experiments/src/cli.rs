//! Command-line interface: one subcommand per experiment.

use clap::{Args, Parser, Subcommand};

#[derive(Parser, Debug)]
#[command(
    name = "tridem",
    version,
    about = "DEM with triangulated particles, and load balancing it across MPI ranks"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Print the versions of Zoltan, MPI, HDF5 and METIS, and the ranks and threads in use.
    Info(InfoArgs),
}

#[derive(Args, Debug)]
pub struct InfoArgs {
    /// Print as one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}
