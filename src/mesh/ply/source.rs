//! Typed values out of a PLY body: one [`Source`] for ASCII, one for binary (either byte
//! order). Readers ask for values by [`Scalar`] type and never allocate per element.
//!
//! Sources report a [`Fault`] without context; the element loop in `read.rs` turns it into a
//! [`MeshError`](crate::mesh::MeshError) naming the file, the element and its index (binary) or
//! the line (ASCII).

use super::header::{Element, PropertyKind, Scalar};
use crate::mesh::error::Location;

/// What went wrong inside one element.
#[derive(Debug)]
pub enum Fault {
    /// The body ended before the element did (detail says what was being read).
    Truncated(String),
    Invalid(String),
    NonFinite(String),
    Index {
        kind: &'static str,
        index: i64,
        count: usize,
    },
}

pub type Step<T = ()> = std::result::Result<T, Fault>;

pub trait Source {
    /// Starts the next element (ASCII: moves to its line).
    fn begin(&mut self) -> Step;
    /// One scalar, widened to f64 (exact for every PLY type).
    fn value(&mut self, ty: Scalar) -> Step<f64>;
    /// A list length, checked against what the rest of the body can hold so that a corrupt
    /// count can never cause a huge allocation or a long loop.
    fn list_len(&mut self, count: Scalar, item: Scalar) -> Step<usize>;
    /// Ends the element (ASCII: no values may be left on its line).
    fn end(&mut self) -> Step;
    /// Skips one property of the current element.
    fn skip(&mut self, kind: PropertyKind) -> Step {
        match kind {
            PropertyKind::Scalar(ty) => self.value(ty).map(drop),
            PropertyKind::List { count, item } => {
                let n = self.list_len(count, item)?;
                (0..n).try_for_each(|_| self.value(item).map(drop))
            }
        }
    }
    /// Skips a whole element kind; returns how many elements were skipped before a fault.
    fn skip_all(&mut self, element: &Element) -> std::result::Result<(), (u64, Fault)>;
    /// Where the current element is, for error messages.
    fn location(&self, element: &str, index: u64) -> Location;
    /// Bytes not yet read.
    fn remaining(&self) -> usize;
    /// The fewest bytes one value of type `ty` takes in this encoding (with what separates it
    /// from the next), so that counts can be checked against [`Source::remaining`].
    fn min_value_bytes(&self, ty: Scalar) -> usize;
    /// A description of non-blank data after the last element, if any.
    fn trailing(&mut self) -> Option<String>;
}

/// A list count as a usize, or a fault for negative / non-integral values.
fn list_count(n: f64) -> Step<usize> {
    if n < 0.0 {
        return Err(Fault::Invalid(format!("negative list length {n}")));
    }
    Ok(n as usize)
}

pub struct Binary<'a> {
    bytes: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl<'a> Binary<'a> {
    pub fn new(bytes: &'a [u8], big_endian: bool) -> Self {
        Binary {
            bytes,
            pos: 0,
            big_endian,
        }
    }

    #[inline]
    fn take<const N: usize>(&mut self) -> Step<[u8; N]> {
        match self.bytes.get(self.pos..self.pos + N) {
            Some(b) => {
                self.pos += N;
                let mut out = [0u8; N];
                out.copy_from_slice(b);
                Ok(out)
            }
            None => Err(Fault::Truncated(String::new())),
        }
    }
}

macro_rules! decode {
    ($self:ident, $t:ty, $n:literal) => {{
        let b = $self.take::<$n>()?;
        if $self.big_endian {
            <$t>::from_be_bytes(b) as f64
        } else {
            <$t>::from_le_bytes(b) as f64
        }
    }};
}

