//! Processing steps, one module each; every step is a function over the mesh.

pub mod crop;
pub mod normals;
pub mod smooth;
pub mod subdivide;
