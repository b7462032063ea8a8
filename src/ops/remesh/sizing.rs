//! The target edge length, uniform or curvature-adaptive (Dunyach, Vanderhaeghe, Barthe &
//! Botsch 2013, *Adaptive remeshing for real-time mesh deformation*, §3, which pmp-library's
//! adaptive remeshing follows).
//!
//! Adaptive: an edge of length h across a surface of curvature radius r leaves a gap of
//! about ε = h²/(6r) between its equilateral triangles and the surface (the circle segment
//! of a triangle's circumcircle), so the size at a vertex is
//! L = sqrt(6ε/κ − 3ε²) for the largest absolute principal curvature κ (the exact circle
//! segment), clamped between the shortest and the longest edge allowed. κ is computed once
//! on the input, per vertex, by fitting a quadric height field to the input vertices within
//! a ball around it (robust on noisy scans: the fit averages the noise over the ball, and its
//! constant term absorbs a vertex's own offset), then averaged once over the 1-ring. The
//! working mesh's vertices carry their size: an input vertex its own, a split vertex the
//! mean of its edge's ends, a projected vertex the input's sizes interpolated at its
//! projection. An edge's length is judged against the mean of its ends' sizes, the size at
//! its middle when the field is linear along it.
//!
//! Every vertex's curvature reads only the input, so the field is computed in parallel and
//! is the same whatever the thread count.

use super::corners::{Corners, VKind};
use super::lines::Lines;
use crate::geom::closest_on_triangle;
use crate::mesh::Mesh;
use crate::mesh::topology::Topology;
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

/// Botsch & Kobbelt (2004): split above 4/3·L, collapse below 4/5·L, so that neither
/// operation makes an edge the other undoes.
const SPLIT: f64 = 4.0 / 3.0;
const COLLAPSE: f64 = 0.8;

/// The most input vertices one curvature fit reads (the nearest rings first): bounds the
/// cost on a scan much denser than the ball.
const MAX_BALL: usize = 512;
/// Fewer points than this do not determine the six coefficients well: the vertex takes its
/// neighbours' curvature instead.
const MIN_BALL: usize = 10;
/// The ball is at least this many input edges across, so that it holds a few rings.
const MIN_BALL_EDGES: f64 = 2.5;

/// The adaptive field's settings, resolved to mesh units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Adaptive {
    /// ε, the approximation tolerance.
    pub tolerance: f64,
    pub min_edge: f64,
    pub max_edge: f64,
}

/// What the adaptive field came to (the step report).
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct SizingReport {
    pub tolerance: f64,
    pub min_edge: f64,
    pub max_edge: f64,
    /// The radius of the balls the curvature was fitted over.
    pub curvature_radius: f64,
    /// Input vertices whose size is the shortest / the longest edge (clamped).
    pub at_min: usize,
    pub at_max: usize,
    /// The input vertices' mean size.
    pub mean_size: f64,
}

/// The target length the passes test edges against.
#[derive(Debug, Clone)]
pub enum Sizing {
    /// One length L everywhere: the thresholds are computed once, as before adaptivity.
    Uniform { lo: f64, hi: f64 },
    /// Per input vertex and per working vertex (same numbering for the input's vertices).
    Adaptive { input: Vec<f64>, size: Vec<f64> },
}

impl Sizing {
    pub fn uniform(l: f64) -> Sizing {
        Sizing::Uniform {
            lo: COLLAPSE * l,
            hi: SPLIT * l,
        }
    }

    /// The field of `input` sizes (per input vertex), which the working mesh starts from.
    pub fn adaptive(input: Vec<f64>) -> Sizing {
        Sizing::Adaptive {
            size: input.clone(),
            input,
        }
    }

    #[inline]
    fn mean(size: &[f64], a: u32, b: u32) -> f64 {
        0.5 * (size[a as usize] + size[b as usize])
    }

    /// An edge a–b longer than this is split.
    #[inline]
    pub fn hi(&self, a: u32, b: u32) -> f64 {
        match self {
            Sizing::Uniform { hi, .. } => *hi,
            Sizing::Adaptive { size, .. } => SPLIT * Self::mean(size, a, b),
        }
    }

