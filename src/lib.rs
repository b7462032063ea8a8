//! scanmill: unattended processing of 3D scans. See DESIGN.md for the architecture.

pub mod compare;
pub mod config;
pub mod daemon;
pub mod memory;
pub mod mesh;
pub mod metrics;
pub mod ops;
pub mod preview;
pub mod process;
pub mod recipe;
pub mod report;
pub mod store;
pub mod text;
pub mod web;
