//! Watch roots against hostile folders, end to end on the real binary: symbolic links,
//! references that lead outside the root, special files, names that are not UTF-8 or hold
//! control characters, and inputs so large that reading them would hold the service loop.
//! Every wait is a poll with a generous deadline; nothing asserts on durations.

mod common;
mod daemon_support;

use daemon_support::*;
use std::ffi::OsStr;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::symlink;
use std::path::Path;

/// Adds keys to the lab's `[[watch]]` table (the last table of its config).
fn watch_keys(lab: &Lab, keys: &str) {
    use std::io::Write;
    let mut f = std::fs::OpenOptions::new()
        .append(true)
        .open(&lab.config)
        .unwrap();
    writeln!(f, "{keys}").unwrap();
}

fn waiting(lab: &Lab) -> Vec<serde_json::Value> {
    lab.jobs_with(&["--status", "waiting"])
}

/// The waiting row whose input ends with `name`, once it is there.
fn wait_waiting(lab: &Lab, name: &str) -> serde_json::Value {
    let mut found = None;
    assert!(
        wait_for(60, || {
            found = waiting(lab)
                .into_iter()
                .find(|w| w["input"].as_str().unwrap_or("").ends_with(name));
            found.is_some()
        }),
        "{name} never recorded as waiting: {:#?}\n{}",
        waiting(lab),
        lab.logs()
    );
    found.unwrap()
}

fn done_inputs(lab: &Lab) -> Vec<String> {
    lab.jobs()
        .iter()
        .filter(|j| j["state"] == "done")
        .map(|j| j["input"].as_str().unwrap().to_string())
        .collect()
}

/// Drops a fresh good scan and waits for it to be done: the daemon is alive and working.
fn good_scan_is_processed(lab: &Lab, tag: &str) {
    let name = format!("good_{tag}.ply");
    std::fs::write(lab.inbox().join(&name), bunny_variant(tag)).unwrap();
    assert!(
        wait_for(90, || done_inputs(lab).iter().any(|i| i.ends_with(&name))),
        "{name} not processed: {:#?}\n{}",
        lab.jobs(),
        lab.logs()
    );
}

fn database(lab: &Lab) -> rusqlite::Connection {
    rusqlite::Connection::open_with_flags(
        lab.dir.path().join("state/scanmill.sqlite"),
        rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY,
    )
    .unwrap()
}

/// Every (size, sha256) of every recorded job input.
fn recorded_inputs(lab: &Lab) -> Vec<(i64, String)> {
    let db = database(lab);
    let mut stmt = db.prepare("SELECT size, sha256 FROM job_input").unwrap();
    stmt.query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
        .unwrap()
        .map(Result::unwrap)
        .collect()
}

fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    hex::encode(sha2::Sha256::digest(bytes))
}

#[test]
fn symlinked_mesh_is_refused_by_default() {
    let lab = Lab::new(0.3, "");
    let _d = KillOnDrop(lab.start(&[]));
    // The target is inside the root under a name that is no scan of its own.
    std::fs::create_dir(lab.inbox().join("data")).unwrap();
    std::fs::write(lab.inbox().join("data/bunny.bin"), bunny_variant("linked")).unwrap();
    symlink("data/bunny.bin", lab.inbox().join("link.ply")).unwrap();
    let w = wait_waiting(&lab, "link.ply");
    let reason = w["error"].as_str().unwrap();
    assert!(
        reason.contains("symbolic link") && reason.contains("follow_symlinks = false"),
        "{reason}"
    );
    good_scan_is_processed(&lab, "after_link");
    assert_eq!(lab.jobs().len(), 1, "only the good scan: {:#?}", lab.jobs());
}