    /// An edge a–b shorter than this is collapsed.
    #[inline]
    pub fn lo(&self, a: u32, b: u32) -> f64 {
        match self {
            Sizing::Uniform { lo, .. } => *lo,
            Sizing::Adaptive { size, .. } => COLLAPSE * Self::mean(size, a, b),
        }
    }

    /// The size of vertex `v` (`None` when uniform).
    #[inline]
    pub fn at(&self, v: u32) -> Option<f64> {
        match self {
            Sizing::Uniform { .. } => None,
            Sizing::Adaptive { size, .. } => Some(size[v as usize]),
        }
    }

    /// Vertex `m` was made by splitting a–b.
    pub fn split(&mut self, a: u32, b: u32, m: u32) {
        if let Sizing::Adaptive { size, .. } = self {
            debug_assert_eq!(m as usize, size.len());
            size.push(Self::mean(size, a, b));
        }
    }

    /// Gives a size to every vertex made since the field last grew: the repair pass splits
    /// edges without one (it runs after the rounds, which are the field's readers, and for
    /// `patches` without a field), and the sliver pass after it reads sizes again. A new
    /// vertex takes the mean size of its neighbours that have one (a split's two ends among
    /// them, whose mean [`Sizing::split`] would have given), or the input's mean size.
    pub fn cover(&mut self, c: &Corners) {
        let Sizing::Adaptive { input, size } = self else {
            return;
        };
        let mut ring = Vec::new();
        for v in size.len() as u32..c.pos.len() as u32 {
            c.ring(v, &mut ring);
            let known: Vec<f64> = ring
                .iter()
                .filter(|&&u| (u as usize) < size.len())
                .map(|&u| size[u as usize])
                .collect();
            let s = if known.is_empty() {
                input.iter().sum::<f64>() / input.len().max(1) as f64
            } else {
                known.iter().sum::<f64>() / known.len() as f64
            };
            size.push(s);
        }
    }

