//! Angular deviation of face normals (the normal criterion of the smoothing thesis,
//! Svěchovský 2010, §4.2.4; with the decimation thesis' reading of "more than 90°" as a
//! flipped face).
//!
//! - Same connectivity (smoothing, fairing, normals): the angle between face f of the
//!   result and face f of the reference.
//! - Otherwise (crop, decimation): the angle between each result face's normal and the
//!   normal of the reference triangle closest to the face's centroid. Where that closest
//!   point lies on an edge or a corner shared by several triangles (a crease, a fold), the
//!   reference's normal there is any of theirs, and the face is measured against the one
//!   nearest its own ([`SurfaceIndex::facing`]): which of them a search happens to answer
//!   must not decide whether a face counts as flipped. A result face whose
//!   corners are exactly those of its counterpart (the reference triangle from the same
//!   input triangle, via `triangle_origins`: e.g. a face a crop kept) is that triangle: no
//!   query needed.
//!
//! Zero-area faces have no normal; they are counted, not measured.

use super::surface::{self, SurfaceIndex};
use super::{MetricsError, Summary, same_connectivity};
use crate::mesh::Mesh;
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Correspondence {
    /// Face f against face f.
    SameFaces,
    /// Each result face against the reference at its centroid's closest point.
    ClosestPoint,
}

/// Angles in radians.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AngularDeviation {
    pub correspondence: Correspondence,
    /// Faces measured.
    pub faces: usize,
    /// Zero-area faces (in the result, or their counterpart in the reference) left out.
    pub degenerate_faces: usize,
    pub mean: f64,
    pub rms: f64,
    /// Sample standard deviation (the thesis' s_x).
    pub std: f64,
    pub p99: f64,
    pub max: f64,
    /// Faces turned by more than 90°.
    pub flipped_faces: usize,
}

fn unit_normal(mesh: &Mesh, t: usize) -> Option<DVec3> {
    let n = mesh.triangle_cross(t).normalize_or_zero();
    (n != DVec3::ZERO).then_some(n)
}

