//! scanmill: unattended processing of 3D scans. See DESIGN.md for the architecture.

pub mod mesh;
pub mod metrics;
pub mod ops;
pub mod recipe;
pub mod report;