    /// After projection: every moving vertex takes the input's size where it now lies (a
    /// free vertex on its input triangle, a line vertex on its segment).
    pub fn follow(&mut self, c: &Corners, lines: &Lines, mesh: &Mesh) {
        let Sizing::Adaptive { input, size } = self else {
            return;
        };
        let input = &*input;
        size.par_iter_mut().enumerate().for_each(|(v, s)| {
            if c.vertex_dead[v] || c.locked[v] {
                return;
            }
            let p = c.pos[v];
            match c.kind[v] {
                VKind::Corner => {}
                VKind::Line => {
                    let seg = c.vseg[v];
                    if seg == super::corners::NIL {
                        return;
                    }
                    let [a, b] = lines.ends[seg as usize];
                    let [x, y] = lines.verts[seg as usize];
                    let ab = b - a;
                    let t = if ab.length_squared() > 0.0 {
                        ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    *s = (1.0 - t) * input[x as usize] + t * input[y as usize];
                }
                VKind::Free => {
                    let t = c.vtri[v] as usize;
                    let [a, b, d] = mesh.triangle_positions(t);
                    let [i, j, k] = mesh.triangle_vertices(t);
                    let (_, w) = closest_on_triangle(p, a, b, d);
                    *s =
                        w.x * input[i as usize] + w.y * input[j as usize] + w.z * input[k as usize];
                }
            }
        });
    }
}

/// The size for the largest absolute principal curvature `kappa`: the edge whose
/// equilateral triangles stay within `tolerance` of a sphere of radius 1/κ
/// (L = sqrt(6ε/κ − 3ε²); for ε ≥ r, a radius below the tolerance, the shortest edge; no
/// curvature, the longest), clamped.
pub fn size_for(kappa: f64, a: &Adaptive) -> f64 {
    let e = a.tolerance;
    let h = if kappa.is_finite() && kappa > 0.0 {
        let r = 1.0 / kappa;
        if e < r {
            (6.0 * e * r - 3.0 * e * e).sqrt()
        } else {
            a.min_edge
        }
    } else {
        a.max_edge
    };
    h.clamp(a.min_edge, a.max_edge)
}

/// The radius of the curvature fit: the curvature radius below which the size is the
/// shortest edge (where L(r) = min_edge), so that everything finer than what changes the size
/// is averaged away; at least a few input edges, at most the longest edge.
pub fn fit_radius(a: &Adaptive, mean_input_edge: f64) -> f64 {
    let r_min = (a.min_edge * a.min_edge + 3.0 * a.tolerance * a.tolerance) / (6.0 * a.tolerance);
    r_min.min(a.max_edge).max(MIN_BALL_EDGES * mean_input_edge)
}

/// How fast the size grows back from a refined border to the interior's: by this much per
/// unit of distance from the border, so `border_edge_ratio` 0.5 reaches L at 2·L from the
/// border. Slow enough that the triangles between keep their angles (james at 1 %: 99.44 %
/// at 30° or more with 0.25, 99.29 % with 0.5; docs/remeshing.md).
pub const BORDER_GRADING: f64 = 0.25;

/// Per input vertex, the size a refined border asks for: `ratio`·`l` on the input's open
/// borders, growing by [`BORDER_GRADING`] per unit of distance along the input's edges,
/// at most `l`. `None` when `ratio` is 1 or more or the mesh has no border.
///
/// Why: a scan's border is a ragged cut, with teeth finer than an edge, and a border
/// vertex stays on it (projection onto its line). With edges of L along it, the result's
/// border is a chord across every tooth, and the input between lies far from the result:
/// on james at 1 % of the diagonal, input points within half an edge of the border are
/// about five times further from the result than those four edges in, a third of the mean
/// distance and the largest distances. Shorter border edges follow the teeth (MeshLab keeps every input border
/// vertex for the same reason); the grading keeps the extra triangles to a band.
pub fn border_sizes(mesh: &Mesh, topo: &Topology, l: f64, ratio: f64) -> Option<Vec<f64>> {
    if ratio >= 1.0 {
        return None;
    }
    let distance = distance_to_border(mesh, topo)?;
    Some(
        distance
            .iter()
            .map(|&d| (ratio * l + BORDER_GRADING * d).min(l))
            .collect(),
    )
}

/// Per input vertex, its shortest distance along the input's edges to a border vertex
/// (Dijkstra from all border vertices at once; infinite where no path leads to one).
/// `None` when the mesh has no border. Ties in the queue are broken by vertex index, so the
/// distances are the same on every run.
fn distance_to_border(mesh: &Mesh, topo: &Topology) -> Option<Vec<f64>> {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    let mut distance = vec![f64::INFINITY; mesh.positions.len()];
    // Non-negative f64s order as their bits.
    let mut queue = BinaryHeap::new();
    for e in topo.boundary_edges() {
        for v in topo.edge_vertices(e) {
            if distance[v as usize] != 0.0 {
                distance[v as usize] = 0.0;
                queue.push(Reverse((0u64, v)));
            }
        }
    }
    if queue.is_empty() {
        return None;
    }
    while let Some(Reverse((bits, v))) = queue.pop() {
        let d = f64::from_bits(bits);
        if d > distance[v as usize] {
            continue;
        }
        let p = mesh.positions[v as usize];
        for &w in topo.vertex_neighbours(v) {
            let dw = d + p.distance(mesh.positions[w as usize]);
            if dw < distance[w as usize] {
                distance[w as usize] = dw;
                queue.push(Reverse((dw.to_bits(), w)));
            }
        }
    }
    Some(distance)
}

/// Per input vertex, its size, and what the field came to.
pub fn input_sizes(mesh: &Mesh, topo: &Topology, a: &Adaptive) -> (Vec<f64>, SizingReport) {
    let radius = fit_radius(a, mesh.mean_edge_length());
    let kappa = curvatures(mesh, topo, radius);
    let kappa = smoothed(topo, &kappa);
    let sizes: Vec<f64> = kappa.par_iter().map(|&k| size_for(k, a)).collect();
    let n = sizes.len().max(1) as f64;
    let report = SizingReport {
        tolerance: a.tolerance,
        min_edge: a.min_edge,
        max_edge: a.max_edge,
        curvature_radius: radius,
        at_min: sizes.iter().filter(|&&s| s <= a.min_edge).count(),
        at_max: sizes.iter().filter(|&&s| s >= a.max_edge).count(),
        mean_size: sizes.iter().sum::<f64>() / n,
    };
    (sizes, report)
}

/// Area-weighted vertex normals (unnormalised sums of the triangles' cross products).
fn vertex_normals(mesh: &Mesh, topo: &Topology) -> Vec<DVec3> {
    (0..mesh.positions.len() as u32)
        .into_par_iter()
        .map(|v| {
            topo.vertex_triangles(v)
                .map(|t| mesh.triangle_cross(t as usize))
                .sum()
        })
        .collect()
}

/// Vertices per parallel task of the curvature fit (each task reuses one visit mark array).
const CHUNK: usize = 2048;

/// The largest absolute principal curvature at every input vertex, NaN where the fit is
/// not determined (too few points, degenerate).
fn curvatures(mesh: &Mesh, topo: &Topology, radius: f64) -> Vec<f64> {
    let normals = vertex_normals(mesh, topo);
    let nv = mesh.positions.len();
    let mut kappa = vec![f64::NAN; nv];
    kappa
        .par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(chunk, out)| {
            let mut mark = vec![u32::MAX; nv];
            let mut ball = Vec::new();
            for (i, k) in out.iter_mut().enumerate() {
                let v = (chunk * CHUNK + i) as u32;
                ball_around(mesh, topo, v, radius, &mut mark, &mut ball);
                *k = fit(mesh, &normals, v, &ball);
            }
        });
    kappa
}

