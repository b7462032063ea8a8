//! glTF 2.0: reading `.gltf`/`.glb` ([`read()`]) and writing `.glb` ([`write()`]).
//!
//! Crate choice: the `gltf` crate (without its importer) parses and validates the JSON
//! document, a schema of some thirty object kinds with cross-references that would be a
//! large and error-prone piece of code to write by hand. What it does not bound is done here:
//! the GLB container, buffers and URIs (confined to the scan's folder through
//! [`crate::mesh::texture::resolve_in_scan`], sized against [`crate::mesh::InputLimits`]) and
//! accessor ranges. The writer is our own: a GLB of one mesh is a few hundred lines, and the
//! crate's JSON types would add nothing but conversions.

mod accessor;
pub mod glb;
mod read;
pub mod refs;
mod write;

pub use read::read;
pub use write::write;
