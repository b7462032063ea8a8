//! Hostile inputs (issue #22, findings 1, 2, 3, 5, 8, 9): every one fails at once with a
//! one-line error naming the file and the reason or the limit, reads nothing outside the
//! scan's folder and copies nothing. Findings about the binary run the real `scanmill` under
//! a kill timer (a regression that hangs fails the test instead of hanging the run). The
//! memory bounds are in hostile_memory.rs, a test binary of its own (see hostile_support).

mod hostile_support;

use hostile_support::*;
use scanmill::mesh::limits::InputLimits;
use scanmill::mesh::{LoadOptions, MeshError, load};
use std::io::Write;
use std::path::Path;

// ---------------------------------------------------------------------------------------
// Findings 1 and 5: limits (memory bounds: hostile_memory.rs)

#[test]
fn decompressed_size_limit_names_its_key() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("x.obj.gz");
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    for i in 0..2000 {
        writeln!(enc, "v {i} {} {}", i * 7 % 13, i * 3 % 11).unwrap();
    }
    enc.write_all(b"f 1 2 3\n").unwrap();
    std::fs::write(&path, enc.finish().unwrap()).unwrap();
    let mut options = LoadOptions::default();
    load(&path, &options).unwrap();
    options.limits.max_decompressed_bytes = 4096;
    let e = load(&path, &options).unwrap_err();
    assert!(matches!(e, MeshError::TooLarge { .. }), "{e}");
    assert!(
        e.to_string()
            .ends_with("decompressed size exceeds limits.max_decompressed_bytes = 4096"),
        "{e}"
    );
}

#[test]
fn one_image_named_by_300_materials_is_decoded_once() {
    let mut mtl = String::new();
    let mut obj = format!("mtllib scan.mtl\n{TRI}");
    for m in 0..300 {
        mtl.push_str(&format!("newmtl m{m}\nmap_Kd skin.png\n"));
        obj.push_str(&format!("usemtl m{m}\nf 1/1 2/2 3/3\n"));
    }
    let (_tmp, dir, _out) = scan_dir(&[
        ("scan.obj", obj.as_bytes()),
        ("scan.mtl", mtl.as_bytes()),
        ("skin.png", &png(32, 32, [9, 9, 9])),
    ]);
    let r = run(&["inspect", "--json", dir.join("scan.obj").to_str().unwrap()]);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    let json: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    assert_eq!(json["materials"].as_array().unwrap().len(), 300);
    assert_eq!(json["load"]["decoded_textures"], 1);
    // Each distinct file counts against the budget once: 300 × 1024 pixels would not fit.
    let mut options = LoadOptions::default();
    options.limits.max_texture_pixels = 32 * 32;
    let (mesh, report) = load(&dir.join("scan.obj"), &options).unwrap();
    assert_eq!(report.decoded_textures, 1);
    assert!(
        mesh.materials
            .iter()
            .all(|m| m.diffuse_texture.as_ref().unwrap().size == Some((32, 32)))
    );
}

