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

/// Runs the recipe `text` (TOML) on `mesh` under `limits`, as `scanmill process` runs it
/// after the load; a recipe that does not parse or run fails the test.
pub fn run_recipe_text(
    text: &str,
    mesh: &mut Mesh,
    limits: &scanmill::mesh::InputLimits,
) -> scanmill::recipe::runner::RunOutcome {
    let recipe = scanmill::recipe::Recipe::from_toml(text, std::path::Path::new("r.toml"))
        .unwrap_or_else(|e| panic!("{text}: {e}"));
    let progress = scanmill::recipe::runner::NoProgress;
    scanmill::recipe::runner::run_recipe(&recipe, mesh, limits, &progress, 0, 1)
        .unwrap_or_else(|e| panic!("{text}: {e}"))
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

/// The centroid of triangle `t` of `m`.
pub fn centroid(m: &Mesh, t: usize) -> glam::DVec3 {
    m.triangle_positions(t).iter().sum::<glam::DVec3>() / 3.0
}

/// The triangles of `out` that face against `input`: against the input triangle closest to
/// their centroid (the metrics' reading, and the rule the remesher's repair pass works by)
/// and against every other input triangle as close (at a sharp edge two are, and which one
/// a search finds is arbitrary).
pub fn faces_against(input: &Mesh, out: &Mesh) -> Vec<usize> {
    let index = scanmill::metrics::surface::SurfaceIndex::new(input, "input").unwrap();
    let tie = 1e-9 * input.bounding_box_diagonal();
    let distance = |p: glam::DVec3, u: usize| {
        let [a, b, c] = input.triangle_positions(u);
        scanmill::geom::closest_on_triangle(p, a, b, c)
            .0
            .distance(p)
    };
    (0..out.triangles.len())
        .filter(|&t| {
            let c = centroid(out, t);
            let n = out.triangle_cross(t);
            let closest = index.closest(c);
            n.dot(input.triangle_cross(closest.on.triangle as usize)) < 0.0
                && (0..input.triangles.len()).all(|u| {
                    n.dot(input.triangle_cross(u)) < 0.0 || distance(c, u) > closest.distance + tie
                })
        })
        .collect()
}
