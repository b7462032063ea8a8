//! Preview pictures of a processed scan, drawn in software (no GPU, no window): three
//! panels side by side, the input, the result (textured, lit, from the front) and the
//! result coloured by its distance to the input, all through the same camera.
//!
//! - [`camera`]: what "front" means and how the view is fitted;
//! - [`raster`]: the z-buffered triangle rasteriser (visibility and barycentrics);
//! - [`shade`]: texture, vertex colour or distance colour, times the lighting;
//! - [`ramp`], [`font`]: the distance colours and the labels.
//!
//! Each panel is drawn `supersample` times larger and averaged down, which smooths the
//! silhouettes and the minified textures.

pub mod camera;
pub mod font;
pub mod ramp;
pub mod raster;
pub mod shade;

use crate::mesh::Mesh;
use crate::metrics::MetricsError;
use crate::metrics::surface::SurfaceIndex;
use crate::metrics::texture::TextureCache;
use camera::{Axis, Camera, Viewport};
use glam::DVec3;
use image::{Rgb, RgbImage};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use shade::{Albedo, Surface};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The recipe's `[preview]` table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PreviewOptions {
    /// Draw the preview (written as `<stem>.preview.png` beside the result).
    pub enabled: bool,
    /// Pixel size of each (square) panel; the picture is 3 × size wide and size high.
    pub size: u32,
    /// The direction the camera looks along, in the scan's own frame (see [`camera`]).
    pub view: Axis,
    /// The axis shown upwards; by default +Y (+Z when looking along Y).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub up: Option<Axis>,
    /// Samples per pixel along each direction (1 = none).
    pub supersample: u32,
}

impl Default for PreviewOptions {
    fn default() -> Self {
        PreviewOptions {
            enabled: true,
            size: 512,
            view: Axis::NegZ,
            up: None,
            supersample: 2,
        }
    }
}

impl PreviewOptions {
    pub fn is_default(&self) -> bool {
        *self == PreviewOptions::default()
    }

    pub fn up_axis(&self) -> Axis {
        self.up.unwrap_or(self.view.default_up())
    }

    pub fn validate(&self) -> Result<(), String> {
        if !(64..=4096).contains(&self.size) {
            return Err(format!("size must be 64 to 4096, got {}", self.size));
        }
        if !(1..=4).contains(&self.supersample) {
            return Err(format!(
                "supersample must be 1 to 4, got {}",
                self.supersample
            ));
        }
        if self.view.vector().cross(self.up_axis().vector()) == DVec3::ZERO {
            return Err("up must not be parallel to view".into());
        }
        Ok(())
    }
}

#[derive(Debug, thiserror::Error)]
pub enum PreviewError {
    #[error("preview: nothing to draw ({0})")]
    Empty(&'static str),
    #[error("preview: {0}")]
    Options(String),
    #[error("preview: distance to the input: {0}")]
    Distance(#[from] MetricsError),
    #[error("{path}: cannot write preview: {message}")]
    Write { path: PathBuf, message: String },
    /// The triangles overlap so deeply that drawing them would take far longer than the
    /// rest of the job (an overlapping triangle soup).
    #[error(
        "preview: the {panel}'s triangles would be drawn {depth} times over on average or \
         more (the limit is {MAX_OVERDRAW}); not drawn"
    )]
    Overdraw { panel: &'static str, depth: u64 },
}

/// Most pixel tests per image pixel a panel may cost (see [`raster::rasterise_within`]). Scans are
/// drawn with a few tests per pixel; only overlapping soups come near this.
pub const MAX_OVERDRAW: u64 = 64;

/// What the picture shows, for the report (distances relative to the input's bounding-box
/// diagonal, in percent, as in the legend).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PreviewFigures {
    pub width: u32,
    pub height: u32,
    pub view: Axis,
    pub up: Axis,
    /// The value at the top of the colour bar (the 99th percentile of the vertex
    /// distances rounded up to 1, 2, 2.5 or 5 × 10^k); larger distances are clamped.
    pub scale_percent: f64,
    /// The largest and 99th-percentile vertex distance of the result to the input.
    pub max_percent: f64,
    pub p99_percent: f64,
    pub render_ms: f64,
}

