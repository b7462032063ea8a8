//! The closest point of the input near a known triangle, by a walk over the input's
//! triangles: the search the projection, the fit and the export make from the input
//! triangle a vertex was last projected onto (`isotropic.rs`, `fit.rs`, `export.rs`).

use super::corners::NIL;
use crate::geom::bvh::TriangleBvh;
use crate::geom::closest::{Plane, closest_on_triangle};
use crate::mesh::Mesh;
use crate::mesh::topology::{NO_EDGE, Topology};
use glam::DVec3;
use rayon::prelude::*;

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

/// The input as the walks read it: every triangle's vertices and the triangle across each
/// of its sides in two flat tables, so that a step reads one record per neighbour instead
/// of going through the mesh's wedges and the topology's edge lists (the walks are the
/// remesher's most frequent search: about 370,000 closest-point tests a run on james),
/// 24 bytes per input triangle; and, when asked for, each triangle's plane, which rules
/// most neighbours out before their closest point is computed ([`Plane::farther_than`]),
/// 32 bytes more ([`Planes`]).
pub struct Sheet<'a> {
    pub mesh: &'a Mesh,
    pub topo: Topology,
    /// Each triangle's vertices (indices of the mesh's positions).
    vertices: Vec<[u32; 3]>,
    /// Across side `k` (from corner `k` to `k + 1`): the one other triangle of a manifold
    /// edge, [`NIL`] where there is none (a border), [`MANY`] where the edge has more than two
    /// triangles (read from the topology then).
    across: Vec<[u32; 3]>,
    /// Empty unless asked for.
    planes: Vec<Plane>,
}

/// Whether the walk's sheet and the remesher's search tree keep each input triangle's
/// plane. They pay where the input's triangles are about as large as the result's or
/// larger (james: 12,228 triangles remeshed into 18,955; the walks 49.9 → 48.7 ms, the
/// repair's tree searches 5.2 → 4.2 ms) and cost where the input is much denser (igea:
/// 269,000 into 24,800, 218 → 233 ms): there a walk crosses several small, nearly coplanar
/// triangles, whose planes rarely rule one out, and the tables take their making and
/// 64 bytes a triangle of cache room (docs/remeshing.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Planes {
    Kept,
    None,
}

impl Planes {
    /// [`Planes::Kept`] when the input has no more triangles than the result is expected to
    /// have faces.
    pub fn for_sizes(input_triangles: usize, expected_faces: f64) -> Planes {
        if input_triangles as f64 <= expected_faces {
            Planes::Kept
        } else {
            Planes::None
        }
    }
}

/// [`Sheet::across`] of a side whose edge has more than two triangles.
const MANY: u32 = NIL - 1;

impl<'a> Sheet<'a> {
    /// The sheet of `mesh` over its topology `topo`, its tables built beside `beside`,
    /// which reads the same topology (the rest of the remesher's set-up).
    pub fn new_beside<R: Send>(
        mesh: &'a Mesh,
        topo: Topology,
        planes: Planes,
        beside: impl FnOnce(&Topology) -> R + Send,
    ) -> (Self, R) {
        let ((vertices, across, planes), r) =
            rayon::join(|| Self::tables(mesh, &topo, planes), || beside(&topo));
        let sheet = Sheet {
            mesh,
            topo,
            vertices,
            across,
            planes,
        };
        (sheet, r)
    }

    /// [`Sheet::vertices`], [`Sheet::across`] and [`Sheet::planes`].
    fn tables(
        mesh: &Mesh,
        topo: &Topology,
        planes: Planes,
    ) -> (Vec<[u32; 3]>, Vec<[u32; 3]>, Vec<Plane>) {
        let n = mesh.triangles.len();
        let vertices = (0..n)
            .into_par_iter()
            .map(|t| mesh.triangle_vertices(t))
            .collect();
        let across = (0..n as u32)
            .into_par_iter()
            .map(|t| {
                topo.triangle_edges(t).map(|e| {
                    if e == NO_EDGE {
                        return NIL;
                    }
                    let mut others = topo.edge_triangles(e).filter(|&u| u != t);
                    match (others.next(), others.next()) {
                        (None, _) => NIL,
                        (Some(u), None) => u,
                        (Some(_), Some(_)) => MANY,
                    }
                })
            })
            .collect();
        let planes = match planes {
            Planes::Kept => (0..n)
                .into_par_iter()
                .map(|t| Plane::of(mesh.triangle_positions(t)))
                .collect(),
            Planes::None => Vec::new(),
        };
        (vertices, across, planes)
    }

    fn positions(&self, t: u32) -> [DVec3; 3] {
        self.vertices[t as usize].map(|v| self.mesh.positions[v as usize])
    }
}

