//! STL and glTF/GLB on the real scans in ../shared/data (issue #28): GLB round trips keep
//! positions, per-corner texture coordinates and seams; STL → PLY keeps every triangle; every
//! GLB scanmill writes passes the Khronos glTF validator.
//!
//! "Bit-exactly" for GLB: glTF stores positions as 32-bit floats, so a position comes back as
//! exactly the `f32` nearest the input's `f64` (bit for bit, compared as `f64`), never
//! anything else. Texture coordinates are flipped (`1 - v`) and stored as `f32`, so they come
//! back within 1.2e-7 (two `f32` steps near 1). The seams, the grouping of corners into
//! vertices and into wedges, must come back identical.

mod common;

use common::data;
use scanmill::mesh::{LoadOptions, Mesh, load, save};
use std::path::Path;
use std::process::Command;

/// The textured scans, with the texture for those whose OBJ names none.
const TEXTURED: &[(&str, Option<&str>)] = &[
    ("textured/james_face_stereo_capture/james.obj", None),
    (
        "textured/lee_perry_smith_head/LeePerrySmith_converted.obj",
        None,
    ),
    (
        "textured/nefertiti_bust_fraunhofer/Nefertiti_converted.obj",
        None,
    ),
    ("textured/esp32cam_meshroom_raw/texturedMesh.obj", None),
    (
        "textured/facefuns_di3d_face/example.obj",
        Some("textured/facefuns_di3d_face/example.png"),
    ),
    ("textured/pizza_rigsters_photogrammetry/pizza.obj", None),
    (
        "textured/spot_keenan_crane/spot_triangulated.obj",
        Some("textured/spot_keenan_crane/spot_texture.png"),
    ),
    (
        "textured/smithsonian_usnm1145291_draco/usnm1145291_converted.obj.gz",
        None,
    ),
    (
        "textured/ict_facekit_neutral/generic_neutral_mesh.obj",
        None,
    ),
];

const TEXTURED_PLY: &[&str] = &[
    "ply_texcoords/artec_pepper_multitexture.ply",
    "ply_texcoords/openmvs_sceaux_castle_scene_mesh_texture.ply",
];

const GLB: &[&str] = &[
    "textured/nefertiti_bust_fraunhofer/Nefertiti.glb",
    "textured/lee_perry_smith_head/LeePerrySmith.glb",
];

fn load_scan(rel: &str, texture: Option<&str>) -> Mesh {
    let options = LoadOptions {
        texture_override: texture.map(data),
        ..LoadOptions::default()
    };
    common::scan_with(rel, &options)
}

fn reload(path: &Path) -> Mesh {
    load(path, &LoadOptions::default())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .0
}

/// The order a GLB lists `mesh`'s triangles in: grouped by material (one primitive each),
/// file order within a group.
fn glb_order(mesh: &Mesh) -> Vec<usize> {
    let mut order: Vec<usize> = (0..mesh.triangle_count()).collect();
    order.sort_by_key(|&t| mesh.triangle_material(t));
    order
}

/// Records that `a` corresponds to `b`; panics if `a` already corresponds to something else.
fn corresponds(map: &mut [u32], a: u32, b: u32, what: &str) {
    let slot = &mut map[a as usize];
    if *slot == u32::MAX {
        *slot = b;
    }
    assert_eq!(*slot, b, "{what} {a} split in two ({} and {b})", *slot);
}

