//! `scanmill process` and `scanmill inspect` as a user runs them: good scans give a result and
//! a report; every kind of bad input gives a one-line error naming the file, a non-zero exit
//! code, and nothing at all in --out.

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
mod hostile_support;

use common::{DATA, scan_folder as scan};
use hostile_support::{RECIPE, Run, process, run};
fn entries(dir: &Path) -> Vec<PathBuf> {
    match std::fs::read_dir(dir) {
        Ok(rd) => rd.map(|e| e.unwrap().path()).collect(),
        Err(_) => Vec::new(),
    }
}

#[test]
fn textured_obj_is_processed_with_its_texture_and_report() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let report = tmp.path().join("report.json");
    let input = format!("{DATA}/textured/james_face_stereo_capture/james.obj");
    let Run { code, stderr, .. } = run(&[
        "process",
        &input,
        "--recipe",
        RECIPE,
        "--out",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    let mut names: Vec<String> = entries(&out)
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        ["james.jpg", "james.mtl", "james.obj", "james.preview.png"]
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["input"]["counts"]["faces"], 12228);
    assert_eq!(json["output"]["counts"]["faces"], 12228);
    assert_eq!(json["steps"][0]["kind"], "normals");
    assert_eq!(json["recipe"]["hash"].as_str().unwrap().len(), 64);
    assert_eq!(json["input"]["content_hash"].as_str().unwrap().len(), 64);
    // The result is a valid scan again, now with one normal per vertex.
    let Run {
        code,
        stdout,
        stderr,
        ..
    } = run(&["inspect", "--json", out.join("james.obj").to_str().unwrap()]);
    assert_eq!(code, Some(0), "{stderr}");
    let summary: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(summary["triangles"], 12228);
    assert_eq!(summary["texture_seam_edges"], 281);
    assert_eq!(summary["load"]["file_normals"], 6393);
}

