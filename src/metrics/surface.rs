//! What every two-mesh metric needs: seeded area-uniform samples on a surface, and exact
//! closest-point queries on the other surface through a BVH (parry3d-f64's `TriMesh`).

use super::MetricsError;
use crate::mesh::Mesh;
use glam::DVec3;
use parry3d_f64::math::Vector as PVector;
use parry3d_f64::query::PointQueryWithLocation;
use parry3d_f64::shape::TriMesh;
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;

/// The generator behind every seeded metric: a fixed algorithm, so that the same seed gives
/// the same samples on every platform and version of its crate.
pub type MetricsRng = rand_pcg::Pcg64Mcg;

pub fn rng(seed: u64) -> MetricsRng {
    MetricsRng::seed_from_u64(seed)
}

/// A point on a mesh's surface: its triangle, barycentric coordinates and position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    pub triangle: u32,
    /// Weights of the triangle's corners 0, 1, 2 (non-negative, summing to 1).
    pub bary: DVec3,
    pub point: DVec3,
}

/// Refuses what the metrics cannot measure: no triangles, or non-finite positions (a bug in
/// a step, but the report must say so rather than panic).
pub fn check_measurable(mesh: &Mesh, which: &'static str) -> Result<(), MetricsError> {
    if mesh.triangles.is_empty() {
        return Err(MetricsError::Empty { which });
    }
    if let Some(vertex) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(MetricsError::NonFinite { which, vertex });
    }
    Ok(())
}

/// `n` points spread uniformly by area over the surface (each triangle gets samples in
/// proportion to its area), drawn in a fixed order from a generator seeded with `seed`.
pub fn sample_surface(mesh: &Mesh, n: usize, seed: u64) -> Vec<SurfacePoint> {
    let mut cumulative = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0;
    for t in 0..mesh.triangles.len() {
        total += mesh.triangle_area(t);
        cumulative.push(total);
    }
    if total <= 0.0 || n == 0 {
        return Vec::new();
    }
    let mut rng = rng(seed);
    (0..n)
        .map(|_| {
            let target = rng.random::<f64>() * total;
            // First triangle whose running area passes the target; zero-area triangles
            // never are (their running area equals their predecessor's).
            let t = cumulative
                .partition_point(|&c| c <= target)
                .min(cumulative.len() - 1);
            let (mut u, mut v): (f64, f64) = (rng.random(), rng.random());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let bary = DVec3::new(1.0 - u - v, u, v);
            SurfacePoint {
                triangle: t as u32,
                bary,
                point: interpolate_position(mesh, t, bary),
            }
        })
        .collect()
}

pub fn interpolate_position(mesh: &Mesh, t: usize, bary: DVec3) -> DVec3 {
    let [a, b, c] = mesh.triangle_positions(t);
    a * bary.x + b * bary.y + c * bary.z
}

/// Barycentric coordinates of `p` (assumed in the triangle's plane) in triangle `a b c`,
/// clamped to the triangle. Computed here rather than taken from the BVH crate so that the
/// corner order is ours beyond doubt.
pub fn barycentric(p: DVec3, [a, b, c]: [DVec3; 3]) -> DVec3 {
    let (v0, v1, v2) = (b - a, c - a, p - a);
    let (d00, d01, d11) = (v0.dot(v0), v0.dot(v1), v1.dot(v1));
    let (d20, d21) = (v2.dot(v0), v2.dot(v1));
    let denom = d00 * d11 - d01 * d01;
    if denom.abs() <= f64::MIN_POSITIVE {
        return DVec3::new(1.0, 0.0, 0.0);
    }
    let v = (d11 * d20 - d01 * d21) / denom;
    let w = (d00 * d21 - d01 * d20) / denom;
    let bary = DVec3::new(1.0 - v - w, v, w).max(DVec3::ZERO);
    let sum = bary.x + bary.y + bary.z;
    if sum > 0.0 {
        bary / sum
    } else {
        DVec3::new(1.0, 0.0, 0.0)
    }
}

/// The closest point on a surface to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closest {
    pub on: SurfacePoint,
    pub distance: f64,
}

