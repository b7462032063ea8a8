//! PLY reading and writing on the real scans in ../shared/data, round trips, and robustness.

use glam::{DVec2, DVec3};
use proptest::prelude::*;
use scanmill::mesh::ply::{self, MISSING_TEXTURE_PREFIX, PlyEncoding};
use scanmill::mesh::{Corner, LoadOptions, LoadReport, Material, Mesh, MeshBuilder, MeshError};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

mod common;

use common::{DATA, read_bytes as bytes_of};

const ENCODINGS: [PlyEncoding; 3] = [
    PlyEncoding::Ascii,
    PlyEncoding::BinaryLittleEndian,
    PlyEncoding::BinaryBigEndian,
];

fn load(rel: &str) -> Result<(Mesh, LoadReport), MeshError> {
    let path = Path::new(DATA).join(rel);
    ply::read(&path, &bytes_of(&path), &LoadOptions::default())
}

fn ply_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.to_string_lossy();
        if path.is_dir() {
            ply_files(&path, out);
        } else if name.ends_with(".ply") || name.ends_with(".ply.gz") {
            out.push(path);
        }
    }
}

/// (file, vertices kept, triangles kept) from data/SOURCES.md, after the load-time repairs.
const EXPECTED: &[(&str, usize, usize)] = &[
    (
        "ply_texcoords/artec_pepper_multitexture.ply",
        14_980,
        29_956,
    ),
    (
        "ply_texcoords/openmvs_sceaux_castle_scene_mesh_texture.ply",
        7_378,
        14_709,
    ),
    (
        "raw_photogrammetry/openmvs_sceaux_castle_scene_mesh_refine.ply",
        87_685,
        174_899,
    ),
    (
        "raw_photogrammetry/ggg_sfm_Angel_decimated.ply",
        18_412,
        35_804,
    ),
    // 7 degenerate faces (6 with a repeated index, 1 of zero area), 3 duplicate positions.
    (
        "raw_photogrammetry/ggg_sfm_birdBath_decimated.ply",
        18_793,
        35_072,
    ),
    (
        "raw_photogrammetry/ggg_sfm_blackVase_decimated.ply",
        17_337,
        31_366,
    ),
    (
        "untextured/misc_scans/igea_cyberware_tristrips.ply",
        134_345,
        268_686,
    ),
    (
        "untextured/misc_scans/igea_cyberware_trilist_DERIVED.ply.gz",
        134_345,
        268_686,
    ),
    (
        "untextured/misc_scans/stanford_lucy_100k.ply",
        50_002,
        100_000,
    ),
    ("untextured/misc_scans/xyzrgb_dragon_20k.ply", 9_994, 19_984),
    // 1,113 unreferenced vertices dropped.
    ("untextured/stanford_bunny/bun_zipper.ply", 34_834, 69_451),
    // 87 / 40 duplicate faces dropped.
    (
        "untextured/stanford_bunny/bun_zipper_res2.ply",
        8_146,
        16_214,
    ),
    ("untextured/stanford_bunny/bun_zipper_res4.ply", 453, 908),
    (
        "untextured/stanford_bunny_range_scans/bun000_grid_triangulated_DERIVED.ply",
        40_245,
        79_312,
    ),
];

const POINT_CLOUDS: &[&str] = &[
    "untextured/stanford_bunny_range_scans/bun000.ply",
    "untextured/stanford_bunny_range_scans/bun045.ply",
];

#[test]
fn every_ply_in_the_data_loads_or_fails_clearly() {
    let mut files = Vec::new();
    ply_files(Path::new(DATA), &mut files);
    files.sort();
    assert!(files.len() >= 16, "found only {files:?}");
    for path in &files {
        let rel = path
            .strip_prefix(DATA)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let result = load(&rel);
        if POINT_CLOUDS.contains(&rel.as_str()) {
            let e = result.unwrap_err();
            assert!(matches!(e, MeshError::NoTriangles { .. }), "{rel}: {e}");
            assert!(
                e.to_string().contains("no face element (it has: vertex 40"),
                "{e}"
            );
            assert!(e.to_string().contains("range_grid 204800"), "{e}");
            continue;
        }
        let (mesh, report) = result.unwrap_or_else(|e| panic!("{rel}: {e}"));
        mesh.check_invariants().unwrap();
        let &(_, v, t) = EXPECTED
            .iter()
            .find(|(name, _, _)| *name == rel)
            .unwrap_or_else(|| panic!("{rel} is not in the expected table"));
        assert_eq!(
            (mesh.vertex_count(), mesh.triangle_count()),
            (v, t),
            "{rel}"
        );
        assert!(report.format.starts_with("ply "));
    }
}

