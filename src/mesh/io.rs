//! Loading and saving by file name: the extension picks the format; `.gz` is unpacked
//! transparently on load, within `limits.max_decompressed_bytes` and `limits.max_gzip_ratio`.
//!
//! Writers write to the path they are given; publishing atomically (temporary name, then
//! rename) is the caller's job.

use super::build::{LoadOptions, LoadReport};
use super::error::{Location, MeshError, Result};
use super::files;
use super::gltf;
use super::limits::{InputLimits, Limit};
use super::model::Mesh;
use super::obj;
use super::ply::{self, PlyEncoding};
use super::stl;
use std::io::Read;
use std::path::{Path, PathBuf};

/// The mesh formats scanmill reads and writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Obj,
    Ply,
    Stl,
    /// glTF 2.0 as JSON (`.gltf`); read only.
    Gltf,
    /// glTF 2.0 binary (`.glb`).
    Glb,
}

/// The format named by a path's extension (case-insensitive), looking under a `.gz`, and
/// whether the file is gzip-compressed.
pub fn format_of(path: &Path) -> Option<(Format, bool)> {
    let name = path.file_name()?.to_string_lossy().to_ascii_lowercase();
    let (inner, gz) = match name.strip_suffix(".gz") {
        Some(inner) => (inner, true),
        None => (name.as_str(), false),
    };
    let format = match Path::new(inner).extension()?.to_str()? {
        "obj" => Format::Obj,
        "ply" => Format::Ply,
        "stl" => Format::Stl,
        "gltf" => Format::Gltf,
        "glb" => Format::Glb,
        _ => return None,
    };
    Some((format, gz))
}

/// Reads a mesh file (`.obj`, `.ply`, `.stl`, `.gltf`, `.glb`, any optionally `.gz`). Only a regular file is
/// read (a FIFO or device is refused at once), within `options.limits`.
pub fn load(path: &Path, options: &LoadOptions) -> Result<(Mesh, LoadReport)> {
    let (format, gz) = format_of(path).ok_or_else(|| MeshError::UnknownFormat {
        path: path.to_path_buf(),
    })?;
    let limits = &options.limits;
    let raw = files::read_whole(path, limits.max_file_bytes, Limit::FileBytes)?;
    let bytes = if gz { gunzip(path, &raw, limits)? } else { raw };
    match format {
        Format::Obj => {
            // The text of a large OBJ is bigger than the mesh: free it before welding.
            let (builder, textures) = obj::parse_unchecked(path, &bytes, options)?;
            drop(bytes);
            obj::finish(builder, textures, options)
        }
        Format::Ply => ply::read(path, &bytes, options),
        Format::Stl => stl::read(path, &bytes, options),
        Format::Gltf | Format::Glb => gltf::read(path, &bytes, options),
    }
}

/// Decompresses within the smaller of `limits.max_decompressed_bytes` and
/// `limits.max_gzip_ratio` times the compressed size, stopping one byte past it: a small
/// file that expands enormously costs no more than the limit.
fn gunzip(path: &Path, compressed: &[u8], limits: &InputLimits) -> Result<Vec<u8>> {
    let by_ratio = (compressed.len() as u64).saturating_mul(limits.max_gzip_ratio);
    let (cap, limit) = if by_ratio < limits.max_decompressed_bytes {
        (by_ratio, Limit::GzipRatio)
    } else {
        (limits.max_decompressed_bytes, Limit::DecompressedBytes)
    };
    // Mesh files compress 2-4 times; the reservation never exceeds the cap.
    let mut bytes = Vec::with_capacity((compressed.len() as u64 * 4).min(cap) as usize);
    flate2::read::MultiGzDecoder::new(compressed)
        .take(cap.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| {
            MeshError::malformed(
                path,
                Location::Header,
                format!("not a valid gzip file (corrupt or truncated): {e}"),
            )
        })?;
    if bytes.len() as u64 > cap {
        let what = match limit {
            Limit::GzipRatio => format!(
                "decompressed size (above {cap} bytes, {}× the {} compressed bytes)",
                limits.max_gzip_ratio,
                compressed.len()
            ),
            _ => "decompressed size".to_string(),
        };
        return Err(files::too_large(path, what, limit, limit.value(limits)));
    }
    Ok(bytes)
}

/// How to save.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SaveOptions {
    pub ply_encoding: PlyEncoding,
}

/// Writes a mesh in the format its extension names (`.obj` with its MTL and textures,
/// `.ply`, or `.glb` with its textures inside). Returns every file written. Compressed output is not supported.
pub fn save(mesh: &Mesh, path: &Path, options: &SaveOptions) -> Result<Vec<PathBuf>> {
    save_reserving(mesh, path, options, &[])
}

/// [`save`], keeping the names of copied textures apart from `reserved`: files the caller
/// writes into the same folder (a preview, a sidecar), which no copy may ever overwrite.
/// A failure to write is [`MeshError::Write`].
pub fn save_reserving(
    mesh: &Mesh,
    path: &Path,
    options: &SaveOptions,
    reserved: &[String],
) -> Result<Vec<PathBuf>> {
    match format_of(path) {
        Some((Format::Obj, false)) => obj::write_reserving(mesh, path, reserved),
        Some((Format::Ply, false)) => {
            ply::write_reserving(mesh, path, options.ply_encoding, reserved)
        }
        Some((Format::Glb, false)) => gltf::write(mesh, path),
        _ => Err(MeshError::UnknownFormat {
            path: path.to_path_buf(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_by_extension() {
        assert_eq!(format_of(Path::new("a/b.OBJ")), Some((Format::Obj, false)));
        assert_eq!(format_of(Path::new("b.obj.gz")), Some((Format::Obj, true)));
        assert_eq!(format_of(Path::new("b.ply.GZ")), Some((Format::Ply, true)));
        assert_eq!(format_of(Path::new("b.STL")), Some((Format::Stl, false)));
        assert_eq!(format_of(Path::new("b.glb")), Some((Format::Glb, false)));
        assert_eq!(format_of(Path::new("b.gltf")), Some((Format::Gltf, false)));
        assert_eq!(format_of(Path::new("b.fbx")), None);
        assert_eq!(format_of(Path::new("b.gz")), None);
        assert_eq!(format_of(Path::new("obj")), None);
    }

    #[test]
    fn unknown_extension_is_unknown_format() {
        let err = load(Path::new("/nonexistent/x.fbx"), &LoadOptions::default()).unwrap_err();
        assert!(matches!(err, MeshError::UnknownFormat { .. }));
    }

    #[test]
    fn corrupt_gzip_is_a_clear_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.obj.gz");
        std::fs::write(&path, b"\x1f\x8b\x08\x00garbage").unwrap();
        let err = load(&path, &LoadOptions::default()).unwrap_err();
        assert!(matches!(err, MeshError::Malformed { .. }), "{err}");
        assert!(err.to_string().contains("gzip"), "{err}");
        assert!(err.to_string().contains("x.obj.gz"), "{err}");
    }

    #[test]
    fn missing_file_is_io() {
        let err = load(Path::new("/nonexistent/x.obj"), &LoadOptions::default()).unwrap_err();
        assert!(matches!(err, MeshError::Io { .. }));
    }
}
