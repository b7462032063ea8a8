//! OBJ + MTL + texture input and output on the real scans in ../shared/data, round trips,
//! tobj as an oracle for the parser, and every kind of bad input.

mod common;

use scanmill::mesh::obj;
use scanmill::mesh::texture::Referenced;
use scanmill::mesh::{LoadOptions, Location, Mesh, MeshError, load, save};
use std::path::{Path, PathBuf};

use common::{data, read_bytes, scan_folder as scan};

fn no_texture_check() -> LoadOptions {
    LoadOptions {
        check_textures: false,
        ..Default::default()
    }
}

/// Every OBJ in the data: path, `v` lines, `f` lines, materials, textured materials.
const DATA_OBJS: &[(&str, usize, usize, usize, usize)] = &[
    (
        "textured/james_face_stereo_capture/james.obj",
        6393,
        12228,
        1,
        1,
    ),
    (
        "textured/lee_perry_smith_head/LeePerrySmith_converted.obj",
        8844,
        17684,
        1,
        1,
    ),
    (
        "textured/nefertiti_bust_fraunhofer/Nefertiti_converted.obj",
        10000,
        19482,
        1,
        1,
    ),
    (
        "textured/esp32cam_meshroom_raw/texturedMesh.obj",
        26984,
        53364,
        1,
        1,
    ),
    (
        "textured/facefuns_di3d_face/example.obj",
        30204,
        59697,
        0,
        0,
    ),
    (
        "textured/pizza_rigsters_photogrammetry/pizza.obj",
        24916,
        49954,
        0,
        0,
    ),
    (
        "textured/smithsonian_usnm1145291_draco/usnm1145291_converted.obj.gz",
        49198,
        100000,
        1,
        1,
    ),
    (
        "textured/ict_facekit_neutral/generic_neutral_mesh.obj",
        26719,
        26384,
        12,
        0,
    ),
    (
        "textured/spot_keenan_crane/spot_triangulated.obj",
        2930,
        5856,
        0,
        0,
    ),
    (
        "untextured/misc_scans/max_planck_decimated_libigl.obj",
        5272,
        10540,
        0,
        0,
    ),
    (
        "untextured/misc_scans/nefertiti_hack_lowres.obj",
        35002,
        70000,
        0,
        0,
    ),
    (
        "untextured/misc_scans/stanford_armadillo_libigl.obj.gz",
        43243,
        86482,
        0,
        0,
    ),
];

#[test]
fn every_data_obj_loads() {
    for &(rel, v, f, materials, textured) in DATA_OBJS {
        let path = data(rel);
        let (mesh, report) =
            load(&path, &LoadOptions::default()).unwrap_or_else(|e| panic!("{rel}: {e}"));
        mesh.check_invariants().unwrap();
        assert_eq!(report.format, "obj");
        assert_eq!(report.file_vertices, v, "{rel}");
        assert_eq!(report.file_faces, f, "{rel}");
        assert_eq!(mesh.materials.len(), materials, "{rel}");
        let with_texture: Vec<_> = mesh
            .materials
            .iter()
            .filter_map(|m| m.diffuse_texture.as_ref())
            .collect();
        assert_eq!(with_texture.len(), textured, "{rel}");
        // Checked textures know their size.
        assert!(with_texture.iter().all(|t| t.size.is_some()), "{rel}");
        assert!(mesh.triangle_count() > f * 9 / 10, "{rel}");
    }
}

#[test]
fn known_details_of_the_data() {
    let (mesh, report) = load(
        &data("textured/ict_facekit_neutral/generic_neutral_mesh.obj"),
        &LoadOptions::default(),
    )
    .unwrap();
    // ICT is quads (and a few triangles), 12 materials in MTL order, each face tagged.
    assert!(report.triangulated_polygons > 20_000);
    assert_eq!(mesh.materials[0].name, "M_BackHead");
    assert_eq!(mesh.materials[11].name, "M_Teeth");
    assert_eq!(mesh.triangle_materials.len(), mesh.triangle_count());
    assert!(
        mesh.materials[0]
            .other_statements
            .contains(&"Kd 0.60 0.60 0.60".to_string())
    );

    let (james, _) = load(
        &data("textured/james_face_stereo_capture/james.obj"),
        &LoadOptions::default(),
    )
    .unwrap();
    let t = james.materials[0].diffuse_texture.as_ref().unwrap();
    assert_eq!(t.name, "james.jpg");
    assert_eq!(t.size, Some((2400, 1600)));
}

