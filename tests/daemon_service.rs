//! The service end to end: the real binary on temporary folders, real scans from
//! ../shared/data, a normals-only recipe, short quiet periods. Every wait is a poll with a
//! generous deadline; nothing asserts on durations.

mod common;
mod daemon_support;

use daemon_support::*;
use std::collections::BTreeSet;
use std::path::Path;
use std::time::Duration;

#[test]
fn slow_piecewise_scan_is_processed_once_with_its_texture() {
    let lab = Lab::new(1.0, "");
    let _d = KillOnDrop(lab.start(&[]));
    let scan = lab.inbox().join("session1");
    std::fs::create_dir(&scan).unwrap();
    let src = james_dir();
    let pause = Duration::from_millis(150);
    // OBJ first, in pieces; then the MTL and the texture later, each in pieces. Every gap
    // while a member is missing is longer than the quiet period.
    write_slowly(
        &scan.join("james.obj"),
        &std::fs::read(src.join("james.obj")).unwrap(),
        4,
        pause,
    );
    std::thread::sleep(Duration::from_millis(1500));
    write_slowly(
        &scan.join("james.obj.mtl"),
        &std::fs::read(src.join("james.obj.mtl")).unwrap(),
        2,
        pause,
    );
    std::thread::sleep(Duration::from_millis(1500));
    assert_eq!(
        lab.jobs().len(),
        0,
        "nothing may start before the texture is there"
    );
    write_slowly(
        &scan.join("james.jpg"),
        &std::fs::read(src.join("james.jpg")).unwrap(),
        5,
        pause,
    );

    assert!(
        wait_for(60, || lab.count_state("done") == 1),
        "{}",
        lab.logs()
    );
    // Still one job a while later: processed once.
    std::thread::sleep(Duration::from_millis(1500));
    let jobs = lab.jobs();
    assert_eq!(jobs.len(), 1, "{jobs:#?}");
    let shown = lab.show(jobs[0]["id"].as_i64().unwrap());
    assert_eq!(
        shown["inputs"].as_array().unwrap().len(),
        3,
        "obj + mtl + texture"
    );
    let out = lab.outbox().join("session1/james");
    for f in ["james.obj", "james.mtl", "james.jpg", "james.scanmill.json"] {
        assert!(out.join(f).is_file(), "{f} missing in {}", out.display());
    }
    assert_eq!(
        std::fs::read(out.join("james.jpg")).unwrap(),
        std::fs::read(src.join("james.jpg")).unwrap(),
        "the texture is the complete one"
    );
    // The report with its steps and metrics is recorded.
    assert_eq!(shown["report"]["steps"][0]["kind"], "normals");
    assert_eq!(shown["attempts_log"][0]["steps"][0]["kind"], "normals");
}

