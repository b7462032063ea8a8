//! Processing steps, one module each; every step is a function over the mesh.

pub mod bake;
pub mod border;
pub mod crop;
pub mod decimate;
pub mod fair;
pub mod normals;
pub mod remesh;
pub mod seam_fix;
pub mod smooth;
pub mod subdivide;
pub mod texture_follow;