impl Source for Binary<'_> {
    #[inline]
    fn begin(&mut self) -> Step {
        Ok(())
    }

    #[inline]
    fn value(&mut self, ty: Scalar) -> Step<f64> {
        Ok(match ty {
            Scalar::I8 => decode!(self, i8, 1),
            Scalar::U8 => decode!(self, u8, 1),
            Scalar::I16 => decode!(self, i16, 2),
            Scalar::U16 => decode!(self, u16, 2),
            Scalar::I32 => decode!(self, i32, 4),
            Scalar::U32 => decode!(self, u32, 4),
            Scalar::F32 => decode!(self, f32, 4),
            Scalar::F64 => decode!(self, f64, 8),
        })
    }

    #[inline]
    fn list_len(&mut self, count: Scalar, item: Scalar) -> Step<usize> {
        let n = list_count(self.value(count)?)?;
        let need = n as u128 * item.size() as u128;
        if need > self.remaining() as u128 {
            return Err(Fault::Truncated(format!(
                " (a list of {n} {} values needs {need} bytes, {} remain)",
                item.name(),
                self.remaining()
            )));
        }
        Ok(n)
    }

    #[inline]
    fn end(&mut self) -> Step {
        Ok(())
    }

    fn skip_all(&mut self, element: &Element) -> std::result::Result<(), (u64, Fault)> {
        if let Some(size) = element.fixed_binary_size() {
            let total = size as u128 * element.count as u128;
            if total > self.remaining() as u128 {
                let whole = self.remaining() / size.max(1);
                return Err((whole as u64, Fault::Truncated(String::new())));
            }
            self.pos += total as usize;
            return Ok(());
        }
        for i in 0..element.count {
            for p in &element.properties {
                self.skip(p.kind).map_err(|f| (i, f))?;
            }
        }
        Ok(())
    }

    fn location(&self, element: &str, index: u64) -> Location {
        Location::Element {
            element: element.to_string(),
            index,
        }
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    fn min_value_bytes(&self, ty: Scalar) -> usize {
        ty.size()
    }

    fn trailing(&mut self) -> Option<String> {
        let n = self.remaining();
        (n > 0).then(|| format!("{n} bytes after the last element"))
    }
}

pub struct Ascii<'a> {
    body: &'a [u8],
    pos: usize,
    /// 1-based file line of `line`.
    line_no: u64,
    line: &'a [u8],
    cursor: usize,
}

impl<'a> Ascii<'a> {
    /// `header_lines`: how many lines precede the body, so that line numbers are the file's.
    pub fn new(body: &'a [u8], header_lines: u64) -> Self {
        Ascii {
            body,
            pos: 0,
            line_no: header_lines,
            line: &[],
            cursor: 0,
        }
    }

    /// The next non-blank line, or `None` at the end of the body.
    fn next_line(&mut self) -> Option<&'a [u8]> {
        while self.pos < self.body.len() {
            let rest = &self.body[self.pos..];
            let len = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
            self.pos += (len + 1).min(rest.len());
            self.line_no += 1;
            let line = &rest[..len];
            if line.iter().any(|b| !b.is_ascii_whitespace()) {
                return Some(line);
            }
        }
        None
    }

    fn token(&mut self) -> Option<&'a [u8]> {
        let line = self.line;
        let mut i = self.cursor;
        while i < line.len() && line[i].is_ascii_whitespace() {
            i += 1;
        }
        if i == line.len() {
            self.cursor = i;
            return None;
        }
        let start = i;
        while i < line.len() && !line[i].is_ascii_whitespace() {
            i += 1;
        }
        self.cursor = i;
        Some(&line[start..i])
    }
}