#[test]
fn texture_given_for_an_obj_without_mtl() {
    // facefuns_di3d_face has no MTL; SOURCES.md says to pair it with its PNG explicitly.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let report = tmp.path().join("report.json");
    let input = format!("{DATA}/textured/facefuns_di3d_face/example.obj");
    let texture = format!("{DATA}/textured/facefuns_di3d_face/example.png");
    let Run { code, stderr, .. } = run(&[
        "process",
        &input,
        "--texture",
        &texture,
        "--recipe",
        RECIPE,
        "--out",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    for name in ["example.obj", "example.mtl", "example.png"] {
        assert!(out.join(name).is_file(), "{name}: {:?}", entries(&out));
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(report["metrics"]["texture"]["status"], "measured");

    // A texture that is not there: a clear error, exit 65, nothing in --out.
    let out = tmp.path().join("out2");
    let Run { code, stderr, .. } = run(&[
        "process",
        &input,
        "--texture",
        "/nonexistent/face.png",
        "--recipe",
        RECIPE,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(65), "{stderr}");
    assert!(stderr.contains("face.png"), "{stderr}");
    assert!(entries(&out).is_empty());
}

#[test]
fn ply_input_is_processed() {
    let tmp = tempfile::tempdir().unwrap();
    let input = Path::new(DATA).join("untextured/stanford_bunny/bun_zipper_res4.ply");
    let Run { code, stderr, .. } = process(&input, tmp.path());
    assert_eq!(code, Some(0), "{stderr}");
    assert!(tmp.path().join("bun_zipper_res4.obj").is_file());
}

/// A recipe without `decimate` or an isotropic `remesh` keeps the file's numbering (the mesh
/// is renumbered for speed only before those, whose output is numbered afresh anyway): the
/// output's vertices correspond one for one to the input's.
#[test]
fn a_recipe_without_decimate_keeps_the_vertex_order() {
    let tmp = tempfile::tempdir().unwrap();
    let input = Path::new(DATA).join("untextured/stanford_bunny/bun_zipper_res4.ply");
    let Run { code, stderr, .. } = process(&input, tmp.path());
    assert_eq!(code, Some(0), "{stderr}");
    let options = scanmill::mesh::LoadOptions::default();
    let (before, _) = scanmill::mesh::load(&input, &options).unwrap();
    let output = tmp.path().join("bun_zipper_res4.obj");
    let (after, _) = scanmill::mesh::load(&output, &options).unwrap();
    assert_eq!(before.positions.len(), after.positions.len());
    for (i, (a, b)) in before.positions.iter().zip(&after.positions).enumerate() {
        assert!(a.distance(*b) < 1e-6, "vertex {i}: {a} became {b}");
    }
}

const TRIANGLE_MTL: &[u8] = b"newmtl m\nmap_Kd tex.png\n";

fn png() -> Vec<u8> {
    let mut bytes = Vec::new();
    image::RgbImage::new(4, 4)
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .unwrap();
    bytes
}

/// (what, files of the scan (first = input), expected exit code, text the error must contain)
type BadCase = (
    &'static str,
    Vec<(&'static str, Vec<u8>)>,
    i32,
    &'static str,
);

#[test]
fn bad_inputs_fail_clearly_and_leave_nothing_in_out() {
    let good_ply_header = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    let mut lying_ply = good_ply_header
        .replace("element vertex 3", "element vertex 30")
        .into_bytes();
    for v in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]] {
        for c in v {
            lying_ply.extend_from_slice(&c.to_le_bytes());
        }
    }
    lying_ply.push(3);
    for i in [0i32, 1, 2] {
        lying_ply.extend_from_slice(&i.to_le_bytes());
    }
    let png = png();
    let garbage: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
        .collect();
    let cases: Vec<BadCase> = vec![
        (
            "empty file",
            vec![("a.obj", vec![])],
            65,
            "no usable triangles",
        ),
        (
            "truncated file",
            vec![("a.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 ".to_vec())],
            65,
            "line 4",
        ),
        (
            "binary garbage",
            vec![("a.obj", garbage.clone())],
            65,
            "a.obj",
        ),
        ("binary garbage ply", vec![("a.ply", garbage)], 65, "a.ply"),
        (
            "NaN coordinate",
            vec![("a.obj", b"v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n".to_vec())],
            65,
            "line 2",
        ),
        (
            "index out of range",
            vec![("a.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n".to_vec())],
            65,
            "7",
        ),
        (
            "face with one corner",
            vec![("a.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1\n".to_vec())],
            65,
            "line 4",
        ),
        (
            "missing texture",
            vec![
                (
                    "a.obj",
                    b"mtllib a.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n"
                        .to_vec(),
                ),
                ("a.mtl", TRIANGLE_MTL.to_vec()),
            ],
            65,
            "tex.png",
        ),
        (
            "MTL path escaping the folder",
            vec![
                (
                    "scan/a.obj",
                    b"mtllib a.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_vec(),
                ),
                ("scan/a.mtl", b"newmtl m\nmap_Kd ../secret.png\n".to_vec()),
                ("secret.png", png),
            ],
            65,
            "resolves outside the scan's folder",
        ),
        (
            "PLY header lying about counts",
            vec![("a.ply", lying_ply)],
            65,
            "a.ply",
        ),
        (
            "missing file",
            vec![("other.obj", b"".to_vec())],
            66,
            "a.obj",
        ),
    ];
    for (what, files, expected_code, expected_text) in cases {
        let tmp = tempfile::tempdir().unwrap();
        let refs: Vec<(&str, &[u8])> = files.iter().map(|(n, c)| (*n, c.as_slice())).collect();
        let (_dir, first) = scan(&refs);
        let input = if what == "missing file" {
            first.with_file_name("a.obj")
        } else {
            first
        };
        let out = tmp.path().join("out");
        let Run { code, stderr, .. } = process(&input, &out);
        assert_eq!(code, Some(expected_code), "{what}: {stderr}");
        let line = stderr.trim_end();
        assert_eq!(line.lines().count(), 1, "{what}: not one line: {stderr}");
        assert!(line.starts_with("scanmill: error: "), "{what}: {line}");
        assert!(
            line.contains(expected_text),
            "{what}: expected {expected_text:?} in {line}"
        );
        assert!(
            entries(&out).is_empty(),
            "{what}: left {:?} in --out",
            entries(&out)
        );
    }
}

#[test]
fn recipe_errors_name_line_and_choices() {
    let tmp = tempfile::tempdir().unwrap();
    let recipe = tmp.path().join("r.toml");
    std::fs::write(
        &recipe,
        "[output]\nformat = \"obj\"\n\n[[step]]\nkind = \"sharpen\"\n",
    )
    .unwrap();
    let input = format!("{DATA}/untextured/stanford_bunny/bun_zipper_res4.ply");
    let out = tmp.path().join("out");
    let Run { code, stderr, .. } = run(&[
        "process",
        &input,
        "--recipe",
        recipe.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(78), "{stderr}");
    assert!(
        stderr.contains("r.toml") && stderr.contains("line 5") && stderr.contains("normals"),
        "{stderr}"
    );
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    assert!(!out.exists());
}

/// `scanmill inspect … | head`: a reader that closes its end before the output is written.
/// The command ends with success and says nothing (it used to panic with a backtrace).
#[test]
fn a_reader_that_stops_early_is_not_an_error() {
    let input = format!("{DATA}/textured/james_face_stereo_capture/james.obj");
    for json in [false, true] {
        let mut args = vec!["inspect", input.as_str()];
        if json {
            args.insert(1, "--json");
        }
        let mut child = Command::new(env!("CARGO_BIN_EXE_scanmill"))
            .args(&args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // The only read end goes before the scan is loaded (tens of milliseconds), so the
        // summary's write meets a closed pipe.
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "json {json}: {stderr}");
        assert!(stderr.is_empty(), "json {json}: {stderr}");
    }
}
