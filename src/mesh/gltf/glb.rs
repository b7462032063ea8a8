//! The GLB container (glTF 2.0 §4.4): a 12-byte header (`glTF`, version 2, total length), a
//! JSON chunk and an optional BIN chunk, each an 8-byte chunk header (length, type) and its
//! data padded to four bytes. Reading checks every length against the bytes present before
//! slicing; writing pads as the specification requires (JSON with spaces, BIN with zeros).

use crate::mesh::error::{Location, MeshError, Result};
use std::io::Write;
use std::path::Path;

pub const MAGIC: &[u8; 4] = b"glTF";
const JSON_CHUNK: u32 = 0x4E4F_534A;
const BIN_CHUNK: u32 = 0x004E_4942;

/// The two chunks of a GLB file.
#[derive(Debug)]
pub struct Chunks<'a> {
    pub json: &'a [u8],
    pub bin: Option<&'a [u8]>,
}

fn word(bytes: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?))
}

/// Splits a GLB file into its chunks. The header's length must be the file's size, the first
/// chunk JSON, a second chunk (if any) BIN; chunks after those are skipped, as the
/// specification allows.
pub fn split<'a>(path: &Path, bytes: &'a [u8]) -> Result<Chunks<'a>> {
    let bad = |at: u64, message: String| MeshError::malformed(path, Location::Byte(at), message);
    let (Some(version), Some(length)) = (word(bytes, 4), word(bytes, 8)) else {
        return Err(bad(
            0,
            format!("GLB header needs 12 bytes, the file has {}", bytes.len()),
        ));
    };
    if version != 2 {
        return Err(bad(
            4,
            format!("GLB version {version}; only glTF 2.0 is read"),
        ));
    }
    if u64::from(length) != bytes.len() as u64 {
        return Err(bad(
            8,
            format!(
                "GLB header declares {length} bytes but the file has {} bytes",
                bytes.len()
            ),
        ));
    }
    let mut at = 12usize;
    let mut chunks: Vec<(u32, &[u8])> = Vec::with_capacity(2);
    while at < bytes.len() && chunks.len() < 2 {
        let (Some(len), Some(kind)) = (word(bytes, at), word(bytes, at + 4)) else {
            return Err(bad(at as u64, "chunk header cut short".into()));
        };
        let start = at + 8;
        let end = start as u64 + u64::from(len);
        if end > bytes.len() as u64 {
            return Err(bad(
                at as u64,
                format!(
                    "chunk declares {len} bytes but {} remain",
                    bytes.len() - start.min(bytes.len())
                ),
            ));
        }
        chunks.push((kind, &bytes[start..end as usize]));
        at = end as usize;
    }
    let json = match chunks.first() {
        Some((JSON_CHUNK, json)) => *json,
        _ => return Err(bad(12, "the first chunk is not JSON".into())),
    };
    let bin = match chunks.get(1) {
        None => None,
        Some((BIN_CHUNK, bin)) => Some(*bin),
        Some(_) => {
            return Err(bad(
                20 + json.len() as u64,
                "the second chunk is not BIN".into(),
            ));
        }
    };
    Ok(Chunks { json, bin })
}

fn padded(len: usize) -> usize {
    len.div_ceil(4) * 4
}

/// Writes a GLB file from its JSON text and binary buffer; an error if the result would pass
/// the format's 4 GiB limit (lengths are 32-bit).
pub fn write(out: &mut impl Write, json: &[u8], bin: &[u8]) -> std::io::Result<()> {
    let json_len = padded(json.len());
    let bin_len = padded(bin.len());
    let total = 12 + 8 + json_len + if bin.is_empty() { 0 } else { 8 + bin_len };
    let too_big = || std::io::Error::other("the GLB would exceed 4 GiB, the format's limit");
    let total = u32::try_from(total).map_err(|_| too_big())?;
    out.write_all(MAGIC)?;
    out.write_all(&2u32.to_le_bytes())?;
    out.write_all(&total.to_le_bytes())?;
    out.write_all(&(json_len as u32).to_le_bytes())?;
    out.write_all(&JSON_CHUNK.to_le_bytes())?;
    out.write_all(json)?;
    out.write_all(&b"   "[..json_len - json.len()])?;
    if !bin.is_empty() {
        out.write_all(&(bin_len as u32).to_le_bytes())?;
        out.write_all(&BIN_CHUNK.to_le_bytes())?;
        out.write_all(bin)?;
        out.write_all(&[0u8; 3][..bin_len - bin.len()])?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn written_chunks_split_again_and_lengths_are_checked() {
        let mut out = Vec::new();
        write(&mut out, b"{\"a\":1}", b"\x01\x02\x03\x04\x05").unwrap();
        assert_eq!(out.len() % 4, 0);
        let chunks = split(Path::new("x.glb"), &out).unwrap();
        assert_eq!(chunks.json, b"{\"a\":1} ");
        assert_eq!(chunks.bin.unwrap(), b"\x01\x02\x03\x04\x05\0\0\0");
        let mut lying = out.clone();
        lying[8] = lying[8].wrapping_add(4);
        let e = split(Path::new("x.glb"), &lying).unwrap_err().to_string();
        assert!(
            e.contains("declares") && e.contains("but the file has"),
            "{e}"
        );
        let mut cut = out.clone();
        cut.truncate(24);
        cut[8..12].copy_from_slice(&24u32.to_le_bytes());
        let e = split(Path::new("x.glb"), &cut).unwrap_err().to_string();
        assert!(e.contains("chunk declares"), "{e}");
        let e = split(Path::new("x.glb"), b"glTF\x02\0")
            .unwrap_err()
            .to_string();
        assert!(e.contains("needs 12 bytes"), "{e}");
    }
}