impl Source for Ascii<'_> {
    fn begin(&mut self) -> Step {
        match self.next_line() {
            Some(line) => {
                self.line = line;
                self.cursor = 0;
                Ok(())
            }
            None => Err(Fault::Truncated(String::new())),
        }
    }

    fn value(&mut self, ty: Scalar) -> Step<f64> {
        let Some(token) = self.token() else {
            return Err(Fault::Invalid(
                "the line has fewer values than the header declares".into(),
            ));
        };
        let text = std::str::from_utf8(token).unwrap_or("\u{fffd}");
        let parsed = if ty.is_integer() {
            text.parse::<i64>().ok().map(|v| v as f64)
        } else {
            text.parse::<f64>().ok()
        };
        parsed.ok_or_else(|| Fault::Invalid(format!("{text:?} is not a valid {}", ty.name())))
    }

    fn list_len(&mut self, count: Scalar, _item: Scalar) -> Step<usize> {
        let n = list_count(self.value(count)?)?;
        // Every value takes at least one character and a separator.
        let room = (self.line.len() - self.cursor).div_ceil(2);
        if n > room {
            return Err(Fault::Invalid(format!(
                "a list of {n} values cannot fit on the rest of the line"
            )));
        }
        Ok(n)
    }

    fn end(&mut self) -> Step {
        match self.token() {
            None => Ok(()),
            Some(extra) => Err(Fault::Invalid(format!(
                "the line has more values than the header declares (starting at {:?})",
                String::from_utf8_lossy(extra)
            ))),
        }
    }

    fn skip_all(&mut self, element: &Element) -> std::result::Result<(), (u64, Fault)> {
        for i in 0..element.count {
            if self.next_line().is_none() {
                return Err((i, Fault::Truncated(String::new())));
            }
        }
        Ok(())
    }

    fn location(&self, _element: &str, _index: u64) -> Location {
        Location::Line(self.line_no)
    }

    fn remaining(&self) -> usize {
        self.body.len() - self.pos
    }

    /// A digit and a space or line break.
    fn min_value_bytes(&self, _ty: Scalar) -> usize {
        2
    }

    fn trailing(&mut self) -> Option<String> {
        let first = self.line_no + 1;
        let mut lines = 0u64;
        while self.next_line().is_some() {
            lines += 1;
        }
        (lines > 0)
            .then(|| format!("{lines} non-blank lines after the last element (from line {first})"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binary_decodes_both_byte_orders() {
        let le = [1u8, 0, 0, 0, 0, 0, 0x80, 0x3f];
        let mut s = Binary::new(&le, false);
        assert_eq!(s.value(Scalar::I32).unwrap(), 1.0);
        assert_eq!(s.value(Scalar::F32).unwrap(), 1.0);
        assert!(matches!(s.value(Scalar::U8), Err(Fault::Truncated(_))));
        let be = [0xffu8, 0xfe, 0x3f, 0xf0, 0, 0, 0, 0, 0, 0];
        let mut s = Binary::new(&be, true);
        assert_eq!(s.value(Scalar::I16).unwrap(), -2.0);
        assert_eq!(s.value(Scalar::F64).unwrap(), 1.0);
    }

    #[test]
    fn binary_list_length_is_bounded_by_the_remaining_bytes() {
        let bytes = [0xffu8, 0xff, 0xff, 0xff, 1, 2, 3];
        let mut s = Binary::new(&bytes, false);
        assert!(matches!(
            s.list_len(Scalar::U32, Scalar::I32),
            Err(Fault::Truncated(_))
        ));
        let mut s = Binary::new(&bytes, false);
        assert!(matches!(
            s.list_len(Scalar::I32, Scalar::I32),
            Err(Fault::Invalid(_))
        ));
    }

    #[test]
    fn ascii_tracks_lines_and_checks_value_counts() {
        let body = b"1 2.5\n\n  3 x\r\n4 5 6\n";
        let mut s = Ascii::new(body, 10);
        s.begin().unwrap();
        assert_eq!(s.value(Scalar::U8).unwrap(), 1.0);
        assert_eq!(s.value(Scalar::F32).unwrap(), 2.5);
        s.end().unwrap();
        s.begin().unwrap();
        assert_eq!(s.location("v", 1), Location::Line(13));
        assert_eq!(s.value(Scalar::I32).unwrap(), 3.0);
        assert!(matches!(s.value(Scalar::F32), Err(Fault::Invalid(_))));
        s.begin().unwrap();
        assert_eq!(s.value(Scalar::I32).unwrap(), 4.0);
        assert!(matches!(s.end(), Err(Fault::Invalid(_))));
        assert!(matches!(s.begin(), Err(Fault::Truncated(_))));
        assert!(s.trailing().is_none());
    }
}
