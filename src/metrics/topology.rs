//! Topology before (reference) and after (result), and cracks.
//!
//! A *crack* is a boundary edge of the result with no boundary of the reference near it: a
//! hole a step opened (a seam that split, a collapse that tore the surface), as opposed to a
//! border the scan already had. "Near": the edge's midpoint lies within
//! `crack_distance_factor` × the reference's mean edge length of a reference boundary edge.
//! The factor defaults to 2: a decimated border edge spans many input edges and its midpoint
//! sits off the input's jagged border by about the sag of the chord, which on face scans is
//! well under two input edges; an opened seam or hole in the middle of the surface is
//! farther than that from any border.

use crate::geom::segment_distance;
use crate::mesh::{Mesh, Topology, TopologyCounts, summary};
use glam::DVec3;
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector as PVector;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy};
use rayon::prelude::*;
use serde::Serialize;

/// One mesh's topology counts plus its zero-area triangles.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TopologySnapshot {
    #[serde(flatten)]
    pub counts: TopologyCounts,
    pub degenerate_triangles: usize,
}

impl TopologySnapshot {
    pub fn of(mesh: &Mesh) -> (Self, Topology) {
        let topology = Topology::new(mesh);
        (Self::with(mesh, &topology), topology)
    }

    /// The snapshot of `mesh` from its topology, built already. Only the counts the
    /// snapshot keeps are taken (not a whole [`crate::mesh::MeshSummary`], whose
    /// duplicate-triangle count sorts every triangle).
    pub fn with(mesh: &Mesh, topology: &Topology) -> Self {
        TopologySnapshot {
            counts: topology.counts(),
            degenerate_triangles: summary::count_degenerate(mesh),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TopologyComparison {
    /// The reference (for the final metrics: the input).
    pub before: TopologySnapshot,
    /// The result.
    pub after: TopologySnapshot,
    /// Result boundary edges with no reference boundary within `crack_distance`.
    pub cracks: usize,
    /// The radius used, in model units.
    pub crack_distance: f64,
}

/// Midpoints of the boundary edges of a mesh.
fn boundary_segments(mesh: &Mesh, topology: &Topology) -> Vec<[DVec3; 2]> {
    topology
        .boundary_edges()
        .map(|e| {
            let [a, b] = topology.edge_vertices(e);
            [mesh.positions[a as usize], mesh.positions[b as usize]]
        })
        .collect()
}

/// The reference's half of [`compare`]: its counts and an index over its boundary edges;
/// its full topology is dropped as soon as these are taken.
pub struct ReferenceTopology {
    pub snapshot: TopologySnapshot,
    /// The reference's boundary edges (`None`: a closed reference).
    boundary: Option<BoundaryIndex>,
    /// Result boundary edges farther than this from `boundary` are cracks (model units).
    crack_distance: f64,
}

impl ReferenceTopology {
    pub fn of(reference: &Mesh, crack_distance_factor: f64) -> Self {
        Self::from_topology(reference, &Topology::new(reference), crack_distance_factor)
    }

    /// [`ReferenceTopology::of`] from the reference's topology, built already (the recipe
    /// runner takes it from the first fairing step, which builds it anyway).
    pub fn from_topology(
        reference: &Mesh,
        topology: &Topology,
        crack_distance_factor: f64,
    ) -> Self {
        let snapshot = TopologySnapshot::with(reference, topology);
        let mean_edge = reference.mean_edge_length();
        let crack_distance = crack_distance_factor * mean_edge;
        let segments = boundary_segments(reference, topology);
        let boundary = (!segments.is_empty())
            .then(|| BoundaryIndex::new(&segments, crack_distance.max(mean_edge)));
        ReferenceTopology {
            snapshot,
            boundary,
            crack_distance,
        }
    }

    /// Whether a reference boundary edge passes within the crack distance of `p`, and what
    /// it cost to tell.
    pub fn probe(&self, p: DVec3) -> Probe {
        match &self.boundary {
            Some(index) => index.probe(p, self.crack_distance),
            None => Probe::default(),
        }
    }
}

/// The answer of [`ReferenceTopology::probe`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Probe {
    /// A reference boundary edge lies within the crack distance.
    pub near: bool,
    /// Boundary pieces whose distance was measured.
    pub measured: u32,
}

/// The most pieces one boundary edge is cut into. Far above what the length bound below
/// asks of a mesh with finite coordinates; it only keeps a hostile edge from asking for more.
const MAX_PIECES_PER_EDGE: f64 = 4096.0;

/// Boundary edges cut into pieces no longer than a given length, indexed by their boxes.
///
/// The crack test asks whether *any* boundary edge lies within the crack distance, not which
/// is closest, so a search may stop at the first piece in range. Cutting long edges keeps
/// each box tight: on a soup of large overlapping triangles every uncut edge's box would hold
/// every query point, and each query would measure most of the edges. With pieces no longer
/// than the larger of the crack distance and the mean edge length, the pieces number at most
/// the boundary edges plus the mesh's total edge length over its mean edge length, about the
/// edge count: the index stays linear in the mesh.
struct BoundaryIndex {
    pieces: Vec<[DVec3; 2]>,
    bvh: Bvh,
}

impl BoundaryIndex {
    fn new(segments: &[[DVec3; 2]], piece_length: f64) -> Self {
        let pieces: Vec<[DVec3; 2]> = segments
            .iter()
            .flat_map(|&[a, b]| {
                let cuts = if piece_length > 0.0 {
                    (a.distance(b) / piece_length)
                        .ceil()
                        .clamp(1.0, MAX_PIECES_PER_EDGE) as usize
                } else {
                    1
                };
                (0..cuts).map(move |i| {
                    let at = |k: usize| a.lerp(b, k as f64 / cuts as f64);
                    [at(i), at(i + 1)]
                })
            })
            .collect();
        let boxes: Vec<Aabb> = pieces
            .iter()
            .map(|&[a, b]| Aabb::new(vector(a.min(b)), vector(a.max(b))))
            .collect();
        let bvh = Bvh::from_leaves(BvhBuildStrategy::Binned, &boxes);
        BoundaryIndex { pieces, bvh }
    }

    fn probe(&self, p: DVec3, radius: f64) -> Probe {
        let reach = Aabb::new(vector(p - radius), vector(p + radius));
        let mut measured = 0;
        let near = self.bvh.intersect_aabb(&reach).any(|leaf| {
            let [a, b] = self.pieces[leaf as usize];
            measured += 1;
            segment_distance(p, a, b) <= radius
        });
        Probe { near, measured }
    }
}

fn vector(p: DVec3) -> PVector {
    PVector::new(p.x, p.y, p.z)
}

/// Counts result boundary edges farther than the crack distance from every reference
/// boundary edge.
fn count_cracks(result_boundary: &[[DVec3; 2]], reference: &ReferenceTopology) -> usize {
    if reference.boundary.is_none() {
        return result_boundary.len();
    }
    result_boundary
        .par_iter()
        .filter(|[a, b]| !reference.probe((*a + *b) * 0.5).near)
        .count()
}

pub fn compare(result: &Mesh, reference: &Mesh, crack_distance_factor: f64) -> TopologyComparison {
    let (reference, (after, result_topology)) = rayon::join(
        || ReferenceTopology::of(reference, crack_distance_factor),
        || TopologySnapshot::of(result),
    );
    compared(result, &result_topology, after, &reference)
}

/// [`compare`] with the reference's half already made.
pub fn compare_with_reference(result: &Mesh, reference: &ReferenceTopology) -> TopologyComparison {
    let (after, result_topology) = TopologySnapshot::of(result);
    compared(result, &result_topology, after, reference)
}

fn compared(
    result: &Mesh,
    result_topology: &Topology,
    after: TopologySnapshot,
    reference: &ReferenceTopology,
) -> TopologyComparison {
    let cracks = count_cracks(&boundary_segments(result, result_topology), reference);
    TopologyComparison {
        before: reference.snapshot,
        after,
        cracks,
        crack_distance: reference.crack_distance,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::{grid, uv_sphere};

    /// The index's answer is the brute-force answer over the uncut edges, for points near,
    /// far and at the edge of the radius, with edges much longer than the radius.
    #[test]
    fn probe_agrees_with_brute_force() {
        let m = grid(12, 9);
        let topology = Topology::new(&m);
        let segments = boundary_segments(&m, &topology);
        for factor in [0.05, 0.7, 2.0, 5.0] {
            let reference = ReferenceTopology::from_topology(&m, &topology, factor);
            let r = reference.crack_distance;
            let mut lcg = crate::testing::Lcg(7);
            let mut unit = || lcg.unit();
            let (mut near, mut far) = (0, 0);
            for _ in 0..2000 {
                let p = DVec3::new(
                    unit() * (12.0 + 6.0 * r) - 3.0 * r,
                    unit() * (9.0 + 6.0 * r) - 3.0 * r,
                    (unit() - 0.5) * 3.0 * r,
                );
                let brute = segments
                    .iter()
                    .any(|&[a, b]| segment_distance(p, a, b) <= r);
                assert_eq!(reference.probe(p).near, brute, "factor {factor}, {p}");
                if brute { near += 1 } else { far += 1 }
            }
            assert!(
                near > 0 && far > 0,
                "factor {factor}: {near} near, {far} far"
            );
        }
    }

    #[test]
    fn same_mesh_has_no_cracks() {
        let m = grid(6, 6);
        let c = compare(&m, &m, 2.0);
        assert_eq!(c.cracks, 0);
        assert_eq!(c.before, c.after);
        assert_eq!(c.after.counts.boundary_edges, 24);
        assert_eq!(c.after.counts.boundary_loops, 1);
    }

    #[test]
    fn a_hole_in_the_middle_is_cracks_a_trimmed_border_is_not() {
        let m = grid(10, 10);
        // Remove the two triangles of the square (5,5): 4 new boundary edges, far from the
        // border.
        let mut holed = m.clone();
        let square = 2 * (5 * 10 + 5);
        holed.triangles.drain(square..square + 2);
        holed.compact();
        let c = compare(&holed, &m, 2.0);
        assert_eq!(c.cracks, 4);
        assert_eq!(c.after.counts.boundary_loops, 2);
        // Remove a triangle at the border instead: its new boundary edges are within one edge
        // of the old border.
        let mut trimmed = m.clone();
        trimmed.triangles.remove(0);
        trimmed.compact();
        assert_eq!(compare(&trimmed, &m, 2.0).cracks, 0);
        // A closed reference has no boundary: every result boundary edge is a crack.
        let s = uv_sphere(1.0, 8, 8);
        let mut opened = s.clone();
        opened.triangles.pop();
        assert_eq!(compare(&opened, &s, 2.0).cracks, 3);
    }
}
