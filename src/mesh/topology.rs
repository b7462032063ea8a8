//! On-demand topology of a [`Mesh`]: adjacency, edges, boundary loops, components,
//! non-manifold elements, seams and the Euler characteristic.
//!
//! Everything is built from sorted arrays (CSR), never from hash maps, so every list comes
//! out in a fixed order: a vertex's corners and neighbours ascending, edges by
//! `(low vertex, high vertex)`, an edge's sides ascending.
//!
//! # Vocabulary
//! - *corner* `c = 3t + k`: corner `k` of triangle `t`; its vertex is
//!   `mesh.wedges[mesh.triangles[t][k]].vertex`.
//! - *side* `s = 3t + k`: the side of triangle `t` that runs from corner `k` to corner
//!   `(k + 1) % 3`, in the triangle's (counter-clockwise) orientation. Side `s` starts at
//!   corner `s` (its *tail*).
//! - *edge*: an undirected vertex pair `(a, b)`, `a < b`, with the sides that run along it.
//!
//! # Definitions
//! - **Boundary edge**: exactly one side; **interior manifold edge**: exactly two;
//!   **non-manifold edge**: three or more.
//! - **Inconsistent edge**: an edge along which two sides run the same way (both
//!   `a → b`). The *count* `inconsistent_edges` counts directed edges used by more than one
//!   triangle, so a non-manifold edge with two sides each way counts twice; this is the
//!   definition `data/SOURCES.md` uses. On an edge with two sides both agree.
//! - **Fan**: the corners at a vertex, grouped by "the two triangles share an interior
//!   manifold edge at this vertex" (orientation is ignored, non-manifold edges do not
//!   connect). A manifold interior vertex has one closed fan, a manifold boundary vertex one
//!   open fan.
//! - **Non-manifold vertex**: a vertex with more than one fan (a bowtie or pinch), or an
//!   endpoint of a non-manifold edge.
//! - **Seam edge** (`seam_edges`): an interior manifold edge whose two triangles use
//!   different wedges at one of its ends (texture coordinate or normal differ).
//!   **Texture seam edge** (`texture_seam_edges`): the same, comparing only the
//!   texture-coordinate index of the wedges (a normal-only split is not a texture seam; the
//!   loader merges bit-identical texture coordinates, so index equality is value equality).
//!   Boundary and non-manifold edges are never seams (as in `data/SOURCES.md`: "edges whose
//!   two faces use different UVs"); non-manifold edges are reported on their own.
//! - **Component**: triangles connected through shared vertices (so a bowtie is one
//!   component). Numbered in the order of their lowest triangle. Vertices used by no
//!   triangle belong to no component.
//! - **Boundary chains and loops**: see [`BoundaryChain`]. A loop is a connected piece of
//!   the boundary (chains joined at pinch vertices), as `data/SOURCES.md` counts them.
//! - **Euler characteristic**: `V − E + F` with `V` every vertex of the mesh.
//!
//! A triangle that repeats a vertex (the loader drops these) gets no edge for the side
//! whose two ends are the same vertex ([`NO_EDGE`]); everything else still works and
//! nothing panics.

mod boundary;
mod classify;
mod ring;
#[cfg(test)]
mod tests;
pub(crate) mod union_find;

pub use boundary::BoundaryChain;
pub use ring::{OrderedRing, RingBuffers};

use super::model::Mesh;
use rayon::prelude::*;
use serde::Serialize;
use union_find::UnionFind;

/// Marks a triangle side that has no edge (its two ends are the same vertex).
pub const NO_EDGE: u32 = u32::MAX;

/// How many triangles run along an edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum EdgeKind {
    /// One triangle.
    Boundary,
    /// Two triangles.
    Manifold,
    /// Three or more triangles.
    NonManifold,
}

const EDGE_INCONSISTENT: u8 = 1;
const EDGE_SEAM: u8 = 2;
const EDGE_TEXTURE_SEAM: u8 = 4;

const VERTEX_NON_MANIFOLD: u8 = 1;
const VERTEX_BOUNDARY: u8 = 2;

