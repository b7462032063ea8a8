//! Load and write speed of GLB and STL beside OBJ and PLY (issue #28), all on one
//! 400,000-triangle textured face scan made as benches/face_scan.rs makes it (the facefuns
//! face, `scanner_sized`, noise σ = 0.1 × mean edge length, seed 1), in one run so that the
//! four formats see the same machine state. `load` is the whole path (read, parse, texture
//! check, welding and repair). STL is load only: scanmill does not write STL.
//!
//! cargo bench --bench formats_io; figures in docs/formats.md.

mod common;

use common::face400k;
use criterion::{Criterion, criterion_group};
use scanmill::mesh::ply::PlyEncoding;
use scanmill::mesh::{LoadOptions, Mesh, SaveOptions, load, save};
use std::hint::black_box;
use std::io::Write;
use std::path::Path;
use std::time::Duration;

/// The mesh's triangles as an STL (binary, or ASCII with `f32` coordinates in shortest form).
fn write_stl(mesh: &Mesh, path: &Path, binary: bool) {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let corners = |t: usize| mesh.triangle_positions(t).map(|p| p.as_vec3());
    if binary {
        out.write_all(&[b' '; 80]).unwrap();
        out.write_all(&(mesh.triangle_count() as u32).to_le_bytes())
            .unwrap();
        for t in 0..mesh.triangle_count() {
            out.write_all(&[0u8; 12]).unwrap();
            for v in corners(t).iter().flat_map(|p| p.to_array()) {
                out.write_all(&v.to_le_bytes()).unwrap();
            }
            out.write_all(&[0, 0]).unwrap();
        }
    } else {
        writeln!(out, "solid face").unwrap();
        for t in 0..mesh.triangle_count() {
            writeln!(out, "facet normal 0 0 0\nouter loop").unwrap();
            for p in corners(t) {
                writeln!(out, "vertex {} {} {}", p.x, p.y, p.z).unwrap();
            }
            writeln!(out, "endloop\nendfacet").unwrap();
        }
        writeln!(out, "endsolid face").unwrap();
    }
    out.flush().unwrap();
}

fn bench(c: &mut Criterion) {
    let Some(mesh) = face400k() else {
        panic!(
            "formats_io bench: the face scan in ../shared/data not found (the benches read ../shared/data beside the checkout)"
        );
    };
    let dir = tempfile::tempdir().unwrap();
    let inputs = dir.path().join("in");
    std::fs::create_dir(&inputs).unwrap();
    let file = |ext: &str| inputs.join(format!("face400k.{ext}"));
    let ply = SaveOptions {
        ply_encoding: PlyEncoding::BinaryLittleEndian,
    };
    for (ext, options) in [("obj", SaveOptions::default()), ("ply", ply), ("glb", ply)] {
        save(&mesh, &file(ext), &options).unwrap();
    }
    write_stl(&mesh, &file("stl"), true);
    let ascii_stl = inputs.join("face400k_ascii.stl");
    write_stl(&mesh, &ascii_stl, false);
    for f in std::fs::read_dir(&inputs).unwrap() {
        let f = f.unwrap();
        eprintln!(
            "{}: {} bytes",
            f.file_name().to_string_lossy(),
            f.metadata().unwrap().len()
        );
    }

    let options = LoadOptions::default();
    let mut group = c.benchmark_group("formats");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(8));
    for ext in ["obj", "ply", "glb", "stl"] {
        let path = file(ext);
        group.bench_function(format!("load 400k {ext}"), |b| {
            b.iter(|| load(black_box(&path), &options).unwrap())
        });
    }
    group.bench_function("load 400k stl (ascii)", |b| {
        b.iter(|| load(black_box(&ascii_stl), &options).unwrap())
    });
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    for ext in ["obj", "ply", "glb"] {
        let path = out.join(format!("face.{ext}"));
        group.bench_function(format!("write 400k {ext}"), |b| {
            b.iter(|| save(black_box(&mesh), &path, &ply).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
scanmill::criterion_main_on_pool!(benches);
