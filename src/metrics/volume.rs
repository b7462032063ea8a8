//! Enclosed volume (the volume criterion of the smoothing thesis (Svěchovský, *Vyhlazování polygonálních modelů*, FIT VUT Brno 2010,
//! §4.2.4): the divergence-theorem sum
//! V = 1/6 Σ a·(b×c), equal to the thesis' prism-against-a-plane construction for a closed,
//! consistently oriented surface. For anything else the number means nothing, so, as the
//! thesis prints "–", we report "not closed" with the reason.

use crate::mesh::{Mesh, TopologyCounts};
use serde::Serialize;

/// A mesh's volume, or why it has none.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "status", rename_all = "kebab-case")]
pub enum Volume {
    /// Signed: positive for outward-facing triangles.
    Closed { volume: f64 },
    NotClosed {
        /// Edges with one triangle.
        boundary_edges: usize,
        /// Edges with more than two triangles.
        non_manifold_edges: usize,
        /// Edges whose two triangles run along them in the same direction.
        inconsistent_edges: usize,
    },
}

impl Volume {
    pub fn value(&self) -> Option<f64> {
        match self {
            Volume::Closed { volume } => Some(*volume),
            Volume::NotClosed { .. } => None,
        }
    }
}

/// Volume of result and reference and the change in percent of the reference's volume.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct VolumeChange {
    pub result: Volume,
    pub reference: Volume,
    /// 100 · (V_result − V_reference) / |V_reference|; `None` unless both are closed and the
    /// reference's volume is not zero.
    pub change_percent: Option<f64>,
}

/// Counts boundary, non-manifold and inconsistently oriented edges by sorting the directed
/// edges (vertex indices, so texture seams do not count as boundaries).
fn edge_defects(mesh: &Mesh) -> (usize, usize, usize) {
    let mut edges: Vec<(u32, u32, bool)> = Vec::with_capacity(3 * mesh.triangles.len());
    for t in 0..mesh.triangles.len() {
        let v = mesh.triangle_vertices(t);
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            edges.push((a.min(b), a.max(b), a < b));
        }
    }
    edges.sort_unstable();
    let (mut boundary, mut non_manifold, mut inconsistent) = (0, 0, 0);
    for group in edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        match group.len() {
            1 => boundary += 1,
            2 if group[0].2 == group[1].2 => inconsistent += 1,
            2 => {}
            _ => non_manifold += 1,
        }
    }
    (boundary, non_manifold, inconsistent)
}

/// The signed volume if the mesh is closed and consistently oriented.
pub fn volume(mesh: &Mesh) -> Volume {
    let (boundary_edges, non_manifold_edges, inconsistent_edges) = edge_defects(mesh);
    volume_given_defects(mesh, boundary_edges, non_manifold_edges, inconsistent_edges)
}

/// [`volume`] with the edge counts a [`TopologyCounts`] already has (same definitions).
pub fn volume_from_counts(mesh: &Mesh, counts: &TopologyCounts) -> Volume {
    volume_given_defects(
        mesh,
        counts.boundary_edges,
        counts.non_manifold_edges,
        counts.inconsistent_edges,
    )
}

fn volume_given_defects(
    mesh: &Mesh,
    boundary_edges: usize,
    non_manifold_edges: usize,
    inconsistent_edges: usize,
) -> Volume {
    if mesh.triangles.is_empty() || boundary_edges + non_manifold_edges + inconsistent_edges > 0 {
        return Volume::NotClosed {
            boundary_edges,
            non_manifold_edges,
            inconsistent_edges,
        };
    }
    // Relative to the bounding-box centre, so that far-from-origin scans do not lose digits.
    let centre = mesh
        .bounding_box()
        .map(|(lo, hi)| (lo + hi) * 0.5)
        .unwrap_or_default();
    let sum: f64 = (0..mesh.triangles.len())
        .map(|t| {
            let [a, b, c] = mesh.triangle_positions(t).map(|p| p - centre);
            a.dot(b.cross(c))
        })
        .sum();
    Volume::Closed { volume: sum / 6.0 }
}

pub fn compare(result: &Mesh, reference: &Mesh) -> VolumeChange {
    change(volume(result), volume(reference))
}

/// The change from `reference` to `result`.
pub fn change(result: Volume, reference: Volume) -> VolumeChange {
    let change_percent = match (result.value(), reference.value()) {
        (Some(r), Some(v)) if v != 0.0 => Some(100.0 * (r - v) / v.abs()),
        _ => None,
    };
    VolumeChange {
        result,
        reference,
        change_percent,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::{cube, grid, uv_sphere};
    use glam::DVec3;

    #[test]
    fn unit_cube_volume() {
        let mut m = cube(); // [-1,1]^3
        for p in &mut m.positions {
            *p = *p * 0.5 + DVec3::splat(1000.5); // unit cube far from the origin
        }
        let v = volume(&m).value().unwrap();
        assert!((v - 1.0).abs() < 1e-12, "{v}");
    }

    #[test]
    fn sphere_and_scaled_copy() {
        let m = uv_sphere(1.0, 48, 96);
        let v = volume(&m).value().unwrap();
        // A polyhedron inscribed in the unit sphere: a little under 4π/3.
        let exact = 4.0 / 3.0 * std::f64::consts::PI;
        assert!(v < exact && v > 0.99 * exact, "{v}");
        let mut big = m.clone();
        for p in &mut big.positions {
            *p *= 1.1;
        }
        let change = compare(&big, &m).change_percent.unwrap();
        assert!(
            (change - (1.1f64.powi(3) - 1.0) * 100.0).abs() < 1e-9,
            "{change}"
        );
    }

    #[test]
    fn open_or_flipped_is_not_closed() {
        assert!(matches!(
            volume(&grid(2, 2)),
            Volume::NotClosed {
                boundary_edges: 8,
                ..
            }
        ));
        let mut m = cube();
        m.triangles[0].swap(1, 2);
        assert!(matches!(
            volume(&m),
            Volume::NotClosed {
                inconsistent_edges: 3,
                boundary_edges: 0,
                ..
            }
        ));
        let mut inside_out = cube();
        for t in &mut inside_out.triangles {
            t.swap(1, 2);
        }
        assert!((volume(&inside_out).value().unwrap() + 8.0).abs() < 1e-12);
        assert_eq!(compare(&grid(1, 1), &cube()).change_percent, None);
    }
}