/// The counts `inspect` and reports show.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct TopologyCounts {
    pub vertices: usize,
    pub triangles: usize,
    pub wedges: usize,
    pub texcoords: usize,
    pub edges: usize,
    pub boundary_edges: usize,
    /// Connected pieces of the boundary (chains sharing a vertex are one loop).
    pub boundary_loops: usize,
    /// Boundary walks, split at pinch vertices (see [`BoundaryChain`]); at least
    /// `boundary_loops`.
    pub boundary_chains: usize,
    /// How many of `boundary_chains` are open (only near non-manifold or inconsistently
    /// oriented edges).
    pub open_boundary_chains: usize,
    pub components: usize,
    pub non_manifold_edges: usize,
    pub non_manifold_vertices: usize,
    /// Directed edges used by more than one triangle.
    pub inconsistent_edges: usize,
    pub seam_edges: usize,
    pub texture_seam_edges: usize,
    pub euler_characteristic: i64,
}

/// The topology of one mesh, as it was when [`Topology::new`] ran.
#[derive(Debug, Clone)]
pub struct Topology {
    wedge_count: usize,
    texcoord_count: usize,
    /// Vertex of each corner (`3t + k`).
    corner_vertices: Vec<u32>,
    /// Vertex → corners (CSR), ascending.
    vertex_corner_offsets: Vec<u32>,
    vertex_corner_list: Vec<u32>,
    /// Vertex → neighbouring vertices (CSR), ascending.
    neighbour_offsets: Vec<u32>,
    neighbour_list: Vec<u32>,
    /// Edges sorted by (low, high) vertex.
    edges: Vec<[u32; 2]>,
    /// Edge → sides (CSR), ascending.
    edge_side_offsets: Vec<u32>,
    edge_side_list: Vec<u32>,
    edge_flags: Vec<u8>,
    /// Edge of each side (`3t + k`), or [`NO_EDGE`].
    side_edges: Vec<u32>,
    /// Fan of each corner: the lowest corner of its fan.
    corner_fans: Vec<u32>,
    vertex_flags: Vec<u8>,
    non_manifold_vertices: Vec<u32>,
    boundary_chains: Vec<BoundaryChain>,
    boundary_loop_count: usize,
    triangle_components: Vec<u32>,
    component_count: usize,
    boundary_edge_count: usize,
    non_manifold_edge_count: usize,
    inconsistent_edge_count: usize,
    seam_edge_count: usize,
    texture_seam_edge_count: usize,
}

/// Compressed rows: `offsets[i]..offsets[i + 1]` indexes `list` for row `i`.
#[inline]
fn row<'a>(offsets: &[u32], list: &'a [u32], i: usize) -> &'a [u32] {
    &list[offsets[i] as usize..offsets[i + 1] as usize]
}

/// Triangle `t`'s three entries of an array kept per corner or per side (`3t + k`).
#[inline]
fn of_triangle(per_corner: &[u32], t: u32) -> [u32; 3] {
    let c = 3 * t as usize;
    [per_corner[c], per_corner[c + 1], per_corner[c + 2]]
}

/// Turns per-row counts into CSR offsets (`counts.len() + 1` entries).
fn offsets_from_counts(counts: &[u32]) -> Vec<u32> {
    let mut offsets = Vec::with_capacity(counts.len() + 1);
    let mut sum = 0u32;
    offsets.push(0);
    for &c in counts {
        sum += c;
        offsets.push(sum);
    }
    offsets
}

