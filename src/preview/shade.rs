//! Shading of a visible surface point: its albedo (texture, per-vertex colour or neutral
//! grey, or a distance colour for the third panel) times simple lighting.
//!
//! Lighting: Lambert with a headlight (the light comes from the camera) plus some ambient
//! light, two-sided (|n·l|): raw scans have ragged borders whose triangles face away, and
//! one-sided lighting would draw them as black holes. Scanned textures already carry the
//! lighting of the capture, so the diffuse share is kept moderate.

use super::ramp::viridis;
use crate::mesh::Mesh;
use crate::metrics::texture::{TextureCache, bilinear};
use glam::{DVec2, DVec3};
use image::RgbImage;
use std::sync::Arc;

/// Light that reaches every point whatever its orientation, as a fraction.
const AMBIENT: f64 = 0.3;
/// The albedo of surfaces without texture or colours (sRGB level).
const GREY: f64 = 190.0;

/// What colours the surface before lighting.
pub enum Albedo {
    /// The mesh's own appearance: the material's diffuse texture where there is one and
    /// the corners have texture coordinates, else per-vertex colour, else grey.
    Appearance {
        /// One image per material (`None` where a material has no usable texture).
        images: Vec<Option<Arc<RgbImage>>>,
    },
    /// A value per vertex mapped through the colour ramp, `value / scale` in [0, 1].
    Scalar { values: Vec<f64>, scale: f64 },
}

/// A mesh made ready for shading: normals per corner and the albedo source.
pub struct Surface<'a> {
    pub mesh: &'a Mesh,
    /// Area-weighted vertex normals, for corners without a normal of their own.
    vertex_normals: Vec<DVec3>,
    albedo: Albedo,
}

impl<'a> Surface<'a> {
    pub fn new(mesh: &'a Mesh, albedo: Albedo) -> Surface<'a> {
        let own_normals =
            !mesh.normals.is_empty() && mesh.wedges.iter().all(|w| w.normal.is_some());
        let vertex_normals = if own_normals {
            Vec::new()
        } else {
            crate::metrics::distance::vertex_normals(mesh)
        };
        Surface {
            mesh,
            vertex_normals,
            albedo,
        }
    }

    /// The mesh's own appearance, decoding its textures through `cache`. A texture that
    /// does not decode is logged and the material drawn grey.
    pub fn appearance(mesh: &'a Mesh, cache: &mut TextureCache) -> Surface<'a> {
        let images = mesh
            .materials
            .iter()
            .map(|m| {
                let texture = m.diffuse_texture.as_ref()?;
                cache
                    .get_texture(texture)
                    .map_err(|e| tracing::warn!("preview: texture not drawn: {e}"))
                    .ok()
            })
            .collect();
        Surface::new(mesh, Albedo::Appearance { images })
    }

    fn corner_normal(&self, wedge: u32) -> DVec3 {
        let w = self.mesh.wedges[wedge as usize];
        match w.normal {
            Some(n) if self.vertex_normals.is_empty() => self.mesh.normals[n as usize],
            _ => self
                .vertex_normals
                .get(w.vertex as usize)
                .copied()
                .unwrap_or(DVec3::ZERO),
        }
    }

    /// The shaded colour (0..255 per channel) of triangle `t` at barycentrics `b`, lit from
    /// `towards_light` (unit).
    pub fn shade(&self, t: usize, b: DVec3, towards_light: DVec3) -> [f64; 3] {
        let corners = self.mesh.triangles[t];
        let n = corners
            .iter()
            .zip(b.to_array())
            .map(|(&w, weight)| self.corner_normal(w) * weight)
            .sum::<DVec3>();
        let n = n.try_normalize().unwrap_or_else(|| {
            self.mesh
                .triangle_cross(t)
                .try_normalize()
                .unwrap_or(towards_light)
        });
        let light = AMBIENT + (1.0 - AMBIENT) * n.dot(towards_light).abs();
        self.albedo(t, b).map(|c| c * light)
    }

    fn albedo(&self, t: usize, b: DVec3) -> [f64; 3] {
        let mesh = self.mesh;
        let corners = mesh.triangles[t];
        match &self.albedo {
            Albedo::Scalar { values, scale } => {
                let v = corners
                    .iter()
                    .zip(b.to_array())
                    .map(|(&w, weight)| {
                        let vertex = mesh.wedges[w as usize].vertex as usize;
                        values.get(vertex).copied().unwrap_or(0.0) * weight
                    })
                    .sum::<f64>();
                viridis(if *scale > 0.0 { v / scale } else { 0.0 })
            }
            Albedo::Appearance { images } => {
                let image = images
                    .get(mesh.triangle_material(t) as usize)
                    .and_then(Option::as_ref);
                if let Some(image) = image {
                    let uv = corners
                        .iter()
                        .zip(b.to_array())
                        .try_fold(DVec2::ZERO, |acc, (&w, weight)| {
                            Some(acc + mesh.wedge_texcoord(w)? * weight)
                        });
                    if let Some(uv) = uv {
                        return bilinear(image, uv).to_array();
                    }
                }
                if mesh.colors.len() == mesh.positions.len() {
                    let mut c = [0.0; 3];
                    for (&w, weight) in corners.iter().zip(b.to_array()) {
                        let rgba = mesh.colors[mesh.wedges[w as usize].vertex as usize];
                        for k in 0..3 {
                            c[k] += rgba[k] as f64 * weight;
                        }
                    }
                    return c;
                }
                [GREY; 3]
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::grid;

    #[test]
    fn grey_lit_head_on_and_two_sided() {
        let m = grid(1, 1);
        let s = Surface::new(&m, Albedo::Appearance { images: vec![] });
        let b = DVec3::splat(1.0 / 3.0);
        let front = s.shade(0, b, DVec3::Z);
        let back = s.shade(0, b, DVec3::NEG_Z);
        assert!((front[0] - GREY).abs() < 1e-9, "{front:?}");
        assert_eq!(front, back);
        // Grazing light: ambient only.
        let side = s.shade(0, b, DVec3::X);
        assert!((side[0] - GREY * AMBIENT).abs() < 1e-9);
    }

    #[test]
    fn vertex_colours_and_scalars() {
        let mut m = grid(1, 1);
        m.colors = vec![[255, 0, 0, 255]; m.positions.len()];
        let s = Surface::new(&m, Albedo::Appearance { images: vec![] });
        let c = s.shade(0, DVec3::new(0.2, 0.3, 0.5), DVec3::Z);
        assert!((c[0] - 255.0).abs() < 1e-9 && c[1] == 0.0);
        let n = m.positions.len();
        let s = Surface::new(
            &m,
            Albedo::Scalar {
                values: vec![0.0; n],
                scale: 0.0,
            },
        );
        assert_eq!(s.shade(1, DVec3::splat(1.0 / 3.0), DVec3::Z), viridis(0.0));
    }
}
