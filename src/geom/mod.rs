//! Geometric and measuring primitives that several parts of the crate share (steps,
//! metrics, benches): one copy of each.
//!
//! - [`closest`]: the point of a triangle closest to a point, a triangle's plane as a lower bound
//!   of that distance, the distance to a segment;
//! - [`timing`]: the process's CPU time.
//!
//! - [`bvh`]: the closest-point index over a mesh's triangles (metrics, preview, `seam_fix`,
//!   texture follow; also reachable as `metrics::bvh`).
//!
//! The surface sampler still lives in `metrics::surface`.

pub mod bvh;
pub mod closest;
pub mod timing;

pub use closest::{closest_on_fan, closest_on_segment, closest_on_triangle, segment_distance};
