//! Surface distance in the manner of Metro / MeshLab's Hausdorff filter
//! (as the decimation thesis measures its results): area-uniform seeded samples on one surface, the exact
//! closest point on the other, both directions. The thesis reports the one-sided
//! decimated → original figures; we give both sides and the symmetric (pooled) figures,
//! whose maximum is the Hausdorff distance.
//!
//! Also the smoothing thesis' per-vertex "distance deviation" (Svěchovský 2010, §4.2.4) for meshes with unchanged connectivity: the offset of each vertex along the
//! reference's outward vertex normal.

use super::surface::{Closest, SurfaceIndex, SurfacePoint, sample_surface};
use super::{MetricsError, Summary, same_connectivity};
use crate::mesh::Mesh;
use glam::DVec3;
use serde::Serialize;

/// One direction: samples on the `from` surface, distances to the other.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct OneSided {
    pub samples: usize,
    pub mean: f64,
    pub rms: f64,
    pub max: f64,
    /// Samples whose closest-point search stopped at its budget (triangles overlapping so
    /// that no box separates them, [`crate::geom::bvh::TriangleBvh::search`]): their distances
    /// are upper bounds. Left out of the report when there are none.
    #[serde(skip_serializing_if = "is_zero")]
    pub inexact: usize,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// Surface distance between result and reference, in model units and as fractions of the
/// reference's bounding-box diagonal (`*_relative`; multiply by 100 for percent).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SurfaceDistance {
    /// Both directions pooled (same sample count each way); `max` is the Hausdorff distance.
    pub mean: f64,
    pub rms: f64,
    pub max: f64,
    pub mean_relative: f64,
    pub rms_relative: f64,
    pub max_relative: f64,
    pub bbox_diagonal: f64,
    /// Samples on the result, distance to the reference (the thesis' and MeshLab's figure).
    pub result_to_reference: OneSided,
    /// Samples on the reference, distance to the result (finds holes the result opened).
    pub reference_to_result: OneSided,
    pub seed: u64,
}

fn one_sided(closest: &[Closest]) -> OneSided {
    let d: Vec<f64> = closest.iter().map(|c| c.distance).collect();
    let s = Summary::of(&d);
    OneSided {
        samples: s.count,
        mean: s.mean,
        rms: s.rms,
        max: s.max,
        inexact: closest.iter().filter(|c| !c.exact).count(),
    }
}

/// Combines the queries of both directions (already made) into the figures.
pub fn from_queries(
    result_to_reference: &[Closest],
    reference_to_result: &[Closest],
    reference: &Mesh,
    seed: u64,
) -> SurfaceDistance {
    let (a, b) = (
        one_sided(result_to_reference),
        one_sided(reference_to_result),
    );
    let n = (a.samples + b.samples).max(1) as f64;
    let mean = (a.mean * a.samples as f64 + b.mean * b.samples as f64) / n;
    let rms = ((a.rms * a.rms * a.samples as f64 + b.rms * b.rms * b.samples as f64) / n).sqrt();
    let max = a.max.max(b.max);
    let bbox_diagonal = reference.bounding_box_diagonal();
    let rel = |x: f64| {
        if bbox_diagonal > 0.0 {
            x / bbox_diagonal
        } else {
            0.0
        }
    };
    SurfaceDistance {
        mean,
        rms,
        max,
        mean_relative: rel(mean),
        rms_relative: rel(rms),
        max_relative: rel(max),
        bbox_diagonal,
        result_to_reference: a,
        reference_to_result: b,
        seed,
    }
}

/// The seed of the reference's samples, derived from the result's so that one seed fixes both.
pub fn reference_seed(seed: u64) -> u64 {
    seed ^ 0x9e37_79b9_7f4a_7c15
}

pub fn positions(samples: &[SurfacePoint]) -> Vec<DVec3> {
    samples.iter().map(|s| s.point).collect()
}