impl Topology {
    /// Builds the topology. Panics only if `mesh` violates [`Mesh::check_invariants`]
    /// (a bug in scanmill, never bad input).
    pub fn new(mesh: &Mesh) -> Self {
        let vertex_count = mesh.positions.len();
        let corner_vertices: Vec<u32> = mesh
            .triangles
            .iter()
            .flat_map(|tri| tri.map(|w| mesh.wedges[w as usize].vertex))
            .collect();
        // Independent passes over the corners, side by side (each is a sequential counting
        // sort or union-find: ~15, ~60 and ~10 ms on a 400k-triangle scan).
        let (
            ((vertex_corner_offsets, vertex_corner_list), (triangle_components, component_count)),
            (edges, edge_side_offsets, edge_side_list, side_edges),
        ) = rayon::join(
            || {
                rayon::join(
                    || vertex_corners_csr(vertex_count, &corner_vertices),
                    || components(vertex_count, &corner_vertices),
                )
            },
            || build_edges(vertex_count, &corner_vertices),
        );
        let (neighbour_offsets, neighbour_list) = neighbours_csr(vertex_count, &edges);

        let mut topo = Topology {
            wedge_count: mesh.wedges.len(),
            texcoord_count: mesh.texcoords.len(),
            corner_vertices,
            vertex_corner_offsets,
            vertex_corner_list,
            neighbour_offsets,
            neighbour_list,
            edge_flags: vec![0; edges.len()],
            edges,
            edge_side_offsets,
            edge_side_list,
            side_edges,
            corner_fans: Vec::new(),
            vertex_flags: vec![0; vertex_count],
            non_manifold_vertices: Vec::new(),
            boundary_chains: Vec::new(),
            boundary_loop_count: 0,
            triangle_components,
            component_count,
            boundary_edge_count: 0,
            non_manifold_edge_count: 0,
            inconsistent_edge_count: 0,
            seam_edge_count: 0,
            texture_seam_edge_count: 0,
        };
        topo.classify_edges_and_fans(mesh);
        (topo.boundary_chains, topo.boundary_loop_count) = boundary::trace_chains(&topo);
        topo
    }

    /// Seam flags of an interior manifold edge (sides `s1`, `s2`): compare the two
    /// triangles' wedges at the low and the high vertex.
    fn seam_flags(&self, mesh: &Mesh, s1: u32, s2: u32, lo: u32) -> u8 {
        let wedges_at_ends = |s: u32| {
            let (tail, head) = (s, next_corner(s));
            let wedge = |c: u32| mesh.triangles[c as usize / 3][c as usize % 3];
            if self.corner_vertices[tail as usize] == lo {
                (wedge(tail), wedge(head))
            } else {
                (wedge(head), wedge(tail))
            }
        };
        let texcoord = |w: u32| mesh.wedges[w as usize].texcoord;
        let (first, other) = (wedges_at_ends(s1), wedges_at_ends(s2));
        let mut flags = 0;
        if other != first {
            flags |= EDGE_SEAM;
        }
        if texcoord(other.0) != texcoord(first.0) || texcoord(other.1) != texcoord(first.1) {
            flags |= EDGE_TEXTURE_SEAM;
        }
        flags
    }

    // ----- sizes -----

    pub fn vertex_count(&self) -> usize {
        self.vertex_flags.len()
    }

    pub fn triangle_count(&self) -> usize {
        self.corner_vertices.len() / 3
    }

    pub fn edge_count(&self) -> usize {
        self.edges.len()
    }

    // ----- corners and vertices -----

    /// The vertex at corner `c = 3t + k`.
    #[inline]
    pub fn corner_vertex(&self, c: u32) -> u32 {
        self.corner_vertices[c as usize]
    }

    /// The three vertices of triangle `t`.
    #[inline]
    pub fn triangle_vertices(&self, t: u32) -> [u32; 3] {
        of_triangle(&self.corner_vertices, t)
    }

    /// The corners (`3t + k`) at vertex `v`, ascending.
    #[inline]
    pub fn vertex_corners(&self, v: u32) -> &[u32] {
        row(
            &self.vertex_corner_offsets,
            &self.vertex_corner_list,
            v as usize,
        )
    }

