//! Scan sets and their readiness.
//!
//! A scan is a set of files: an OBJ with the MTLs its `mtllib` lines name and the images
//! those MTLs' map statements name, or one PLY. The set is ready when every member exists
//! and no member's (size, mtime, inode) has changed for the quiet period, or at once when
//! the optional marker file exists (and every member does). A set with a member missing
//! waits; it is never processed without its textures (spec/service.md §1.3, §2.2).
//!
//! File events never make a set ready: the [`Tracker`] decides from `stat` alone, so a
//! lost, duplicated or reordered event can delay a scan but never corrupt or repeat it.

use super::glob::{Filter, PrimaryKind, primary_kind};
use crate::report::FileHash;
use crate::store::InputMember;
use sha2::{Digest, Sha256};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::io::{BufRead, BufReader, Read};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// What identifies a file version without reading it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct StatSig {
    pub size: u64,
    pub mtime_ns: i64,
    pub ino: u64,
    pub dev: u64,
}

impl StatSig {
    /// Stats `path` (following symlinks); only regular files have a signature.
    pub fn of(path: &Path) -> std::io::Result<StatSig> {
        let m = std::fs::metadata(path)?;
        if !m.is_file() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "not a regular file",
            ));
        }
        Ok(StatSig {
            size: m.size(),
            mtime_ns: m.mtime() * 1_000_000_000 + m.mtime_nsec(),
            ino: m.ino(),
            dev: m.dev(),
        })
    }
}

/// One member of a set.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Member {
    pub path: PathBuf,
    pub role: &'static str,
}

/// The members a primary file names, and the references that could not be found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SetSpec {
    /// Primary first, then MTLs, then textures, in reference order, without repeats.
    pub members: Vec<Member>,
    /// References to files that do not exist (yet): "james.obj.mtl (named by james.obj)".
    pub missing: Vec<String>,
}

/// The rest of a line after a keyword, or `None` if the line is another statement.
fn statement<'a>(line: &'a str, keyword: &str) -> Option<&'a str> {
    let line = line.trim_start();
    let rest = line.strip_prefix(keyword)?;
    if rest.is_empty() || rest.starts_with(char::is_whitespace) {
        Some(rest.split('#').next().unwrap_or("").trim())
    } else {
        None
    }
}

/// `mtllib` names of an OBJ, in order. Reads the whole file as text lines (a `.gz` through
/// the decoder); cheap next to processing, and cached by the caller per file version.
pub fn obj_mtllibs(path: &Path) -> std::io::Result<Vec<String>> {
    let file = std::fs::File::open(path)?;
    let reader: Box<dyn Read> = if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"))
    {
        Box::new(flate2::read::MultiGzDecoder::new(file))
    } else {
        Box::new(file)
    };
    let mut names = Vec::new();
    let mut reader = BufReader::with_capacity(1 << 16, reader);
    let mut buf = Vec::new();
    loop {
        buf.clear();
        if reader.read_until(b'\n', &mut buf)? == 0 {
            break;
        }
        // Only lines that start with "mtllib" matter; skip the rest without decoding.
        let trimmed = buf.trim_ascii_start();
        if !trimmed.starts_with(b"mtllib") {
            continue;
        }
        let line = String::from_utf8_lossy(trimmed);
        if let Some(arg) = statement(line.trim_end(), "mtllib")
            && !arg.is_empty()
        {
            names.push(arg.to_string());
        }
    }
    Ok(names)
}

/// Whether an MTL keyword names a file (`map_Kd`, `map_Bump`, `bump`, `disp`, `decal`,
/// `refl`, `norm`, any `map_*`).
fn is_map_keyword(k: &str) -> bool {
    let k = k.to_ascii_lowercase();
    k.starts_with("map_") || matches!(k.as_str(), "bump" | "disp" | "decal" | "refl" | "norm")
}

