use super::*;
use crate::daemon::glob::Filter;

const JAMES: &str = "../shared/data/textured/james_face_stereo_capture";

fn root(dir: &Path, quiet_ms: u64, marker: Option<&str>) -> RootSpec {
    RootSpec {
        path: dir.to_path_buf(),
        filter: Filter::default(),
        quiet: Duration::from_millis(quiet_ms),
        marker: marker.map(str::to_string),
        follow_symlinks: false,
    }
}

fn tracker(dir: &Path, quiet_ms: u64, marker: Option<&str>) -> Tracker {
    Tracker::new(
        vec![root(dir, quiet_ms, marker)],
        Known::new(),
        limits(Duration::from_secs(60)),
        Content::inline(),
    )
}

fn limits(unreadable_retry: Duration) -> Limits {
    Limits {
        incomplete_after: Duration::from_secs(5),
        unreadable_retry,
        max_input_bytes: 1 << 30,
    }
}

fn confine(dir: &Path) -> Confine {
    Confine {
        root: dir.to_path_buf(),
        canonical: std::fs::canonicalize(dir).unwrap(),
        follow_symlinks: false,
    }
}

/// The set of `primary` (under `dir`), its references read inline.
fn spec_of(dir: &Path, primary: &Path) -> Result<SetSpec, SpecError> {
    let c = confine(dir);
    let Look::Regular { sig, real, rel } = c.look(primary) else {
        panic!("{} is not a regular file", primary.display());
    };
    let mut cache = RefCache::default();
    loop {
        match set_spec(primary, (sig, real.clone(), rel.clone()), &c, &cache) {
            Err(SpecError::Read(work)) => match work.run() {
                Done::Refs {
                    path, sig, names, ..
                } => cache.insert(path, sig, names.map_err(|e| format!("{e:?}"))),
                Done::Hash { .. } => unreachable!(),
            },
            other => return other,
        }
    }
}

fn ready(events: &[Event]) -> Vec<&ReadySet> {
    events
        .iter()
        .filter_map(|e| match e {
            Event::Ready(r) => Some(r),
            _ => None,
        })
        .collect()
}

fn copy_james(to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for f in ["james.obj", "james.obj.mtl", "james.jpg"] {
        std::fs::write(to.join(f), std::fs::read(Path::new(JAMES).join(f)).unwrap()).unwrap();
    }
}

#[test]
fn map_file_name_strips_options_and_keeps_spaces() {
    assert_eq!(map_file_name("tex.png"), "tex.png");
    assert_eq!(map_file_name("-s 1 1 1 my tex.png"), "my tex.png");
    assert_eq!(map_file_name("-clamp on -bm 0.5 a.jpg"), "a.jpg");
    assert_eq!(map_file_name("-o 0.5 b.png"), "b.png");
}

#[test]
fn james_set_has_obj_mtl_and_texture() {
    let spec = spec_of(Path::new(JAMES), &Path::new(JAMES).join("james.obj")).unwrap();
    let roles: Vec<_> = spec.members.iter().map(|m| m.role.as_str()).collect();
    assert_eq!(roles, ["mesh", "mtl", "texture"]);
    assert!(spec.missing.is_empty(), "{:?}", spec.missing);
}

#[test]
fn mtllib_with_spaces_and_subfolder_textures() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("tex")).unwrap();
    std::fs::write(
        d.join("a b.mtl"),
        "newmtl m\nmap_Kd -s 1 1 1 tex/skin map.png\nbump tex\\n.png\n",
    )
    .unwrap();
    std::fs::write(d.join("tex/skin map.png"), b"x").unwrap();
    std::fs::write(d.join("s.obj"), "mtllib a b.mtl\nv 0 0 0\n").unwrap();
    let spec = spec_of(d, &d.join("s.obj")).unwrap();
    assert_eq!(spec.members.len(), 3, "{spec:?}");
    assert_eq!(spec.missing, ["tex/n.png (named by a b.mtl)"]);
}

