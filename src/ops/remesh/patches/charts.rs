//! The cells' harmonic charts (remeshing thesis §4.2 c and §4.3, reading P9).
//!
//! 1. **Cut** (§4.2 c): every input triangle whose vertices lie in two or three cells is split
//!    along the cell borders: a new point at the middle of each edge between two cells, and
//!    the centroid of a triangle with three cells, which is a cell corner (one region's
//!    centre). Each cell is then a piece of surface of its own, which must be a disc.
//! 2. **Map** (§4.3 step 1, after Eck et al. 1995): each cell onto a regular k-gon on the unit
//!    circle, one polygon corner per cell corner (region) in the order they go round the
//!    cell, the border points between two corners spaced along the polygon side by arc length
//!    (chord length), and the inside by the harmonic map with **mean-value weights** (Floater
//!    2003), symmetrised. The weights are positive, so by Tutte's and Floater's theorem the
//!    map of a disc onto a convex polygon is one-to-one: no parameter triangle folds over (the
//!    thesis gives no weights; Eck's cotangent weights turn negative on obtuse triangles and
//!    can fold, which made the thesis' inverse look-ups ambiguous on noisy scans).
//!
//! In a cell's chart, the thesis' lines from the cell centre to the middles of its cuts are
//! straight (§4.3.1 tunnels them along exactly those segments), so each quad of the
//! three-quad split (reading P3) is, in its cell's chart, the kite of the polygon's centre,
//! the middles of the two sides at a corner, and that corner. Reading P9: the quads are
//! sampled in these charts directly instead of tunnelling the lines and building a second
//! harmonic map per quad region: the same lines, no splitting of the surface along them,
//! and every Doo–Sabin point lands on its own cell's surface (a closest-point projection
//! could snap to the other side of a thin part).

use super::layout::Layout;
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use std::collections::HashMap;

/// One cell's chart: its piece of surface (local vertex ids), the 2D position of every
/// vertex, the input triangle each piece triangle was cut from, and the regions at its
/// polygon's corners in counter-clockwise order.
pub struct Chart {
    xyz: Vec<DVec3>,
    uv: Vec<DVec2>,
    triangles: Vec<[u32; 3]>,
    parent: Vec<u32>,
    corners: Vec<u32>,
    grid: Lookup,
}

/// All cells' charts and, per region, the corner index it has in each of its three cells'
/// charts.
pub struct Charts {
    pub cells: Vec<Chart>,
    region_corner: Vec<[u32; 3]>,
    /// Parameter triangles with zero or negative area after the solve (0 unless the solve
    /// failed to converge on a degenerate cell).
    pub folded: usize,
}

/// A surface point found through a chart: the position and the input triangle it lies on.
pub struct Lifted {
    pub point: DVec3,
    pub triangle: u32,
}

impl Charts {
    /// The surface point at bilinear parameter (u, v) of the quad of region `region` in its
    /// `k`-th cell (the cell `layout.regions[region][k]`): the quad whose corners are the
    /// chart's centre, the middle of the side before the region's corner, the corner, and
    /// the middle of the side after it (the order of `quads`' coarse quads).
    pub fn quad_point(&self, layout: &Layout, region: usize, k: usize, u: f64, v: f64) -> Lifted {
        let cell = layout.regions[region][k] as usize;
        let chart = &self.cells[cell];
        let j = self.region_corner[region][k] as usize;
        let sides = chart.corners.len();
        let corner = |i: usize| polygon_corner(i % sides, sides);
        let at = corner(j);
        let before = (corner(j + sides - 1) + at) * 0.5;
        let after = (at + corner(j + 1)) * 0.5;
        let q = [DVec2::ZERO, before, at, after];
        let p = q[0] * ((1.0 - u) * (1.0 - v))
            + q[1] * (u * (1.0 - v))
            + q[2] * (u * v)
            + q[3] * ((1.0 - u) * v);
        chart.lift(p)
    }
}

