//! Per-triangle geometry of one snapshot: unit normal, area and centroid.

use super::super::CHUNK;
use glam::DVec3;
use rayon::prelude::*;

#[derive(Debug, Clone, Default)]
pub struct Faces {
    pub normal: Vec<DVec3>,
    pub area: Vec<f64>,
    pub centroid: Vec<DVec3>,
}

impl Faces {
    pub fn new(count: usize) -> Faces {
        Faces {
            normal: vec![DVec3::ZERO; count],
            area: vec![0.0; count],
            centroid: vec![DVec3::ZERO; count],
        }
    }

    /// Recomputes everything from `positions`. A zero-area (or non-finite) triangle gets
    /// a zero normal and area 0: it then weighs nothing in any filter.
    pub fn update(&mut self, corners: &[[u32; 3]], positions: &[DVec3]) {
        self.normal
            .par_chunks_mut(CHUNK)
            .zip(self.area.par_chunks_mut(CHUNK))
            .zip(self.centroid.par_chunks_mut(CHUNK))
            .zip(corners.par_chunks(CHUNK))
            .for_each(|(((normal, area), centroid), corners)| {
                for (k, c) in corners.iter().enumerate() {
                    let [a, b, d] = c.map(|v| positions[v as usize]);
                    let cross = (b - a).cross(d - a);
                    let len = cross.length();
                    let ok = len.is_finite() && len > 0.0;
                    normal[k] = if ok { cross / len } else { DVec3::ZERO };
                    area[k] = if ok { 0.5 * len } else { 0.0 };
                    centroid[k] = (a + b + d) * (1.0 / 3.0);
                }
            });
    }
}

/// The unnormalised normals (twice the area vector) of the triangles at `positions`.
pub fn cross_products(corners: &[[u32; 3]], positions: &[DVec3]) -> Vec<DVec3> {
    corners
        .par_iter()
        .with_min_len(CHUNK)
        .map(|c| {
            let [a, b, d] = c.map(|v| positions[v as usize]);
            (b - a).cross(d - a)
        })
        .collect()
}
