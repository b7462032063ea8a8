//! A compact bounding-volume hierarchy over a mesh's triangles for exact closest-point
//! queries: the index behind every two-mesh metric.
//!
//! Why not parry3d's `TriMesh`: on a 400k-triangle scan it holds about 100 MB at its peak
//! (64-byte f64 nodes, one leaf per triangle, a refit buffer of the same size, a copy of the
//! vertices and indices), which alone broke the whole run's memory budget (issue #8: 400 bytes
//! per input triangle). This tree has leaves of up to [`LEAF_SIZE`] triangles and 32-byte
//! nodes with `f32` boxes rounded outwards, so the boxes stay conservative for the `f64`
//! queries: about 8 MB for the same scan, positions read from the mesh itself.
//!
//! Queries are exact (the closest point of each candidate triangle is computed in `f64`,
//! [`closest_on_triangle`]) and deterministic: the tree does not depend on the thread count,
//! and the traversal order (nearer child first) only depends on the tree and the query.

use crate::mesh::Mesh;
use glam::DVec3;

/// Triangles per leaf. Four keeps the tree small (a quarter of the nodes of one per leaf)
/// while a leaf's triangles are still cheap to test one after another.
pub const LEAF_SIZE: usize = 4;

/// A node: a box, and either two children (`count == 0`, at `first` and `first + 1`) or a
/// run of `count` triangles starting at `first` in [`TriangleBvh::order`].
#[derive(Debug, Clone, Copy)]
struct Node {
    min: [f32; 3],
    max: [f32; 3],
    first: u32,
    count: u32,
}

/// The closest point of a triangle to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleHit {
    /// The mesh's triangle index.
    pub triangle: u32,
    pub point: DVec3,
    /// Weights of the triangle's corners 0, 1, 2.
    pub bary: DVec3,
    pub distance_squared: f64,
}

pub struct TriangleBvh<'a> {
    mesh: &'a Mesh,
    nodes: Vec<Node>,
    /// Mesh triangle indices in leaf order.
    order: Vec<u32>,
    /// The triangles' vertex indices in leaf order (one indirection less per test).
    corners: Vec<[u32; 3]>,
}

/// The largest `f32` not above `x`, and the smallest not below it.
fn f32_down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x { f.next_down() } else { f }
}

fn f32_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x { f.next_up() } else { f }
}

