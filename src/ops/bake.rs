//! Texture baking: a new image for each textured material of a mesh whose triangles no
//! longer follow the source's (a remesh), so that every point of the new surface shows the
//! colour the source shows at its closest point.
//!
//! Why: a remesh gives each new corner the texture coordinate of the source at that point,
//! within its chart, but between the corners the new triangle interpolates the coordinates
//! linearly, where the source's own map is linear per source triangle. Where the two
//! triangulations differ the photo lands a little off (up to a few texels on a scan whose
//! map stretches), which the texture metric reads as colour deviation (docs/remeshing.md).
//! Baking reads the colour through the source's map at every texel instead.
//!
//! The rule, per texel of the new image: the texel's centre, inside a new triangle's
//! texture-space image, is a point of that triangle (its barycentric weights in texture
//! space); the colour is the source's (bilinear) at the source point nearest to it, the
//! same correspondence the texture metric uses. Texels no new triangle covers keep the
//! source image's colour, so the gutters around charts stay as they were and bilinear
//! look-ups at chart edges read sensible colours. Coordinates outside [0, 1] (tiled
//! textures) are not baked: those texels keep the source's colour.
//!
//! The nearest source point of a texel is exact, as in the tree (`geom::bvh`), and found
//! among the few source triangles that can hold it for any point of the new triangle
//! ([`Reader::neighbourhood`], tested one by one with their boxes), starting from the
//! previous texel's source triangle. Where two source triangles are exactly as near (a point
//! over a source edge, often a seam, whose sides show different colours) the tree is
//! searched, so that the tie goes the way the tree, and the texture metric, break it: the
//! image is the one a tree search per texel gives, to the bit, in about two thirds of the
//! time (docs/remeshing.md). A walk over the source's triangles
//! from there (`ops::remesh::walk`, remeshing's projection) was twice as fast but settled
//! on the wrong sheet where scans fold or fall apart into pieces: the coral's deviation at
//! 1 % of the diagonal rose from 1.47 to 2.24 levels RMS, the esp32cam's from 1.87 to 2.76.
//!
//! The image is the source's size. Rows are baked in bands, in parallel; within a band the
//! triangles are rasterised in ascending order (a later one wins a shared texel), so the
//! image is the same whatever the thread count.

use crate::geom::bvh::{Among, Neighbourhood, TriangleBvh, TriangleHit};
use crate::mesh::{EmbeddedImage, Mesh, Texture};
use crate::metrics::texture::{TextureCache, colour_on};
use glam::{DVec2, DVec3};
use image::RgbImage;
use rayon::prelude::*;
use serde::Serialize;
use std::path::PathBuf;
use std::sync::Arc;

/// Rows of one band: enough texels per task to amortise the bucketing, small enough that
/// a 1,600-row image gives both cores many bands.
const BAND_ROWS: usize = 32;

/// Most source triangles a new triangle's texels test one by one; with more the tree is
/// searched per texel (a large new triangle over a fine source).
const NEIGHBOURHOOD_LIMIT: usize = 128;

/// Texture-space slack of the inside test, in barycentric weight: a texel centre on a
/// shared edge belongs to both triangles rather than to neither.
const INSIDE_SLACK: f64 = 1e-9;

#[derive(Debug, Clone, Default, Serialize)]
pub struct BakeReport {
    /// Materials given a baked image.
    pub images: usize,
    /// Texels read from the source surface.
    pub texels: usize,
    /// Why a textured material was left with the source's image, if one was.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub skipped: Vec<String>,
}

/// The surface a bake reads: the mesh the result was made from and its closest-point tree.
pub struct Source<'a> {
    pub mesh: &'a Mesh,
    pub bvh: &'a TriangleBvh<'a>,
}

