//! A z-buffered triangle rasteriser for orthographic views. It only finds, for every pixel,
//! the nearest triangle and the barycentric coordinates of the pixel centre in it (a
//! "G-buffer"); shading happens afterwards, once per visible pixel.
//!
//! Orthographic projection is affine, so barycentrics measured in the image are the
//! barycentrics on the triangle: no perspective correction is needed.
//!
//! Coverage follows the top-left rule: a pixel centre exactly on an edge shared by two
//! triangles belongs to exactly one of them, so a closed mesh has neither gaps nor pixels
//! drawn twice. The depth test is strict (`<`), and every row strip draws its triangles in
//! index order, so on equal depth the lower triangle index wins whatever the thread count:
//! the image is deterministic.

use rayon::prelude::*;

/// The marker for "no triangle" in [`GBuffer::triangle`].
pub const NONE: u32 = u32::MAX;

/// Rows per parallel strip.
const STRIP_ROWS: usize = 16;

/// Per pixel: the nearest triangle, its depth and the barycentric weights of its corners
/// 1 and 2 at the pixel centre (corner 0's is `1 - b1 - b2`).
#[derive(Debug, Clone)]
pub struct GBuffer {
    pub width: usize,
    pub height: usize,
    pub depth: Vec<f32>,
    pub triangle: Vec<u32>,
    pub bary: Vec<[f32; 2]>,
    /// Pixel centres that passed a coverage test, counted before the depth test (tests).
    pub fragments: u64,
}

/// 2D edge function: twice the signed area of (a, b, p); positive when p is on the
/// interior side of a → b for a triangle of positive area (rows grow downwards).
#[inline]
fn edge(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// Whether a pixel centre on edge a → b (of a positive-area triangle) belongs to the
/// triangle: the top edge (horizontal, interior below) and the left edges (interior to
/// their right) own their centres, the others do not.
#[inline]
fn owns_edge(a: [f64; 2], b: [f64; 2]) -> bool {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    (dy == 0.0 && dx > 0.0) || dy < 0.0
}

/// The pixel tests that drawing would make pass the caller's budget: at least `tests`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OverBudget {
    pub tests: u64,
}

/// Draws the triangles (corner indices into `vertices`, each vertex (column, row, depth)
/// in pixels) into a `width` × `height` G-buffer. Triangles that are not finite or have
/// no area in the image are skipped, as are corners with out-of-range indices.
pub fn rasterise(
    vertices: &[[f64; 3]],
    triangles: &[[u32; 3]],
    width: usize,
    height: usize,
) -> GBuffer {
    match rasterise_within(vertices, triangles, width, height, u64::MAX) {
        Ok(g) => g,
        Err(_) => unreachable!("no count of pixel tests passes u64::MAX"),
    }
}

/// [`rasterise`], refused before any pixel is drawn when the pixel tests it would make
/// (each triangle's clipped bounding box, see [`box_tests`]) pass `max_tests`. The count
/// is taken while the triangles are binned, and binning stops as soon as it passes.
pub fn rasterise_within(
    vertices: &[[f64; 3]],
    triangles: &[[u32; 3]],
    width: usize,
    height: usize,
    max_tests: u64,
) -> Result<GBuffer, OverBudget> {
    let pixels = width * height;
    let mut depth = vec![f32::INFINITY; pixels];
    let mut triangle = vec![NONE; pixels];
    let mut bary = vec![[0.0f32; 2]; pixels];
    if pixels == 0 {
        return Ok(GBuffer {
            width,
            height,
            depth,
            triangle,
            bary,
            fragments: 0,
        });
    }
    // Bin the triangles into row strips, in index order (sequential: the order matters).
    let strips = height.div_ceil(STRIP_ROWS);
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); strips];
    let mut tests = 0u64;
    for (t, corners) in triangles.iter().enumerate() {
        let Some(rows) = row_span(vertices, corners, height) else {
            continue;
        };
        let own_tests = box_tests(vertices, corners, rows, width);
        tests = tests.saturating_add(own_tests);
        if tests > max_tests {
            return Err(OverBudget { tests });
        }
        if own_tests == 0 {
            continue; // no pixel centre in its box: it would draw nothing
        }
        for bin in &mut bins[rows.0 / STRIP_ROWS..=rows.1 / STRIP_ROWS] {
            bin.push(t as u32);
        }
    }
    let fragments: u64 = depth
        .par_chunks_mut(STRIP_ROWS * width)
        .zip(triangle.par_chunks_mut(STRIP_ROWS * width))
        .zip(bary.par_chunks_mut(STRIP_ROWS * width))
        .zip(bins.par_iter())
        .enumerate()
        .map(|(s, (((depth, triangle), bary), bin))| {
            let mut strip = Strip {
                width,
                row0: s * STRIP_ROWS,
                rows: depth.len() / width,
                depth,
                triangle,
                bary,
                fragments: 0,
            };
            for &t in bin {
                let [a, b, c] = triangles[t as usize];
                let v = |i: u32| vertices[i as usize];
                strip.draw(t, [v(a), v(b), v(c)]);
            }
            strip.fragments
        })
        .sum();
    Ok(GBuffer {
        width,
        height,
        depth,
        triangle,
        bary,
        fragments,
    })
}

