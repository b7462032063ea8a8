//! Boundary chains: the boundary edges chained head to tail in the direction their
//! triangle runs along them; and boundary loops: the chains grouped by shared vertices.

use super::union_find::UnionFind;
use super::{Topology, next_corner};
use serde::Serialize;

/// One chain of boundary edges, in order: a simple closed polygon on a clean mesh, the
/// unit hole filling works on.
///
/// Each boundary edge is used by exactly one chain. Every step follows the edge's only
/// side, from its tail to its head, so on a consistently oriented surface the surface is
/// on the left of the walk.
///
/// At a *pinch* vertex (several boundary edges leave it) the walk continues with the
/// boundary edge of the same fan as the edge it arrived by, so a pinch vertex appears once
/// in the loop of each of its open fans: two triangles sharing only one vertex (a bowtie)
/// give two loops of three vertices. If no edge of the same fan leaves the vertex (only
/// near non-manifold or inconsistently oriented edges), the walk takes the lowest unused
/// boundary edge leaving it, and closes when it is back at its first vertex.
///
/// If the walk gets stuck before it is back (an inconsistently oriented edge reverses the
/// direction), the chain is *open* (`closed == false`). Open chains are listed with the
/// loops, and are started at a vertex with more boundary edges leaving than arriving so
/// that a chain is not cut in two.
///
/// A *boundary loop* (what [`TopologyCounts::boundary_loops`](super::TopologyCounts)
/// counts, and what `data/SOURCES.md` calls loops) is a connected piece of the boundary:
/// chains that share a vertex belong to the same loop. A bowtie's two chains are one loop.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct BoundaryChain {
    /// The vertices in walking order. A closed loop does not repeat its first vertex
    /// (`vertices.len() == edges.len()`); an open chain lists both ends
    /// (`vertices.len() == edges.len() + 1`).
    pub vertices: Vec<u32>,
    /// The boundary edges in walking order; edge `i` runs from `vertices[i]` to
    /// `vertices[i + 1]` (wrapping around for a closed loop).
    pub edges: Vec<u32>,
    pub closed: bool,
    /// The boundary loop this chain belongs to; loops are numbered in order of their first
    /// chain, so loop `k`'s first chain comes before loop `k + 1`'s.
    pub boundary_loop: u32,
}

/// One boundary edge as walked: from `tail` to `head` along side `side`.
#[derive(Clone, Copy)]
struct Step {
    tail: u32,
    head: u32,
    side: u32,
    edge: u32,
}

/// The chains and the number of loops they form.
pub(super) fn trace_chains(topo: &Topology) -> (Vec<BoundaryChain>, usize) {
    // Boundary steps sorted by tail vertex (then edge): the steps leaving a vertex are a
    // contiguous range found by binary search. No per-vertex arrays needed.
    let mut steps: Vec<Step> = topo
        .boundary_edges()
        .map(|e| {
            let side = topo.edge_sides(e)[0];
            Step {
                tail: topo.corner_vertex(side),
                head: topo.corner_vertex(next_corner(side)),
                side,
                edge: e,
            }
        })
        .collect();
    steps.sort_unstable_by_key(|s| (s.tail, s.edge));
    let mut arrivals: Vec<u32> = steps.iter().map(|s| s.head).collect();
    arrivals.sort_unstable();

    let leaving = |v: u32| {
        let start = steps.partition_point(|s| s.tail < v);
        let end = steps.partition_point(|s| s.tail <= v);
        start..end
    };
    let arriving_count =
        |v: u32| arrivals.partition_point(|&h| h <= v) - arrivals.partition_point(|&h| h < v);

    let mut used = vec![false; steps.len()];
    let mut loops = Vec::new();
    // First the chains that must start somewhere (more leaving than arriving), then the rest.
    for i in 0..steps.len() {
        let v = steps[i].tail;
        if !used[i] && leaving(v).len() > arriving_count(v) {
            loops.push(walk(topo, &steps, &leaving, &mut used, i));
        }
    }
    for i in 0..steps.len() {
        if !used[i] {
            loops.push(walk(topo, &steps, &leaving, &mut used, i));
        }
    }
    let loop_count = number_loops(topo.vertex_count(), &mut loops);
    (loops, loop_count)
}

/// Groups chains that share a vertex and numbers the groups in chain order.
fn number_loops(vertex_count: usize, chains: &mut [BoundaryChain]) -> usize {
    if chains.is_empty() {
        return 0;
    }
    let mut sets = UnionFind::new(vertex_count);
    for chain in chains.iter() {
        for pair in chain.vertices.windows(2) {
            sets.union(pair[0], pair[1]);
        }
    }
    let mut number_of_root = vec![u32::MAX; vertex_count];
    let mut count = 0u32;
    for chain in chains.iter_mut() {
        let root = sets.find(chain.vertices[0]) as usize;
        if number_of_root[root] == u32::MAX {
            number_of_root[root] = count;
            count += 1;
        }
        chain.boundary_loop = number_of_root[root];
    }
    count as usize
}

fn walk(
    topo: &Topology,
    steps: &[Step],
    leaving: &impl Fn(u32) -> std::ops::Range<usize>,
    used: &mut [bool],
    first: usize,
) -> BoundaryChain {
    let start_vertex = steps[first].tail;
    let mut vertices = vec![start_vertex];
    let mut edges = vec![steps[first].edge];
    used[first] = true;
    let mut current = first;
    loop {
        let here = steps[current].head;
        // The fan of the arriving triangle at `here` (the head corner of its side).
        let fan = topo.corner_fan(next_corner(steps[current].side));
        let candidates = leaving(here);
        let same_fan = candidates
            .clone()
            .find(|&j| topo.corner_fan(steps[j].side) == fan);
        let next = match same_fan {
            Some(j) if j == first => return closed(vertices, edges),
            Some(j) if !used[j] => Some(j),
            _ if here == start_vertex => return closed(vertices, edges),
            _ => candidates.clone().find(|&j| !used[j]),
        };
        vertices.push(here);
        let Some(j) = next else {
            return BoundaryChain {
                vertices,
                edges,
                closed: false,
                boundary_loop: 0,
            };
        };
        used[j] = true;
        edges.push(steps[j].edge);
        current = j;
    }
}

fn closed(vertices: Vec<u32>, edges: Vec<u32>) -> BoundaryChain {
    BoundaryChain {
        vertices,
        edges,
        closed: true,
        boundary_loop: 0,
    }
}