impl Chart {
    /// The surface point at chart position `p`, by the barycentric coordinates of the
    /// parameter triangle that contains it.
    fn lift(&self, p: DVec2) -> Lifted {
        let t = self.grid.locate(p, &self.uv, &self.triangles);
        let tri = self.triangles[t];
        let b = barycentric(p, tri.map(|v| self.uv[v as usize]));
        let point = self.xyz[tri[0] as usize] * b[0]
            + self.xyz[tri[1] as usize] * b[1]
            + self.xyz[tri[2] as usize] * b[2];
        Lifted {
            point,
            triangle: self.parent[t],
        }
    }
}

/// Corner `i` of the regular `k`-gon on the unit circle.
fn polygon_corner(i: usize, k: usize) -> DVec2 {
    let a = std::f64::consts::TAU * i as f64 / k as f64;
    DVec2::new(a.cos(), a.sin())
}

/// Cuts the surface along the cell borders and maps every cell. `label` is each vertex's
/// cell, `triangles` the input triangles the layout was built over, `ids` each one's index in
/// the input mesh. Fails with the cells that are not discs (the layout's seed retry splits
/// them).
pub fn build(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    ids: &[u32],
    label: &[u32],
    layout: &Layout,
) -> Result<Charts, Vec<u32>> {
    let cut = Cut::new(positions, triangles, label, layout);
    let built: Vec<Result<Chart, ()>> = cut
        .pieces
        .par_iter()
        .map(|pieces| chart_of(&cut, pieces, ids))
        .collect();
    let bad: Vec<u32> = (0..built.len() as u32)
        .filter(|&c| built[c as usize].is_err())
        .collect();
    if !bad.is_empty() {
        return Err(bad);
    }
    let cells: Vec<Chart> = built.into_iter().flatten().collect();
    let mut region_corner = vec![[u32::MAX; 3]; layout.regions.len()];
    for (c, chart) in cells.iter().enumerate() {
        for (j, &r) in chart.corners.iter().enumerate() {
            let k = layout.regions[r as usize]
                .iter()
                .position(|&l| l as usize == c)
                .ok_or_else(|| vec![c as u32])?;
            region_corner[r as usize][k] = j as u32;
        }
    }
    if let Some(r) = region_corner.iter().position(|rc| rc.contains(&u32::MAX)) {
        return Err(layout.regions[r].to_vec());
    }
    let folded = cells.iter().map(Chart::folded).sum();
    Ok(Charts {
        cells,
        region_corner,
        folded,
    })
}

/// The surface cut along the cell borders (§4.2 c): the points (input vertices, then the
/// middles of edges between two cells, then the centroids of triangles with three), each
/// cell's triangles over them with the input triangle they come from, and the region of
/// each centroid.
struct Cut {
    points: Vec<DVec3>,
    first_corner: u32,
    pieces: Vec<Vec<([u32; 3], u32)>>,
    /// The region of centroid `first_corner + i`.
    corner_region: Vec<u32>,
}

