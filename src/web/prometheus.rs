//! `/metrics` in the Prometheus text exposition format (version 0.0.4), written by hand:
//! a handful of gauges, one counter family and one histogram, all read from the store
//! (so they survive restarts) plus the live worker count. A client crate would add a
//! registry and a second copy of state the store already holds.

use super::LiveStatus;
use super::reader::Figures;
use std::fmt::Write;

/// Upper bounds of the processing-time buckets, in seconds: a normals-only job takes well
/// under a second, a face scan with decimation and metrics tens of seconds to minutes.
pub const TIME_BUCKETS_SECS: [f64; 11] = [
    0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 120.0, 300.0, 900.0, 3600.0,
];

/// A label value escaped as the format requires (`\\`, `\"`, `\n`); input-derived text is
/// made printable first.
fn label(value: &str) -> String {
    let printable = crate::text::escape_str(value);
    let mut out = String::with_capacity(printable.len());
    for c in printable.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            '"' => out.push_str("\\\""),
            '\n' => out.push_str("\\n"),
            c => out.push(c),
        }
    }
    out
}

fn header(out: &mut String, name: &str, kind: &str, help: &str) {
    let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} {kind}");
}

/// One gauge without labels: its header and its value.
fn gauge(out: &mut String, name: &str, help: &str, value: impl std::fmt::Display) {
    header(out, name, "gauge", help);
    let _ = writeln!(out, "{name} {value}");
}

/// The whole exposition.
pub fn render(f: &Figures, live: &LiveStatus) -> String {
    let mut s = String::new();
    jobs(&mut s, f);
    gauge(
        &mut s,
        "scanmill_queue_depth",
        "Jobs queued or waiting for a retry.",
        f.queue_depth,
    );
    gauge(
        &mut s,
        "scanmill_workers_busy",
        "Jobs running now.",
        live.running,
    );
    gauge(
        &mut s,
        "scanmill_workers",
        "Jobs that may run at the same time (workers).",
        live.workers,
    );
    gauge(
        &mut s,
        "scanmill_waiting_scans",
        "Scans that are not jobs: waiting for a missing member, or refused (a link, a file outside the folder, too large).",
        f.waiting,
    );
    let paused = matches!(live.state, super::DaemonState::Paused(_));
    gauge(
        &mut s,
        "scanmill_paused",
        "1 while claiming is paused (low disk), else 0.",
        u8::from(paused),
    );
    failures(&mut s, f);
    let last = f.last_success_ms.map_or(0.0, |ms| ms as f64 / 1e3);
    gauge(
        &mut s,
        "scanmill_last_success_timestamp_seconds",
        "When the most recent successful job finished (Unix time); 0 if none has.",
        format_args!("{last:.3}"),
    );
    processing_times(&mut s, f);
    s
}

fn jobs(s: &mut String, f: &Figures) {
    header(
        s,
        "scanmill_jobs",
        "gauge",
        "Jobs in the store by state and watched folder.",
    );
    for (state, root, n) in &f.jobs {
        let _ = writeln!(
            s,
            "scanmill_jobs{{state=\"{}\",root=\"{}\"}} {n}",
            label(state),
            label(root)
        );
    }
}

fn failures(s: &mut String, f: &Figures) {
    header(
        s,
        "scanmill_attempt_failures_total",
        "counter",
        "Failed attempts by error kind (retried, failed for good or quarantined).",
    );
    for (kind, n) in &f.failures {
        let _ = writeln!(
            s,
            "scanmill_attempt_failures_total{{kind=\"{}\"}} {n}",
            label(kind)
        );
    }
}

fn processing_times(s: &mut String, f: &Figures) {
    header(
        s,
        "scanmill_job_processing_seconds",
        "histogram",
        "Processing time of finished jobs by watched folder.",
    );
    for h in &f.times {
        let root = label(&h.root);
        for (bound, n) in TIME_BUCKETS_SECS.iter().zip(&h.le) {
            let _ = writeln!(
                s,
                "scanmill_job_processing_seconds_bucket{{root=\"{root}\",le=\"{bound}\"}} {n}"
            );
        }
        let _ = writeln!(
            s,
            "scanmill_job_processing_seconds_bucket{{root=\"{root}\",le=\"+Inf\"}} {}",
            h.count
        );
        let _ = writeln!(
            s,
            "scanmill_job_processing_seconds_sum{{root=\"{root}\"}} {:.3}",
            h.sum_ms / 1e3
        );
        let _ = writeln!(
            s,
            "scanmill_job_processing_seconds_count{{root=\"{root}\"}} {}",
            h.count
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn label_values_cannot_break_the_line_or_the_quotes() {
        assert_eq!(label("a\"b\\c\nd"), "a\\\"b\\\\c\\\\nd");
        assert!(!label("x\ny").contains('\n'));
    }
}
