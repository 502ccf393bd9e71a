//! tridem's discrete element method.
//!
//! - [`distance`]: minimum distance between triangles by three methods (exact
//!   brute force, SIMD-batched penalty Newton, and the hybrid of the two).

pub mod distance;
pub mod mesh;
