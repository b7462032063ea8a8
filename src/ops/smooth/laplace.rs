//! Laplacian smoothing (thesis §3.2), and the umbrella pass the other Laplacian-type
//! filters (HC, Taubin) are built from.

use super::{LaplaceAnchor, LaplaceParams, SmoothGraph, Update, par_for_each_indexed};
use glam::DVec3;

/// One buffered pass of Eq. (3.3) / (3.5) / (3.7):
/// `out_i = (1 − f)·a_i + f·avg_j(q_j)`, with `a = anchor` (the original positions o, Eq. 3.5)
/// or `a = q` (Eq. 3.3; with f = 1 this is exactly Eq. 3.4, plain averaging, and with f = μ < 0
/// it is Taubin's inflating step, Eq. 3.7). A vertex with an empty row keeps `q_i`.
///
/// Each output depends only on the snapshot `q`, so the result is the same for any thread
/// count (the thesis' "sequential" mode, thesis §3.1).
pub(super) fn pass_buffered(
    graph: &SmoothGraph,
    weights: Option<&[f64]>,
    q: &[DVec3],
    anchor: Option<&[DVec3]>,
    factor: f64,
    out: &mut [DVec3],
) {
    let keep = 1.0 - factor;
    par_for_each_indexed(out, |i, p| {
        *p = match graph.average(weights, q, i) {
            Some(avg) => keep * anchor.map_or(q[i], |o| o[i]) + factor * avg,
            None => q[i],
        };
    });
}

/// One in-place (Gauss–Seidel) pass in vertex order: each vertex already sees the moved
/// positions of the vertices before it (the thesis' "simultaneous" mode, thesis §3.1). Sequential.
pub(super) fn pass_in_place(
    graph: &SmoothGraph,
    weights: Option<&[f64]>,
    x: &mut [DVec3],
    anchor: Option<&[DVec3]>,
    factor: f64,
) {
    let keep = 1.0 - factor;
    for i in 0..x.len() {
        if let Some(avg) = graph.average(weights, x, i) {
            x[i] = keep * anchor.map_or(x[i], |o| o[i]) + factor * avg;
        }
    }
}

/// Laplace smoothing: `iterations` passes of Eq. (3.3) or (3.5) with factor λ.
/// Returns the number of passes.
pub(super) fn run(
    graph: &SmoothGraph,
    positions: &mut Vec<DVec3>,
    params: &LaplaceParams,
    iterations: u32,
    update: Update,
) -> u32 {
    // Eq. (3.5): o is the noisy input of this run, fixed for all iterations.
    let original = (params.anchor == LaplaceAnchor::Original).then(|| positions.clone());
    let mut weights = graph.weight_buffer(params.weights);
    let mut pass = Pass::new(update, positions.len());
    for _ in 0..iterations {
        graph.refresh_weights(&mut weights, positions);
        pass.run(
            graph,
            weights.as_deref(),
            positions,
            original.as_deref(),
            params.lambda,
        );
    }
    iterations
}

/// One umbrella pass in either update mode, with the buffer a buffered pass writes into
/// (kept across passes; Laplace and Taubin share it).
pub(super) struct Pass {
    update: Update,
    scratch: Vec<DVec3>,
}

impl Pass {
    pub(super) fn new(update: Update, vertices: usize) -> Pass {
        let scratch = match update {
            Update::Buffered => vec![DVec3::ZERO; vertices],
            Update::InPlace => Vec::new(),
        };
        Pass { update, scratch }
    }

    pub(super) fn run(
        &mut self,
        graph: &SmoothGraph,
        weights: Option<&[f64]>,
        positions: &mut Vec<DVec3>,
        anchor: Option<&[DVec3]>,
        factor: f64,
    ) {
        match self.update {
            Update::Buffered => {
                pass_buffered(graph, weights, positions, anchor, factor, &mut self.scratch);
                std::mem::swap(positions, &mut self.scratch);
            }
            Update::InPlace => pass_in_place(graph, weights, positions, anchor, factor),
        }
    }
}