    /// The triangles around vertex `v`, ascending (a triangle that repeats `v` appears
    /// once per corner).
    #[inline]
    pub fn vertex_triangles(&self, v: u32) -> impl ExactSizeIterator<Item = u32> + '_ {
        self.vertex_corners(v).iter().map(|&c| c / 3)
    }

    /// The vertices that share an edge with `v`, ascending (the unordered 1-ring).
    #[inline]
    pub fn vertex_neighbours(&self, v: u32) -> &[u32] {
        row(&self.neighbour_offsets, &self.neighbour_list, v as usize)
    }

    /// The fan of corner `c`, named by its lowest corner.
    #[inline]
    pub fn corner_fan(&self, c: u32) -> u32 {
        self.corner_fans[c as usize]
    }

    /// How many fans meet at `v` (0 for a vertex no triangle uses).
    pub fn vertex_fan_count(&self, v: u32) -> usize {
        self.vertex_corners(v)
            .iter()
            .filter(|&&c| self.corner_fans[c as usize] == c)
            .count()
    }

    pub fn is_non_manifold_vertex(&self, v: u32) -> bool {
        self.vertex_flags[v as usize] & VERTEX_NON_MANIFOLD != 0
    }

    /// True when `v` is an end of a boundary edge.
    pub fn is_boundary_vertex(&self, v: u32) -> bool {
        self.vertex_flags[v as usize] & VERTEX_BOUNDARY != 0
    }

    /// Non-manifold vertices, ascending.
    pub fn non_manifold_vertices(&self) -> &[u32] {
        &self.non_manifold_vertices
    }

    // ----- edges -----

    /// The two vertices of edge `e`, low first.
    #[inline]
    pub fn edge_vertices(&self, e: u32) -> [u32; 2] {
        self.edges[e as usize]
    }

    /// All edges, sorted by (low, high) vertex; an edge's index is its position here.
    pub fn edges(&self) -> &[[u32; 2]] {
        &self.edges
    }

    /// The sides (`3t + k`) along edge `e`, ascending.
    #[inline]
    pub fn edge_sides(&self, e: u32) -> &[u32] {
        row(&self.edge_side_offsets, &self.edge_side_list, e as usize)
    }

    /// The triangles along edge `e`, ascending.
    #[inline]
    pub fn edge_triangles(&self, e: u32) -> impl ExactSizeIterator<Item = u32> + '_ {
        self.edge_sides(e).iter().map(|&s| s / 3)
    }

    /// The edge between `a` and `b`, if there is one.
    pub fn find_edge(&self, a: u32, b: u32) -> Option<u32> {
        let key = [a.min(b), a.max(b)];
        self.edges.binary_search(&key).ok().map(|e| e as u32)
    }

    /// The edge of side `s = 3t + k` (from corner `k` to corner `k + 1`), or [`NO_EDGE`].
    #[inline]
    pub fn side_edge(&self, s: u32) -> u32 {
        self.side_edges[s as usize]
    }

    /// The edges of triangle `t`'s three sides.
    #[inline]
    pub fn triangle_edges(&self, t: u32) -> [u32; 3] {
        of_triangle(&self.side_edges, t)
    }

    /// The other side of an interior manifold edge (`None` on boundary and non-manifold
    /// edges).
    pub fn opposite_side(&self, s: u32) -> Option<u32> {
        let e = self.side_edge(s);
        if e == NO_EDGE {
            return None;
        }
        match *self.edge_sides(e) {
            [a, b] => Some(if a == s { b } else { a }),
            _ => None,
        }
    }

    pub fn edge_kind(&self, e: u32) -> EdgeKind {
        match self.edge_sides(e).len() {
            0 | 1 => EdgeKind::Boundary,
            2 => EdgeKind::Manifold,
            _ => EdgeKind::NonManifold,
        }
    }

    pub fn is_boundary_edge(&self, e: u32) -> bool {
        self.edge_sides(e).len() == 1
    }

    pub fn is_non_manifold_edge(&self, e: u32) -> bool {
        self.edge_sides(e).len() > 2
    }

    /// Two triangles run along `e` in the same direction (also on a non-manifold edge).
    pub fn is_inconsistent_edge(&self, e: u32) -> bool {
        self.edge_flags[e as usize] & EDGE_INCONSISTENT != 0
    }

    /// `e` is an interior manifold edge whose triangles use different wedges at one end.
    pub fn is_seam_edge(&self, e: u32) -> bool {
        self.edge_flags[e as usize] & EDGE_SEAM != 0
    }

    /// `e` is an interior manifold edge whose triangles use different texture coordinates
    /// at one end.
    pub fn is_texture_seam_edge(&self, e: u32) -> bool {
        self.edge_flags[e as usize] & EDGE_TEXTURE_SEAM != 0
    }

    /// Non-manifold edges, ascending.
    pub fn non_manifold_edges(&self) -> impl Iterator<Item = u32> + '_ {
        (0..self.edges.len() as u32).filter(|&e| self.is_non_manifold_edge(e))
    }

    /// Boundary edges, ascending.
    pub fn boundary_edges(&self) -> impl Iterator<Item = u32> + '_ {
        (0..self.edges.len() as u32).filter(|&e| self.is_boundary_edge(e))
    }

    // ----- global structure -----

    /// Boundary chains (closed and open), in a fixed order; chains of the same boundary
    /// loop share [`BoundaryChain::boundary_loop`].
    pub fn boundary_chains(&self) -> &[BoundaryChain] {
        &self.boundary_chains
    }

    /// Connected pieces of the boundary.
    pub fn boundary_loop_count(&self) -> usize {
        self.boundary_loop_count
    }

    pub fn component_count(&self) -> usize {
        self.component_count
    }

    /// The component of every triangle.
    pub fn triangle_components(&self) -> &[u32] {
        &self.triangle_components
    }

    #[inline]
    pub fn triangle_component(&self, t: u32) -> u32 {
        self.triangle_components[t as usize]
    }

    /// `V − E + F`.
    pub fn euler_characteristic(&self) -> i64 {
        self.vertex_count() as i64 - self.edge_count() as i64 + self.triangle_count() as i64
    }

    pub fn counts(&self) -> TopologyCounts {
        TopologyCounts {
            vertices: self.vertex_count(),
            triangles: self.triangle_count(),
            wedges: self.wedge_count,
            texcoords: self.texcoord_count,
            edges: self.edge_count(),
            boundary_edges: self.boundary_edge_count,
            boundary_loops: self.boundary_loop_count,
            boundary_chains: self.boundary_chains.len(),
            open_boundary_chains: self.boundary_chains.iter().filter(|l| !l.closed).count(),
            components: self.component_count,
            non_manifold_edges: self.non_manifold_edge_count,
            non_manifold_vertices: self.non_manifold_vertices.len(),
            inconsistent_edges: self.inconsistent_edge_count,
            seam_edges: self.seam_edge_count,
            texture_seam_edges: self.texture_seam_edge_count,
            euler_characteristic: self.euler_characteristic(),
        }
    }
}

