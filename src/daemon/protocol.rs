//! The pipe protocol between the daemon and a job's worker process.
//!
//! The daemon starts `scanmill worker` (the same binary) with the job's paths as arguments
//! (arguments carry any bytes, so no file name is ever re-encoded) and reads the worker's
//! standard output: one JSON object per line, each tagged with the protocol version. The
//! worker's standard error is its log; the daemon forwards it and keeps the last lines to
//! explain a worker that died without a word.
//!
//! Version 1:
//! - `{"v":1,"event":"stage","index":I,"total":N,"name":"fair"}` as each stage starts;
//! - then exactly one of `{"v":1,"event":"done","report":{…},"busy_ms":T}` (the report of
//!   [`crate::report::Report`], its output paths inside the staging folder, and the time the
//!   worker spent on the job) or
//!   `{"v":1,"event":"failed","kind":K,"message":M,"transient":B}`.
//!
//! The daemon stops reading at the final event. Anything else on the pipe before it, or a
//! pipe that closes without one, is a protocol failure of that job, never of the daemon.

use crate::report::Report;
use crate::store::FailureKind;
use serde::{Deserialize, Serialize};

/// Bumped whenever an event's shape changes; the daemon refuses other versions.
pub const VERSION: u32 = 1;

/// Longest line the daemon accepts from a worker (a report is a few kilobytes).
pub const MAX_LINE_BYTES: usize = 16 << 20;

/// One line of the worker's standard output.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Line {
    pub v: u32,
    #[serde(flatten)]
    pub event: Event,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum Event {
    Stage {
        index: usize,
        total: usize,
        name: String,
    },
    Done {
        report: Box<Report>,
        /// Milliseconds the worker spent from taking up the job to this report.
        busy_ms: f64,
    },
    Failed {
        kind: FailureKind,
        message: String,
        transient: bool,
    },
}

impl Line {
    pub fn new(event: Event) -> Line {
        Line { v: VERSION, event }
    }

    /// The line as written on the pipe, newline included.
    pub fn encode(&self) -> Vec<u8> {
        let mut bytes = serde_json::to_vec(self).expect("protocol lines always serialise");
        bytes.push(b'\n');
        bytes
    }

    /// Parses one line; any error names what was wrong without echoing the bytes.
    pub fn decode(bytes: &[u8]) -> Result<Line, String> {
        let line: Line = serde_json::from_slice(bytes).map_err(|e| {
            format!(
                "unreadable line from the worker ({} bytes): {e}",
                bytes.len()
            )
        })?;
        if line.v != VERSION {
            return Err(format!(
                "worker speaks protocol version {}, this daemon {VERSION}",
                line.v
            ));
        }
        Ok(line)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_round_trips() {
        let line = Line::new(Event::Failed {
            kind: FailureKind::Input,
            message: "line 3: bad\nindex".into(),
            transient: false,
        });
        let bytes = line.encode();
        assert_eq!(bytes.iter().filter(|&&b| b == b'\n').count(), 1);
        match Line::decode(&bytes[..bytes.len() - 1]).unwrap().event {
            Event::Failed {
                kind,
                message,
                transient,
            } => {
                assert_eq!(kind, FailureKind::Input);
                assert_eq!(message, "line 3: bad\nindex");
                assert!(!transient);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn other_versions_and_garbage_are_refused() {
        let err =
            Line::decode(br#"{"v":2,"event":"stage","index":0,"total":1,"name":"x"}"#).unwrap_err();
        assert!(err.contains("version 2"), "{err}");
        let err = Line::decode(b"root:x:0:0:root:/root:/bin/bash").unwrap_err();
        assert!(
            !err.contains("root:x"),
            "the bytes must not be echoed: {err}"
        );
    }
}
