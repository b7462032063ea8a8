//! The tracker's work on file contents: reading an OBJ's `mtllib` names, an MTL's map
//! names and a `.gltf`'s buffer and image URIs, and hashing a quiet set. None of it runs on the service loop: [`Content::spawn`]
//! gives it one blocking thread, and each result comes back as a [`Done`] message (tests
//! use [`Content::inline`], which does the work at once).
//!
//! Every read is bounded, and every file is opened without blocking and checked, on the
//! open descriptor, to be the regular file (device and inode) that `stat` saw, so a member
//! swapped for a FIFO, a device or another file between the look and the read is refused
//! rather than read or waited on.

use super::StatSig;
use crate::mesh::gltf::refs::{RefRole, external_refs};
use crate::store::InputRole;
use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Read};
use std::os::unix::fs::{MetadataExt, OpenOptionsExt};
use std::path::{Path, PathBuf};

/// How much of an OBJ (after decompression) is searched for `mtllib` lines. An OBJ names
/// its material libraries before the first `usemtl` that uses them, and exporters write
/// them in the header; a prefix this size holds any real header with a wide margin, while
/// a file that decompresses to gigabytes costs at most this much reading. An `mtllib`
/// after the prefix is not a set member (the loader still sees it when the job runs).
pub const MTLLIB_SCAN_BYTES: u64 = 8 << 20;

/// The largest MTL that is read to find its textures. Material libraries are text of a few
/// lines per material (kilobytes); a bigger file is refused unread, with this limit named.
pub const MTL_MAX_BYTES: u64 = 4 << 20;

/// The largest `.gltf` JSON (after decompression) that is read for its references. A glTF
/// whose buffers sit beside it is kilobytes of JSON; one with its buffers and images inline
/// as `data:` URIs is about 4/3 of the binary data, which for a 400,000-triangle scan with
/// its photo stays far below this. Streaming keeps memory at the largest single string.
pub const GLTF_JSON_MAX_BYTES: u64 = 512 << 20;

/// A file another file names, and what it is to the set.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reference {
    pub role: InputRole,
    /// As written in the referring file (`\` already read as `/` where the format says so).
    pub name: String,
}

impl Reference {
    fn all(role: InputRole, names: Vec<String>) -> Vec<Reference> {
        names
            .into_iter()
            .map(|name| Reference { role, name })
            .collect()
    }
}

/// Which references a file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RefKind {
    /// `mtllib` names of an OBJ (`.gz` read through the decoder).
    Obj,
    /// Map file names of an MTL.
    Mtl,
    /// External buffers and images of a `.gltf` (`.gz` read through the decoder).
    Gltf,
}

/// One piece of content work.
#[derive(Debug, Clone)]
pub enum Work {
    /// Read the references of `path` (the file `sig` describes), for the set of `primary`.
    Refs {
        primary: PathBuf,
        path: PathBuf,
        sig: StatSig,
        kind: RefKind,
    },
    /// Hash every member of the set of `primary`: (file to open, its signature).
    Hash {
        primary: PathBuf,
        files: Vec<(PathBuf, StatSig)>,
    },
}

/// Why content work did not produce a result.
#[derive(Debug, Clone, PartialEq)]
pub enum ContentError {
    /// The file is not (any more) the one that was looked at: look again later.
    Changed,
    /// It cannot be read; the text names the file (escaped) and the cause.
    Unreadable(String),
}

/// The result of one [`Work`].
#[derive(Debug, Clone)]
pub enum Done {
    Refs {
        primary: PathBuf,
        path: PathBuf,
        sig: StatSig,
        names: Result<Vec<Reference>, ContentError>,
    },
    Hash {
        primary: PathBuf,
        files: Vec<(PathBuf, StatSig)>,
        sha256: Result<Vec<String>, ContentError>,
    },
}

impl Work {
    pub fn primary(&self) -> &Path {
        match self {
            Work::Refs { primary, .. } | Work::Hash { primary, .. } => primary,
        }
    }

