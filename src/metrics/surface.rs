//! What every two-mesh metric needs: seeded area-uniform samples on a surface, and exact
//! closest-point queries on the other surface through a BVH (`crate::geom::bvh::TriangleBvh`).

use super::MetricsError;
use crate::geom::bvh::{Search, TriangleBvh, TriangleHit};
use crate::mesh::Mesh;
use glam::DVec3;
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
    // Draw every sample first, then visit them in surface order (ascending running area,
    // so ascending triangle index): the same set of samples as drawing them one by one, but
    // neighbouring samples then lie on neighbouring triangles, and the closest-point queries
    // that follow touch memory in order instead of at random (surface distance with 100k
    // samples each way on a 400k-triangle scan: 1.15 → 0.53 CPU seconds, benches/metrics.rs).
    let mut rng = rng(seed);
    let mut draws: Vec<(f64, f64, f64)> = (0..n)
        .map(|_| (rng.random::<f64>() * total, rng.random(), rng.random()))
        .collect();
    draws.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut t = 0;
    draws
        .into_iter()
        .map(|(target, mut u, mut v)| {
            // First triangle whose running area passes the target; zero-area triangles
            // never are (their running area equals their predecessor's).
            while t + 1 < cumulative.len() && cumulative[t] <= target {
                t += 1;
            }
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

/// The closest point on a surface to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closest {
    pub on: SurfacePoint,
    pub distance: f64,
    /// Whether the search proved this the closest point; `false` when it stopped at its
    /// budget (overlapping triangles, [`crate::geom::bvh::TriangleBvh::search`]): `distance` is
    /// then an upper bound.
    pub exact: bool,
}

/// An index over a mesh's triangles for exact closest-point queries ([`crate::geom::bvh`]).
/// Zero-area triangles are left out: they add no surface, and the projection onto them is
/// ill-defined.
pub struct SurfaceIndex<'a> {
    mesh: &'a Mesh,
    bvh: TriangleBvh<'a>,
}

impl<'a> SurfaceIndex<'a> {
    pub fn new(mesh: &'a Mesh, which: &'static str) -> Result<Self, MetricsError> {
        check_measurable(mesh, which)?;
        let triangles: Vec<u32> = (0..mesh.triangles.len())
            .filter(|&t| mesh.triangle_cross(t).length_squared() > 0.0)
            .map(|t| t as u32)
            .collect();
        if triangles.is_empty() {
            return Err(MetricsError::Empty { which });
        }
        Ok(SurfaceIndex {
            mesh,
            bvh: TriangleBvh::new(mesh, triangles),
        })
    }

