//! The shared job queue on a real PostgreSQL server (issue #25, docs/scale-out.md): several
//! daemons on one watch root and one output root, each with its own state folder, sharing
//! one server that the test starts itself (tests/common/pg.rs). Light recipe (normals only)
//! and tiny scans, so that what is measured is coordination, not geometry. Polling with
//! generous deadlines, never a timed assertion.

mod common;
mod daemon_support;

use common::pg::PgServer;
use daemon_support::{BIN, KillOnDrop, bunny_variant, daemon_command, signal, wait_exit, wait_for};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Shared folders (in, out) and one state folder and config per host.
struct Farm {
    dir: tempfile::TempDir,
    url: String,
}

impl Farm {
    fn new(server: &PgServer, db: &str) -> Farm {
        let dir = tempfile::tempdir().unwrap();
        for sub in ["in", "out"] {
            std::fs::create_dir(dir.path().join(sub)).unwrap();
        }
        std::fs::write(
            dir.path().join("recipe.toml"),
            "[output]\nformat = \"obj\"\n\n[[step]]\nkind = \"normals\"\n",
        )
        .unwrap();
        Farm {
            url: server.createdb(db),
            dir,
        }
    }

    fn inbox(&self) -> PathBuf {
        self.dir.path().join("in")
    }
    fn outbox(&self) -> PathBuf {
        self.dir.path().join("out")
    }

    /// Host `n`'s config: its own state folder, the shared folders, the shared store, and
    /// `extra` TOML tables at the end.
    fn config_with(&self, n: usize, lease_secs: f64, workers: usize, extra: &str) -> PathBuf {
        let d = self.dir.path();
        let state = d.join(format!("state{n}"));
        std::fs::create_dir_all(&state).unwrap();
        let path = d.join(format!("host{n}.toml"));
        std::fs::write(
            &path,
            format!(
                "state_dir = {state:?}\nworkers = {workers}\nrescan_secs = 5\nmin_free_disk_mb = 1\n\
                 retry_base_secs = 0.5\n\
                 [store]\nurl = {:?}\nlease_secs = {lease_secs}\nrescue_secs = 0.5\n\
                 [[watch]]\npath = {:?}\noutput = {:?}\nrecipe = {:?}\nquiet_period_secs = 0.5\n{extra}",
                self.url,
                d.join("in"),
                d.join("out"),
                d.join("recipe.toml"),
            ),
        )
        .unwrap();
        path
    }

    /// Starts host `n`; waits until it is ready.
    fn start(
        &self,
        n: usize,
        lease_secs: f64,
        workers: usize,
        envs: &[(&str, &str)],
    ) -> KillOnDrop {
        self.start_with(n, lease_secs, workers, envs, "")
    }

    /// [`Farm::start`] with `extra` TOML tables in the host's config.
    fn start_with(
        &self,
        n: usize,
        lease_secs: f64,
        workers: usize,
        envs: &[(&str, &str)],
        extra: &str,
    ) -> KillOnDrop {
        let config = self.config_with(n, lease_secs, workers, extra);
        let log_path = self.dir.path().join(format!("log-{n}.txt"));
        let log = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log_path)
            .unwrap();
        let before = std::fs::read_to_string(&log_path).unwrap_or_default().len();
        let child = KillOnDrop(daemon_command(&config, log, envs).spawn().unwrap());
        assert!(
            wait_for(60, || std::fs::read_to_string(&log_path)
                .unwrap_or_default()
                .get(before..)
                .is_some_and(|s| s.contains(" ready "))),
            "host {n} did not become ready:\n{}",
            self.logs()
        );
        child
    }

    fn logs(&self) -> String {
        let mut all = String::new();
        for n in 0..4 {
            let p = self.dir.path().join(format!("log-{n}.txt"));
            if let Ok(t) = std::fs::read_to_string(&p) {
                all.push_str(&format!("--- host {n}\n{t}"));
            }
        }
        all
    }

    /// Runs the CLI against the shared store (through host 0's config).
    fn cli(&self, args: &[&str]) -> (i32, String, String) {
        let out = Command::new(BIN)
            .args(args)
            .arg("--config")
            .arg(self.dir.path().join("host0.toml"))
            .output()
            .unwrap();
        (
            out.status.code().unwrap_or(-1),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    }

    fn jobs(&self) -> Vec<Value> {
        let (code, out, err) = self.cli(&["history", "--json"]);
        assert_eq!(code, 0, "{err}");
        serde_json::from_str(&out).unwrap()
    }

    fn show(&self, id: i64) -> Value {
        let (code, out, err) = self.cli(&["show", &id.to_string()]);
        assert_eq!(code, 0, "{err}");
        serde_json::from_str(&out).unwrap()
    }

    fn count_done(&self) -> usize {
        self.jobs().iter().filter(|j| j["state"] == "done").count()
    }
}

