//! Unit tests of the PLY reader and writer on small hand-made files.

use super::*;
use crate::mesh::{LoadOptions, LoadReport, Location, Mesh, MeshError};
use glam::{DVec2, DVec3};
use std::path::{Path, PathBuf};
use tempfile::TempDir;

fn load(bytes: &[u8]) -> Result<(Mesh, LoadReport), MeshError> {
    read(Path::new("test.ply"), bytes, &LoadOptions::default())
}

fn load_err(bytes: &[u8]) -> String {
    load(bytes).unwrap_err().to_string()
}

/// Binary body builder.
struct Bin {
    out: Vec<u8>,
    big: bool,
}

impl Bin {
    fn new(header: &str, big: bool) -> Self {
        Bin {
            out: header.as_bytes().to_vec(),
            big,
        }
    }
    fn put(&mut self, le: &[u8], be: &[u8]) -> &mut Self {
        self.out.extend_from_slice(if self.big { be } else { le });
        self
    }
    fn f32(&mut self, v: f32) -> &mut Self {
        self.put(&v.to_le_bytes(), &v.to_be_bytes())
    }
    fn f64(&mut self, v: f64) -> &mut Self {
        self.put(&v.to_le_bytes(), &v.to_be_bytes())
    }
    fn i32(&mut self, v: i32) -> &mut Self {
        self.put(&v.to_le_bytes(), &v.to_be_bytes())
    }
    fn u16(&mut self, v: u16) -> &mut Self {
        self.put(&v.to_le_bytes(), &v.to_be_bytes())
    }
    fn u8(&mut self, v: u8) -> &mut Self {
        self.out.push(v);
        self
    }
}

const SQUARE_ASCII: &str = "ply
format ascii 1.0
comment a unit square as one quad and a triangle below it
element vertex 5
property float x
property float y
property float z
element face 2
property list uchar int vertex_index
end_header
0 0 0
1 0 0
1 1 0
0 1 0
0.5 -1 0
4 0 1 2 3
3 0 4 1
";

#[test]
fn ascii_polygons_are_fan_triangulated() {
    let (mesh, report) = load(SQUARE_ASCII.as_bytes()).unwrap();
    assert_eq!(mesh.triangle_count(), 3);
    assert_eq!(report.triangulated_polygons, 1);
    assert_eq!(report.file_faces, 2);
    assert_eq!(mesh.triangle_vertices(0), [0, 1, 2]);
    assert_eq!(mesh.triangle_vertices(1), [0, 2, 3]);
    assert_eq!(mesh.triangle_vertices(2), [0, 4, 1]);
    assert_eq!(report.format, "ply ascii");
}

#[test]
fn crlf_files_read() {
    let crlf = SQUARE_ASCII.replace('\n', "\r\n");
    assert_eq!(load(crlf.as_bytes()).unwrap().0.triangle_count(), 3);
}