#[test]
fn mtl_above_its_limit_is_refused_before_reading() {
    let big = format!("newmtl m\n{}", "Kd 1 1 1\n".repeat(200_000));
    let (_tmp, dir, _out) = scan_dir(&[]);
    write_all(&dir, &obj_with_mtl(&big));
    let mut options = LoadOptions::default();
    load(&dir.join("scan.obj"), &options).unwrap();
    options.limits.max_mtl_bytes = 1 << 20;
    let e = load(&dir.join("scan.obj"), &options).unwrap_err();
    assert!(
        e.to_string()
            .contains("scan.mtl: file size 1800009 bytes exceeds limits.max_mtl_bytes = 1048576"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------------------
// Findings 2 and 3: paths

#[test]
fn backslash_parent_path_is_refused_even_with_a_literal_file_of_that_name() {
    let (_tmp, dir, out) = scan_dir(&[]);
    // As many `..\` as it takes from the scan's folder to the root, then `etc\passwd`.
    let depth = dir.canonicalize().unwrap().components().count() - 1;
    let name = format!("{}etc\\passwd", "..\\".repeat(depth));
    let mut files = obj_with_mtl(&format!("newmtl m\nmap_Kd t.png\nmap_Bump {name}\n"));
    files.push(("t.png", png(4, 4, [0, 0, 0])));
    write_all(&dir, &files);
    // A file whose name is literally the backslash path, inside the scan's folder.
    std::fs::write(dir.join(&name), b"not the real passwd").unwrap();
    assert!(dir.join(&name).is_file());
    let r = process(&dir.join("scan.obj"), &out);
    assert_refused(
        &r,
        &out,
        &[
            "scan.mtl",
            "resolves outside the scan's folder (/etc/passwd); refusing",
        ],
    );
    let r = inspect(&dir.join("scan.obj"));
    assert_eq!(r.code, Some(65), "{}", r.stderr);
}

#[test]
fn references_outside_the_scan_folder_are_refused() {
    let outside = tempfile::tempdir().unwrap();
    let secret_png = outside.path().join("secret.png");
    std::fs::write(&secret_png, png(4, 4, [255, 0, 0])).unwrap();
    let secret_mtl = outside.path().join("secret.mtl");
    std::fs::write(&secret_mtl, "newmtl m\n").unwrap();
    let link = |dir: &Path, name: &str, target: &Path| {
        std::os::unix::fs::symlink(target, dir.join(name)).unwrap();
    };
    type Case = (
        &'static str,
        fn(&Path, &Path) -> Vec<(&'static str, Vec<u8>)>,
    );
    let cases: [Case; 5] = [
        ("symlinked mtllib", |_, _| {
            vec![(
                "scan.obj",
                format!("mtllib scan.mtl\n{TRI}usemtl m\nf 1/1 2/2 3/3\n").into_bytes(),
            )]
        }),
        ("symlinked map_Kd", |_, _| {
            obj_with_mtl("newmtl m\nmap_Kd skin.png\n")
        }),
        ("symlinked map_Bump", |_, _| {
            let mut f = obj_with_mtl("newmtl m\nmap_Kd t.png\nmap_Bump -bm 0.5 skin.png\n");
            f.push(("t.png", png(4, 4, [0, 0, 0])));
            f
        }),
        ("absolute map_Kd", |_, secret| {
            obj_with_mtl(&format!("newmtl m\nmap_Kd {}\n", secret.display()))
        }),
        ("parent map_Kd", |_, _| {
            obj_with_mtl("newmtl m\nmap_Kd ../../../../secret.png\n")
        }),
    ];
    for (what, files) in cases {
        let (_tmp, dir, out) = scan_dir(&[]);
        write_all(&dir, &files(&dir, &secret_png));
        match what {
            "symlinked mtllib" => link(&dir, "scan.mtl", &secret_mtl),
            "symlinked map_Kd" | "symlinked map_Bump" => link(&dir, "skin.png", &secret_png),
            _ => {}
        }
        let r = process(&dir.join("scan.obj"), &out);
        assert_eq!(r.code, Some(65), "{what}: {}", r.stderr);
        assert!(
            r.stderr.contains("resolves outside the scan's folder"),
            "{what}: {}",
            r.stderr
        );
        // The refusal says what the file was named as.
        let role = match what {
            "symlinked mtllib" => "material library path \"scan.mtl\"",
            _ => "texture path",
        };
        assert!(r.stderr.contains(role), "{what}: {}", r.stderr);
        assert_eq!(tree(&out), Vec::<String>::new(), "{what}");
    }

    // A PLY whose TextureFile is a symlink to an outside image.
    let (_tmp, dir, out) = scan_dir(&[(
        "scan.ply",
        b"ply\nformat ascii 1.0\ncomment TextureFile skin.png\nelement vertex 3\n\
          property float x\nproperty float y\nproperty float z\nelement face 1\n\
          property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
    )]);
    link(&dir, "skin.png", &secret_png);
    let r = process(&dir.join("scan.ply"), &out);
    assert_refused(
        &r,
        &out,
        &["scan.ply", "resolves outside the scan's folder"],
    );
}

// ---------------------------------------------------------------------------------------
// Finding 9: special files

#[test]
fn fifos_and_devices_are_refused_at_once() {
    let (_tmp, dir, out) = scan_dir(&[]);
    let fifo = dir.join("f.obj");
    mkfifo(&fifo);
    let zero = dir.join("z.ply");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    for (input, kind) in [
        (&fifo, "is a FIFO; refusing to read it"),
        (&zero, "is a character device; refusing to read it"),
    ] {
        for r in [inspect(input), process(input, &out)] {
            assert_refused(&r, &out, &[kind]);
        }
    }
    let r = run(&["inspect", "/dev/zero"]);
    assert_eq!(r.code, Some(65), "{}", r.stderr);

    // A FIFO named as a texture or a material library is refused by the loader too.
    let mut files = obj_with_mtl("newmtl m\nmap_Kd t.png\n");
    files.retain(|(n, _)| *n != "scan.mtl");
    write_all(&dir, &files);
    mkfifo(&dir.join("scan.mtl"));
    let r = process(&dir.join("scan.obj"), &out);
    assert_refused(&r, &out, &["scan.mtl is a FIFO; refusing to read it"]);
    std::fs::remove_file(dir.join("scan.mtl")).unwrap();
    write_all(&dir, &obj_with_mtl("newmtl m\nmap_Kd t.png\n"));
    mkfifo(&dir.join("t.png"));
    let r = process(&dir.join("scan.obj"), &out);
    assert_refused(&r, &out, &["t.png is a FIFO; refusing to read it"]);
}

#[test]
fn weld_tolerance_out_of_range_is_a_usage_error() {
    let (_tmp, dir, _out) = scan_dir(&[("s.obj", format!("{TRI}f 1 2 3\n").as_bytes())]);
    let input = dir.join("s.obj");
    for bad in ["nan", "-1", "0.5"] {
        let r = run(&[
            "inspect",
            input.to_str().unwrap(),
            &format!("--weld-tolerance={bad}"),
        ]);
        assert_eq!(r.code, Some(78), "{bad}: {}", r.stderr);
        assert!(r.stderr.contains("weld_tolerance must be"), "{}", r.stderr);
    }
    let recipe = dir.join("r.toml");
    std::fs::write(&recipe, "[input]\nweld_tolerance = 1e300\n").unwrap();
    let out = dir.join("out");
    let r = run(&[
        "process",
        input.to_str().unwrap(),
        "--recipe",
        recipe.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.code, Some(78), "{}", r.stderr);
    assert!(
        r.stderr.contains("line 2: [input]: weld_tolerance"),
        "{}",
        r.stderr
    );
}

// ---------------------------------------------------------------------------------------
// Finding 8: generated names and output errors

#[test]
fn textures_named_like_the_sidecar_or_the_preview_do_not_collide() {
    let red = png(8, 8, [255, 0, 0]);
    let blue = png(8, 8, [0, 0, 255]);
    let obj = format!("mtllib scan.mtl\n{TRI}usemtl a\nf 1/1 2/2 3/3\nusemtl b\nf 1/1 3/3 2/2\n");
    let mtl = "newmtl a\nmap_Kd scan.scanmill.json\nnewmtl b\nmap_Kd scan.preview.png\n";
    let (_tmp, dir, out) = scan_dir(&[
        ("scan.obj", obj.as_bytes()),
        ("scan.mtl", mtl.as_bytes()),
        ("scan.scanmill.json", &red),
        ("scan.preview.png", &blue),
    ]);
    let r = process(&dir.join("scan.obj"), &out);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    assert_eq!(
        tree(&out),
        [
            "scan.mtl",
            "scan.obj",
            "scan.preview.png",
            "scan.preview_2.png",
            "scan.scanmill_2.json"
        ]
    );
    // The copies hold the textures; the preview is scanmill's own picture; the sidecar's
    // name is left free for the daemon.
    assert_eq!(
        std::fs::read(out.join("scan.scanmill_2.json")).unwrap(),
        red
    );
    assert_eq!(std::fs::read(out.join("scan.preview_2.png")).unwrap(), blue);
    let preview = image::open(out.join("scan.preview.png")).unwrap();
    assert!(preview.width() > 8, "{}", preview.width());
    let mtl_out = std::fs::read_to_string(out.join("scan.mtl")).unwrap();
    assert!(
        mtl_out.contains("map_Kd scan.scanmill_2.json\n")
            && mtl_out.contains("map_Kd scan.preview_2.png\n"),
        "{mtl_out}"
    );
}

#[test]
fn a_full_disk_while_writing_is_an_output_error() {
    use scanmill::process::{ProcessError, write_mesh};
    let (_tmp, dir, _out) = scan_dir(&[("s.obj", format!("{TRI}f 1 2 3\n").as_bytes())]);
    let (mesh, _) = load(&dir.join("s.obj"), &LoadOptions::default()).unwrap();
    let recipe = scanmill::recipe::Recipe::from_path(Path::new(RECIPE)).unwrap();
    let target = tempfile::tempdir().unwrap();
    // Writes to /dev/full fail with ENOSPC, as on a full disk.
    std::os::unix::fs::symlink("/dev/full", target.path().join("r.obj")).unwrap();
    let e = write_mesh(&mesh, &recipe, target.path(), "r").unwrap_err();
    assert!(matches!(e, ProcessError::Output { .. }), "{e}");
    assert!(e.is_transient());
    assert!(e.to_string().contains("No space left on device"), "{e}");
}

#[test]
fn lowered_file_size_limit_names_its_key() {
    let limits = InputLimits::default();
    assert!(limits.validate().is_empty());
    let (_tmp, dir, _out) = scan_dir(&[("s.obj", format!("{TRI}f 1 2 3\n").as_bytes())]);
    let mut options = LoadOptions::default();
    options.limits.max_file_bytes = 10;
    let e = load(&dir.join("s.obj"), &options).unwrap_err();
    assert!(
        e.to_string().contains("exceeds limits.max_file_bytes = 10"),
        "{e}"
    );
}

#[test]
fn the_daemon_configuration_has_a_validated_limits_table() {
    use scanmill::config::DaemonConfig;
    let parse = |text: &str| DaemonConfig::from_toml(text, Path::new("c.toml"));
    let config = parse("[limits]\nmax_texture_pixels = 1000000\n").unwrap();
    assert_eq!(config.limits.max_texture_pixels, 1_000_000);
    assert_eq!(
        config.limits.max_gzip_ratio,
        InputLimits::default().max_gzip_ratio
    );
    assert!(parse("[limits]\nmax_pixels = 1\n").is_err());
    let bad = parse("[limits]\nmax_gzip_ratio = 0\n").unwrap();
    let problems = bad.validate().join("\n");
    assert!(
        problems.contains("limits.max_gzip_ratio must be 2..=1048576, not 0"),
        "{problems}"
    );
}
