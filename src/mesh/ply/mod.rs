//! PLY input and output: ASCII and binary (both byte orders), with the texture-coordinate
//! layouts scanners write (MeshLab/OpenMVS per-face `texcoord`, Artec `multi_texture_*`,
//! per-vertex `u v`), triangle strips, and located errors for malformed files.
//!
//! The reader is our own rather than `ply-rs-bw`: that crate stores every element as a hash
//! map of named properties (375 ms and 257 MB to parse a 400k-face file before any conversion)
//! and reports errors by a line counter rather than by element and index.

mod header;
mod read;
mod source;
mod write;

pub use read::{MISSING_TEXTURE_PREFIX, read};
pub use write::{write, write_reserving};

/// How a PLY file is encoded on output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PlyEncoding {
    Ascii,
    #[default]
    BinaryLittleEndian,
    BinaryBigEndian,
}

#[cfg(test)]
mod tests;