    /// Does the work (on whatever thread calls it).
    pub fn run(self) -> Done {
        match self {
            Work::Refs {
                primary,
                path,
                sig,
                kind,
            } => {
                let names = match kind {
                    RefKind::Obj => {
                        obj_mtllibs(&path, sig).map(|n| Reference::all(InputRole::Mtl, n))
                    }
                    RefKind::Mtl => {
                        mtl_maps(&path, sig).map(|n| Reference::all(InputRole::Texture, n))
                    }
                    RefKind::Gltf => gltf_refs(&path, sig),
                };
                Done::Refs {
                    primary,
                    path,
                    sig,
                    names,
                }
            }
            Work::Hash { primary, files } => {
                let sha256 = files.iter().map(|(p, s)| hash_file(p, *s)).collect();
                Done::Hash {
                    primary,
                    files,
                    sha256,
                }
            }
        }
    }
}

/// Where content work runs.
pub enum Content {
    /// At once, on the caller's thread; results wait in the queue (unit tests).
    Inline(VecDeque<Done>),
    /// On a dedicated thread; results go to the callback given to [`Content::spawn`].
    Thread(std::sync::mpsc::Sender<Work>),
}

impl Content {
    pub fn inline() -> Content {
        Content::Inline(VecDeque::new())
    }

    /// Starts the content thread. It ends when the [`Content`] is dropped (after the work
    /// in hand). A panic in one piece of work is reported as that file being unreadable.
    pub fn spawn(notify: impl Fn(Done) + Send + 'static) -> std::io::Result<Content> {
        let (tx, rx) = std::sync::mpsc::channel::<Work>();
        std::thread::Builder::new()
            .name("scanmill-content".into())
            .spawn(move || {
                while let Ok(work) = rx.recv() {
                    let fallback = work.clone();
                    let done =
                        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work.run()))
                            .unwrap_or_else(|_| failed(fallback, "internal error while reading"));
                    notify(done);
                }
            })?;
        Ok(Content::Thread(tx))
    }

    /// Hands work over. Returns false if the content thread is gone (it never should be).
    pub fn submit(&mut self, work: Work) -> bool {
        match self {
            Content::Inline(queue) => {
                queue.push_back(work.run());
                true
            }
            Content::Thread(tx) => tx.send(work).is_ok(),
        }
    }

    /// Results of inline work not yet applied.
    pub fn take_inline(&mut self) -> Option<Done> {
        match self {
            Content::Inline(queue) => queue.pop_front(),
            Content::Thread(_) => None,
        }
    }
}

fn failed(work: Work, why: &str) -> Done {
    let e = ContentError::Unreadable(why.to_string());
    match work {
        Work::Refs {
            primary, path, sig, ..
        } => Done::Refs {
            primary,
            path,
            sig,
            names: Err(e),
        },
        Work::Hash { primary, files } => Done::Hash {
            primary,
            files,
            sha256: Err(e),
        },
    }
}

fn unreadable(path: &Path, e: impl std::fmt::Display) -> ContentError {
    ContentError::Unreadable(format!(
        "cannot read {}: {}",
        crate::text::escape_path(path),
        crate::text::bounded(&e.to_string(), crate::text::MAX_SHOWN)
    ))
}

/// Opens `path` for reading only if it is still the regular file `sig` describes: never
/// blocks on a FIFO, never follows a final symbolic link, checks the open descriptor.
pub fn open_checked(path: &Path, sig: StatSig) -> Result<std::fs::File, ContentError> {
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK | libc::O_NOFOLLOW | libc::O_NOCTTY)
        .open(path)
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => ContentError::Changed,
            _ if e.raw_os_error() == Some(libc::ELOOP) => ContentError::Changed,
            _ => unreadable(path, e),
        })?;
    let m = file.metadata().map_err(|e| unreadable(path, e))?;
    if !m.is_file() || m.ino() != sig.ino || m.dev() != sig.dev {
        return Err(ContentError::Changed);
    }
    Ok(file)
}

/// The rest of a line after a keyword, or `None` if the line is another statement.
pub(super) fn statement<'a>(line: &'a str, keyword: &str) -> Option<&'a str> {
    let line = line.trim_start();
    let rest = line.strip_prefix(keyword)?;
    if rest.is_empty() || rest.starts_with(char::is_whitespace) {
        Some(rest.split('#').next().unwrap_or("").trim())
    } else {
        None
    }
}

