//! The ordered 1-rings the thesis' formulas need (§3.4: neighbours in cyclic fan order),
//! packed for fast sweeps, with the relative orientation of neighbouring fans used by the
//! sign reconstruction (§3.6.2: "the neighbourhood of every neighbour oriented
//! consistently with the neighbourhood of a").
//!
//! The rings come from adjacency (`Topology::ordered_ring`), not from the stored winding,
//! so a non-orientable or inconsistently wound mesh still gets a valid local orientation
//! (docs/fairing.md, reading F5).

use crate::mesh::{RingBuffers, Topology};
use rayon::prelude::*;

/// Vertices per block when building (see [`Neighbourhood::new`]).
const BLOCK: usize = 4096;

#[derive(Debug, Clone, Default)]
pub struct Neighbourhood {
    /// CSR offsets into `ring`, one row per vertex (empty for vertices without a ring).
    offsets: Vec<u32>,
    ring: Vec<u32>,
    /// CSR of the fan triangles: `fan[i]` has corners `v`, `ring[i]`, `ring[i + 1]`.
    fan_offsets: Vec<u32>,
    fan: Vec<u32>,
    /// Per ring slot: +1 if the neighbour's closed ring runs the same way round the
    /// triangles they share as this ring, −1 if opposite, 0 if the neighbour has no closed
    /// ring (boundary, non-manifold: excluded from H̄, (4.1)–(4.3)).
    orient: Vec<i8>,
    /// The vertex has a closed fan: a manifold interior vertex.
    closed: Vec<bool>,
    /// The vertex has an ordered ring (closed or open): it is manifold.
    manifold: Vec<bool>,
}

/// The rings of one block of vertices, flattened on its own thread (see [`ring_blocks`]).
struct Block {
    ring_lengths: Vec<u32>,
    fan_lengths: Vec<u32>,
    ring: Vec<u32>,
    fan: Vec<u32>,
    closed: Vec<bool>,
    manifold: Vec<bool>,
}

/// Every vertex's ordered ring and fan, in blocks of [`BLOCK`] vertices, each block's
/// flattened on its own thread: no per-vertex allocation survives the block, so the
/// transient memory is about one more copy of the result (a Vec per vertex cost ~30 MB for
/// a 400k-triangle scan, on top of its topology).
fn ring_blocks(topo: &Topology) -> Vec<Block> {
    let n = topo.vertex_count();
    (0..n.div_ceil(BLOCK))
        .into_par_iter()
        .map(|b| {
            let vertices = b * BLOCK..((b + 1) * BLOCK).min(n);
            let mut block = Block {
                ring_lengths: Vec::with_capacity(vertices.len()),
                fan_lengths: Vec::with_capacity(vertices.len()),
                ring: Vec::new(),
                fan: Vec::new(),
                closed: Vec::with_capacity(vertices.len()),
                manifold: Vec::with_capacity(vertices.len()),
            };
            let mut buffers = RingBuffers::default();
            for v in vertices {
                let (ring_len, fan_len, closed, manifold) =
                    match topo.ordered_ring_into(v as u32, &mut buffers) {
                        Some(closed) => {
                            block.ring.extend_from_slice(&buffers.vertices);
                            block.fan.extend_from_slice(&buffers.triangles);
                            (
                                buffers.vertices.len(),
                                buffers.triangles.len(),
                                closed,
                                true,
                            )
                        }
                        None => (0, 0, false, false),
                    };
                block.ring_lengths.push(ring_len as u32);
                block.fan_lengths.push(fan_len as u32);
                block.closed.push(closed);
                block.manifold.push(manifold);
            }
            block
        })
        .collect()
}

impl Neighbourhood {
    pub fn new(topo: &Topology) -> Self {
        let mut nb = Neighbourhood::joined(ring_blocks(topo), topo.vertex_count());
        nb.orient = nb.all_orientations();
        nb
    }