/// The input vertices within `radius` of `v` reached through edges between such vertices,
/// nearest rings first, at most [`MAX_BALL`]. `mark[w] == v` marks a visited vertex.
fn ball_around(
    mesh: &Mesh,
    topo: &Topology,
    v: u32,
    radius: f64,
    mark: &mut [u32],
    ball: &mut Vec<u32>,
) {
    let p = mesh.positions[v as usize];
    let r2 = radius * radius;
    ball.clear();
    ball.push(v);
    mark[v as usize] = v;
    let mut i = 0;
    while i < ball.len() && ball.len() < MAX_BALL {
        let u = ball[i];
        i += 1;
        for &w in topo.vertex_neighbours(u) {
            if mark[w as usize] == v {
                continue;
            }
            mark[w as usize] = v;
            if mesh.positions[w as usize].distance_squared(p) <= r2 {
                ball.push(w);
                if ball.len() == MAX_BALL {
                    break;
                }
            }
        }
    }
}

/// Fits z = a x² + b xy + c y² + d x + e y + f to the ball in the frame of its mean normal
/// (least squares) and returns the largest absolute eigenvalue of the Hessian,
/// |a + c| + sqrt((a − c)² + b²).
fn fit(mesh: &Mesh, normals: &[DVec3], v: u32, ball: &[u32]) -> f64 {
    if ball.len() < MIN_BALL {
        return f64::NAN;
    }
    let n = ball
        .iter()
        .map(|&w| normals[w as usize])
        .sum::<DVec3>()
        .normalize_or_zero();
    if n == DVec3::ZERO {
        return f64::NAN;
    }
    let (tu, tv) = n.any_orthonormal_pair();
    let p = mesh.positions[v as usize];
    // Normal equations, 6 × 6.
    let mut m = [[0.0f64; 6]; 6];
    let mut rhs = [0.0f64; 6];
    let mut scale = 0.0f64;
    for &w in ball {
        let d = mesh.positions[w as usize] - p;
        scale = scale.max(d.length());
    }
    if scale <= 0.0 {
        return f64::NAN;
    }
    // Coordinates scaled to the ball so the system is well conditioned.
    for &w in ball {
        let d = (mesh.positions[w as usize] - p) / scale;
        let (x, y, z) = (d.dot(tu), d.dot(tv), d.dot(n));
        let row = [x * x, x * y, y * y, x, y, 1.0];
        for (mr, &xr) in m.iter_mut().zip(&row) {
            for (ms, &xs) in mr.iter_mut().zip(&row) {
                *ms += xr * xs;
            }
        }
        for (rr, &xr) in rhs.iter_mut().zip(&row) {
            *rr += xr * z;
        }
    }
    let Some(q) = solve6(m, rhs) else {
        return f64::NAN;
    };
    // Back to mesh units: z/s = q(x/s, y/s) scales the second-order terms by 1/s.
    let (a, b, c) = (q[0] / scale, q[1] / scale, q[2] / scale);
    (a + c).abs() + ((a - c) * (a - c) + b * b).sqrt()
}

