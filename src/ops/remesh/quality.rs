//! Triangle quality by the smallest angle: the figures a remeshing is judged by.

use crate::mesh::Mesh;
use crate::metrics::percentile;
use rayon::prelude::*;
use serde::Serialize;

/// Smallest-angle statistics of a mesh's triangles (degrees).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct AngleQuality {
    /// Share of triangles whose smallest angle is at least 30°.
    pub share_min_angle_30: f64,
    /// 1st percentile of the triangles' smallest angles.
    pub min_angle_p1: f64,
    pub min_angle: f64,
}

/// The smallest angle of a triangle in degrees (0 for a degenerate one): the angle opposite
/// its shortest edge (the law of sines), so one arc cosine rather than three.
pub fn min_angle(p: [glam::DVec3; 3]) -> f64 {
    let opposite = |k: usize| p[(k + 1) % 3].distance_squared(p[(k + 2) % 3]);
    let k = (1..3).fold(0, |k, j| if opposite(j) < opposite(k) { j } else { k });
    let (a, b, c) = (p[k], p[(k + 1) % 3], p[(k + 2) % 3]);
    let (u, v) = (b - a, c - a);
    if u.length_squared() == 0.0 || v.length_squared() == 0.0 {
        0.0
    } else {
        u.angle_between(v).to_degrees()
    }
}

pub fn min_angles(mesh: &Mesh) -> Vec<f64> {
    (0..mesh.triangles.len())
        .into_par_iter()
        .map(|t| min_angle(mesh.triangle_positions(t)))
        .collect()
}

impl AngleQuality {
    pub fn of(mesh: &Mesh) -> AngleQuality {
        let angles = min_angles(mesh);
        if angles.is_empty() {
            return AngleQuality::default();
        }
        let good = angles.iter().filter(|&&a| a >= 30.0).count();
        AngleQuality {
            share_min_angle_30: good as f64 / angles.len() as f64,
            min_angle_p1: percentile(&angles, 0.01),
            min_angle: angles.iter().copied().fold(f64::INFINITY, f64::min),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::surface::rng;
    use glam::DVec3;
    use rand::RngExt;

    #[test]
    fn smallest_angle_is_the_least_of_the_three() {
        let all_three = |p: [DVec3; 3]| {
            (0..3)
                .map(|k| {
                    let (a, b, c) = (p[k], p[(k + 1) % 3], p[(k + 2) % 3]);
                    (b - a).angle_between(c - a).to_degrees()
                })
                .fold(f64::INFINITY, f64::min)
        };
        let mut r = rng(3);
        for _ in 0..10_000 {
            let p = [(); 3].map(|_| {
                DVec3::new(
                    r.random_range(-1.0..1.0),
                    r.random_range(-1.0..1.0),
                    r.random_range(-1.0..1.0),
                )
            });
            assert!((min_angle(p) - all_three(p)).abs() < 1e-9, "{p:?}");
        }
        let (o, x, y) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        assert!((min_angle([o, x, y]) - 45.0).abs() < 1e-12);
        let h = DVec3::new(0.5, 3f64.sqrt() / 2.0, 0.0);
        assert!((min_angle([o, x, h]) - 60.0).abs() < 1e-9);
        assert_eq!(min_angle([o, o, x]), 0.0);
        assert_eq!(min_angle([x, x, x]), 0.0);
    }
}