#[test]
fn two_hundred_scans_from_four_writers_each_done_once() {
    let lab = Lab::new(0.5, "workers = 2");
    let _d = KillOnDrop(lab.start(&[]));
    let inbox = lab.inbox();
    let writers: Vec<_> = (0..4)
        .map(|w| {
            let inbox = inbox.clone();
            std::thread::spawn(move || {
                for n in 0..50 {
                    let bytes = bunny_variant(&format!("writer {w} scan {n}"));
                    match w {
                        // Written in place.
                        0 => std::fs::write(inbox.join(format!("w0_{n}.ply")), &bytes).unwrap(),
                        // Written under a temporary name, renamed into place.
                        1 => {
                            let tmp = inbox.join(format!(".w1_{n}.ply.tmp"));
                            std::fs::write(&tmp, &bytes).unwrap();
                            std::fs::rename(&tmp, inbox.join(format!("w1_{n}.ply"))).unwrap();
                        }
                        // A new nested folder per scan.
                        2 => {
                            let d = inbox.join(format!("w2/day/scan_{n}"));
                            std::fs::create_dir_all(&d).unwrap();
                            std::fs::write(d.join("bunny.ply"), &bytes).unwrap();
                        }
                        // A whole folder built elsewhere and renamed in.
                        _ => {
                            let stage = inbox.join(format!(".stage_{n}"));
                            std::fs::create_dir_all(stage.join("inner")).unwrap();
                            std::fs::write(stage.join("inner/bunny.ply"), &bytes).unwrap();
                            std::fs::rename(&stage, inbox.join(format!("w3_{n}"))).unwrap();
                        }
                    }
                }
            })
        })
        .collect();
    for w in writers {
        w.join().unwrap();
    }
    assert!(
        wait_for(240, || lab.count_state("done") == 200),
        "done: {}\n{}",
        lab.count_state("done"),
        lab.logs()
    );
    let jobs = lab.jobs();
    assert_eq!(jobs.len(), 200, "one job per scan");
    let inputs: BTreeSet<_> = jobs
        .iter()
        .map(|j| j["input"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(inputs.len(), 200, "no input twice");
    let outputs: BTreeSet<_> = jobs
        .iter()
        .map(|j| j["output"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(outputs.len(), 200, "no output twice");
    for o in &outputs {
        let dir = Path::new(o);
        let stem = dir.file_name().unwrap().to_string_lossy().into_owned();
        assert!(!stem.contains(".v"), "no second version: {o}");
        assert!(dir.join(format!("{stem}.obj")).is_file(), "{o}");
        assert!(dir.join(format!("{stem}.scanmill.json")).is_file(), "{o}");
    }
    // The database's output rows name files that exist with their recorded sizes.
    let shown = lab.show(jobs[199]["id"].as_i64().unwrap());
    for f in shown["outputs"].as_array().unwrap() {
        let meta = std::fs::metadata(f["path"].as_str().unwrap()).unwrap();
        assert_eq!(meta.len(), f["bytes"].as_u64().unwrap());
    }
}

#[test]
fn sigkill_mid_job_then_restart_completes_without_duplicate_or_partial_output() {
    let lab = Lab::new(0.3, "");
    let mut d = lab.start(&[("SCANMILL_TEST_STEP_DELAY_MS", "1500")]);
    copy_james(&lab.inbox().join("s"));
    assert!(
        wait_for(60, || lab.count_state("running") == 1),
        "{}",
        lab.logs()
    );
    signal(&d, libc::SIGKILL);
    let _ = d.wait();
    // The job's worker process does not outlive its daemon.
    assert!(
        wait_for(10, || lab.worker_pids().is_empty()),
        "orphaned workers: {:?}",
        lab.worker_pids()
    );
    assert!(
        lab.visible_outputs().is_empty(),
        "partial output: {:?}",
        lab.visible_outputs()
    );

    let _d2 = KillOnDrop(lab.start(&[]));
    assert!(
        wait_for(60, || lab.count_state("done") == 1),
        "{}",
        lab.logs()
    );
    let jobs = lab.jobs();
    assert_eq!(jobs.len(), 1);
    assert_eq!(
        jobs[0]["attempts"], 2,
        "the attempt the daemon died in is counted, so a file that kills it is quarantined in the end"
    );
    let shown = lab.show(jobs[0]["id"].as_i64().unwrap());
    let outcomes: Vec<_> = shown["attempts_log"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["outcome"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(outcomes, ["interrupted", "ok"]);
    assert_eq!(
        lab.visible_outputs(),
        [
            "s",
            "s/james",
            "s/james/james.jpg",
            "s/james/james.mtl",
            "s/james/james.obj",
            "s/james/james.preview.png",
            "s/james/james.scanmill.json"
        ]
    );
    // No temporaries left behind.
    let staging = lab.outbox().join(".scanmill-staging");
    assert!(
        std::fs::read_dir(&staging)
            .map(|mut r| r.next().is_none())
            .unwrap_or(true)
    );
}

#[test]
fn bad_inputs_interleaved_with_good_ones() {
    let lab = Lab::new(0.5, "incomplete_report_secs = 1\nmax_attempts = 2");
    let d = lab.start(&[("SCANMILL_TEST_STEP_DELAY_MS", "500")]);
    let mut d = KillOnDrop(d);
    let inbox = lab.inbox();
    let good = |n: usize| {
        std::fs::write(
            inbox.join(format!("good_{n}.ply")),
            bunny_variant(&format!("good {n}")),
        )
        .unwrap()
    };
    good(0);
    std::fs::write(inbox.join("garbage.ply"), b"this is not a mesh\n").unwrap();
    good(1);
    std::fs::write(inbox.join("empty.ply"), b"").unwrap();
    good(2);
    let bunny = bunny();
    std::fs::write(inbox.join("truncated.ply"), &bunny[..bunny.len() / 2]).unwrap();
    good(3);
    std::fs::write(
        inbox.join("bad_index.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
    )
    .unwrap();
    std::fs::write(
        inbox.join("nan.obj"),
        "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    good(4);
    // An OBJ whose texture never arrives.
    let lonely = inbox.join("lonely");
    copy_james(&lonely);
    std::fs::remove_file(lonely.join("james.jpg")).unwrap();
    // A dangling link (unreadable whoever we are).
    std::os::unix::fs::symlink(inbox.join("nowhere.ply"), inbox.join("dangling.ply")).unwrap();
    good(5);

    // Every good one done, every bad one failed or waiting with a reason.
    assert!(
        wait_for(90, || lab.count_state("done") == 6),
        "{}",
        lab.logs()
    );
    assert!(
        wait_for(60, || lab.count_state("failed")
            + lab.count_state("quarantined")
            == 5),
        "{:#?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    for j in lab
        .jobs()
        .iter()
        .filter(|j| j["state"] == "failed" || j["state"] == "quarantined")
    {
        assert!(!j["error"].as_str().unwrap_or("").is_empty(), "{j}");
    }
    assert!(
        wait_for(30, || lab.jobs_with(&["--status", "waiting"]).len() == 2),
        "{:#?}",
        lab.jobs_with(&["--status", "waiting"])
    );
    let waiting = lab.jobs_with(&["--status", "waiting"]);
    let reasons: Vec<_> = waiting
        .iter()
        .map(|w| w["error"].as_str().unwrap().to_string())
        .collect();
    assert!(
        reasons.iter().any(|r| r.contains("james.jpg")),
        "{reasons:?}"
    );
    assert!(
        reasons.iter().any(|r| r.contains("cannot read")),
        "{reasons:?}"
    );

    // A file that vanishes while its job runs: recorded, not fatal.
    std::fs::write(inbox.join("vanishing.ply"), bunny_variant("vanishing")).unwrap();
    assert!(
        wait_for(60, || lab.jobs().iter().any(|j| j["input"]
            .as_str()
            .unwrap()
            .ends_with("vanishing.ply")
            && j["state"] == "running")),
        "{}",
        lab.logs()
    );
    std::fs::remove_file(inbox.join("vanishing.ply")).unwrap();
    assert!(
        wait_for(60, || lab.jobs().iter().any(|j| j["input"]
            .as_str()
            .unwrap()
            .ends_with("vanishing.ply")
            && j["state"] == "failed"
            && j["error_kind"] == "input_vanished")),
        "{:#?}",
        lab.jobs()
    );
    // And the service is still there, still working.
    good(6);
    assert!(
        wait_for(60, || lab.count_state("done") == 7),
        "{}",
        lab.logs()
    );
    assert!(
        d.0.try_wait().unwrap().is_none(),
        "the daemon must not stop"
    );
}

#[test]
fn sigterm_lets_a_running_job_finish_or_requeues_it() {
    // Drain deadline long enough: the job finishes, exit 0.
    let lab = Lab::new(0.3, "");
    let d = lab.start(&[("SCANMILL_TEST_STEP_DELAY_MS", "700")]);
    let mut d = KillOnDrop(d);
    std::fs::write(lab.inbox().join("a.ply"), bunny_variant("a")).unwrap();
    assert!(
        wait_for(60, || lab.count_state("running") == 1),
        "{}",
        lab.logs()
    );
    signal(&d.0, libc::SIGTERM);
    assert_eq!(wait_exit(&mut d.0, 60), Some(0), "{}", lab.logs());
    assert_eq!(lab.count_state("done"), 1, "{:#?}", lab.jobs());

    // Drain deadline too short: the job goes back to the queue, not counted, exit 0.
    let lab = Lab::new(0.3, "drain_timeout_secs = 0.2");
    let d = lab.start(&[("SCANMILL_TEST_STEP_DELAY_MS", "3000")]);
    let mut d = KillOnDrop(d);
    std::fs::write(lab.inbox().join("b.ply"), bunny_variant("b")).unwrap();
    assert!(
        wait_for(60, || lab.count_state("running") == 1),
        "{}",
        lab.logs()
    );
    signal(&d.0, libc::SIGTERM);
    assert_eq!(wait_exit(&mut d.0, 60), Some(0), "{}", lab.logs());
    let jobs = lab.jobs();
    assert_eq!(jobs[0]["state"], "queued", "{jobs:#?}");
    assert_eq!(jobs[0]["attempts"], 0);
    assert!(lab.visible_outputs().is_empty());
}

#[test]
fn history_show_requeue_and_backup_while_the_daemon_runs() {
    let lab = Lab::new(0.3, "");
    let mut d = KillOnDrop(lab.start(&[]));
    std::fs::write(lab.inbox().join("a.ply"), bunny_variant("a")).unwrap();
    copy_james(&lab.inbox().join("j"));
    assert!(
        wait_for(60, || lab.count_state("done") == 2),
        "{}",
        lab.logs()
    );

    let (code, text, _) = lab.cli(&["history"]);
    assert_eq!(code, 0);
    assert!(text.contains("done") && text.contains("2 row(s)"), "{text}");
    let (code, csv, _) = lab.cli(&["history", "--csv", "--input", "*james*", "--since", "1h"]);
    assert_eq!(code, 0);
    assert_eq!(csv.lines().count(), 2, "{csv}");
    let (code, _, err) = lab.cli(&["history", "--status", "bogus"]);
    assert_eq!(code, 64, "{err}");

    let id = lab.jobs()[0]["id"].as_i64().unwrap();
    let shown = lab.show(id);
    assert_eq!(shown["state"], "done");
    assert!(
        shown["report"]["output"]["counts"]["faces"]
            .as_u64()
            .unwrap()
            > 0
    );
    assert!(!shown["outputs"].as_array().unwrap().is_empty());
    // The preview picture beside the result, its path recorded.
    let preview = shown["preview"].as_str().unwrap();
    assert!(
        preview.ends_with(".preview.png") && std::path::Path::new(preview).is_file(),
        "{preview}"
    );
    // Every path recorded is where the files are now, never the staging folder.
    let report_preview = shown["report"]["preview"]["file"]["path"].as_str().unwrap();
    assert_eq!(report_preview, preview);
    for file in shown["report"]["output"]["files"].as_array().unwrap() {
        let path = file["path"].as_str().unwrap();
        assert!(std::path::Path::new(path).is_file(), "{path}");
    }
    assert!(!shown.to_string().contains(".scanmill-staging"), "{shown}");
    let (code, _, _) = lab.cli(&["show", "9999"]);
    assert_ne!(code, 0);

    // Requeue: processed again, published next to the first result, never over it.
    let (code, out, err) = lab.cli(&["requeue", &id.to_string()]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("done -> queued"), "{out}");
    assert!(
        wait_for(60, || lab.jobs().iter().any(|j| j["id"] == id
            && j["state"] == "done"
            && j["output"].as_str().unwrap_or("").ends_with(".v2"))),
        "{:#?}\n{}",
        lab.jobs(),
        lab.logs()
    );

    let backup = lab.dir.path().join("backup.sqlite");
    let (code, _, err) = lab.cli(&["db", "backup", backup.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let conn = rusqlite::Connection::open(&backup).unwrap();
    let n: i64 = conn
        .query_row("SELECT count(*) FROM job", [], |r| r.get(0))
        .unwrap();
    assert_eq!(n, 2);

    // A second daemon on the same state directory is refused.
    let second = std::process::Command::new(BIN)
        .args(["daemon", "--config"])
        .arg(&lab.config)
        .output()
        .unwrap();
    assert_eq!(
        second.status.code(),
        Some(75),
        "{}",
        String::from_utf8_lossy(&second.stderr)
    );
    assert!(d.0.try_wait().unwrap().is_none());
}