impl Cut {
    fn new(positions: &[DVec3], triangles: &[[u32; 3]], label: &[u32], layout: &Layout) -> Cut {
        let mut points = positions.to_vec();
        let mut middles: HashMap<(u32, u32), u32> = HashMap::new();
        let mut pieces: Vec<Vec<([u32; 3], u32)>> = vec![Vec::new(); layout.cells];
        // Middles first, so that every middle is numbered before any centroid.
        for tri in triangles {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                if label[a as usize] != label[b as usize] {
                    middles.entry((a.min(b), a.max(b))).or_insert_with(|| {
                        points.push((positions[a as usize] + positions[b as usize]) * 0.5);
                        points.len() as u32 - 1
                    });
                }
            }
        }
        let first_corner = points.len() as u32;
        let mut corner_region = Vec::with_capacity(layout.corner_triangle.len());
        let region_of: HashMap<u32, u32> = layout
            .corner_triangle
            .iter()
            .enumerate()
            .map(|(r, &t)| (t, r as u32))
            .collect();
        let mid = |a: u32, b: u32| middles[&(a.min(b), a.max(b))];
        for (t, tri) in triangles.iter().enumerate() {
            let parent = t as u32;
            let l = tri.map(|v| label[v as usize]);
            if l[0] == l[1] && l[1] == l[2] {
                pieces[l[0] as usize].push((*tri, parent));
            } else if l[0] != l[1] && l[1] != l[2] && l[0] != l[2] {
                // Each vertex keeps the quad (vertex, middle, centroid, middle), cut along
                // the diagonal from the vertex so that every triangle has an inside vertex.
                let g = points.len() as u32;
                points.push(
                    (positions[tri[0] as usize]
                        + positions[tri[1] as usize]
                        + positions[tri[2] as usize])
                        / 3.0,
                );
                corner_region.push(region_of[&parent]);
                for k in 0..3 {
                    let (a, b, c) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
                    let cell = &mut pieces[l[k] as usize];
                    cell.push(([a, mid(a, b), g], parent));
                    cell.push(([a, g, mid(c, a)], parent));
                }
            } else {
                // Two vertices a, b in one cell, c in another: c keeps the triangle at its
                // corner, a and b the quad, cut along its shorter diagonal.
                let k = (0..3).find(|&k| l[k] == l[(k + 1) % 3]).unwrap_or(0);
                let (a, b, c) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
                let (mbc, mca) = (mid(b, c), mid(c, a));
                for t in super::split_quad([a, b, mbc, mca], |v| points[v as usize]) {
                    pieces[l[k] as usize].push((t, parent));
                }
                pieces[l[(k + 2) % 3] as usize].push(([mbc, c, mca], parent));
            }
        }
        Cut {
            points,
            first_corner,
            pieces,
            corner_region,
        }
    }
}

/// One cell's chart, or `Err` when its piece is not a disc with at least three corners.
fn chart_of(cut: &Cut, pieces: &[([u32; 3], u32)], ids: &[u32]) -> Result<Chart, ()> {
    // Local vertex ids in ascending global order: deterministic.
    let mut global: Vec<u32> = pieces.iter().flat_map(|p| p.0).collect();
    global.sort_unstable();
    global.dedup();
    let local = |g: u32| {
        global
            .binary_search(&g)
            .map(|i| i as u32)
            .unwrap_or(u32::MAX)
    };
    let triangles: Vec<[u32; 3]> = pieces.iter().map(|p| p.0.map(local)).collect();
    let border = border_loop(global.len(), &triangles).ok_or(())?;
    // Rotate the loop to start at a corner; the corners in loop order.
    let is_corner = |v: u32| global[v as usize] >= cut.first_corner;
    let start = border.iter().position(|&v| is_corner(v)).ok_or(())?;
    let border: Vec<u32> = border[start..]
        .iter()
        .chain(&border[..start])
        .copied()
        .collect();
    let corners: Vec<u32> = border
        .iter()
        .filter(|&&v| is_corner(v))
        .map(|&v| cut.corner_region[(global[v as usize] - cut.first_corner) as usize])
        .collect();
    if corners.len() < 3 {
        return Err(());
    }
    let xyz: Vec<DVec3> = global.iter().map(|&g| cut.points[g as usize]).collect();
    let mut uv = vec![DVec2::ZERO; xyz.len()];
    let mut on_border = vec![false; xyz.len()];
    place_border(&border, &xyz, &is_corner, corners.len(), &mut uv);
    for &v in &border {
        on_border[v as usize] = true;
    }
    harmonic_inside(&xyz, &triangles, &on_border, &mut uv);
    let grid = Lookup::new(&uv, &triangles);
    Ok(Chart {
        xyz,
        uv,
        parent: pieces.iter().map(|p| ids[p.1 as usize]).collect(),
        triangles,
        corners,
        grid,
    })
}

/// The border of a piece as one loop in the triangles' direction (counter-clockwise round
/// the piece seen from outside), or `None` when the piece is not a disc: V − E + F ≠ 1, a
/// border vertex passed twice, or more than one loop.
fn border_loop(vertices: usize, triangles: &[[u32; 3]]) -> Option<Vec<u32>> {
    let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * triangles.len());
    for t in triangles {
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    if directed.values().any(|&n| n != 1) {
        return None;
    }
    let mut next: HashMap<u32, u32> = HashMap::new();
    for &(a, b) in directed.keys() {
        if !directed.contains_key(&(b, a)) && next.insert(a, b).is_some() {
            return None;
        }
    }
    let edges = (directed.len() + next.len()) / 2;
    if vertices as i64 - edges as i64 + triangles.len() as i64 != 1 || next.len() < 3 {
        return None;
    }
    let first = *next.keys().min()?;
    let mut border = vec![first];
    let mut v = next[&first];
    while v != first {
        if border.len() > next.len() {
            return None;
        }
        border.push(v);
        v = *next.get(&v)?;
    }
    (border.len() == next.len()).then_some(border)
}

