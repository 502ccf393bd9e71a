//! Domain decomposition for tridem.
//!
//! One interface over three backends: Trilinos Zoltan (through the safe layer
//! in [`zoltan`] over `zoltan-sys`), METIS, and a native recursive coordinate
//! bisection.

pub mod zoltan;
