//! The connectivity the normal filter works on, built once per step from [`Topology`]:
//! each triangle's face ring (the triangles sharing a vertex with it, itself included), its
//! edge neighbours (for the guided variant's patch measure) and each vertex's triangles (for
//! the vertex update). All CSR, all in ascending order, so every sum over them has one
//! fixed order whatever the thread count.

use crate::mesh::topology::Topology;
use rayon::prelude::*;

/// "No triangle across this side": a border or non-manifold edge.
pub const NONE: u32 = u32::MAX;

#[derive(Debug, Clone, Default)]
pub struct Rings {
    /// Each triangle's three vertices.
    corners: Vec<[u32; 3]>,
    face_offsets: Vec<u32>,
    face_list: Vec<u32>,
    /// Per triangle, the triangle across each of its three sides, or [`NONE`].
    across: Vec<[u32; 3]>,
    vertex_offsets: Vec<u32>,
    vertex_list: Vec<u32>,
}

/// Triangles per block of the parallel build (blocks are concatenated in order).
const BLOCK: usize = 8192;

impl Rings {
    pub fn new(topology: &Topology) -> Rings {
        let t_count = topology.triangle_count();
        let blocks: Vec<(Vec<u32>, Vec<u32>)> = (0..t_count.div_ceil(BLOCK))
            .into_par_iter()
            .map(|b| {
                let (mut counts, mut list) = (Vec::new(), Vec::new());
                let mut scratch = Vec::new();
                for t in b * BLOCK..((b + 1) * BLOCK).min(t_count) {
                    scratch.clear();
                    for v in topology.triangle_vertices(t as u32) {
                        scratch.extend(topology.vertex_triangles(v));
                    }
                    scratch.sort_unstable();
                    scratch.dedup();
                    counts.push(scratch.len() as u32);
                    list.extend_from_slice(&scratch);
                }
                (counts, list)
            })
            .collect();
        let mut face_offsets = Vec::with_capacity(t_count + 1);
        face_offsets.push(0u32);
        let mut face_list = Vec::with_capacity(blocks.iter().map(|b| b.1.len()).sum());
        for (counts, list) in blocks {
            for c in counts {
                let last = *face_offsets.last().expect("starts with 0");
                face_offsets.push(last + c);
            }
            face_list.extend(list);
        }
        let across = (0..t_count as u32)
            .into_par_iter()
            .map(|t| {
                topology.triangle_edges(t).map(|e| {
                    if e == crate::mesh::topology::NO_EDGE {
                        return NONE;
                    }
                    let mut it = topology.edge_triangles(e).filter(|&u| u != t);
                    match (it.next(), it.next()) {
                        (Some(u), None) => u,
                        _ => NONE,
                    }
                })
            })
            .collect();
        let v_count = topology.vertex_count();
        let mut vertex_offsets = Vec::with_capacity(v_count + 1);
        let mut vertex_list = Vec::with_capacity(3 * t_count);
        vertex_offsets.push(0u32);
        for v in 0..v_count as u32 {
            let start = vertex_list.len();
            vertex_list.extend(topology.vertex_triangles(v));
            // A triangle that repeats v is listed once.
            let mut end = start;
            for k in start..vertex_list.len() {
                if end == start || vertex_list[end - 1] != vertex_list[k] {
                    vertex_list[end] = vertex_list[k];
                    end += 1;
                }
            }
            vertex_list.truncate(end);
            vertex_offsets.push(vertex_list.len() as u32);
        }
        let corners = (0..t_count as u32)
            .map(|t| topology.triangle_vertices(t))
            .collect();
        Rings {
            corners,
            face_offsets,
            face_list,
            across,
            vertex_offsets,
            vertex_list,
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.across.len()
    }

    /// Each triangle's three vertices.
    pub fn corners(&self) -> &[[u32; 3]] {
        &self.corners
    }

    /// The triangles sharing a vertex with `t`, `t` included, ascending.
    #[inline]
    pub fn face_ring(&self, t: usize) -> &[u32] {
        &self.face_list[self.face_offsets[t] as usize..self.face_offsets[t + 1] as usize]
    }

    /// The triangles across `t`'s three sides ([`NONE`] where there is none).
    #[inline]
    pub fn across(&self, t: usize) -> [u32; 3] {
        self.across[t]
    }

    /// The triangles around vertex `v`, ascending, each once.
    #[inline]
    pub fn vertex_faces(&self, v: usize) -> &[u32] {
        &self.vertex_list[self.vertex_offsets[v] as usize..self.vertex_offsets[v + 1] as usize]
    }
}