#[test]
fn ply_ready_only_after_quiet_period_and_again_after_change() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("a.ply"), b"ply\n").unwrap();
    let mut t = tracker(d, 300, None);
    let t0 = Instant::now();
    assert!(ready(&t.reconcile_root(0, t0, 0)).is_empty());
    assert_eq!(t.pending(), 1);
    assert!(ready(&t.recheck_pending(t0 + Duration::from_millis(100), 0)).is_empty());
    let deadline = t.next_deadline(t0).unwrap();
    assert!(deadline >= t0 + Duration::from_millis(300));
    let ev = t.recheck_pending(t0 + Duration::from_millis(350), 0);
    assert_eq!(ready(&ev).len(), 1);
    assert_eq!(t.pending(), 0);
    // Nothing new on later looks.
    assert!(
        t.reconcile_root(0, t0 + Duration::from_secs(1), 0)
            .is_empty()
    );
    // Rewritten: a new set after a new quiet period.
    std::fs::write(d.join("a.ply"), b"ply\nmore\n").unwrap();
    let t1 = t0 + Duration::from_secs(2);
    assert!(ready(&t.reconcile_root(0, t1, 0)).is_empty());
    let ev = t.recheck_pending(t1 + Duration::from_millis(400), 0);
    assert_eq!(ready(&ev).len(), 1);
}

#[test]
fn obj_waits_for_missing_texture_and_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    copy_james(d);
    std::fs::remove_file(d.join("james.jpg")).unwrap();
    let mut t = tracker(d, 10, None);
    let t0 = Instant::now();
    assert!(t.reconcile_root(0, t0, 0).is_empty());
    let ev = t.recheck_pending(t0 + Duration::from_secs(6), 0);
    assert!(
        matches!(&ev[..], [Event::Waiting { reason, .. }] if reason.contains("james.jpg")),
        "{ev:?}"
    );
    // The texture arrives: ready after the quiet period, with all three members.
    std::fs::write(
        d.join("james.jpg"),
        std::fs::read(Path::new(JAMES).join("james.jpg")).unwrap(),
    )
    .unwrap();
    let t1 = t0 + Duration::from_secs(7);
    assert!(ready(&t.reconcile_root(0, t1, 0)).is_empty());
    let ev = t.recheck_pending(t1 + Duration::from_millis(20), 0);
    let r = ready(&ev);
    assert_eq!(r.len(), 1);
    assert_eq!(r[0].inputs.len(), 3);
}

#[test]
fn marker_makes_ready_without_quiet_period() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.ply"), b"ply\n").unwrap();
    let mut t = tracker(d, 3_600_000, Some("{stem}.done"));
    let t0 = Instant::now();
    assert!(ready(&t.reconcile_root(0, t0, 0)).is_empty());
    std::fs::write(d.join("s.done"), b"").unwrap();
    assert_eq!(ready(&t.reconcile_root(0, t0, 0)).len(), 1);
}

#[test]
fn renamed_copy_has_the_same_set_hash() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    copy_james(&d.join("one"));
    copy_james(&d.join("two"));
    std::fs::rename(d.join("two/james.obj"), d.join("two/renamed.obj")).unwrap();
    let mut t = tracker(d, 1, None);
    let t0 = Instant::now();
    t.reconcile_root(0, t0, 0);
    let ev = t.recheck_pending(t0 + Duration::from_millis(5), 0);
    let r = ready(&ev);
    assert_eq!(r.len(), 2);
    assert_eq!(r[0].set_hash, r[1].set_hash);
    assert_ne!(r[0].rel_path, r[1].rel_path);
}

#[test]
fn known_sets_are_not_hashed_again() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("a.ply"), b"ply\n").unwrap();
    let sig = StatSig::of(&d.join("a.ply")).unwrap();
    let mut known = Known::new();
    known.insert(
        (d.to_string_lossy().into_owned(), "a.ply".into()),
        vec![("a.ply".into(), sig.size, sig.mtime_ns, sig.ino)],
    );
    let mut t = Tracker::new(
        vec![root(d, 1, None)],
        known,
        limits(Duration::from_secs(5)),
        Content::inline(),
    );
    let t0 = Instant::now();
    t.reconcile_root(0, t0, 0);
    assert!(ready(&t.recheck_pending(t0 + Duration::from_millis(5), 0)).is_empty());
    assert_eq!(t.pending(), 0);
}

