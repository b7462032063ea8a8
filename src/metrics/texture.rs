//! Texture deviation: what a person sees as a smeared or shifted texture. At sample points
//! on the result, the colour the result's own texture coordinates pick from its texture is
//! compared with the colour the reference's texture coordinates pick at the closest point of
//! the reference (barycentric texture coordinates, bilinear lookup).
//!
//! Conventions: OBJ `vt` has its origin at the bottom left (data/SOURCES.md), so image row
//! = (1 − v) · height. Coordinates outside \[0,1\] wrap (the OBJ/MTL default of repeating
//! textures). The difference of two colours is the RMS over the R, G, B channels, in 0..255
//! units, so a uniform shift of k levels in every channel reads k.

use super::Summary;
use super::surface::{Closest, SurfacePoint};
use crate::mesh::{InputLimits, Mesh, Texture, texture};
use glam::{DVec2, DVec3};
use image::RgbImage;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "status", rename_all = "kebab-case")]
pub enum TextureDeviation {
    Measured {
        /// Samples where both sides had texture coordinates and a texture.
        samples: usize,
        mean: f64,
        rms: f64,
        p99: f64,
        max: f64,
    },
    Skipped {
        reason: String,
    },
}

/// Decoded texture images by path, decoded once (RGB8), shared by later comparisons, through
/// the loader's bounded image reader ([`texture::load_image`]): a file within
/// `limits.max_file_bytes`, and all images together within `limits.max_texture_pixels`.
///
/// Clones share the images and the pixel allowance, so that the final metrics and the
/// preview, which run side by side on the same textures, decode each image once: a second
/// decoded copy of the coral's 2048² texture was 12.6 MB at the whole run's memory peak, at
/// its end (docs/face-scan.md). A texture is decoded under the cache's lock; the other user
/// waits for it rather than decoding it again.
#[derive(Clone)]
pub struct TextureCache {
    shared: Arc<Mutex<Images>>,
}

struct Images {
    images: HashMap<PathBuf, Result<Arc<RgbImage>, String>>,
    limits: InputLimits,
    pixels_left: u64,
}

impl Default for TextureCache {
    fn default() -> Self {
        TextureCache::with_limits(InputLimits::default())
    }
}

impl TextureCache {
    pub fn new() -> Self {
        Self::default()
    }

    /// A cache whose images stay within `limits` (the job's input limits).
    pub fn with_limits(limits: InputLimits) -> Self {
        TextureCache {
            shared: Arc::new(Mutex::new(Images {
                images: HashMap::new(),
                pixels_left: limits.max_texture_pixels,
                limits,
            })),
        }
    }

    /// The decoded image, or why it could not be read.
    pub fn get(&mut self, path: &Path) -> Result<Arc<RgbImage>, String> {
        self.cached(path, |limits, pixels_left| {
            texture::load_image(path, limits, pixels_left)
        })
    }

    /// The decoded image of texture `t` (a file or embedded in the scan's file), or why it
    /// could not be read.
    pub fn get_texture(&mut self, t: &Texture) -> Result<Arc<RgbImage>, String> {
        // A file is named by its path in errors, as `get` names it.
        self.cached(&t.path, |limits, pixels_left| match t.embedded {
            None => texture::load_image(&t.path, limits, pixels_left),
            Some(_) => texture::load_texture(t, limits, pixels_left),
        })
    }

    /// Keeps `image`, made by the caller (a baked texture), under `key`, so that later users
    /// of that texture read it from here instead of decoding its encoded copy; its pixels
    /// count against the allowance as a decoded one would.
    pub fn insert(&mut self, key: &Path, image: Arc<RgbImage>) {
        let mut cache = self.shared.lock().unwrap_or_else(PoisonError::into_inner);
        let pixels = u64::from(image.width()) * u64::from(image.height());
        cache.pixels_left = cache.pixels_left.saturating_sub(pixels);
        cache.images.insert(key.to_path_buf(), Ok(image));
    }

    /// The image cached under `key`, or `load`ed within the cache's limits and kept (an
    /// error too, so a bad file is read once). `into_rgb8`: an image decoded as RGB8 (JPEG,
    /// most PNGs) is kept, not copied.
    fn cached<E: std::fmt::Display>(
        &mut self,
        key: &Path,
        load: impl FnOnce(&InputLimits, &mut u64) -> Result<image::DynamicImage, E>,
    ) -> Result<Arc<RgbImage>, String> {
        let mut cache = self.shared.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(known) = cache.images.get(key) {
            return known.clone();
        }
        let Images {
            limits,
            pixels_left,
            ..
        } = &mut *cache;
        let loaded = load(limits, pixels_left)
            .map(|img| Arc::new(img.into_rgb8()))
            .map_err(|e| e.to_string());
        cache.images.insert(key.to_path_buf(), loaded.clone());
        loaded
    }

