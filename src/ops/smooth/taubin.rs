//! Taubin's λ|μ low-pass filter (thesis §3.4; Taubin 1995): a shrinking Laplace pass with
//! λ > 0 (Eq. 3.3) alternating with an inflating pass with μ < −λ (Eq. 3.7).
//!
//! Iteration accounting differs between tools (thesis §3.4 and §5.3). With
//! `count = "pairs"` (the default, as in Taubin's paper and MeshLab) one iteration is one λ
//! pass followed by one μ pass. With `count = "passes"` one iteration is one pass,
//! alternating and starting with λ: the thesis' count, where "13 iterations" means 7 λ and
//! 6 μ passes, ending on λ.

use super::laplace::Pass;
use super::{SmoothGraph, TaubinCount, TaubinParams, Update};
use glam::DVec3;

/// Returns the number of passes.
pub(super) fn run(
    graph: &SmoothGraph,
    positions: &mut Vec<DVec3>,
    params: &TaubinParams,
    iterations: u32,
    update: Update,
) -> u32 {
    let passes = match params.count {
        TaubinCount::Pairs => 2 * iterations,
        TaubinCount::Passes => iterations,
    };
    let mut weights = graph.weight_buffer(params.weights);
    let mut pass = Pass::new(update, positions.len());
    for k in 0..passes {
        let factor = if k % 2 == 0 { params.lambda } else { params.mu };
        graph.refresh_weights(&mut weights, positions);
        pass.run(graph, weights.as_deref(), positions, None, factor);
    }
    passes
}