fn binary_square(big: bool) -> Vec<u8> {
    let header = format!(
        "ply\nformat {} 1.0\nelement vertex 4\nproperty double x\nproperty float y\nproperty float z\n\
         element face 2\nproperty list ushort uchar vertex_indices\nend_header\n",
        if big {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        }
    );
    let mut b = Bin::new(&header, big);
    for (x, y) in [(0.1, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
        b.f64(x).f32(y).f32(0.0);
    }
    b.u16(3).u8(0).u8(1).u8(2);
    b.u16(3).u8(0).u8(2).u8(3);
    b.out
}

#[test]
fn binary_both_byte_orders_and_odd_types() {
    let (le, _) = load(&binary_square(false)).unwrap();
    let (be, report) = load(&binary_square(true)).unwrap();
    assert_eq!(le, be);
    assert_eq!(le.positions[0], DVec3::new(0.1, 0.0, 0.0));
    assert_eq!(le.triangle_count(), 2);
    assert_eq!(report.format, "ply binary_big_endian");
}

#[test]
fn colours_normals_and_vertex_uvs() {
    for (u, v) in [
        ("s", "t"),
        ("u", "v"),
        ("texture_u", "texture_v"),
        ("texture_s", "texture_t"),
    ] {
        let text = format!(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
             property float nx\nproperty float ny\nproperty float nz\nproperty uchar red\nproperty uchar green\n\
             property uchar blue\nproperty float {u}\nproperty float {v}\nproperty float quality\n\
             element face 1\nproperty list uchar int vertex_indices\nend_header\n\
             0 0 0 0 0 1 255 0 0 0 0 7\n1 0 0 0 0 1 0 255 0 1 0 7\n0 1 0 0 0 1 0 0 255 0 1 7\n3 0 1 2\n"
        );
        let (mesh, report) = load(text.as_bytes()).unwrap();
        assert_eq!(
            mesh.colors,
            vec![[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255]]
        );
        assert_eq!(mesh.normals, vec![DVec3::Z]);
        assert_eq!(
            mesh.wedge_texcoord(mesh.triangles[0][1]),
            Some(DVec2::new(1.0, 0.0))
        );
        assert_eq!(report.skipped, vec!["vertex.quality".to_string()]);
    }
}

#[test]
fn float_colours_scale_to_bytes() {
    let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                property float red\nproperty float green\nproperty float blue\nproperty float alpha\n\
                element face 1\nproperty list uchar int vertex_indices\nend_header\n\
                0 0 0 1 0.5 0 0.2\n1 0 0 0 0 0 1\n0 1 0 2 -1 0 1\n3 0 1 2\n";
    let (mesh, _) = load(text.as_bytes()).unwrap();
    assert_eq!(mesh.colors[0], [255, 128, 0, 51]);
    assert_eq!(mesh.colors[2], [255, 0, 0, 255]);
}

const TEXTURED_HEADER: &str = "ply
format ascii 1.0
comment TextureFile first_missing.png
comment TextureFile second missing.png
element vertex 4
property float x
property float y
property float z
element face 2
property list uchar float texcoord
property list uchar int vertex_indices
property int texnumber
end_header
0 0 0
1 0 0
1 1 0
0 1 0
";

#[test]
fn per_face_texcoords_texnumber_and_missing_textures() {
    let text =
        format!("{TEXTURED_HEADER}6 0 0 0.5 0 0.5 0.5 3 0 1 2 0\n6 0 0 0.5 0.5 0 0.5 3 0 2 3 1\n");
    let (mesh, report) = load(text.as_bytes()).unwrap();
    assert_eq!(mesh.triangle_count(), 2);
    assert_eq!(mesh.triangle_materials, vec![0, 1]);
    assert_eq!(mesh.materials.len(), 2);
    assert_eq!(mesh.materials[1].name, "texture1");
    assert!(mesh.materials[1].diffuse_texture.is_none());
    assert_eq!(
        mesh.materials[1].other_statements,
        vec![format!("{MISSING_TEXTURE_PREFIX}second missing.png")]
    );
    assert_eq!(
        mesh.wedge_texcoord(mesh.triangles[1][2]),
        Some(DVec2::new(0.0, 0.5))
    );
    // The bit-identical corner coordinates (0,0) and (0.5,0.5) are merged.
    assert_eq!(report.file_texcoords, 6);
    assert_eq!(mesh.texcoords.len(), 4);

    let bad = format!("{TEXTURED_HEADER}4 0 0 0.5 0 3 0 1 2 0\n6 0 0 0.5 0.5 0 0.5 3 0 2 3 1\n");
    let e = load_err(bad.as_bytes());
    assert!(
        e.contains("line 18: face 0: texcoord has 4 values for a face with 3 corners"),
        "{e}"
    );
}

#[test]
fn present_texture_is_checked() {
    let dir = tempfile::tempdir().unwrap();
    let image = image::RgbImage::from_pixel(3, 2, image::Rgb([1, 2, 3]));
    image.save(dir.path().join("tex.png")).unwrap();
    std::fs::write(dir.path().join("broken.png"), b"not a png").unwrap();
    let text = |name: &str| {
        SQUARE_ASCII.replace(
            "comment a unit",
            &format!("comment TextureFile {name}\ncomment a unit"),
        )
    };
    let path = dir.path().join("m.ply");
    let (mesh, _) = read(&path, text("tex.png").as_bytes(), &LoadOptions::default()).unwrap();
    let texture = mesh.materials[0].diffuse_texture.as_ref().unwrap();
    assert_eq!(texture.size, Some((3, 2)));
    assert_eq!(texture.path, dir.path().join("tex.png"));

    let e = read(
        &path,
        text("broken.png").as_bytes(),
        &LoadOptions::default(),
    )
    .unwrap_err();
    assert!(matches!(e, MeshError::Texture { .. }), "{e}");
    let lenient = LoadOptions {
        check_textures: false,
        ..LoadOptions::default()
    };
    let (mesh, _) = read(&path, text("broken.png").as_bytes(), &lenient).unwrap();
    assert_eq!(
        mesh.materials[0].diffuse_texture.as_ref().unwrap().size,
        None
    );
    // Names leaving the folder are never read: `..`, an absolute path, a symlink.
    let outside = tempfile::tempdir().unwrap();
    let secret = outside.path().join("secret.png");
    image.save(&secret).unwrap();
    std::os::unix::fs::symlink(&secret, dir.path().join("link.png")).unwrap();
    for name in [
        "../tex.png".to_string(),
        "..\\tex.png".to_string(),
        secret.display().to_string(),
        "link.png".to_string(),
    ] {
        let e = read(&path, text(&name).as_bytes(), &LoadOptions::default()).unwrap_err();
        assert!(matches!(e, MeshError::PathEscapes { .. }), "{name}: {e}");
        assert!(
            e.to_string().contains("resolves outside the scan's folder"),
            "{e}"
        );
    }
    // A missing texture is still only a warning.
    let (mesh, _) = read(&path, text("gone.png").as_bytes(), &LoadOptions::default()).unwrap();
    assert!(mesh.materials[0].diffuse_texture.is_none());
}

#[test]
fn tristrips_unroll_with_alternating_winding_and_restarts() {
    let header = "ply\nformat binary_little_endian 1.0\nelement vertex 6\nproperty float x\nproperty float y\n\
                  property float z\nelement tristrips 1\nproperty list int int vertex_indices\nend_header\n";
    let mut b = Bin::new(header, false);
    for (x, y) in [
        (0.0, 0.0),
        (0.0, 1.0),
        (1.0, 0.0),
        (1.0, 1.0),
        (2.0, 0.0),
        (2.0, 1.0),
    ] {
        b.f32(x).f32(y).f32(0.0);
    }
    // Strip 0 1 2 3, a zero-area join (3 3), then a restart with 2 3 4 5.
    let strip = [0, 1, 2, 3, 3, -1, 2, 3, 4, 5];
    b.i32(strip.len() as i32);
    for v in strip {
        b.i32(v);
    }
    let (mesh, report) = load(&b.out).unwrap();
    assert_eq!(report.strip_triangles, 4);
    let tris: Vec<_> = (0..mesh.triangle_count())
        .map(|t| mesh.triangle_vertices(t))
        .collect();
    assert_eq!(tris, vec![[0, 1, 2], [2, 1, 3], [2, 3, 4], [4, 3, 5]]);
    // All four face the same way.
    assert!((0..4).all(|t| mesh.triangle_cross(t).z < 0.0));
}

#[test]
fn artec_multi_texture_faces_map_to_their_face() {
    let header = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
                  element face 2\nproperty list uchar int vertex_indices\nelement multi_texture_vertex 4\n\
                  property uchar tx\nproperty float u\nproperty float v\nelement multi_texture_face 2\n\
                  property uchar tx\nproperty uint tn\nproperty list uchar int texture_vertex_indices\nend_header\n";
    // The records come in reverse face order: tn says which face each is for.
    let body = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n\
                0 0 0\n0 0.25 0\n0 0.25 0.25\n0 0 0.25\n0 1 3 3 2 1\n0 0 3 0 1 2\n";
    let (mesh, _) = load(format!("{header}{body}").as_bytes()).unwrap();
    let uv = |t: usize, k: usize| mesh.wedge_texcoord(mesh.triangles[t][k]).unwrap();
    assert_eq!(
        [uv(0, 0), uv(0, 1), uv(0, 2)],
        [
            DVec2::new(0.0, 0.0),
            DVec2::new(0.25, 0.0),
            DVec2::new(0.25, 0.25)
        ]
    );
    assert_eq!(uv(1, 0), DVec2::new(0.0, 0.25));
    assert!(mesh.materials.is_empty());

    let wrong = body.replace("0 1 3 3 2 1\n", "0 7 3 3 2 1\n");
    let e = load(format!("{header}{wrong}").as_bytes()).unwrap_err();
    assert!(
        matches!(e, MeshError::IndexOutOfRange { kind: "face", .. }),
        "{e}"
    );
}

#[test]
fn unknown_binary_elements_with_lists_are_skipped() {
    let header = "ply\nformat binary_little_endian 1.0\nelement camera 2\nproperty list uchar float k\nproperty short id\n\
                  element vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                  element face 1\nproperty list uchar int vertex_indices\nproperty uchar red\nend_header\n";
    let mut b = Bin::new(header, false);
    b.u8(2).f32(1.0).f32(2.0).put(&[0, 0], &[0, 0]);
    b.u8(0).put(&[1, 0], &[0, 1]);
    for (x, y) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)] {
        b.f32(x).f32(y).f32(0.0);
    }
    b.u8(3).i32(0).i32(1).i32(2).u8(9);
    let (mesh, report) = load(&b.out).unwrap();
    assert_eq!(mesh.triangle_count(), 1);
    assert_eq!(
        report.skipped,
        vec![
            "element camera (2 elements)".to_string(),
            "face.red".to_string()
        ]
    );
}