/// The file's text, through the gzip decoder for a `.gz`, at most `bound` bytes of it.
fn text_of(
    path: &Path,
    sig: StatSig,
    bound: u64,
) -> Result<std::io::Take<Box<dyn Read>>, ContentError> {
    let file = open_checked(path, sig)?;
    let gz = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"));
    let reader: Box<dyn Read> = if gz {
        Box::new(flate2::read::MultiGzDecoder::new(file))
    } else {
        Box::new(file)
    };
    Ok(reader.take(bound))
}

/// `mtllib` names of an OBJ, in order, from its first [`MTLLIB_SCAN_BYTES`] (a `.gz`
/// through the decoder, the bound applying to the decompressed text).
pub fn obj_mtllibs(path: &Path, sig: StatSig) -> Result<Vec<String>, ContentError> {
    let mut reader = BufReader::with_capacity(1 << 16, text_of(path, sig, MTLLIB_SCAN_BYTES)?);
    let mut names = Vec::new();
    let mut buf = Vec::new();
    loop {
        buf.clear();
        // `take` bounds the line buffer too: one line cannot exceed the prefix.
        if reader
            .read_until(b'\n', &mut buf)
            .map_err(|e| unreadable(path, e))?
            == 0
        {
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

/// The external buffers and images a `.gltf` names, buffers first (a `.gz` through the
/// decoder). A document above [`GLTF_JSON_MAX_BYTES`] or not glTF JSON is unreadable, with
/// the reason; the loader would refuse the same file.
pub fn gltf_refs(path: &Path, sig: StatSig) -> Result<Vec<Reference>, ContentError> {
    let mut text = BufReader::with_capacity(1 << 16, text_of(path, sig, GLTF_JSON_MAX_BYTES + 1)?);
    let refs = external_refs(&mut text);
    if text.get_ref().limit() == 0 {
        return Err(ContentError::Unreadable(format!(
            "too large: {} holds more than {GLTF_JSON_MAX_BYTES} bytes of glTF JSON; not read (a .glb, or buffers and images beside the .gltf, are read)",
            crate::text::escape_path(path)
        )));
    }
    let refs = refs.map_err(|why| {
        ContentError::Unreadable(format!("{}: {why}", crate::text::escape_path(path)))
    })?;
    Ok(refs
        .into_iter()
        .map(|r| Reference {
            role: match r.role {
                RefRole::Buffer => InputRole::Buffer,
                RefRole::Image => InputRole::Texture,
            },
            name: r.name,
        })
        .collect())
}

/// File names an MTL refers to, in order. The caller refuses an MTL above
/// [`MTL_MAX_BYTES`] before asking; the read is bounded by it again here.
pub fn mtl_maps(path: &Path, sig: StatSig) -> Result<Vec<String>, ContentError> {
    if sig.size > MTL_MAX_BYTES {
        return Err(ContentError::Unreadable(too_large_mtl(path, sig.size)));
    }
    let mut bytes = Vec::with_capacity(sig.size as usize);
    open_checked(path, sig)?
        .take(MTL_MAX_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| unreadable(path, e))?;
    if bytes.len() as u64 != sig.size {
        return Err(ContentError::Changed);
    }
    Ok(super::parse_mtl_maps(&String::from_utf8_lossy(&bytes)))
}

/// The reason an MTL is not read.
pub fn too_large_mtl(path: &Path, size: u64) -> String {
    format!(
        "too large: {} is {size} bytes, above the {MTL_MAX_BYTES}-byte limit for a material library; not read",
        crate::text::escape_path(path)
    )
}

/// SHA-256 (hex) of the file's bytes as stored (a `.gz` is hashed compressed), reading at
/// most its recorded size; a file that grew, shrank or was replaced meanwhile is `Changed`.
pub fn hash_file(path: &Path, sig: StatSig) -> Result<String, ContentError> {
    use sha2::{Digest, Sha256};
    let mut file = open_checked(path, sig)?.take(sig.size + 1);
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut total = 0u64;
    loop {
        let n = file.read(&mut buf).map_err(|e| unreadable(path, e))?;
        if n == 0 {
            break;
        }
        total += n as u64;
        hasher.update(&buf[..n]);
    }
    if total != sig.size {
        return Err(ContentError::Changed);
    }
    Ok(hex::encode(hasher.finalize()))
}
