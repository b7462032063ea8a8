use super::query::HistoryFilter;
use super::*;

fn owner() -> Owner {
    Owner {
        id: "test".into(),
        host: "h".into(),
        app_version: "0".into(),
    }
}

fn job(key: &str, rel: &str) -> NewJob {
    NewJob {
        order: JobOrder {
            job_key: key.into(),
            set_hash: format!("set-{key}"),
            root: "/in".into(),
            rel_path: rel.into(),
            output_root: "/out".into(),
            recipe_path: "r.toml".into(),
            recipe_hash: "rh".into(),
        },
        recipe_json: "{}".into(),
        config_hash: "ch".into(),
        max_attempts: 2,
        inputs: vec![InputMember {
            rel_path: rel.into(),
            role: InputRole::Mesh,
            size: 10,
            mtime_ns: 5,
            ino: 7,
            sha256: "ab".into(),
        }],
    }
}

fn open() -> (tempfile::TempDir, Store) {
    let dir = tempfile::tempdir().unwrap();
    let store = Store::open(&dir.path().join("db.sqlite")).unwrap();
    (dir, store)
}

/// A fresh store with one job (`a.ply`), claimed.
fn open_with_one_claimed() -> (tempfile::TempDir, Store, ClaimedJob) {
    let (dir, mut store) = open();
    store.enqueue(&job("k1", "a.ply")).unwrap();
    let claimed = store.claim(&owner()).unwrap().unwrap();
    (dir, store, claimed)
}

fn failed(transient: bool) -> Finish {
    Finish::Failed {
        kind: FailureKind::Output,
        message: "boom".into(),
        transient,
    }
}

#[test]
fn migrations_apply_once_and_record_version() {
    let (dir, store) = open();
    drop(store);
    let mut again = Store::open(&dir.path().join("db.sqlite")).unwrap();
    assert_eq!(again.migrate().unwrap(), schema::LATEST);
    let n: i64 = again
        .connection()
        .query_row("SELECT count(*) FROM schema_migrations", [], |r| r.get(0))
        .unwrap();
    assert_eq!(n, schema::LATEST as i64);
    let mode: String = again
        .connection()
        .query_row("PRAGMA journal_mode", [], |r| r.get(0))
        .unwrap();
    assert_eq!(mode, "wal");
}

#[test]
fn a_version_1_database_gains_the_preview_column() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("db.sqlite");
    let conn = rusqlite::Connection::open(&path).unwrap();
    conn.execute_batch(schema::MIGRATIONS[0]).unwrap();
    conn.pragma_update(None, "user_version", 1).unwrap();
    drop(conn);
    let store = Store::open(&path).unwrap();
    let columns: Vec<String> = store
        .connection()
        .prepare("SELECT name FROM pragma_table_info('job')")
        .unwrap()
        .query_map([], |r| r.get(0))
        .unwrap()
        .collect::<rusqlite::Result<_>>()
        .unwrap();
    assert!(columns.iter().any(|c| c == "preview"), "{columns:?}");
}

#[test]
fn a_version_3_database_keeps_its_inputs_in_order_and_accepts_buffers() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("db.sqlite");
    let conn = rusqlite::Connection::open(&path).unwrap();
    for m in &schema::MIGRATIONS[..3] {
        conn.execute_batch(m).unwrap();
    }
    conn.pragma_update(None, "user_version", 3).unwrap();
    drop(conn);
    let mut old = Store::open_existing(&path, true).unwrap();
    let mut set = job("k1", "a.obj");
    for (rel, role) in [("a.mtl", InputRole::Mtl), ("a.jpg", InputRole::Texture)] {
        set.inputs.push(InputMember {
            rel_path: rel.into(),
            role,
            ..set.inputs[0].clone()
        });
    }
    old.enqueue(&set).unwrap();
    drop(old);

    let mut s = Store::open(&path).unwrap();
    let mut gltf = job("k2", "b.gltf");
    gltf.inputs.push(InputMember {
        rel_path: "b.bin".into(),
        role: InputRole::Buffer,
        ..gltf.inputs[0].clone()
    });
    s.enqueue(&gltf).unwrap();
    let first = s.claim(&owner()).unwrap().unwrap();
    let roles: Vec<_> = first.inputs.iter().map(|m| m.role).collect();
    assert_eq!(roles, [InputRole::Mesh, InputRole::Mtl, InputRole::Texture]);
    let second = s.claim(&owner()).unwrap().unwrap();
    let roles: Vec<_> = second.inputs.iter().map(|m| m.role).collect();
    assert_eq!(roles, [InputRole::Mesh, InputRole::Buffer]);
}

#[test]
fn newer_schema_is_refused() {
    let (dir, store) = open();
    store
        .connection()
        .pragma_update(None, "user_version", schema::LATEST + 1)
        .unwrap();
    drop(store);
    let e = Store::open(&dir.path().join("db.sqlite")).err().unwrap();
    assert!(matches!(e, StoreError::TooNew { .. }), "{e}");
}

