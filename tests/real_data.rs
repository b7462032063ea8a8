//! Every mesh file in ../shared/data loads (or fails with a specific error), with the counts
//! below, and survives writing and reading back in every format.
//!
//! The expected figures were read with `scanmill inspect` and checked by hand against
//! ../shared/data/SOURCES.md. Where they differ from SOURCES.md, it is because of scanmill's
//! documented load rules:
//! - bit-identical texture coordinates are merged, so split copies of one UV are no seam
//!   (Lee Perry-Smith 375 seams vs 429, ICT 2,021 vs 2,213);
//! - duplicate faces are dropped (bunny res2: 87, res4: 40, Nefertiti: 3, USNM: 7), which
//!   also removes the non-manifold edges they made and opens a few boundary edges;
//! - degenerate faces are dropped and duplicate positions welded (birdBath: 7 and 3).

use scanmill::mesh::ply::PlyEncoding;
use scanmill::mesh::{LoadOptions, Mesh, MeshError, SaveOptions, Topology, load, save};
use std::path::{Path, PathBuf};

mod common;

use common::DATA;

/// (file, vertices, triangles, texture seam edges, boundary edges, boundary loops,
///  components, non-manifold edges)
type Expected = (
    &'static str,
    usize,
    usize,
    usize,
    usize,
    usize,
    usize,
    usize,
);

const EXPECTED: &[Expected] = &[
    (
        "ply_texcoords/artec_pepper_multitexture.ply",
        14980,
        29956,
        44934,
        0,
        0,
        1,
        0,
    ),
    (
        "ply_texcoords/openmvs_sceaux_castle_scene_mesh_texture.ply",
        7378,
        14709,
        1010,
        45,
        1,
        1,
        0,
    ),
    (
        "raw_photogrammetry/ggg_sfm_Angel_decimated.ply",
        18412,
        35804,
        0,
        1413,
        199,
        1,
        41,
    ),
    (
        "raw_photogrammetry/ggg_sfm_birdBath_decimated.ply",
        18793,
        35072,
        0,
        3336,
        329,
        28,
        2,
    ),
    (
        "raw_photogrammetry/ggg_sfm_blackVase_decimated.ply",
        17337,
        31366,
        0,
        4540,
        279,
        27,
        2,
    ),
    (
        "raw_photogrammetry/openmvs_sceaux_castle_scene_mesh_refine.ply",
        87685,
        174899,
        0,
        469,
        1,
        1,
        0,
    ),
    (
        "textured/esp32cam_meshroom_raw/texturedMesh.obj",
        26875,
        53364,
        7117,
        206,
        4,
        50,
        0,
    ),
    (
        "textured/facefuns_di3d_face/example.obj",
        30204,
        59697,
        0,
        711,
        2,
        1,
        0,
    ),
    (
        "textured/ict_facekit_neutral/generic_neutral_mesh.obj",
        26374,
        52220,
        2021,
        718,
        25,
        40,
        104,
    ),
    (
        "textured/james_face_stereo_capture/james.obj",
        6393,
        12228,
        281,
        552,
        8,
        6,
        0,
    ),
    (
        "textured/lee_perry_smith_head/LeePerrySmith_converted.obj",
        8844,
        17684,
        375,
        0,
        0,
        1,
        0,
    ),
    (
        "textured/nefertiti_bust_fraunhofer/Nefertiti_converted.obj",
        10000,
        19479,
        1228,
        522,
        4,
        1,
        3,
    ),
    (
        "textured/pizza_rigsters_photogrammetry/pizza.obj",
        24916,
        49954,
        19232,
        168,
        1,
        1,
        0,
    ),
    (
        "textured/smithsonian_usnm1145291_draco/usnm1145291_converted.obj.gz",
        49198,
        99993,
        20640,
        7,
        7,
        1,
        31,
    ),
    (
        "textured/spot_keenan_crane/spot_triangulated.obj",
        2930,
        5856,
        288,
        0,
        0,
        1,
        0,
    ),
    (
        "untextured/misc_scans/igea_cyberware_trilist_DERIVED.ply.gz",
        134345,
        268686,
        0,
        0,
        0,
        1,
        0,
    ),
    (
        "untextured/misc_scans/igea_cyberware_tristrips.ply",
        134345,
        268686,
        0,
        0,
        0,
        1,
        0,
    ),
    (
        "untextured/misc_scans/max_planck_decimated_libigl.obj",
        5272,
        10540,
        0,
        0,
        0,
        1,
        0,
    ),
    (
        "untextured/misc_scans/nefertiti_hack_lowres.obj",
        35002,
        70000,
        0,
        0,
        0,
        1,
        0,
    ),
    (
        "untextured/misc_scans/stanford_armadillo_libigl.obj.gz",
        43243,
        86482,
        0,
        0,
        0,
        1,
        0,
    ),
    (
        "untextured/misc_scans/stanford_lucy_100k.ply",
        50002,
        100000,
        0,
        0,
        0,
        1,
        0,
    ),
    (
        "untextured/misc_scans/xyzrgb_dragon_20k.ply",
        9994,
        19984,
        0,
        0,
        0,
        1,
        0,
    ),
    (
        "untextured/stanford_bunny/bun_zipper.ply",
        34834,
        69451,
        0,
        223,
        5,
        1,
        0,
    ),
    (
        "untextured/stanford_bunny/bun_zipper_res2.ply",
        8146,
        16214,
        0,
        215,
        70,
        1,
        125,
    ),
    (
        "untextured/stanford_bunny/bun_zipper_res4.ply",
        453,
        908,
        0,
        55,
        22,
        1,
        47,
    ),
    (
        "untextured/stanford_bunny_range_scans/bun000_grid_triangulated_DERIVED.ply",
        40245,
        79312,
        0,
        1186,
        3,
        1,
        0,
    ),
];