/// atan2 rather than acos of the dot product: exact for identical normals and accurate for
/// small angles (acos loses half the digits near 1; clamping its argument is then moot).
fn angle(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

fn summarise(angles: &[Option<f64>], correspondence: Correspondence) -> AngularDeviation {
    let measured: Vec<f64> = angles.iter().flatten().copied().collect();
    let s = Summary::of(&measured);
    AngularDeviation {
        correspondence,
        faces: s.count,
        degenerate_faces: angles.len() - s.count,
        mean: s.mean,
        rms: s.rms,
        std: s.std,
        p99: s.p99,
        max: s.max,
        flipped_faces: measured
            .iter()
            .filter(|&&a| a > std::f64::consts::FRAC_PI_2)
            .count(),
    }
}

/// Angular deviation with a prepared closest-point index of the reference and, optionally,
/// each result face's counterpart in the reference ([`surface::counterparts`]).
pub fn angular_deviation_with(
    result: &Mesh,
    reference_index: &SurfaceIndex<'_>,
    counterparts: Option<&[u32]>,
) -> AngularDeviation {
    let reference = reference_index.mesh();
    if same_connectivity(result, reference) {
        let angles: Vec<Option<f64>> = (0..result.triangles.len())
            .into_par_iter()
            .map(|t| Some(angle(unit_normal(result, t)?, unit_normal(reference, t)?)))
            .collect();
        return summarise(&angles, Correspondence::SameFaces);
    }
    let angles: Vec<Option<f64>> = (0..result.triangles.len())
        .into_par_iter()
        .map(|t| {
            let n = unit_normal(result, t)?;
            let near = counterparts
                .and_then(|c| c.get(t).copied())
                .filter(|&c| (c as usize) < reference.triangles.len());
            let reference_face = match near {
                // The face a crop kept: it is its counterpart.
                Some(c)
                    if result.triangle_positions(t) == reference.triangle_positions(c as usize) =>
                {
                    c as usize
                }
                _ => {
                    let [a, b, c] = result.triangle_positions(t);
                    let centroid = (a + b + c) / 3.0;
                    let closest = match near {
                        Some(near) => reference_index.closest_near(centroid, near as usize),
                        None => reference_index.closest(centroid),
                    };
                    reference_index.facing(centroid, &closest, n)
                }
            };
            Some(angle(n, unit_normal(reference, reference_face)?))
        })
        .collect();
    summarise(&angles, Correspondence::ClosestPoint)
}

pub fn angular_deviation(
    result: &Mesh,
    reference: &Mesh,
) -> Result<AngularDeviation, MetricsError> {
    super::surface::check_measurable(result, "result")?;
    let index = SurfaceIndex::new(reference, "reference")?;
    let counterparts = surface::counterparts(result, reference);
    Ok(angular_deviation_with(
        result,
        &index,
        counterparts.as_deref(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::{grid, uv_sphere};

    #[test]
    fn itself_is_zero() {
        let m = uv_sphere(1.0, 10, 12);
        let a = angular_deviation(&m, &m).unwrap();
        assert_eq!(a.correspondence, Correspondence::SameFaces);
        assert_eq!(
            (a.max, a.flipped_faces, a.faces),
            (0.0, 0, m.triangles.len())
        );
    }

    fn soup(positions: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Mesh {
        Mesh {
            wedges: (0..positions.len() as u32)
                .map(|vertex| crate::mesh::Wedge {
                    vertex,
                    texcoord: None,
                    normal: None,
                })
                .collect(),
            positions,
            triangles,
            ..Mesh::default()
        }
    }

    /// A page folded back over itself along x = 0, and a result face beside the fold whose
    /// centroid is as near to both of its triangles: the face is measured against the one
    /// it faces with, whichever way it faces, so it is not flipped either way (a search
    /// alone answers the same triangle for both faces, and one of them would count).
    #[test]
    fn at_a_fold_the_nearest_normal_counts() {
        let reference = soup(
            vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(0.8, 0.5, 0.3)],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let centre = DVec3::new(-0.5, 0.5, 0.0);
        for t in 0..2 {
            let n = reference.triangle_cross(t).normalize();
            let e1 = n.any_orthonormal_vector();
            let e2 = n.cross(e1);
            let corners: Vec<DVec3> = [0.0f64, 120.0, 240.0]
                .iter()
                .map(|a| centre + 0.1 * (e1 * a.to_radians().cos() + e2 * a.to_radians().sin()))
                .collect();
            let result = soup(corners, vec![[0, 1, 2]]);
            assert!(result.triangle_cross(0).dot(n) > 0.0);
            let a = angular_deviation(&result, &reference).unwrap();
            assert_eq!(a.correspondence, Correspondence::ClosestPoint);
            assert_eq!(a.flipped_faces, 0, "face along triangle {t}: {a:?}");
            assert!(a.max < 1e-9, "{a:?}");
        }
    }

    #[test]
    fn a_flipped_face_is_counted() {
        let m = uv_sphere(1.0, 10, 12);
        let mut flipped = m.clone();
        flipped.triangles[5].swap(1, 2);
        let a = angular_deviation(&flipped, &m).unwrap();
        assert_eq!(a.flipped_faces, 1);
        assert!((a.max - std::f64::consts::PI).abs() < 1e-6, "{a:?}");
        // Different connectivity (a face removed) goes through closest points and still
        // finds it.
        flipped.triangles.remove(0);
        let a = angular_deviation(&flipped, &m).unwrap();
        assert_eq!(a.correspondence, Correspondence::ClosestPoint);
        assert_eq!(a.flipped_faces, 1);
    }

    #[test]
    fn tilted_plane_gives_its_angle() {
        let reference = grid(4, 4);
        let mut result = grid(3, 5); // other connectivity
        let tilt = 0.1f64;
        for p in &mut result.positions {
            *p = DVec3::new(0.2 + p.x, 0.2 + p.y * 0.7, (0.2 + p.x) * tilt.tan());
        }
        let a = angular_deviation(&result, &reference).unwrap();
        assert!((a.mean - tilt).abs() < 1e-12 && a.std < 1e-12, "{a:?}");
        assert!((a.p99 - tilt).abs() < 1e-12);
    }

    #[test]
    fn degenerate_faces_are_counted_not_measured() {
        let mut m = grid(2, 1);
        let reference = m.clone();
        m.positions[1] = m.positions[0]; // collapses faces touching vertices 0 and 1
        let a = angular_deviation(&m, &reference).unwrap();
        assert_eq!(a.degenerate_faces, 1);
        assert_eq!(a.faces + a.degenerate_faces, m.triangles.len());
    }
}