    /// One image per material of `mesh` (`None` where a material has no texture).
    fn material_images(&mut self, mesh: &Mesh) -> Result<Vec<Option<Arc<RgbImage>>>, String> {
        mesh.materials
            .iter()
            .map(|m| {
                m.diffuse_texture
                    .as_ref()
                    .map(|t| self.get_texture(t))
                    .transpose()
            })
            .collect()
    }
}

/// Bilinear lookup with wrap-around; `uv` in OBJ convention (v up).
pub fn bilinear(image: &RgbImage, uv: DVec2) -> DVec3 {
    let (w, h) = (image.width() as i64, image.height() as i64);
    if w == 0 || h == 0 {
        return DVec3::ZERO;
    }
    let x = uv.x.rem_euclid(1.0) * w as f64 - 0.5;
    let y = (1.0 - uv.y.rem_euclid(1.0)) * h as f64 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let texel = |i: i64, j: i64| {
        let p = image
            .get_pixel(i.rem_euclid(w) as u32, j.rem_euclid(h) as u32)
            .0;
        DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
    };
    let (i, j) = (x0 as i64, y0 as i64);
    let [t00, t10, t01, t11] = if 0 <= i && i + 1 < w && 0 <= j && j + 1 < h {
        // The four texels inside the image (all but its last row and column): read
        // directly, without the wrap-around's four integer divisions per texel.
        let at = |i: i64, j: i64| {
            let p = image.get_pixel(i as u32, j as u32).0;
            DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
        };
        [at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)]
    } else {
        [
            texel(i, j),
            texel(i + 1, j),
            texel(i, j + 1),
            texel(i + 1, j + 1),
        ]
    };
    let top = t00 * (1.0 - fx) + t10 * fx;
    let bottom = t01 * (1.0 - fx) + t11 * fx;
    top * (1.0 - fy) + bottom * fy
}

/// The colour a mesh shows at a surface point, if that triangle is textured.
fn colour_at(mesh: &Mesh, images: &[Option<Arc<RgbImage>>], at: &SurfacePoint) -> Option<DVec3> {
    colour_on(mesh, images, at.triangle as usize, at.bary)
}

/// The colour a mesh shows at the point of triangle `t` with barycentric weights `bary`, if
/// that triangle is textured (`images` per material, as [`TextureCache`] gives them).
pub fn colour_on(
    mesh: &Mesh,
    images: &[Option<Arc<RgbImage>>],
    t: usize,
    bary: DVec3,
) -> Option<DVec3> {
    let image = images.get(mesh.triangle_material(t) as usize)?.as_ref()?;
    let [a, b, c] = mesh.triangles[t];
    let uv = mesh.wedge_texcoord(a)? * bary.x
        + mesh.wedge_texcoord(b)? * bary.y
        + mesh.wedge_texcoord(c)? * bary.z;
    Some(bilinear(image, uv))
}

fn textured(mesh: &Mesh) -> bool {
    mesh.has_texcoords() && mesh.materials.iter().any(|m| m.diffuse_texture.is_some())
}