/// Places the border loop (starting at a corner) on the regular polygon: corner j at
/// polygon corner j, the points between two corners along the side by arc length.
fn place_border(
    border: &[u32],
    xyz: &[DVec3],
    is_corner: &dyn Fn(u32) -> bool,
    sides: usize,
    uv: &mut [DVec2],
) {
    let mut j = 0;
    let mut i = 0;
    while i < border.len() {
        // The run from this corner to the next (exclusive), with its arc lengths.
        let mut end = i + 1;
        while end < border.len() && !is_corner(border[end]) {
            end += 1;
        }
        let at = |k: usize| xyz[border[k % border.len()] as usize];
        let mut s = vec![0.0; end - i + 1];
        for k in i..end {
            s[k - i + 1] = s[k - i] + at(k).distance(at(k + 1));
        }
        let (a, b) = (
            polygon_corner(j % sides, sides),
            polygon_corner((j + 1) % sides, sides),
        );
        let total = s[end - i];
        for k in i..end {
            let t = if total > 0.0 {
                s[k - i] / total
            } else {
                (k - i) as f64 / (end - i) as f64
            };
            uv[border[k] as usize] = a + (b - a) * t;
        }
        j += 1;
        i = end;
    }
}

/// tan(α/2) for the angle α between `a` and `b`: |a×b| / (|a||b| + a·b).
fn half_tan(a: DVec3, b: DVec3) -> f64 {
    let denominator = a.length() * b.length() + a.dot(b);
    a.cross(b).length() / denominator
}

/// The inside vertices' chart positions: the harmonic map with symmetrised mean-value
/// weights w_ij = ½(λ_ij + λ_ji), λ_ij = (tan(α/2) + tan(β/2)) / |x_i − x_j| with α, β the
/// angles at i next to edge ij (Floater 2003). Solved by conjugate gradients, the system
/// being symmetric positive definite.
fn harmonic_inside(xyz: &[DVec3], triangles: &[[u32; 3]], on_border: &[bool], uv: &mut [DVec2]) {
    let mut lambda: Vec<(u32, u32, f64)> = Vec::with_capacity(6 * triangles.len());
    for t in triangles {
        for k in 0..3 {
            let (i, j, l) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            let (pi, pj, pl) = (xyz[i as usize], xyz[j as usize], xyz[l as usize]);
            let h = half_tan(pj - pi, pl - pi);
            lambda.push((i, j, h / pi.distance(pj)));
            lambda.push((i, l, h / pi.distance(pl)));
        }
    }
    // Symmetrise: both directions of every edge under one key.
    let mut weight: HashMap<(u32, u32), f64> = HashMap::with_capacity(lambda.len() / 2);
    for (i, j, w) in lambda {
        // A degenerate triangle gives 0, NaN or ∞; a tiny positive weight keeps the map
        // one-to-one and the system definite.
        let w = if w.is_finite() && w > 0.0 { w } else { 1e-12 };
        *weight.entry((i.min(j), i.max(j))).or_default() += 0.5 * w;
    }
    let inside: Vec<u32> = (0..xyz.len() as u32)
        .filter(|&v| !on_border[v as usize])
        .collect();
    if inside.is_empty() {
        return;
    }
    let mut row = vec![u32::MAX; xyz.len()];
    for (r, &v) in inside.iter().enumerate() {
        row[v as usize] = r as u32;
    }
    let n = inside.len();
    let mut diagonal = vec![0.0; n];
    let mut rhs = vec![DVec2::ZERO; n];
    let mut entries: Vec<(u32, u32, f64)> = Vec::new();
    let mut keys: Vec<_> = weight.into_iter().collect();
    keys.sort_unstable_by_key(|e| e.0);
    for ((a, b), w) in keys {
        for (x, y) in [(a, b), (b, a)] {
            let rx = row[x as usize];
            if rx == u32::MAX {
                continue;
            }
            diagonal[rx as usize] += w;
            let ry = row[y as usize];
            if ry == u32::MAX {
                rhs[rx as usize] += uv[y as usize] * w;
            } else {
                entries.push((rx, ry, w));
            }
        }
    }
    let solution = Sparse::new(n, entries, diagonal).solve(&rhs);
    for (r, &v) in inside.iter().enumerate() {
        uv[v as usize] = solution[r];
    }
}

