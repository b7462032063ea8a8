//! Render time of the preview on a face scan at about 60k and 400k triangles (the facefuns
//! scan with its texture, and the same subdivided twice and cropped to the middle, as in
//! benches/metrics.rs), against its decimation to 26k faces. Prints the median wall time
//! and the CPU time (user + system) of that run, over `RUNS` runs.
//!
//! cargo run --release --example preview_timing [RUNS=5]

use scanmill::mesh::{LoadOptions, Mesh, load};
use scanmill::ops::crop::{CropMode, CropParams, crop};
use scanmill::ops::decimate::{DecimateParams, decimate};
use scanmill::ops::subdivide::subdivide;
use scanmill::preview::{PreviewOptions, render};
use std::path::{Path, PathBuf};

const FACE: &str = "../shared/data/textured/facefuns_di3d_face/example.obj";
const TEXTURE: &str = "../shared/data/textured/facefuns_di3d_face/example.png";

fn crop_middle(mesh: &Mesh, margin: f64) -> Mesh {
    let (lo, hi) = mesh.bounding_box().unwrap();
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
    .unwrap();
    cropped
}

fn face_400k(mesh: &Mesh) -> Mesh {
    let mesh = subdivide(&subdivide(mesh));
    let (mut low, mut high) = (0.0, 0.3);
    let mut best = mesh.clone();
    for _ in 0..12 {
        let mid = 0.5 * (low + high);
        best = crop_middle(&mesh, mid);
        if best.triangles.len() > 400_000 {
            low = mid;
        } else {
            high = mid;
        }
    }
    best
}

use scanmill::geom::timing::cpu_seconds;

fn main() {
    let runs: usize = std::env::args()
        .nth(1)
        .map(|s| s.parse().expect("RUNS"))
        .unwrap_or(5);
    let options = LoadOptions {
        texture_override: Some(PathBuf::from(TEXTURE)),
        ..LoadOptions::default()
    };
    let (face, _) = load(Path::new(FACE), &options).unwrap_or_else(|e| panic!("{e}"));
    let big = face_400k(&face);
    for input in [face, big] {
        let (result, _) = decimate(
            &input,
            &DecimateParams {
                target_faces: Some(26_000),
                ..DecimateParams::default()
            },
        )
        .unwrap();
        let (cpu, wall) = (cpu_seconds(), std::time::Instant::now());
        scanmill::metrics::distance::vertex_distances(&result, &input).unwrap();
        println!(
            "  of which the vertex distances (BVH over the input, closest points): wall {:.0} ms, cpu {:.0} ms",
            wall.elapsed().as_secs_f64() * 1e3,
            (cpu_seconds() - cpu) * 1e3
        );
        let mut times: Vec<(f64, f64)> = (0..runs)
            .map(|_| {
                let (cpu, wall) = (cpu_seconds(), std::time::Instant::now());
                let p = render(&input, &result, &PreviewOptions::default()).unwrap();
                std::hint::black_box(p.image);
                (wall.elapsed().as_secs_f64(), cpu_seconds() - cpu)
            })
            .collect();
        times.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (wall, cpu) = times[runs / 2];
        println!(
            "{} → {} triangles, 3 × 512² at 2×2 samples: median wall {:.0} ms, cpu {:.0} ms ({runs} runs)",
            input.triangles.len(),
            result.triangles.len(),
            wall * 1e3,
            cpu * 1e3
        );
    }
}