#[test]
fn texture_override_for_an_obj_without_mtl() {
    let options = LoadOptions {
        texture_override: Some(data("textured/facefuns_di3d_face/example.png")),
        ..Default::default()
    };
    let (mesh, _) = load(&data("textured/facefuns_di3d_face/example.obj"), &options).unwrap();
    assert_eq!(mesh.materials.len(), 1);
    assert_eq!(mesh.materials[0].name, obj::OVERRIDE_MATERIAL);
    let t = mesh.materials[0].diffuse_texture.as_ref().unwrap();
    assert_eq!(t.name, "example.png");
    assert_eq!(t.size, Some((1024, 1024)));
    assert!(mesh.triangle_materials.iter().all(|&m| m == 0));

    // An override does not replace the materials a file declares.
    let options = LoadOptions {
        texture_override: Some(data("textured/facefuns_di3d_face/example.png")),
        ..no_texture_check()
    };
    let (james, _) = load(
        &data("textured/james_face_stereo_capture/james.obj"),
        &options,
    )
    .unwrap();
    assert_eq!(james.materials[0].name, "material_0");
}

/// The parser against tobj (`single_index: false`, `triangulate: true`): the positions and
/// texture coordinates referenced by every triangle corner, in file order.
#[test]
fn parser_agrees_with_tobj() {
    for &(rel, ..) in DATA_OBJS {
        let path = data(rel);
        let bytes = read_bytes(&path);
        let ours = obj::parse(&path, &bytes, &no_texture_check()).unwrap();
        let (models, _) = tobj::load_obj_buf(
            &mut std::io::BufReader::new(&bytes[..]),
            &tobj::LoadOptions {
                single_index: false,
                triangulate: true,
                ..Default::default()
            },
            |_| Ok(Default::default()),
        )
        .unwrap_or_else(|e| panic!("{rel}: tobj: {e}"));
        let mut corners = 0;
        for model in &models {
            let m = &model.mesh;
            for (k, &i) in m.indices.iter().enumerate() {
                let face = &ours.faces[corners / 3];
                let c = face[corners % 3];
                let p = ours.positions[c.vertex as usize];
                let q = &m.positions[3 * i as usize..3 * i as usize + 3];
                for (a, b) in [p.x, p.y, p.z].into_iter().zip(q) {
                    assert!(
                        (a - *b as f64).abs() <= 1e-6 * a.abs().max(1.0),
                        "{rel}: corner {corners}: {a} vs {b}"
                    );
                }
                if !m.texcoord_indices.is_empty() {
                    let ti = m.texcoord_indices[k] as usize;
                    let t = ours.texcoords[c.texcoord.unwrap() as usize];
                    let u = &m.texcoords[2 * ti..2 * ti + 2];
                    assert!((t.x - u[0] as f64).abs() <= 1e-6, "{rel}: corner {corners}");
                    assert!((t.y - u[1] as f64).abs() <= 1e-6, "{rel}: corner {corners}");
                }
                corners += 1;
            }
        }
        assert_eq!(corners, ours.faces.len() * 3, "{rel}");
    }
}