#[test]
fn same_key_never_makes_two_jobs_and_records_sightings() {
    let (_d, mut s) = open();
    let a = s.enqueue(&job("k1", "a.ply")).unwrap();
    assert_eq!(a, Enqueued::New(1));
    let b = s.enqueue(&job("k1", "copy/b.ply")).unwrap();
    assert_eq!(
        b,
        Enqueued::Existing {
            id: 1,
            state: "queued".into()
        }
    );
    let shown = s.show(1).unwrap();
    assert_eq!(shown["sightings"].as_array().unwrap().len(), 2);
}

#[test]
fn claim_finish_done_records_everything() {
    let (_d, mut s, c) = open_with_one_claimed();
    assert_eq!(c.attempt, 1);
    assert_eq!(c.inputs.len(), 1);
    assert!(s.claim(&owner()).unwrap().is_none(), "only one job");
    let fin = Finish::Done(JobDone {
        output_dir: "/out/a".into(),
        preview: Some("/out/a/a.preview.png".into()),
        outputs: vec![OutputFile {
            path: "/out/a/a.obj".into(),
            bytes: 3,
            sha256: "cc".into(),
        }],
        report_json: "{\"metrics\":{\"x\":1}}".into(),
        counts: MeshSizes {
            in_vertices: 1,
            in_faces: 2,
            out_vertices: 3,
            out_faces: 4,
        },
        process_ms: 5.0,
        steps: vec![StepRow {
            kind: "normals".into(),
            wall_ms: 1.0,
            vertices_before: 1,
            vertices_after: 1,
            faces_before: 2,
            faces_after: 2,
            figures_json: "{}".into(),
        }],
    });
    assert_eq!(
        s.finish(&c, &fin, retry(1.0, 10.0), 6.0).unwrap(),
        FinalState::Done
    );
    let shown = s.show(c.id).unwrap();
    assert_eq!(shown["state"], "done");
    assert_eq!(shown["report"]["metrics"]["x"], 1);
    assert_eq!(shown["preview"], "/out/a/a.preview.png");
    assert_eq!(shown["attempts_log"][0]["steps"][0]["kind"], "normals");
    let h = s.history(&HistoryFilter::default()).unwrap();
    assert_eq!(h.len(), 1);
    assert_eq!(h[0].out_faces, Some(4));
}

#[test]
fn transient_failures_back_off_then_quarantine_permanent_fail_at_once() {
    let (_d, mut s, c) = open_with_one_claimed();
    assert_eq!(
        s.finish(&c, &failed(true), retry(3600.0, 3600.0), 1.0)
            .unwrap(),
        FinalState::RetryLater
    );
    assert!(s.claim(&owner()).unwrap().is_none(), "backoff holds it");
    // Let the backoff pass.
    s.connection()
        .execute("UPDATE job SET run_after = 0", [])
        .unwrap();
    let c = s.claim(&owner()).unwrap().unwrap();
    assert_eq!(c.attempt, 2);
    assert_eq!(
        s.finish(&c, &failed(true), retry(1.0, 1.0), 1.0).unwrap(),
        FinalState::Quarantined
    );

    s.enqueue(&job("k2", "b.ply")).unwrap();
    let c = s.claim(&owner()).unwrap().unwrap();
    assert_eq!(
        s.finish(&c, &failed(false), retry(1.0, 1.0), 1.0).unwrap(),
        FinalState::Failed
    );
    s.connection()
        .execute("UPDATE job SET run_after = 0", [])
        .unwrap();
    assert!(
        s.claim(&owner()).unwrap().is_none(),
        "permanent failure is not retried"
    );
}

#[test]
fn recover_running_counts_the_attempt_and_quarantines_at_the_limit() {
    let (_d, mut s, c) = open_with_one_claimed();
    assert_eq!(c.attempt, 1);
    // The daemon died while the job ran (no finish): recovery keeps the attempt counted.
    assert_eq!(s.recover_running().unwrap(), 1);
    let c = s.claim(&owner()).unwrap().unwrap();
    assert_eq!(c.attempt, 2, "the interrupted attempt was counted");
    let shown = s.show(c.id).unwrap();
    assert_eq!(shown["attempts_log"][0]["outcome"], "interrupted");
    // The second death reaches max_attempts (2 here): quarantined, not queued again.
    assert_eq!(s.recover_running().unwrap(), 0);
    assert!(s.claim(&owner()).unwrap().is_none());
    let shown = s.show(c.id).unwrap();
    assert_eq!(shown["state"], "quarantined", "{shown}");
    assert_eq!(shown["error_kind"], "daemon_stopped", "{shown}");
}

