//! The closest point of the input near a known triangle, by a walk over the input's
//! triangles: the search the projection, the fit and the export make from the input
//! triangle a vertex was last projected onto (`isotropic.rs`, `fit.rs`, `export.rs`).

use super::corners::NIL;
use crate::geom::bvh::TriangleBvh;
use crate::geom::closest::closest_on_triangle;
use crate::mesh::Mesh;
use crate::mesh::topology::{NO_EDGE, Topology};
use glam::DVec3;

/// Steps at most: a vertex or a centroid is within about an edge of the triangle it starts
/// from, which is a few input triangles even on a scan ten times denser than the result.
const MAX_STEPS: usize = 64;

/// Where a walk ended: the closest point it found and the triangle that point is on.
#[derive(Debug, Clone, Copy)]
pub struct Foot {
    pub point: DVec3,
    pub triangle: u32,
    /// The point's barycentric weights on the triangle.
    pub bary: DVec3,
    /// No neighbour is closer: a local minimum of the distance. `false` when the walk ran
    /// out of steps first (the query was farther from the start than a walk should go).
    pub settled: bool,
}

/// The point closest to `q` found by walking from triangle `start` to the neighbour with a
/// closer point, among the triangles `within` admits, until none is closer. A neighbour
/// is a triangle across an edge, or, when the closest point is a corner of the current
/// triangle, any triangle around that corner (the closer point may be on a triangle that
/// shares only the corner). The walk finds a local minimum of the distance: the closest
/// point of the sheet of the input the search starts on, which is what a vertex that moved
/// by less than an edge wants where the input folds over itself, and it costs a few
/// closest-point tests where the tree search (`geom::bvh`) descends from the root.
pub fn walk(
    input: &Mesh,
    topo: &Topology,
    start: u32,
    q: DVec3,
    within: impl Fn(u32) -> bool,
) -> Foot {
    let on = |t: u32| {
        let [a, b, d] = input.triangle_positions(t as usize);
        let (p, w) = closest_on_triangle(q, a, b, d);
        (p.distance_squared(q), p, w)
    };
    let (mut best, mut foot, mut w) = on(start);
    let mut t = start;
    // The triangle the walk came from: farther than `t`'s point, so never the next step.
    let mut from = NIL;
    for _ in 0..MAX_STEPS {
        // The closest candidate so far: distance², triangle, point, weights.
        let mut next = (best, NIL, foot, w);
        let consider = |u: u32, next: &mut (f64, u32, DVec3, DVec3)| {
            if u != t && u != from && within(u) {
                let (d, p, wu) = on(u);
                if d < next.0 {
                    *next = (d, u, p, wu);
                }
            }
        };
        for e in topo.triangle_edges(t) {
            if e != NO_EDGE {
                topo.edge_triangles(e).for_each(|u| consider(u, &mut next));
            }
        }
        if next.1 == NIL
            && let Some(k) = (0..3).find(|&k| w[k] >= 1.0)
        {
            let corner = input.triangle_vertices(t as usize)[k];
            topo.vertex_triangles(corner)
                .for_each(|u| consider(u, &mut next));
        }
        if next.1 == NIL {
            return Foot {
                point: foot,
                triangle: t,
                bary: w,
                settled: true,
            };
        }
        from = t;
        (best, t, foot, w) = next;
    }
    Foot {
        point: foot,
        triangle: t,
        bary: w,
        settled: false,
    }
}

/// The closest point to `q` near triangle `start`: the [`walk`]'s, or, where the walk runs
/// out of steps, the tree's from where the walk got to (`bvh` indexes the triangles `within`
/// admits). `None` only for an empty tree.
pub fn walk_or_search(
    input: &Mesh,
    topo: &Topology,
    bvh: &TriangleBvh,
    start: u32,
    q: DVec3,
    within: impl Fn(u32) -> bool,
) -> Option<Foot> {
    settle(bvh, q, walk(input, topo, start, q, within))
}

/// `foot` when the walk settled; else the tree's answer, searched from where the walk got to
/// (`bvh` indexes the triangles the walk was allowed on). `None` only for an empty tree.
pub fn settle(bvh: &TriangleBvh, q: DVec3, foot: Foot) -> Option<Foot> {
    if foot.settled {
        return Some(foot);
    }
    let hit = bvh.closest(q, Some(bvh.hit_on(q, foot.triangle)))?;
    Some(Foot {
        point: hit.point,
        triangle: hit.triangle,
        bary: hit.bary,
        settled: true,
    })
}
