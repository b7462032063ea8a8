//! PLY read and write speed: a synthetic 400k-triangle binary file (the size target) and the
//! largest real PLY in the data (igea, 269k triangles).

use criterion::{Criterion, criterion_group};
use glam::DVec3;
use scanmill::mesh::ply::{self, PlyEncoding};
use scanmill::mesh::{Corner, LoadOptions, Mesh, MeshBuilder};
use std::hint::black_box;
use std::io::Read;
use std::path::Path;

/// A 449 x 449 height-field grid: 403,202 triangles.
fn grid(n: usize) -> Mesh {
    let mut b = MeshBuilder::new(Path::new("grid.ply"), "bench");
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (i as f64 * 0.01, j as f64 * 0.01);
            b.positions
                .push(DVec3::new(x, y, (x * 10.0).sin() * (y * 10.0).cos() * 0.1));
        }
    }
    let c = |v: usize| Corner {
        vertex: v as u32,
        texcoord: None,
        normal: None,
    };
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let a = j * n + i;
            b.faces.push([c(a), c(a + 1), c(a + n + 1)]);
            b.faces.push([c(a), c(a + n + 1), c(a + n)]);
        }
    }
    b.finish(&LoadOptions::default()).unwrap().0
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let mesh = grid(450);
    let path = dir.path().join("grid.ply");
    ply::write(&mesh, &path, PlyEncoding::BinaryLittleEndian).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let options = LoadOptions::default();

    let mut group = c.benchmark_group("ply");
    group.sample_size(10);
    group.bench_function("read 400k-triangle binary", |b| {
        b.iter(|| ply::read(&path, black_box(&bytes), &options).unwrap())
    });
    group.bench_function("write 400k-triangle binary", |b| {
        b.iter(|| ply::write(black_box(&mesh), &path, PlyEncoding::BinaryLittleEndian).unwrap())
    });
    let ascii = dir.path().join("grid_ascii.ply");
    group.bench_function("write 400k-triangle ascii", |b| {
        b.iter(|| ply::write(black_box(&mesh), &ascii, PlyEncoding::Ascii).unwrap())
    });

    let igea =
        Path::new("../shared/data/untextured/misc_scans/igea_cyberware_trilist_DERIVED.ply.gz");
    if let Ok(gz) = std::fs::read(igea) {
        let mut igea_bytes = Vec::new();
        flate2::read::GzDecoder::new(&gz[..])
            .read_to_end(&mut igea_bytes)
            .unwrap();
        group.bench_function("read igea 269k (binary)", |b| {
            b.iter(|| ply::read(igea, black_box(&igea_bytes), &options).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
scanmill::criterion_main_on_pool!(benches);
