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

use crate::mesh::{Mesh, Topology, TopologyCounts, summary};
use glam::DVec3;
use parry3d_f64::math::Vector as PVector;
use parry3d_f64::query::PointQuery;
use parry3d_f64::shape::Polyline;
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
    /// The reference's boundary edges as a polyline (`None`: a closed reference).
    boundary: Option<Polyline>,
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
        let segments = boundary_segments(reference, topology);
        let boundary = (!segments.is_empty()).then(|| {
            let vertices: Vec<PVector> = segments
                .iter()
                .flatten()
                .map(|p| PVector::new(p.x, p.y, p.z))
                .collect();
            let indices: Vec<[u32; 2]> = (0..segments.len() as u32)
                .map(|i| [2 * i, 2 * i + 1])
                .collect();
            Polyline::new(vertices, Some(indices))
        });
        ReferenceTopology {
            snapshot,
            boundary,
            crack_distance: crack_distance_factor * reference.mean_edge_length(),
        }
    }
}

/// Counts result boundary edges farther than the crack distance from every reference
/// boundary edge.
fn count_cracks(result_boundary: &[[DVec3; 2]], reference: &ReferenceTopology) -> usize {
    let Some(polyline) = &reference.boundary else {
        return result_boundary.len();
    };
    result_boundary
        .par_iter()
        .filter(|[a, b]| {
            let m = (*a + *b) * 0.5;
            polyline.distance_to_local_point(PVector::new(m.x, m.y, m.z), true)
                > reference.crack_distance
        })
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
