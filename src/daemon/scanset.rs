//! Scan sets and their readiness.
//!
//! A scan is a set of files: an OBJ with the MTLs its `mtllib` lines name and the images
//! those MTLs' map statements name, or one PLY. The set is ready when every member exists
//! and no member's (size, mtime, inode) has changed for the quiet period, or at once when
//! the optional marker file exists (and every member does). A set with a member missing
//! waits; it is never processed without its textures (docs/service.md, "Readiness").
//!
//! File events never make a set ready: the [`Tracker`] decides from `stat` alone, so a
//! lost, duplicated or reordered event can delay a scan but never corrupt or repeat it.
//!
//! Confinement: a member is only ever a regular file inside the watched folder. Every
//! candidate and every reference is resolved with its symbolic links and must lie in the
//! canonical root; with `follow_symlinks = false` (the default) a path that goes through
//! any link at all is refused, and FIFOs, devices and sockets are refused from `stat`,
//! never opened. A refused reference holds its set back with the reason recorded.
//!
//! The service loop only ever `stat`s. Reading references and hashing run as [`Work`] on
//! the content thread ([`content`]), bounded, and come back as [`Done`] messages.

pub mod content;

pub use content::{
    Content, ContentError, Done, GLTF_JSON_MAX_BYTES, MTL_MAX_BYTES, MTLLIB_SCAN_BYTES, RefKind,
    Reference, Work,
};

use super::glob::{Filter, PrimaryKind, primary_kind};
use crate::store::{InputMember, InputRole, RelPath};
use crate::text::{escape_path, escape_str};
use sha2::{Digest, Sha256};
use std::collections::{BTreeMap, BTreeSet, HashMap};
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
        Ok(StatSig::from_meta(&m))
    }

    fn from_meta(m: &std::fs::Metadata) -> StatSig {
        StatSig {
            size: m.size(),
            mtime_ns: m.mtime() * 1_000_000_000 + m.mtime_nsec(),
            ino: m.ino(),
            dev: m.dev(),
        }
    }
}

/// Where a watched folder's members may be: its path as configured, the same resolved
/// (symbolic links and all), and whether links inside it are followed.
#[derive(Debug, Clone)]
pub struct Confine {
    pub root: PathBuf,
    pub canonical: PathBuf,
    pub follow_symlinks: bool,
}

/// What a look (`stat`, no opening) at a would-be member found.
#[derive(Debug, Clone, PartialEq)]
pub enum Look {
    /// A regular file inside the root: its signature, the resolved path (what is opened),
    /// and its path relative to the root.
    Regular {
        sig: StatSig,
        real: PathBuf,
        rel: RelPath,
    },
    /// Not there (yet), or a dangling link.
    Missing,
    /// Never a member: the rule it breaks.
    Refused(String),
    /// `stat` failed otherwise (permissions, I/O): the error.
    Unreadable(String),
}

impl Confine {
    /// Looks at `path` (lexically clean, e.g. from the walk or [`resolve`]).
    pub fn look(&self, path: &Path) -> Look {
        let Some(rel) = RelPath::under(&self.root, path) else {
            return Look::Refused("outside the watched folder".into());
        };
        let real = match std::fs::canonicalize(path) {
            Ok(p) => p,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Look::Missing,
            Err(e) => return Look::Unreadable(e.to_string()),
        };
        if !real.starts_with(&self.canonical) {
            return Look::Refused("a symbolic link that leads outside the watched folder".into());
        }
        if !self.follow_symlinks && real != self.canonical.join(rel.as_path()) {
            return Look::Refused(
                "goes through a symbolic link, not followed (follow_symlinks = false)".into(),
            );
        }
        let meta = match std::fs::symlink_metadata(&real) {
            Ok(m) => m,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Look::Missing,
            Err(e) => return Look::Unreadable(e.to_string()),
        };
        if !meta.is_file() {
            return Look::Refused(
                "not a regular file (a FIFO, device, socket or folder); never opened".into(),
            );
        }
        Look::Regular {
            sig: StatSig::from_meta(&meta),
            real,
            rel,
        }
    }
}

/// One member of a set.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Member {
    /// Under the root as named (what is shown and recorded).
    pub path: PathBuf,
    /// Resolved (what the content thread opens).
    pub real: PathBuf,
    pub rel: RelPath,
    pub role: InputRole,
    pub sig: StatSig,
}

