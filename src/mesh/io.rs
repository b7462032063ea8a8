//! Loading and saving by file name: the extension picks the format; `.gz` is unpacked
//! transparently on load.
//!
//! Writers write to the path they are given; publishing atomically (temporary name, then
//! rename) is the caller's job.

use super::build::{LoadOptions, LoadReport};
use super::error::{Location, MeshError, Result};
use super::model::Mesh;
use super::obj;
use super::ply::{self, PlyEncoding};
use std::io::Read;
use std::path::{Path, PathBuf};

/// The mesh formats scanmill reads and writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Obj,
    Ply,
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
        _ => return None,
    };
    Some((format, gz))
}

/// Reads a mesh file (`.obj`, `.ply`, either optionally `.gz`).
pub fn load(path: &Path, options: &LoadOptions) -> Result<(Mesh, LoadReport)> {
    let (format, gz) = format_of(path).ok_or_else(|| MeshError::UnknownFormat {
        path: path.to_path_buf(),
    })?;
    let raw = std::fs::read(path).map_err(|e| MeshError::io(path, e))?;
    let bytes = if gz { gunzip(path, &raw)? } else { raw };
    match format {
        Format::Obj => {
            // The text of a large OBJ is bigger than the mesh: free it before welding.
            let builder = obj::parse(path, &bytes, options)?;
            drop(bytes);
            builder.finish(options)
        }
        Format::Ply => ply::read(path, &bytes, options),
    }
}

fn gunzip(path: &Path, compressed: &[u8]) -> Result<Vec<u8>> {
    let mut bytes = Vec::with_capacity(compressed.len() * 4);
    flate2::read::MultiGzDecoder::new(compressed)
        .read_to_end(&mut bytes)
        .map_err(|e| {
            MeshError::malformed(
                path,
                Location::Header,
                format!("not a valid gzip file (corrupt or truncated): {e}"),
            )
        })?;
    Ok(bytes)
}

/// How to save.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SaveOptions {
    pub ply_encoding: PlyEncoding,
}

/// Writes a mesh in the format its extension names (`.obj` with its MTL and textures, or
/// `.ply`). Returns every file written. Compressed output is not supported.
pub fn save(mesh: &Mesh, path: &Path, options: &SaveOptions) -> Result<Vec<PathBuf>> {
    match format_of(path) {
        Some((Format::Obj, false)) => obj::write(mesh, path),
        Some((Format::Ply, false)) => ply::write(mesh, path, options.ply_encoding),
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
        assert_eq!(format_of(Path::new("b.stl")), None);
        assert_eq!(format_of(Path::new("b.gz")), None);
        assert_eq!(format_of(Path::new("obj")), None);
    }

    #[test]
    fn unknown_extension_is_unknown_format() {
        let err = load(Path::new("/nonexistent/x.stl"), &LoadOptions::default()).unwrap_err();
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
