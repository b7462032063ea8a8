//! Bilateral mesh denoising (thesis §3.5; the thesis gives no formula, so the update is
//! Fleishman, Drori & Cohen-Or 2003, "DenoisePoint", spec §6.2):
//!
//! ```text
//! N(v) = { q_k : ‖v − q_k‖ < ρ },  t_k = ‖v − q_k‖,  h_k = ⟨n, v − q_k⟩
//! w_k = exp(−t_k²/2σ_c²) · exp(−h_k²/2σ_s²)
//! v̂ = v − n · Σ w_k h_k / Σ w_k
//! ```
//!
//! Choices where the thesis is silent (spec pitfall 5), each following Fleishman et al.
//! unless said otherwise:
//! - ρ = 2σ_c unless `radius` is given.
//! - The neighbourhood is gathered through the mesh (breadth-first over 1-rings, keeping
//!   vertices inside the ρ-ball), not from all vertices in space: no spatial index needed,
//!   and a thin part (a lip, an ear) is not pulled towards the surface across the gap.
//! - The vertex itself is left out of N(v) (spec §1 and pitfall 7); it would only add
//!   weight 1 with h = 0 and damp the move.
//! - n is the area-weighted average of the 1-ring face normals, recomputed from the current
//!   mesh before every iteration; updates are buffered.
//! - An empty neighbourhood, a zero normal or underflowing weights leave the vertex where it
//!   is (counted in the report).

use super::{BilateralParams, SmoothGraph};
use crate::mesh::topology::Topology;
use glam::DVec3;
use rayon::prelude::*;

pub(super) struct BilateralOutcome {
    pub passes: u32,
    pub empty_neighbourhoods: u64,
}

/// Area-weighted vertex normals (unit, or zero where every face around is degenerate).
fn vertex_normals(topology: &Topology, x: &[DVec3], out: &mut Vec<DVec3>) {
    let faces: Vec<DVec3> = (0..topology.triangle_count() as u32)
        .into_par_iter()
        .map(|t| {
            let [a, b, c] = topology.triangle_vertices(t).map(|v| x[v as usize]);
            // |(b − a) × (c − a)| is twice the area: the sum below is area-weighted.
            (b - a).cross(c - a)
        })
        .collect();
    out.resize(x.len(), DVec3::ZERO);
    out.par_iter_mut().enumerate().for_each(|(v, n)| {
        let sum: DVec3 = topology
            .vertex_triangles(v as u32)
            .map(|t| faces[t as usize])
            .sum();
        *n = sum.normalize_or_zero();
    });
}

/// Scratch of one task: `stamp[j] == i + 1` marks vertex j as seen while denoising vertex i
/// (no clearing needed between vertices), and the breadth-first queue.
struct Scratch {
    stamp: Vec<u32>,
    queue: Vec<u32>,
}

/// Returns `None` when vertex `i` cannot move (no neighbours, zero normal, zero weights).
#[inline]
fn denoise_vertex(
    topology: &Topology,
    x: &[DVec3],
    i: usize,
    n: DVec3,
    radius_sq: f64,
    inv_2sc2: f64,
    inv_2ss2: f64,
    scratch: &mut Scratch,
) -> Option<DVec3> {
    if n == DVec3::ZERO {
        return None;
    }
    let v = x[i];
    let mark = i as u32 + 1;
    scratch.stamp[i] = mark;
    scratch.queue.clear();
    scratch.queue.push(i as u32);
    let (mut sum_wh, mut sum_w) = (0.0, 0.0);
    let mut head = 0;
    while head < scratch.queue.len() {
        let u = scratch.queue[head];
        head += 1;
        for &k in topology.vertex_neighbours(u) {
            let slot = &mut scratch.stamp[k as usize];
            if *slot == mark {
                continue;
            }
            *slot = mark;
            let d = v - x[k as usize];
            let t2 = d.length_squared();
            if t2 >= radius_sq {
                continue;
            }
            scratch.queue.push(k);
            let h = n.dot(d);
            let w = (-t2 * inv_2sc2 - h * h * inv_2ss2).exp();
            sum_wh += w * h;
            sum_w += w;
        }
    }
    (sum_w > 0.0 && sum_wh.is_finite()).then(|| v - n * (sum_wh / sum_w))
}

/// `unit` converts the parameters to model units (the mean edge length, or 1).
pub(super) fn run(
    topology: &Topology,
    graph: &SmoothGraph,
    positions: &mut Vec<DVec3>,
    params: &BilateralParams,
    unit: f64,
    iterations: u32,
) -> BilateralOutcome {
    let n = positions.len();
    let sigma_c = params.sigma_c * unit;
    let sigma_s = params.sigma_s * unit;
    let radius = params.radius.map_or(2.0 * sigma_c, |r| r * unit);
    let (inv_2sc2, inv_2ss2) = (
        1.0 / (2.0 * sigma_c * sigma_c),
        1.0 / (2.0 * sigma_s * sigma_s),
    );
    let mut outcome = BilateralOutcome {
        passes: iterations,
        empty_neighbourhoods: 0,
    };
    if !(sigma_c > 0.0 && sigma_s > 0.0 && radius > 0.0 && inv_2sc2.is_finite() && inv_2ss2.is_finite()) {
        // A mesh whose edges all have length 0 has no scale to smooth at.
        outcome.empty_neighbourhoods = graph.smoothed_vertices() as u64 * u64::from(iterations);
        return outcome;
    }
    let radius_sq = radius * radius;
    // Few large blocks: each task allocates one stamp array of n entries (zeroed pages
    // are lazily mapped, so only what the search touches costs anything).
    let block = n.div_ceil(4 * rayon::current_num_threads()).max(1024);
    let mut normals = Vec::with_capacity(n);
    let mut next = vec![DVec3::ZERO; n];
    for _ in 0..iterations {
        vertex_normals(topology, positions, &mut normals);
        let x = &*positions;
        let empty: u64 = next
            .par_chunks_mut(block)
            .enumerate()
            .map_init(
                || Scratch {
                    stamp: vec![0; n],
                    queue: Vec::new(),
                },
                |scratch, (chunk, out)| {
                    let first = chunk * block;
                    let mut empty = 0u64;
                    for (k, p) in out.iter_mut().enumerate() {
                        let i = first + k;
                        *p = x[i];
                        if !graph.moves(i) {
                            continue;
                        }
                        match denoise_vertex(
                            topology, x, i, normals[i], radius_sq, inv_2sc2, inv_2ss2, scratch,
                        ) {
                            Some(moved) => *p = moved,
                            None => empty += 1,
                        }
                    }
                    empty
                },
            )
            .sum();
        outcome.empty_neighbourhoods += empty;
        std::mem::swap(positions, &mut next);
    }
    outcome
}