#[test]
fn bunny_counts() {
    let (_, report) = load("untextured/stanford_bunny/bun_zipper.ply").unwrap();
    assert_eq!(report.file_vertices, 35_947);
    assert_eq!(report.file_faces, 69_451);
    assert_eq!(report.dropped_unreferenced_vertices, 1_113);
    assert_eq!(
        report.skipped,
        vec!["vertex.confidence", "vertex.intensity"]
    );
}

#[test]
fn tristrips_unroll_to_the_derived_triangle_list() {
    let (strips, report) = load("untextured/misc_scans/igea_cyberware_tristrips.ply").unwrap();
    assert_eq!(report.strip_triangles, 268_686);
    let (list, _) = load("untextured/misc_scans/igea_cyberware_trilist_DERIVED.ply.gz").unwrap();
    assert_eq!(strips.positions, list.positions);
    let tris = |m: &Mesh| -> Vec<[u32; 3]> {
        (0..m.triangle_count())
            .map(|t| m.triangle_vertices(t))
            .collect()
    };
    assert_eq!(tris(&strips), tris(&list));
}

/// Edges whose faces use different texture coordinates at the edge's ends.
fn seam_edges(mesh: &Mesh) -> (usize, usize) {
    let mut edges: HashMap<(u32, u32), Vec<[u64; 4]>> = HashMap::new();
    for t in 0..mesh.triangle_count() {
        let v = mesh.triangle_vertices(t);
        let uv: Vec<DVec2> = mesh.triangles[t]
            .iter()
            .map(|&w| mesh.wedge_texcoord(w).unwrap())
            .collect();
        for k in 0..3 {
            let (a, b) = (k, (k + 1) % 3);
            let (a, b) = if v[a] < v[b] { (a, b) } else { (b, a) };
            let key = [uv[a].x, uv[a].y, uv[b].x, uv[b].y].map(f64::to_bits);
            edges.entry((v[a], v[b])).or_default().push(key);
        }
    }
    let seams = edges
        .values()
        .filter(|uvs| uvs.iter().any(|k| *k != uvs[0]))
        .count();
    (seams, edges.len())
}

#[test]
fn openmvs_per_face_uvs() {
    let (mesh, report) =
        load("ply_texcoords/openmvs_sceaux_castle_scene_mesh_texture.ply").unwrap();
    assert_eq!(mesh.triangle_count(), 14_709);
    assert_eq!(report.file_texcoords, 3 * 14_709);
    assert!(mesh.wedges.iter().all(|w| w.texcoord.is_some()));
    assert_eq!(seam_edges(&mesh).0, 1_010);
    // The texture is missing: one material, no texture, its name kept.
    assert_eq!(mesh.materials.len(), 1);
    assert!(mesh.materials[0].diffuse_texture.is_none());
    assert_eq!(
        mesh.materials[0].other_statements,
        vec![format!("{MISSING_TEXTURE_PREFIX}scene_mesh_texture0.png")]
    );
}

#[test]
fn artec_pepper_every_edge_is_a_seam() {
    let (mesh, report) = load("ply_texcoords/artec_pepper_multitexture.ply").unwrap();
    assert_eq!(mesh.triangle_count(), 29_956);
    assert_eq!(report.file_texcoords, 89_868);
    assert_eq!(seam_edges(&mesh), (44_934, 44_934));
}

