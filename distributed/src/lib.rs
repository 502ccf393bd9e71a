//! tridem's DEM split across MPI ranks (the paper's Algorithm 1).
//!
//! [`DistributedSimulation`] steps a scene on every rank of a communicator
//! and gives, to the bit, what one process gives, while each rank holds only
//! its own particles, the ghosts within their reach and the obstacles near
//! them ([`local`]). See its module doc for who computes what, what travels
//! when, and why the results do not depend on the rank count. [`ghosts`]
//! draws and exchanges the ghost bodies, [`forces`] sums the force terms of
//! bodies near a cut in one process's order, [`history`] moves each
//! contact's state with its home particle, [`records`] names what
//! travels, [`metrics`] what each rank measures per step.

pub mod forces;
pub mod ghosts;
pub mod history;
pub mod local;
pub mod metrics;
pub mod records;
mod simulation;
pub mod weights;

pub use ghosts::Exchange;
pub use metrics::StepMetrics;
pub use simulation::{
    merge_by_pair, DistributedSimulation, Gathered, Settings, Start, CHECK_EVERY, GHOST_SKINS,
};
pub use weights::Weights;