/// Bakes every textured material of `result` from `source`. `result`'s material `m` is
/// assumed to be the source's material `m` (a remesh keeps them), its texture coordinates in
/// the same charts. The source's images are read through `cache`, and each baked image is
/// left there under its texture's path, so that whoever reads the result's textures next
/// (the final metrics, the preview) need not decode them.
pub fn bake(result: &mut Mesh, source: &Source, cache: &mut TextureCache) -> BakeReport {
    let mut report = BakeReport::default();
    if !result.has_texcoords() || !source.mesh.has_texcoords() {
        return report;
    }
    let images: Vec<Option<Arc<RgbImage>>> = (source.mesh.materials.iter())
        .map(|m| cache.get_texture(m.diffuse_texture.as_ref()?).ok())
        .collect();
    let reader = Reader { source, images };
    for m in 0..result.materials.len() {
        let Some(texture) = result.materials[m].diffuse_texture.clone() else {
            continue;
        };
        let name = &result.materials[m].name;
        let Some(Some(background)) = reader.images.get(m) else {
            let why = format!("material {name:?}: the source's texture could not be read");
            tracing::warn!("bake: {why}; the input's image is kept");
            report.skipped.push(why);
            continue;
        };
        let (image, texels) = bake_material(result, m as u32, &reader, background);
        match encode_png(&image) {
            Ok(bytes) => {
                let baked = baked_texture(&texture, bytes, &image);
                cache.insert(&baked.path, Arc::new(image));
                result.materials[m].diffuse_texture = Some(baked);
                report.images += 1;
                report.texels += texels;
            }
            Err(e) => {
                let why = format!("material {name:?}: the baked image did not encode: {e}");
                tracing::warn!("bake: {why}; the input's image is kept");
                report.skipped.push(why);
            }
        }
    }
    report
}

/// The source and its decoded images, one per material.
struct Reader<'a> {
    source: &'a Source<'a>,
    images: Vec<Option<Arc<RgbImage>>>,
}

impl Reader<'_> {
    /// The source's point nearest to `p`; `last` (a nearby texel's source triangle) bounds
    /// the search from the start. Among the triangles of `near` when given (gathered by
    /// [`Reader::neighbourhood`] for a triangle `p` lies in); in the tree otherwise, and
    /// where two triangles are exactly as near, so that the tie goes the tree's way.
    fn nearest_within(
        &self,
        p: DVec3,
        near: Option<&Neighbourhood>,
        last: Option<u32>,
    ) -> Option<TriangleHit> {
        let bvh = self.source.bvh;
        let start = last.map(|t| bvh.hit_on(p, t));
        match near.map(|n| bvh.closest_among(p, n, start)) {
            Some(Among::Nearest(hit)) => Some(hit),
            _ => bvh.closest(p, start),
        }
    }

    /// The source triangles that can hold the nearest source point of any point of the
    /// triangle with corners `c`, into `out`; `false` when there are more than
    /// [`NEIGHBOURHOOD_LIMIT`] (the tree is then searched per texel instead). Every point p
    /// of the triangle lies within ℓ/√3 of a corner (ℓ its longest side; the equilateral
    /// triangle's centre is the farthest case), so p's distance to the source is at most
    /// that plus the corner's: every triangle nearer to p meets the triangle's box grown by
    /// that bound.
    fn neighbourhood(&self, c: [DVec3; 3], out: &mut Neighbourhood) -> bool {
        let mut reach: f64 = 0.0;
        for corner in c {
            match self.source.bvh.closest(corner, None) {
                // An answer cut short by the tree's budget is still an upper bound.
                Some(hit) => reach = reach.max(hit.distance_squared.sqrt()),
                None => return false,
            }
        }
        let longest = (0..3)
            .map(|k| c[k].distance(c[(k + 1) % 3]))
            .fold(0.0, f64::max);
        let (lo, hi) = (c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2]));
        // A little more than the bound, against rounding in the texel's point.
        let scale = lo.abs().max(hi.abs()).max_element();
        let r = (reach + longest / 3f64.sqrt()) * (1.0 + 1e-6) + 1e-12 * (1.0 + scale);
        let grow = DVec3::splat(r);
        self.source
            .bvh
            .neighbourhood(lo - grow, hi + grow, NEIGHBOURHOOD_LIMIT, out)
    }

    /// The source's colour at `hit`, if that triangle is textured.
    fn colour(&self, hit: &TriangleHit) -> Option<DVec3> {
        colour_on(
            self.source.mesh,
            &self.images,
            hit.triangle as usize,
            hit.bary,
        )
    }
}