/// The pixel tests drawing one triangle may make: the pixel centres of its bounding box
/// clipped to the image (its `rows` from [`row_span`], its columns here). A mesh drawn
/// once over its silhouette makes a few times the image's pixels in all; an overlapping
/// triangle soup makes thousands of times.
fn box_tests(vertices: &[[f64; 3]], corners: &[u32; 3], rows: (usize, usize), width: usize) -> u64 {
    let xs = corners.map(|i| vertices[i as usize][0]);
    let lo = (xs.iter().copied().fold(f64::INFINITY, f64::min) - 0.5)
        .ceil()
        .max(0.0);
    let hi = (xs.iter().copied().fold(f64::NEG_INFINITY, f64::max) - 0.5)
        .floor()
        .min(width as f64 - 1.0);
    let columns = if lo <= hi { (hi - lo) as u64 + 1 } else { 0 };
    columns * (rows.1 - rows.0 + 1) as u64
}

/// The rows (inclusive) whose pixel centres the triangle may cover, `None` if none or if
/// the triangle is unusable.
fn row_span(vertices: &[[f64; 3]], corners: &[u32; 3], height: usize) -> Option<(usize, usize)> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for &i in corners {
        let v = vertices.get(i as usize)?;
        if !v.iter().all(|x| x.is_finite()) {
            return None;
        }
        lo = lo.min(v[1]);
        hi = hi.max(v[1]);
    }
    // Row r's centre is at r + 0.5.
    let first = (lo - 0.5).ceil().max(0.0);
    let last = (hi - 0.5).floor().min(height as f64 - 1.0);
    (first <= last).then_some((first as usize, last as usize))
}

/// One strip of rows, owned by one thread.
struct Strip<'a> {
    width: usize,
    row0: usize,
    rows: usize,
    depth: &'a mut [f32],
    triangle: &'a mut [u32],
    bary: &'a mut [[f32; 2]],
    fragments: u64,
}