/// The file name of a map statement's arguments, after its options (`-s 1 1 1`,
/// `-clamp on`, …). Spaces inside the name are kept.
pub fn map_file_name(args: &str) -> &str {
    let mut rest = args.trim();
    loop {
        let Some(option) = rest.strip_prefix('-') else {
            return rest;
        };
        let (name, after) = option
            .split_once(char::is_whitespace)
            .unwrap_or((option, ""));
        let count = match name {
            "blendu" | "blendv" | "bm" | "boost" | "cc" | "clamp" | "imfchan" | "texres"
            | "type" => 1,
            "mm" => 2,
            "o" | "s" | "t" => 3,
            _ => return rest,
        };
        let mut after = after.trim_start();
        for _ in 0..count {
            // `-o/-s/-t` take up to three numbers; stop at the first non-number.
            let (token, tail) = after.split_once(char::is_whitespace).unwrap_or((after, ""));
            if token.is_empty()
                || (matches!(name, "o" | "s" | "t") && token.parse::<f64>().is_err())
            {
                break;
            }
            if tail.trim().is_empty() && matches!(name, "o" | "s" | "t") {
                // The last token is the file name, never an option value.
                break;
            }
            after = tail.trim_start();
        }
        rest = after;
    }
}

/// File names an MTL refers to, in order.
pub fn mtl_maps(path: &Path) -> std::io::Result<Vec<String>> {
    let bytes = std::fs::read(path)?;
    let text = String::from_utf8_lossy(&bytes);
    let mut out = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        let Some((keyword, args)) = line.split_once(char::is_whitespace) else {
            continue;
        };
        if is_map_keyword(keyword) {
            let name = map_file_name(args.split('#').next().unwrap_or(""));
            if !name.is_empty() {
                out.push(name.replace('\\', "/"));
            }
        }
    }
    Ok(out)
}

/// Resolves a reference against the referring file's folder. A name that does not exist
/// as written is also tried with whitespace splitting for `mtllib` (several names on one
/// line), which the caller handles.
fn resolve(dir: &Path, name: &str) -> PathBuf {
    let joined = dir.join(name.replace('\\', "/"));
    let mut out = PathBuf::new();
    for c in joined.components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir if out.file_name().is_some() => {
                out.pop();
            }
            other => out.push(other.as_os_str()),
        }
    }
    out
}

/// Caches parsed references per file version, so that a walk re-reads nothing that did not
/// change.
#[derive(Default)]
pub struct RefCache {
    entries: HashMap<PathBuf, (StatSig, Vec<String>)>,
}

impl RefCache {
    fn get(
        &mut self,
        path: &Path,
        sig: StatSig,
        parse: fn(&Path) -> std::io::Result<Vec<String>>,
    ) -> std::io::Result<Vec<String>> {
        if let Some((cached, names)) = self.entries.get(path)
            && *cached == sig
        {
            return Ok(names.clone());
        }
        let names = parse(path)?;
        self.entries
            .insert(path.to_path_buf(), (sig, names.clone()));
        Ok(names)
    }

    fn forget(&mut self, path: &Path) {
        self.entries.remove(path);
    }
}

/// The members of the set whose primary is `primary` (with its current signature).
pub fn set_spec(
    primary: &Path,
    primary_sig: StatSig,
    cache: &mut RefCache,
) -> std::io::Result<SetSpec> {
    let mut spec = SetSpec {
        members: vec![Member {
            path: primary.to_path_buf(),
            role: "mesh",
        }],
        missing: Vec::new(),
    };
    let name = primary
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    if primary_kind(&name) != Some(PrimaryKind::Obj) {
        return Ok(spec);
    }
    let dir = primary.parent().unwrap_or(Path::new("."));
    let mut seen: BTreeSet<PathBuf> = BTreeSet::new();
    for argument in cache.get(primary, primary_sig, obj_mtllibs)? {
        // The whole argument if that file exists (names with spaces), else its words.
        let whole = resolve(dir, &argument);
        let names: Vec<String> = if whole.is_file() {
            vec![argument.clone()]
        } else {
            argument.split_whitespace().map(str::to_string).collect()
        };
        for mtl_name in names {
            let mtl = resolve(dir, &mtl_name);
            if !seen.insert(mtl.clone()) {
                continue;
            }
            let mtl_sig = match StatSig::of(&mtl) {
                Ok(s) => s,
                Err(_) => {
                    spec.missing.push(format!("{mtl_name} (named by {name})"));
                    continue;
                }
            };
            spec.members.push(Member {
                path: mtl.clone(),
                role: "mtl",
            });
            let mtl_dir = mtl.parent().unwrap_or(dir).to_path_buf();
            for texture in cache.get(&mtl, mtl_sig, mtl_maps)? {
                let path = resolve(&mtl_dir, &texture);
                if seen.insert(path.clone()) {
                    if path.is_file() {
                        spec.members.push(Member {
                            path,
                            role: "texture",
                        });
                    } else {
                        spec.missing
                            .push(format!("{texture} (named by {mtl_name})"));
                    }
                }
            }
        }
    }
    Ok(spec)
}

