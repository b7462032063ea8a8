//! The ceiling of the thesis' fairing on the noise protocol of issue #4 (docs/fairing.md,
//! "The method's ceiling").
//!
//! On small noise the curvature-magnitude diffusion of the fairing thesis' ch. 3 linearises to
//! a bi-Laplacian flow of the positions, `x ← x − λ·L(L x)` with `L` the umbrella
//! operator (docs/fairing.md, "Why", point 8). This probe runs that linear flow, with no
//! guard, sign or placement effect in the way, on the four scans of the issue and prints
//! its distance to the clean scan against Taubin's at several flow times λT. Whatever the
//! nonlinear method gains or loses on top, this is the filter it approximates.
//!
//! Also printed: the flow with each vertex's curvature scaled by its own squared mean edge
//! (`H_v = (L x)_v / e_v²`, moved by `e_v²·λ·(L H)_v`), which is how the thesis' curvature
//! scales on an irregular mesh.
//!
//! `cargo run --release --example bilap_probe` (`FP_SCANS=lucy,igea` to choose scans).

#[path = "common/noise_protocol.rs"]
mod noise_protocol;

use glam::DVec3;
use noise_protocol::{SCANS, load, noisy, taubin, wanted};
use scanmill::mesh::{Mesh, Topology};
use scanmill::metrics::distance::surface_distance;
use scanmill::ops::smooth::TaubinCount;

const SAMPLES: usize = 100_000;
/// Umbrella operator `(L x)_v = mean of the neighbours − x_v`, every vertex with
/// neighbours.
pub fn umbrella(topo: &Topology, x: &[DVec3]) -> Vec<DVec3> {
    (0..x.len())
        .map(|v| {
            let nb = topo.vertex_neighbours(v as u32);
            if nb.is_empty() {
                return DVec3::ZERO;
            }
            nb.iter().map(|&j| x[j as usize]).sum::<DVec3>() / nb.len() as f64 - x[v]
        })
        .collect()
}

/// Explicit step of the bi-Laplacian flow: stable below 1/8 for the umbrella operator's
/// spectrum in [−2, 0].
const STEP: f64 = 0.1;
/// Flow times λT printed (in units of the thesis' λ × iterations: the face-scan recipe's
/// 400 curvature iterations at λ = 0.01 are λT = 4).
const TIMES: [f64; 6] = [1.0, 2.0, 3.0, 4.0, 6.0, 8.0];

/// Squared mean edge length around each vertex.
fn local_scale(topo: &Topology, x: &[DVec3]) -> Vec<f64> {
    (0..x.len())
        .map(|v| {
            let nb = topo.vertex_neighbours(v as u32);
            if nb.is_empty() {
                return 1.0;
            }
            let e = nb
                .iter()
                .map(|&j| (x[j as usize] - x[v]).length())
                .sum::<f64>()
                / nb.len() as f64;
            e * e
        })
        .collect()
}

/// One explicit step of the bi-Laplacian flow, plain or locally scaled.
fn bilaplacian_step(topo: &Topology, mesh: &mut Mesh, scaled: bool) {
    let l = umbrella(topo, &mesh.positions);
    if scaled {
        let e2 = local_scale(topo, &mesh.positions);
        let h: Vec<DVec3> = l.iter().zip(&e2).map(|(x, e)| *x / *e).collect();
        let lh = umbrella(topo, &h);
        for ((p, d), e) in mesh.positions.iter_mut().zip(lh).zip(&e2) {
            *p -= STEP * *e * d;
        }
    } else {
        let ll = umbrella(topo, &l);
        for (p, d) in mesh.positions.iter_mut().zip(ll) {
            *p -= STEP * d;
        }
    }
}

fn main() {
    for (name, rel) in SCANS {
        if !wanted(name) {
            continue;
        }
        let clean = load(rel);
        let topo = clean.topology();
        let noisy = noisy(&clean);
        let dist = |m: &Mesh| surface_distance(m, &clean, SAMPLES, 7).unwrap().mean;
        let dn = dist(&noisy);
        let mut t13 = noisy.clone();
        taubin(&mut t13, 13, TaubinCount::Passes);
        let mut t26 = noisy.clone();
        taubin(&mut t26, 13, TaubinCount::Pairs);
        let (d13, d26) = (dist(&t13), dist(&t26));
        println!(
            "{name}: Taubin 13 passes {:.3} of noisy, 13 pairs {:.3} of noisy",
            d13 / dn,
            d26 / dn
        );
        for scaled in [false, true] {
            let mut m = noisy.clone();
            let mut steps = 0usize;
            let mut row = Vec::new();
            for time in TIMES {
                while (steps as f64) * STEP < time - 1e-9 {
                    bilaplacian_step(&topo, &mut m, scaled);
                    steps += 1;
                }
                let d = dist(&m);
                row.push(format!("λT {time}: {:.3}/{:.3}", d / d13, d / d26));
            }
            println!(
                "  {} × Taubin (passes/pairs): {}",
                if scaled {
                    "scaled bi-Laplacian"
                } else {
                    "bi-Laplacian"
                },
                row.join(", ")
            );
        }
    }
}
