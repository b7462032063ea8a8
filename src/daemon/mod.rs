//! The service: watch folders, group files into scan sets, queue jobs in SQLite, run them
//! off the async threads, publish results atomically, talk to systemd.
//! See docs/service.md for operation and spec/service.md for the reasoning.

pub mod glob;
pub mod scanset;
