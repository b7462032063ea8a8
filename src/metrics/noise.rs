//! The noise model of the smoothing thesis (Svěchovský, *Vyhlazování polygonálních modelů*, FIT VUT Brno 2010,
//! §4.2.2, the `mdNoise` module): Gaussian noise
//! with standard deviation σ = k · ē, ē the mean edge length of the clean mesh, k = 0.2 by
//! default, from a recorded seed. Used by tests, benchmarks and `scanmill compare`.
//!
//! The thesis does not say in which direction the noise goes ; independent noise per
//! coordinate is one reading; issue #3 asks for noise along the vertex
//! normals, which moves the surface without sliding vertices along it (what a scanner's
//! depth error does). Both are offered; along the normals is the default.

use crate::mesh::Mesh;
use glam::DVec3;
use rand::RngExt;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum NoiseDirection {
    /// One N(0, σ²) offset per vertex along its area-weighted normal.
    #[default]
    Normal,
    /// Independent N(0, σ²) per x, y, z (one reading of the smoothing thesis, §4.2.2, which
    /// does not say).
    Isotropic,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NoiseOptions {
    /// k in σ = k · mean edge length.
    pub sigma_factor: f64,
    pub seed: u64,
    pub direction: NoiseDirection,
}

impl Default for NoiseOptions {
    fn default() -> Self {
        NoiseOptions {
            sigma_factor: 0.2,
            seed: 1,
            direction: NoiseDirection::Normal,
        }
    }
}

/// Mean length of the mesh's distinct edges (each shared edge counted once).
pub fn mean_unique_edge_length(mesh: &Mesh) -> f64 {
    let mut edges: Vec<(u32, u32)> = Vec::with_capacity(3 * mesh.triangles.len());
    for t in 0..mesh.triangles.len() {
        let v = mesh.triangle_vertices(t);
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            edges.push((a.min(b), a.max(b)));
        }
    }
    edges.sort_unstable();
    edges.dedup();
    if edges.is_empty() {
        return 0.0;
    }
    let sum: f64 = edges
        .iter()
        .map(|&(a, b)| mesh.positions[a as usize].distance(mesh.positions[b as usize]))
        .sum();
    sum / edges.len() as f64
}

/// A standard normal deviate (Box–Muller; uses two uniforms, the second value is dropped so
/// that every draw consumes the same amount of the stream).
fn standard_normal(rng: &mut super::surface::MetricsRng) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>(); // (0, 1]: ln is finite
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// What [`add_noise`] did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NoiseReport {
    pub mean_edge_length: f64,
    pub sigma: f64,
    pub seed: u64,
    pub direction: NoiseDirection,
}

/// Moves every vertex of `mesh` by Gaussian noise. Connectivity, wedges and attributes are
/// untouched, so the result can be compared face by face with the original.
pub fn add_noise(mesh: &mut Mesh, options: &NoiseOptions) -> NoiseReport {
    let mean_edge_length = mean_unique_edge_length(mesh);
    let sigma = options.sigma_factor * mean_edge_length;
    let mut rng = super::surface::rng(options.seed);
    match options.direction {
        NoiseDirection::Normal => {
            let normals = super::distance::vertex_normals(mesh);
            for (p, n) in mesh.positions.iter_mut().zip(normals) {
                *p += n * (sigma * standard_normal(&mut rng));
            }
        }
        NoiseDirection::Isotropic => {
            for p in &mut mesh.positions {
                let x = standard_normal(&mut rng);
                let y = standard_normal(&mut rng);
                let z = standard_normal(&mut rng);
                *p += DVec3::new(x, y, z) * sigma;
            }
        }
    }
    NoiseReport {
        mean_edge_length,
        sigma,
        seed: options.seed,
        direction: options.direction,
    }
}

/// A noisy copy of `mesh`.
pub fn noisy_copy(mesh: &Mesh, options: &NoiseOptions) -> (Mesh, NoiseReport) {
    let mut copy = mesh.clone();
    let report = add_noise(&mut copy, options);
    (copy, report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::{grid, uv_sphere};

    #[test]
    fn sigma_and_distribution_along_normals() {
        let m = grid(60, 60);
        assert!((mean_unique_edge_length(&m) - (2.0 + 2f64.sqrt()) / 3.0).abs() < 0.01);
        let (noisy, r) = noisy_copy(&m, &NoiseOptions::default());
        assert!((r.sigma - 0.2 * r.mean_edge_length).abs() < 1e-15);
        let dz: Vec<f64> = noisy.positions.iter().map(|p| p.z).collect();
        let n = dz.len() as f64;
        let mean = dz.iter().sum::<f64>() / n;
        let std = (dz.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        assert!(
            mean.abs() < 0.01 && (std / r.sigma - 1.0).abs() < 0.05,
            "{mean} {std}"
        );
        // Along the normal of a flat grid: x and y do not move.
        assert!(
            noisy
                .positions
                .iter()
                .zip(&m.positions)
                .all(|(a, b)| a.x == b.x && a.y == b.y)
        );
    }

    #[test]
    fn seeded_and_isotropic() {
        let m = uv_sphere(1.0, 10, 12);
        let o = NoiseOptions {
            direction: NoiseDirection::Isotropic,
            ..Default::default()
        };
        assert_eq!(noisy_copy(&m, &o).0, noisy_copy(&m, &o).0);
        let other = NoiseOptions { seed: 2, ..o };
        assert_ne!(noisy_copy(&m, &o).0, noisy_copy(&m, &other).0);
        assert_ne!(
            noisy_copy(&m, &o).0,
            noisy_copy(&m, &NoiseOptions::default()).0
        );
    }
}
