//! Publishing a finished scan into the output tree, atomically.
//!
//! Layout: a scan found at `<watch>/<rel dir>/<name>.obj` is published as the folder
//! `<output>/<rel dir>/<name>/` holding the mesh (OBJ + MTL + textures, or PLY) and
//! `<name>.scanmill.json`, the provenance sidecar. The folder is built under
//! `<output>/.scanmill-staging/` (same file system), every file and the folder are fsynced,
//! then it is renamed into place in one `renameat2(RENAME_NOREPLACE)` and the parent is
//! fsynced. A reader sees the whole scan or nothing.
//!
//! Never overwritten: if `<name>/` exists and holds another job's result, the new one is
//! published as `<name>.v2/` (then `.v3`, …) and the log says so. If it holds this very
//! job's result (same job key and generation: the daemon died between publishing and
//! recording), that result is taken as published and nothing is written twice.

use serde_json::Value;
use std::ffi::CString;
use std::os::unix::ffi::OsStrExt;
use std::path::{Path, PathBuf};

/// The hidden folder in each output root where scans are assembled.
pub const STAGING_DIR: &str = ".scanmill-staging";
/// The provenance sidecar's suffix.
pub const SIDECAR_SUFFIX: &str = ".scanmill.json";

pub fn fsync_dir(dir: &Path) -> std::io::Result<()> {
    std::fs::File::open(dir)?.sync_all()
}

/// `rename(from, to)` that fails with `AlreadyExists` instead of replacing `to`
/// (a plain rename silently replaces an empty directory).
pub fn rename_no_replace(from: &Path, to: &Path) -> std::io::Result<()> {
    let c = |p: &Path| {
        CString::new(p.as_os_str().as_bytes())
            .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidInput, "NUL in path"))
    };
    let (f, t) = (c(from)?, c(to)?);
    // SAFETY: both are valid NUL-terminated paths; AT_FDCWD resolves them like rename(2).
    let r = unsafe {
        libc::renameat2(
            libc::AT_FDCWD,
            f.as_ptr(),
            libc::AT_FDCWD,
            t.as_ptr(),
            libc::RENAME_NOREPLACE,
        )
    };
    if r == 0 {
        return Ok(());
    }
    let e = std::io::Error::last_os_error();
    match e.raw_os_error() {
        // File systems without RENAME_NOREPLACE: check, then rename. Only this daemon
        // writes into its output tree, so the window is ours alone.
        Some(libc::EINVAL) | Some(libc::ENOSYS) | Some(libc::EOPNOTSUPP) => {
            if std::fs::symlink_metadata(to).is_ok() {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::AlreadyExists,
                    "target exists",
                ));
            }
            std::fs::rename(from, to)
        }
        _ => Err(e),
    }
}

/// Removes every leftover staging folder of an output root (at start-up: the daemon holds
/// the state lock, and an output root belongs to one daemon).
pub fn clean_staging(output_root: &Path) -> usize {
    clean_staging_older(output_root, std::time::Duration::ZERO)
}

/// Removes the staging folders of an output root last changed at least `age` ago (an
/// output root shared by several hosts: younger ones may be another host's attempt).
pub fn clean_staging_older(output_root: &Path, age: std::time::Duration) -> usize {
    let staging = output_root.join(STAGING_DIR);
    let Ok(entries) = std::fs::read_dir(&staging) else {
        return 0;
    };
    let mut n = 0;
    for e in entries.flatten() {
        let p = e.path();
        let young = e
            .metadata()
            .and_then(|m| m.modified())
            .ok()
            .and_then(|t| t.elapsed().ok())
            .is_none_or(|elapsed| elapsed < age);
        if !age.is_zero() && young {
            continue;
        }
        let removed = if p.is_dir() {
            std::fs::remove_dir_all(&p)
        } else {
            std::fs::remove_file(&p)
        };
        match removed {
            Ok(()) => n += 1,
            Err(err) => tracing::warn!("cannot remove stale temporary {}: {err}", p.display()),
        }
    }
    n
}

/// fsyncs every file in `dir` (recursively) and the folders themselves.
pub fn sync_tree(dir: &Path) -> std::io::Result<()> {
    for e in std::fs::read_dir(dir)? {
        let e = e?;
        let p = e.path();
        if e.file_type()?.is_dir() {
            sync_tree(&p)?;
        } else {
            std::fs::File::open(&p)?.sync_all()?;
        }
    }
    fsync_dir(dir)
}

/// Where a published scan goes, before any suffix.
pub fn destination(output_root: &Path, rel_path: &str, stem: &str) -> PathBuf {
    let rel_dir = Path::new(rel_path).parent().unwrap_or(Path::new(""));
    output_root.join(rel_dir).join(stem)
}