/// Writes, reads back and checks that nothing changed.
fn round_trip(mesh: &Mesh, dir: &Path, name: &str) -> (Mesh, Vec<PathBuf>) {
    let out = dir.join(name);
    let written = save(mesh, &out, &Default::default()).unwrap();
    assert_eq!(written[0], out);
    let (back, _) = load(&out, &LoadOptions::default()).unwrap();
    // Positions bit-exact, per-corner texture coordinates, materials per face, face order,
    // vertex and wedge counts: the loaded mesh is already welded and compacted, so reading
    // it back must give the very same arrays.
    assert_eq!(back.positions.len(), mesh.positions.len());
    for (a, b) in back.positions.iter().zip(&mesh.positions) {
        assert_eq!(
            [a.x.to_bits(), a.y.to_bits(), a.z.to_bits()],
            [b.x.to_bits(), b.y.to_bits(), b.z.to_bits()]
        );
    }
    assert_eq!(back.texcoords, mesh.texcoords);
    assert_eq!(back.normals, mesh.normals);
    assert_eq!(back.wedges, mesh.wedges);
    assert_eq!(back.triangles, mesh.triangles);
    assert_eq!(back.triangle_materials, mesh.triangle_materials);
    assert_eq!(back.colors, mesh.colors);
    let names = |m: &Mesh| {
        m.materials
            .iter()
            .map(|m| m.name.clone())
            .collect::<Vec<_>>()
    };
    assert_eq!(names(&back), names(mesh));
    for (a, b) in back.materials.iter().zip(&mesh.materials) {
        assert_eq!(a.other_statements, b.other_statements);
        assert_eq!(
            a.diffuse_texture.as_ref().map(|t| t.size),
            b.diffuse_texture.as_ref().map(|t| t.size)
        );
    }
    (back, written)
}

#[test]
fn round_trips_keep_everything() {
    let dir = tempfile::tempdir().unwrap();
    for rel in [
        "textured/james_face_stereo_capture/james.obj",
        "textured/ict_facekit_neutral/generic_neutral_mesh.obj",
        "textured/lee_perry_smith_head/LeePerrySmith_converted.obj",
        "textured/smithsonian_usnm1145291_draco/usnm1145291_converted.obj.gz",
        "untextured/misc_scans/max_planck_decimated_libigl.obj",
    ] {
        let (mesh, _) = load(&data(rel), &LoadOptions::default()).unwrap();
        let sub = dir.path().join(rel.replace('/', "_"));
        std::fs::create_dir(&sub).unwrap();
        let (_, written) = round_trip(&mesh, &sub, "out.obj");
        let textured = mesh
            .materials
            .iter()
            .filter(|m| m.diffuse_texture.is_some())
            .count();
        let expected = if mesh.materials.is_empty() {
            1
        } else {
            2 + textured
        };
        assert_eq!(written.len(), expected, "{rel}: {written:?}");
        for w in &written {
            assert!(w.is_file(), "{rel}: {}", w.display());
        }
    }
}

#[test]
fn round_trip_with_override_texture_copies_it() {
    let dir = tempfile::tempdir().unwrap();
    let options = LoadOptions {
        texture_override: Some(data("textured/facefuns_di3d_face/example.png")),
        ..Default::default()
    };
    let (mesh, _) = load(&data("textured/facefuns_di3d_face/example.obj"), &options).unwrap();
    let (_, written) = round_trip(&mesh, dir.path(), "face.obj");
    let names: Vec<String> = written
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, vec!["face.obj", "face.mtl", "example.png"]);
    let mtl = std::fs::read_to_string(dir.path().join("face.mtl")).unwrap();
    assert!(
        mtl.contains("newmtl scanmill_texture\nmap_Kd example.png\n"),
        "{mtl}"
    );
    assert_eq!(
        std::fs::read(dir.path().join("example.png")).unwrap(),
        std::fs::read(data("textured/facefuns_di3d_face/example.png")).unwrap()
    );
}

#[test]
fn gzip_and_plain_load_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let src = data("untextured/misc_scans/stanford_armadillo_libigl.obj.gz");
    let plain = dir.path().join("armadillo.obj");
    std::fs::write(&plain, read_bytes(&src)).unwrap();
    let (a, ra) = load(&src, &LoadOptions::default()).unwrap();
    let (b, rb) = load(&plain, &LoadOptions::default()).unwrap();
    assert_eq!(a, b);
    assert_eq!(ra, rb);
}