#[test]
fn point_clouds_say_there_is_no_face_element() {
    let text = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n\
                element range_grid 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0\n0\n";
    let e = load(text.as_bytes()).unwrap_err();
    assert!(matches!(e, MeshError::NoTriangles { .. }));
    assert!(
        e.to_string()
            .contains("no face element (it has: vertex 1, range_grid 2)"),
        "{e}"
    );
}

/// Each file is refused with a message that contains its snippet.
fn assert_refused<T: AsRef<[u8]>>(cases: &[(T, &str)]) {
    for (bytes, says) in cases {
        let e = load_err(bytes.as_ref());
        assert!(
            e.contains(says),
            "{}: {e}",
            String::from_utf8_lossy(bytes.as_ref())
        );
    }
}

#[test]
fn bad_headers_are_refused() {
    assert_refused(&[
        (&b""[..], "not a PLY file"),
        (b"\x00\x01garbage\xff", "not a PLY file"),
        (
            b"ply\nformat binary_middle_endian 1.0\nend_header\n",
            "unknown format",
        ),
    ]);
}

#[test]
fn truncated_binary_names_the_element_that_was_cut() {
    // The second triangle is cut.
    let full = binary_square(false);
    let e = load(&full[..full.len() - 2]).unwrap_err();
    assert_eq!(
        e.to_string(),
        "test.ply: face 1: truncated: expected 2 face elements, found 1 (a list of 3 uchar values needs 3 bytes, 1 remain)"
    );
    // Cut inside the vertices.
    let body_start = full.len() - 2 * (2 + 3) - 4 * 16;
    let e = load(&full[..body_start + 16 + 5]).unwrap_err();
    assert_eq!(
        e.to_string(),
        "test.ply: vertex 1: truncated: expected 4 vertex elements, found 1"
    );
}

