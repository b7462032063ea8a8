//! Boundary loops: the boundary edges chained head to tail in the direction their
//! triangle runs along them.

use super::{Topology, next_corner};
use serde::Serialize;

/// One chain of boundary edges, in order.
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
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct BoundaryLoop {
    /// The vertices in walking order. A closed loop does not repeat its first vertex
    /// (`vertices.len() == edges.len()`); an open chain lists both ends
    /// (`vertices.len() == edges.len() + 1`).
    pub vertices: Vec<u32>,
    /// The boundary edges in walking order; edge `i` runs from `vertices[i]` to
    /// `vertices[i + 1]` (wrapping around for a closed loop).
    pub edges: Vec<u32>,
    pub closed: bool,
}

/// One boundary edge as walked: from `tail` to `head` along side `side`.
#[derive(Clone, Copy)]
struct Step {
    tail: u32,
    head: u32,
    side: u32,
    edge: u32,
}

pub(super) fn trace_loops(topo: &Topology) -> Vec<BoundaryLoop> {
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
    loops
}

fn walk(
    topo: &Topology,
    steps: &[Step],
    leaving: &impl Fn(u32) -> std::ops::Range<usize>,
    used: &mut [bool],
    first: usize,
) -> BoundaryLoop {
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
            return BoundaryLoop {
                vertices,
                edges,
                closed: false,
            };
        };
        used[j] = true;
        edges.push(steps[j].edge);
        current = j;
    }
}

fn closed(vertices: Vec<u32>, edges: Vec<u32>) -> BoundaryLoop {
    BoundaryLoop {
        vertices,
        edges,
        closed: true,
    }
}