// ---------------------------------------------------------------------------------------
// Synthetic files

const TRI: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n";

fn png(w: u32, h: u32) -> Vec<u8> {
    let img = image::RgbImage::from_pixel(w, h, image::Rgb([200, 100, 50]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

fn jpeg(w: u32, h: u32) -> Vec<u8> {
    let img = image::RgbImage::from_fn(w, h, |x, y| image::Rgb([(x * 7) as u8, (y * 3) as u8, 9]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Jpeg).unwrap();
    out.into_inner()
}

fn load_err(obj: &Path) -> MeshError {
    load(obj, &LoadOptions::default()).expect_err("must fail")
}

fn assert_names_file_and_line(e: &MeshError, file: &str, line: u64) {
    let text = e.to_string();
    assert!(text.contains(file), "{text}");
    assert!(text.contains(&format!("line {line}")), "{text}");
}

fn textured(mtl: &str, extra: &[(&str, &[u8])]) -> (tempfile::TempDir, PathBuf) {
    let obj = format!("mtllib s.mtl\n{TRI}usemtl m\nf 1/1 2/2 3/3\n");
    let mut files: Vec<(&str, &[u8])> = vec![("s.obj", obj.as_bytes()), ("s.mtl", mtl.as_bytes())];
    files.extend_from_slice(extra);
    scan(&files)
}

#[test]
fn empty_file() {
    let (_d, obj) = scan(&[("empty.obj", b"")]);
    let e = load_err(&obj);
    assert!(matches!(e, MeshError::NoTriangles { .. }), "{e}");
    assert!(e.to_string().contains("empty.obj"), "{e}");
}

#[test]
fn truncated_face_line() {
    let (_d, obj) = scan(&[("cut.obj", format!("{TRI}f 1/1 2/2 3/3\nf 1/").as_bytes())]);
    let e = load_err(&obj);
    assert!(matches!(e, MeshError::Malformed { .. }), "{e}");
    assert_names_file_and_line(&e, "cut.obj", 8);
}

#[test]
fn truncated_vertex_line() {
    let (_d, obj) = scan(&[("cut.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nv 1.0 2.")]);
    let e = load_err(&obj);
    assert!(matches!(e, MeshError::Malformed { .. }), "{e}");
    assert_names_file_and_line(&e, "cut.obj", 5);
}

#[test]
fn binary_garbage() {
    // A deterministic pseudo-random byte soup.
    let mut x: u32 = 12345;
    let bytes: Vec<u8> = (0..4096)
        .map(|_| {
            x = x.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (x >> 16) as u8
        })
        .collect();
    let (_d, obj) = scan(&[("junk.obj", &bytes)]);
    let e = load_err(&obj);
    assert!(matches!(e, MeshError::Malformed { .. }), "{e}");
    assert!(e.to_string().contains("junk.obj"), "{e}");
    assert!(matches!(
        e,
        MeshError::Malformed {
            at: Location::Line(_),
            ..
        }
    ));
}

#[test]
fn nan_coordinate() {
    let (_d, obj) = scan(&[("nan.obj", b"v 0 0 0\nv 1 NaN 0\nv 0 1 0\nf 1 2 3\n")]);
    let e = load_err(&obj);
    assert!(
        matches!(e, MeshError::NonFinite { ref value, .. } if value == "NaN"),
        "{e}"
    );
    assert_names_file_and_line(&e, "nan.obj", 2);
}

#[test]
fn index_out_of_range() {
    let (_d, obj) = scan(&[(
        "oor.obj",
        format!("{TRI}f 1/1 2/2 3/3\nf 1/1 2/7 3/3\n").as_bytes(),
    )]);
    let e = load_err(&obj);
    assert!(
        matches!(
            e,
            MeshError::IndexOutOfRange {
                index: 7,
                count: 3,
                kind: "texture coordinate",
                ..
            }
        ),
        "{e}"
    );
    assert_names_file_and_line(&e, "oor.obj", 8);
}

#[test]
fn face_with_one_or_two_corners() {
    for (face, n) in [("f 1", 1), ("f 1 2", 2)] {
        let (_d, obj) = scan(&[("short.obj", format!("{TRI}{face}\n").as_bytes())]);
        let e = load_err(&obj);
        assert!(matches!(e, MeshError::Malformed { .. }), "{e}");
        assert!(e.to_string().contains(&format!("{n} corner")), "{e}");
        assert_names_file_and_line(&e, "short.obj", 7);
    }
}

#[test]
fn missing_mtl() {
    let (_d, obj) = scan(&[(
        "s.obj",
        format!("mtllib gone.mtl\n{TRI}f 1 2 3\n").as_bytes(),
    )]);
    let e = load_err(&obj);
    assert!(matches!(e, MeshError::Io { .. }), "{e}");
    let text = e.to_string();
    assert!(
        text.contains("gone.mtl") && text.contains("s.obj line 1"),
        "{text}"
    );
}

#[test]
fn missing_texture() {
    let (_d, obj) = textured("newmtl m\nmap_Kd gone.png\n", &[]);
    let e = load_err(&obj);
    assert!(
        matches!(
            e,
            MeshError::MissingFile {
                role: Referenced::Texture,
                ..
            }
        ),
        "{e}"
    );
    let text = e.to_string();
    assert!(
        text.contains("gone.png") && text.contains("s.mtl"),
        "{text}"
    );
}

#[test]
fn missing_bump_map_is_an_error_too() {
    let png = png(4, 4);
    let (_d, obj) = textured(
        "newmtl m\nmap_Kd t.png\nmap_Bump -bm 0.5 n.png\n",
        &[("t.png", &png)],
    );
    let e = load_err(&obj);
    assert!(
        matches!(e, MeshError::MissingFile { ref name, .. } if name == "n.png"),
        "{e}"
    );
}

#[test]
fn texture_path_escaping_the_folder() {
    let png = png(4, 4);
    // `../x.png` is refused whether the file exists or not.
    let (dir, obj) = textured("newmtl m\nmap_Kd ../x.png\n", &[]);
    let e = load_err(&obj);
    assert!(
        matches!(
            e,
            MeshError::PathEscapes { ref name, role: Referenced::Texture, .. } if name == "../x.png"
        ),
        "{e}"
    );
    std::fs::write(dir.path().parent().unwrap().join("x.png"), &png).ok();
    assert!(matches!(load_err(&obj), MeshError::PathEscapes { .. }));

    let outside = tempfile::tempdir().unwrap();
    let abs = outside.path().join("abs.png");
    std::fs::write(&abs, &png).unwrap();
    let (_d, obj) = textured(&format!("newmtl m\nmap_Kd {}\n", abs.display()), &[]);
    let e = load_err(&obj);
    assert!(matches!(e, MeshError::PathEscapes { .. }), "{e}");
    assert!(e.to_string().contains("s.mtl"), "{e}");

    // A symlink inside the folder that points outside.
    let (dir, obj) = textured("newmtl m\nmap_Kd link.png\n", &[]);
    std::os::unix::fs::symlink(&abs, dir.path().join("link.png")).unwrap();
    assert!(matches!(load_err(&obj), MeshError::PathEscapes { .. }));

    // Inside the folder, with `..` that stays inside and an absolute path: fine.
    let (dir, obj) = textured("newmtl m\nmap_Kd sub/../t.png\n", &[("t.png", &png)]);
    load(&obj, &LoadOptions::default()).unwrap();
    let inside = dir.path().join("t.png");
    std::fs::write(
        dir.path().join("s.mtl"),
        format!("newmtl m\nmap_Kd {}\n", inside.display()),
    )
    .unwrap();
    load(&obj, &LoadOptions::default()).unwrap();
}

#[test]
fn mtl_escaping_the_folder() {
    let (_d, obj) = scan(&[(
        "s.obj",
        format!("mtllib ../m.mtl\n{TRI}f 1 2 3\n").as_bytes(),
    )]);
    assert!(matches!(load_err(&obj), MeshError::PathEscapes { .. }));
}

#[test]
fn truncated_and_corrupt_images() {
    let jpg = jpeg(64, 64);
    let (_d, obj) = textured(
        "newmtl m\nmap_Kd t.jpg\n",
        &[("t.jpg", &jpg[..jpg.len() / 2])],
    );
    let e = load_err(&obj);
    assert!(matches!(e, MeshError::Texture { .. }), "{e}");
    assert!(
        e.to_string().contains("t.jpg") && e.to_string().contains("s.mtl"),
        "{e}"
    );

    let png = png(64, 64);
    let (_d, obj) = textured(
        "newmtl m\nmap_Kd t.png\n",
        &[("t.png", &png[..png.len() - 20])],
    );
    assert!(matches!(load_err(&obj), MeshError::Texture { .. }));

    let (_d, obj) = textured(
        "newmtl m\nmap_Kd t.png\n",
        &[("t.png", b"not an image at all")],
    );
    assert!(matches!(load_err(&obj), MeshError::Texture { .. }));

    // The complete images are fine, and without the check even the broken one loads.
    let (_d, obj) = textured("newmtl m\nmap_Kd t.jpg\n", &[("t.jpg", &jpg)]);
    let (mesh, _) = load(&obj, &LoadOptions::default()).unwrap();
    assert_eq!(
        mesh.materials[0].diffuse_texture.as_ref().unwrap().size,
        Some((64, 64))
    );
    let (_d, obj) = textured("newmtl m\nmap_Kd t.png\n", &[("t.png", b"broken")]);
    load(&obj, &no_texture_check()).unwrap();
}

/// The textures are checked beside the weld: a bad texture is still the error when the
/// geometry is bad too, and the sizes reach the materials the repaired mesh keeps (here the
/// second one, after an unused first material is dropped).
#[test]
fn texture_check_beside_the_weld() {
    // Its only face is degenerate: the repair drops it, and the weld finds no triangle.
    let obj = format!("mtllib s.mtl\n{TRI}usemtl m\nf 1/1 1/1 2/2\n");
    let mtl = "newmtl m\nmap_Kd t.png\n";
    let (_d, path) = scan(&[
        ("s.obj", obj.as_bytes()),
        ("s.mtl", mtl.as_bytes()),
        ("t.png", b"not an image at all"),
    ]);
    let e = load_err(&path);
    assert!(matches!(e, MeshError::Texture { .. }), "{e}");
    let options = LoadOptions {
        check_textures: false,
        ..LoadOptions::default()
    };
    let e = load(&path, &options).expect_err("no triangle");
    assert!(matches!(e, MeshError::NoTriangles { .. }), "{e}");

    let png = png(6, 4);
    let obj = format!("mtllib s.mtl\n{TRI}usemtl used\nf 1/1 2/2 3/3\n");
    let mtl = "newmtl unused\nmap_Kd a.png\nnewmtl used\nmap_Kd b.png\n";
    let (_d, path) = scan(&[
        ("s.obj", obj.as_bytes()),
        ("s.mtl", mtl.as_bytes()),
        ("a.png", &png),
        ("b.png", &self::png(3, 5)),
    ]);
    let (mesh, report) = load(&path, &LoadOptions::default()).unwrap();
    let sizes: Vec<_> = mesh
        .materials
        .iter()
        .map(|m| {
            (
                m.name.as_str(),
                m.diffuse_texture.as_ref().and_then(|t| t.size),
            )
        })
        .collect();
    assert!(sizes.contains(&("used", Some((3, 5)))), "{sizes:?}");
    assert_eq!(report.decoded_textures, 2);
}

#[test]
fn mtl_features_and_output_names() {
    let png = png(8, 8);
    let mtl = "# lib\nnewmtl skin\nKd 1 1 1\nmap_Kd -s 1 1 1 tex dir/my skin.png\nmap_Bump -bm 0.3 tex dir/n.png\n\
               newmtl eye\nKd 0 0 1\n";
    let obj = format!(
        "mtllib s.mtl\n{TRI}v 1 1 0\nf 1/1 2/2 3/3\nusemtl skin\nf 2/2 4/1 3/3\nusemtl eye\nf 1 2 4\n"
    );
    let (dir, obj_path) = scan(&[
        ("s.obj", obj.as_bytes()),
        ("s.mtl", mtl.as_bytes()),
        ("tex dir/my skin.png", &png),
        ("tex dir/n.png", &png),
    ]);
    let (mesh, _) = load(&obj_path, &LoadOptions::default()).unwrap();
    let names: Vec<&str> = mesh.materials.iter().map(|m| m.name.as_str()).collect();
    // MTL order, then the default for the face before the first usemtl.
    assert_eq!(names, vec!["skin", "eye", obj::DEFAULT_MATERIAL]);
    assert_eq!(mesh.triangle_materials, vec![2, 0, 1]);
    let skin = &mesh.materials[0];
    assert_eq!(
        skin.diffuse_texture.as_ref().unwrap().name,
        "tex dir/my skin.png"
    );
    assert_eq!(
        skin.other_statements,
        vec!["Kd 1 1 1", "map_Bump -bm 0.3 tex dir/n.png"]
    );

    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let (_, written) = round_trip(&mesh, &out, "result.obj");
    assert!(out.join("tex dir/my skin.png").is_file());
    assert!(out.join("tex dir/n.png").is_file());
    assert_eq!(written.len(), 4);
    let text = std::fs::read_to_string(out.join("result.obj")).unwrap();
    assert_eq!(text.matches("usemtl ").count(), 3);
    assert!(text.contains("\nf 1 2 4\n"), "{text}");
    assert!(text.contains("\nf 1/1 2/2 3/3\n"), "{text}");
}

#[test]
fn writing_over_the_input_folder_keeps_textures() {
    let png = png(8, 8);
    let (dir, obj) = textured("newmtl m\nmap_Kd t.png\n", &[("t.png", &png)]);
    let (mesh, _) = load(&obj, &LoadOptions::default()).unwrap();
    save(&mesh, &dir.path().join("again.obj"), &Default::default()).unwrap();
    assert_eq!(std::fs::read(dir.path().join("t.png")).unwrap(), png);
}

#[test]
fn corner_forms_are_written_as_they_are() {
    // Mixed corners: no texture on one, normal only on another.
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 1\nvn 0 0 1\n\
                f 1 2 3\nf 2/1 4/2 3/1\nf 1//1 4//1 3//1\nf 1/1/1 2/2/1 4/1/1\n";
    let (dir, obj) = scan(&[("c.obj", text.as_bytes())]);
    let (mesh, _) = load(&obj, &LoadOptions::default()).unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    round_trip(&mesh, &out, "c.obj");
    let written = std::fs::read_to_string(out.join("c.obj")).unwrap();
    for face in [
        "f 1 2 3",
        "f 2/1 4/2 3/1",
        "f 1//1 4//1 3//1",
        "f 1/1/1 2/2/1 4/1/1",
    ] {
        assert!(written.contains(face), "{face} in {written}");
    }
}

#[test]
fn vertex_colours_round_trip() {
    let text = "v 0 0 0 1 0 0\nv 1 0 0 0 0.5 0\nv 0 1 0 0.2 0.4 0.6\nf 1 2 3\n";
    let (dir, obj) = scan(&[("col.obj", text.as_bytes())]);
    let (mesh, _) = load(&obj, &LoadOptions::default()).unwrap();
    assert_eq!(mesh.colors[1], [0, 128, 0, 255]);
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    round_trip(&mesh, &out, "col.obj");
}