/// Per-corner comparison: positions bit-exact, texture coordinates to f32, normals to f32,
/// materials and colours exact, triangles in the same order.
fn assert_same_corners(a: &Mesh, b: &Mesh, what: &str) {
    assert_eq!(a.triangle_count(), b.triangle_count(), "{what}");
    let bits = |p: DVec3| p.to_array().map(f64::to_bits);
    for t in 0..a.triangle_count() {
        for k in 0..3 {
            let (wa, wb) = (a.triangles[t][k], b.triangles[t][k]);
            let (va, vb) = (a.wedges[wa as usize].vertex, b.wedges[wb as usize].vertex);
            assert_eq!(
                bits(a.positions[va as usize]),
                bits(b.positions[vb as usize]),
                "{what}: triangle {t} corner {k}"
            );
            let uv = |m: &Mesh, w| m.wedge_texcoord(w).map(|uv| uv.as_vec2());
            assert_eq!(uv(a, wa), uv(b, wb), "{what}: triangle {t} corner {k} uv");
            let normal = |m: &Mesh, w: u32| {
                m.wedges[w as usize]
                    .normal
                    .map(|n| m.normals[n as usize].as_vec3())
            };
            assert_eq!(normal(a, wa), normal(b, wb), "{what}: triangle {t} normal");
            if !a.colors.is_empty() {
                assert_eq!(
                    a.colors[va as usize], b.colors[vb as usize],
                    "{what}: colour"
                );
            }
        }
        assert_eq!(
            a.triangle_material(t),
            b.triangle_material(t),
            "{what}: material {t}"
        );
    }
    assert_eq!(a.materials, b.materials, "{what}");
    assert_eq!(a.colors.is_empty(), b.colors.is_empty(), "{what}");
}

fn round_trip(mesh: &Mesh, dir: &Path, encoding: PlyEncoding) -> Mesh {
    let path = dir.join(format!("out_{encoding:?}.ply"));
    let written = ply::write(mesh, &path, encoding).unwrap();
    assert_eq!(written[0], path);
    let (back, _) = ply::read(
        &path,
        &std::fs::read(&path).unwrap(),
        &LoadOptions::default(),
    )
    .unwrap_or_else(|e| panic!("reading back {encoding:?}: {e}"));
    back
}

#[test]
fn real_scans_round_trip_in_every_encoding() {
    let dir = tempfile::tempdir().unwrap();
    for rel in [
        "ply_texcoords/artec_pepper_multitexture.ply",
        "ply_texcoords/openmvs_sceaux_castle_scene_mesh_texture.ply",
        "untextured/stanford_bunny/bun_zipper_res2.ply",
    ] {
        let (mesh, _) = load(rel).unwrap();
        for encoding in ENCODINGS {
            let back = round_trip(&mesh, dir.path(), encoding);
            assert_same_corners(&mesh, &back, &format!("{rel} {encoding:?}"));
        }
    }
}

/// A random height-field grid with seams: some corners get their own texture coordinate, so
/// vertices have several wedges. Values are f32-representable where the file stores f32.
#[derive(Debug, Clone)]
struct Spec {
    w: usize,
    h: usize,
    heights: Vec<f64>,
    seam_corners: Vec<bool>,
    colors: Option<Vec<[u8; 4]>>,
    materials: usize,
    face_materials: Vec<u32>,
    normals: bool,
}

fn spec() -> impl Strategy<Value = Spec> {
    (2usize..6, 2usize..6).prop_flat_map(|(w, h)| {
        let faces = 2 * (w - 1) * (h - 1);
        (
            proptest::collection::vec(-1e3f64..1e3, w * h),
            proptest::collection::vec(proptest::bool::weighted(0.3), faces * 3),
            proptest::option::of(proptest::collection::vec(any::<[u8; 4]>(), w * h)),
            0usize..4,
            proptest::collection::vec(0u32..3, faces),
            any::<bool>(),
        )
            .prop_map(
                move |(heights, seam_corners, colors, materials, face_materials, normals)| Spec {
                    w,
                    h,
                    heights,
                    seam_corners,
                    colors,
                    materials,
                    face_materials,
                    normals,
                },
            )
    })
}