#[test]
fn symlinked_mesh_is_followed_when_enabled_and_only_inside_the_root() {
    let lab = Lab::new(0.3, "");
    watch_keys(&lab, "follow_symlinks = true");
    let _d = KillOnDrop(lab.start(&[]));
    std::fs::create_dir(lab.inbox().join("data")).unwrap();
    std::fs::write(lab.inbox().join("data/bunny.bin"), bunny_variant("linked")).unwrap();
    symlink("data/bunny.bin", lab.inbox().join("link.ply")).unwrap();
    // A link to a mesh outside the watched folder.
    let outside = lab.dir.path().join("outside.ply");
    let outside_bytes = bunny_variant("outside");
    std::fs::write(&outside, &outside_bytes).unwrap();
    symlink(&outside, lab.inbox().join("escape.ply")).unwrap();

    assert!(
        wait_for(90, || done_inputs(&lab)
            .iter()
            .any(|i| i.ends_with("/link.ply"))),
        "{:#?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    let w = wait_waiting(&lab, "escape.ply");
    assert!(
        w["error"]
            .as_str()
            .unwrap()
            .contains("outside the watched folder"),
        "{w}"
    );
    let outside_hash = sha256_hex(&outside_bytes);
    assert!(
        recorded_inputs(&lab)
            .iter()
            .all(|(_, h)| *h != outside_hash),
        "the outside file was hashed into the database"
    );
    assert_eq!(lab.jobs().len(), 1, "{:#?}", lab.jobs());
}

#[test]
fn symlink_to_passwd_leaks_nothing() {
    let passwd = std::fs::read_to_string("/etc/passwd").unwrap();
    let lines: Vec<&str> = passwd.lines().filter(|l| l.len() >= 8).collect();
    assert!(!lines.is_empty(), "/etc/passwd has no line to look for");
    for follow in [false, true] {
        let lab = Lab::new(0.3, "");
        if follow {
            watch_keys(&lab, "follow_symlinks = true");
        }
        let _d = KillOnDrop(lab.start(&[]));
        symlink("/etc/passwd", lab.inbox().join("x.obj")).unwrap();
        wait_waiting(&lab, "x.obj");
        good_scan_is_processed(&lab, "after_passwd");
        let mut everything = lab.logs();
        for args in [
            &["history"][..],
            &["history", "--json"],
            &["history", "--csv"],
            &["history", "--status", "waiting"],
            &["show", "1"],
        ] {
            let (_, out, err) = lab.cli(args);
            everything.push_str(&out);
            everything.push_str(&err);
        }
        for line in &lines {
            assert!(
                !everything.contains(line),
                "follow_symlinks = {follow}: a line of /etc/passwd was shown: {line}"
            );
        }
        assert_eq!(lab.jobs().len(), 1, "{:#?}", lab.jobs());
    }
}

#[test]
fn references_outside_the_root_are_never_members() {
    let lab = Lab::new(0.3, "");
    let _d = KillOnDrop(lab.start(&[]));
    let lab_dir = lab.dir.path();
    let image = b"\x89PNG not really, but outside".to_vec();
    std::fs::write(lab_dir.join("secret.png"), &image).unwrap();
    let mtl = b"newmtl m\nmap_Kd secret.png\n".to_vec();
    std::fs::write(lab_dir.join("outside.mtl"), &mtl).unwrap();
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3\n";
    // `../` from the root, an absolute path, and a texture that climbs out of an MTL that
    // is itself inside the root.
    std::fs::write(
        lab.inbox().join("up.obj"),
        format!("mtllib ../outside.mtl\n{tri}"),
    )
    .unwrap();
    std::fs::write(
        lab.inbox().join("abs.obj"),
        format!("mtllib {}\n{tri}", lab_dir.join("outside.mtl").display()),
    )
    .unwrap();
    std::fs::write(
        lab.inbox().join("in.mtl"),
        b"newmtl m\nmap_Kd ../secret.png\n",
    )
    .unwrap();
    std::fs::write(
        lab.inbox().join("climb.obj"),
        format!("mtllib in.mtl\n{tri}"),
    )
    .unwrap();

    for name in ["up.obj", "abs.obj", "climb.obj"] {
        let w = wait_waiting(&lab, name);
        let reason = w["error"].as_str().unwrap();
        assert!(
            reason.starts_with("refused:") && reason.contains("outside the watched folder"),
            "{name}: {reason}"
        );
    }
    good_scan_is_processed(&lab, "after_outside");
    // A lab looking at the jobs, or at what failed, is told of the refused scans.
    for args in [&["history"][..], &["history", "--status", "failed"]] {
        let (code, text, _) = lab.cli(args);
        assert_eq!(code, 0);
        assert!(
            text.contains("3 scan(s) found but not jobs")
                && text.contains("history --status waiting"),
            "{args:?}: {text}"
        );
    }
    let (_, done, _) = lab.cli(&["history", "--status", "done"]);
    assert!(!done.contains("not jobs"), "{done}");
    let recorded = recorded_inputs(&lab);
    for outside in [&mtl, &image] {
        let hash = sha256_hex(outside);
        assert!(
            recorded.iter().all(|(_, h)| *h != hash),
            "an outside file was hashed into the database"
        );
    }
    assert_eq!(lab.jobs().len(), 1, "{:#?}", lab.jobs());
}

#[test]
fn fifo_with_a_mesh_name_is_refused_unopened() {
    let lab = Lab::new(0.3, "");
    let _d = KillOnDrop(lab.start(&[]));
    let fifo = lab.inbox().join("pipe.ply");
    let c = std::ffi::CString::new(fifo.as_os_str().as_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0);
    let w = wait_waiting(&lab, "pipe.ply");
    assert!(
        w["error"].as_str().unwrap().contains("not a regular file"),
        "{w}"
    );
    good_scan_is_processed(&lab, "after_fifo");
}

#[test]
fn odd_names_are_processed_and_shown_escaped() {
    let lab = Lab::new(0.3, "");
    let _d = KillOnDrop(lab.start(&[]));
    let invalid = OsStr::from_bytes(b"bun\xff\xfe.ply");
    let control = OsStr::from_bytes(b"new\nline\x1b[31m\rx.ply");
    let same = bunny_variant("invalid utf-8");
    std::fs::write(lab.inbox().join(invalid), &same).unwrap();
    std::fs::write(lab.inbox().join(control), bunny_variant("control")).unwrap();
    // A byte-identical copy under a plain name: the same job, its own sighting.
    std::fs::write(lab.inbox().join("copy.ply"), &same).unwrap();

    assert!(
        wait_for(90, || lab.count_state("done") == 2),
        "{:#?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    let inputs = done_inputs(&lab);
    assert!(
        inputs.iter().any(|i| i.ends_with("/bun\\xff\\xfe.ply"))
            || inputs.iter().any(|i| i.ends_with("/copy.ply")),
        "{inputs:?}"
    );
    let control_shown = "new\\nline\\x1b[31m\\rx.ply";
    assert!(
        inputs.iter().any(|i| i.ends_with(control_shown)),
        "{inputs:?}"
    );
    // Both sightings of the shared content are recorded, each under its own name.
    let shared = lab
        .jobs()
        .into_iter()
        .find(|j| !j["input"].as_str().unwrap().ends_with(control_shown))
        .unwrap();
    let mut sighted = Vec::new();
    assert!(
        wait_for(30, || {
            let shown = lab.show(shared["id"].as_i64().unwrap());
            sighted = shown["sightings"]
                .as_array()
                .unwrap()
                .iter()
                .map(|s| s["rel_path"].as_str().unwrap().to_string())
                .collect();
            sighted.len() == 2
        }),
        "{sighted:?}"
    );
    sighted.sort();
    assert_eq!(sighted, ["bun\\xff\\xfe.ply", "copy.ply"]);
    // The job's report is recorded whole, its input path escaped.
    let report = &lab.show(shared["id"].as_i64().unwrap())["report"];
    assert!(
        report["input"]["path"]
            .as_str()
            .is_some_and(|p| p.ends_with(".ply")),
        "{report}"
    );

    // Shown escaped: no raw control character in any output or log line.
    let (code, text, _) = lab.cli(&["history"]);
    assert_eq!(code, 0);
    assert!(text.contains(control_shown), "{text}");
    let (_, csv, _) = lab.cli(&["history", "--csv"]);
    let (_, shown, _) = lab.cli(&["show", &shared["id"].to_string()]);
    let logs = lab.logs();
    for (what, out) in [
        ("history", &text),
        ("csv", &csv),
        ("show", &shown),
        ("log", &logs),
    ] {
        let raw: Vec<&str> = out
            .lines()
            .filter(|l| l.contains('\x1b') || l.contains('\r'))
            .collect();
        assert!(
            raw.is_empty(),
            "{what} holds a raw control character: {raw:?}"
        );
    }
    assert!(logs.contains(control_shown), "{logs}");
    // One record per line: every log line starts with its timestamp (or is a file header
    // of `logs()`), so no name split a record.
    for line in logs.lines().filter(|l| !l.is_empty()) {
        assert!(
            line.starts_with("--- ") || line.as_bytes()[0].is_ascii_digit(),
            "a log record was split: {line:?}"
        );
    }
    // The history rows: one per job plus the header and the count.
    assert_eq!(text.lines().count(), 2 + 2, "{text}");
}

/// Collects sd_notify datagrams sent to a socket in the lab.
struct NotifySink {
    path: std::path::PathBuf,
    received: std::sync::Arc<std::sync::Mutex<Vec<String>>>,
}

impl NotifySink {
    fn new(dir: &Path) -> NotifySink {
        let path = dir.join("notify.sock");
        let socket = std::os::unix::net::UnixDatagram::bind(&path).unwrap();
        let received = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let sink = received.clone();
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = socket.recv(&mut buf) {
                sink.lock()
                    .unwrap()
                    .push(String::from_utf8_lossy(&buf[..n]).into_owned());
            }
        });
        NotifySink { path, received }
    }

    fn pings(&self) -> usize {
        self.received
            .lock()
            .unwrap()
            .iter()
            .filter(|m| m.lines().any(|l| l == "WATCHDOG=1"))
            .count()
    }
}