#[test]
fn ascii_element_counts_that_lie_are_located() {
    let lying = SQUARE_ASCII.replace("element vertex 5", "element vertex 6");
    assert_refused(&[(
        lying,
        "line 16: vertex 5: the line has more values than the header declares",
    )]);
    let lying = SQUARE_ASCII.replace("element face 2", "element face 3");
    assert_eq!(
        load_err(lying.as_bytes()),
        "test.ply: line 17: truncated: expected 3 face elements, found 2"
    );
}

#[test]
fn nan_is_located_in_ascii_and_binary() {
    let nan = SQUARE_ASCII.replace("1 1 0\n", "1 nan 0\n");
    let e = load(nan.as_bytes()).unwrap_err();
    assert!(
        matches!(
            &e,
            MeshError::NonFinite {
                at: Location::Line(13),
                ..
            }
        ),
        "{e}"
    );
    let mut bin = binary_square(true);
    let first_vertex = bin.len() - 2 * 5 - 4 * 16;
    bin[first_vertex + 8..first_vertex + 12].copy_from_slice(&f32::NAN.to_be_bytes());
    let e = load(&bin).unwrap_err();
    assert!(
        matches!(&e, MeshError::NonFinite { at: Location::Element { element, index: 0 }, .. } if element == "vertex"),
        "{e}"
    );
}

