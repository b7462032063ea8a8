//! Speed probe: smoothing throughput on one scan, per method, for the closing figures.
//! `cargo run --release --example smooth_probe -- SCAN [ITERATIONS] [METHOD…]`
//! (METHOD: only the cases whose name starts with it, e.g. `bilateral`)
//!
//! Prints wall-clock throughput and, because the project machine is shared, also the
//! throughput implied by the process' CPU time (utime + stime from /proc/self/stat) spread
//! over the worker threads: what two dedicated cores would give if the work scales.

use scanmill::mesh::{LoadOptions, load};
use scanmill::ops::smooth::{MethodName, SmoothParams, SmoothParamsFile, Smoother, Weights};
use std::path::Path;

use scanmill::geom::timing::cpu_seconds;

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args
        .next()
        .expect("usage: smooth_probe SCAN [ITERATIONS] [METHOD...]");
    let iterations: u32 = args.next().map_or(20, |s| s.parse().unwrap());
    let only: Vec<String> = args.collect();
    let options = LoadOptions {
        check_textures: false,
        ..Default::default()
    };
    let (mesh, _) = load(Path::new(&path), &options).unwrap();
    let threads = rayon::current_num_threads();
    ball_coverage(&mesh);
    println!(
        "{path}: {} vertices, {} triangles, {threads} threads, {iterations} iterations per run",
        mesh.positions.len(),
        mesh.triangles.len()
    );
    let file = |method, weights, rings| SmoothParamsFile {
        method: Some(method),
        iterations: Some(iterations),
        weights,
        rings,
        ..Default::default()
    };
    let cases = [
        ("laplace", file(MethodName::Laplace, None, None)),
        (
            "laplace cot",
            file(MethodName::Laplace, Some(Weights::Cotangent), None),
        ),
        ("hc", file(MethodName::Hc, None, None)),
        ("taubin", file(MethodName::Taubin, None, None)),
        ("bilateral", file(MethodName::Bilateral, None, None)),
        ("bilateral 3", file(MethodName::Bilateral, None, Some(3))),
    ];
    for (name, file) in cases {
        if !only.is_empty() && !only.iter().any(|o| name.starts_with(o.as_str())) {
            continue;
        }
        let params = SmoothParams::try_from(file).unwrap();
        let start = std::time::Instant::now();
        let smoother = Smoother::new(&mesh, &params);
        let setup = start.elapsed().as_secs_f64();
        let mut runs = Vec::new();
        for _ in 0..5 {
            let mut positions = mesh.positions.clone();
            let (cpu, start) = (cpu_seconds(), std::time::Instant::now());
            let passes = smoother.run(&mut positions).passes;
            runs.push((start.elapsed().as_secs_f64(), cpu_seconds() - cpu, passes));
        }
        runs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (wall, cpu, passes) = runs[2];
        let updates = smoother.graph().smoothed_vertices() as f64 * f64::from(passes);
        println!(
            "{name:<12} setup {:>6.1} ms | per pass {:>7.2} ms wall | {:>6.1} M updates/s wall, {:>6.1} M/s by CPU time",
            setup * 1e3,
            wall * 1e3 / f64::from(passes),
            updates / wall / 1e6,
            if cpu > 0.0 {
                updates / (cpu / threads as f64) / 1e6
            } else {
                f64::NAN
            },
        );
    }
}

/// How many of the vertices a breadth-first search inside the default bilateral ball
/// (ρ = 1.8 mean edges) finds are in the 2-ring.
fn ball_coverage(mesh: &scanmill::mesh::Mesh) {
    let topo = mesh.topology();
    let rho = 1.8 * mesh.mean_edge_length();
    let n = mesh.positions.len();
    let (mut ball, mut in_two) = (0usize, 0usize);
    let mut mark = vec![u32::MAX; n];
    let mut ring2 = vec![u32::MAX; n];
    let mut ring3 = vec![u32::MAX; n];
    let mut in_three = 0usize;
    for i in 0..n as u32 {
        for &a in topo.vertex_neighbours(i) {
            ring2[a as usize] = i;
            for &b in topo.vertex_neighbours(a) {
                ring2[b as usize] = i;
                for &c in topo.vertex_neighbours(b) {
                    if ring3[c as usize] != i {
                        ring3[c as usize] = i;
                    }
                }
            }
        }
        mark[i as usize] = i;
        let mut queue = vec![i];
        let mut head = 0;
        while head < queue.len() {
            let u = queue[head];
            head += 1;
            for &k in topo.vertex_neighbours(u) {
                if mark[k as usize] == i {
                    continue;
                }
                mark[k as usize] = i;
                if mesh.positions[k as usize].distance(mesh.positions[i as usize]) < rho {
                    queue.push(k);
                    ball += 1;
                    in_two += usize::from(ring2[k as usize] == i);
                    in_three += usize::from(ring3[k as usize] == i || ring2[k as usize] == i);
                }
            }
        }
    }
    println!(
        "bilateral ball (ρ = 1.8 mean edges, through the mesh): {:.2} vertices on average, {:.3} % of them in the 2-ring, {:.3} % in the 3-ring",
        ball as f64 / n as f64,
        100.0 * in_two as f64 / ball.max(1) as f64,
        100.0 * in_three as f64 / ball.max(1) as f64
    );
}
