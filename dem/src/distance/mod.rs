//! Minimum distance between two triangles, with the closest points.
//!
//! Three methods, all in f64:
//! - [`distance_triangle_triangle`]: exact brute force over the 15 feature pairs
//!   plus an intersection test. The reference for the others.
//! - [`penalty`]: Newton on the penalty formulation, on SIMD batches of pairs,
//!   finished exactly on the feature pair it identifies and checked by a
//!   certificate that bounds its error.
//! - [`hybrid`]: penalty per batch, with the batch recomputed by brute force when
//!   any of its pairs was not certified.
//!
//! The math is in `docs/distance.md`.

mod certificate;
mod closest_point_segment_segment;
mod closest_point_triangle;
mod distance_triangle_triangle;
mod distance_triangle_triangle_batch;
pub mod hybrid;
mod isa;
mod lanes;
mod pair_lanes;
mod pair_source;
pub mod penalty;
mod penalty_finish;
mod random_pairs;
mod solve_spd4;

pub use certificate::certified_error_bound;
pub use closest_point_segment_segment::closest_points_segment_segment;
pub use closest_point_triangle::closest_point_triangle;
pub use distance_triangle_triangle::distance_triangle_triangle;
pub use distance_triangle_triangle_batch::{
    distance_triangle_triangle_batch, distance_triangle_triangle_many,
    distance_triangle_triangle_many_on, LANES as BRUTE_LANES,
};
pub use hybrid::{
    distance_many, distance_many_serial, distances, Counts, Fallback, Method, Options, Schedule,
    Threading,
};
pub use isa::{Isa, Supported};
pub use pair_source::PairSource;
pub use penalty::{
    penalty_many, penalty_many_on, penalty_scalar, PenaltyParams, PenaltyStats, UnsupportedBatch,
};
pub use random_pairs::random_unit_pairs;

use glam::DVec3;

/// A triangle by its three vertices. Orientation does not matter here.
pub type Triangle = [DVec3; 3];

/// Which computation produced an answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Solver {
    Penalty,
    Brute,
}

impl Solver {
    pub fn name(self) -> &'static str {
        match self {
            Solver::Penalty => "penalty",
            Solver::Brute => "brute",
        }
    }
}

/// The minimum distance between two triangles and where it is attained.
///
/// `repr(C)`: the SIMD kernels write the distance and points of eight answers
/// with one vector store each (`pair_lanes.rs`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct Closest {
    pub distance: f64,
    /// Closest point on the first triangle.
    pub p: DVec3,
    /// Closest point on the second triangle.
    pub q: DVec3,
    pub solver: Solver,
}

impl Closest {
    /// An answer slot for a kernel to overwrite; NaN, so a slot left unwritten
    /// cannot pass for a distance.
    pub const UNSET: Closest = Closest {
        distance: f64::NAN,
        p: DVec3::ZERO,
        q: DVec3::ZERO,
        solver: Solver::Brute,
    };
}

/// Length of the diagonal of the bounding box of both triangles: the scale that
/// every tolerance in this module is relative to.
pub fn pair_scale(a: &Triangle, b: &Triangle) -> f64 {
    let mut lo = a[0];
    let mut hi = a[0];
    for v in a.iter().chain(b.iter()) {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    (hi - lo).length()
}
