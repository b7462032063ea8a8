//! Laplace-HC (thesis §3.3, Eq. 3.6; Vollmer, Mencl & Müller 1999): after each Laplace step,
//! push the vertices back towards a blend of their original and previous positions, which
//! cancels most of the shrinkage.
//!
//! Steps (a), (b) and (c) each finish for every vertex before the next starts:
//! (c) reads the neighbours' b_j. So HC is always buffered.

use super::laplace::pass_buffered;
use super::{HcParams, SmoothGraph, par_for_each_indexed};
use glam::DVec3;

/// Returns the number of passes (one per iteration).
pub(super) fn run(
    graph: &SmoothGraph,
    positions: &mut Vec<DVec3>,
    params: &HcParams,
    iterations: u32,
) -> u32 {
    let n = positions.len();
    // o: the noisy input of this run, fixed for all iterations.
    let original = positions.clone();
    let mut p = vec![DVec3::ZERO; n];
    let mut b = vec![DVec3::ZERO; n];
    let mut weights = graph.weight_buffer(params.weights);
    let (alpha, beta) = (params.alpha, params.beta);
    for _ in 0..iterations {
        let q = &*positions;
        graph.refresh_weights(&mut weights, q);
        let w = weights.as_deref();
        // (a) p_i = (1−λ) q_i + λ/|adj(i)| Σ q_j
        pass_buffered(graph, w, q, None, params.lambda, &mut p);
        // (b) b_i = p_i − (α o_i + (1−α) q_i)
        par_for_each_indexed(&mut b, |i, bi| {
            *bi = p[i] - (alpha * original[i] + (1.0 - alpha) * q[i]);
        });
        // (c) p_i ← p_i − (β b_i + (1−β)/|adj(i)| Σ b_j); vertices that do not move
        // (empty rows) are skipped, their b_i is 0 anyway.
        par_for_each_indexed(&mut p, |i, pi| {
            if let Some(avg_b) = graph.average(w, &b, i) {
                *pi -= beta * b[i] + (1.0 - beta) * avg_b;
            }
        });
        // (d) q ← p
        std::mem::swap(positions, &mut p);
    }
    iterations
}