/// Every visible folder under `out` that holds a published scan, relative, with its files.
fn published(out: &Path) -> BTreeMap<String, Vec<String>> {
    let mut found = BTreeMap::new();
    let mut stack = vec![out.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        let mut files = Vec::new();
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.starts_with('.') {
                continue;
            }
            if e.file_type().is_ok_and(|t| t.is_dir()) {
                stack.push(e.path());
            } else {
                files.push(name);
            }
        }
        if !files.is_empty() {
            files.sort();
            let rel = d.strip_prefix(out).unwrap().to_string_lossy().into_owned();
            found.insert(rel, files);
        }
    }
    found
}

/// A published scan folder is whole: its mesh and its sidecar, both non-empty.
fn whole(out: &Path, rel: &str, files: &[String]) -> bool {
    let stem = Path::new(rel)
        .file_name()
        .unwrap()
        .to_string_lossy()
        .into_owned();
    let stem = stem.split(".v").next().unwrap().to_string();
    let sidecar = format!("{stem}.scanmill.json");
    let mesh = format!("{stem}.obj");
    files.contains(&sidecar)
        && files.contains(&mesh)
        && [sidecar, mesh]
            .iter()
            .all(|f| std::fs::metadata(out.join(rel).join(f)).is_ok_and(|m| m.len() > 0))
}

fn attempts(job: &Value) -> Vec<String> {
    job["attempts_log"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["outcome"].as_str().unwrap_or("").to_string())
        .collect()
}

#[test]
fn three_hosts_share_one_root_and_publish_every_scan_exactly_once() {
    let server = PgServer::start();
    let farm = Farm::new(&server, "three");
    let hosts: Vec<KillOnDrop> = (0..3).map(|n| farm.start(n, 5.0, 2, &[])).collect();

    // A watcher lists the output tree the whole time: a scan folder it sees is whole.
    let stop = Arc::new(AtomicBool::new(false));
    let watcher = {
        let (stop, out) = (stop.clone(), farm.outbox());
        std::thread::spawn(move || {
            let mut partial = Vec::new();
            let mut looks = 0u64;
            while !stop.load(Ordering::SeqCst) {
                for (rel, files) in published(&out) {
                    if !whole(&out, &rel, &files) {
                        partial.push(format!("{rel}: {files:?}"));
                    }
                }
                looks += 1;
            }
            (partial, looks)
        })
    };
    let writers: Vec<_> = (0..4)
        .map(|w| {
            let inbox = farm.inbox().join(format!("w{w}"));
            std::thread::spawn(move || {
                std::fs::create_dir_all(&inbox).unwrap();
                for i in 0..50 {
                    let tmp = inbox.join(format!(".s{i}.ply.part"));
                    std::fs::write(&tmp, bunny_variant(&format!("w{w}s{i}"))).unwrap();
                    std::fs::rename(&tmp, inbox.join(format!("s{i}.ply"))).unwrap();
                }
            })
        })
        .collect();
    for w in writers {
        w.join().unwrap();
    }
    let all_done = wait_for(600, || farm.count_done() == 200);
    stop.store(true, Ordering::SeqCst);
    let (partial, looks) = watcher.join().unwrap();
    assert!(all_done, "not all 200 done:\n{}", farm.logs());
    assert!(looks > 0);
    assert!(partial.is_empty(), "partial output seen: {partial:?}");

    let jobs = farm.jobs();
    assert_eq!(jobs.len(), 200, "one job per scan");
    let outputs = published(&farm.outbox());
    assert_eq!(outputs.len(), 200, "{:?}", outputs.keys());
    assert!(
        outputs.keys().all(|k| !k.contains(".v")),
        "a scan was published twice: {:?}",
        outputs
            .keys()
            .filter(|k| k.contains(".v"))
            .collect::<Vec<_>>()
    );
    // Every job: one successful attempt, and it ran on some host; work spread over hosts.
    let mut by_host: BTreeMap<String, usize> = BTreeMap::new();
    for j in &jobs {
        let shown = farm.show(j["id"].as_i64().unwrap());
        assert_eq!(attempts(&shown).iter().filter(|o| *o == "ok").count(), 1);
        let owner = shown["attempts_log"][0]["owner"]
            .as_str()
            .unwrap()
            .to_string();
        *by_host.entry(owner).or_default() += 1;
    }
    assert!(by_host.len() >= 2, "one host did everything: {by_host:?}");
    drop(hosts);
}

