//! Replays every input the fuzzer ever found a problem with (tests/fuzz/regressions/<target>/)
//! and the hand-made hostile seeds through the fuzzer's own oracle (examples/fuzz/), each in
//! a worker process: a panic, an abort or signal, a hang, more than 1 GiB of heap, an escape
//! from the scan folder, a messy error or an unusable configuration fails the test. A clean
//! refusal is fine. See docs/fuzzing.md.
//!
//! The worker is this test binary again, started with `fuzz_worker_entry` as the only test and
//! the worker's environment set.

#[allow(dead_code)]
#[path = "../examples/fuzz/oracle.rs"]
mod oracle;
#[allow(dead_code)]
#[path = "../examples/fuzz/seeds.rs"]
mod seeds;
#[allow(dead_code)]
#[path = "../examples/fuzz/worker.rs"]
mod worker;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use oracle::Target;
use worker::{FindingKind, Outcome, ViolationKind, Worker};

#[global_allocator]
static ALLOC: oracle::Counting = oracle::Counting;

/// The heap limit of the campaigns (issue #22: no run over 1 GB).
const MEMORY_LIMIT: u64 = 1 << 30;
/// Wall limit per input: far above what any of these inputs needs on a loaded machine;
/// reaching it is a hang, whatever the machine's speed.
const TIMEOUT: Duration = Duration::from_secs(60);

#[test]
#[ignore = "the worker process of the other tests in this file, not a test itself"]
fn fuzz_worker_entry() {
    if let Some(env) = oracle::worker_env() {
        std::process::exit(oracle::worker_main(env));
    }
}

fn spawn_worker(target: Target, scratch: &Path) -> Worker {
    let mut cmd = Command::new(std::env::current_exe().expect("the test binary"));
    cmd.args([
        "fuzz_worker_entry",
        "--exact",
        "--ignored",
        "--nocapture",
        "--test-threads=1",
    ])
    .env(oracle::ENV_TARGET, target.name())
    .env(oracle::ENV_SCRATCH, scratch)
    .env(oracle::ENV_MEMORY, MEMORY_LIMIT.to_string());
    Worker::spawn(cmd).expect("start a fuzz worker")
}

/// Runs each `(name, bytes)` through `target`'s oracle; returns one line per finding.
fn replay(target: Target, inputs: &[(String, Vec<u8>)]) -> Vec<String> {
    let scratch = tempfile::tempdir().expect("scratch folder");
    let mut worker = spawn_worker(target, scratch.path());
    let mut findings = Vec::new();
    for (name, bytes) in inputs {
        let run = worker.run(bytes, TIMEOUT);
        if !worker.is_alive() {
            worker = spawn_worker(target, scratch.path());
        }
        if let Outcome::Finding(f) = run.outcome {
            findings.push(format!(
                "{} {name}: {}: {}",
                target.name(),
                f.kind.name(),
                f.detail
            ));
        }
    }
    findings
}

fn regression_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz/regressions")
}

/// The saved inputs of one target (every file but notes).
fn regression_files(target: Target) -> Vec<(String, Vec<u8>)> {
    let dir = regression_dir().join(target.name());
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.is_file() && !matches!(p.extension().and_then(|e| e.to_str()), Some("txt" | "md"))
        })
        .collect();
    files.sort();
    files
        .into_iter()
        .map(|p| {
            let bytes = std::fs::read(&p).expect("read a regression file");
            (p.display().to_string(), bytes)
        })
        .collect()
}

#[test]
fn regression_folders_are_named_after_targets() {
    let entries = std::fs::read_dir(regression_dir()).expect("tests/fuzz/regressions exists");
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if e.path().is_dir() {
            assert!(
                Target::parse(&name).is_some_and(|t| t != Target::SelfTest),
                "tests/fuzz/regressions/{name} is not a fuzz target: its files would never run"
            );
        }
    }
}

#[test]
fn every_saved_finding_stays_fixed() {
    let mut findings = Vec::new();
    for target in Target::ALL {
        let inputs = regression_files(target);
        if !inputs.is_empty() {
            findings.extend(replay(target, &inputs));
        }
    }
    assert!(findings.is_empty(), "regressions:\n{}", findings.join("\n"));
}

#[test]
fn hand_made_hostile_seeds_are_refused_cleanly() {
    let mut findings = Vec::new();
    let mut count = 0;
    for target in Target::ALL {
        let inputs: Vec<(String, Vec<u8>)> = seeds::hand_made(target)
            .into_iter()
            .map(|s| (format!("hand-made/{}", s.name), s.bytes))
            .collect();
        count += inputs.len();
        findings.extend(replay(target, &inputs));
    }
    assert!(count > 50, "only {count} hand-made seeds");
    assert!(findings.is_empty(), "findings:\n{}", findings.join("\n"));
}

/// The oracle must see every kind of finding, or a clean replay would mean nothing.
#[test]
fn the_oracle_sees_every_kind_of_finding() {
    let scratch = tempfile::tempdir().expect("scratch folder");
    let mut worker = spawn_worker(Target::SelfTest, scratch.path());
    let cases: [(&[u8], Option<FindingKind>); 7] = [
        (b"fine", None),
        (b"panic", Some(FindingKind::Panic)),
        (b"abort", Some(FindingKind::Crash)),
        (b"oom", Some(FindingKind::OverMemory)),
        (b"hang", Some(FindingKind::Hang)),
        (
            b"escape",
            Some(FindingKind::Violation(ViolationKind::Escape)),
        ),
        (
            b"messy",
            Some(FindingKind::Violation(ViolationKind::MessyError)),
        ),
    ];
    for (input, expected) in cases {
        // The hang is the only input that should reach the limit, and a short one shows
        // it; the others get the usual limit, so that a busy machine (the oom case
        // allocates a gigabyte) cannot turn them into hangs.
        let limit = if input == b"hang" {
            Duration::from_secs(3)
        } else {
            TIMEOUT
        };
        let run = worker.run(input, limit);
        if !worker.is_alive() {
            worker = spawn_worker(Target::SelfTest, scratch.path());
        }
        let got = match &run.outcome {
            Outcome::Finding(f) => Some(f.kind),
            _ => None,
        };
        assert_eq!(
            got,
            expected,
            "{}: {:?}",
            String::from_utf8_lossy(input),
            run.outcome
        );
        if let Outcome::Finding(f) = &run.outcome
            && f.kind == FindingKind::Panic
        {
            assert!(f.detail.contains("self-test panic"), "{}", f.detail);
            assert!(f.detail.contains("oracle.rs"), "{}", f.detail);
        }
    }
    // A worker that survived a panic still answers.
    assert_eq!(worker.run(b"fine", TIMEOUT).outcome, Outcome::Accepted);
}