/// A set that is ready: hashed, re-checked, with its identity.
#[derive(Debug, Clone)]
pub struct ReadySet {
    pub root_index: usize,
    pub primary: PathBuf,
    pub rel_path: String,
    pub set_hash: String,
    pub inputs: Vec<InputMember>,
    pub sigs: Vec<StatSig>,
}

/// Something the service should record or log about a set.
#[derive(Debug, Clone)]
pub enum Event {
    Ready(ReadySet),
    /// Waiting too long for a member, or unreadable: recorded in the `waiting` table.
    Waiting {
        root_index: usize,
        rel_path: String,
        reason: String,
        first_seen_ms: i64,
    },
    /// No longer waiting (gone, or became a job).
    NotWaiting {
        root_index: usize,
        rel_path: String,
    },
}

/// A watched folder as the tracker sees it.
#[derive(Debug, Clone)]
pub struct RootSpec {
    pub path: PathBuf,
    pub filter: Filter,
    pub quiet: Duration,
    pub marker: Option<String>,
}

impl RootSpec {
    fn marker_path(&self, primary: &Path) -> Option<PathBuf> {
        let template = self.marker.as_ref()?;
        let name = primary.file_name()?.to_string_lossy().into_owned();
        let no_gz = name.strip_suffix(".gz").unwrap_or(&name);
        let stem = no_gz.rsplit_once('.').map(|(s, _)| s).unwrap_or(no_gz);
        Some(primary.with_file_name(template.replace("{stem}", stem).replace("{name}", &name)))
    }
}

#[derive(Debug)]
struct Tracked {
    root_index: usize,
    first_seen: Instant,
    first_seen_ms: i64,
    last_change: Instant,
    /// Signatures at the last look, primary first, `None` for missing members.
    sigs: Vec<Option<StatSig>>,
    /// The signatures that were handed over (enqueued or already known): nothing to do
    /// until they change.
    handled: Option<Vec<Option<StatSig>>>,
    /// Reported as waiting (so the report is made once, and withdrawn when resolved).
    reported: bool,
    /// Unreadable: do not retry before this.
    retry_at: Option<Instant>,
    /// The mesh file changed since the previous look (its references are not read yet).
    changing: bool,
}

/// Known input sets from the database, keyed by (root, primary rel_path): the signatures
/// recorded with their jobs. A set on disk that matches needs no hashing at start-up.
pub type Known = HashMap<(String, String), Vec<crate::store::MemberSig>>;

/// Decides which sets are ready. Owned by the service loop; all file-system work is
/// synchronous and cheap (stat), except hashing a set once it is quiet.
pub struct Tracker {
    roots: Vec<RootSpec>,
    sets: BTreeMap<PathBuf, Tracked>,
    refs: RefCache,
    known: Known,
    /// Report a set with missing members after this long.
    incomplete_after: Duration,
    /// Re-check an unreadable set this often.
    unreadable_retry: Duration,
}

/// Relative `/`-separated path of `path` under `root`, or the absolute path if outside.
pub fn rel_to(root: &Path, path: &Path) -> String {
    match path.strip_prefix(root) {
        Ok(rel) => rel.to_string_lossy().into_owned(),
        Err(_) => path.to_string_lossy().into_owned(),
    }
}