impl Mesh {
    /// Computes the mesh's [`Topology`].
    pub fn topology(&self) -> Topology {
        Topology::new(self)
    }
}

/// The corner after `c` in its triangle (the head of side `c`).
#[inline]
pub(crate) fn next_corner(c: u32) -> u32 {
    if c % 3 == 2 { c - 2 } else { c + 1 }
}

/// The corner before `c` in its triangle.
#[inline]
pub(crate) fn prev_corner(c: u32) -> u32 {
    if c.is_multiple_of(3) { c + 2 } else { c - 1 }
}

/// Components through shared vertices, numbered by their lowest triangle: each triangle's
/// component, and how many there are.
fn components(vertex_count: usize, corner_vertices: &[u32]) -> (Vec<u32>, usize) {
    let mut sets = UnionFind::new(vertex_count);
    for tri in corner_vertices.chunks_exact(3) {
        sets.union(tri[0], tri[1]);
        sets.union(tri[0], tri[2]);
    }
    let mut component_of_root = vec![u32::MAX; vertex_count];
    let mut count = 0u32;
    let triangle_components = corner_vertices
        .chunks_exact(3)
        .map(|tri| {
            let root = sets.find(tri[0]) as usize;
            if component_of_root[root] == u32::MAX {
                component_of_root[root] = count;
                count += 1;
            }
            component_of_root[root]
        })
        .collect();
    (triangle_components, count as usize)
}