/// The members a primary file names, and the references that are not members.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SetSpec {
    /// Primary first, then MTLs, then textures, in reference order, without repeats.
    pub members: Vec<Member>,
    /// References to files that do not exist (yet): "james.obj.mtl (named by james.obj)".
    pub missing: Vec<String>,
    /// References that can never be members (outside the root, a link not followed, not
    /// a regular file, too large), each with its reason.
    pub refused: Vec<String>,
}

impl SetSpec {
    /// The signatures that decide whether the set changed: members', then `None` for each
    /// reference that is not a member.
    fn sigs(&self) -> Vec<Option<StatSig>> {
        self.members
            .iter()
            .map(|m| Some(m.sig))
            .chain(self.missing.iter().chain(&self.refused).map(|_| None))
            .collect()
    }
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

/// File names an MTL's text refers to, in order (`\` read as `/`).
pub fn parse_mtl_maps(text: &str) -> Vec<String> {
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
    out
}

/// Resolves a reference against the referring file's folder, lexically (`.` and `..`
/// folded); whether the result is allowed is [`Confine::look`]'s decision.
pub fn resolve(dir: &Path, name: &str) -> PathBuf {
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

/// Parsed references per file version (keyed by the resolved path), so that a walk
/// re-reads nothing that did not change. Unreadable files are remembered too, so that
/// they are not read again until they change.
#[derive(Default)]
pub struct RefCache {
    entries: HashMap<PathBuf, (StatSig, Result<Vec<Reference>, String>)>,
}

impl RefCache {
    fn get(&self, path: &Path, sig: StatSig) -> Option<&Result<Vec<Reference>, String>> {
        self.entries
            .get(path)
            .filter(|(cached, _)| *cached == sig)
            .map(|(_, r)| r)
    }

    fn insert(&mut self, path: PathBuf, sig: StatSig, names: Result<Vec<Reference>, String>) {
        self.entries.insert(path, (sig, names));
    }

    fn forget(&mut self, path: &Path) {
        self.entries.remove(path);
    }
}

/// Why [`set_spec`] has no answer yet.
#[derive(Debug)]
pub enum SpecError {
    /// This file's references must be read first (off the loop).
    Read(Work),
    /// The set cannot be made: the reason.
    Failed(String),
}

/// The members of the set whose primary is `primary` (found regular by `look`), from the
/// references already in `cache`; asks for the first read that is missing.
pub fn set_spec(
    primary: &Path,
    look: (StatSig, PathBuf, RelPath),
    confine: &Confine,
    cache: &RefCache,
) -> Result<SetSpec, SpecError> {
    let (primary_sig, primary_real, primary_rel) = look;
    let name = primary_rel.file_name_display();
    let mut spec = SetSpec {
        members: vec![Member {
            path: primary.to_path_buf(),
            real: primary_real.clone(),
            rel: primary_rel,
            role: InputRole::Mesh,
            sig: primary_sig,
        }],
        ..SetSpec::default()
    };
    let Some(kind) = references_of(primary) else {
        return Ok(spec);
    };
    let refs = match cache.get(&primary_real, primary_sig) {
        None => return Err(read_refs(primary, &primary_real, primary_sig, kind)),
        Some(Err(reason)) => return Err(SpecError::Failed(reason.clone())),
        Some(Ok(refs)) => refs.clone(),
    };
    let dir = primary.parent().unwrap_or(Path::new("."));
    let mut seen: BTreeSet<PathBuf> = BTreeSet::new();
    match kind {
        RefKind::Obj => obj_members(
            &mut spec, primary, dir, &name, refs, confine, cache, &mut seen,
        )?,
        _ => {
            for r in refs {
                spec.add(dir, &r, &escape_str(&name), confine, &mut seen);
            }
        }
    }
    Ok(spec)
}

/// Which references a primary file holds that make other files members of its set: an
/// OBJ's material libraries and a `.gltf`'s buffers and images. PLY, STL and GLB scans
/// are one file.
fn references_of(primary: &Path) -> Option<RefKind> {
    let kind = primary_kind(&primary.file_name()?.to_string_lossy())?;
    match kind {
        PrimaryKind::Obj => Some(RefKind::Obj),
        PrimaryKind::Gltf => Some(RefKind::Gltf),
        PrimaryKind::Ply | PrimaryKind::SelfContained => None,
    }
}

fn read_refs(primary: &Path, path: &Path, sig: StatSig, kind: RefKind) -> SpecError {
    SpecError::Read(Work::Refs {
        primary: primary.to_path_buf(),
        path: path.to_path_buf(),
        sig,
        kind,
    })
}

/// An OBJ's members: each MTL its `mtllib` arguments name, then the images each MTL names.
#[allow(clippy::too_many_arguments)]
fn obj_members(
    spec: &mut SetSpec,
    primary: &Path,
    dir: &Path,
    name: &str,
    mtllibs: Vec<Reference>,
    confine: &Confine,
    cache: &RefCache,
    seen: &mut BTreeSet<PathBuf>,
) -> Result<(), SpecError> {
    for argument in mtllibs.into_iter().map(|r| r.name) {
        // The whole argument if that file exists (names with spaces), else its words.
        let whole = resolve(dir, &argument);
        let names: Vec<String> = if matches!(confine.look(&whole), Look::Regular { .. }) {
            vec![argument.clone()]
        } else {
            argument.split_whitespace().map(str::to_string).collect()
        };
        for mtl_name in names {
            let mtl = resolve(dir, &mtl_name);
            if !seen.insert(mtl.clone()) {
                continue;
            }
            let named = format!("{} (named by {name})", escape_str(&mtl_name));
            let (sig, real, rel) = match confine.look(&mtl) {
                Look::Regular { sig, real, rel } => (sig, real, rel),
                other => {
                    spec.note(named, other);
                    continue;
                }
            };
            if sig.size > MTL_MAX_BYTES {
                spec.refused.push(content::too_large_mtl(&mtl, sig.size));
                continue;
            }
            let maps = match cache.get(&real, sig) {
                None => return Err(read_refs(primary, &real, sig, RefKind::Mtl)),
                Some(Err(reason)) => {
                    spec.refused.push(reason.clone());
                    continue;
                }
                Some(Ok(maps)) => maps.clone(),
            };
            spec.members.push(Member {
                path: mtl.clone(),
                real,
                rel,
                role: InputRole::Mtl,
                sig,
            });
            let mtl_dir = mtl.parent().unwrap_or(dir).to_path_buf();
            for texture in maps {
                spec.add(&mtl_dir, &texture, &escape_str(&mtl_name), confine, seen);
            }
        }
    }
    Ok(())
}

impl SetSpec {
    /// Adds the file `r` names (relative to `dir`, the referring file's folder, named
    /// `by`) as a member, or notes why it is not one; a file already seen is skipped.
    fn add(
        &mut self,
        dir: &Path,
        r: &Reference,
        by: &str,
        confine: &Confine,
        seen: &mut BTreeSet<PathBuf>,
    ) {
        let path = resolve(dir, &r.name);
        if !seen.insert(path.clone()) {
            return;
        }
        match confine.look(&path) {
            Look::Regular { sig, real, rel } => self.members.push(Member {
                path,
                real,
                rel,
                role: r.role,
                sig,
            }),
            other => self.note(format!("{} (named by {by})", escape_str(&r.name)), other),
        }
    }

    /// Files a reference that is not a member under missing or refused.
    fn note(&mut self, named: String, look: Look) {
        match look {
            Look::Regular { .. } => {}
            Look::Missing => self.missing.push(named),
            Look::Refused(why) => self.refused.push(format!("{named}: {why}")),
            Look::Unreadable(e) => self.refused.push(format!("{named}: cannot read: {e}")),
        }
    }
}

/// A set that is ready: hashed, re-checked, with its identity.
#[derive(Debug, Clone)]
pub struct ReadySet {
    pub root_index: usize,
    pub primary: PathBuf,
    pub rel_path: RelPath,
    pub set_hash: String,
    pub inputs: Vec<InputMember>,
    pub sigs: Vec<StatSig>,
}

/// Something the service should record or log about a set.
#[derive(Debug, Clone)]
pub enum Event {
    Ready(ReadySet),
    /// Waiting too long for a member, refused, too large or unreadable: recorded in the
    /// `waiting` table with the reason.
    Waiting {
        root_index: usize,
        rel_path: RelPath,
        reason: String,
        first_seen_ms: i64,
    },
    /// No longer waiting (gone, or became a job).
    NotWaiting {
        root_index: usize,
        rel_path: RelPath,
    },
}

/// A watched folder as the tracker sees it.
#[derive(Debug, Clone)]
pub struct RootSpec {
    pub path: PathBuf,
    pub filter: Filter,
    pub quiet: Duration,
    pub marker: Option<String>,
    /// Follow symbolic links inside the folder (their targets must still be inside it).
    pub follow_symlinks: bool,
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
    rel: RelPath,
    first_seen: Instant,
    first_seen_ms: i64,
    last_change: Instant,
    /// Signatures at the last look, primary first, `None` for references not members.
    sigs: Vec<Option<StatSig>>,
    /// The signatures that were handed over (enqueued or already known): nothing to do
    /// until they change.
    handled: Option<Vec<Option<StatSig>>>,
    /// The reason reported as waiting, if any (reported again only when it changes, and
    /// withdrawn when resolved).
    reported: Option<String>,
    /// Unreadable, refused or too large: do not look again before this.
    retry_at: Option<Instant>,
    /// The mesh file changed since the previous look (its references are not read yet).
    changing: bool,
    /// Content work for this set is on the content thread: wait for its result.
    busy: bool,
    /// The members being hashed.
    hashing: Option<Vec<Member>>,
}

/// Known input sets from the database, keyed by (root, primary rel_path): the signatures
/// recorded with their jobs. A set on disk that matches needs no hashing at start-up.
pub type Known = HashMap<(String, RelPath), Vec<crate::store::MemberSig>>;

/// Decides which sets are ready. Owned by the service loop, which it never blocks: its
/// own file-system work is `stat`; reading and hashing go to [`Content`].
pub struct Tracker {
    roots: Vec<RootSpec>,
    /// Each root resolved (refreshed at every walk); `None` while it is unavailable.
    canonical: Vec<Option<PathBuf>>,
    sets: BTreeMap<PathBuf, Tracked>,
    refs: RefCache,
    known: Known,
    content: Content,
    /// Report a set with missing members after this long.
    incomplete_after: Duration,
    /// Re-check an unreadable set this often.
    unreadable_retry: Duration,
    /// A set larger than this (all members) is not hashed.
    max_input_bytes: u64,
}

/// The settings of a [`Tracker`] besides its roots.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    pub incomplete_after: Duration,
    pub unreadable_retry: Duration,
    pub max_input_bytes: u64,
}

impl Tracker {
    pub fn new(roots: Vec<RootSpec>, known: Known, limits: Limits, content: Content) -> Tracker {
        let canonical = roots
            .iter()
            .map(|r| std::fs::canonicalize(&r.path).ok())
            .collect();
        Tracker {
            roots,
            canonical,
            sets: BTreeMap::new(),
            refs: RefCache::default(),
            known,
            content,
            incomplete_after: limits.incomplete_after,
            unreadable_retry: limits.unreadable_retry,
            max_input_bytes: limits.max_input_bytes,
        }
    }

