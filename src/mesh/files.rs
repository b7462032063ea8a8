//! Reading input files safely: the one place where scanmill opens a file a scan gave it.
//!
//! Rules:
//! - only regular files are read: a FIFO, a device, a socket or a folder is refused before it
//!   is opened (from its metadata), and again after opening (from the open file's own
//!   metadata), because the path may have been replaced in between; the open itself uses
//!   `O_NONBLOCK`, so that opening a FIFO that appeared in that window returns at once
//!   instead of waiting for a writer;
//! - a file read whole is checked against its size cap from the metadata before reading, and
//!   the read itself stops one byte past the cap, so a file that grows while it is read cannot
//!   make scanmill read more.

use super::error::{MeshError, Result};
use super::limits::Limit;
use std::fs::{File, Metadata};
use std::io::Read;
use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
use std::path::Path;

/// A kind of file that is not a regular file and is never read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpecialKind {
    Fifo,
    CharDevice,
    BlockDevice,
    Socket,
    Directory,
    Other,
}

impl std::fmt::Display for SpecialKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SpecialKind::Fifo => "a FIFO",
            SpecialKind::CharDevice => "a character device",
            SpecialKind::BlockDevice => "a block device",
            SpecialKind::Socket => "a socket",
            SpecialKind::Directory => "a folder",
            SpecialKind::Other => "not a regular file",
        })
    }
}

/// `None` for a regular file, else what the file is.
pub fn special_kind(meta: &Metadata) -> Option<SpecialKind> {
    let t = meta.file_type();
    if t.is_file() {
        None
    } else if t.is_fifo() {
        Some(SpecialKind::Fifo)
    } else if t.is_char_device() {
        Some(SpecialKind::CharDevice)
    } else if t.is_block_device() {
        Some(SpecialKind::BlockDevice)
    } else if t.is_socket() {
        Some(SpecialKind::Socket)
    } else if t.is_dir() {
        Some(SpecialKind::Directory)
    } else {
        Some(SpecialKind::Other)
    }
}

fn refuse_special(path: &Path, meta: &Metadata) -> Result<()> {
    match special_kind(meta) {
        None => Ok(()),
        Some(kind) => Err(MeshError::SpecialFile {
            path: path.to_path_buf(),
            kind,
        }),
    }
}

/// Opens a regular file for reading (see the module rules). Symlinks are followed: callers
/// that must stay inside a folder resolve the path first.
pub fn open_regular(path: &Path) -> Result<(File, Metadata)> {
    let before = std::fs::metadata(path).map_err(|e| MeshError::io(path, e))?;
    refuse_special(path, &before)?;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK | libc::O_NOCTTY)
        .open(path)
        .map_err(|e| MeshError::io(path, e))?;
    let meta = file.metadata().map_err(|e| MeshError::io(path, e))?;
    refuse_special(path, &meta)?;
    Ok((file, meta))
}

/// The error for a file (or its content) above a limit.
pub fn too_large(path: &Path, what: String, limit: Limit, value: u64) -> MeshError {
    MeshError::TooLarge {
        path: path.to_path_buf(),
        what,
        limit,
        value,
    }
}

/// Reads a regular file whole, refusing it if it is (or grows) larger than `cap` bytes, the
/// value of `limit`.
pub fn read_whole(path: &Path, cap: u64, limit: Limit) -> Result<Vec<u8>> {
    let (file, meta) = open_regular(path)?;
    let size = meta.len();
    if size > cap {
        return Err(too_large(
            path,
            format!("file size {size} bytes"),
            limit,
            cap,
        ));
    }
    // The reservation is the size on disk, already checked against the cap.
    let mut bytes = Vec::with_capacity(size as usize);
    file.take(cap.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| MeshError::io(path, e))?;
    if bytes.len() as u64 > cap {
        return Err(too_large(
            path,
            "file grew while being read; its size".into(),
            limit,
            cap,
        ));
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_files_read_and_caps_hold() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        std::fs::write(&p, b"hello").unwrap();
        assert_eq!(read_whole(&p, 5, Limit::FileBytes).unwrap(), b"hello");
        let e = read_whole(&p, 4, Limit::MtlBytes).unwrap_err();
        assert!(
            e.to_string()
                .contains("file size 5 bytes exceeds limits.max_mtl_bytes = 4"),
            "{e}"
        );
    }

    #[test]
    fn special_files_are_refused_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("f.obj");
        let c = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let e = read_whole(&fifo, 1 << 20, Limit::FileBytes).unwrap_err();
        assert!(
            matches!(
                e,
                MeshError::SpecialFile {
                    kind: SpecialKind::Fifo,
                    ..
                }
            ),
            "{e}"
        );
        assert!(
            e.to_string().ends_with("is a FIFO; refusing to read it"),
            "{e}"
        );
        let e = read_whole(Path::new("/dev/zero"), 1 << 20, Limit::FileBytes).unwrap_err();
        assert!(e.to_string().contains("character device"), "{e}");
        let e = read_whole(dir.path(), 1 << 20, Limit::FileBytes).unwrap_err();
        assert!(e.to_string().contains("is a folder"), "{e}");
    }
}