impl Tracker {
    pub fn new(
        roots: Vec<RootSpec>,
        known: Known,
        incomplete_after: Duration,
        unreadable_retry: Duration,
    ) -> Tracker {
        Tracker {
            roots,
            sets: BTreeMap::new(),
            refs: RefCache::default(),
            known,
            incomplete_after,
            unreadable_retry,
        }
    }

    pub fn roots(&self) -> &[RootSpec] {
        &self.roots
    }

    /// Remembers a set's signatures as recorded in the database (after an enqueue).
    pub fn remember(&mut self, root: &str, rel_path: &str, members: Vec<crate::store::MemberSig>) {
        self.known
            .insert((root.to_string(), rel_path.to_string()), members);
    }

    /// A ready set that could not be handed over (the database was busy): it becomes
    /// pending again, so that a later look hands it over anew.
    pub fn hand_back(&mut self, primary: &Path) {
        if let Some(t) = self.sets.get_mut(primary) {
            t.handled = None;
        }
    }

    /// Number of sets not yet handed over (waiting for quiet or for members).
    pub fn pending(&self) -> usize {
        self.sets
            .values()
            .filter(|t| t.handled.as_ref() != Some(&t.sigs))
            .count()
    }

    /// Lists every candidate primary file under a root (recursively; hidden and temporary
    /// names skipped, symlinked folders not followed).
    pub fn walk(&self, root_index: usize) -> Vec<PathBuf> {
        let root = &self.roots[root_index];
        let mut out = Vec::new();
        let mut stack = vec![root.path.clone()];
        while let Some(dir) = stack.pop() {
            let Ok(entries) = std::fs::read_dir(&dir) else {
                continue;
            };
            for entry in entries.flatten() {
                let path = entry.path();
                let name = entry.file_name().to_string_lossy().into_owned();
                let Ok(ft) = entry.file_type() else { continue };
                if ft.is_dir() {
                    if !super::glob::is_ignored_name(&name) {
                        stack.push(path);
                    }
                } else if primary_kind(&name).is_some()
                    && root.filter.accepts(&rel_to(&root.path, &path))
                {
                    out.push(path);
                }
            }
        }
        out.sort();
        out
    }

    /// A full reconcile of one root: walk it, forget sets that are gone, look at every set.
    pub fn reconcile_root(&mut self, root_index: usize, now: Instant, now_ms: i64) -> Vec<Event> {
        let found: BTreeSet<PathBuf> = self.walk(root_index).into_iter().collect();
        let mut events = Vec::new();
        let gone: Vec<PathBuf> = self
            .sets
            .iter()
            .filter(|(p, t)| t.root_index == root_index && !found.contains(*p))
            .map(|(p, _)| p.clone())
            .collect();
        for p in gone {
            if let Some(t) = self.sets.remove(&p) {
                self.refs.forget(&p);
                if t.reported {
                    events.push(Event::NotWaiting {
                        root_index,
                        rel_path: rel_to(&self.roots[root_index].path, &p),
                    });
                }
            }
        }
        for primary in found {
            self.sets.entry(primary.clone()).or_insert_with(|| Tracked {
                root_index,
                first_seen: now,
                first_seen_ms: now_ms,
                last_change: now,
                sigs: Vec::new(),
                handled: None,
                reported: false,
                retry_at: None,
                changing: false,
            });
            events.extend(self.evaluate(&primary, now, now_ms));
        }
        events
    }

    /// Looks again at the sets not yet handed over (between walks), e.g. when a quiet
    /// period ends.
    pub fn recheck_pending(&mut self, now: Instant, now_ms: i64) -> Vec<Event> {
        let pending: Vec<PathBuf> = self
            .sets
            .iter()
            .filter(|(_, t)| t.handled.as_ref() != Some(&t.sigs))
            .map(|(p, _)| p.clone())
            .collect();
        let mut events = Vec::new();
        for p in pending {
            events.extend(self.evaluate(&p, now, now_ms));
        }
        events
    }