impl Strip<'_> {
    fn draw(&mut self, t: u32, corners: [[f64; 3]; 3]) {
        let p = corners.map(|v| [v[0], v[1]]);
        // The pixel centres of the bounding box within the strip first: most triangles of
        // a scan drawn at preview size cover one centre or none, and those with none need
        // nothing else (the same pixels as testing their area first).
        let (xmin, xmax) = (
            p.iter().map(|v| v[0]).fold(f64::INFINITY, f64::min),
            p.iter().map(|v| v[0]).fold(f64::NEG_INFINITY, f64::max),
        );
        let (ymin, ymax) = (
            p.iter().map(|v| v[1]).fold(f64::INFINITY, f64::min),
            p.iter().map(|v| v[1]).fold(f64::NEG_INFINITY, f64::max),
        );
        let col0 = (xmin - 0.5).ceil().max(0.0);
        let col1 = (xmax - 0.5).floor().min(self.width as f64 - 1.0);
        let row0 = (ymin - 0.5).ceil().max(self.row0 as f64);
        let row1 = (ymax - 0.5)
            .floor()
            .min((self.row0 + self.rows) as f64 - 1.0);
        if !(col0 <= col1 && row0 <= row1) {
            return;
        }
        let area = edge(p[0], p[1], p[2]);
        if area == 0.0 || !area.is_finite() {
            return;
        }
        // Walk a positive-area order; `order[k]` is the original corner at position k.
        let order = if area > 0.0 { [0, 1, 2] } else { [0, 2, 1] };
        let q = order.map(|k| p[k]);
        let area = area.abs();
        let owns = [
            owns_edge(q[1], q[2]),
            owns_edge(q[2], q[0]),
            owns_edge(q[0], q[1]),
        ];
        let z = order.map(|k| corners[k][2]);
        for row in row0 as usize..=row1 as usize {
            let y = row as f64 + 0.5;
            for col in col0 as usize..=col1 as usize {
                let c = [col as f64 + 0.5, y];
                let w = [
                    edge(q[1], q[2], c),
                    edge(q[2], q[0], c),
                    edge(q[0], q[1], c),
                ];
                let inside = (0..3).all(|k| w[k] > 0.0 || (w[k] == 0.0 && owns[k]));
                if !inside {
                    continue;
                }
                self.fragments += 1;
                let b = w.map(|x| x / area);
                let d = (b[0] * z[0] + b[1] * z[1] + b[2] * z[2]) as f32;
                let i = (row - self.row0) * self.width + col;
                if d < self.depth[i] {
                    self.depth[i] = d;
                    self.triangle[i] = t;
                    // Back to the original corner order.
                    let mut original = [0.0; 3];
                    for k in 0..3 {
                        original[order[k]] = b[k];
                    }
                    self.bary[i] = [original[1] as f32, original[2] as f32];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A square from (x0, y0) to (x1, y1) in pixels, as two triangles sharing a diagonal.
    fn square(x0: f64, y0: f64, x1: f64, y1: f64, z: f64) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        (
            vec![[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    #[test]
    fn a_square_covers_exactly_its_pixels_once() {
        // Pixel-aligned: 8 x 8 pixels, the diagonal runs through pixel centres.
        let (v, t) = square(2.0, 3.0, 10.0, 11.0, 1.0);
        let g = rasterise(&v, &t, 16, 16);
        let covered = g.triangle.iter().filter(|&&t| t != NONE).count();
        assert_eq!(covered, 64);
        assert_eq!(g.fragments, 64, "no pixel drawn twice, none missed");
        for row in 0..16 {
            for col in 0..16 {
                let inside = (2..10).contains(&col) && (3..11).contains(&row);
                assert_eq!(g.triangle[row * 16 + col] != NONE, inside, "{col} {row}");
            }
        }
        // Either winding, the same coverage (two-sided).
        let flipped: Vec<[u32; 3]> = t.iter().map(|&[a, b, c]| [a, c, b]).collect();
        let g2 = rasterise(&v, &flipped, 16, 16);
        assert_eq!(g2.fragments, 64);
        assert_eq!(g2.triangle, g.triangle);
    }

    #[test]
    fn barycentrics_interpolate_exactly() {
        let v = vec![[0.0, 0.0, 0.0], [8.0, 0.0, 8.0], [0.0, 8.0, 16.0]];
        let g = rasterise(&v, &[[0, 1, 2]], 8, 8);
        // Pixel (1, 2): centre (1.5, 2.5): weights of corner 1 and 2 are x/8 and y/8.
        let i = 2 * 8 + 1;
        assert_eq!(g.triangle[i], 0);
        assert_eq!(g.bary[i], [1.5 / 8.0, 2.5 / 8.0]);
        assert_eq!(g.depth[i], 1.5 + 2.0 * 2.5);
    }

    #[test]
    fn the_nearer_triangle_wins_whatever_the_order() {
        let (mut v, mut t) = square(0.0, 0.0, 8.0, 8.0, 5.0);
        let (v2, t2) = square(2.0, 2.0, 6.0, 6.0, 1.0);
        t.extend(t2.iter().map(|c| c.map(|i| i + 4)));
        v.extend(v2);
        let g = rasterise(&v, &t, 8, 8);
        assert!(g.triangle[3 * 8 + 3] >= 2 && g.depth[3 * 8 + 3] == 1.0);
        assert!(g.triangle[0] < 2 && g.depth[0] == 5.0);
        // The same with the near square drawn first.
        let reversed: Vec<[u32; 3]> = t.iter().rev().copied().collect();
        let g2 = rasterise(&v, &reversed, 8, 8);
        assert_eq!(g2.depth, g.depth);
        assert!(g2.triangle[3 * 8 + 3] < 2);
    }

    #[test]
    fn junk_is_skipped_and_strips_join() {
        let v = vec![
            [0.0, 0.0, 0.0],
            [f64::NAN, 1.0, 0.0],
            [5.0, 5.0, 0.0],
            [1.0, 1.0, 0.0],
        ];
        // Non-finite corner, out-of-range index, zero area.
        let g = rasterise(&v, &[[0, 1, 2], [0, 9, 2], [0, 3, 2]], 8, 8);
        assert_eq!(g.fragments, 0);
        // A tall triangle across several strips: coverage equals its area.
        let (v, t) = square(0.0, 0.0, 4.0, 100.0, 0.0);
        let g = rasterise(&v, &t, 4, 100);
        assert_eq!(g.fragments, 400);
        assert!(rasterise(&v, &t, 0, 0).triangle.is_empty());
    }
}
