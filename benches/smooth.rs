//! Smoothing speed on the 269k-triangle igea scan: one iteration of each method (Taubin:
//! one λ+μ pair, i.e. two passes), the per-step setup (topology + CSR rows), and the
//! normal filter's whole step (set-up and its default rounds; throughput in triangles).
//! Throughput is in vertex updates (smoothed vertices × passes); the target is at least
//! 10 million per second on the project's 2-core machine.

use criterion::{BatchSize, Criterion, Throughput, criterion_group};
use scanmill::mesh::{LoadOptions, Mesh, ply};
use scanmill::ops::smooth::{MethodName, SmoothParams, SmoothParamsFile, Smoother, Weights};
use std::hint::black_box;
use std::io::Read;
use std::path::Path;

const IGEA: &str = "../shared/data/untextured/misc_scans/igea_cyberware_trilist_DERIVED.ply.gz";

fn load_igea() -> Option<Mesh> {
    let gz = std::fs::read(IGEA).ok()?;
    let mut bytes = Vec::new();
    flate2::read::GzDecoder::new(&gz[..])
        .read_to_end(&mut bytes)
        .ok()?;
    let options = LoadOptions {
        check_textures: false,
        ..Default::default()
    };
    Some(ply::read(Path::new(IGEA), &bytes, &options).ok()?.0)
}

fn one_iteration(method: MethodName, weights: Option<Weights>) -> SmoothParams {
    SmoothParams::try_from(SmoothParamsFile {
        method: Some(method),
        iterations: Some(1),
        weights,
        ..Default::default()
    })
    .unwrap()
}

fn bench(c: &mut Criterion) {
    let Some(mesh) = load_igea() else {
        panic!(
            "smooth bench: igea not found at {IGEA} (the benches read ../shared/data beside the checkout)"
        );
    };
    let mut group = c.benchmark_group("smooth igea 269k");
    group.sample_size(20);
    group.bench_function("setup (topology + rows)", |b| {
        b.iter(|| Smoother::new(black_box(&mesh), &one_iteration(MethodName::Laplace, None)))
    });
    let cases = [
        ("laplace", MethodName::Laplace, None),
        (
            "laplace cotangent",
            MethodName::Laplace,
            Some(Weights::Cotangent),
        ),
        ("hc", MethodName::Hc, None),
        ("taubin (λ+μ pair)", MethodName::Taubin, None),
        ("bilateral", MethodName::Bilateral, None),
    ];
    for (name, method, weights) in cases {
        let smoother = Smoother::new(&mesh, &one_iteration(method, weights));
        let passes = smoother.run(&mut mesh.positions.clone()).passes;
        let updates = smoother.graph().smoothed_vertices() as u64 * u64::from(passes);
        group.throughput(Throughput::Elements(updates));
        group.bench_function(format!("{name}: one iteration"), |b| {
            b.iter_batched_ref(
                || mesh.positions.clone(),
                |positions| smoother.run(positions),
                BatchSize::LargeInput,
            )
        });
    }
    // The normal filter's whole step with its defaults (4 rounds of 1 filter and 3 vertex
    // passes), set-up included: the target is 1 s on 2 cores.
    let defaults = SmoothParams::defaults(MethodName::NormalFilter);
    group.throughput(Throughput::Elements(mesh.triangles.len() as u64));
    group.bench_function("normal-filter: whole denoise (set-up + defaults)", |b| {
        b.iter_batched_ref(
            || mesh.positions.clone(),
            |positions| Smoother::new(&mesh, &defaults).run(positions),
            BatchSize::LargeInput,
        )
    });
    group.finish();
}

criterion_group!(benches, bench);
scanmill::criterion_main_on_pool!(benches);