/// Vertex → corners by counting sort; corners come out ascending per vertex.
fn vertex_corners_csr(vertex_count: usize, corner_vertices: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let mut counts = vec![0u32; vertex_count];
    for &v in corner_vertices {
        counts[v as usize] += 1;
    }
    let offsets = offsets_from_counts(&counts);
    let mut next: Vec<u32> = offsets[..vertex_count].to_vec();
    let mut list = vec![0u32; corner_vertices.len()];
    for (c, &v) in corner_vertices.iter().enumerate() {
        list[next[v as usize] as usize] = c as u32;
        next[v as usize] += 1;
    }
    (offsets, list)
}

type EdgeArrays = (Vec<[u32; 2]>, Vec<u32>, Vec<u32>, Vec<u32>);

/// Edges from sides: bucket the sides by their low vertex (counting sort), sort each small
/// bucket by (high vertex, side), then read off runs of equal high vertex.
/// Returns (edges, edge→side offsets, side list, side→edge).
fn build_edges(vertex_count: usize, corner_vertices: &[u32]) -> EdgeArrays {
    let side_count = corner_vertices.len();
    let (bucket_offsets, mut keyed) = bucket_sides(vertex_count, corner_vertices);
    let edge_base = sort_buckets(&mut keyed, &bucket_offsets);
    let (edges, edge_offsets) = read_edges(&keyed, &bucket_offsets, &edge_base);
    // The sides in bucket order, and each side's edge.
    let side_list: Vec<u32> = keyed.par_iter().map(|&key| key as u32).collect();
    drop(keyed);
    let mut side_edges = vec![NO_EDGE; side_count];
    for (e, run) in edge_offsets.windows(2).enumerate() {
        for &side in &side_list[run[0] as usize..run[1] as usize] {
            side_edges[side as usize] = e as u32;
        }
    }
    (edges, edge_offsets, side_list, side_edges)
}

/// The sides (corner `s` to the next corner) bucketed by their low vertex (counting sort),
/// each as `(high vertex << 32) | side`, unsorted within its bucket, with the buckets'
/// offsets. Sides whose two ends are one vertex have no edge and are left out.
fn bucket_sides(vertex_count: usize, corner_vertices: &[u32]) -> (Vec<u32>, Vec<u64>) {
    let ends = |s: usize| {
        (
            corner_vertices[s],
            corner_vertices[next_corner(s as u32) as usize],
        )
    };
    let mut counts = vec![0u32; vertex_count];
    for s in 0..corner_vertices.len() {
        let (a, b) = ends(s);
        if a != b {
            counts[a.min(b) as usize] += 1;
        }
    }
    let bucket_offsets = offsets_from_counts(&counts);
    drop(counts);
    let mut next: Vec<u32> = bucket_offsets[..vertex_count].to_vec();
    // (high vertex << 32) | side: sorting a bucket sorts by high vertex, then side.
    let mut keyed = vec![0u64; bucket_offsets[vertex_count] as usize];
    for s in 0..corner_vertices.len() {
        let (a, b) = ends(s);
        if a != b {
            let lo = a.min(b) as usize;
            keyed[next[lo] as usize] = (u64::from(a.max(b)) << 32) | s as u64;
            next[lo] += 1;
        }
    }
    (bucket_offsets, keyed)
}

/// Vertices per block of [`sort_buckets`] and [`read_edges`].
const EDGE_BLOCK: usize = 4096;

/// The keys of each block of [`EDGE_BLOCK`] low vertices: `keyed` cut at the blocks'
/// first buckets.
fn key_blocks<'k>(keyed: &'k mut [u64], bucket_offsets: &[u32]) -> Vec<&'k mut [u64]> {
    let vertex_count = bucket_offsets.len() - 1;
    let mut blocks = Vec::with_capacity(vertex_count.div_ceil(EDGE_BLOCK));
    let mut rest = keyed;
    for first in (0..vertex_count).step_by(EDGE_BLOCK) {
        let end = (first + EDGE_BLOCK).min(vertex_count);
        let len = (bucket_offsets[end] - bucket_offsets[first]) as usize;
        let (block, tail) = std::mem::take(&mut rest).split_at_mut(len);
        blocks.push(block);
        rest = tail;
    }
    blocks
}

