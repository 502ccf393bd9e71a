//! tridem's discrete element method.
//!
//! - [`distance`]: minimum distance between triangles by three methods (exact
//!   brute force, SIMD-batched penalty Newton, and the hybrid of the two).
//! - [`mesh`]: closed triangle meshes, their mass properties, generators and loaders.
//! - [`scene`] -> [`world`] -> [`simulation`] (the step pipeline of [`effects`],
//!   with [`contact`] detection and [`integrate`]) -> output (in the `tridem` binary).
//! - [`exp_map`]: rotations by rotation vectors (the quaternion exponential).
//! - [`ledger`]: energy books whose sums do not depend on the order of their terms.
//! - [`checkpoint`]: a run's whole state, to stop it and resume it unchanged.
//! - [`timing`]: where a run's time goes, by section of the step pipeline.
//! - [`busy_workers`]: keeps the thread pool polling through a run of short
//!   parallel sections.

pub mod body;
pub mod busy_workers;
pub mod checkpoint;
pub mod contact;
pub mod distance;
pub mod drive;
pub mod effects;
pub mod exp_map;
mod fingerprint;
pub mod frame;
pub mod integrate;
pub mod ledger;
pub mod material;
pub mod mesh;
mod names;
mod prefetch;
pub mod scene;
pub mod simulation;
pub mod timing;
pub mod world;