/// `back` is `orig` through a GLB: triangle `order[t]` of `orig` is triangle `t` of `back`,
/// with the same corner positions (as `f32`, bit for bit), texture coordinates (two f32 steps)
/// and the same vertices and wedges (the correspondence is one-to-one).
fn assert_kept(name: &str, orig: &Mesh, back: &Mesh, order: &[usize]) {
    assert_eq!(
        back.triangle_count(),
        orig.triangle_count(),
        "{name}: triangles"
    );
    let mut vertices = vec![u32::MAX; orig.vertex_count()];
    let mut wedges = vec![u32::MAX; orig.wedges.len()];
    let mut worst_uv = 0.0f64;
    for (tb, &ta) in order.iter().enumerate() {
        for k in 0..3 {
            let (wa, wb) = (orig.triangles[ta][k], back.triangles[tb][k]);
            let (va, vb) = (
                orig.wedges[wa as usize].vertex,
                back.wedges[wb as usize].vertex,
            );
            let expected = orig.positions[va as usize].as_vec3().as_dvec3();
            let got = back.positions[vb as usize];
            assert_eq!(
                expected.to_array().map(f64::to_bits),
                got.to_array().map(f64::to_bits),
                "{name}: triangle {ta} corner {k}: {got} is not {expected}"
            );
            match (orig.wedge_texcoord(wa), back.wedge_texcoord(wb)) {
                (Some(a), Some(b)) => {
                    // Two f32 steps at the coordinate's magnitude (UDIM tiles go past 1).
                    let step = f64::from(f32::EPSILON) * (1.0 + a.abs().max_element());
                    worst_uv = worst_uv.max((a - b).abs().max_element() / step);
                }
                (None, None) => {}
                (a, b) => panic!("{name}: triangle {ta} corner {k}: texcoord {a:?} became {b:?}"),
            }
            corresponds(&mut vertices, va, vb, "vertex");
            corresponds(&mut wedges, wa, wb, "wedge");
        }
    }
    assert!(
        worst_uv <= 2.0,
        "{name}: texture coordinates moved by {worst_uv} f32 steps"
    );
    // A map onto every vertex (wedge) of `back` between sets of equal size is one-to-one.
    assert_eq!(back.vertex_count(), orig.vertex_count(), "{name}: vertices");
    assert_eq!(
        back.wedges.len(),
        orig.wedges.len(),
        "{name}: wedges (seams)"
    );
}

#[test]
fn obj_to_glb_to_obj_keeps_positions_texcoords_and_seams() {
    let dir = tempfile::tempdir().unwrap();
    for (rel, texture) in TEXTURED {
        let orig = load_scan(rel, *texture);
        let glb = dir.path().join("scan.glb");
        save(&orig, &glb, &Default::default()).unwrap();
        let through_glb = reload(&glb);
        let obj = dir.path().join("back.obj");
        save(&through_glb, &obj, &Default::default()).unwrap();
        let back = reload(&obj);
        assert_kept(rel, &orig, &back, &glb_order(&orig));
        // The texture came through the GLB byte for byte.
        let textures = |m: &Mesh| -> Vec<Vec<u8>> {
            m.materials
                .iter()
                .filter_map(|m| m.diffuse_texture.as_ref())
                .map(|t| std::fs::read(&t.path).unwrap())
                .collect()
        };
        assert_eq!(textures(&orig), textures(&back), "{rel}: texture bytes");
    }
}

#[test]
fn ply_to_glb_keeps_positions_texcoords_and_seams() {
    let dir = tempfile::tempdir().unwrap();
    for rel in TEXTURED_PLY {
        let orig = load_scan(rel, None);
        let glb = dir.path().join("scan.glb");
        save(&orig, &glb, &Default::default()).unwrap();
        assert_kept(rel, &orig, &reload(&glb), &glb_order(&orig));
    }
}

#[test]
fn real_glb_files_load_welded_with_their_embedded_texture() {
    // Counts from data/SOURCES.md (welded by exact position); Nefertiti also has 3 duplicate
    // faces, which the repair rules drop.
    let (nefertiti, report) = load(&data(GLB[0]), &LoadOptions::default()).unwrap();
    assert_eq!(
        (nefertiti.vertex_count(), report.file_faces),
        (10_000, 19_482)
    );
    assert_eq!(report.dropped_duplicate_faces, 3);
    let texture = nefertiti.materials[0].diffuse_texture.as_ref().unwrap();
    assert_eq!(texture.size, Some((2048, 2048)));
    let extracted = std::fs::read(data(
        "textured/nefertiti_bust_fraunhofer/material0_basecolor.jpg",
    ))
    .unwrap();
    assert_eq!(&*texture.embedded.as_ref().unwrap().0, extracted.as_slice());
    let (lee, _) = load(&data(GLB[1]), &LoadOptions::default()).unwrap();
    assert_eq!((lee.vertex_count(), lee.triangle_count()), (8_844, 17_684));
}

/// A binary STL of `mesh`'s triangles (positions as `f32`).
fn binary_stl(mesh: &Mesh) -> Vec<u8> {
    let mut out = vec![b' '; 80];
    out.extend_from_slice(&(mesh.triangle_count() as u32).to_le_bytes());
    for t in 0..mesh.triangle_count() {
        out.extend_from_slice(&[0u8; 12]);
        for p in mesh.triangle_positions(t) {
            out.extend(p.as_vec3().to_array().iter().flat_map(|v| v.to_le_bytes()));
        }
        out.extend_from_slice(&[0, 0]);
    }
    out
}