/// The symmetric matrix D − W of the inside vertices, off-diagonal entries by row.
struct Sparse {
    start: Vec<usize>,
    column: Vec<u32>,
    value: Vec<f64>,
    diagonal: Vec<f64>,
}

impl Sparse {
    fn new(n: usize, mut entries: Vec<(u32, u32, f64)>, diagonal: Vec<f64>) -> Sparse {
        entries.sort_unstable_by_key(|e| (e.0, e.1));
        let mut start = vec![0usize; n + 1];
        for e in &entries {
            start[e.0 as usize + 1] += 1;
        }
        for r in 0..n {
            start[r + 1] += start[r];
        }
        Sparse {
            start,
            column: entries.iter().map(|e| e.1).collect(),
            value: entries.iter().map(|e| e.2).collect(),
            diagonal,
        }
    }

    /// `out` = A·x; returns x·(A·x), summed in row order.
    fn times(&self, x: &[DVec2], out: &mut [DVec2]) -> DVec2 {
        let mut xax = DVec2::ZERO;
        for (r, o) in out.iter_mut().enumerate() {
            let mut s = x[r] * self.diagonal[r];
            for k in self.start[r]..self.start[r + 1] {
                s -= x[self.column[k] as usize] * self.value[k];
            }
            *o = s;
            xax += x[r] * s;
        }
        xax
    }

    /// Jacobi-preconditioned conjugate gradients from 0, both coordinates at once (each
    /// with its own step lengths), to a relative residual of 1e-9 (or 4n + 100 iterations).
    /// One pass over the vectors per step besides the product: the update of x and r, the
    /// preconditioned residual and both dot products together.
    fn solve(&self, b: &[DVec2]) -> Vec<DVec2> {
        let n = b.len();
        let mut x = vec![DVec2::ZERO; n];
        let mut r = b.to_vec();
        let mut z: Vec<DVec2> = r.iter().zip(&self.diagonal).map(|(r, d)| *r / *d).collect();
        let mut p = z.clone();
        let mut rz = r.iter().zip(&z).fold(DVec2::ZERO, |s, (r, z)| s + *r * *z);
        let mut rr = r.iter().fold(DVec2::ZERO, |s, r| s + *r * *r);
        let goal = rr.max(DVec2::splat(f64::MIN_POSITIVE)) * 1e-18;
        let mut ap = vec![DVec2::ZERO; n];
        for _ in 0..4 * n + 100 {
            if rr.x <= goal.x && rr.y <= goal.y {
                break;
            }
            let pap = self.times(&p, &mut ap);
            // A converged coordinate stops moving (0/0 would be NaN).
            let alpha = DVec2::new(
                if pap.x > 0.0 { rz.x / pap.x } else { 0.0 },
                if pap.y > 0.0 { rz.y / pap.y } else { 0.0 },
            );
            let (mut next, mut squares) = (DVec2::ZERO, DVec2::ZERO);
            for k in 0..n {
                x[k] += alpha * p[k];
                r[k] -= alpha * ap[k];
                z[k] = r[k] / self.diagonal[k];
                next += r[k] * z[k];
                squares += r[k] * r[k];
            }
            rr = squares;
            let beta = DVec2::new(
                if rz.x > 0.0 { next.x / rz.x } else { 0.0 },
                if rz.y > 0.0 { next.y / rz.y } else { 0.0 },
            );
            rz = next;
            for k in 0..n {
                p[k] = z[k] + beta * p[k];
            }
        }
        x
    }
}

