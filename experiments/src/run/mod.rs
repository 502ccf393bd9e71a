//! `tridem run SCENE`: a DEM run on one process ([`node`]), or under
//! `mpirun -np P` split across P ranks ([`ranks`]). Both drive their
//! simulation through one step loop ([`drive`]), with the same checks,
//! output steps, checkpoints and stop on a signal; they differ in how a step
//! is taken and how its state reaches the disk.

mod checks;
mod drive;
mod node;
mod ranks;
mod signals;

use crate::cli::RunArgs;
use crate::error::{CliError, CliResult};

pub fn run(args: &RunArgs) -> CliResult {
    // A singleton MPI start costs seconds (Open MPI starts its runtime
    // daemon) and gives one rank: a run not started by a launcher goes
    // without MPI.
    if !launched_by_mpi() {
        return node::run(args);
    }
    // Funneled: MPI is called from the main thread only, while the thread
    // pool's workers and the signal thread exist.
    let (universe, _) = mpi::initialize_with_threading(mpi::Threading::Funneled)
        .ok_or_else(|| CliError::runtime("MPI was already initialised"))?;
    let comm = universe.world();
    match mpi::traits::Communicator::size(&comm) {
        1 => node::run(args),
        _ => ranks::run(args, &comm),
    }
}

/// Whether an MPI launcher started this process: mpirun (Open MPI, its
/// PRRTE runtime, MPICH's Hydra) and srun with a PMI or PMIx plugin all set
/// one of these.
fn launched_by_mpi() -> bool {
    ["OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"]
        .iter()
        .any(|v| std::env::var_os(v).is_some())
}