/// Gaussian elimination with partial pivoting; `None` for a (near-)singular system.
fn solve6(mut m: [[f64; 6]; 6], mut b: [f64; 6]) -> Option<[f64; 6]> {
    let norm = m.iter().flatten().fold(0.0f64, |s, x| s.max(x.abs()));
    for col in 0..6 {
        let piv = (col..6).max_by(|&i, &j| m[i][col].abs().total_cmp(&m[j][col].abs()))?;
        let pivot = m[piv][col].abs();
        if pivot.is_nan() || pivot <= 1e-12 * norm {
            return None;
        }
        m.swap(col, piv);
        b.swap(col, piv);
        let (top, rest) = m.split_at_mut(col + 1);
        let prow = &top[col];
        let bcol = b[col];
        for (row, br) in rest.iter_mut().zip(b[col + 1..].iter_mut()) {
            let f = row[col] / prow[col];
            for (x, &p) in row[col..].iter_mut().zip(&prow[col..]) {
                *x -= f * p;
            }
            *br -= f * bcol;
        }
    }
    let mut x = [0.0; 6];
    for r in (0..6).rev() {
        let s: f64 = (r + 1..6).map(|k| m[r][k] * x[k]).sum();
        x[r] = (b[r] - s) / m[r][r];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// One averaging of every vertex's curvature with its 1-ring's (a vertex without a fit
/// takes its neighbours' mean; one whose neighbours have none either stays NaN and gets the
/// longest edge).
fn smoothed(topo: &Topology, kappa: &[f64]) -> Vec<f64> {
    (0..kappa.len() as u32)
        .into_par_iter()
        .map(|v| {
            let (mut sum, mut n) = (0.0, 0usize);
            let own = kappa[v as usize];
            if own.is_finite() {
                sum += own;
                n += 1;
            }
            for &w in topo.vertex_neighbours(v) {
                let k = kappa[w as usize];
                if k.is_finite() {
                    sum += k;
                    n += 1;
                }
            }
            if n == 0 { f64::NAN } else { sum / n as f64 }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn adaptive() -> Adaptive {
        Adaptive {
            tolerance: 0.001,
            min_edge: 0.01,
            max_edge: 1.0,
        }
    }

    #[test]
    fn size_follows_the_circle_segment_and_is_clamped() {
        let a = adaptive();
        // Radius 1: sqrt(6·0.001 − 3·10⁻⁶).
        let h = size_for(1.0, &a);
        assert!((h - (0.006f64 - 3e-6).sqrt()).abs() < 1e-12, "{h}");
        assert_eq!(size_for(0.0, &a), a.max_edge);
        assert_eq!(size_for(f64::NAN, &a), a.max_edge);
        assert_eq!(size_for(1e6, &a), a.min_edge);
        // Shorter where more curved.
        assert!(size_for(10.0, &a) < size_for(1.0, &a));
    }

    #[test]
    fn sphere_curvature_is_its_inverse_radius() {
        let mesh = crate::mesh::shapes::uv_sphere(2.0, 48, 96);
        let topo = Topology::new(&mesh);
        let k = curvatures(&mesh, &topo, 0.4);
        let mut ks: Vec<f64> = k.iter().copied().filter(|k| k.is_finite()).collect();
        assert!(ks.len() > k.len() * 9 / 10);
        ks.sort_by(f64::total_cmp);
        let median = ks[ks.len() / 2];
        assert!((median - 0.5).abs() < 0.05, "{median}");
    }

    #[test]
    fn solve6_solves_and_refuses_a_singular_system() {
        let mut m = [[0.0; 6]; 6];
        for (i, row) in m.iter_mut().enumerate() {
            row[i] = (i + 1) as f64;
        }
        let x = solve6(m, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]).unwrap();
        assert!(x.iter().all(|&v| (v - 1.0).abs() < 1e-12));
        m[5][5] = 0.0;
        assert!(solve6(m, [1.0; 6]).is_none());
    }
}
