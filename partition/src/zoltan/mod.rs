//! Safe layer over the raw Zoltan bindings: an owned handle destroyed on drop,
//! typed parameters, query callbacks reading a Rust struct through the
//! callback data pointer (no globals), and Zoltan's error codes as `Result`.

mod handle;
mod library;
mod partitioner;

pub use handle::{Method, Param, Zoltan};
pub use library::{initialize, ZoltanError, ZoltanVersion};
pub use partitioner::ZoltanPartitioner;