/// A rendered preview.
#[derive(Debug)]
pub struct Preview {
    pub image: RgbImage,
    pub figures: PreviewFigures,
}

const BACKGROUND: [u8; 3] = [236, 236, 236];
const INK: Rgb<u8> = Rgb([40, 40, 40]);

/// The bands of a panel: titles above, the colour bar below, the mesh in between.
struct Layout {
    size: u32,
    /// Font scale.
    k: u32,
    title_band: u32,
    legend_band: u32,
}

impl Layout {
    fn new(size: u32) -> Layout {
        let k = (size / 256).max(1);
        Layout {
            size,
            k,
            title_band: 15 * k,
            legend_band: 30 * k,
        }
    }

    fn viewport(&self) -> Viewport {
        Viewport {
            x: 0.0,
            y: self.title_band as f64,
            width: self.size as f64,
            height: (self.size - self.title_band - self.legend_band) as f64,
        }
    }
}

/// Renders the three panels: `input`, `result`, and `result` coloured by its distance to
/// `input`.
pub fn render(
    input: &Mesh,
    result: &Mesh,
    options: &PreviewOptions,
) -> Result<Preview, PreviewError> {
    render_with_textures(input, None, result, options, &mut TextureCache::new())
}

/// [`render`] reading the textures through `textures` (the run's, within the job's limits,
/// shared with the metrics), with `input_index`, when given, the metrics' closest-point index
/// over `input`: the distance panel then needs no index of its own.
pub fn render_with_textures(
    input: &Mesh,
    input_index: Option<&SurfaceIndex<'_>>,
    result: &Mesh,
    options: &PreviewOptions,
    cache: &mut TextureCache,
) -> Result<Preview, PreviewError> {
    debug_assert!(input_index.is_none_or(|i| std::ptr::eq(i.mesh(), input)));
    let start = Instant::now();
    options.validate().map_err(PreviewError::Options)?;
    if input.triangles.is_empty() {
        return Err(PreviewError::Empty("the input has no triangles"));
    }
    if result.triangles.is_empty() {
        return Err(PreviewError::Empty("the result has no triangles"));
    }
    let layout = Layout::new(options.size);
    let (view, up) = (options.view, options.up_axis());
    let camera = Camera::fit(
        input.positions.iter().chain(&result.positions),
        view,
        up,
        layout.viewport(),
        0.03,
    )
    .ok_or(PreviewError::Empty("no finite vertex to frame"))?;
    let mut heat = Heat::new(input, input_index, result)?;

    let size = options.size;
    let mut image = RgbImage::from_pixel(3 * size, size, Rgb(BACKGROUND));
    let panels = [
        Surface::appearance(input, cache),
        Surface::appearance(result, cache),
        Surface::new(
            result,
            Albedo::Scalar {
                values: std::mem::take(&mut heat.percents),
                scale: heat.scale_percent,
            },
        ),
    ];
    let ss = options.supersample;
    let g = rasterise_panel(input, "input", &camera, ss, size)?;
    shade_panel(&panels[0], &g, &camera, ss, size, &mut image, 0);
    drop(g);
    // The result's two panels see the same triangles at the same pixels.
    let g = rasterise_panel(result, "result", &camera, ss, size)?;
    for (i, surface) in panels.iter().enumerate().skip(1) {
        shade_panel(surface, &g, &camera, ss, size, &mut image, i as u32 * size);
    }
    draw_labels(&mut image, &layout, size, &heat);

    Ok(Preview {
        figures: PreviewFigures {
            width: image.width(),
            height: image.height(),
            view,
            up,
            scale_percent: heat.scale_percent,
            max_percent: heat.max_percent,
            p99_percent: heat.p99_percent,
            render_ms: start.elapsed().as_secs_f64() * 1e3,
        },
        image,
    })
}

/// The distance panel's figures: each result vertex's distance to the input in % of the
/// input's bounding-box diagonal, its maximum and 99th percentile, and the colour scale
/// (the 99th percentile rounded up to a readable number, at least [`MIN_SCALE_PERCENT`]).
struct Heat {
    percents: Vec<f64>,
    max_percent: f64,
    p99_percent: f64,
    scale_percent: f64,
    scale_label: String,
}