impl Chart {
    /// Parameter triangles of zero or negative signed area.
    fn folded(&self) -> usize {
        self.triangles
            .iter()
            .filter(|t| {
                let [a, b, c] = t.map(|v| self.uv[v as usize]);
                (b - a).perp_dot(c - a) <= 0.0
            })
            .count()
    }
}

/// Barycentric coordinates of `p` in the 2D triangle `t` (the centroid's when degenerate).
fn barycentric(p: DVec2, t: [DVec2; 3]) -> [f64; 3] {
    let area = (t[1] - t[0]).perp_dot(t[2] - t[0]);
    if area.abs() <= f64::MIN_POSITIVE {
        return [1.0 / 3.0; 3];
    }
    let b1 = (p - t[0]).perp_dot(t[2] - t[0]) / area;
    let b2 = (t[1] - t[0]).perp_dot(p - t[0]) / area;
    [1.0 - b1 - b2, b1, b2]
}

/// A uniform grid over [−1, 1]² listing the parameter triangles whose bounding box meets
/// each square: point location in a chart.
struct Lookup {
    size: usize,
    start: Vec<u32>,
    items: Vec<u32>,
}

impl Lookup {
    fn new(uv: &[DVec2], triangles: &[[u32; 3]]) -> Lookup {
        let size = ((triangles.len() as f64 / 2.0).sqrt().ceil() as usize).clamp(1, 256);
        let squares = |t: &[u32; 3]| {
            let p = t.map(|v| uv[v as usize]);
            let lo = p[0].min(p[1]).min(p[2]);
            let hi = p[0].max(p[1]).max(p[2]);
            let (x0, y0) = Self::square_of(lo, size);
            let (x1, y1) = Self::square_of(hi, size);
            (x0..=x1).flat_map(move |x| (y0..=y1).map(move |y| y * size + x))
        };
        let mut start = vec![0u32; size * size + 1];
        for t in triangles {
            for s in squares(t) {
                start[s + 1] += 1;
            }
        }
        for s in 0..size * size {
            start[s + 1] += start[s];
        }
        let mut fill = start.clone();
        let mut items = vec![0u32; start[size * size] as usize];
        for (i, t) in triangles.iter().enumerate() {
            for s in squares(t) {
                items[fill[s] as usize] = i as u32;
                fill[s] += 1;
            }
        }
        Lookup { size, start, items }
    }

    fn square_of(p: DVec2, size: usize) -> (usize, usize) {
        let f = |x: f64| (((x + 1.0) * 0.5 * size as f64).floor().max(0.0) as usize).min(size - 1);
        (f(p.x), f(p.y))
    }

    /// The triangle that contains `p` best (largest smallest barycentric coordinate): among
    /// those listed at its square, or among all when none there contains it (rounding at a
    /// square's edge).
    fn locate(&self, p: DVec2, uv: &[DVec2], triangles: &[[u32; 3]]) -> usize {
        let score = |t: usize| {
            let b = barycentric(p, triangles[t].map(|v| uv[v as usize]));
            b[0].min(b[1]).min(b[2])
        };
        let best = |it: &mut dyn Iterator<Item = usize>| {
            it.map(|t| (score(t), t))
                .fold((f64::NEG_INFINITY, 0), |a, b| if b.0 > a.0 { b } else { a })
        };
        let (x, y) = Self::square_of(p, self.size);
        let s = y * self.size + x;
        let listed = &self.items[self.start[s] as usize..self.start[s + 1] as usize];
        let found = best(&mut listed.iter().map(|&t| t as usize));
        if found.0 >= -1e-9 {
            return found.1;
        }
        best(&mut (0..triangles.len())).1
    }
}

#[cfg(test)]
mod tests {
    use super::super::{cells, checked_input, valid_layout};
    use super::*;
    use crate::mesh::Mesh;
    use crate::mesh::shapes::{grid, uv_sphere};

