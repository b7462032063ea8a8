//! Quality probe for `relax` + `fair` on the noise protocol (issue #4): distance to the
//! clean scan against the number of iterations and the parameters, split by region.
//! `cargo run --release --example fair_probe` with settings in the environment:
//!
//! - `FP_SCANS`: comma list of facefuns, lucy, igea, bunny (default all four);
//! - `FP_CAPS`: comma list of `max_iterations` (thesis iterations) to run, each from the
//!   noisy scan (default the `fair` default);
//! - `FP_LAMBDA`, `FP_LAMBDA_U`, `FP_TH`, `FP_TU`, `FP_STOP`, `FP_SCHEDULE` (`fast` or
//!   `thesis`), `FP_RELAX` (`1`: relax first), `FP_RELAX_ITER`, `FP_BOUNDARY` (`fair` or
//!   `fixed`), `FP_SAMPLES` (default 100000);
//! - `FP_REGIONS=1`: split the per-vertex distance by the number of edges to the border.

#[path = "common/noise_protocol.rs"]
mod noise_protocol;

use noise_protocol::{SCANS, load, noisy, taubin, wanted};
use scanmill::mesh::Mesh;
use scanmill::metrics::distance::{surface_distance, vertex_distances};
use scanmill::metrics::volume;
use scanmill::ops::border::Border;
use scanmill::ops::fair::{self, FairParams, RelaxParams, Schedule};
use scanmill::ops::smooth::TaubinCount;
use std::time::Instant;

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|s| s.parse().ok())
}

/// Edges from each vertex to the nearest border vertex (u32::MAX without a border).
fn border_hops(mesh: &Mesh) -> Vec<u32> {
    let topo = mesh.topology();
    let n = mesh.positions.len();
    let mut hops = vec![u32::MAX; n];
    let mut queue = std::collections::VecDeque::new();
    for (v, h) in hops.iter_mut().enumerate() {
        if topo.is_boundary_vertex(v as u32) {
            *h = 0;
            queue.push_back(v);
        }
    }
    while let Some(v) = queue.pop_front() {
        for &j in topo.vertex_neighbours(v as u32) {
            if hops[j as usize] == u32::MAX {
                hops[j as usize] = hops[v] + 1;
                queue.push_back(j as usize);
            }
        }
    }
    hops
}

fn quality_class(mesh: &Mesh) -> Vec<u32> {
    let mut worst = vec![1.0f64; mesh.positions.len()];
    for t in 0..mesh.triangles.len() {
        let [a, b, c] = mesh.triangle_vertices(t);
        let (pa, pb, pc) = (
            mesh.positions[a as usize],
            mesh.positions[b as usize],
            mesh.positions[c as usize],
        );
        let s =
            (pb - pa).length_squared() + (pc - pb).length_squared() + (pa - pc).length_squared();
        let q = 2.0 * 3f64.sqrt() * (pb - pa).cross(pc - pa).length() / s;
        for v in [a, b, c] {
            worst[v as usize] = worst[v as usize].min(q);
        }
    }
    worst
        .iter()
        .map(|&q| {
            if q < 0.2 {
                0
            } else if q < 0.4 {
                2
            } else if q < 0.7 {
                5
            } else {
                20
            }
        })
        .collect()
}

const CLASSES: [(&str, u32, u32); 4] = [
    ("border", 0, 0),
    ("1-3", 1, 3),
    ("4-10", 4, 10),
    (">10", 11, u32::MAX),
];

fn regions(mesh: &Mesh, clean: &Mesh, hops: &[u32]) -> String {
    let d = vertex_distances(mesh, clean).unwrap();
    let total: f64 = d.iter().sum();
    CLASSES
        .iter()
        .map(|&(name, lo, hi)| {
            let (s, c) = d
                .iter()
                .zip(hops)
                .filter(|&(_, &h)| (lo..=hi).contains(&h))
                .fold((0.0, 0usize), |(s, c), (x, _)| (s + x, c + 1));
            format!(
                "{name}: n {c} mean {:.3e} share {:.0}%",
                if c > 0 { s / c as f64 } else { 0.0 },
                100.0 * s / total
            )
        })
        .collect::<Vec<_>>()
        .join("; ")
}