#[test]
fn stl_to_ply_keeps_every_triangle() {
    let dir = tempfile::tempdir().unwrap();
    for rel in [
        "untextured/stanford_bunny/bun_zipper.ply",
        "untextured/misc_scans/stanford_lucy_100k.ply",
    ] {
        let orig = load_scan(rel, None);
        let stl = dir.path().join("scan.stl");
        std::fs::write(&stl, binary_stl(&orig)).unwrap();
        let (from_stl, report) = load(&stl, &LoadOptions::default()).unwrap();
        assert_eq!(report.file_faces, orig.triangle_count(), "{rel}");
        assert_eq!(
            report.welded_vertices,
            3 * orig.triangle_count() - orig.vertex_count(),
            "{rel}"
        );
        let ply = dir.path().join("back.ply");
        save(&from_stl, &ply, &Default::default()).unwrap();
        let back = reload(&ply);
        let order: Vec<usize> = (0..orig.triangle_count()).collect();
        assert_kept(rel, &orig, &back, &order);
    }
}

/// Runs the Khronos validator on `file`: its exit code (0 valid, 1 errors) and summary.
/// Panics if it cannot run: the validator is part of the test setup (`.ci/run` installs
/// node, npm and the `gltf-validator` package), never a reason to skip.
fn run_validator(file: &Path) -> (Option<i32>, String) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/gltf_support/validate.cjs");
    let npm_root = Command::new("npm")
        .args(["root", "-g"])
        .output()
        .unwrap_or_else(|e| {
            panic!("npm is needed to find gltf-validator ({e}); .ci/run installs it")
        });
    let out = Command::new("node")
        .arg(&script)
        .arg(file)
        .env(
            "NODE_PATH",
            String::from_utf8_lossy(&npm_root.stdout).trim(),
        )
        .output()
        .unwrap_or_else(|e| {
            panic!("node is needed to run gltf-validator ({e}); .ci/run installs it")
        });
    assert!(
        out.status.code() != Some(2),
        "the validator cannot run: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
    )
}

/// The validator's summary of `file`; panics if it reports any error.
fn validate(file: &Path) -> String {
    let (code, report) = run_validator(file);
    assert_eq!(
        code,
        Some(0),
        "{}: validator errors: {report}",
        file.display()
    );
    report
}

#[test]
fn every_glb_written_from_the_real_scans_passes_the_khronos_validator() {
    let dir = tempfile::tempdir().unwrap();
    let mut scans: Vec<(&str, Option<&str>)> = TEXTURED.to_vec();
    scans.extend(TEXTURED_PLY.iter().chain(GLB).map(|r| (*r, None)));
    // And one with vertex colours (COLOR_0).
    scans.push(("untextured/misc_scans/xyzrgb_dragon_20k.ply", None));
    let mut validated = 0;
    for (rel, texture) in scans {
        let mesh = load_scan(rel, texture);
        let glb = dir.path().join(format!("scan{validated}.glb"));
        save(&mesh, &glb, &Default::default()).unwrap();
        let report = validate(&glb);
        assert!(report.contains("\"numErrors\":0"), "{rel}: {report}");
        validated += 1;
    }
    assert_eq!(
        validated,
        TEXTURED.len() + TEXTURED_PLY.len() + GLB.len() + 1
    );
}

#[test]
fn the_validator_catches_a_broken_glb() {
    // The check itself can fail: a GLB whose index points past its vertices is an error.
    let dir = tempfile::tempdir().unwrap();
    let mesh = load_scan("untextured/stanford_bunny/bun_zipper_res4.ply", None);
    let glb = dir.path().join("bad.glb");
    save(&mesh, &glb, &Default::default()).unwrap();
    let mut bytes = std::fs::read(&glb).unwrap();
    // The last four bytes of the binary chunk are the last index (u32).
    let n = bytes.len();
    bytes[n - 4..].copy_from_slice(&u32::MAX.to_le_bytes());
    std::fs::write(&glb, &bytes).unwrap();
    let (code, report) = run_validator(&glb);
    assert_eq!(code, Some(1), "{report}");
    assert!(report.contains("ACCESSOR_INDEX_OOB"), "{report}");
}
