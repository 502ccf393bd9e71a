//! Safe layer over the raw Zoltan bindings.

mod library;

pub use library::{initialize, ZoltanError, ZoltanVersion};