/// Host 0 runs a slow job (the test-only stage delay); returns once it is running there.
fn slow_job_on_host0(farm: &Farm) -> (KillOnDrop, i64) {
    let host0 = farm.start(0, 2.0, 1, &[("SCANMILL_TEST_STEP_DELAY_MS", "1500")]);
    std::fs::write(farm.inbox().join("slow.ply"), bunny_variant("slow")).unwrap();
    let mut id = 0;
    assert!(
        wait_for(60, || {
            let jobs = farm.jobs();
            match jobs.first() {
                Some(j) if j["state"] == "running" => {
                    id = j["id"].as_i64().unwrap();
                    true
                }
                _ => false,
            }
        }),
        "the job never ran:\n{}",
        farm.logs()
    );
    (host0, id)
}

#[test]
fn a_host_killed_mid_job_loses_its_lease_and_another_host_finishes() {
    let server = PgServer::start();
    let farm = Farm::new(&server, "killed");
    let (mut host0, id) = slow_job_on_host0(&farm);
    let _host1 = farm.start(1, 2.0, 1, &[]);
    signal(&host0.0, libc::SIGKILL);
    wait_exit(&mut host0.0, 30);
    assert!(
        wait_for(120, || farm.count_done() == 1),
        "not finished by the other host:\n{}",
        farm.logs()
    );
    let job = farm.show(id);
    assert_eq!(attempts(&job), ["lost", "ok"], "{job:#}");
    assert_eq!(job["attempts_log"][0]["error_kind"], "lease_expired");
    assert_ne!(
        job["attempts_log"][0]["owner"],
        job["attempts_log"][1]["owner"]
    );
    let outputs = published(&farm.outbox());
    assert_eq!(outputs.keys().collect::<Vec<_>>(), ["slow"], "{outputs:?}");
}

