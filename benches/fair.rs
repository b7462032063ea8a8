//! Fairing speed on a 200k-vertex scan: Lucy (50k vertices) subdivided once, with the
//! noise protocol (σ = 0.2 × mean edge along normals, seed 1). Target: the `fair` step
//! (fast schedule, defaults) in at most 2 s on 2 cores. Also `relax`, the thesis schedule
//! (a few iterations, per-iteration cost), and Taubin λ|μ ×13 as the reference a
//! smoothing step is compared with (written here, spec/smoothing.md §5).
//!
//! Run: `cargo bench --bench fair`. Each run prints vertex updates per second.

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use scanmill::mesh::{LoadOptions, Mesh, io};
use scanmill::metrics::noise::{NoiseOptions, noisy_copy};
use scanmill::ops::fair::{self, FairParams, RelaxParams, Schedule};
use scanmill::ops::subdivide::subdivide;
use std::hint::black_box;
use std::path::Path;

fn scan_200k() -> Mesh {
    let path = Path::new("../shared/data/untextured/misc_scans/stanford_lucy_100k.ply");
    let (lucy, _) = io::load(path, &LoadOptions::default()).expect("lucy");
    let (noisy, _) = noisy_copy(&subdivide(&lucy), &NoiseOptions::default());
    noisy
}

/// Taubin λ|μ: `passes` buffered umbrella passes alternating λ and μ.
fn taubin(mesh: &mut Mesh, lambda: f64, mu: f64, passes: usize) {
    let topo = mesh.topology();
    let mut old = mesh.positions.clone();
    for k in 0..passes {
        let f = if k % 2 == 0 { lambda } else { mu };
        old.copy_from_slice(&mesh.positions);
        for (v, p) in mesh.positions.iter_mut().enumerate() {
            let nb = topo.vertex_neighbours(v as u32);
            if !nb.is_empty() {
                let avg = nb.iter().map(|&j| old[j as usize]).sum::<DVec3>() / nb.len() as f64;
                *p = old[v] + f * (avg - old[v]);
            }
        }
    }
}

fn bench(c: &mut Criterion) {
    let mesh = scan_200k();
    let mut group = c.benchmark_group("fair_200k");
    group.sample_size(10);

    // One run of each, to print the figures the report carries.
    let mut m = mesh.clone();
    let r = fair::fair(&mut m, &FairParams::default());
    eprintln!(
        "fair (fast, defaults): {} vertices, {} iterations (×{}), {:.0} ms, {:.1} M vertex updates/s",
        mesh.positions.len(),
        r.iterations,
        r.time_scale,
        r.time_ms,
        r.updates_per_second / 1e6
    );

    group.bench_function("fair_fast_defaults", |b| {
        b.iter(|| {
            let mut m = mesh.clone();
            black_box(fair::fair(&mut m, &FairParams::default()))
        })
    });
    group.bench_function("relax_defaults", |b| {
        b.iter(|| {
            let mut m = mesh.clone();
            black_box(fair::relax(&mut m, &RelaxParams::default()))
        })
    });
    group.bench_function("fair_thesis_4_iterations", |b| {
        let p = FairParams {
            schedule: Schedule::Thesis,
            max_iterations: 4,
            ..FairParams::default()
        };
        b.iter(|| {
            let mut m = mesh.clone();
            black_box(fair::fair(&mut m, &p))
        })
    });
    group.bench_function("taubin_13", |b| {
        b.iter(|| {
            let mut m = mesh.clone();
            taubin(&mut m, 0.53, -0.54, 13);
            black_box(m.positions.len())
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
