//! One pass of face-normal filtering: every triangle's normal replaced by a weighted mean
//! of the normals in its face ring, from one snapshot (buffered), in parallel, each sum in
//! the ring's fixed ascending order.
//!
//! The weight of neighbour j in the ring of face i is
//! `A_j · exp(−‖c_i − c_j‖² / 2σ_s²) · exp(−‖r_i − r_j‖² / 2σ_r²)`, with A the area and c the
//! centroid. What r is makes the variant:
//! - bilateral (Zheng et al. 2011, the local iterative scheme): r = the normal itself, so a
//!   neighbour across a crease (a normal far from this one) counts little;
//! - guided (Zhang et al. 2015): r = a guidance normal, the area-weighted mean normal of the
//!   most consistent patch containing the face (see [`guidance`]), which is less noisy than
//!   the face's own normal, so the range weight is decided on cleaner data.

use super::super::{CHUNK, par_for_each_indexed};
use super::faces::Faces;
use super::rings::{NONE, Rings};
use glam::DVec3;
use rayon::prelude::*;

/// The filter's widths, in model units (σ_s) and normal-difference units (σ_r, ‖n_i − n_j‖
/// ranges from 0 to 2).
#[derive(Debug, Clone, Copy)]
pub struct Widths {
    pub sigma_s: f64,
    pub sigma_r: f64,
}

/// Filters `faces.normal` into `out`. `range` holds the normals the range weight compares
/// (the normals themselves, or the guidance).
pub fn pass(rings: &Rings, faces: &Faces, range: &[DVec3], widths: Widths, out: &mut [DVec3]) {
    let inv_s = 1.0 / (2.0 * widths.sigma_s * widths.sigma_s);
    let inv_r = 1.0 / (2.0 * widths.sigma_r * widths.sigma_r);
    par_for_each_indexed(out, |i, slot| {
        let (ci, ri) = (faces.centroid[i], range[i]);
        let mut acc = DVec3::ZERO;
        for &j in rings.face_ring(i) {
            let j = j as usize;
            let ds = faces.centroid[j].distance_squared(ci);
            let dr = range[j].distance_squared(ri);
            let w = faces.area[j] * (-(ds * inv_s + dr * inv_r)).exp();
            acc += faces.normal[j] * w;
        }
        let len = acc.length();
        *slot = if len > 0.0 && len.is_finite() {
            acc / len
        } else {
            faces.normal[i]
        };
    });
}

/// Guidance normals of Zhang et al. 2015. Each triangle j defines a patch, its face ring
/// P_j; the patch's consistency is `H = D · R`, with D the largest normal difference
/// between two of its triangles and R = max φ / (ε + Σ φ) over the patch's inner edges (φ =
/// the normal difference across the edge): a patch is consistent when its normals agree
/// (small D) or when they differ only along one clear crease (small R). Triangle i's
/// guidance is the area-weighted mean normal of the most consistent patch among those that
/// contain it (the patches of the triangles in its own ring; ties go to the lowest index).
pub fn guidance(rings: &Rings, faces: &Faces, out: &mut [DVec3]) {
    let n = rings.triangle_count();
    let scored: Vec<(f64, DVec3)> = (0..n)
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(|j| patch_score(rings, faces, j))
        .collect();
    par_for_each_indexed(out, |i, slot| {
        let mut best = (f64::INFINITY, faces.normal[i]);
        for &j in rings.face_ring(i) {
            let (h, g) = scored[j as usize];
            if h < best.0 {
                best = (h, g);
            }
        }
        *slot = best.1;
    });
}

/// ε of R's denominator (Zhang et al. give 10⁻⁹): only keeps a perfectly flat patch finite.
const EPSILON: f64 = 1e-9;

/// (H, mean normal) of triangle j's patch.
fn patch_score(rings: &Rings, faces: &Faces, j: usize) -> (f64, DVec3) {
    let patch = rings.face_ring(j);
    let mut mean = DVec3::ZERO;
    let mut d_max = 0.0f64;
    let (mut phi_max, mut phi_sum) = (0.0f64, 0.0f64);
    for (a, &p) in patch.iter().enumerate() {
        let np = faces.normal[p as usize];
        mean += np * faces.area[p as usize];
        for &q in &patch[a + 1..] {
            d_max = d_max.max(np.distance(faces.normal[q as usize]));
        }
        // Each inner edge once: from its lower triangle.
        for q in rings.across(p as usize) {
            if q != NONE && q > p && patch.binary_search(&q).is_ok() {
                let phi = np.distance(faces.normal[q as usize]);
                phi_max = phi_max.max(phi);
                phi_sum += phi;
            }
        }
    }
    let len = mean.length();
    let mean = if len > 0.0 && len.is_finite() {
        mean / len
    } else {
        faces.normal[j]
    };
    let h = d_max * phi_max / (EPSILON + phi_sum);
    (if h.is_finite() { h } else { f64::INFINITY }, mean)
}

/// Mean normal difference ‖n_i − n_j‖ across the inner edges (each once), the scan's own
/// roughness the range width is measured in. Partial sums over fixed chunks, added in
/// chunk order: the same bits whatever the thread count. 0 for a mesh with no inner edge.
pub fn mean_edge_difference(rings: &Rings, faces: &Faces) -> f64 {
    let n = rings.triangle_count();
    let partial: Vec<(f64, u64)> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|chunk| {
            let (mut sum, mut count) = (0.0, 0u64);
            for i in chunk * CHUNK..((chunk + 1) * CHUNK).min(n) {
                for j in rings.across(i) {
                    if j != NONE && (j as usize) > i {
                        sum += faces.normal[i].distance(faces.normal[j as usize]);
                        count += 1;
                    }
                }
            }
            (sum, count)
        })
        .collect();
    let (sum, count) = partial
        .iter()
        .fold((0.0, 0u64), |(s, c), &(ps, pc)| (s + ps, c + pc));
    if count > 0 { sum / count as f64 } else { 0.0 }
}
