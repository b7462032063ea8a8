//! Showing text that came from input (file names, parser messages) safely.
//!
//! Rule: every input-derived string that goes into a log line, an error or a command's
//! output passes through [`escape_for_display`] (or [`escape_path`] / [`bounded`]), so that a
//! name with a newline cannot split a log record, an ESC or CR cannot rewrite a terminal, and
//! a file name that is not UTF-8 is shown byte for byte instead of being replaced.
//!
//! Escapes: `\n`, `\r`, `\t`, other control characters (C0, DEL, C1) as `\xNN` (one byte)
//! or `\u{NN}` (C1, a two-byte character), bytes that are not valid UTF-8 as `\xNN`.
//! Backslash itself is left alone: the display form is for people, not a round trip (the
//! database has its own lossless form, [`crate::store::RelPath`]).

use std::ffi::OsStr;
use std::fmt::Write;
use std::os::unix::ffi::OsStrExt;
use std::path::Path;

/// `bytes` as printable text: valid UTF-8 kept, control characters and invalid bytes escaped.
pub fn escape_for_display(bytes: &[u8]) -> String {
    let mut out = String::with_capacity(bytes.len());
    for chunk in bytes.utf8_chunks() {
        for c in chunk.valid().chars() {
            push_char(&mut out, c);
        }
        for b in chunk.invalid() {
            let _ = write!(out, "\\x{b:02x}");
        }
    }
    out
}

fn push_char(out: &mut String, c: char) {
    match c {
        '\n' => out.push_str("\\n"),
        '\r' => out.push_str("\\r"),
        '\t' => out.push_str("\\t"),
        c if (c as u32) < 0x20 || c as u32 == 0x7f => {
            let _ = write!(out, "\\x{:02x}", c as u32);
        }
        // C1 controls (CSI among them) act like ESC sequences on many terminals.
        c if (0x80..0xa0).contains(&(c as u32)) => {
            let _ = write!(out, "\\u{{{:x}}}", c as u32);
        }
        c => out.push(c),
    }
}

/// A string escaped for display (see [`escape_for_display`]).
pub fn escape_str(text: &str) -> String {
    escape_for_display(text.as_bytes())
}

/// A path escaped for display, byte for byte.
pub fn escape_path(path: &Path) -> String {
    escape_os(path.as_os_str())
}

/// An `OsStr` escaped for display, byte for byte.
pub fn escape_os(s: &OsStr) -> String {
    escape_for_display(s.as_bytes())
}

/// Serde: a path as its escaped text, so that a report with a name that is not UTF-8
/// serialises (instead of failing) and shows that name byte for byte.
pub fn serialize_path<S: serde::Serializer>(path: &Path, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(&escape_path(path))
}

/// The longest input-derived text kept in an error message or a log line: enough for a
/// path and a parser's message, too short for a file's contents to leak in bulk.
pub const MAX_SHOWN: usize = 512;

/// `text` escaped and cut to at most `max` characters of output, marked `…` when cut
/// (never inside an escape sequence).
pub fn bounded(text: &str, max: usize) -> String {
    let mut out = String::new();
    let mut shown = 0usize;
    for chunk in text.as_bytes().utf8_chunks() {
        for c in chunk.valid().chars() {
            let mut piece = String::new();
            push_char(&mut piece, c);
            let n = piece.chars().count();
            if shown + n > max {
                out.push('…');
                return out;
            }
            shown += n;
            out.push_str(&piece);
        }
    }
    out
}

/// The name serde gives a unit enum variant (its `rename_all` spelling): names shown in
/// reports and messages are derived from the serde attributes once, not kept in tables
/// beside them that could drift.
pub fn serde_name<T: serde::Serialize>(value: &T) -> String {
    match serde_json::to_value(value) {
        Ok(serde_json::Value::String(name)) => name,
        other => panic!("serde_name of a value that is not a unit variant: {other:?}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn controls_and_invalid_bytes_are_escaped() {
        assert_eq!(escape_for_display(b"a\nb\rc\x1b[31m"), "a\\nb\\rc\\x1b[31m");
        assert_eq!(
            escape_for_display(b"caf\xc3\xa9 \xff\xfe.obj"),
            "café \\xff\\xfe.obj"
        );
        assert_eq!(escape_for_display("x\u{9b}y".as_bytes()), "x\\u{9b}y");
        assert_eq!(escape_for_display(b"\x7f\x00"), "\\x7f\\x00");
        assert_eq!(escape_for_display(b"plain\\name.obj"), "plain\\name.obj");
    }

    #[test]
    fn bounded_cuts_whole_escapes() {
        assert_eq!(bounded("abc", 3), "abc");
        assert_eq!(bounded("abcd", 3), "abc…");
        // "\n" is two characters shown: it does not fit after "ab" with max 3.
        assert_eq!(bounded("ab\ncd", 3), "ab…");
        assert!(!bounded(&"root:x:0:0\n".repeat(1000), MAX_SHOWN).contains('\n'));
        assert!(bounded(&"y".repeat(10_000), MAX_SHOWN).chars().count() <= MAX_SHOWN + 1);
    }
}
