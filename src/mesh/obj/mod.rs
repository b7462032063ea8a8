//! Wavefront OBJ input and output (see `read.rs` for the rules of the reader).

mod read;

pub use read::*;