    /// The layout and charts of a sphere with cells at spacing `f` of the diagonal.
    fn sphere_charts(f: f64) -> (Mesh, Layout, Charts) {
        let mesh = uv_sphere(1.0, 24, 48);
        let input = checked_input(&mesh, &mesh.topology()).unwrap();
        let seeds = cells::spaced_seeds(&input.graph, f * mesh.bounding_box_diagonal());
        let (layout, charts, _, _) = valid_layout(&input, seeds).unwrap();
        drop(input);
        (mesh, layout, charts)
    }

    fn area(t: [DVec2; 3]) -> f64 {
        0.5 * (t[1] - t[0]).perp_dot(t[2] - t[0])
    }

    #[test]
    fn every_cell_maps_one_to_one_onto_its_polygon() {
        let (_, layout, charts) = sphere_charts(0.25);
        assert!(layout.cells >= 8);
        assert_eq!(charts.folded, 0);
        for chart in &charts.cells {
            let k = chart.corners.len();
            assert!(k >= 3);
            assert!(chart.uv.iter().all(|p| p.length() <= 1.0 + 1e-9));
            // The triangles' unsigned areas add up to the polygon's: they cover it once,
            // with no triangle folded over another.
            let covered: f64 = chart
                .triangles
                .iter()
                .map(|t| area(t.map(|v| chart.uv[v as usize])).abs())
                .sum();
            let polygon = 0.5 * k as f64 * (std::f64::consts::TAU / k as f64).sin();
            assert!(
                (covered - polygon).abs() < 1e-9 * polygon,
                "{covered} vs {polygon}"
            );
        }
    }

    #[test]
    fn lifted_points_lie_on_the_input_triangle_they_name() {
        let (mesh, layout, charts) = sphere_charts(0.25);
        for r in 0..layout.regions.len() {
            for k in 0..3 {
                let lifted = charts.quad_point(&layout, r, k, 0.3, 0.6);
                let [a, b, c] = mesh
                    .triangle_vertices(lifted.triangle as usize)
                    .map(|v| mesh.positions[v as usize]);
                let n = (b - a).cross(c - a).normalize();
                assert!((lifted.point - a).dot(n).abs() < 1e-12);
                for (p, q) in [(a, b), (b, c), (c, a)] {
                    assert!((q - p).cross(lifted.point - p).dot(n) >= -1e-12);
                }
            }
        }
    }

    #[test]
    fn neighbouring_quads_agree_on_their_shared_corners() {
        let (_, layout, charts) = sphere_charts(0.25);
        for (ri, region) in layout.regions.iter().enumerate() {
            // The region centre, corner (1, 1) of all three quads: the corner triangle's centroid.
            let centre = charts.quad_point(&layout, ri, 0, 1.0, 1.0).point;
            for k in 1..3 {
                let other = charts.quad_point(&layout, ri, k, 1.0, 1.0).point;
                assert!(centre.distance(other) < 1e-12);
            }
            // The middle of the border between cells k and k+1: corner (1, 0) of cell k's
            // quad and corner (0, 1) of cell k+1's, each found in its own chart.
            for k in 0..3 {
                let here = charts.quad_point(&layout, ri, k, 1.0, 0.0).point;
                let there = charts.quad_point(&layout, ri, (k + 1) % 3, 0.0, 1.0).point;
                assert!(here.distance(there) < 1e-9, "cells {region:?}");
            }
        }
    }

    #[test]
    fn a_piece_with_a_hole_is_not_a_disc() {
        let plate = grid(3, 3);
        let triangles: Vec<[u32; 3]> = (0..plate.triangles.len())
            .map(|t| plate.triangle_vertices(t))
            .collect();
        let border = border_loop(plate.positions.len(), &triangles).unwrap();
        assert_eq!(border.len(), 12);
        // Without the two triangles of the middle square the plate is an annulus: two loops.
        let middle = |t: &[u32; 3]| {
            let centroid = t
                .iter()
                .map(|&v| plate.positions[v as usize])
                .sum::<DVec3>()
                / 3.0;
            centroid.distance(DVec3::new(1.5, 1.5, 0.0)) < 0.5
        };
        let holed: Vec<[u32; 3]> = triangles.iter().filter(|t| !middle(t)).copied().collect();
        assert_eq!(holed.len(), triangles.len() - 2);
        assert!(border_loop(plate.positions.len(), &holed).is_none());
    }
}