/// A BVH over a mesh's triangles for exact closest-point queries. Zero-area triangles are
/// left out: they add no surface, and the projection onto them is ill-defined.
pub struct SurfaceIndex<'a> {
    mesh: &'a Mesh,
    trimesh: TriMesh,
    /// Mesh triangle of each BVH triangle.
    triangles: Vec<u32>,
}

fn to_parry(p: DVec3) -> PVector {
    PVector::new(p.x, p.y, p.z)
}

impl<'a> SurfaceIndex<'a> {
    pub fn new(mesh: &'a Mesh, which: &'static str) -> Result<Self, MetricsError> {
        check_measurable(mesh, which)?;
        let mut triangles = Vec::with_capacity(mesh.triangles.len());
        let mut indices = Vec::with_capacity(mesh.triangles.len());
        for t in 0..mesh.triangles.len() {
            if mesh.triangle_cross(t).length_squared() > 0.0 {
                triangles.push(t as u32);
                indices.push(mesh.triangle_vertices(t));
            }
        }
        if indices.is_empty() {
            return Err(MetricsError::Empty { which });
        }
        let vertices = mesh.positions.iter().map(|&p| to_parry(p)).collect();
        let trimesh = TriMesh::new(vertices, indices).map_err(|e| MetricsError::Index {
            which,
            message: e.to_string(),
        })?;
        Ok(SurfaceIndex {
            mesh,
            trimesh,
            triangles,
        })
    }

    pub fn mesh(&self) -> &'a Mesh {
        self.mesh
    }

    /// The exact closest point of the surface to `p`.
    pub fn closest(&self, p: DVec3) -> Closest {
        let (projection, (part, _)) = self
            .trimesh
            .project_local_point_and_get_location(to_parry(p), false);
        let point = DVec3::new(projection.point.x, projection.point.y, projection.point.z);
        // `part` is always in range for a finite query on a non-empty mesh (both checked);
        // fall back to the first triangle rather than panic should that ever change.
        let triangle = self
            .triangles
            .get(part as usize)
            .copied()
            .unwrap_or(self.triangles[0]);
        let bary = barycentric(point, self.mesh.triangle_positions(triangle as usize));
        Closest {
            on: SurfacePoint {
                triangle,
                bary,
                point,
            },
            distance: point.distance(p),
        }
    }

    /// Closest points for many query points, in parallel, in the order given.
    pub fn closest_all(&self, points: &[DVec3]) -> Vec<Closest> {
        points.par_iter().map(|&p| self.closest(p)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::{grid, uv_sphere};

    #[test]
    fn samples_are_seeded_on_surface_and_area_uniform() {
        let m = grid(4, 2);
        let a = sample_surface(&m, 4000, 7);
        assert_eq!(a, sample_surface(&m, 4000, 7));
        assert_ne!(a, sample_surface(&m, 4000, 8));
        // Uniform over [0,4]x[0,2]: about a quarter of the points have x < 1.
        let left = a.iter().filter(|s| s.point.x < 1.0).count() as f64 / a.len() as f64;
        assert!((left - 0.25).abs() < 0.03, "{left}");
        for s in &a {
            assert_eq!(s.point.z, 0.0);
            assert!((s.bary.element_sum() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn closest_point_is_exact() {
        let m = uv_sphere(1.0, 16, 24);
        let index = SurfaceIndex::new(&m, "reference").unwrap();
        let c = index.closest(DVec3::new(0.0, 0.0, 5.0));
        assert!((c.on.point - DVec3::new(0.0, 0.0, 1.0)).length() < 1e-12);
        assert!((c.distance - 4.0).abs() < 1e-12);
        let g = grid(3, 3);
        let index = SurfaceIndex::new(&g, "reference").unwrap();
        let c = index.closest(DVec3::new(1.25, 2.5, -0.5));
        assert!((c.on.point - DVec3::new(1.25, 2.5, 0.0)).length() < 1e-12);
        let back = interpolate_position(&g, c.on.triangle as usize, c.on.bary);
        assert!((back - c.on.point).length() < 1e-12);
    }
}
