//! Job isolation (issue "no file can stop the service"): every job runs in its own worker
//! process with memory, CPU and wall-clock limits. A worker that aborts, segfaults, runs out
//! of memory, spins or hangs fails its own job only; the daemon keeps its PID and processes
//! the next scan; attempts are counted at claim, so a poison file ends quarantined even
//! across daemon restarts. The faults come from the test-only hook
//! `SCANMILL_TEST_WORKER_FAULT` (the worker misbehaves for inputs whose name matches).

mod common;
mod daemon_support;

use daemon_support::*;

fn job_named<'a>(jobs: &'a [serde_json::Value], name: &str) -> &'a serde_json::Value {
    jobs.iter()
        .find(|j| j["input"].as_str().unwrap_or_default().contains(name))
        .unwrap_or_else(|| panic!("no job for {name}: {jobs:?}"))
}

fn attempts_log(lab: &Lab, job: &serde_json::Value) -> Vec<serde_json::Value> {
    let shown = lab.show(job["id"].as_i64().unwrap());
    shown["attempts_log"].as_array().unwrap().clone()
}

#[test]
fn abort_segfault_and_out_of_memory_fail_only_their_jobs() {
    let lab = Lab::new(0.3, "max_attempts = 2\njob_memory_mb = 320\n");
    let mut d = KillOnDrop(lab.start(&[(
        "SCANMILL_TEST_WORKER_FAULT",
        "abort:poison-abort,segv:poison-segv,oom:poison-oom",
    )]));
    let pid = d.0.id();
    for name in ["poison-abort", "poison-segv", "poison-oom"] {
        std::fs::write(lab.inbox().join(format!("{name}.ply")), bunny_variant(name)).unwrap();
    }
    assert!(
        wait_for(120, || lab.count_state("quarantined") == 3),
        "{:?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    // The daemon is the same process, and still works.
    assert!(d.0.try_wait().unwrap().is_none(), "daemon exited");
    std::fs::write(lab.inbox().join("good.ply"), bunny_variant("good")).unwrap();
    assert!(
        wait_for(60, || lab.count_state("done") == 1),
        "{:?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    assert_eq!(d.0.id(), pid);
    assert!(d.0.try_wait().unwrap().is_none(), "daemon exited");

    let jobs = lab.jobs();
    for (name, kind, says) in [
        ("poison-abort", "worker_crashed", "signal 6 (SIGABRT)"),
        ("poison-segv", "worker_crashed", "signal 11 (SIGSEGV)"),
        ("poison-oom", "out_of_memory", "job_memory_mb = 320"),
    ] {
        let job = job_named(&jobs, name);
        assert_eq!(job["attempts"], 2, "{job}");
        let log = attempts_log(&lab, job);
        assert_eq!(log.len(), 2, "{log:?}");
        for a in &log {
            assert_eq!(a["error_kind"], kind, "{a}");
            let error = a["error"].as_str().unwrap();
            assert!(error.contains(says), "{name}: {error}");
            assert!(error.contains(" peak "), "{name}: {error}");
        }
    }
    assert!(
        wait_for(10, || lab.worker_pids().is_empty()),
        "{:?}",
        lab.worker_pids()
    );
    assert_eq!(
        lab.visible_outputs(),
        [
            "good",
            "good/good.obj",
            "good/good.preview.png",
            "good/good.scanmill.json"
        ],
        "nothing of a failed job is published"
    );
}

#[test]
fn the_attempt_count_of_a_poison_file_survives_a_restart() {
    let lab = Lab::new(0.3, "max_attempts = 3\n");
    // A long backoff, so that the daemon can be restarted between two attempts.
    let config = std::fs::read_to_string(&lab.config).unwrap();
    std::fs::write(
        &lab.config,
        config.replace("retry_base_secs = 0.5", "retry_base_secs = 600"),
    )
    .unwrap();
    let fault = [("SCANMILL_TEST_WORKER_FAULT", "abort:poison")];
    let mut d = lab.start(&fault);
    std::fs::write(lab.inbox().join("poison.ply"), bunny_variant("p")).unwrap();
    assert!(
        wait_for(60, || lab
            .jobs()
            .first()
            .is_some_and(|j| j["attempts"] == 1 && j["state"] == "failed")),
        "{:?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    signal(&d, libc::SIGTERM);
    assert_eq!(wait_exit(&mut d, 30), Some(0));
    // The backoff is long; a requeue by hand would reset the count, so the test changes
    // the retry time instead, as an operator would: the count must still be 1.
    let jobs = lab.jobs();
    assert_eq!(jobs[0]["attempts"], 1, "{jobs:?}");
    let db = lab.dir.path().join("state/scanmill.sqlite");
    let conn = rusqlite_open(&db);
    conn.execute("UPDATE job SET run_after = 0", []).unwrap();
    drop(conn);
    let _d = KillOnDrop(lab.start(&fault));
    assert!(
        wait_for(60, || {
            let j = lab.jobs();
            j.first()
                .is_some_and(|j| j["attempts"] == 2 && j["state"] == "failed")
        }),
        "{:?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    let conn = rusqlite_open(&db);
    conn.execute("UPDATE job SET run_after = 0", []).unwrap();
    drop(conn);
    assert!(
        wait_for(60, || lab.count_state("quarantined") == 1),
        "{:?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    assert_eq!(lab.jobs()[0]["attempts"], 3);
}

fn rusqlite_open(path: &std::path::Path) -> scanmill::store::rusqlite::Connection {
    let conn = scanmill::store::rusqlite::Connection::open(path).unwrap();
    conn.busy_timeout(std::time::Duration::from_secs(10))
        .unwrap();
    conn
}

#[test]
fn a_hanging_worker_is_killed_at_the_timeout_and_never_overlaps_its_retry() {
    let lab = Lab::new(0.3, "max_attempts = 2\njob_timeout_secs = 2\nworkers = 1\n");
    let _d = KillOnDrop(lab.start(&[("SCANMILL_TEST_WORKER_FAULT", "hang:stuck")]));
    std::fs::write(lab.inbox().join("stuck.ply"), bunny_variant("stuck")).unwrap();
    let mut most_workers = 0;
    assert!(
        wait_for(90, || {
            most_workers = most_workers.max(lab.worker_pids().len());
            lab.count_state("quarantined") == 1
        }),
        "{:?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    assert!(
        most_workers <= 1,
        "two attempts ran at once ({most_workers})"
    );
    let job = &lab.jobs()[0];
    for a in attempts_log(&lab, job) {
        assert_eq!(a["error_kind"], "timeout", "{a}");
        assert!(
            a["error"]
                .as_str()
                .unwrap()
                .contains("job_timeout_secs = 2"),
            "{a}"
        );
    }
    assert!(
        wait_for(10, || lab.worker_pids().is_empty()),
        "{:?}",
        lab.worker_pids()
    );
}

#[test]
fn a_spinning_worker_is_stopped_by_its_cpu_limit() {
    let lab = Lab::new(0.3, "max_attempts = 1\njob_cpu_secs = 1\n");
    let _d = KillOnDrop(lab.start(&[("SCANMILL_TEST_WORKER_FAULT", "spin:spin")]));
    std::fs::write(lab.inbox().join("spin.ply"), bunny_variant("spin")).unwrap();
    assert!(
        wait_for(60, || lab.count_state("quarantined") == 1),
        "{:?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    let job = &lab.jobs()[0];
    let log = attempts_log(&lab, job);
    assert_eq!(log[0]["error_kind"], "cpu_limit", "{log:?}");
    assert!(
        log[0]["error"]
            .as_str()
            .unwrap()
            .contains("job_cpu_secs = 1"),
        "{log:?}"
    );
}

#[test]
fn a_database_locked_longer_than_the_busy_timeout_is_waited_out() {
    let lab = Lab::new(0.3, "");
    let mut d = KillOnDrop(lab.start(&[("SCANMILL_TEST_STEP_DELAY_MS", "300")]));
    std::fs::write(lab.inbox().join("a.ply"), bunny_variant("a")).unwrap();
    assert!(
        wait_for(60, || lab.count_state("running") == 1),
        "{:?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    // Another process takes the write lock for longer than SQLite's 10 s busy timeout,
    // while the job finishes and a second scan arrives.
    let db = lab.dir.path().join("state/scanmill.sqlite");
    let conn = rusqlite_open(&db);
    conn.execute_batch("BEGIN IMMEDIATE").unwrap();
    std::fs::write(lab.inbox().join("b.ply"), bunny_variant("b")).unwrap();
    std::thread::sleep(std::time::Duration::from_secs(14));
    conn.execute_batch("COMMIT").unwrap();
    drop(conn);
    assert!(d.0.try_wait().unwrap().is_none(), "{}", lab.logs());
    assert!(
        wait_for(60, || lab.count_state("done") == 2),
        "{:?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    assert!(lab.logs().contains("write lock"), "{}", lab.logs());
}

#[test]
fn the_daemons_input_limits_reach_the_worker() {
    let lab = Lab::new(0.3, "[limits]\nmax_file_bytes = 2000\n");
    let _d = KillOnDrop(lab.start(&[]));
    std::fs::write(lab.inbox().join("big.ply"), bunny_variant("big")).unwrap();
    assert!(
        wait_for(60, || lab.count_state("failed") == 1),
        "{:?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    let job = &lab.jobs()[0];
    assert_eq!(job["error_kind"], "input", "{job}");
    assert!(
        job["error"]
            .as_str()
            .unwrap()
            .contains("limits.max_file_bytes = 2000"),
        "{job}"
    );
}