impl Heat {
    fn new(
        input: &Mesh,
        input_index: Option<&SurfaceIndex<'_>>,
        result: &Mesh,
    ) -> Result<Heat, PreviewError> {
        let distances = match input_index {
            Some(index) => {
                crate::metrics::surface::check_measurable(result, "result")?;
                crate::metrics::distance::vertex_distances_with(result, index)
            }
            None => crate::metrics::distance::vertex_distances(result, input)?,
        };
        let diagonal = input.bounding_box_diagonal();
        let percent = |d: f64| {
            if diagonal > 0.0 {
                100.0 * d / diagonal
            } else {
                0.0
            }
        };
        let max_percent = percent(distances.iter().copied().fold(0.0, f64::max));
        let p99_percent = percent(crate::metrics::percentile(&distances, 0.99));
        let (scale_percent, scale_label) = nice_ceil(p99_percent.max(MIN_SCALE_PERCENT));
        Ok(Heat {
            percents: distances.iter().map(|&d| percent(d)).collect(),
            max_percent,
            p99_percent,
            scale_percent,
            scale_label,
        })
    }
}

/// The colour bar never tops out below this (% of the diagonal). A remesh or a step that
/// leaves vertices on the input puts them there to rounding (10⁻¹⁴ %): a bar scaled to that
/// would colour rounding noise and label it "0.000000000000005%".
const MIN_SCALE_PERCENT: f64 = 0.001;

/// The panels' titles, the maximum distance and the colour bar.
fn draw_labels(image: &mut RgbImage, layout: &Layout, size: u32, heat: &Heat) {
    let k = layout.k;
    let titles = ["input", "result", "distance to input"];
    for (i, title) in titles.iter().enumerate() {
        font::draw_text(
            image,
            (i as u32 * size + 4 * k) as i64,
            (4 * k) as i64,
            title,
            k,
            INK,
        );
    }
    let max_label = format!("max {}%", significant(heat.max_percent));
    let right = 3 * size - 4 * k;
    font::draw_text(
        image,
        (right - font::text_width(&max_label, k)) as i64,
        (4 * k) as i64,
        &max_label,
        k,
        INK,
    );
    draw_colour_bar(image, layout, 2 * size, &format!("{}%", heat.scale_label));
}

/// What a panel's camera sees of `mesh`: for every sample (`ss` × `ss` per pixel of a
/// `size`² panel) the nearest triangle and where in it.
fn rasterise_panel(
    mesh: &Mesh,
    panel: &'static str,
    camera: &Camera,
    ss: u32,
    size: u32,
) -> Result<raster::GBuffer, PreviewError> {
    let cam = camera.scaled(ss as f64);
    let n = (size * ss) as usize;
    let vertices: Vec<[f64; 3]> = mesh
        .positions
        .par_iter()
        .map(|&p| cam.project(p).to_array())
        .collect();
    let triangles: Vec<[u32; 3]> = (0..mesh.triangles.len())
        .map(|t| mesh.triangle_vertices(t))
        .collect();
    let pixels = (n * n) as u64;
    raster::rasterise_within(&vertices, &triangles, n, n, MAX_OVERDRAW * pixels).map_err(|over| {
        PreviewError::Overdraw {
            panel,
            depth: over.tests.div_ceil(pixels),
        }
    })
}

/// Shades `surface` where `g` (its mesh through `camera`, [`rasterise_panel`]) shows it,
/// into the panel of `image` starting at column `x0`, averaging each pixel's samples.
fn shade_panel(
    surface: &Surface,
    g: &raster::GBuffer,
    camera: &Camera,
    ss: u32,
    size: u32,
    image: &mut RgbImage,
    x0: u32,
) {
    let n = (size * ss) as usize;
    let cam = camera.scaled(ss as f64);
    let towards_light = -cam.forward;
    let ss = ss as usize;
    let background = BACKGROUND.map(f64::from);
    // One output row per task: average the ss × ss samples of each pixel.
    let rows: Vec<Vec<[u8; 3]>> = (0..size as usize)
        .into_par_iter()
        .map(|row| {
            (0..size as usize)
                .map(|col| {
                    let mut sum = [0.0; 3];
                    for sy in 0..ss {
                        for sx in 0..ss {
                            let i = (row * ss + sy) * n + col * ss + sx;
                            let t = g.triangle[i];
                            let c = if t == raster::NONE {
                                background
                            } else {
                                let [b1, b2] = g.bary[i].map(f64::from);
                                let b = DVec3::new(1.0 - b1 - b2, b1, b2);
                                surface.shade(t as usize, b, towards_light)
                            };
                            for k in 0..3 {
                                sum[k] += c[k];
                            }
                        }
                    }
                    sum.map(|s| (s / (ss * ss) as f64).round().clamp(0.0, 255.0) as u8)
                })
                .collect()
        })
        .collect();
    for (row, pixels) in rows.iter().enumerate() {
        for (col, &p) in pixels.iter().enumerate() {
            image.put_pixel(x0 + col as u32, row as u32, Rgb(p));
        }
    }
}