/// Surface distance with `samples` points on each surface; builds both BVHs.
pub fn surface_distance(
    result: &Mesh,
    reference: &Mesh,
    samples: usize,
    seed: u64,
) -> Result<SurfaceDistance, MetricsError> {
    let (reference_index, result_index) = rayon::join(
        || SurfaceIndex::new(reference, "reference"),
        || SurfaceIndex::new(result, "result"),
    );
    let (reference_index, result_index) = (reference_index?, result_index?);
    let on_result = sample_surface(result, samples, seed);
    let on_reference = sample_surface(reference, samples, reference_seed(seed));
    let forward = reference_index.closest_to_samples(
        &on_result,
        super::surface::counterparts(result, reference).as_deref(),
    );
    let backward = result_index.closest_to_samples(
        &on_reference,
        super::surface::counterparts(reference, result).as_deref(),
    );
    Ok(from_queries(&forward, &backward, reference, seed))
}

/// The distance of every vertex of `mesh` to the surface of `reference` (exact closest
/// point), in vertex order: the preview colours a result with it. A triangle of the
/// reference that descends from the same input triangle as one around the vertex, when
/// known, speeds up the search without changing the answer.
pub fn vertex_distances(mesh: &Mesh, reference: &Mesh) -> Result<Vec<f64>, MetricsError> {
    super::surface::check_measurable(mesh, "result")?;
    let index = SurfaceIndex::new(reference, "reference")?;
    Ok(vertex_distances_with(mesh, &index))
}

/// [`vertex_distances`] with the reference's index already built.
pub fn vertex_distances_with(mesh: &Mesh, index: &SurfaceIndex<'_>) -> Vec<f64> {
    let reference = index.mesh();
    let near = super::surface::counterparts(mesh, reference).map(|by_triangle| {
        let mut near = vec![u32::MAX; mesh.positions.len()];
        for (t, &hint) in by_triangle.iter().enumerate() {
            for v in mesh.triangle_vertices(t) {
                if near[v as usize] == u32::MAX {
                    near[v as usize] = hint;
                }
            }
        }
        near
    });
    use rayon::prelude::*;
    mesh.positions
        .par_iter()
        .enumerate()
        .map(|(v, &p)| match near.as_ref().map(|n| n[v]) {
            Some(t) if t != u32::MAX => index.closest_near(p, t as usize).distance,
            _ => index.closest(p).distance,
        })
        .collect()
}

/// Area-weighted outward vertex normals (zero for vertices without area around them).
pub fn vertex_normals(mesh: &Mesh) -> Vec<DVec3> {
    let mut normals = vec![DVec3::ZERO; mesh.positions.len()];
    for t in 0..mesh.triangles.len() {
        let n = mesh.triangle_cross(t);
        for v in mesh.triangle_vertices(t) {
            normals[v as usize] += n;
        }
    }
    normals.iter().map(|n| n.normalize_or_zero()).collect()
}

/// The smoothing protocol's distance deviation: d_i = (p_i − p_i^ref) · n_i^ref.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct VertexDeviation {
    pub vertices: usize,
    /// Mean of the signed d_i (negative = moved inwards, i.e. shrinkage).
    pub signed_mean: f64,
    /// Mean of |d_i| (what the thesis' tables most likely list).
    pub abs_mean: f64,
    /// Sample standard deviation of the signed d_i.
    pub std: f64,
    pub max_abs: f64,
}