/// Files that are not meshes (range images without faces) and the error they must give.
const NOT_MESHES: &[&str] = &[
    "untextured/stanford_bunny_range_scans/bun000.ply",
    "untextured/stanford_bunny_range_scans/bun045.ply",
];

fn mesh_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            mesh_files(&path, out);
        } else {
            let name = path.file_name().unwrap().to_string_lossy().to_string();
            let name = name.strip_suffix(".gz").unwrap_or(&name);
            if name.ends_with(".obj") || name.ends_with(".ply") {
                out.push(path);
            }
        }
    }
}

fn relative(path: &Path) -> String {
    path.strip_prefix(DATA)
        .unwrap()
        .to_string_lossy()
        .replace('\\', "/")
}

fn all_files() -> Vec<PathBuf> {
    let mut files = Vec::new();
    mesh_files(Path::new(DATA), &mut files);
    files.sort();
    files
}

#[test]
fn every_mesh_file_loads_with_the_expected_counts() {
    let files = all_files();
    assert_eq!(
        files.len(),
        EXPECTED.len() + NOT_MESHES.len(),
        "data folder changed: {files:?}"
    );
    for path in &files {
        let rel = relative(path);
        let result = load(path, &LoadOptions::default());
        if NOT_MESHES.contains(&rel.as_str()) {
            let e = result.expect_err(&rel);
            assert!(matches!(e, MeshError::NoTriangles { .. }), "{rel}: {e}");
            continue;
        }
        let (mesh, _) = result.unwrap_or_else(|e| panic!("{rel}: {e}"));
        mesh.check_invariants().unwrap();
        let c = Topology::new(&mesh).counts();
        let got = (
            rel.as_str(),
            c.vertices,
            c.triangles,
            c.texture_seam_edges,
            c.boundary_edges,
            c.boundary_loops,
            c.components,
            c.non_manifold_edges,
        );
        let expected = EXPECTED
            .iter()
            .find(|e| e.0 == rel)
            .unwrap_or_else(|| panic!("{rel} not in table"));
        assert_eq!(
            &got, expected,
            "(file, V, F, seams, bnd edges, loops, components, nm edges)"
        );
    }
}

