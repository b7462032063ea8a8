//! What the integration tests share: where the real scans are (`../shared/data` beside the
//! checkout, see its SOURCES.md) and loading one. `mod common;` in a test file.
#![allow(dead_code)]

pub mod pg;

use scanmill::mesh::io::load;
use scanmill::mesh::{LoadOptions, Mesh};
use std::path::PathBuf;

/// The folder of the real scans.
pub const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data");

/// The path of `rel` in the real scans' folder.
pub fn data(rel: &str) -> PathBuf {
    PathBuf::from(DATA).join(rel)
}

/// The scan at `rel`, loaded with the default options; a scan that does not load fails the
/// test, naming it.
pub fn scan(rel: &str) -> Mesh {
    scan_with(rel, &LoadOptions::default())
}

/// The scan at `rel` without checking that its textures exist and decode (for tests of
/// geometry on scans whose texture files are not in the data set).
pub fn scan_untextured(rel: &str) -> Mesh {
    let options = LoadOptions {
        check_textures: false,
        ..Default::default()
    };
    scan_with(rel, &options)
}

/// The scan at `rel`, loaded with `options`.
pub fn scan_with(rel: &str, options: &LoadOptions) -> Mesh {
    let path = data(rel);
    load(&path, options)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .0
}

/// The bytes of the file at `path`, decompressed when its name ends in `.gz`.
pub fn read_bytes(path: &std::path::Path) -> Vec<u8> {
    use std::io::Read;
    let raw = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    if path.extension().is_some_and(|e| e == "gz") {
        let mut out = Vec::new();
        flate2::read::GzDecoder::new(&raw[..])
            .read_to_end(&mut out)
            .unwrap();
        out
    } else {
        raw
    }
}

/// Writes the named files into a fresh folder and returns (folder, the first file).
pub fn scan_folder(files: &[(&str, &[u8])]) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    for (name, content) in files {
        let path = dir.path().join(name);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, content).unwrap();
    }
    let first = dir.path().join(files[0].0);
    (dir, first)
}
