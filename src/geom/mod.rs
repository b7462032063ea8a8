//! Geometric and measuring primitives that several parts of the crate share (steps,
//! metrics, benches): one copy of each.
//!
//! - [`closest`]: the point of a triangle closest to a point;
//! - [`timing`]: the process's CPU time.
//!
//! The triangle BVH and the surface sampler still live in `metrics` (`metrics::bvh`,
//! `metrics::surface`) though `seam_fix` and `texture_follow` use them too; they belong here.

pub mod closest;
pub mod timing;

pub use closest::closest_on_triangle;