/// Sorts every bucket of `keyed` (by high vertex, then side), blocks of low vertices in
/// parallel (each bucket on its own: the same order as sorting them one after another),
/// and returns the first edge index of each block, with the edge count last. An edge is a
/// run of equal high vertex in its bucket.
fn sort_buckets(keyed: &mut [u64], bucket_offsets: &[u32]) -> Vec<usize> {
    let vertex_count = bucket_offsets.len() - 1;
    let counts: Vec<usize> = key_blocks(keyed, bucket_offsets)
        .into_par_iter()
        .enumerate()
        .map(|(b, block)| {
            let first = b * EDGE_BLOCK;
            let base = bucket_offsets[first] as usize;
            let mut edges = 0;
            for lo in first..(first + EDGE_BLOCK).min(vertex_count) {
                let bucket = &mut block
                    [bucket_offsets[lo] as usize - base..bucket_offsets[lo + 1] as usize - base];
                bucket.sort_unstable();
                edges += bucket.chunk_by(|x, y| x >> 32 == y >> 32).count();
            }
            edges
        })
        .collect();
    let mut base = Vec::with_capacity(counts.len() + 1);
    let mut sum = 0;
    base.push(0);
    for c in counts {
        sum += c;
        base.push(sum);
    }
    base
}

/// The edges `[low, high]` in order and each edge's first position in `keyed` (its sides'
/// offsets, with `keyed.len()` last), from sorted buckets; blocks of low vertices in
/// parallel, each writing its own edges from `edge_base` ([`sort_buckets`]).
fn read_edges(
    keyed: &[u64],
    bucket_offsets: &[u32],
    edge_base: &[usize],
) -> (Vec<[u32; 2]>, Vec<u32>) {
    let vertex_count = bucket_offsets.len() - 1;
    let edge_count = edge_base[edge_base.len() - 1];
    let mut edges = vec![[0u32; 2]; edge_count];
    let mut offsets = vec![0u32; edge_count + 1];
    offsets[edge_count] = keyed.len() as u32;
    // Each block's share of the two arrays.
    let mut shares = Vec::with_capacity(edge_base.len() - 1);
    let (mut edges_rest, mut offsets_rest) = (&mut edges[..], &mut offsets[..edge_count]);
    for run in edge_base.windows(2) {
        let len = run[1] - run[0];
        let (e, e_tail) = std::mem::take(&mut edges_rest).split_at_mut(len);
        let (o, o_tail) = std::mem::take(&mut offsets_rest).split_at_mut(len);
        shares.push((e, o));
        (edges_rest, offsets_rest) = (e_tail, o_tail);
    }
    shares
        .into_par_iter()
        .enumerate()
        .for_each(|(b, (edges, offsets))| {
            let first = b * EDGE_BLOCK;
            let mut e = 0;
            for lo in first..(first + EDGE_BLOCK).min(vertex_count) {
                let start = bucket_offsets[lo] as usize;
                let bucket = &keyed[start..bucket_offsets[lo + 1] as usize];
                let mut at = start;
                for run in bucket.chunk_by(|x, y| x >> 32 == y >> 32) {
                    edges[e] = [lo as u32, (run[0] >> 32) as u32];
                    offsets[e] = at as u32;
                    at += run.len();
                    e += 1;
                }
            }
        });
    (edges, offsets)
}

/// Vertex → neighbours from the sorted edge list. Edges `(a, v)` with `a < v` all come
/// before edges `(v, b)`, and each group is sorted, so every row comes out ascending.
fn neighbours_csr(vertex_count: usize, edges: &[[u32; 2]]) -> (Vec<u32>, Vec<u32>) {
    let mut counts = vec![0u32; vertex_count];
    for &[a, b] in edges {
        counts[a as usize] += 1;
        counts[b as usize] += 1;
    }
    let offsets = offsets_from_counts(&counts);
    let mut next: Vec<u32> = offsets[..vertex_count].to_vec();
    let mut list = vec![0u32; 2 * edges.len()];
    for &[a, b] in edges {
        list[next[a as usize] as usize] = b;
        next[a as usize] += 1;
        list[next[b as usize] as usize] = a;
        next[b as usize] += 1;
    }
    (offsets, list)
}