/// Texture deviation from the result's samples and their closest reference points (the
/// queries the surface distance made already).
pub fn deviation_with(
    result: &Mesh,
    reference: &Mesh,
    samples: &[SurfacePoint],
    closest: &[Closest],
    cache: &mut TextureCache,
) -> TextureDeviation {
    let skipped = |reason: &str| TextureDeviation::Skipped {
        reason: reason.to_string(),
    };
    if !textured(result) {
        return skipped("the result has no textured material with texture coordinates");
    }
    if !textured(reference) {
        return skipped("the reference has no textured material with texture coordinates");
    }
    let images = match (
        cache.material_images(result),
        cache.material_images(reference),
    ) {
        (Ok(a), Ok(b)) => (a, b),
        (Err(e), _) | (_, Err(e)) => return skipped(&format!("texture not readable: {e}")),
    };
    let differences: Vec<f64> = samples
        .par_iter()
        .zip(closest.par_iter())
        .filter_map(|(s, c)| {
            let mine = colour_at(result, &images.0, s)?;
            let theirs = colour_at(reference, &images.1, &c.on)?;
            Some(((mine - theirs).length_squared() / 3.0).sqrt())
        })
        .collect();
    if differences.is_empty() {
        return skipped("no sample fell on textured triangles of both meshes");
    }
    let s = Summary::of(&differences);
    TextureDeviation::Measured {
        samples: s.count,
        mean: s.mean,
        rms: s.rms,
        p99: s.p99,
        max: s.max,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::grid;
    use crate::testing::{ramp_material, ramp_png, texture_deviation};

    fn textured_grid(path: &Path) -> Mesh {
        let mut m = grid(8, 8);
        m.materials.push(ramp_material(path));
        m
    }

    fn measure(result: &Mesh, reference: &Mesh) -> TextureDeviation {
        texture_deviation(result, reference)
    }

    #[test]
    fn bilinear_flips_v_and_interpolates() {
        let img = RgbImage::from_fn(2, 2, |x, y| {
            image::Rgb([(100 * x) as u8, (200 * y) as u8, 0])
        });
        // v = 1 is the image's top row (y = 0).
        let top_left = bilinear(&img, DVec2::new(0.25, 0.75));
        assert_eq!(top_left, DVec3::new(0.0, 0.0, 0.0));
        let bottom_right = bilinear(&img, DVec2::new(0.75, 0.25));
        assert_eq!(bottom_right, DVec3::new(100.0, 200.0, 0.0));
        let centre = bilinear(&img, DVec2::new(0.5, 0.5));
        assert_eq!(centre, DVec3::new(50.0, 100.0, 0.0));
    }

    /// Inside the image the four texels are read directly; the result is the one of
    /// reading every texel through the wrap-around, to the bit, everywhere: inside, on the
    /// last row and column, across the edges and outside [0, 1].
    #[test]
    fn bilinear_inside_is_the_wrapped_lookup() {
        let (w, h) = (7u32, 5u32);
        let img = RgbImage::from_fn(w, h, |x, y| {
            image::Rgb([
                (37 * x + 11 * y) as u8,
                (91 * y + 3 * x) as u8,
                (x * y) as u8,
            ])
        });
        let wrapped = |uv: DVec2| {
            let x = uv.x.rem_euclid(1.0) * w as f64 - 0.5;
            let y = (1.0 - uv.y.rem_euclid(1.0)) * h as f64 - 0.5;
            let (x0, y0) = (x.floor(), y.floor());
            let (fx, fy) = (x - x0, y - y0);
            let texel = |i: i64, j: i64| {
                let p = img.get_pixel(i.rem_euclid(w as i64) as u32, j.rem_euclid(h as i64) as u32);
                DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
            };
            let (i, j) = (x0 as i64, y0 as i64);
            let top = texel(i, j) * (1.0 - fx) + texel(i + 1, j) * fx;
            let bottom = texel(i, j + 1) * (1.0 - fx) + texel(i + 1, j + 1) * fx;
            top * (1.0 - fy) + bottom * fy
        };
        let (mut inside, mut edge) = (0, 0);
        for a in -20..=60 {
            for b in -20..=60 {
                let uv = DVec2::new(a as f64 / 40.0 + 0.0013, b as f64 / 40.0 - 0.0007);
                assert_eq!(bilinear(&img, uv), wrapped(uv), "{uv}");
                let x = uv.x.rem_euclid(1.0) * w as f64 - 0.5;
                let y = (1.0 - uv.y.rem_euclid(1.0)) * h as f64 - 0.5;
                if x >= 0.0 && x < (w - 1) as f64 && y >= 0.0 && y < (h - 1) as f64 {
                    inside += 1;
                } else {
                    edge += 1;
                }
            }
        }
        assert!(
            inside > 1000 && edge > 1000,
            "{inside} inside, {edge} at the edges"
        );
    }

    #[test]
    fn same_texture_is_zero_and_shift_is_measured() {
        let dir = tempfile::tempdir().unwrap();
        let path = ramp_png(dir.path());
        let reference = textured_grid(&path);
        match measure(&reference, &reference) {
            TextureDeviation::Measured { max, samples, .. } => {
                assert_eq!(samples, 4000);
                assert!(max < 1e-9, "{max}");
            }
            other => panic!("{other:?}"),
        }
        // Shift u by 8 texels: red and green each differ by 8 levels, blue by 0, so the
        // per-sample RMS over channels is sqrt((64 + 64) / 3). Stay clear of the wrap: only
        // u in [0.1, 0.85] is sampled.
        let mut result = reference.clone();
        for t in &mut result.texcoords {
            t.x = 0.1 + t.x * 0.75 + 8.0 / 256.0;
        }
        let mut reference = reference;
        for t in &mut reference.texcoords {
            t.x = 0.1 + t.x * 0.75;
        }
        let expected = (128.0f64 / 3.0).sqrt();
        match measure(&result, &reference) {
            TextureDeviation::Measured { rms, p99, mean, .. } => {
                assert!((rms - expected).abs() < 1e-6, "{rms} vs {expected}");
                assert!((p99 - expected).abs() < 1e-6 && (mean - expected).abs() < 1e-6);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn skipped_without_texture() {
        let m = grid(2, 2);
        assert!(matches!(measure(&m, &m), TextureDeviation::Skipped { .. }));
        let missing = textured_grid(Path::new("/nonexistent/ramp.png"));
        match measure(&missing, &missing) {
            TextureDeviation::Skipped { reason } => {
                assert!(reason.contains("ramp.png"), "{reason}")
            }
            other => panic!("{other:?}"),
        }
    }
}