#[test]
fn indices_out_of_range_or_negative_and_faces_too_small_are_refused() {
    let e = load(SQUARE_ASCII.replace("3 0 4 1", "3 0 5 1").as_bytes()).unwrap_err();
    assert!(
        matches!(
            e,
            MeshError::IndexOutOfRange {
                index: 5,
                count: 5,
                ..
            }
        ),
        "{e}"
    );
    let face = |f: &str| SQUARE_ASCII.replace("3 0 4 1", f);
    assert_refused(&[
        (face("3 0 -4 1"), "index -4 is out of range"),
        (
            face("1 0"),
            "face 1: a face needs at least 3 vertex indices, this one has 1",
        ),
        (face("3 0 4 1 9"), "more values than the header declares"),
        (face("200 0 4 1"), "cannot fit"),
    ]);
}

#[test]
fn absurd_counts_fail_fast_without_allocating() {
    let mut huge = binary_square(false);
    let at = huge.len() - 5;
    huge[at..at + 2].copy_from_slice(&u16::MAX.to_le_bytes());
    let header_only = "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n\
                       property float y\nproperty float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n";
    assert_refused(&[
        (huge, "needs 65535 bytes"),
        (
            header_only.as_bytes().to_vec(),
            "truncated: expected 4000000000 vertex elements, found 0",
        ),
    ]);
}

#[test]
fn trailing_data_is_ignored_and_reported() {
    let mut bin = binary_square(false);
    bin.extend_from_slice(&[3, 0, 0, 1, 2, 3]);
    let (mesh, report) = load(&bin).unwrap();
    assert_eq!(mesh.triangle_count(), 2);
    assert_eq!(
        report.skipped,
        vec!["6 bytes after the last element (ignored)".to_string()]
    );
    // Fewer faces declared than present: the declared ones load.
    let fewer = SQUARE_ASCII.replace("element face 2", "element face 1");
    let (mesh, report) = load(fewer.as_bytes()).unwrap();
    assert_eq!(mesh.triangle_count(), 2);
    assert!(
        report.skipped[0].starts_with("1 non-blank lines after the last element (from line 17)")
    );
}

#[test]
fn write_then_read_keeps_everything() {
    let text = format!(
        "{TEXTURED_HEADER}6 0 0 0.5 0 0.5 0.5 3 0 1 2 0\n6 0 0.1 0.5 0.5 0 0.5 3 0 2 3 1\n"
    );
    let (mut mesh, _) = load(text.as_bytes()).unwrap();
    mesh.colors = vec![[1, 2, 3, 4], [5, 6, 7, 255], [8, 9, 10, 11], [0, 0, 0, 0]];
    mesh.positions[0] = DVec3::new(0.1, 1e-300, 0.3);
    let dir = tempfile::tempdir().unwrap();
    for encoding in [
        PlyEncoding::Ascii,
        PlyEncoding::BinaryLittleEndian,
        PlyEncoding::BinaryBigEndian,
    ] {
        let path = dir.path().join(format!("{encoding:?}.ply"));
        assert_eq!(write(&mesh, &path, encoding).unwrap(), vec![path.clone()]);
        let bytes = std::fs::read(&path).unwrap();
        let text = String::from_utf8_lossy(&bytes);
        assert!(text.contains("comment scanmill\ncomment TextureFile first_missing.png\ncomment TextureFile second missing.png\n"));
        assert!(text.contains("property int texnumber\n"));
        let (back, _) = read(&path, &bytes, &LoadOptions::default()).unwrap();
        assert_eq!(back.positions, mesh.positions);
        assert_eq!(back.colors, mesh.colors);
        assert_eq!(back.triangles.len(), 2);
        assert_eq!(back.triangle_materials, mesh.triangle_materials);
        assert_eq!(back.materials, mesh.materials);
        for t in 0..2 {
            assert_eq!(back.triangle_vertices(t), mesh.triangle_vertices(t));
            for k in 0..3 {
                let uv = |m: &Mesh| m.wedge_texcoord(m.triangles[t][k]).map(|uv| uv.as_vec2());
                assert_eq!(uv(&back), uv(&mesh));
            }
        }
    }
}

