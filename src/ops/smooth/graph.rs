//! The adjacency the Laplacian-type filters iterate over: one CSR row per vertex with the
//! neighbours its Laplacian averages, built once per step from [`Topology`].
//!
//! The row already encodes the border rule, so the inner loops have no branches for it:
//! an empty row means "this vertex does not move" (isolated, or a fixed border vertex);
//! a free border vertex's row holds only its neighbours along border edges.

use super::{Border, CHUNK, Weights};
use crate::mesh::topology::Topology;
use glam::DVec3;
use rayon::prelude::*;

/// Cotangent weights, one per row entry, and the per-corner cotangents they are summed
/// from, kept between passes so that a pass allocates nothing. Reads as the per-entry
/// weights.
#[derive(Debug, Clone)]
pub struct EdgeWeights {
    per_entry: Vec<f64>,
    per_corner: Vec<f64>,
}

impl std::ops::Deref for EdgeWeights {
    type Target = [f64];
    fn deref(&self) -> &[f64] {
        &self.per_entry
    }
}

/// CSR rows of the smoothing operator, plus what cotangent weights need.
#[derive(Debug, Clone)]
pub struct SmoothGraph {
    offsets: Vec<u32>,
    neighbours: Vec<u32>,
    /// 1/|row| (0 for an empty row), so the uniform average is one multiply.
    inv_degree: Vec<f64>,
    /// Row owner of every entry (cotangent weights are computed per entry in parallel).
    entry_owner: Vec<u32>,
    /// Per entry (CSR over entries): the corners (`3t + k`) opposite the edge in its
    /// triangles. Empty for entries whose weight stays 1 (free border rows, which average
    /// along the border).
    opposite_offsets: Vec<u32>,
    opposite: Vec<u32>,
    /// Vertex of every corner (cotangent weights only).
    corner_vertices: Vec<u32>,
    smoothed: usize,
    fixed_boundary: usize,
    isolated: usize,
}

impl SmoothGraph {
    /// Builds the rows. `cotangent` also records each edge's opposite vertices.
    pub fn new(topology: &Topology, boundary: Border, cotangent: bool) -> SmoothGraph {
        let n = topology.vertex_count();
        let mut offsets = Vec::with_capacity(n + 1);
        let mut neighbours = Vec::with_capacity(topology.edge_count() * 2);
        let mut inv_degree = Vec::with_capacity(n);
        let mut opposite_offsets = vec![0u32];
        let mut opposite = Vec::new();
        let (mut smoothed, mut fixed_boundary, mut isolated) = (0, 0, 0);
        offsets.push(0u32);
        for v in 0..n as u32 {
            let ring = topology.vertex_neighbours(v);
            let start = neighbours.len();
            let on_border = topology.is_boundary_vertex(v);
            if ring.is_empty() {
                isolated += 1;
            } else if on_border && boundary == Border::Fixed {
                fixed_boundary += 1;
            } else if on_border {
                for &u in ring {
                    let e = topology
                        .find_edge(v, u)
                        .expect("a ring neighbour shares an edge");
                    if topology.is_boundary_edge(e) {
                        neighbours.push(u);
                    }
                }
            } else {
                neighbours.extend_from_slice(ring);
            }
            if cotangent {
                for &u in &neighbours[start..] {
                    if !on_border {
                        let e = topology
                            .find_edge(v, u)
                            .expect("a ring neighbour shares an edge");
                        for t in topology.edge_triangles(e) {
                            let corners = topology.triangle_vertices(t);
                            let third = (0..3).find(|&k| corners[k] != v && corners[k] != u);
                            opposite.extend(third.map(|k| 3 * t + k as u32));
                        }
                    }
                    opposite_offsets.push(opposite.len() as u32);
                }
            }
            let degree = neighbours.len() - start;
            smoothed += usize::from(degree > 0);
            inv_degree.push(if degree > 0 { 1.0 / degree as f64 } else { 0.0 });
            offsets.push(neighbours.len() as u32);
        }
        let corner_vertices = if cotangent {
            (0..topology.triangle_count() as u32)
                .flat_map(|t| topology.triangle_vertices(t))
                .collect()
        } else {
            Vec::new()
        };
        let entry_owner = if cotangent {
            (0..n)
                .flat_map(|v| std::iter::repeat_n(v as u32, (offsets[v + 1] - offsets[v]) as usize))
                .collect()
        } else {
            Vec::new()
        };
        SmoothGraph {
            offsets,
            neighbours,
            inv_degree,
            entry_owner,
            opposite_offsets,
            opposite,
            corner_vertices,
            smoothed,
            fixed_boundary,
            isolated,
        }
    }

