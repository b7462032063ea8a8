//! Fairing speed on a 200k-vertex scan: Lucy (50k vertices) subdivided once, with the
//! noise protocol (σ = 0.2 × mean edge along normals, seed 1). Target: the `fair` step
//! (fast schedule, defaults) in at most 2 s on 2 cores. Also `relax`, the thesis schedule
//! (a few iterations, per-iteration cost), and Taubin λ|μ (the `smooth` step's, 13 pairs)
//! as the reference a smoothing step is compared with.
//!
//! Run: `cargo bench --bench fair`. Each run prints vertex updates per second.

use criterion::{Criterion, criterion_group};
use scanmill::mesh::{LoadOptions, Mesh, io};
use scanmill::metrics::noise::{NoiseOptions, noisy_copy};
use scanmill::ops::fair::{self, FairParams, RelaxParams, Schedule};
use scanmill::ops::smooth::{MethodName, SmoothParams, smooth};
use scanmill::ops::subdivide::subdivide;
use std::hint::black_box;
use std::path::Path;

fn scan_200k() -> Mesh {
    let path = Path::new("../shared/data/untextured/misc_scans/stanford_lucy_100k.ply");
    let (lucy, _) = io::load(path, &LoadOptions::default()).expect("lucy");
    let (noisy, _) = noisy_copy(&subdivide(&lucy), &NoiseOptions::default());
    noisy
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
    group.bench_function("taubin_13_pairs", |b| {
        let p = SmoothParams::defaults(MethodName::Taubin);
        b.iter(|| {
            let mut m = mesh.clone();
            black_box(smooth(&mut m, &p))
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
scanmill::criterion_main_on_pool!(benches);
