//! Edge kinds, orientation and seams; corner fans and vertex flags (the definitions are in
//! the parent module's documentation).
//!
//! Both passes are parallel: an edge's kind and flags depend on its own sides only, and a
//! fan never leaves its vertex (two corners are joined only across an interior manifold
//! edge at the vertex they share), so each vertex's fans are found from its own corners.
//! The counts are sums and the flags ORs: the result is the same in any order and on any
//! number of threads.

use super::{
    EDGE_INCONSISTENT, EDGE_SEAM, EDGE_TEXTURE_SEAM, NO_EDGE, Topology, VERTEX_BOUNDARY,
    VERTEX_NON_MANIFOLD, next_corner, prev_corner,
};
use crate::mesh::Mesh;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering};

/// Fewest vertices per parallel task of the fan pass.
const VERTEX_BLOCK: usize = 4096;

/// The counts one edge adds to the topology's.
#[derive(Clone, Copy, Default)]
struct EdgeCounts {
    boundary: usize,
    non_manifold: usize,
    inconsistent: usize,
    seam: usize,
    texture_seam: usize,
}

impl EdgeCounts {
    fn add(self, o: EdgeCounts) -> EdgeCounts {
        EdgeCounts {
            boundary: self.boundary + o.boundary,
            non_manifold: self.non_manifold + o.non_manifold,
            inconsistent: self.inconsistent + o.inconsistent,
            seam: self.seam + o.seam,
            texture_seam: self.texture_seam + o.texture_seam,
        }
    }
}

impl Topology {
    /// Edge kinds, orientation, seams; corner fans and vertex flags.
    pub(super) fn classify_edges_and_fans(&mut self, mesh: &Mesh) {
        self.classify_edges(mesh);
        self.find_fans();
    }

    /// Each edge's flags and the counts; the ends of boundary and non-manifold edges
    /// flagged.
    fn classify_edges(&mut self, mesh: &Mesh) {
        let mut flags = std::mem::take(&mut self.edge_flags);
        let this = &*self;
        let counts = flags
            .par_iter_mut()
            .enumerate()
            .map(|(e, flag)| {
                let (f, counts) = this.edge_class(mesh, e);
                *flag |= f;
                counts
            })
            .reduce(EdgeCounts::default, EdgeCounts::add);
        self.edge_flags = flags;
        self.boundary_edge_count = counts.boundary;
        self.non_manifold_edge_count = counts.non_manifold;
        self.inconsistent_edge_count = counts.inconsistent;
        self.seam_edge_count = counts.seam;
        self.texture_seam_edge_count = counts.texture_seam;
        // Boundary and non-manifold edges are few (a scan's border); their ends are marked
        // on one thread.
        let marked: Vec<(u32, u8)> = (0..self.edges.len())
            .into_par_iter()
            .filter_map(|e| match self.edge_sides(e as u32).len() {
                1 => Some((e as u32, VERTEX_BOUNDARY)),
                2 => None,
                _ => Some((e as u32, VERTEX_NON_MANIFOLD)),
            })
            .collect();
        for (e, flag) in marked {
            for v in self.edges[e as usize] {
                self.vertex_flags[v as usize] |= flag;
            }
        }
    }

    /// Edge `e`'s flags and what it adds to the counts.
    fn edge_class(&self, mesh: &Mesh, e: usize) -> (u8, EdgeCounts) {
        let sides = self.edge_sides(e as u32);
        let [lo, _] = self.edges[e];
        let mut flags = 0;
        let mut counts = EdgeCounts::default();
        match sides.len() {
            1 => counts.boundary = 1,
            2 => {
                let seam = self.seam_flags(mesh, sides[0], sides[1], lo);
                flags |= seam;
                counts.seam = usize::from(seam & EDGE_SEAM != 0);
                counts.texture_seam = usize::from(seam & EDGE_TEXTURE_SEAM != 0);
            }
            _ => counts.non_manifold = 1,
        }
        if sides.len() >= 2 {
            let forward = sides
                .iter()
                .filter(|&&s| self.corner_vertices[s as usize] == lo)
                .count();
            let repeated = usize::from(forward >= 2) + usize::from(sides.len() - forward >= 2);
            if repeated > 0 {
                flags |= EDGE_INCONSISTENT;
                counts.inconsistent = repeated;
            }
        }
        (flags, counts)
    }

    /// The fan of every corner (its lowest corner), and the vertices where more than one
    /// fan meets flagged non-manifold; then the list of non-manifold vertices.
    fn find_fans(&mut self) {
        let vertex_count = self.vertex_flags.len();
        // A union-find over all corners, each vertex's corners joined by the task that owns
        // the vertex (no other touches them: relaxed atomics only make the sharing safe).
        let parent: Vec<AtomicU32> = (0..self.corner_vertices.len() as u32)
            .map(AtomicU32::new)
            .collect();
        let this = &*self;
        let pinched: Vec<u32> = (0..vertex_count as u32)
            .into_par_iter()
            .with_min_len(VERTEX_BLOCK)
            .filter(|&v| this.vertex_fans(v, &parent) > 1)
            .collect();
        for v in pinched {
            self.vertex_flags[v as usize] |= VERTEX_NON_MANIFOLD;
        }
        self.corner_fans = parent.into_iter().map(AtomicU32::into_inner).collect();
        self.non_manifold_vertices = (0..vertex_count as u32)
            .into_par_iter()
            .filter(|&v| self.vertex_flags[v as usize] & VERTEX_NON_MANIFOLD != 0)
            .collect();
    }

    /// Joins vertex `v`'s corners into its fans in `parent` (the lower corner the root) and
    /// points each straight at its fan's lowest corner; returns how many fans meet at `v`.
    fn vertex_fans(&self, v: u32, parent: &[AtomicU32]) -> usize {
        let get = |c: u32| parent[c as usize].load(Ordering::Relaxed);
        let set = |c: u32, p: u32| parent[c as usize].store(p, Ordering::Relaxed);
        let find = |mut c: u32| {
            while get(c) != c {
                let grand = get(get(c));
                set(c, grand);
                c = grand;
            }
            c
        };
        let corners = self.vertex_corners(v);
        for &c in corners {
            // The two sides at corner c: its own (c the tail) and the one before (c the head).
            for (side, c_is_tail) in [(c, true), (prev_corner(c), false)] {
                if let Some(partner) = self.partner_across(side, c_is_tail) {
                    debug_assert_eq!(self.corner_vertices[partner as usize], v);
                    let (a, b) = (find(c), find(partner));
                    set(a.max(b), a.min(b));
                }
            }
        }
        let mut fans = 0;
        for &c in corners {
            let root = find(c);
            set(c, root);
            fans += usize::from(root == c);
        }
        fans
    }

    /// The corner joined to an end of `side` across its edge, when the edge is an interior
    /// manifold one: the end is the side's tail when `tail`, else its head. The two sides
    /// run the same way (inconsistent orientation) or opposite ways; either way the partner
    /// is the other side's corner at the same vertex.
    fn partner_across(&self, side: u32, tail: bool) -> Option<u32> {
        let e = self.side_edges[side as usize];
        if e == NO_EDGE {
            return None;
        }
        let [s1, s2] = self.edge_sides(e) else {
            return None;
        };
        let other = if *s1 == side { *s2 } else { *s1 };
        let same_way = self.corner_vertices[*s1 as usize] == self.corner_vertices[*s2 as usize];
        Some(if same_way == tail {
            other
        } else {
            next_corner(other)
        })
    }
}