impl<'a> TriangleBvh<'a> {
    /// Indexes the given triangles of `mesh` (the caller leaves out those it does not want,
    /// e.g. zero-area ones). Positions must be finite.
    pub fn new(mesh: &'a Mesh, triangles: Vec<u32>) -> TriangleBvh<'a> {
        let mut items: Vec<(u32, [f32; 3])> = triangles
            .iter()
            .map(|&t| {
                let [a, b, c] = mesh.triangle_positions(t as usize);
                let centroid = (a + b + c) / 3.0;
                (t, centroid.as_vec3().to_array())
            })
            .collect();
        let mut nodes = Vec::with_capacity(2 * items.len() / LEAF_SIZE + 1);
        nodes.push(Node {
            min: [0.0; 3],
            max: [0.0; 3],
            first: 0,
            count: 0,
        });
        // Depth-first with an explicit stack: (node, start, end) over `items`.
        let mut stack = vec![(0usize, 0usize, items.len())];
        while let Some((node, start, end)) = stack.pop() {
            let (min, max) = bounds(mesh, &items[start..end]);
            nodes[node].min = min;
            nodes[node].max = max;
            if end - start <= LEAF_SIZE {
                nodes[node].first = start as u32;
                nodes[node].count = (end - start) as u32;
                continue;
            }
            // Split at the median centroid along the axis where the centroids spread most.
            let slice = &mut items[start..end];
            let axis = widest_centroid_axis(slice);
            let mid = slice.len() / 2;
            slice.select_nth_unstable_by(mid, |a, b| {
                a.1[axis].total_cmp(&b.1[axis]).then(a.0.cmp(&b.0))
            });
            let left = nodes.len();
            nodes[node].first = left as u32;
            nodes[node].count = 0;
            for _ in 0..2 {
                nodes.push(Node {
                    min: [0.0; 3],
                    max: [0.0; 3],
                    first: 0,
                    count: 0,
                });
            }
            stack.push((left + 1, start + mid, end));
            stack.push((left, start, start + mid));
        }
        let order: Vec<u32> = items.iter().map(|&(t, _)| t).collect();
        let corners = order
            .iter()
            .map(|&t| mesh.triangle_vertices(t as usize))
            .collect();
        TriangleBvh {
            mesh,
            nodes,
            order,
            corners,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// Bytes held by the index (not counting the mesh).
    pub fn heap_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node>()
            + self.order.capacity() * 4
            + self.corners.capacity() * 12
    }

    /// The closest point of the indexed surface to `p`. `start`, if given, is a candidate
    /// already known (e.g. from a nearby triangle): it bounds the search from the start, which
    /// prunes most of the tree. `None` only for an empty index.
    pub fn closest(&self, p: DVec3, start: Option<TriangleHit>) -> Option<TriangleHit> {
        if self.order.is_empty() {
            return None;
        }
        let mut best = start;
        let mut best_d2 = best.map_or(f64::INFINITY, |h| h.distance_squared);
        // Depth is about log2(n / LEAF_SIZE) for a median split; 64 covers any mesh we can load.
        let mut stack = [0u32; 64];
        let mut top = 0;
        let mut node = 0u32;
        loop {
            let n = &self.nodes[node as usize];
            if n.count > 0 {
                let first = n.first as usize;
                for i in first..first + n.count as usize {
                    let [a, b, c] = self.corners[i].map(|v| self.mesh.positions[v as usize]);
                    let (point, bary) = closest_on_triangle(p, a, b, c);
                    let d2 = point.distance_squared(p);
                    if d2 < best_d2 {
                        best_d2 = d2;
                        best = Some(TriangleHit {
                            triangle: self.order[i],
                            point,
                            bary,
                            distance_squared: d2,
                        });
                    }
                }
            } else {
                let (l, r) = (n.first, n.first + 1);
                let dl = box_distance_squared(&self.nodes[l as usize], p);
                let dr = box_distance_squared(&self.nodes[r as usize], p);
                let (near, d_near, far, d_far) = if dl <= dr {
                    (l, dl, r, dr)
                } else {
                    (r, dr, l, dl)
                };
                if d_far < best_d2 && top < stack.len() {
                    stack[top] = far;
                    top += 1;
                }
                if d_near < best_d2 {
                    node = near;
                    continue;
                }
            }
            // Next pending node that can still hold something closer.
            loop {
                if top == 0 {
                    return best;
                }
                top -= 1;
                node = stack[top];
                if box_distance_squared(&self.nodes[node as usize], p) < best_d2 {
                    break;
                }
            }
        }
    }

    /// The closest point of triangle `t` of the mesh (indexed or not) to `p`.
    pub fn hit_on(&self, p: DVec3, t: u32) -> TriangleHit {
        let [a, b, c] = self.mesh.triangle_positions(t as usize);
        let (point, bary) = closest_on_triangle(p, a, b, c);
        TriangleHit {
            triangle: t,
            point,
            bary,
            distance_squared: point.distance_squared(p),
        }
    }
}

fn bounds(mesh: &Mesh, items: &[(u32, [f32; 3])]) -> ([f32; 3], [f32; 3]) {
    let mut min = DVec3::INFINITY;
    let mut max = DVec3::NEG_INFINITY;
    for &(t, _) in items {
        for p in mesh.triangle_positions(t as usize) {
            min = min.min(p);
            max = max.max(p);
        }
    }
    (
        [f32_down(min.x), f32_down(min.y), f32_down(min.z)],
        [f32_up(max.x), f32_up(max.y), f32_up(max.z)],
    )
}

fn widest_centroid_axis(items: &[(u32, [f32; 3])]) -> usize {
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    for (_, c) in items {
        for k in 0..3 {
            min[k] = min[k].min(c[k]);
            max[k] = max[k].max(c[k]);
        }
    }
    let extent = [max[0] - min[0], max[1] - min[1], max[2] - min[2]];
    if extent[0] >= extent[1] && extent[0] >= extent[2] {
        0
    } else if extent[1] >= extent[2] {
        1
    } else {
        2
    }
}

/// Squared distance from `p` to the node's box (0 inside).
#[inline]
fn box_distance_squared(n: &Node, p: DVec3) -> f64 {
    let lo = DVec3::new(n.min[0] as f64, n.min[1] as f64, n.min[2] as f64);
    let hi = DVec3::new(n.max[0] as f64, n.max[1] as f64, n.max[2] as f64);
    let d = (lo - p).max(p - hi).max(DVec3::ZERO);
    d.length_squared()
}

/// The point of triangle `a b c` closest to `p`, and its barycentric weights, by the
/// Voronoi-region case analysis (Ericson, *Real-Time Collision Detection*, §5.1.5): every
/// corner and edge region is tested before the interior, so a degenerate triangle still
/// gives a point on it.
pub fn closest_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> (DVec3, DVec3) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, DVec3::X);
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, DVec3::Y);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, DVec3::new(1.0 - v, v, 0.0));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, DVec3::Z);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, DVec3::new(1.0 - w, 0.0, w));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, DVec3::new(0.0, 1.0 - w, w));
    }
    let denom = va + vb + vc;
    if denom.abs() <= f64::MIN_POSITIVE || !denom.is_finite() {
        // Only reachable for a degenerate triangle that slipped through: its corner a.
        return (a, DVec3::X);
    }
    let v = vb / denom;
    let w = vc / denom;
    (a + ab * v + ac * w, DVec3::new(1.0 - v - w, v, w))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::{grid, uv_sphere};
    use crate::metrics::surface::rng;
    use rand::RngExt;

    fn brute_force(mesh: &Mesh, p: DVec3) -> f64 {
        (0..mesh.triangles.len())
            .map(|t| {
                let [a, b, c] = mesh.triangle_positions(t);
                closest_on_triangle(p, a, b, c).0.distance_squared(p)
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn triangle_regions() {
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        let cases = [
            (DVec3::new(0.25, 0.25, 1.0), DVec3::new(0.25, 0.25, 0.0)),
            (DVec3::new(-1.0, -1.0, 0.0), a),
            (DVec3::new(2.0, -0.5, 0.0), b),
            (DVec3::new(-0.1, 3.0, 0.0), c),
            (DVec3::new(0.5, -1.0, 0.0), DVec3::new(0.5, 0.0, 0.0)),
            (DVec3::new(-1.0, 0.5, 0.0), DVec3::new(0.0, 0.5, 0.0)),
            (DVec3::new(1.0, 1.0, 0.0), DVec3::new(0.5, 0.5, 0.0)),
        ];
        for (p, want) in cases {
            let (got, bary) = closest_on_triangle(p, a, b, c);
            assert!((got - want).length() < 1e-15, "{p}: {got} vs {want}");
            assert!((bary.element_sum() - 1.0).abs() < 1e-15);
            let back = a * bary.x + b * bary.y + c * bary.z;
            assert!((back - got).length() < 1e-15);
        }
        // Degenerate triangles still give a point on them.
        let (got, _) = closest_on_triangle(DVec3::new(0.5, 1.0, 0.0), a, b, b);
        assert!((got - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-15);
    }

    #[test]
    fn matches_brute_force() {
        for mesh in [uv_sphere(1.0, 12, 20), grid(7, 5)] {
            let all: Vec<u32> = (0..mesh.triangles.len() as u32).collect();
            let bvh = TriangleBvh::new(&mesh, all);
            let mut r = rng(11);
            for _ in 0..2000 {
                let p = DVec3::new(r.random(), r.random(), r.random()) * 8.0 - 2.0;
                let hit = bvh.closest(p, None).unwrap();
                assert_eq!(hit.distance_squared, brute_force(&mesh, p), "{p}");
                // A start candidate never changes the distance found.
                let start = bvh.hit_on(p, (hit.triangle + 7) % mesh.triangles.len() as u32);
                let hinted = bvh.closest(p, Some(start)).unwrap();
                assert_eq!(hinted.distance_squared, hit.distance_squared);
            }
        }
    }

    #[test]
    fn boxes_are_conservative_in_f64() {
        // Coordinates that f32 cannot hold exactly.
        let mut mesh = grid(3, 3);
        for p in &mut mesh.positions {
            *p = *p * 0.1 + DVec3::splat(1e3 + 1.0 / 3.0);
        }
        let all: Vec<u32> = (0..mesh.triangles.len() as u32).collect();
        let bvh = TriangleBvh::new(&mesh, all);
        for n in &bvh.nodes {
            let leaf = n.count > 0;
            if leaf {
                for i in n.first..n.first + n.count {
                    for v in bvh.corners[i as usize] {
                        let p = mesh.positions[v as usize].to_array();
                        for ((lo, hi), x) in n.min.iter().zip(n.max).zip(p) {
                            assert!(*lo as f64 <= x && x <= hi as f64);
                        }
                    }
                }
            }
        }
        assert!(bvh.closest(DVec3::ZERO, None).is_some());
        let empty = TriangleBvh::new(&mesh, Vec::new());
        assert!(empty.is_empty() && empty.closest(DVec3::ZERO, None).is_none());
    }
}