/// The colour bar along the bottom band of the panel starting at column `x0`: the ramp,
/// ticks at quarters, "0" under its left end and `top` under its right end.
fn draw_colour_bar(image: &mut RgbImage, layout: &Layout, x0: u32, top: &str) {
    let k = layout.k;
    let left = x0 + 8 * k;
    let right = x0 + layout.size - 8 * k;
    let bar_top = layout.size - layout.legend_band + 4 * k;
    let bar_height = 6 * k;
    let width = right - left;
    for x in left..right {
        let t = (x - left) as f64 / (width - 1).max(1) as f64;
        let c = ramp::viridis(t).map(|v| v.round() as u8);
        for y in bar_top..bar_top + bar_height {
            image.put_pixel(x, y, Rgb(c));
        }
    }
    for q in 0..=4 {
        let x = (left + q * (width - 1) / 4).min(right - 1);
        for y in bar_top + bar_height..bar_top + bar_height + 3 * k {
            for dx in 0..k.min(right - x) {
                image.put_pixel(x + dx, y, INK);
            }
        }
    }
    let text_y = (bar_top + bar_height + 4 * k) as i64;
    font::draw_text(image, left as i64, text_y, "0", k, INK);
    let w = font::text_width(top, k);
    font::draw_text(image, (right - w) as i64, text_y, top, k, INK);
}

/// The smallest of 1, 2, 2.5, 5 × 10^e not below `x` (a tidy top for the colour bar), with
/// its label; 0 and non-finite read as 0.
fn nice_ceil(x: f64) -> (f64, String) {
    if !(x.is_finite() && x > 0.0) {
        return (0.0, "0".into());
    }
    // Start a decade low: log10 of an exact power of ten may round either way.
    let mut e = x.log10().floor() as i32 - 1;
    loop {
        for (m, digits, shift) in [(1.0, "1", 0), (2.0, "2", 0), (2.5, "25", 1), (5.0, "5", 0)] {
            let value = m * 10f64.powi(e);
            if value >= x * (1.0 - 1e-12) {
                return (value, decimal_label(digits, e - shift));
            }
        }
        e += 1;
    }
}

/// `digits` × 10^exponent written out in decimal ("25", -3 → "0.025").
fn decimal_label(digits: &str, exponent: i32) -> String {
    if exponent >= 0 {
        format!("{digits}{}", "0".repeat(exponent as usize))
    } else {
        let shift = (-exponent) as usize;
        let padded = format!(
            "{}{digits}",
            "0".repeat(shift.saturating_sub(digits.len()) + 1)
        );
        let (int, frac) = padded.split_at(padded.len() - shift);
        format!("{int}.{frac}")
    }
}

/// Two significant digits, in plain decimal.
fn significant(x: f64) -> String {
    if !(x.is_finite() && x > 0.0) {
        return "0".into();
    }
    let decimals = (1 - x.log10().floor() as i32).max(0) as usize;
    format!("{x:.decimals$}")
}

/// Writes the picture as PNG (to be published with the rest of the output).
pub fn write_png(image: &RgbImage, path: &Path) -> Result<(), PreviewError> {
    image
        .save_with_format(path, image::ImageFormat::Png)
        .map_err(|e| PreviewError::Write {
            path: path.to_path_buf(),
            message: e.to_string(),
        })
}

#[cfg(test)]
mod tests;