/// The point closest to `q` found by walking from triangle `start` to the neighbour with a
/// closer point, among the triangles `within` admits, until none is closer. A neighbour
/// is a triangle across an edge, or, when the closest point is a corner of the current
/// triangle, any triangle around that corner (the closer point may be on a triangle that
/// shares only the corner). The walk finds a local minimum of the distance: the closest
/// point of the sheet of the input the search starts on, which is what a vertex that moved
/// by less than an edge wants where the input folds over itself, and it costs a few
/// closest-point tests where the tree search (`geom::bvh`) descends from the root.
pub fn walk(sheet: &Sheet, start: u32, q: DVec3, within: impl Fn(u32) -> bool) -> Foot {
    let on = |t: u32| {
        let [a, b, d] = sheet.positions(t);
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
            if u != t
                && u != from
                && within(u)
                && !sheet
                    .planes
                    .get(u as usize)
                    .is_some_and(|p| p.farther_than(q, next.0))
            {
                let (d, p, wu) = on(u);
                if d < next.0 {
                    *next = (d, u, p, wu);
                }
            }
        };
        // The same triangles in the same order as the topology's edge lists give them.
        for (k, &u) in sheet.across[t as usize].iter().enumerate() {
            match u {
                NIL => {}
                MANY => {
                    let e = sheet.topo.triangle_edges(t)[k];
                    sheet
                        .topo
                        .edge_triangles(e)
                        .for_each(|u| consider(u, &mut next));
                }
                u => consider(u, &mut next),
            }
        }
        if next.1 == NIL
            && let Some(k) = (0..3).find(|&k| w[k] >= 1.0)
        {
            let corner = sheet.vertices[t as usize][k];
            sheet
                .topo
                .vertex_triangles(corner)
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
    sheet: &Sheet,
    bvh: &TriangleBvh,
    start: u32,
    q: DVec3,
    within: impl Fn(u32) -> bool,
) -> Option<Foot> {
    settle(bvh, q, walk(sheet, start, q, within))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Wedge;
    use crate::mesh::shapes::grid;

    fn sheet_of(mesh: &Mesh) -> Sheet<'_> {
        Sheet::new_beside(mesh, Topology::new(mesh), Planes::Kept, |_| ()).0
    }

    /// The nearest triangle by testing every one, the first on a tie (as the walk keeps the
    /// one it has on a tie).
    fn nearest(mesh: &Mesh, q: DVec3) -> (u32, f64) {
        (0..mesh.triangles.len() as u32)
            .map(|t| {
                let [a, b, c] = mesh.triangle_positions(t as usize);
                (t, closest_on_triangle(q, a, b, c).0.distance_squared(q))
            })
            .fold(
                (NIL, f64::INFINITY),
                |best, x| if x.1 < best.1 { x } else { best },
            )
    }

    /// On a flat grid the walk from a far corner reaches the triangle under the query,
    /// with the point straight below it.
    #[test]
    fn walks_across_a_grid_to_the_triangle_below() {
        let mesh = grid(8, 8);
        let sheet = sheet_of(&mesh);
        let q = DVec3::new(6.3, 5.6, 0.25);
        let foot = walk(&sheet, 0, q, |_| true);
        assert!(foot.settled);
        assert_eq!(foot.triangle, nearest(&mesh, q).0);
        assert!((foot.point - DVec3::new(6.3, 5.6, 0.0)).length() < 1e-12);
        // A walk that may not leave the first column of squares stops at its edge.
        let foot = walk(&sheet, 0, q, |t| t % 16 < 2);
        assert!(foot.settled && foot.triangle % 16 < 2);
    }

    /// Three triangles on one edge: the tables mark the edge, and the walk reads the
    /// topology there and goes on to the third triangle, folded up over the first two.
    #[test]
    fn walks_over_an_edge_with_three_triangles() {
        let positions = vec![
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(0.5, -1.0, 0.0),
            DVec3::new(0.5, 1.0, 0.0),
            DVec3::new(0.5, 0.0, 1.0),
        ];
        let mesh = Mesh {
            wedges: (0..5)
                .map(|vertex| Wedge {
                    vertex,
                    texcoord: None,
                    normal: None,
                })
                .collect(),
            positions,
            triangles: vec![[1, 0, 2], [0, 1, 3], [0, 1, 4]],
            ..Mesh::default()
        };
        let sheet = sheet_of(&mesh);
        assert!(sheet.across[0].contains(&MANY));
        assert!(sheet.across[0].iter().filter(|&&u| u == NIL).count() == 2);
        let q = DVec3::new(0.5, 0.3, 0.6);
        let foot = walk(&sheet, 0, q, |_| true);
        assert!(foot.settled);
        assert_eq!(foot.triangle, 2);
        assert_eq!(foot.triangle, nearest(&mesh, q).0);
    }
}