#[test]
fn a_paused_host_is_fenced_out_when_it_comes_back() {
    let server = PgServer::start();
    let farm = Farm::new(&server, "paused");
    let (host0, id) = slow_job_on_host0(&farm);
    signal(&host0.0, libc::SIGSTOP);
    let _host1 = farm.start(1, 2.0, 1, &[]);
    let finished = wait_for(120, || farm.count_done() == 1);
    // The paused host's worker process ran on: let its result wait, then wake the host.
    signal(&host0.0, libc::SIGCONT);
    assert!(finished, "not finished by the other host:\n{}", farm.logs());
    assert!(
        wait_for(60, || attempts(&farm.show(id))[0] == "superseded"),
        "the late attempt was not fenced out: {:#}\n{}",
        farm.show(id),
        farm.logs()
    );
    let job = farm.show(id);
    assert_eq!(attempts(&job), ["superseded", "ok"], "{job:#}");
    assert_eq!(job["state"], "done");
    assert_eq!(job["attempts_log"][1]["id"], job["attempt_token"]);
    assert!(farm.logs().contains("fenced out"), "{}", farm.logs());
    let outputs = published(&farm.outbox());
    assert_eq!(outputs.keys().collect::<Vec<_>>(), ["slow"], "{outputs:?}");
    let sidecar: Value = serde_json::from_str(
        &std::fs::read_to_string(farm.outbox().join("slow/slow.scanmill.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(sidecar["daemon"], job["attempts_log"][1]["owner"]);
}

#[test]
fn hosts_reconnect_after_a_server_restart_and_nothing_is_lost_or_doubled() {
    let server = PgServer::start();
    let farm = Farm::new(&server, "restart");
    let delay = [("SCANMILL_TEST_STEP_DELAY_MS", "100")];
    let _hosts: Vec<KillOnDrop> = (0..2).map(|n| farm.start(n, 10.0, 2, &delay)).collect();
    let inbox = farm.inbox();
    for i in 0..30 {
        std::fs::write(
            inbox.join(format!("r{i}.ply")),
            bunny_variant(&format!("r{i}")),
        )
        .unwrap();
    }
    assert!(wait_for(120, || farm.count_done() >= 5), "{}", farm.logs());
    server.restart();
    assert!(
        wait_for(300, || farm.count_done() == 30),
        "not all done after the restart:\n{}",
        farm.logs()
    );
    assert!(farm.logs().contains("connected again"), "{}", farm.logs());
    let jobs = farm.jobs();
    assert_eq!(jobs.len(), 30);
    let outputs = published(&farm.outbox());
    assert_eq!(outputs.len(), 30, "{:?}", outputs.keys());
    assert!(outputs.keys().all(|k| !k.contains(".v")), "{outputs:?}");
    for j in &jobs {
        let shown = farm.show(j["id"].as_i64().unwrap());
        assert_eq!(
            attempts(&shown).iter().filter(|o| *o == "ok").count(),
            1,
            "{shown:#}"
        );
    }
}

#[test]
fn sqlite_history_migrates_into_postgres_with_every_job_and_metric() {
    use daemon_support::Lab;
    let server = PgServer::start();
    let url = server.createdb("migrated");
    let lab = Lab::new(0.5, "");
    let mut daemon = KillOnDrop(lab.start(&[]));
    for i in 0..6 {
        std::fs::write(
            lab.inbox().join(format!("m{i}.ply")),
            bunny_variant(&format!("m{i}")),
        )
        .unwrap();
    }
    assert!(
        wait_for(120, || lab.count_state("done") == 6),
        "{}",
        lab.logs()
    );
    signal(&daemon.0, libc::SIGTERM);
    assert_eq!(wait_exit(&mut daemon.0, 60), Some(0));

    let (code, out, err) = lab.cli(&["db", "migrate", "--to", &url]);
    assert_eq!(code, 0, "{out}{err}");
    assert!(out.contains("copied 6 job"), "{out}");

    let sqlite = rusqlite::Connection::open(lab.dir.path().join("state/scanmill.sqlite")).unwrap();
    let mut pg = server.client("migrated");
    for table in [
        "job",
        "job_input",
        "job_output",
        "sighting",
        "attempt",
        "step_timing",
        "waiting",
    ] {
        let q = format!("SELECT count(*) FROM {table}");
        let a: i64 = sqlite.query_row(&q, [], |r| r.get(0)).unwrap();
        let b: i64 = pg.query_one(q.as_str(), &[]).unwrap().get(0);
        assert_eq!(a, b, "{table}");
        if table != "waiting" {
            assert!(
                a > 0,
                "{table} is empty: the comparison would prove nothing"
            );
        }
    }
    // A sample, compared as `show` prints it from either store (the lease columns aside).
    for id in [1, 4, 6] {
        let mut from_pg: Value = {
            let (code, out, err) = lab.cli(&["show", &id.to_string(), "--store", &url]);
            assert_eq!(code, 0, "{err}");
            serde_json::from_str(&out).unwrap()
        };
        let from_sqlite = lab.show(id);
        let map = from_pg.as_object_mut().unwrap();
        assert!(map.remove("lease_until").is_some());
        assert!(map.remove("attempt_token").is_some());
        assert_eq!(from_pg, from_sqlite, "job {id}");
    }
    // history reads the same rows through --store.
    let (code, out, _) = lab.cli(&["history", "--json", "--store", &url]);
    assert_eq!(code, 0);
    let rows: Vec<Value> = serde_json::from_str(&out).unwrap();
    assert_eq!(rows, lab.jobs());
    let (code, out, _) = lab.cli(&["history", "--json", "--input", "*/m3*", "--store", &url]);
    assert_eq!(code, 0);
    assert_eq!(serde_json::from_str::<Vec<Value>>(&out).unwrap().len(), 1);

    // Twice: refused, nothing changed.
    let (code, _, err) = lab.cli(&["db", "migrate", "--to", &url]);
    assert_eq!(code, 73, "{err}");
    assert!(err.contains("already holds 6 job(s)"), "{err}");
    // New ids continue after the copied ones; requeue works on the copy.
    let (code, out, err) = lab.cli(&["requeue", "2", "--store", &url]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("done -> queued"), "{out}");
    let next: i64 = pg
        .query_one("SELECT nextval(pg_get_serial_sequence('job', 'id'))", &[])
        .unwrap()
        .get(0);
    assert_eq!(next, 7);
}

#[test]
fn a_bad_store_url_or_unreachable_server_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("c.toml");
    let write = |store: &str| {
        std::fs::write(
            &config,
            format!(
                "state_dir = {:?}\n[store]\n{store}\nconnect_patience_secs = 1\n",
                dir.path()
            ),
        )
        .unwrap()
    };
    let run = |args: &[&str]| {
        let out = Command::new(BIN)
            .args(args)
            .arg("--config")
            .arg(&config)
            .output()
            .unwrap();
        (
            out.status.code().unwrap_or(-1),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    write("url = \"mysql://db/scans\"");
    let (code, err) = run(&["validate-config"]);
    assert_eq!(code, 78, "{err}");
    assert!(err.contains("[store] url"), "{err}");
    // A worker-only host (no [[watch]]) is a valid configuration on a shared store.
    write("url = \"postgres://scanmill@%2Fnonexistent:5999/scans\"");
    let (code, err) = run(&["validate-config"]);
    assert_eq!(code, 0, "{err}");
    let (code, err) = run(&["daemon"]);
    assert_eq!(code, 69, "{err}");
    let last = err.trim().lines().last().unwrap();
    assert!(
        last.starts_with("scanmill: error: postgres://scanmill@/nonexistent:5999/scans: error connecting to server: "),
        "{err}"
    );
}

/// Figures for docs/scale-out.md (not a check; run by hand, release-like `--profile test`):
/// the queue's own cost per job on either store (enqueue, claim, publish under the fence,
/// finish; no processing), then whole jobs per second with 1, 2 and 3 daemons on the
/// normals-only recipe. `cargo test --test pg_queue -- --ignored --nocapture queue_figures`
#[test]
#[ignore = "prints measurements for docs/scale-out.md; run by hand"]
fn queue_figures() {
    let server = PgServer::start_durable();
    queue_overhead(&server);
    for hosts in 1..=3 {
        claims_per_second(&server, hosts);
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn new_job(i: usize) -> scanmill::store::NewJob {
    use scanmill::store::{InputMember, InputRole, JobOrder, NewJob, RelPath};
    let rel = RelPath::new(format!("s{i}.ply")).unwrap();
    NewJob {
        order: JobOrder {
            job_key: format!("key{i}"),
            set_hash: format!("set{i}"),
            root: "/in".into(),
            rel_path: rel.clone(),
            output_root: "/out".into(),
            recipe_path: "/r.toml".into(),
            recipe_hash: "r".into(),
        },
        recipe_json: "{}".into(),
        config_hash: "c".into(),
        max_attempts: 3,
        inputs: vec![InputMember {
            rel_path: rel,
            role: InputRole::Mesh,
            size: 1000,
            mtime_ns: 1,
            ino: i as u64,
            sha256: format!("{i:064}"),
        }],
    }
}

fn done_finish() -> scanmill::store::Finish {
    use scanmill::store::{Finish, JobDone, MeshSizes, OutputFile, StepRow};
    Finish::Done(JobDone {
        output_dir: "/out/s".into(),
        preview: None,
        outputs: vec![OutputFile {
            path: "/out/s/s.obj".into(),
            bytes: 1,
            sha256: "0".repeat(64),
        }],
        report_json: "{}".into(),
        counts: MeshSizes::default(),
        process_ms: 1.0,
        steps: vec![StepRow {
            kind: "normals".into(),
            wall_ms: 1.0,
            vertices_before: 1,
            vertices_after: 1,
            faces_before: 1,
            faces_after: 1,
            figures_json: "{}".into(),
        }],
    })
}

fn queue_overhead(server: &PgServer) {
    use scanmill::store::{Owner, Queue, RetryPolicy, StoreConfig};
    use std::time::Instant;
    let retry = RetryPolicy {
        base_secs: 1.0,
        max_secs: 10.0,
    };
    let dir = tempfile::tempdir().unwrap();
    let url = server.createdb("overhead");
    let stores = [
        ("sqlite", StoreConfig::default()),
        (
            "postgres",
            StoreConfig {
                url: Some(url),
                ..StoreConfig::default()
            },
        ),
    ];
    let owner = Owner::current();
    let mut stats = server.client("overhead");
    stats
        .batch_execute("CREATE EXTENSION pg_stat_statements")
        .unwrap();
    for (name, config) in stores {
        let mut q = Queue::open(&config, &dir.path().join("s.sqlite")).unwrap();
        let fence = q.fence();
        let (mut enq, mut run) = (Vec::new(), Vec::new());
        for i in 0..400 {
            let t = Instant::now();
            q.enqueue(&new_job(i)).unwrap();
            enq.push(t.elapsed().as_secs_f64() * 1e3);
            let t = Instant::now();
            let job = q.claim(&owner).unwrap().unwrap();
            let finish = done_finish();
            if let Some(f) = &fence {
                let held = f.hold(&job, t, || Ok::<_, ()>(finish.clone())).unwrap();
                assert!(matches!(held, scanmill::store::pg::Fenced::Held(Ok(_))));
            }
            q.finish(&job, &finish, retry, 1.0).unwrap();
            run.push(t.elapsed().as_secs_f64() * 1e3);
        }
        println!(
            "FIGURE overhead {name}: enqueue median {:.3} ms, claim+publish-fence+finish median {:.3} ms (400 jobs)",
            median(enq),
            median(run)
        );
    }
    // Statements the server ran for those 400 jobs, per job (transactions included).
    let r = stats
        .query_one(
            "SELECT sum(calls)::bigint, sum(calls) FILTER (WHERE query ILIKE 'begin%' OR query ILIKE 'commit%')::bigint
             FROM pg_stat_statements s JOIN pg_database d ON d.oid = s.dbid
             WHERE d.datname = 'overhead' AND query NOT ILIKE '%pg_stat_statements%'",
            &[],
        )
        .unwrap();
    let (all, tx): (Option<i64>, Option<i64>) = (r.get(0), r.get(1));
    println!(
        "FIGURE statements per job on postgres: {:.1} (of which BEGIN/COMMIT {:.1}), migrations included",
        all.unwrap_or(0) as f64 / 400.0,
        tx.unwrap_or(0) as f64 / 400.0
    );
}

fn claims_per_second(server: &PgServer, hosts: usize) {
    let farm = Farm::new(server, &format!("rate{hosts}"));
    let n = 60;
    for i in 0..n {
        std::fs::write(
            farm.inbox().join(format!("c{i}.ply")),
            bunny_variant(&format!("c{i}")),
        )
        .unwrap();
    }
    let daemons: Vec<KillOnDrop> = (0..hosts).map(|h| farm.start(h, 30.0, 2, &[])).collect();
    let mut pg = server.client(&format!("rate{hosts}"));
    assert!(wait_for(600, || {
        let done: i64 = pg
            .query_one("SELECT count(*) FROM job WHERE state='done'", &[])
            .unwrap()
            .get(0);
        done == n
    }));
    let r = pg
        .query_one(
            "SELECT min(started_at), max(finished_at), count(*) FROM attempt WHERE outcome='ok'",
            &[],
        )
        .unwrap();
    let (first, last, count): (i64, i64, i64) = (r.get(0), r.get(1), r.get(2));
    println!(
        "FIGURE rate {hosts} daemon(s) x 2 workers: {count} jobs in {:.2} s = {:.1} jobs/s",
        (last - first) as f64 / 1e3,
        count as f64 * 1e3 / (last - first) as f64
    );
    drop(daemons);
}

/// GET `url` on the dashboard: (status, body).
fn web_get(url: &str) -> (u16, String) {
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .build()
        .into();
    let mut r = agent
        .get(url)
        .call()
        .unwrap_or_else(|e| panic!("{url}: {e}"));
    let body = r.body_mut().read_to_string().unwrap();
    (r.status().as_u16(), body)
}

/// The job ids listed on a page of the job list.
fn listed_ids(page: &str) -> Vec<i64> {
    page.split("<td class=\"n\"><a href=\"/jobs/")
        .skip(1)
        .map(|s| s[..s.find('"').unwrap()].parse().unwrap())
        .collect()
}

#[test]
fn the_dashboard_and_metrics_of_one_host_show_the_whole_shared_queue() {
    let server = PgServer::start();
    let farm = Farm::new(&server, "web");
    let _host0 = farm.start_with(
        0,
        5.0,
        1,
        &[],
        "[web]\nenabled = true\nlisten = \"127.0.0.1:0\"\n",
    );
    let _host1 = farm.start(1, 5.0, 1, &[]);
    for tag in ["alpha", "beta", "gamma", "delta"] {
        std::fs::write(farm.inbox().join(format!("{tag}.ply")), bunny_variant(tag)).unwrap();
    }
    assert!(
        wait_for(120, || farm.count_done() == 4),
        "not all done:\n{}",
        farm.logs()
    );
    let jobs = farm.jobs();
    let mut all: Vec<i64> = jobs.iter().map(|j| j["id"].as_i64().unwrap()).collect();
    all.sort_unstable_by(|a, b| b.cmp(a));
    // One job's report is not JSON (an edited row): it costs that job's figure only.
    let broken = all[0];
    server
        .client("web")
        .execute(
            "UPDATE job SET report_json = 'not json' WHERE id = $1",
            &[&broken],
        )
        .unwrap();

    let logs = std::fs::read_to_string(farm.dir.path().join("log-0.txt")).unwrap();
    let at = logs
        .find("web dashboard on http://")
        .unwrap_or_else(|| panic!("no dashboard address logged:\n{logs}"));
    let base = logs[at + "web dashboard on ".len()..]
        .split_whitespace()
        .next()
        .unwrap()
        .trim_end_matches('/')
        .to_string();

    let (status, page) = web_get(&format!("{base}/"));
    assert_eq!(status, 200, "{page}");
    assert_eq!(listed_ids(&page), all, "every host's jobs, newest first");
    for tag in ["alpha", "beta", "gamma", "delta"] {
        assert!(page.contains(&format!("{tag}.ply")), "{tag} listed");
    }
    let (_, page) = web_get(&format!("{base}/?q=GAMMA"));
    assert_eq!(listed_ids(&page).len(), 1, "name search ignores case");
    let (_, page) = web_get(&format!("{base}/?state=failed"));
    assert!(listed_ids(&page).is_empty());
    let (_, first) = web_get(&format!("{base}/?n=3"));
    assert_eq!(listed_ids(&first), all[..3]);
    let (_, second) = web_get(&format!("{base}/?n=3&before={}", all[2]));
    assert_eq!(listed_ids(&second), all[3..]);

    let (status, page) = web_get(&format!("{base}/jobs/{}", all[1]));
    assert_eq!(status, 200, "{page}");
    assert!(page.contains("done"), "{page}");
    assert_eq!(web_get(&format!("{base}/jobs/999999")).0, 404);
    assert_eq!(web_get(&format!("{base}/jobs/{broken}")).0, 200);
    assert_eq!(web_get(&format!("{base}/trends")).0, 200);
    assert_eq!(web_get(&format!("{base}/health")).0, 200);

    let (status, metrics) = web_get(&format!("{base}/metrics"));
    assert_eq!(status, 200, "{metrics}");
    let done: i64 = metrics
        .lines()
        .filter(|l| l.starts_with("scanmill_jobs{state=\"done\""))
        .map(|l| l.rsplit(' ').next().unwrap().parse::<i64>().unwrap())
        .sum();
    assert_eq!(done, 4, "{metrics}");
    assert!(
        metrics.contains("scanmill_job_processing_seconds_count"),
        "{metrics}"
    );
    assert!(metrics.contains("scanmill_queue_depth 0"), "{metrics}");
}