    pub fn roots(&self) -> &[RootSpec] {
        &self.roots
    }

    /// Remembers a set's signatures as recorded in the database (after an enqueue).
    pub fn remember(
        &mut self,
        root: &str,
        rel_path: &RelPath,
        members: Vec<crate::store::MemberSig>,
    ) {
        self.known
            .insert((root.to_string(), rel_path.clone()), members);
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

    /// Number of sets whose content work (reading, hashing) is under way.
    pub fn busy(&self) -> usize {
        self.sets.values().filter(|t| t.busy).count()
    }

    fn confine(&self, root_index: usize) -> Option<Confine> {
        Some(Confine {
            root: self.roots[root_index].path.clone(),
            canonical: self.canonical[root_index].clone()?,
            follow_symlinks: self.roots[root_index].follow_symlinks,
        })
    }

    /// Lists every candidate primary file under a root (recursively; hidden and temporary
    /// names skipped, symlinked folders never entered). Links and special files with a
    /// mesh name are candidates: looking at them refuses them with a reason.
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
                } else if primary_kind(&name).is_some() {
                    // Patterns match the name as text (bytes that are not UTF-8 as U+FFFD).
                    let rel = path.strip_prefix(&root.path).unwrap_or(&path);
                    if root.filter.accepts(&rel.to_string_lossy()) {
                        out.push(path);
                    }
                }
            }
        }
        out.sort();
        out
    }

    /// A full reconcile of one root: walk it, forget sets that are gone, look at every set.
    pub fn reconcile_root(&mut self, root_index: usize, now: Instant, now_ms: i64) -> Vec<Event> {
        self.canonical[root_index] = std::fs::canonicalize(&self.roots[root_index].path).ok();
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
                if t.reported.is_some() {
                    events.push(Event::NotWaiting {
                        root_index,
                        rel_path: t.rel,
                    });
                }
            }
        }
        let root = self.roots[root_index].path.clone();
        for primary in found {
            let Some(rel) = RelPath::under(&root, &primary) else {
                continue;
            };
            self.sets.entry(primary.clone()).or_insert_with(|| Tracked {
                root_index,
                rel,
                first_seen: now,
                first_seen_ms: now_ms,
                last_change: now,
                sigs: Vec::new(),
                handled: None,
                reported: None,
                retry_at: None,
                changing: false,
                busy: false,
                hashing: None,
            });
            events.extend(self.evaluate(&primary, now));
        }
        self.drain_inline(now, &mut events);
        events
    }

    /// Looks again at the sets not yet handed over (between walks), e.g. when a quiet
    /// period ends.
    pub fn recheck_pending(&mut self, now: Instant, now_ms: i64) -> Vec<Event> {
        let _ = now_ms;
        let pending: Vec<PathBuf> = self
            .sets
            .iter()
            .filter(|(_, t)| t.handled.as_ref() != Some(&t.sigs) && !t.busy)
            .map(|(p, _)| p.clone())
            .collect();
        let mut events = Vec::new();
        for p in pending {
            events.extend(self.evaluate(&p, now));
        }
        self.drain_inline(now, &mut events);
        events
    }

    /// Takes a result of the content thread.
    pub fn content_done(&mut self, done: Done, now: Instant) -> Vec<Event> {
        let mut events = self.apply(done, now);
        self.drain_inline(now, &mut events);
        events
    }

    fn drain_inline(&mut self, now: Instant, events: &mut Vec<Event>) {
        while let Some(done) = self.content.take_inline() {
            events.extend(self.apply(done, now));
        }
    }

    fn apply(&mut self, done: Done, now: Instant) -> Vec<Event> {
        match done {
            Done::Refs {
                primary,
                path,
                sig,
                names,
            } => {
                let changed = names == Err(ContentError::Changed);
                match names {
                    Ok(n) => self.refs.insert(path, sig, Ok(n)),
                    Err(ContentError::Unreadable(why)) => self.refs.insert(path, sig, Err(why)),
                    Err(ContentError::Changed) => {}
                }
                let Some(t) = self.sets.get_mut(&primary) else {
                    return Vec::new();
                };
                t.busy = false;
                if changed {
                    // Look again once it holds still.
                    t.last_change = now;
                    return Vec::new();
                }
                self.evaluate(&primary, now)
            }
            Done::Hash {
                primary, sha256, ..
            } => self.hashed(&primary, sha256, now),
        }
    }

    /// When the next pending set could become ready (or should be looked at again).
    pub fn next_deadline(&self, now: Instant) -> Option<Instant> {
        self.sets
            .values()
            .filter(|t| t.handled.as_ref() != Some(&t.sigs) && !t.busy)
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
                    if t.reported.is_some() {
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

    fn evaluate(&mut self, primary: &Path, now: Instant) -> Vec<Event> {
        let Some(t) = self.sets.get(primary) else {
            return Vec::new();
        };
        if t.busy || t.retry_at.is_some_and(|at| now < at) {
            return Vec::new();
        }
        let Some(confine) = self.confine(t.root_index) else {
            return Vec::new();
        };
        let shown = escape_path(primary);
        let look = match confine.look(primary) {
            Look::Regular { sig, real, rel } => (sig, real, rel),
            Look::Missing => {
                // Gone (or a dangling link): the next walk forgets it.
                return self.stuck(primary, format!("cannot read {shown}: no such file"), now);
            }
            Look::Refused(why) => {
                return self.stuck(primary, format!("refused: {shown}: {why}"), now);
            }
            Look::Unreadable(e) => {
                return self.stuck(primary, format!("cannot read {shown}: {e}"), now);
            }
        };
        match self.spec_of(primary, look, &confine) {
            Ok((spec, changing)) => self.settle(primary, spec, changing, now),
            Err(SpecError::Read(work)) => self.submit(primary, work, now),
            Err(SpecError::Failed(reason)) => self.stuck(primary, reason, now),
        }
    }

    /// The set a primary names, and whether the primary (an OBJ or `.gltf`) is still
    /// changing. Its references are parsed only once it has held still for one look, so that a file
    /// being written is not re-read on every event.
    fn spec_of(
        &self,
        primary: &Path,
        look: (StatSig, PathBuf, RelPath),
        confine: &Confine,
    ) -> Result<(SetSpec, bool), SpecError> {
        let t = &self.sets[primary];
        let previous_primary = t.sigs.first().copied().flatten();
        let changing = references_of(primary).is_some()
            && !(previous_primary == Some(look.0) || t.sigs.is_empty());
        if !changing {
            return set_spec(primary, look, confine, &self.refs).map(|spec| (spec, false));
        }
        let (sig, real, rel) = look;
        let spec = SetSpec {
            members: vec![Member {
                path: primary.to_path_buf(),
                real,
                rel,
                role: InputRole::Mesh,
                sig,
            }],
            missing: vec!["(mesh file still changing)".into()],
            refused: Vec::new(),
        };
        Ok((spec, true))
    }

    /// What becomes of a set after a look: nothing yet (unchanged, incomplete, not quiet),
    /// reported as waiting or stuck, recognised as already recorded, or handed over to be
    /// hashed.
    fn settle(
        &mut self,
        primary: &Path,
        spec: SetSpec,
        changing: bool,
        now: Instant,
    ) -> Vec<Event> {
        let incomplete_after = self.incomplete_after;
        let t = self.sets.get_mut(primary).expect("tracked");
        let root = &self.roots[t.root_index];
        let marker_ready = root.marker_path(primary).is_some_and(|m| m.is_file());
        let quiet = root.quiet;
        let sigs = spec.sigs();
        t.retry_at = None;
        t.changing = changing;
        if sigs != t.sigs {
            t.sigs = sigs.clone();
            t.last_change = now;
        }
        if t.handled.as_ref() == Some(&sigs) {
            return Vec::new();
        }
        if !spec.refused.is_empty() {
            let reason = format!("refused: {}", spec.refused.join("; "));
            return self.stuck(primary, reason, now);
        }
        if !spec.missing.is_empty() {
            if now.duration_since(t.first_seen) >= incomplete_after {
                let reason = format!("incomplete: missing {}", spec.missing.join(", "));
                return self.report(primary, reason);
            }
            return Vec::new();
        }
        if !marker_ready && now.duration_since(t.last_change) < quiet {
            return Vec::new();
        }
        // Already recorded with these exact files (e.g. after a restart): no need to hash.
        if self.is_known(primary, &spec) {
            let t = self.sets.get_mut(primary).expect("tracked");
            t.handled = Some(sigs);
            if t.reported.take().is_some() {
                return vec![Event::NotWaiting {
                    root_index: t.root_index,
                    rel_path: t.rel.clone(),
                }];
            }
            return Vec::new();
        }
        self.hash(primary, spec, now)
    }

    /// Whether the set is recorded in the store with exactly these files.
    fn is_known(&self, primary: &Path, spec: &SetSpec) -> bool {
        let t = &self.sets[primary];
        let root_key = self.roots[t.root_index].path.to_string_lossy().into_owned();
        self.known
            .get(&(root_key, t.rel.clone()))
            .is_some_and(|known| {
                known.len() == spec.members.len()
                    && spec.members.iter().zip(known).all(|(m, k)| {
                        m.rel == k.0
                            && m.sig.size == k.1
                            && m.sig.mtime_ns == k.2
                            && m.sig.ino == k.3
                    })
            })
    }

    /// Hands a complete, quiet set over to be hashed, unless it is above the size limit.
    fn hash(&mut self, primary: &Path, spec: SetSpec, now: Instant) -> Vec<Event> {
        let total: u64 = spec.members.iter().map(|m| m.sig.size).sum();
        if total > self.max_input_bytes {
            let reason = format!(
                "too large: the set is {total} bytes, above max_input_bytes = {}; not hashed",
                self.max_input_bytes
            );
            return self.stuck(primary, reason, now);
        }
        let files = spec
            .members
            .iter()
            .map(|m| (m.real.clone(), m.sig))
            .collect();
        let t = self.sets.get_mut(primary).expect("tracked");
        t.hashing = Some(spec.members);
        self.submit(
            primary,
            Work::Hash {
                primary: primary.to_path_buf(),
                files,
            },
            now,
        )
    }

    /// Hands content work to the content thread; the set waits for the result.
    fn submit(&mut self, primary: &Path, work: Work, now: Instant) -> Vec<Event> {
        if !self.content.submit(work) {
            let reason = "internal error: the content thread is gone".to_string();
            return self.stuck(primary, reason, now);
        }
        if let Some(t) = self.sets.get_mut(primary) {
            t.busy = true;
        }
        Vec::new()
    }

    /// A set's hashes are in: check nothing moved meanwhile, then it is ready.
    fn hashed(
        &mut self,
        primary: &Path,
        sha256: Result<Vec<String>, ContentError>,
        now: Instant,
    ) -> Vec<Event> {
        let Some(t) = self.sets.get_mut(primary) else {
            return Vec::new();
        };
        t.busy = false;
        let Some(members) = t.hashing.take() else {
            return Vec::new();
        };
        let hashes = match sha256 {
            Ok(h) => h,
            Err(ContentError::Changed) => {
                t.last_change = now;
                return Vec::new();
            }
            Err(ContentError::Unreadable(why)) => return self.stuck(primary, why, now),
        };
        let root_index = t.root_index;
        let Some(confine) = self.confine(root_index) else {
            return Vec::new();
        };
        let unmoved = members
            .iter()
            .all(|m| matches!(confine.look(&m.path), Look::Regular { sig, .. } if sig == m.sig));
        let t = self.sets.get_mut(primary).expect("tracked");
        if !unmoved {
            t.last_change = now;
            return Vec::new();
        }
        let inputs: Vec<InputMember> = members
            .iter()
            .zip(hashes)
            .map(|(m, sha256)| InputMember {
                rel_path: m.rel.clone(),
                role: m.role,
                size: m.sig.size,
                mtime_ns: m.sig.mtime_ns,
                ino: m.sig.ino,
                sha256,
            })
            .collect();
        let sigs: Vec<StatSig> = members.iter().map(|m| m.sig).collect();
        if t.sigs != sigs.iter().copied().map(Some).collect::<Vec<_>>() {
            // The set was looked at again meanwhile and differs: wait anew.
            return Vec::new();
        }
        t.handled = Some(t.sigs.clone());
        t.reported = None;
        vec![Event::Ready(ReadySet {
            root_index,
            primary: primary.to_path_buf(),
            rel_path: t.rel.clone(),
            set_hash: set_hash(&inputs),
            inputs,
            sigs,
        })]
    }

    /// Reports a set that cannot go on (unreadable, refused, too large) and leaves it
    /// alone until `unreadable_retry` has passed.
    fn stuck(&mut self, primary: &Path, reason: String, now: Instant) -> Vec<Event> {
        let retry = self.unreadable_retry;
        if let Some(t) = self.sets.get_mut(primary) {
            t.retry_at = Some(now + retry);
        }
        self.report(primary, reason)
    }

    /// Records a set as waiting with `reason` (once per distinct reason).
    fn report(&mut self, primary: &Path, reason: String) -> Vec<Event> {
        let Some(t) = self.sets.get_mut(primary) else {
            return Vec::new();
        };
        if t.reported.as_ref() == Some(&reason) {
            return Vec::new();
        }
        t.reported = Some(reason.clone());
        tracing::warn!(scan = %escape_path(primary), "{reason}");
        vec![Event::Waiting {
            root_index: t.root_index,
            rel_path: t.rel.clone(),
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
        h.update(m.role.as_str().as_bytes());
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