    /// The blocks' rings and fans in one flat table of `n` vertices (no orientations yet).
    fn joined(blocks: Vec<Block>, n: usize) -> Neighbourhood {
        let ring_total: usize = blocks.iter().map(|b| b.ring.len()).sum();
        let fan_total: usize = blocks.iter().map(|b| b.fan.len()).sum();
        let mut nb = Neighbourhood {
            offsets: Vec::with_capacity(n + 1),
            ring: Vec::with_capacity(ring_total),
            fan_offsets: Vec::with_capacity(n + 1),
            fan: Vec::with_capacity(fan_total),
            orient: Vec::new(),
            closed: Vec::with_capacity(n),
            manifold: Vec::with_capacity(n),
        };
        nb.offsets.push(0);
        nb.fan_offsets.push(0);
        for block in blocks {
            for (&r, &f) in block.ring_lengths.iter().zip(&block.fan_lengths) {
                nb.offsets.push(nb.offsets.last().copied().unwrap_or(0) + r);
                nb.fan_offsets
                    .push(nb.fan_offsets.last().copied().unwrap_or(0) + f);
            }
            nb.ring.extend_from_slice(&block.ring);
            nb.fan.extend_from_slice(&block.fan);
            nb.closed.extend_from_slice(&block.closed);
            nb.manifold.extend_from_slice(&block.manifold);
        }
        nb
    }

    /// Per ring entry of every closed ring, the orientation of that neighbour's ring
    /// relative to the vertex's ([`Neighbourhood::relative_orientation`]); 0 in open rings.
    fn all_orientations(&self) -> Vec<i8> {
        let n = self.closed.len();
        let blocks: Vec<Vec<i8>> = (0..n.div_ceil(BLOCK))
            .into_par_iter()
            .map(|b| {
                let mut out = Vec::new();
                for v in b * BLOCK..((b + 1) * BLOCK).min(n) {
                    let r = self.ring(v);
                    out.extend((0..r.len()).map(|i| {
                        if self.closed[v] {
                            self.relative_orientation(v as u32, r[i], r[(i + 1) % r.len()])
                        } else {
                            0
                        }
                    }));
                }
                out
            })
            .collect();
        blocks.concat()
    }

    /// Orientation of `j`'s ring relative to `v`'s, where `next` follows `j` in `v`'s ring.
    /// In `v`'s order the shared triangle runs `v → j → next`, i.e. `j → next → v`; `j`'s
    /// ring agrees if `next` comes right before `v` in it.
    fn relative_orientation(&self, v: u32, j: u32, next: u32) -> i8 {
        let j = j as usize;
        if !self.closed[j] {
            return 0;
        }
        let rj = self.ring(j);
        let m = rj.len();
        let Some(pos) = rj.iter().position(|&x| x == v) else {
            return 0;
        };
        if rj[(pos + m - 1) % m] == next {
            1
        } else if rj[(pos + 1) % m] == next {
            -1
        } else {
            0
        }
    }

    pub fn vertex_count(&self) -> usize {
        self.closed.len()
    }

    #[inline]
    pub fn ring(&self, v: usize) -> &[u32] {
        &self.ring[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }

    /// The fan triangles of `v`, in ring order (one fewer than the ring when open).
    #[inline]
    pub fn fan(&self, v: usize) -> &[u32] {
        &self.fan[self.fan_offsets[v] as usize..self.fan_offsets[v + 1] as usize]
    }

    #[inline]
    pub fn orientations(&self, v: usize) -> &[i8] {
        &self.orient[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }

    /// A manifold interior vertex (closed fan).
    #[inline]
    pub fn is_closed(&self, v: usize) -> bool {
        self.closed[v]
    }

    /// A manifold vertex (closed or open fan).
    #[inline]
    pub fn is_manifold(&self, v: usize) -> bool {
        self.manifold[v]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;

    #[test]
    fn consistent_mesh_has_agreeing_orientations() {
        let m = shapes::uv_sphere(1.0, 6, 8);
        let nb = Neighbourhood::new(&m.topology());
        for v in 0..nb.vertex_count() {
            assert!(nb.is_closed(v));
            assert!(nb.orientations(v).iter().all(|&o| o == 1), "{v}");
        }
    }

    #[test]
    fn flipped_triangle_is_detected_through_adjacency() {
        let mut m = shapes::uv_sphere(1.0, 6, 8);
        // Reverse one triangle's winding: its neighbours' fans disagree with its corners'.
        let t = 20;
        m.triangles[t].swap(1, 2);
        let nb = Neighbourhood::new(&m.topology());
        let [a, b, _] = m.triangle_vertices(t);
        // Every vertex still has a closed ring, and orientation flags are ±1.
        assert!((0..nb.vertex_count()).all(|v| nb.is_closed(v)));
        let ra = nb.ring(a as usize);
        let slot = ra.iter().position(|&x| x == b).unwrap();
        assert!(nb.orientations(a as usize)[slot].abs() == 1);
    }
}