#[test]
fn normals_are_written_only_when_per_vertex() {
    let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                property float nx\nproperty float ny\nproperty float nz\nelement face 1\n\
                property list uchar int vertex_indices\nend_header\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 1 0\n3 0 1 2\n";
    let (mut mesh, _) = load(text.as_bytes()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("n.ply");
    write(&mesh, &path, PlyEncoding::Ascii).unwrap();
    let (back, _) = read(
        &path,
        &std::fs::read(&path).unwrap(),
        &LoadOptions::default(),
    )
    .unwrap();
    assert_eq!(back.normals, mesh.normals);
    assert_eq!(back.wedges, mesh.wedges);
    // Give vertex 0 a second wedge with another normal: PLY cannot say that; normals go.
    mesh.wedges.push(crate::mesh::Wedge {
        vertex: 0,
        texcoord: None,
        normal: Some(1),
    });
    write(&mesh, &path, PlyEncoding::Ascii).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert!(!String::from_utf8_lossy(&bytes).contains("nx"));
}

/// The ASCII unit square read from `dir`, naming the texture `name` (a 2×2 PNG made there).
fn square_textured(dir: &Path, name: &str) -> Mesh {
    image::RgbImage::from_pixel(2, 2, image::Rgb([9, 9, 9]))
        .save(dir.join(name))
        .unwrap();
    let text = SQUARE_ASCII.replace(
        "comment a unit",
        &format!("comment TextureFile {name}\ncomment a unit"),
    );
    read(
        &dir.join("in.ply"),
        text.as_bytes(),
        &LoadOptions::default(),
    )
    .unwrap()
    .0
}

/// A textured square read from a folder of its own, and `out.ply` in another.
fn textured_square_and_output(texture: &str) -> (TempDir, Mesh, TempDir, PathBuf) {
    let src = tempfile::tempdir().unwrap();
    let mesh = square_textured(src.path(), texture);
    let out = tempfile::tempdir().unwrap();
    let path = out.path().join("out.ply");
    (src, mesh, out, path)
}

#[test]
fn writer_copies_present_textures() {
    let (src, mesh, out, path) = textured_square_and_output("skin.png");
    let written = write(&mesh, &path, PlyEncoding::BinaryLittleEndian).unwrap();
    assert_eq!(written, vec![path.clone(), out.path().join("skin.png")]);
    let (back, _) = read(
        &path,
        &std::fs::read(&path).unwrap(),
        &LoadOptions::default(),
    )
    .unwrap();
    let texture = back.materials[0].diffuse_texture.as_ref().unwrap();
    assert_eq!(
        (texture.name.as_str(), texture.size),
        ("skin.png", Some((2, 2)))
    );
    // Writing next to the texture itself does not copy it onto itself.
    let beside = src.path().join("again.ply");
    let written = write(&mesh, &beside, PlyEncoding::Ascii).unwrap();
    assert_eq!(written, vec![beside, src.path().join("skin.png")]);
}

#[test]
fn writer_keeps_copied_textures_apart_from_reserved_names() {
    let (_src, mesh, out, path) = textured_square_and_output("out.preview.png");
    let reserved = ["out.preview.png".to_string()];
    let written = write_reserving(&mesh, &path, PlyEncoding::Ascii, &reserved).unwrap();
    assert_eq!(
        written,
        vec![path.clone(), out.path().join("out.preview_2.png")]
    );
    assert!(!out.path().join("out.preview.png").exists());
    let header = std::fs::read_to_string(&path).unwrap();
    assert!(
        header.contains("comment TextureFile out.preview_2.png\n"),
        "{header}"
    );
}
