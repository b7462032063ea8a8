//! scanmill: unattended processing of 3D scans. The architecture (layout, data flow, the
//! recipe-step contract, conventions) is in docs/architecture.md.

// The API documentation is built with `--document-private-items` (`.ci/run` checks it): its
// readers are the service's maintainers, and a public item's doc may point at the private
// helper that does the work.
#![allow(rustdoc::private_intra_doc_links)]

pub mod compare;
pub mod config;
pub mod daemon;
pub mod geom;
pub mod memory;
pub mod mesh;
pub mod metrics;
pub mod ops;
pub mod preview;
pub mod process;
pub mod recipe;
pub mod report;
pub mod store;
#[cfg(test)]
mod testing;
pub mod text;
pub mod web;