fn main() {
    let samples: usize = env("FP_SAMPLES").unwrap_or(100_000);
    let mut params = FairParams::default();
    if let Some(x) = env("FP_LAMBDA") {
        params.lambda = x;
    }
    if let Some(x) = env("FP_LAMBDA_U") {
        params.lambda_u = x;
    }
    if let Some(x) = env("FP_TH") {
        params.t_h = x;
    }
    if let Some(x) = env("FP_TU") {
        params.t_u = x;
    }
    if let Some(x) = env("FP_STOP") {
        params.stop = x;
    }
    if env::<String>("FP_SCHEDULE").as_deref() == Some("thesis") {
        params.schedule = Schedule::Thesis;
    }
    let mut relax_params = RelaxParams::default();
    if let Some(x) = env("FP_RELAX_ITER") {
        relax_params.max_iterations = x;
    }
    if env::<String>("FP_BOUNDARY").as_deref() == Some("fixed") {
        params.boundary = Border::Fixed;
        relax_params.boundary = Border::Fixed;
    }
    let caps: Vec<u32> = env::<String>("FP_CAPS").map_or(vec![params.max_iterations], |s| {
        s.split(',').map(|x| x.trim().parse().unwrap()).collect()
    });
    let relax_first = env::<u32>("FP_RELAX") == Some(1);
    let split = env::<u32>("FP_REGIONS").is_some_and(|x| x > 0);
    println!(
        "params: lambda {} lambda_u {} t_h {} t_u {} stop {} {:?} relax {relax_first} boundary {:?}",
        params.lambda,
        params.lambda_u,
        params.t_h,
        params.t_u,
        params.stop,
        params.schedule,
        params.boundary
    );
    for (name, rel) in SCANS {
        if !wanted(name) {
            continue;
        }
        let clean = load(rel);
        // FP_CLEAN=1: fair the clean scan instead, to see the shape change alone.
        let noisy = if env::<u32>("FP_CLEAN") == Some(1) {
            clean.clone()
        } else {
            noisy(&clean)
        };
        let dist = |m: &Mesh| surface_distance(m, &clean, samples, 7).unwrap().mean;
        let vol = |m: &Mesh| {
            volume::compare(m, &clean)
                .change_percent
                .map_or("open".to_string(), |v| format!("{v:+.3}%"))
        };
        let mut t = noisy.clone();
        taubin(&mut t, 13, TaubinCount::Pairs);
        let (dn, dt) = (dist(&noisy), dist(&t));
        println!(
            "{name}: V {} noisy {dn:.4e}, Taubin {:.3} of noisy, vol {}",
            clean.positions.len(),
            dt / dn,
            vol(&t)
        );
        // FP_REGIONS=2: split by the worst triangle quality around the vertex instead
        // (bins 0: < 0.2, 1-3: < 0.4, 4-10: < 0.7, >10: the rest).
        let hops = split.then(|| {
            if env::<u32>("FP_REGIONS") == Some(2) {
                quality_class(&clean)
            } else {
                border_hops(&clean)
            }
        });
        if let Some(h) = &hops {
            println!("  noisy  {}", regions(&noisy, &clean, h));
            println!("  taubin {}", regions(&t, &clean, h));
        }
        let mut start = noisy.clone();
        if relax_first {
            let r = fair::relax(&mut start, &relax_params);
            let d = dist(&start);
            println!(
                "  relax: {:.3} of noisy, {:.3} of Taubin, {} it, {:.0} ms",
                d / dn,
                d / dt,
                r.iterations,
                r.time_ms
            );
        }
        for &cap in &caps {
            let mut m = start.clone();
            let p = FairParams {
                max_iterations: cap,
                ..params.clone()
            };
            let w = Instant::now();
            let r = fair::fair(&mut m, &p);
            let ms = w.elapsed().as_secs_f64() * 1e3;
            let d = dist(&m);
            println!(
                "  cap {cap:5}: {:.3} of noisy, {:.3} of Taubin, vol {}, {} it (×{}) conv {} {:.0} ms, flips avoided {} degenerate {} skipped {}",
                d / dn,
                d / dt,
                vol(&m),
                r.iterations,
                r.time_scale,
                r.converged,
                ms,
                r.flips_avoided,
                r.degenerate_avoided,
                r.moves_skipped
            );
            if let Some(h) = &hops {
                println!("    ours {}", regions(&m, &clean, h));
            }
        }
    }
}