    /// When the next pending set could become ready (or should be looked at again).
    pub fn next_deadline(&self, now: Instant) -> Option<Instant> {
        self.sets
            .values()
            .filter(|t| t.handled.as_ref() != Some(&t.sigs))
            .map(|t| {
                if let Some(at) = t.retry_at {
                    return at;
                }
                if t.changing {
                    // Look again shortly: once it holds still its references are read.
                    return t.last_change + Duration::from_millis(200);
                }
                let quiet = self.roots[t.root_index].quiet;
                let missing = t.sigs.iter().any(Option::is_none) || t.sigs.is_empty();
                if missing {
                    // Missing members arrive with an event; look again now and then anyway,
                    // and when it is time to report the set.
                    let report_at = t.first_seen + self.incomplete_after;
                    let soon = now + Duration::from_secs(2);
                    if t.reported {
                        soon
                    } else {
                        soon.min(report_at.max(now))
                    }
                } else {
                    t.last_change + quiet
                }
            })
            .min()
    }

    fn evaluate(&mut self, primary: &Path, now: Instant, now_ms: i64) -> Vec<Event> {
        let Some(t) = self.sets.get(primary) else {
            return Vec::new();
        };
        let root_index = t.root_index;
        let root = self.roots[root_index].clone();
        let rel_path = rel_to(&root.path, primary);
        if let Some(at) = t.retry_at
            && now < at
        {
            return Vec::new();
        }
        let primary_sig = match StatSig::of(primary) {
            Ok(s) => s,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                // Gone (or a dangling link): the next walk forgets it.
                return self.unreadable(primary, &rel_path, format!("cannot read: {e}"), now);
            }
            Err(e) => return self.unreadable(primary, &rel_path, format!("cannot read: {e}"), now),
        };
        // Parse references only once the primary has held still for one look, so that a
        // file being written is not re-read on every event.
        let previous_primary = t.sigs.first().copied().flatten();
        let is_obj = primary
            .file_name()
            .is_some_and(|n| primary_kind(&n.to_string_lossy()) == Some(PrimaryKind::Obj));
        let changing = is_obj && !(previous_primary == Some(primary_sig) || t.sigs.is_empty());
        let spec = if !changing {
            match set_spec(primary, primary_sig, &mut self.refs) {
                Ok(s) => s,
                Err(e) => {
                    return self.unreadable(primary, &rel_path, format!("cannot read: {e}"), now);
                }
            }
        } else {
            SetSpec {
                members: vec![Member {
                    path: primary.to_path_buf(),
                    role: "mesh",
                }],
                missing: vec!["(mesh file still changing)".into()],
            }
        };
        let mut sigs: Vec<Option<StatSig>> = spec
            .members
            .iter()
            .map(|m| StatSig::of(&m.path).ok())
            .collect();
        // Missing references count as members that do not exist yet.
        sigs.extend(spec.missing.iter().map(|_| None));
        let t = self.sets.get_mut(primary).expect("tracked");
        t.retry_at = None;
        t.changing = changing;
        if sigs != t.sigs {
            t.sigs = sigs.clone();
            t.last_change = now;
        }
        if t.handled.as_ref() == Some(&sigs) {
            return Vec::new();
        }
        let mut events = Vec::new();
        let missing: Vec<String> = spec
            .missing
            .iter()
            .cloned()
            .chain(
                spec.members
                    .iter()
                    .zip(&sigs)
                    .filter(|(_, s)| s.is_none())
                    .map(|(m, _)| format!("{} (vanished)", m.path.display())),
            )
            .collect();
        if !missing.is_empty() {
            if now.duration_since(t.first_seen) >= self.incomplete_after && !t.reported {
                t.reported = true;
                let reason = format!("incomplete: missing {}", missing.join(", "));
                tracing::warn!(scan = %primary.display(), "{reason}");
                events.push(Event::Waiting {
                    root_index,
                    rel_path,
                    reason,
                    first_seen_ms: t.first_seen_ms,
                });
            }
            return events;
        }
        let marker_ready = root.marker_path(primary).is_some_and(|m| m.is_file());
        if !marker_ready && now.duration_since(t.last_change) < root.quiet {
            return events;
        }
        let sigs: Vec<StatSig> = sigs.into_iter().map(|s| s.expect("all present")).collect();
        // Already recorded with these exact files (e.g. after a restart): no need to hash.
        let root_key = root.path.to_string_lossy().into_owned();
        if let Some(known) = self.known.get(&(root_key, rel_path.clone())) {
            let same = known.len() == sigs.len()
                && spec
                    .members
                    .iter()
                    .zip(&sigs)
                    .zip(known)
                    .all(|((m, s), k)| {
                        rel_to(&root.path, &m.path) == k.0
                            && s.size == k.1
                            && s.mtime_ns == k.2
                            && s.ino == k.3
                    });
            if same {
                let t = self.sets.get_mut(primary).expect("tracked");
                t.handled = Some(sigs.into_iter().map(Some).collect());
                if t.reported {
                    t.reported = false;
                    events.push(Event::NotWaiting {
                        root_index,
                        rel_path,
                    });
                }
                return events;
            }
        }
        // Hash every member, then look again: if anything moved meanwhile, wait anew.
        let mut inputs = Vec::with_capacity(spec.members.len());
        for (m, s) in spec.members.iter().zip(&sigs) {
            match FileHash::of(&m.path) {
                Ok(h) => inputs.push(InputMember {
                    rel_path: rel_to(&root.path, &m.path),
                    role: m.role,
                    size: s.size,
                    mtime_ns: s.mtime_ns,
                    ino: s.ino,
                    sha256: h.sha256,
                }),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                    let t = self.sets.get_mut(primary).expect("tracked");
                    t.last_change = now;
                    return events;
                }
                Err(e) => {
                    return self.unreadable(
                        primary,
                        &rel_path,
                        format!("cannot read {}: {e}", m.path.display()),
                        now,
                    );
                }
            }
        }
        let after: Vec<Option<StatSig>> = spec
            .members
            .iter()
            .map(|m| StatSig::of(&m.path).ok())
            .collect();
        let t = self.sets.get_mut(primary).expect("tracked");
        if after.iter().zip(&sigs).any(|(a, b)| *a != Some(*b)) {
            t.sigs = after;
            t.last_change = Instant::now();
            return events;
        }
        t.handled = Some(sigs.iter().copied().map(Some).collect());
        if t.reported {
            t.reported = false;
        }
        events.push(Event::Ready(ReadySet {
            root_index,
            primary: primary.to_path_buf(),
            rel_path,
            set_hash: set_hash(&inputs),
            inputs,
            sigs,
        }));
        let _ = now_ms;
        events
    }

    fn unreadable(
        &mut self,
        primary: &Path,
        rel_path: &str,
        reason: String,
        now: Instant,
    ) -> Vec<Event> {
        let retry = self.unreadable_retry;
        let Some(t) = self.sets.get_mut(primary) else {
            return Vec::new();
        };
        t.retry_at = Some(now + retry);
        if t.reported {
            return Vec::new();
        }
        t.reported = true;
        tracing::warn!(scan = %primary.display(), "{reason}");
        vec![Event::Waiting {
            root_index: t.root_index,
            rel_path: rel_path.to_string(),
            reason,
            first_seen_ms: t.first_seen_ms,
        }]
    }

    /// Forgets everything about a root (it vanished or was remounted).
    pub fn forget_root(&mut self, root_index: usize) {
        self.sets.retain(|_, t| t.root_index != root_index);
    }
}

/// The content identity of a set: SHA-256 over the members' roles and content hashes in
/// set order. Names are left out on purpose: a renamed or copied scan is the same scan
/// (its MTL and texture names are inside the OBJ and MTL contents anyway).
pub fn set_hash(inputs: &[InputMember]) -> String {
    let mut h = Sha256::new();
    for m in inputs {
        h.update(m.role.as_bytes());
        h.update(b":");
        h.update(m.sha256.as_bytes());
        h.update(b"\n");
    }
    hex::encode(h.finalize())
}

/// The job key: the set's content plus the resolved recipe.
pub fn job_key(set_hash: &str, recipe_hash: &str) -> String {
    hex::encode(Sha256::digest(
        format!("{set_hash}\n{recipe_hash}").as_bytes(),
    ))
}

#[cfg(test)]
mod tests;
