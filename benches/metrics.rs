//! Metric time on a scanner-sized face: the facefuns face scan subdivided twice (955k
//! triangles) and cropped to its middle, about 400k triangles (the size target),
//! against a copy with the thesis' noise (σ = 0.2 × mean edge length along the normals).
//! Target: the surface distance (both BVH builds, both directions, default sample count)
//! under 1 s on two cores. The setup prints the metric values once, as a sanity line.

use criterion::{Criterion, criterion_group};
use scanmill::mesh::io::load;
use scanmill::mesh::{LoadOptions, Mesh};
use scanmill::metrics::noise::{NoiseOptions, noisy_copy};
use scanmill::metrics::surface::SurfaceIndex;
use scanmill::metrics::{self, MetricsOptions};
use scanmill::ops::crop::{CropMode, CropParams, crop};
use scanmill::ops::subdivide::subdivide;
use std::hint::black_box;
use std::path::Path;

const FACE: &str = "../shared/data/textured/facefuns_di3d_face/example.obj";

fn crop_middle(mesh: &Mesh, margin: f64) -> Option<Mesh> {
    let (lo, hi) = mesh.bounding_box()?;
    let margin = (hi - lo) * glam::DVec3::new(margin, margin, 0.0);
    let mut cropped = mesh.clone();
    crop(
        &mut cropped,
        &CropParams {
            min: Some((lo + margin).to_array()),
            max: Some((hi - margin).to_array()),
            mode: CropMode::AnyCornerOutside,
            ..Default::default()
        },
    )
    .ok()?;
    Some(cropped)
}

/// The face at about 400k triangles: subdivided twice (955k), then cropped to the middle
/// with the x/y margin that leaves closest to 400k (bisection).
fn face_400k() -> Option<Mesh> {
    let (mesh, _) = load(Path::new(FACE), &LoadOptions::default()).ok()?;
    let mesh = subdivide(&subdivide(&mesh));
    let (mut low, mut high) = (0.0, 0.3);
    let mut best = mesh.clone();
    for _ in 0..12 {
        let mid = 0.5 * (low + high);
        best = crop_middle(&mesh, mid)?;
        if best.triangles.len() > 400_000 {
            low = mid;
        } else {
            high = mid;
        }
    }
    Some(best)
}

use scanmill::geom::timing::cpu_seconds;

/// Wall and CPU seconds of `f`, the median of `runs` runs by wall time.
fn timed<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, f64) {
    let mut times: Vec<(f64, f64)> = (0..runs)
        .map(|_| {
            let (cpu, wall) = (cpu_seconds(), std::time::Instant::now());
            black_box(f());
            (wall.elapsed().as_secs_f64(), cpu_seconds() - cpu)
        })
        .collect();
    times.sort_by(|a, b| a.0.total_cmp(&b.0));
    times[runs / 2]
}

fn bench(c: &mut Criterion) {
    let Some(face) = face_400k() else {
        panic!(
            "metrics bench: {FACE} not found (the benches read ../shared/data beside the checkout)"
        );
    };
    let (noisy, noise) = noisy_copy(&face, &NoiseOptions::default());
    let options = MetricsOptions::default();
    let all = metrics::compare(&noisy, &face, &options).unwrap();
    eprintln!(
        "metrics bench: {} triangles, σ = {:.5} (0.2 × mean edge {:.5}), {} samples per direction",
        face.triangles.len(),
        noise.sigma,
        noise.mean_edge_length,
        options.samples
    );
    eprintln!(
        "sanity (noisy vs clean): {}",
        serde_json::to_string(&all).unwrap()
    );
    // CPU time next to wall time: on a loaded machine the wall time overstates the cost;
    // CPU seconds / 2 is what two idle cores would take (the work is parallel).
    for samples in [25_000, 50_000, 100_000, 200_000] {
        let (wall, cpu) = timed(5, || {
            metrics::distance::surface_distance(&noisy, &face, samples, options.seed).unwrap()
        });
        eprintln!(
            "surface distance, {samples} samples per direction: median wall {wall:.3} s, CPU {cpu:.2} s (threads: {})",
            rayon::current_num_threads()
        );
    }
    let (wall, cpu) = timed(5, || SurfaceIndex::new(&face, "reference").unwrap());
    eprintln!("one BVH build: median wall {wall:.3} s, CPU {cpu:.2} s");
    let (wall, cpu) = timed(3, || metrics::compare(&noisy, &face, &options).unwrap());
    eprintln!("all metrics: median wall {wall:.3} s, CPU {cpu:.2} s");

    let mut group = c.benchmark_group("metrics 400k face");
    group.sample_size(10);
    group.bench_function("BVH build (one mesh)", |b| {
        b.iter(|| SurfaceIndex::new(black_box(&face), "reference").unwrap())
    });
    group.bench_function("surface distance vs noisy copy (default samples)", |b| {
        b.iter(|| {
            metrics::distance::surface_distance(
                black_box(&noisy),
                &face,
                options.samples,
                options.seed,
            )
            .unwrap()
        })
    });
    group.bench_function("all metrics vs noisy copy", |b| {
        b.iter(|| metrics::compare(black_box(&noisy), &face, &options).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench);
scanmill::criterion_main_on_pool!(benches);
