//! Topology and summary of a synthetic 400k-triangle grid (the size of a large raw scan).
//! Target: `Topology::new` well under 0.2 s in release.

use criterion::{Criterion, criterion_group};
use glam::{DVec2, DVec3};
use scanmill::mesh::{Mesh, MeshSummary, Topology, Wedge};
use std::hint::black_box;

/// `n × n` vertices, two triangles per cell (2 (n − 1)² triangles), one wedge per vertex.
fn grid(n: u32) -> Mesh {
    let mut mesh = Mesh::default();
    for j in 0..n {
        for i in 0..n {
            mesh.positions.push(DVec3::new(i as f64, j as f64, 0.0));
            mesh.texcoords
                .push(DVec2::new(i as f64, j as f64) / n as f64);
            let v = j * n + i;
            mesh.wedges.push(Wedge {
                vertex: v,
                texcoord: Some(v),
                normal: None,
            });
        }
    }
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let v = j * n + i;
            mesh.triangles.push([v, v + 1, v + n + 1]);
            mesh.triangles.push([v, v + n + 1, v + n]);
        }
    }
    mesh
}

/// The same triangles in a scrambled order (worst case for memory locality).
fn shuffled(mut mesh: Mesh) -> Mesh {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    for i in (1..mesh.triangles.len()).rev() {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        mesh.triangles.swap(i, (state % (i as u64 + 1)) as usize);
    }
    mesh
}

fn bench(c: &mut Criterion) {
    let mesh = grid(448); // 399,618 triangles
    let scrambled = shuffled(mesh.clone());
    let mut group = c.benchmark_group("topology_400k");
    group.sample_size(20);
    group.bench_function("grid", |b| b.iter(|| Topology::new(black_box(&mesh))));
    group.bench_function("grid_shuffled", |b| {
        b.iter(|| Topology::new(black_box(&scrambled)))
    });
    group.bench_function("summary", |b| {
        b.iter(|| MeshSummary::new(black_box(&mesh), None))
    });
    group.finish();
}

criterion_group!(benches, bench);
scanmill::criterion_main_on_pool!(benches);