/// `None` unless result and reference have the same vertices and triangles (smoothing).
pub fn vertex_deviation(result: &Mesh, reference: &Mesh) -> Option<VertexDeviation> {
    if !same_connectivity(result, reference) {
        return None;
    }
    let normals = vertex_normals(reference);
    let signed: Vec<f64> = (0..reference.positions.len())
        .filter(|&i| normals[i] != DVec3::ZERO)
        .map(|i| (result.positions[i] - reference.positions[i]).dot(normals[i]))
        .collect();
    let abs: Vec<f64> = signed.iter().map(|d| d.abs()).collect();
    let (s, a) = (Summary::of(&signed), Summary::of(&abs));
    Some(VertexDeviation {
        vertices: s.count,
        signed_mean: s.mean,
        abs_mean: a.mean,
        std: s.std,
        max_abs: a.max,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::{grid, uv_sphere};

    #[test]
    fn parallel_planes_at_distance_d() {
        let reference = grid(10, 10);
        let mut result = reference.clone();
        // Shrink the result a little so that its border stays inside the reference's: every
        // closest point is then straight below.
        for p in &mut result.positions {
            *p = DVec3::new(0.5 + p.x * 0.9, 0.5 + p.y * 0.9, 0.25);
        }
        let d = surface_distance(&result, &reference, 5000, 3).unwrap();
        let r = d.result_to_reference;
        assert!(
            (r.mean - 0.25).abs() < 1e-12 && (r.max - 0.25).abs() < 1e-12,
            "{r:?}"
        );
        assert!((r.rms - 0.25).abs() < 1e-12);
        // The other way, samples outside the shrunken square are farther: never closer.
        assert!(d.reference_to_result.mean > 0.25 && d.max >= 0.25);
        let diag = (200.0f64).sqrt();
        assert!((d.bbox_diagonal - diag).abs() < 1e-12);
        assert!((d.result_to_reference.max / diag - 0.25 / diag).abs() < 1e-15);
    }

    #[test]
    fn sphere_against_scaled_copy() {
        let reference = uv_sphere(1.0, 64, 128);
        let mut result = reference.clone();
        for p in &mut result.positions {
            *p *= 1.1;
        }
        let d = surface_distance(&result, &reference, 20_000, 1).unwrap();
        // Every point of the big sphere is 0.1 (up to the tessellation's sag) from the small.
        let sag = 1.0 - (std::f64::consts::PI / 64.0).cos();
        assert!((d.mean - 0.1).abs() < 2.0 * sag, "{d:?}");
        assert!((d.max - 0.1).abs() < 2.0 * sag, "{d:?}");
        assert!((d.result_to_reference.mean - 0.1).abs() < 2.0 * sag);
        let v = vertex_deviation(&result, &reference).unwrap();
        assert!((v.signed_mean - 0.1).abs() < 1e-3 && v.std < 1e-3, "{v:?}");
    }

    #[test]
    fn mesh_against_itself_is_zero_and_seeded() {
        let m = uv_sphere(2.0, 12, 16);
        let d = surface_distance(&m, &m, 3000, 9).unwrap();
        assert!(d.max < 1e-12, "{d:?}");
        assert_eq!(d, surface_distance(&m, &m, 3000, 9).unwrap());
        let v = vertex_deviation(&m, &m).unwrap();
        assert_eq!((v.abs_mean, v.max_abs), (0.0, 0.0));
        assert!(vertex_deviation(&grid(2, 2), &m).is_none());
    }

    #[test]
    fn vertex_distances_of_offset_plane() {
        let reference = grid(4, 4);
        let mut lifted = reference.clone();
        for p in &mut lifted.positions {
            p.z = 0.5;
        }
        let d = vertex_distances(&lifted, &reference).unwrap();
        assert_eq!(d.len(), lifted.positions.len());
        assert!(d.iter().all(|&x| (x - 0.5).abs() < 1e-12), "{d:?}");
        let itself = vertex_distances(&reference, &reference).unwrap();
        assert!(itself.iter().all(|&x| x == 0.0));
        assert!(vertex_distances(&Mesh::default(), &reference).is_err());
    }

    #[test]
    fn deterministic_across_thread_counts() {
        let a = uv_sphere(1.0, 20, 30);
        let mut b = a.clone();
        for (i, p) in b.positions.iter_mut().enumerate() {
            *p *= 1.0 + 0.01 * ((i * 7919) % 13) as f64;
        }
        let run = |threads| {
            crate::testing::on_threads(threads, || surface_distance(&b, &a, 4000, 5).unwrap())
        };
        let (one, two) = (run(1), run(2));
        assert_eq!(
            serde_json::to_string(&one).unwrap(),
            serde_json::to_string(&two).unwrap()
        );
    }
}