#[test]
fn a_graceful_interruption_is_not_counted() {
    let (_d, mut s, c) = open_with_one_claimed();
    let f = Finish::Interrupted {
        reason: "daemon stopped before the job finished".into(),
    };
    assert_eq!(
        s.finish(&c, &f, retry(1.0, 1.0), 0.0).unwrap(),
        FinalState::Requeued
    );
    let c = s.claim(&owner()).unwrap().unwrap();
    assert_eq!(
        c.attempt, 1,
        "a drain at shutdown does not use up an attempt"
    );
}

#[test]
fn requeue_bumps_generation_and_refuses_running() {
    let (_d, mut s, c) = open_with_one_claimed();
    assert!(matches!(
        s.requeue(c.id),
        Err(StoreError::WrongState { .. })
    ));
    s.finish(&c, &failed(false), retry(1.0, 1.0), 1.0).unwrap();
    assert_eq!(s.requeue(c.id).unwrap(), "failed");
    let c2 = s.claim(&owner()).unwrap().unwrap();
    assert_eq!(c2.generation, 1);
    assert!(matches!(s.requeue(99), Err(StoreError::NoSuchJob(99))));
}

#[test]
fn vanished_input_job_is_revived_when_input_returns() {
    let (_d, mut s, c) = open_with_one_claimed();
    let gone = Finish::Failed {
        kind: FailureKind::InputVanished,
        message: "gone".into(),
        transient: false,
    };
    s.finish(&c, &gone, retry(1.0, 1.0), 1.0).unwrap();
    assert_eq!(
        s.enqueue(&job("k1", "back.ply")).unwrap(),
        Enqueued::Revived(1)
    );
    let c = s.claim(&owner()).unwrap().unwrap();
    assert_eq!(c.order.rel_path, "back.ply");
}

#[test]
fn waiting_rows_show_in_history_and_backup_works() {
    let (d, mut s) = open();
    s.set_waiting("/in", &"x.obj".into(), "missing x.mtl", 1)
        .unwrap();
    let f = HistoryFilter {
        status: Some("waiting".into()),
        ..Default::default()
    };
    let rows = s.history(&f).unwrap();
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0].error.as_deref(), Some("missing x.mtl"));
    s.clear_waiting("/in", &"x.obj".into()).unwrap();
    assert!(s.history(&f).unwrap().is_empty());
    let dest = d.path().join("backup.sqlite");
    s.backup(&dest).unwrap();
    let reader = Store::open_existing(&dest, false).unwrap();
    assert!(
        reader
            .history(&HistoryFilter::default())
            .unwrap()
            .is_empty()
    );
}

#[test]
fn since_parsing() {
    let (_d, s) = open();
    assert_eq!(
        s.parse_since("2d", 200_000_000),
        Some(200_000_000 - 172_800_000)
    );
    assert_eq!(s.parse_since("1970-01-02", 0), Some(86_400_000));
    assert_eq!(s.parse_since("bogus", 0), None);
}

#[test]
fn history_filters_by_glob_and_state() {
    let (_d, mut s) = open();
    s.enqueue(&job("k1", "james/james.obj")).unwrap();
    s.enqueue(&job("k2", "bunny.ply")).unwrap();
    let f = HistoryFilter {
        input_glob: Some("*james*".into()),
        ..Default::default()
    };
    assert_eq!(s.history(&f).unwrap().len(), 1);
    let f = HistoryFilter {
        status: Some("done".into()),
        ..Default::default()
    };
    assert!(s.history(&f).unwrap().is_empty());
}

#[test]
fn backoff_doubles_and_caps() {
    assert_eq!(backoff_ms(1, 2.0, 100.0), 2000);
    assert_eq!(backoff_ms(3, 2.0, 100.0), 8000);
    assert_eq!(backoff_ms(20, 2.0, 100.0), 100_000);
}

#[test]
fn a_huge_failure_message_is_cut_when_recorded() {
    let (_d, mut s, c) = open_with_one_claimed();
    let f = Finish::Failed {
        kind: FailureKind::Input,
        message: "é".repeat(100_000),
        transient: false,
    };
    s.finish(&c, &f, retry(1.0, 1.0), 1.0).unwrap();
    let shown = s.show(c.id).unwrap();
    let stored: String = s
        .connection()
        .query_row("SELECT error FROM job WHERE id=?1", [c.id], |r| r.get(0))
        .unwrap();
    assert!(
        stored.len() <= MAX_ERROR_BYTES + "…".len(),
        "{}",
        stored.len()
    );
    assert!(stored.ends_with('…'));
    let logged: String = s
        .connection()
        .query_row("SELECT error FROM attempt WHERE job_id=?1", [c.id], |r| {
            r.get(0)
        })
        .unwrap();
    assert_eq!(logged, stored);
    assert_eq!(shown["state"], "failed");
}

fn retry(base_secs: f64, max_secs: f64) -> RetryPolicy {
    RetryPolicy {
        base_secs,
        max_secs,
    }
}