/// The baked image of material `m` of `result` and how many texels were read.
fn bake_material(
    result: &Mesh,
    m: u32,
    reader: &Reader,
    background: &RgbImage,
) -> (RgbImage, usize) {
    let (w, h) = (background.width() as usize, background.height() as usize);
    let mut by_band: Vec<Vec<u32>> = vec![Vec::new(); h.div_ceil(BAND_ROWS)];
    for t in 0..result.triangles.len() {
        if result.triangle_material(t) != m {
            continue;
        }
        let Some(px) = pixel_corners(result, t, w, h) else {
            continue;
        };
        let (lo, hi) = row_range(&px, h);
        if lo < hi {
            for band in &mut by_band[lo / BAND_ROWS..=(hi - 1) / BAND_ROWS] {
                band.push(t as u32);
            }
        }
    }
    let mut image = background.clone();
    let texels: usize = image
        .par_chunks_mut(w * 3 * BAND_ROWS)
        .zip(by_band.par_iter())
        .enumerate()
        .map(|(band, (rows, triangles))| {
            let mut band = Band {
                rows,
                first_row: band * BAND_ROWS,
                width: w,
                height: h,
                texels: 0,
                near: Neighbourhood::default(),
            };
            for &t in triangles {
                band.fill(result, t as usize, reader);
            }
            band.texels
        })
        .sum();
    (image, texels)
}

/// Triangle `t`'s corners in pixel coordinates (texel `(i, j)` has its centre at `(i, j)`),
/// if all three have texture coordinates within [0, 1] and the image is not degenerate.
fn pixel_corners(mesh: &Mesh, t: usize, w: usize, h: usize) -> Option<[DVec2; 3]> {
    let mut out = [DVec2::ZERO; 3];
    for (k, &wedge) in mesh.triangles[t].iter().enumerate() {
        let uv = mesh.wedge_texcoord(wedge)?;
        if !(0.0..=1.0).contains(&uv.x) || !(0.0..=1.0).contains(&uv.y) {
            return None;
        }
        out[k] = DVec2::new(uv.x * w as f64 - 0.5, (1.0 - uv.y) * h as f64 - 0.5);
    }
    let [a, b, c] = out;
    let area = (b - a).perp_dot(c - a);
    (area.abs() > 1e-12).then_some(out)
}

/// The rows `lo..hi` whose centres the triangle's pixel box spans, within the image.
fn row_range(px: &[DVec2; 3], h: usize) -> (usize, usize) {
    let min = px.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
    let max = px.iter().map(|p| p.y).fold(f64::NEG_INFINITY, f64::max);
    let lo = min.ceil().max(0.0) as usize;
    let hi = ((max.floor() + 1.0).max(0.0) as usize).min(h);
    (lo, hi)
}

/// One band of rows of the image being baked.
struct Band<'a> {
    rows: &'a mut [u8],
    first_row: usize,
    width: usize,
    height: usize,
    texels: usize,
    near: Neighbourhood,
}