    pub fn vertex_count(&self) -> usize {
        self.inv_degree.len()
    }

    /// Vertices with a non-empty row (the ones a Laplacian filter moves).
    pub fn smoothed_vertices(&self) -> usize {
        self.smoothed
    }

    pub fn fixed_boundary_vertices(&self) -> usize {
        self.fixed_boundary
    }

    pub fn isolated_vertices(&self) -> usize {
        self.isolated
    }

    /// True when vertex `i` may move.
    #[inline]
    pub fn moves(&self, i: usize) -> bool {
        self.offsets[i] != self.offsets[i + 1]
    }

    #[inline]
    fn range(&self, i: usize) -> std::ops::Range<usize> {
        self.offsets[i] as usize..self.offsets[i + 1] as usize
    }

    /// The weighted average of `x` over row `i` (the Σ_j w_ij x_j of Eq. 3.1 with weights
    /// summing to one), or `None` for an empty row. `weights` are the raw per-entry weights
    /// of [`Self::refresh_weights`] (`None` = uniform, 1/|adj(i)|, the thesis' umbrella).
    #[inline]
    pub fn average(&self, weights: Option<&[f64]>, x: &[DVec3], i: usize) -> Option<DVec3> {
        let range = self.range(i);
        if range.is_empty() {
            return None;
        }
        let row = &self.neighbours[range.clone()];
        if let Some(w) = weights {
            let (mut acc, mut sum) = (DVec3::ZERO, 0.0);
            for (&j, &wj) in row.iter().zip(&w[range]) {
                acc += x[j as usize] * wj;
                sum += wj;
            }
            // All cotangents clamped to zero (a degenerate ring): fall back to uniform.
            if sum > 0.0 {
                return Some(acc * sum.recip());
            }
        }
        let mut acc = DVec3::ZERO;
        for &j in row {
            acc += x[j as usize];
        }
        Some(acc * self.inv_degree[i])
    }

    /// A weight buffer for `weights` (`None` for uniform weights).
    pub fn weight_buffer(&self, weights: Weights) -> Option<EdgeWeights> {
        match weights {
            Weights::Uniform => None,
            Weights::Cotangent => {
                assert!(
                    !self.entry_owner.is_empty() || self.neighbours.is_empty(),
                    "graph built without cotangent data"
                );
                Some(EdgeWeights {
                    per_entry: vec![1.0; self.neighbours.len()],
                    per_corner: vec![0.0; self.corner_vertices.len()],
                })
            }
        }
    }

    /// Recomputes cotangent weights from the current positions: for entry (i, j),
    /// w = ½ Σ cot(angle opposite the edge ij), clamped at 0 (an obtuse pair would give a
    /// negative weight and break the convex-combination property the filters rely on).
    /// Entries without opposite corners (free border rows) keep weight 1. The cotangents
    /// are computed once per triangle corner (one cross product per triangle), then summed
    /// per entry.
    pub fn refresh_weights(&self, weights: &mut Option<EdgeWeights>, x: &[DVec3]) {
        let Some(EdgeWeights {
            per_entry: w,
            per_corner: cot,
        }) = weights
        else {
            return;
        };
        cot.par_chunks_mut(3 * CHUNK)
            .zip(self.corner_vertices.par_chunks(3 * CHUNK))
            .for_each(|(cot, corners)| {
                for (c, v) in cot.chunks_exact_mut(3).zip(corners.chunks_exact(3)) {
                    let p = [x[v[0] as usize], x[v[1] as usize], x[v[2] as usize]];
                    // Twice the area; the same for all three corners.
                    let sin = (p[1] - p[0]).cross(p[2] - p[0]).length();
                    // Zero, or NaN for non-finite input: no weight from this triangle.
                    if sin.is_nan() || sin <= 0.0 {
                        c.fill(0.0);
                        continue;
                    }
                    let inv_sin = 1.0 / sin;
                    for k in 0..3 {
                        let (a, b) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
                        c[k] = a.dot(b) * inv_sin;
                    }
                }
            });
        w.par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(chunk, out)| {
                for (k, slot) in out.iter_mut().enumerate() {
                    let e = chunk * CHUNK + k;
                    let opp = &self.opposite
                        [self.opposite_offsets[e] as usize..self.opposite_offsets[e + 1] as usize];
                    *slot = if opp.is_empty() {
                        1.0
                    } else {
                        let wij = 0.5 * opp.iter().map(|&c| cot[c as usize]).sum::<f64>();
                        if wij.is_finite() { wij.max(0.0) } else { 0.0 }
                    };
                }
            });
    }
}