fn build(spec: &Spec) -> Mesh {
    let mut b = MeshBuilder::new(Path::new("gen.ply"), "test");
    let (w, h) = (spec.w, spec.h);
    for j in 0..h {
        for i in 0..w {
            // Irrational-ish offsets so that positions use all 52 mantissa bits.
            b.positions.push(DVec3::new(
                i as f64 + 0.1 * (j as f64).sqrt(),
                j as f64 * std::f64::consts::PI,
                spec.heights[j * w + i],
            ));
            let uv = DVec2::new(i as f64 / w as f64, j as f64 / 7.0)
                .as_vec2()
                .as_dvec2();
            b.texcoords.push(uv);
            if spec.normals {
                b.normals
                    .push(DVec3::new(0.25, j as f64 / 3.0, 1.0).as_vec3().as_dvec3());
            }
        }
    }
    if let Some(colors) = &spec.colors {
        b.colors = colors.clone();
    }
    let mut corner_index = 0;
    for j in 0..h - 1 {
        for i in 0..w - 1 {
            let a = (j * w + i) as u32;
            let quad = [a, a + 1, a + 1 + w as u32, a + w as u32];
            for tri in [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] {
                let corners = tri.map(|v| {
                    let seam = spec.seam_corners[corner_index];
                    corner_index += 1;
                    let texcoord = if seam {
                        let base = b.texcoords[v as usize];
                        b.texcoords.push(
                            (base + DVec2::new(0.5, corner_index as f64 / 64.0))
                                .as_vec2()
                                .as_dvec2(),
                        );
                        b.texcoords.len() as u32 - 1
                    } else {
                        v
                    };
                    Corner {
                        vertex: v,
                        texcoord: Some(texcoord),
                        normal: spec.normals.then_some(v),
                    }
                });
                b.faces.push(corners);
            }
        }
    }
    if spec.materials > 0 {
        b.materials = (0..spec.materials)
            .map(|m| Material {
                name: format!("texture{m}"),
                other_statements: vec![format!("{MISSING_TEXTURE_PREFIX}tex {m}.png")],
                ..Material::default()
            })
            .collect();
        b.face_materials = spec
            .face_materials
            .iter()
            .map(|&m| m % spec.materials as u32)
            .collect();
    }
    b.finish(&LoadOptions::default()).unwrap().0
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]
    #[test]
    fn random_meshes_with_seams_round_trip(spec in spec()) {
        let mesh = build(&spec);
        let dir = tempfile::tempdir().unwrap();
        for encoding in ENCODINGS {
            let back = round_trip(&mesh, dir.path(), encoding);
            assert_same_corners(&mesh, &back, &format!("{encoding:?}"));
            // Seams survive: the same number of wedges per vertex.
            prop_assert_eq!(back.wedges.len(), mesh.wedges.len());
        }
    }
}

#[test]
fn random_byte_flips_never_panic() {
    let (mesh, _) = load("untextured/stanford_bunny/bun_zipper_res4.ply").unwrap();
    let mut mesh = mesh;
    mesh.triangles.truncate(12);
    mesh.compact();
    mesh.texcoords = vec![DVec2::new(0.25, 0.5)];
    for w in &mut mesh.wedges {
        w.texcoord = Some(0);
    }
    mesh.materials = vec![Material::default(), Material::default()];
    mesh.triangle_materials = (0..12).map(|t| t % 2).collect();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("small.ply");
    let mut originals = Vec::new();
    for encoding in ENCODINGS {
        ply::write(&mesh, &path, encoding).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        ply::read(&path, &bytes, &LoadOptions::default()).unwrap();
        originals.push(bytes);
    }
    // xorshift: deterministic, no dependency.
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let mut failures = 0;
    for round in 0..600 {
        let mut bytes = originals[round % 3].clone();
        match next() % 4 {
            0 => {
                let cut = (next() as usize) % bytes.len();
                bytes.truncate(cut);
            }
            choice => {
                // Half the flips go to the body only, past the header's checks.
                let body = if choice == 1 {
                    0
                } else {
                    bytes
                        .windows(11)
                        .position(|w| w == b"end_header\n")
                        .unwrap()
                        + 11
                };
                for _ in 0..1 + next() % 6 {
                    let at = body + (next() as usize) % (bytes.len() - body);
                    bytes[at] = next() as u8;
                }
            }
        }
        if ply::read(&path, &bytes, &LoadOptions::default()).is_err() {
            failures += 1;
        }
    }
    // Most mutations hit data values and still load; many must fail; none may panic.
    assert!(failures > 50, "{failures}");
}