    pub fn mesh(&self) -> &'a Mesh {
        self.mesh
    }

    /// The closest-point tree, when it holds every triangle of the mesh (none has zero
    /// area), so that it answers as a tree over the whole mesh does (the texture follow's).
    pub fn whole_mesh_tree(&self) -> Option<&TriangleBvh<'a>> {
        (self.bvh.len() == self.mesh.triangles.len()).then_some(&self.bvh)
    }

    /// The exact closest point of the surface to `p`.
    pub fn closest(&self, p: DVec3) -> Closest {
        self.to_closest(p, self.bvh.search(p, None))
    }

    /// Of the triangles as near to `p` as `closest` (which must be `p`'s closest point),
    /// the one whose normal is nearest to `normal`: at a crease or a fold, where the
    /// closest point lies on an edge or a corner, several are ([`TriangleBvh::facing`]).
    pub fn facing(&self, p: DVec3, closest: &Closest, normal: DVec3) -> usize {
        let hit = TriangleHit {
            triangle: closest.on.triangle,
            point: closest.on.point,
            bary: closest.on.bary,
            distance_squared: closest.distance * closest.distance,
        };
        self.bvh.facing(p, &hit, normal) as usize
    }

    /// The exact closest point of the surface to `p`, knowing that triangle `near` of the
    /// mesh is close: its distance bounds the search from the start, which prunes most of
    /// the tree (the answer is the same, only found faster).
    pub fn closest_near(&self, p: DVec3, near: usize) -> Closest {
        if near >= self.mesh.triangles.len() {
            return self.closest(p);
        }
        let start = self.bvh.hit_on(p, near as u32);
        self.to_closest(p, self.bvh.search(p, Some(start)))
    }

    fn to_closest(&self, p: DVec3, search: Search) -> Closest {
        // The index is never empty (checked in `new`); the fallback only avoids a panic.
        let hit = search.hit.unwrap_or_else(|| self.bvh.hit_on(p, 0));
        Closest {
            on: SurfacePoint {
                triangle: hit.triangle,
                bary: hit.bary,
                point: hit.point,
            },
            distance: hit.distance_squared.sqrt(),
            exact: search.complete,
        }
    }

    /// Closest points for many query points, in parallel, in the order given.
    pub fn closest_all(&self, points: &[DVec3]) -> Vec<Closest> {
        points.par_iter().map(|&p| self.closest(p)).collect()
    }

    /// Closest points of samples on another mesh, in parallel, in the order given;
    /// `counterparts[t]` (if any) is a triangle of this mesh near the other's triangle `t`.
    pub fn closest_to_samples(
        &self,
        samples: &[SurfacePoint],
        counterparts: Option<&[u32]>,
    ) -> Vec<Closest> {
        samples
            .par_iter()
            .map(
                |s| match counterparts.and_then(|c| c.get(s.triangle as usize)) {
                    Some(&near) if near != u32::MAX => self.closest_near(s.point, near as usize),
                    _ => self.closest(s.point),
                },
            )
            .collect()
    }
}

/// For each triangle of `from`, a triangle of `to` that is likely near it (`u32::MAX` for
/// none): the same triangle when the connectivity is the same (smoothing), else the `to`
/// triangle descending from the same input triangle (`triangle_origins`; crop, decimation).
/// Only a hint for [`SurfaceIndex::closest_near`]: a wrong one costs time, never accuracy.
pub fn counterparts(from: &Mesh, to: &Mesh) -> Option<Vec<u32>> {
    if super::same_connectivity(from, to) {
        return Some((0..from.triangles.len() as u32).collect());
    }
    if from.triangle_origins.is_empty() && to.triangle_origins.is_empty() {
        return None; // unrelated meshes, as far as we can tell
    }
    let size = (0..to.triangles.len())
        .map(|t| to.triangle_origin(t) as usize + 1)
        .max()
        .unwrap_or(0);
    let mut by_origin = vec![u32::MAX; size];
    for t in (0..to.triangles.len()).rev() {
        by_origin[to.triangle_origin(t) as usize] = t as u32;
    }
    Some(
        (0..from.triangles.len())
            .map(|t| {
                by_origin
                    .get(from.triangle_origin(t) as usize)
                    .copied()
                    .unwrap_or(u32::MAX)
            })
            .collect(),
    )
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

    #[test]
    fn a_hint_changes_speed_not_answers() {
        let m = uv_sphere(1.0, 24, 32);
        let index = SurfaceIndex::new(&m, "reference").unwrap();
        let mut rng = rng(3);
        for i in 0..500 {
            let p = DVec3::new(rng.random(), rng.random(), rng.random()) * 3.0 - 1.5;
            let exact = index.closest(p);
            // Good, poor and out-of-range hints.
            for near in [
                exact.on.triangle as usize,
                (i * 37) % m.triangles.len(),
                usize::MAX,
            ] {
                let hinted = index.closest_near(p, near);
                assert!(
                    (hinted.distance - exact.distance).abs() < 1e-12,
                    "{p} {near}"
                );
            }
        }
        let mut cropped = m.clone();
        cropped.triangles.drain(0..10);
        cropped.triangle_origins = (10..m.triangles.len() as u32).collect();
        let c = counterparts(&cropped, &m).unwrap();
        assert_eq!((c[0], c[5]), (10, 15));
        let back = counterparts(&m, &cropped).unwrap();
        assert_eq!((back[0], back[10]), (u32::MAX, 0));
        assert!(counterparts(&grid(2, 2), &m).is_none());
    }
}
