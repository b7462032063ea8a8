//! The service: watch folders, group files into scan sets, queue jobs in SQLite, run them
//! in worker processes with resource limits, publish results atomically, talk to systemd.
//! See docs/service.md for operation and the reasoning, docs/architecture.md for the layout.

pub mod cli;
pub mod glob;
pub mod protocol;
pub mod publish;
pub mod scanset;
pub mod service;
pub mod supervise;
pub mod systemd;
pub mod worker;
pub mod worker_process;
