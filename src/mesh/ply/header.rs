//! The PLY header: magic, format, comments, elements and their properties.
//!
//! Lines end in `\n` or `\r\n` (CRLF headers from Windows tools are common). Errors name the
//! 1-based header line.

use crate::mesh::error::{Location, MeshError, Result};
use std::path::Path;

/// How the body after `end_header` is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

impl Format {
    pub fn keyword(self) -> &'static str {
        match self {
            Format::Ascii => "ascii",
            Format::BinaryLittleEndian => "binary_little_endian",
            Format::BinaryBigEndian => "binary_big_endian",
        }
    }
}

/// A PLY scalar type (both the classic and the sized spellings are accepted).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    pub fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// Bytes in binary encodings.
    pub fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    pub fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    pub fn name(self) -> &'static str {
        match self {
            Scalar::I8 => "char",
            Scalar::U8 => "uchar",
            Scalar::I16 => "short",
            Scalar::U16 => "ushort",
            Scalar::I32 => "int",
            Scalar::U32 => "uint",
            Scalar::F32 => "float",
            Scalar::F64 => "double",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PropertyKind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Property {
    pub name: String,
    pub kind: PropertyKind,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Element {
    pub name: String,
    pub count: u64,
    pub properties: Vec<Property>,
}

impl Element {
    pub fn property(&self, name: &str) -> Option<(usize, &Property)> {
        self.properties
            .iter()
            .enumerate()
            .find(|(_, p)| p.name == name)
    }

    /// The fewest bytes one element can take in a binary body (lists empty). Used to cap
    /// allocations by what the file can actually hold.
    pub fn min_binary_size(&self) -> usize {
        self.properties
            .iter()
            .map(|p| match p.kind {
                PropertyKind::Scalar(s) => s.size(),
                PropertyKind::List { count, .. } => count.size(),
            })
            .sum()
    }

    /// The byte size of every element when it has no lists.
    pub fn fixed_binary_size(&self) -> Option<usize> {
        self.properties
            .iter()
            .all(|p| matches!(p.kind, PropertyKind::Scalar(_)))
            .then(|| self.min_binary_size())
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    pub format: Format,
    pub elements: Vec<Element>,
    /// `comment` lines, without the keyword, in order.
    pub comments: Vec<String>,
    /// `obj_info` lines, without the keyword, in order.
    pub obj_info: Vec<String>,
    /// Offset of the first body byte (just after the `end_header` line break).
    pub body_start: usize,
    /// Number of header lines, so that ASCII body lines can be numbered from the file start.
    pub lines: u64,
}

impl Header {
    pub fn element(&self, name: &str) -> Option<&Element> {
        self.elements.iter().find(|e| e.name == name)
    }

    /// `comment TextureFile NAME` lines (MeshLab, OpenMVS), in order, names normalised
    /// ([`normalise_name`](crate::mesh::texture::normalise_name)).
    pub fn texture_files(&self) -> Vec<String> {
        self.comments
            .iter()
            .filter_map(|c| {
                let rest = c.strip_prefix("TextureFile")?;
                rest.starts_with([' ', '\t'])
                    .then(|| crate::mesh::texture::normalise_name(rest.trim()))
                    .filter(|name| !name.is_empty())
            })
            .collect()
    }
}

/// Parses the header at the start of `bytes`.
pub fn parse(path: &Path, bytes: &[u8]) -> Result<Header> {
    if !(bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r\n")) {
        let shown = String::from_utf8_lossy(&bytes[..bytes.len().min(16)]).into_owned();
        return Err(MeshError::malformed(
            path,
            Location::Header,
            format!("not a PLY file: it must start with the line \"ply\", found {shown:?}"),
        ));
    }
    let mut header = Header {
        format: Format::Ascii,
        elements: Vec::new(),
        comments: Vec::new(),
        obj_info: Vec::new(),
        body_start: 0,
        lines: 0,
    };
    let mut format: Option<Format> = None;
    loop {
        if header.body_start >= bytes.len() {
            return Err(MeshError::malformed(
                path,
                Location::Header,
                "the header never ends: no end_header line",
            ));
        }
        let raw = next_line(bytes, &mut header.body_start);
        header.lines += 1;
        let line_no = header.lines;
        let bad = |message: String| MeshError::malformed(path, Location::Line(line_no), message);
        let Ok(line) = std::str::from_utf8(raw) else {
            return Err(bad("header line is not text".into()));
        };
        if header.lines == 1 {
            continue; // the magic, checked above
        }
        match header_line(line, &mut header, &mut format).map_err(bad)? {
            Flow::Next => {}
            Flow::End => break,
        }
    }
    header.format =
        format.ok_or_else(|| MeshError::malformed(path, Location::Header, "no format line"))?;
    Ok(header)
}

/// Whether the header goes on after a line.
enum Flow {
    Next,
    End,
}

/// The line starting at `*pos`, without its `\n` or `\r\n`; `*pos` moves past it.
fn next_line<'b>(bytes: &'b [u8], pos: &mut usize) -> &'b [u8] {
    let end = bytes[*pos..]
        .iter()
        .position(|&b| b == b'\n')
        .map_or(bytes.len(), |i| *pos + i);
    let raw = &bytes[*pos..end];
    *pos = (end + 1).min(bytes.len());
    raw.strip_suffix(b"\r").unwrap_or(raw)
}

/// One header line after the magic, added to `header` (the format to `format`, so that a
/// second one is seen); blank lines are tolerated.
fn header_line(
    line: &str,
    header: &mut Header,
    format: &mut Option<Format>,
) -> std::result::Result<Flow, String> {
    let mut words = line.split_ascii_whitespace();
    let Some(keyword) = words.next() else {
        return Ok(Flow::Next);
    };
    let rest = || {
        line.trim_start()
            .strip_prefix(keyword)
            .unwrap_or("")
            .trim()
            .to_string()
    };
    match keyword {
        "comment" => header.comments.push(rest()),
        "obj_info" => header.obj_info.push(rest()),
        "format" => {
            if format.is_some() {
                return Err("a second format line".into());
            }
            *format = Some(format_line(words)?);
        }
        "element" => {
            let element = element_line(line, words)?;
            if header.elements.iter().any(|e| e.name == element.name) {
                return Err(format!("element {:?} declared twice", element.name));
            }
            header.elements.push(element);
        }
        "property" => {
            let Some(element) = header.elements.last_mut() else {
                return Err("property before any element".into());
            };
            let property = property_line(line, words)?;
            if element.properties.iter().any(|p| p.name == property.name) {
                return Err(format!(
                    "property {:?} declared twice in element {:?}",
                    property.name, element.name
                ));
            }
            element.properties.push(property);
        }
        "end_header" => return Ok(Flow::End),
        other => return Err(format!("unknown header keyword {other:?}")),
    }
    Ok(Flow::Next)
}

/// `format FORMAT 1.0`, after the keyword.
fn format_line<'l>(
    mut words: impl Iterator<Item = &'l str>,
) -> std::result::Result<Format, String> {
    let f = match words.next() {
        Some("ascii") => Format::Ascii,
        Some("binary_little_endian") => Format::BinaryLittleEndian,
        Some("binary_big_endian") => Format::BinaryBigEndian,
        other => {
            return Err(format!(
                "unknown format {:?} (expected ascii, binary_little_endian or binary_big_endian)",
                other.unwrap_or("")
            ));
        }
    };
    match words.next() {
        Some("1.0") | Some("1") => Ok(f),
        other => Err(format!(
            "unsupported PLY version {:?} (expected 1.0)",
            other.unwrap_or("")
        )),
    }
}

