//! The closest point of the input near a known triangle, by a walk over the input's
//! triangles: the search the fit (`fit.rs`) makes from where a vertex was last projected.

use super::corners::NIL;
use crate::geom::closest::closest_on_triangle;
use crate::mesh::Mesh;
use crate::mesh::topology::{NO_EDGE, Topology};
use glam::DVec3;

/// Steps at most: a vertex or a centroid is within about an edge of the triangle it starts
/// from, which is a few input triangles even on a scan ten times denser than the result.
const MAX_STEPS: usize = 64;

/// The point of the input closest to `q` found by walking from triangle `start` to the
/// neighbour with a closer point, until none is closer. A
/// neighbour is a triangle across an edge, or, when the closest point is a corner of the
/// current triangle, any triangle around that corner (the closer point may be on a triangle
/// that shares only the corner). The walk finds a local minimum of the distance: the
/// closest point of the sheet of the input the search starts on, which is what a vertex
/// that moved by less than an edge wants where the input folds over itself, and it costs a
/// few closest-point tests where the tree search (`geom::bvh`) descends from the root.
pub fn closest(input: &Mesh, topo: &Topology, start: u32, q: DVec3) -> DVec3 {
    let on = |t: u32| {
        let [a, b, d] = input.triangle_positions(t as usize);
        let (p, w) = closest_on_triangle(q, a, b, d);
        (p.distance_squared(q), p, w)
    };
    let (mut best, mut foot, mut w) = on(start);
    let mut t = start;
    for _ in 0..MAX_STEPS {
        // The closest candidate so far: distance², triangle, point, weights.
        let mut next = (best, NIL, foot, w);
        let consider = |u: u32, next: &mut (f64, u32, DVec3, DVec3)| {
            if u != t {
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
            break;
        }
        (best, t, foot, w) = next;
    }
    foot
}
