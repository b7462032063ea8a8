//! OBJ read and write speed on a scanner-sized textured mesh: the facefuns face (60k
//! triangles, one texture) subdivided twice 1→4 and cut to its first 400,000 triangles
//! (about 34 MB of OBJ). `load` is the whole path (read, parse, MTL, texture check, welding
//! and repair); `parse` is the OBJ parser alone, without `MeshBuilder::finish`.

use criterion::{Criterion, criterion_group};
use scanmill::mesh::{LoadOptions, Mesh, load, obj};
use scanmill::ops::subdivide::subdivide;
use std::hint::black_box;
use std::path::Path;

const TRIANGLES: usize = 400_000;

fn textured_face() -> Option<Mesh> {
    let dir = Path::new("../shared/data/textured/facefuns_di3d_face");
    let options = LoadOptions {
        texture_override: Some(dir.join("example.png")),
        ..Default::default()
    };
    let (face, _) = load(&dir.join("example.obj"), &options).ok()?;
    let mut mesh = subdivide(&subdivide(&face));
    mesh.triangles.truncate(TRIANGLES);
    mesh.triangle_materials.truncate(TRIANGLES);
    mesh.triangle_origins.truncate(TRIANGLES);
    mesh.compact();
    Some(mesh)
}

fn bench(c: &mut Criterion) {
    let Some(mesh) = textured_face() else {
        panic!(
            "obj_io bench: the textured face in ../shared/data not found (the benches read ../shared/data beside the checkout)"
        );
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("face400k.obj");
    obj::write(&mesh, &path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let options = LoadOptions::default();
    let parse_options = LoadOptions {
        check_textures: false,
        ..Default::default()
    };

    let mut group = c.benchmark_group("obj");
    group.sample_size(10);
    group.bench_function("load 400k-triangle textured", |b| {
        b.iter(|| load(black_box(&path), &options).unwrap())
    });
    group.bench_function("parse 400k-triangle textured", |b| {
        b.iter(|| obj::parse(&path, black_box(&bytes), &parse_options).unwrap())
    });
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let out = out.join("face.obj");
    group.bench_function("write 400k-triangle textured", |b| {
        b.iter(|| obj::write(black_box(&mesh), &out).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench);
scanmill::criterion_main_on_pool!(benches);
