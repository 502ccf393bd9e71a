//! tridem's DEM split across MPI ranks (the paper's Algorithm 1).
//!
//! [`DistributedSimulation`] steps a scene on every rank of a communicator
//! and gives, to the bit, what one process gives: see its module doc for who
//! owns what, what travels when, and why the results do not depend on the
//! rank count. [`ghosts`] draws and exchanges the ghost bodies, [`records`]
//! names what travels, [`metrics`] what each rank measures per step.

pub mod ghosts;
pub mod metrics;
pub mod records;
mod simulation;

pub use ghosts::Exchange;
pub use metrics::StepMetrics;
pub use simulation::{DistributedSimulation, Gathered, Settings};
