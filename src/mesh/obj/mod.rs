//! Wavefront OBJ input and output: the reader (`read.rs`, with the rules it follows), the
//! materials its statements name (`materials.rs`), and the writer (`write.rs`).

mod materials;
mod read;
mod write;

pub(crate) use read::{finish, parse_unchecked};
pub use read::{parse, read};
pub use write::{copy_file, copy_source, write, write_reserving};

/// Name of the material created for [`LoadOptions::texture_override`](crate::mesh::LoadOptions).
pub const OVERRIDE_MATERIAL: &str = "scanmill_texture";
/// Name of the material given to faces before the first `usemtl`.
pub const DEFAULT_MATERIAL: &str = "default";