/// Reads the (job key, generation) a published folder's sidecar names, if any.
fn published_identity(dir: &Path, stem: &str) -> Option<(String, i64)> {
    let text = std::fs::read_to_string(dir.join(format!("{stem}{SIDECAR_SUFFIX}"))).ok()?;
    let v: Value = serde_json::from_str(&text).ok()?;
    Some((
        v["job_key"].as_str()?.to_string(),
        v["generation"].as_i64()?,
    ))
}

/// Creates `dir` and its missing parents, fsyncing each parent whose entries changed.
fn create_dirs_durably(dir: &Path) -> std::io::Result<()> {
    let mut missing = Vec::new();
    let mut p = dir.to_path_buf();
    while !p.exists() {
        missing.push(p.clone());
        if !p.pop() {
            break;
        }
    }
    std::fs::create_dir_all(dir)?;
    for m in missing.iter().rev() {
        if let Some(parent) = m.parent() {
            fsync_dir(parent)?;
        }
    }
    Ok(())
}

/// Outcome of [`publish_dir`].
#[derive(Debug, PartialEq)]
pub enum Published {
    /// Renamed into place here.
    New(PathBuf),
    /// This job's result was already there (published before a crash).
    AlreadyThere(PathBuf),
}

/// Moves the assembled folder `staged` (its sidecar named `<stem>.scanmill.json`) to its
/// destination, never replacing anything.
pub fn publish_dir(
    staged: &Path,
    dest: &Path,
    stem: &str,
    job_key: &str,
    generation: i64,
) -> std::io::Result<Published> {
    let parent = dest.parent().unwrap_or(Path::new("/")).to_path_buf();
    create_dirs_durably(&parent)?;
    let base = dest
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    for n in 1..10_000 {
        let candidate = if n == 1 {
            dest.to_path_buf()
        } else {
            parent.join(format!("{base}.v{n}"))
        };
        if std::fs::symlink_metadata(&candidate).is_ok() {
            if published_identity(&candidate, stem)
                .is_some_and(|(k, g)| k == job_key && g == generation)
            {
                return Ok(Published::AlreadyThere(candidate));
            }
            continue;
        }
        match rename_no_replace(staged, &candidate) {
            Ok(()) => {
                fsync_dir(&parent)?;
                if n > 1 {
                    tracing::warn!(
                        "{} exists with another result; published as {}",
                        dest.display(),
                        candidate.display()
                    );
                }
                return Ok(Published::New(candidate));
            }
            Err(e)
                if e.kind() == std::io::ErrorKind::AlreadyExists
                    || e.raw_os_error() == Some(libc::ENOTEMPTY) =>
            {
                continue;
            }
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::other(format!(
        "{}: too many versions",
        dest.display()
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn staged(dir: &Path, name: &str, key: &str, generation: i64) -> PathBuf {
        let s = dir.join(STAGING_DIR).join(name).join("scan");
        std::fs::create_dir_all(&s).unwrap();
        std::fs::write(s.join("scan.ply"), b"ply").unwrap();
        let sidecar = serde_json::json!({ "job_key": key, "generation": generation });
        std::fs::write(s.join(format!("scan{SIDECAR_SUFFIX}")), sidecar.to_string()).unwrap();
        sync_tree(&s).unwrap();
        s
    }

    #[test]
    fn publishes_then_suffixes_then_recognises_itself() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        let dest = destination(out, "lab/a/scan.ply", "scan");
        assert_eq!(dest, out.join("lab/a/scan"));
        let first = publish_dir(&staged(out, "j1", "k1", 0), &dest, "scan", "k1", 0).unwrap();
        assert_eq!(first, Published::New(dest.clone()));
        assert!(dest.join("scan.ply").is_file());
        let second = publish_dir(&staged(out, "j2", "k2", 0), &dest, "scan", "k2", 0).unwrap();
        assert_eq!(second, Published::New(out.join("lab/a/scan.v2")));
        let again = publish_dir(&staged(out, "j3", "k2", 0), &dest, "scan", "k2", 0).unwrap();
        assert_eq!(again, Published::AlreadyThere(out.join("lab/a/scan.v2")));
        assert_eq!(clean_staging(out), 3);
        assert!(
            std::fs::read_dir(out.join(STAGING_DIR))
                .unwrap()
                .next()
                .is_none()
        );
    }

    #[test]
    fn rename_no_replace_refuses_empty_target_dir() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("a")).unwrap();
        std::fs::create_dir(dir.path().join("b")).unwrap();
        let e = rename_no_replace(&dir.path().join("a"), &dir.path().join("b")).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::AlreadyExists);
    }
}