#[test]
fn ignored_and_hidden_files_are_not_candidates() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join(".staging")).unwrap();
    std::fs::create_dir(d.join("sub")).unwrap();
    for f in [
        "x.ply.part",
        ".y.ply",
        ".staging/z.ply",
        "sub/ok.ply",
        "notes.txt",
    ] {
        std::fs::write(d.join(f), b"ply\n").unwrap();
    }
    let t = tracker(d, 1, None);
    assert_eq!(t.walk(0), [d.join("sub/ok.ply")]);
}

fn waiting_reasons(events: &[Event]) -> Vec<String> {
    events
        .iter()
        .filter_map(|e| match e {
            Event::Waiting { reason, .. } => Some(reason.clone()),
            _ => None,
        })
        .collect()
}

#[test]
fn mtllib_is_looked_for_only_in_the_bounded_prefix() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let early = d.join("early.obj");
    std::fs::write(&early, "# header\nmtllib a.mtl\nv 0 0 0\n").unwrap();
    let sig = StatSig::of(&early).unwrap();
    assert_eq!(content::obj_mtllibs(&early, sig).unwrap(), ["a.mtl"]);
    // One line longer than the prefix, then an mtllib: not seen, and the line buffer is
    // bounded by the prefix too.
    let late = d.join("late.obj");
    let mut text = vec![b'#'; MTLLIB_SCAN_BYTES as usize + 10];
    text.extend_from_slice(b"\nmtllib late.mtl\n");
    std::fs::write(&late, &text).unwrap();
    let sig = StatSig::of(&late).unwrap();
    assert!(content::obj_mtllibs(&late, sig).unwrap().is_empty());
    // The same through gzip: the bound applies to the decompressed text.
    let gz = d.join("late.obj.gz");
    {
        use std::io::Write;
        let mut e = flate2::write::GzEncoder::new(
            std::fs::File::create(&gz).unwrap(),
            flate2::Compression::fast(),
        );
        e.write_all(&text).unwrap();
        e.finish().unwrap();
    }
    let sig = StatSig::of(&gz).unwrap();
    assert!(content::obj_mtllibs(&gz, sig).unwrap().is_empty());
}

#[test]
fn files_are_opened_only_as_the_regular_file_that_was_looked_at() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let f = d.join("a.ply");
    std::fs::write(&f, b"ply\n").unwrap();
    let sig = StatSig::of(&f).unwrap();
    assert_eq!(
        content::hash_file(&f, sig).unwrap(),
        hex::encode(Sha256::digest(b"ply\n"))
    );
    // Grown since the look: not hashed.
    std::fs::write(&f, b"ply\nmore\n").unwrap();
    assert_eq!(content::hash_file(&f, sig), Err(ContentError::Changed));
    // Replaced by a FIFO under the same name: refused at once, never waited on.
    std::fs::remove_file(&f).unwrap();
    let c = std::ffi::CString::new(f.as_os_str().as_encoded_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0);
    assert_eq!(content::hash_file(&f, sig), Err(ContentError::Changed));
    assert_eq!(
        confine(d).look(&f),
        Look::Refused("not a regular file (a FIFO, device, socket or folder); never opened".into())
    );
}