#[test]
fn huge_inputs_are_refused_unread_while_the_loop_keeps_working() {
    let lab = Lab::new(0.3, "max_input_bytes = 100000000");
    let notify = NotifySink::new(lab.dir.path());
    let _d = KillOnDrop(lab.start(&[
        ("NOTIFY_SOCKET", notify.path.to_str().unwrap()),
        ("WATCHDOG_USEC", "2000000"),
    ]));
    assert!(
        wait_for(30, || notify.pings() > 0),
        "no watchdog ping at all"
    );
    let inbox = lab.inbox();
    // A one-line OBJ naming a 2 GiB MTL (sparse: no disk used).
    std::fs::write(inbox.join("huge.obj"), "mtllib huge.mtl\nv 0 0 0\n").unwrap();
    std::fs::File::create(inbox.join("huge.mtl"))
        .unwrap()
        .set_len(2 << 30)
        .unwrap();
    // A PLY far above max_input_bytes (sparse too).
    std::fs::File::create(inbox.join("big.ply"))
        .unwrap()
        .set_len(1 << 30)
        .unwrap();
    // A small gzip that expands to 64 MiB of newlines: only a bounded prefix is read.
    {
        use std::io::Write;
        let f = std::fs::File::create(inbox.join("bomb.obj.gz")).unwrap();
        let mut gz = flate2::write::GzEncoder::new(f, flate2::Compression::fast());
        let newlines = vec![b'\n'; 1 << 20];
        for _ in 0..64 {
            gz.write_all(&newlines).unwrap();
        }
        gz.finish().unwrap();
    }
    let before = notify.pings();

    let mtl = wait_waiting(&lab, "huge.obj");
    let reason = mtl["error"].as_str().unwrap();
    assert!(
        reason.contains("too large") && reason.contains("material library"),
        "{reason}"
    );
    let big = wait_waiting(&lab, "big.ply");
    let reason = big["error"].as_str().unwrap();
    assert!(
        reason.contains("too large")
            && reason.contains("max_input_bytes")
            && reason.contains("not hashed"),
        "{reason}"
    );
    good_scan_is_processed(&lab, "after_huge");
    // The bomb was looked at (it names no MTL, so it is a set of its own and runs as a job;
    // whatever the loader makes of it, the daemon is still there and answering).
    assert!(
        wait_for(90, || lab
            .jobs()
            .iter()
            .any(|j| j["input"].as_str().unwrap().ends_with("bomb.obj.gz"))),
        "{:#?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    // The watchdog was fed all along and still is.
    let after = notify.pings();
    assert!(after > before, "no ping since the huge inputs arrived");
    assert!(wait_for(30, || notify.pings() > after), "pings stopped");
    let recorded = recorded_inputs(&lab);
    assert!(
        recorded.iter().all(|(size, _)| *size < 100_000_000),
        "a huge file was recorded: {recorded:?}"
    );
}
