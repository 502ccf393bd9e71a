//! `tridem info`: what this build runs on.

use crate::cli::InfoArgs;
use crate::error::{CliError, CliResult};
use mpi::traits::*;

pub fn run(args: &InfoArgs) -> CliResult {
    let universe =
        mpi::initialize().ok_or_else(|| CliError::runtime("MPI was already initialised"))?;
    let world = universe.world();
    let zoltan =
        partition::zoltan::initialize(&universe).map_err(|e| CliError::runtime(e.to_string()))?;
    if world.rank() != 0 {
        return Ok(());
    }
    let mpi_library = mpi::environment::library_version()
        .map(|s| {
            s.lines()
                .next()
                .unwrap_or("")
                .trim_matches(|c: char| c.is_whitespace() || c == '\0')
                .to_string()
        })
        .unwrap_or_else(|_| "unknown".into());
    let (mpi_major, mpi_minor) = mpi::environment::version();
    let (h5a, h5b, h5c) = hdf5::library_version();
    let metis = format!(
        "{}.{}.{}",
        metis_sys::METIS_VER_MAJOR,
        metis_sys::METIS_VER_MINOR,
        metis_sys::METIS_VER_SUBMINOR
    );
    let ranks = world.size();
    let threads = rayon::current_num_threads();
    if args.json {
        let v = serde_json::json!({
            "tridem": env!("CARGO_PKG_VERSION"),
            "zoltan": zoltan.to_string(),
            "mpi_library": mpi_library,
            "mpi_standard": format!("{mpi_major}.{mpi_minor}"),
            "hdf5": format!("{h5a}.{h5b}.{h5c}"),
            "metis": metis,
            "ranks": ranks,
            "threads_per_rank": threads,
        });
        println!("{v}");
    } else {
        println!("tridem            {}", env!("CARGO_PKG_VERSION"));
        println!("Zoltan            {zoltan}");
        println!("MPI library       {mpi_library}");
        println!("MPI standard      {mpi_major}.{mpi_minor}");
        println!("HDF5              {h5a}.{h5b}.{h5c}");
        println!("METIS             {metis}");
        println!("ranks             {ranks}");
        println!("threads per rank  {threads}");
    }
    Ok(())
}
