//! [`RelPath`]: a path relative to a watched folder, kept byte for byte from the walk to the
//! database to the worker that opens the file, and shown escaped.
//!
//! Storage: the `rel_path` columns are `TEXT` in STRICT tables, which refuse a BLOB, so
//! the lossless form is text too, without a migration:
//! - a path that is valid UTF-8 is stored as it is (every row written before this type);
//! - any other path is stored as `//` followed by its bytes with `\` written `\\` and each
//!   byte that is not part of valid UTF-8 written `\xNN`.
//!
//! The two cannot be confused: a relative path never starts with `/`, so no UTF-8 path is
//! ever stored with the `//` mark, and the escaped tail decodes to exactly one byte string.

use rusqlite::types::{FromSql, FromSqlError, FromSqlResult, ToSql, ToSqlOutput, ValueRef};
use std::ffi::OsStr;
use std::fmt::Write;
use std::os::unix::ffi::{OsStrExt, OsStringExt};
use std::path::{Component, Path, PathBuf};

/// A relative path (no root, no `..`), any bytes.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct RelPath(PathBuf);

/// Marks a stored path that is not UTF-8.
const RAW_MARK: &str = "//";

impl RelPath {
    /// `path` if it is relative and goes nowhere up (`..`) or to a root.
    pub fn new(path: impl Into<PathBuf>) -> Option<RelPath> {
        let path = path.into();
        path.components()
            .all(|c| matches!(c, Component::Normal(_) | Component::CurDir))
            .then_some(RelPath(path))
    }

    /// `path` relative to `root`, if it lies under it (lexically).
    pub fn under(root: &Path, path: &Path) -> Option<RelPath> {
        RelPath::new(path.strip_prefix(root).ok()?)
    }

    pub fn as_path(&self) -> &Path {
        &self.0
    }

    pub fn as_bytes(&self) -> &[u8] {
        self.0.as_os_str().as_bytes()
    }

    /// The form stored in the database (see the module notes).
    pub fn to_stored(&self) -> String {
        match std::str::from_utf8(self.as_bytes()) {
            Ok(text) => text.to_string(),
            Err(_) => {
                let mut out = String::from(RAW_MARK);
                for chunk in self.as_bytes().utf8_chunks() {
                    for c in chunk.valid().chars() {
                        if c == '\\' {
                            out.push_str("\\\\");
                        } else {
                            out.push(c);
                        }
                    }
                    for b in chunk.invalid() {
                        let _ = write!(out, "\\x{b:02x}");
                    }
                }
                out
            }
        }
    }

    /// Reads the stored form back; `None` for a marked text that is not a valid escape.
    pub fn from_stored(text: &str) -> Option<RelPath> {
        let Some(tail) = text.strip_prefix(RAW_MARK) else {
            return Some(RelPath(PathBuf::from(text)));
        };
        let mut bytes = Vec::with_capacity(tail.len());
        let mut rest = tail.as_bytes();
        while let Some((&b, after)) = rest.split_first() {
            if b != b'\\' {
                bytes.push(b);
                rest = after;
                continue;
            }
            match after {
                [b'\\', tail @ ..] => {
                    bytes.push(b'\\');
                    rest = tail;
                }
                [b'x', h, l, tail @ ..] => {
                    let hex = std::str::from_utf8(&[*h, *l]).ok()?.to_string();
                    bytes.push(u8::from_str_radix(&hex, 16).ok()?);
                    rest = tail;
                }
                _ => return None,
            }
        }
        Some(RelPath(PathBuf::from(std::ffi::OsString::from_vec(bytes))))
    }

    /// The file name, escaped for display.
    pub fn file_name_display(&self) -> String {
        crate::text::escape_os(self.0.file_name().unwrap_or(OsStr::new("")))
    }
}

/// For tests: a literal relative path.
#[cfg(test)]
impl From<&str> for RelPath {
    fn from(text: &str) -> RelPath {
        RelPath::new(text).expect("a relative path")
    }
}

#[cfg(test)]
impl PartialEq<&str> for RelPath {
    fn eq(&self, other: &&str) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl AsRef<Path> for RelPath {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

/// Escaped for people and logs: control characters and invalid UTF-8 as `\n`, `\xNN`, ….
impl std::fmt::Display for RelPath {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&crate::text::escape_for_display(self.as_bytes()))
    }
}

impl ToSql for RelPath {
    fn to_sql(&self) -> rusqlite::Result<ToSqlOutput<'_>> {
        Ok(ToSqlOutput::from(self.to_stored()))
    }
}

impl FromSql for RelPath {
    fn column_result(value: ValueRef<'_>) -> FromSqlResult<Self> {
        let text = value.as_str()?;
        RelPath::from_stored(text).ok_or_else(|| {
            FromSqlError::Other(format!("not a stored relative path: {text:?}").into())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raw(bytes: &[u8]) -> RelPath {
        RelPath::new(PathBuf::from(std::ffi::OsString::from_vec(bytes.to_vec()))).unwrap()
    }

    #[test]
    fn utf8_paths_are_stored_unchanged() {
        let p = RelPath::new("session 1/james.obj").unwrap();
        assert_eq!(p.to_stored(), "session 1/james.obj");
        assert_eq!(
            RelPath::from_stored("a\\b.obj").unwrap().as_bytes(),
            b"a\\b.obj"
        );
    }

    #[test]
    fn any_bytes_round_trip() {
        for bytes in [
            &b"scan\xff.obj"[..],
            b"d\xc3/\\x41\xfe\\.ply",
            b"\xe9t\xe9.obj",
            b"new\nline\x1b.obj",
        ] {
            let p = raw(bytes);
            let stored = p.to_stored();
            assert_eq!(RelPath::from_stored(&stored).unwrap(), p, "{stored}");
        }
        // A literal backslash-x name and the byte it spells are different paths.
        assert_ne!(
            raw(b"a\\xff\xfe").to_stored(),
            raw(b"a\xff\xfe").to_stored()
        );
        assert!(raw(b"a\xff").to_stored().starts_with("//"));
    }

    #[test]
    fn only_relative_downward_paths() {
        assert!(RelPath::new("/etc/passwd").is_none());
        assert!(RelPath::new("../x.mtl").is_none());
        assert!(RelPath::new("a/../../x.mtl").is_none());
        assert!(RelPath::from_stored("//bad\\q").is_none());
    }

    #[test]
    fn display_is_escaped() {
        assert_eq!(raw(b"a\nb\xff.obj").to_string(), "a\\nb\\xff.obj");
    }

    #[test]
    fn sqlite_round_trip() {
        let conn = rusqlite::Connection::open_in_memory().unwrap();
        conn.execute_batch("CREATE TABLE t(p TEXT NOT NULL) STRICT")
            .unwrap();
        let p = raw(b"x\xff\\y.obj");
        conn.execute("INSERT INTO t(p) VALUES (?1)", [&p]).unwrap();
        let back: RelPath = conn.query_row("SELECT p FROM t", [], |r| r.get(0)).unwrap();
        assert_eq!(back, p);
    }
}