impl Band<'_> {
    /// Writes every texel of this band whose centre lies in triangle `t`'s texture image.
    /// Each texel's search looks among the source triangles near `t` and starts from the
    /// source triangle of the texel before.
    fn fill(&mut self, result: &Mesh, t: usize, reader: &Reader) {
        let Some(px) = pixel_corners(result, t, self.width, self.height) else {
            return;
        };
        let (lo, hi) = row_range(&px, self.height);
        let band_end = (self.first_row + BAND_ROWS).min(self.height);
        let corners = result.triangle_positions(t);
        let [a, b, c] = px;
        let area = (b - a).perp_dot(c - a);
        let xmin = px.iter().map(|p| p.x).fold(f64::INFINITY, f64::min);
        let xmax = px.iter().map(|p| p.x).fold(f64::NEG_INFINITY, f64::max);
        let (x0, x1) = (
            xmin.ceil().max(0.0) as usize,
            ((xmax.floor() + 1.0).max(0.0) as usize).min(self.width),
        );
        let rows = lo.max(self.first_row)..hi.min(band_end);
        if rows.is_empty() {
            return;
        }
        let near = reader
            .neighbourhood(corners, &mut self.near)
            .then_some(&self.near);
        let mut last: Option<u32> = None;
        for j in rows {
            for i in x0..x1 {
                let p = DVec2::new(i as f64, j as f64);
                let wa = (b - p).perp_dot(c - p) / area;
                let wb = (c - p).perp_dot(a - p) / area;
                let wc = 1.0 - wa - wb;
                if wa < -INSIDE_SLACK || wb < -INSIDE_SLACK || wc < -INSIDE_SLACK {
                    continue;
                }
                let point = corners[0] * wa + corners[1] * wb + corners[2] * wc;
                let Some(hit) = reader.nearest_within(point, near, last) else {
                    continue;
                };
                last = Some(hit.triangle);
                let Some(colour) = reader.colour(&hit) else {
                    continue;
                };
                let at = ((j - self.first_row) * self.width + i) * 3;
                for (k, v) in colour.to_array().into_iter().enumerate() {
                    self.rows[at + k] = v.round().clamp(0.0, 255.0) as u8;
                }
                self.texels += 1;
            }
        }
    }
}

/// PNG, fast compression: lossless, so the bake adds no error of its own.
fn encode_png(image: &RgbImage) -> Result<Vec<u8>, image::ImageError> {
    use image::ImageEncoder;
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    let mut bytes = Vec::new();
    PngEncoder::new_with_quality(&mut bytes, CompressionType::Fast, FilterType::Adaptive)
        .write_image(
            image.as_raw(),
            image.width(),
            image.height(),
            image::ExtendedColorType::Rgb8,
        )?;
    Ok(bytes)
}