/// `element NAME COUNT`, after the keyword.
fn element_line<'l>(
    line: &str,
    mut words: impl Iterator<Item = &'l str>,
) -> std::result::Result<Element, String> {
    let (Some(name), Some(count), None) = (words.next(), words.next(), words.next()) else {
        return Err(format!(
            "bad element line {line:?} (expected: element NAME COUNT)"
        ));
    };
    let Ok(count) = count.parse::<u64>() else {
        return Err(format!("bad element count {count:?}"));
    };
    Ok(Element {
        name: name.to_string(),
        count,
        properties: Vec::new(),
    })
}

/// `property TYPE NAME` or `property list COUNT_TYPE ITEM_TYPE NAME`, after the keyword.
fn property_line<'l>(
    line: &str,
    words: impl Iterator<Item = &'l str>,
) -> std::result::Result<Property, String> {
    let words: Vec<&str> = words.collect();
    let scalar = |w: &str| Scalar::parse(w).ok_or_else(|| format!("unknown property type {w:?}"));
    let (kind, name) = match words.as_slice() {
        ["list", count, item, name] => {
            let count = scalar(count)?;
            if !count.is_integer() {
                return Err(format!(
                    "list count type must be an integer type, not {}",
                    count.name()
                ));
            }
            let item = scalar(item)?;
            (PropertyKind::List { count, item }, *name)
        }
        [ty, name] if *ty != "list" => (PropertyKind::Scalar(scalar(ty)?), *name),
        _ => {
            return Err(format!(
                "bad property line {line:?} (expected: property TYPE NAME or property list COUNT_TYPE ITEM_TYPE NAME)"
            ));
        }
    };
    Ok(Property {
        name: name.to_string(),
        kind,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_str(s: &str) -> Result<Header> {
        parse(Path::new("t.ply"), s.as_bytes())
    }

    #[test]
    fn parses_elements_comments_and_crlf() {
        let h = parse_str(
            "ply\r\nformat binary_big_endian 1.0\r\ncomment TextureFile a b.png\r\nobj_info x 1\r\n\
             element vertex 3\r\nproperty float32 x\r\nproperty list uint8 int vertex_indices\r\nend_header\r\nBODY",
        )
        .unwrap();
        assert_eq!(h.format, Format::BinaryBigEndian);
        assert_eq!(h.texture_files(), vec!["a b.png".to_string()]);
        assert_eq!(h.obj_info, vec!["x 1".to_string()]);
        let v = h.element("vertex").unwrap();
        assert_eq!(v.count, 3);
        assert_eq!(v.properties[0].kind, PropertyKind::Scalar(Scalar::F32));
        assert_eq!(
            v.properties[1].kind,
            PropertyKind::List {
                count: Scalar::U8,
                item: Scalar::I32
            }
        );
        assert_eq!(
            &"ply\r\nformat binary_big_endian 1.0\r\ncomment TextureFile a b.png\r\nobj_info x 1\r\nelement vertex 3\r\nproperty float32 x\r\nproperty list uint8 int vertex_indices\r\nend_header\r\nBODY"
                [h.body_start..],
            "BODY"
        );
        assert_eq!(h.lines, 8);
    }

    #[test]
    fn rejects_bad_headers_with_line_numbers() {
        for (text, says) in [
            ("plx\n", "not a PLY file"),
            ("", "not a PLY file"),
            ("ply\nformat ascii 1.0\n", "no end_header"),
            (
                "ply\nformat utf8 1.0\nend_header\n",
                "line 2: unknown format",
            ),
            (
                "ply\nformat ascii 1.0\nproperty float x\nend_header\n",
                "line 3: property before any element",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex -3\nend_header\n",
                "bad element count",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty flot x\nend_header\n",
                "unknown property type \"flot\"",
            ),
            (
                "ply\nformat ascii 1.0\nelement face 3\nproperty list float int v\nend_header\n",
                "list count type",
            ),
            (
                "ply\nformat ascii 1.0\nwhatever\nend_header\n",
                "line 3: unknown header keyword",
            ),
            ("ply\nelement vertex 0\nend_header\n", "no format line"),
        ] {
            let e = parse_str(text).unwrap_err().to_string();
            assert!(e.contains(says), "{text:?}: {e}");
        }
    }
}