/// Per triangle, in order: corner positions, corner texture coordinates (rounded to
/// f32 when a format stores them so), and material (its texture's name through PLY).
fn corners(mesh: &Mesh, uv_f32: bool) -> Vec<([u64; 9], [u64; 6], String)> {
    (0..mesh.triangle_count())
        .map(|t| {
            let mut p = [0u64; 9];
            let mut uv = [u64::MAX; 6];
            for k in 0..3 {
                let w = mesh.wedges[mesh.triangles[t][k] as usize];
                let q = mesh.positions[w.vertex as usize];
                p[3 * k..3 * k + 3].copy_from_slice(&[q.x.to_bits(), q.y.to_bits(), q.z.to_bits()]);
                if let Some(tc) = w.texcoord.map(|i| mesh.texcoords[i as usize]) {
                    let (u, v) = if uv_f32 {
                        ((tc.x as f32) as f64, (tc.y as f32) as f64)
                    } else {
                        (tc.x, tc.y)
                    };
                    uv[2 * k] = u.to_bits();
                    uv[2 * k + 1] = v.to_bits();
                }
            }
            // PLY has no material names, only texture files: through PLY, compare those.
            let material = mesh
                .triangle_materials
                .get(t)
                .map(|&m| {
                    let m = &mesh.materials[m as usize];
                    match (uv_f32, &m.diffuse_texture) {
                        (true, Some(texture)) => texture.name.clone(),
                        (true, None) => String::new(),
                        (false, _) => m.name.clone(),
                    }
                })
                .unwrap_or_default();
            (p, uv, material)
        })
        .collect()
}

fn write_read(mesh: &Mesh, dir: &Path, name: &str, encoding: PlyEncoding) -> Mesh {
    let path = dir.join(name);
    save(
        mesh,
        &path,
        &SaveOptions {
            ply_encoding: encoding,
        },
    )
    .unwrap_or_else(|e| panic!("{name}: {e}"));
    load(&path, &LoadOptions::default())
        .unwrap_or_else(|e| panic!("{name}: {e}"))
        .0
}

fn assert_same(a: &Mesh, b: &Mesh, uv_f32: bool, what: &str) {
    assert_eq!(a.triangle_count(), b.triangle_count(), "{what}: faces");
    assert_eq!(a.vertex_count(), b.vertex_count(), "{what}: vertices");
    let (ca, cb) = (corners(a, uv_f32), corners(b, uv_f32));
    let first_diff = ca.iter().zip(&cb).position(|(x, y)| x != y);
    if let Some(i) = first_diff {
        panic!("{what}: triangle {i} differs: {:?} vs {:?}", ca[i], cb[i]);
    }
    let (ta, tb) = (Topology::new(a).counts(), Topology::new(b).counts());
    assert_eq!(
        ta.texture_seam_edges, tb.texture_seam_edges,
        "{what}: seams"
    );
    assert_eq!(ta.boundary_edges, tb.boundary_edges, "{what}: boundary");
}

#[test]
fn round_trips_keep_positions_texcoords_seams_materials_and_order() {
    let tmp = tempfile::tempdir().unwrap();
    for path in all_files() {
        let rel = relative(&path);
        if NOT_MESHES.contains(&rel.as_str()) {
            continue;
        }
        let (mesh, _) = load(&path, &LoadOptions::default()).unwrap();
        let dir = tmp.path().join(rel.replace('/', "_"));
        std::fs::create_dir_all(&dir).unwrap();
        let is_obj = rel.contains(".obj");
        if is_obj {
            let obj = write_read(&mesh, &dir, "a.obj", PlyEncoding::default());
            assert_same(&mesh, &obj, false, &format!("{rel} OBJ→OBJ"));
            let ply = write_read(&mesh, &dir, "b.ply", PlyEncoding::BinaryLittleEndian);
            let back = write_read(&ply, &dir, "c.obj", PlyEncoding::default());
            assert_same(&mesh, &back, true, &format!("{rel} OBJ→PLY→OBJ"));
        } else {
            for (i, encoding) in [
                PlyEncoding::BinaryLittleEndian,
                PlyEncoding::BinaryBigEndian,
                PlyEncoding::Ascii,
            ]
            .into_iter()
            .enumerate()
            {
                let ply = write_read(&mesh, &dir, &format!("p{i}.ply"), encoding);
                assert_same(&mesh, &ply, true, &format!("{rel} PLY→PLY {encoding:?}"));
            }
        }
    }
}