#[test]
fn references_outside_through_links_or_too_large_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("root");
    std::fs::create_dir(&root).unwrap();
    std::fs::write(dir.path().join("x.mtl"), "newmtl m\n").unwrap();
    std::fs::write(root.join("up.obj"), "mtllib ../x.mtl\n").unwrap();
    std::fs::write(root.join("real.mtl"), "newmtl m\n").unwrap();
    std::os::unix::fs::symlink("real.mtl", root.join("link.mtl")).unwrap();
    std::fs::write(root.join("linked.obj"), "mtllib link.mtl\n").unwrap();
    std::fs::File::create(root.join("big.mtl"))
        .unwrap()
        .set_len(MTL_MAX_BYTES + 1)
        .unwrap();
    std::fs::write(root.join("big.obj"), "mtllib big.mtl\n").unwrap();

    let up = spec_of(&root, &root.join("up.obj")).unwrap();
    assert_eq!(up.members.len(), 1);
    assert_eq!(
        up.refused,
        ["../x.mtl (named by up.obj): outside the watched folder"]
    );
    let linked = spec_of(&root, &root.join("linked.obj")).unwrap();
    assert!(
        linked.refused[0].contains("symbolic link, not followed"),
        "{linked:?}"
    );
    let big = spec_of(&root, &root.join("big.obj")).unwrap();
    assert!(
        big.refused[0].contains("too large") && big.refused[0].contains("not read"),
        "{big:?}"
    );

    // With links followed, a link inside the root is a member under its own name.
    let mut follow = confine(&root);
    follow.follow_symlinks = true;
    let Look::Regular { sig, real, rel } = follow.look(&root.join("linked.obj")) else {
        panic!()
    };
    let mut cache = RefCache::default();
    let primary = root.join("linked.obj");
    let spec = loop {
        match set_spec(&primary, (sig, real.clone(), rel.clone()), &follow, &cache) {
            Err(SpecError::Read(work)) => match work.run() {
                Done::Refs {
                    path, sig, names, ..
                } => cache.insert(path, sig, names.map_err(|e| format!("{e:?}"))),
                Done::Hash { .. } => unreachable!(),
            },
            other => break other.unwrap(),
        }
    };
    assert!(spec.refused.is_empty(), "{spec:?}");
    assert_eq!(spec.members[1].rel, "link.mtl");
    assert_eq!(
        spec.members[1].real,
        root.canonicalize().unwrap().join("real.mtl")
    );

    // Refused sets are reported at once, not after the incomplete-report delay.
    let mut t = tracker(&root, 1, None);
    let reasons = waiting_reasons(&t.reconcile_root(0, Instant::now(), 0));
    assert_eq!(reasons.len(), 3, "{reasons:?}");
    assert!(
        reasons.iter().all(|r| r.starts_with("refused: ")),
        "{reasons:?}"
    );
}

#[test]
fn a_set_above_max_input_bytes_is_not_hashed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("a.ply"), vec![b'x'; 100]).unwrap();
    let mut t = Tracker::new(
        vec![root(d, 1, None)],
        Known::new(),
        Limits {
            max_input_bytes: 99,
            ..limits(Duration::from_secs(60))
        },
        Content::inline(),
    );
    let t0 = Instant::now();
    t.reconcile_root(0, t0, 0);
    let ev = t.recheck_pending(t0 + Duration::from_millis(5), 0);
    assert!(ready(&ev).is_empty());
    let reasons = waiting_reasons(&ev);
    assert_eq!(reasons.len(), 1, "{ev:?}");
    assert!(
        reasons[0].contains("max_input_bytes = 99") && reasons[0].contains("not hashed"),
        "{reasons:?}"
    );
}

#[test]
fn content_work_on_its_thread_comes_back_as_messages() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    copy_james(d);
    let (tx, rx) = std::sync::mpsc::channel();
    let content = Content::spawn(move |done| tx.send(done).unwrap()).unwrap();
    let mut t = Tracker::new(
        vec![root(d, 1, None)],
        Known::new(),
        limits(Duration::from_secs(60)),
        content,
    );
    let t0 = Instant::now();
    let mut events = t.reconcile_root(0, t0, 0);
    let mut later = t0;
    // OBJ references, MTL references, then the hashes: each a message; the set is left
    // alone (busy) while its work is out.
    let mut messages = 0;
    for _ in 0..100 {
        if !ready(&events).is_empty() {
            break;
        }
        later += Duration::from_millis(5);
        if t.busy() == 0 {
            // Waiting for quiet: look again later.
            events = t.recheck_pending(later, 0);
            continue;
        }
        assert!(t.recheck_pending(later, 0).is_empty());
        let done = rx.recv_timeout(Duration::from_secs(60)).unwrap();
        messages += 1;
        events = t.content_done(done, later);
    }
    assert_eq!(messages, 3, "OBJ references, MTL references, hashes");
    assert_eq!(ready(&events)[0].inputs.len(), 3);
}