/// The texture the baked image becomes: named after the source's (`<stem>_baked.png`; the
/// writers sanitise it), held in memory, with a path that is never opened and that no other
/// texture has.
fn baked_texture(source: &Texture, bytes: Vec<u8>, image: &RgbImage) -> Texture {
    let stem = source
        .name
        .rsplit('/')
        .next()
        .and_then(|n| n.rsplit_once('.').map(|(s, _)| s).or(Some(n)))
        .filter(|s| !s.is_empty())
        .unwrap_or("texture");
    Texture {
        name: format!("{stem}_baked.png"),
        path: PathBuf::from(format!("{}#baked", source.path.display())),
        size: Some((image.width(), image.height())),
        embedded: Some(EmbeddedImage(bytes.into())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::grid;
    use crate::metrics::texture::TextureDeviation;
    use crate::testing::{on_threads, ramp_material, ramp_png, texture_deviation};
    use std::path::Path;

    /// The square [0, 8]² as `n`×`n` cells, textured by the ramp through a map that is not
    /// linear (u = 0.05 + 0.9 (x/8)², v = y/8), so that a coarser triangulation
    /// interpolating the same map at its corners puts the photo off between them. (u stays
    /// clear of the image's left and right edges, where the look-ups wrap around and the
    /// ramp jumps from 255 to 0.)
    fn square(n: usize, texture: &Path) -> Mesh {
        let mut m = grid(n, n);
        let scale = 8.0 / n as f64;
        for (p, uv) in m.positions.iter_mut().zip(m.texcoords.iter_mut()) {
            *p *= scale;
            *uv = DVec2::new(0.05 + 0.9 * (p.x / 8.0).powi(2), p.y / 8.0);
        }
        m.materials.push(ramp_material(texture));
        m
    }

    fn rms(result: &Mesh, source: &Mesh) -> f64 {
        match texture_deviation(result, source) {
            TextureDeviation::Measured { rms, .. } => rms,
            other => panic!("{other:?}"),
        }
    }

    fn baked(result: &Mesh, source: &Mesh) -> (Mesh, BakeReport) {
        baked_into(result, source, &mut TextureCache::new())
    }

    /// [`baked`], reading and leaving images in `cache`.
    fn baked_into(result: &Mesh, source: &Mesh, cache: &mut TextureCache) -> (Mesh, BakeReport) {
        let bvh = TriangleBvh::new(source, (0..source.triangles.len() as u32).collect());
        let mut out = result.clone();
        let source = Source {
            mesh: source,
            bvh: &bvh,
        };
        let report = bake(&mut out, &source, cache);
        (out, report)
    }

    #[test]
    fn a_coarser_mesh_shows_the_source_colours_once_baked() {
        let dir = tempfile::tempdir().unwrap();
        let texture = ramp_png(dir.path());
        let source = square(16, &texture);
        let coarse = square(2, &texture);
        let before = rms(&coarse, &source);
        let (out, report) = baked(&coarse, &source);
        let after = rms(&out, &source);
        // Between the coarse corners u is off by up to 0.9/16 of the ramp: 14 levels.
        assert!(before > 5.0, "unbaked {before}");
        assert!(after < 1.0, "baked {after} (unbaked {before})");
        assert_eq!(report.images, 1);
        assert!(report.skipped.is_empty(), "{report:?}");
        // The square's image covers 90 % of the texture's columns, all its rows.
        assert!(report.texels >= 230 * 63, "{report:?}");
        let t = out.materials[0].diffuse_texture.as_ref().unwrap();
        assert_eq!(t.name, "ramp_baked.png");
        assert_eq!(t.size, Some((256, 64)));
        assert!(t.embedded.is_some());
        // The untouched mesh keeps its texture.
        assert_eq!(out.triangles, coarse.triangles);
        assert_eq!(out.texcoords, coarse.texcoords);
    }

    #[test]
    fn the_same_image_whatever_the_thread_count() {
        let dir = tempfile::tempdir().unwrap();
        let texture = ramp_png(dir.path());
        let source = square(16, &texture);
        let coarse = square(3, &texture);
        let image = |threads| {
            let (out, _) = on_threads(threads, || baked(&coarse, &source));
            out.materials[0].diffuse_texture.clone().unwrap().embedded
        };
        assert_eq!(image(1), image(3));
    }

    /// The baked image the cache keeps for later readers is the image its PNG decodes to,
    /// and the source's image is the one read from its file.
    #[test]
    fn the_cache_holds_what_the_files_decode_to() {
        let dir = tempfile::tempdir().unwrap();
        let texture = ramp_png(dir.path());
        let mut cache = TextureCache::new();
        let (out, _) = baked_into(&square(3, &texture), &square(16, &texture), &mut cache);
        let t = out.materials[0].diffuse_texture.clone().unwrap();
        let png = image::load_from_memory(&t.embedded.unwrap().0).unwrap();
        let kept = cache.get(&t.path).unwrap();
        assert_eq!(*kept, png.into_rgb8());
        let file = image::open(&texture).unwrap().into_rgb8();
        assert_eq!(*cache.get(&texture).unwrap(), file);
        // Not the source's image under another name: the bake changed it.
        assert_ne!(*kept, file);
    }

    #[test]
    fn untextured_meshes_are_left_alone() {
        let source = grid(4, 4);
        let (out, report) = baked(&grid(2, 2), &source);
        assert_eq!(report.images, 0);
        assert_eq!(out, grid(2, 2));
    }
}
