//! A pass of `isotropic` after the iterations: free vertices move along their normal so that
//! the result fits the input in the least-squares sense instead of interpolating it.
//!
//! Projection puts every vertex *on* the input, so each result triangle is a chord of the
//! input: on a curved or noisy scan the triangle lies on one side of the surface between its
//! corners (a parabola's chord is off by h²κ/12 on average), and the least-squares plane
//! through the same span is off by less. Botsch & Kobbelt (2004) project onto the input
//! because their target is a remesh *of* the surface; the measure of a scanmill result is
//! its distance to the input (`metrics`), and this pass lowers exactly that. It takes a few
//! Jacobi rounds of the least-squares problem
//!
//!   min over normal offsets t_v of  Σ_f A_f (r_f − φ_v(f)·t_v)²  +  anchors,
//!
//! with one sample per result triangle f: its centroid, weighted by its area A_f, r_f the
//! signed distance from the centroid to its closest input point along the triangle's
//! normal, and φ_v(f) = 1/3 v's barycentric weight there. (More samples per triangle, or the
//! input's own vertices as samples, cost more and came out no closer: docs/remeshing.md
//! compares the variants.) The closest input points are found once, before the rounds, by
//! a walk from where a corner was projected ([`walk`]): the vertices move by a small
//! fraction of an edge. Holding the
//! neighbours, the best offset is t_v = Σ A φ r / Σ A φ²; every vertex moves at once by
//! [`DAMPING`] of it. The *anchor*, v's own footprint on the input at weight [`ANCHOR`] × a
//! third of its fan's area, keeps the offsets small where the samples say little: a few
//! noisy samples would otherwise pull a vertex past the surface they straddle. A centroid
//! farther from the input
//! than [`OUTLIER`] × its triangle's longest edge sees another sheet of the input (a fold)
//! and is left out. A move that would turn a face of the fan over is not made.
//!
//! Line vertices (borders, seams, features) stay on their lines and corners stay: a line is
//! where the surface is cut or creased, and a vertex moved off it would open a gap between
//! texture charts.

use super::PIECE;
use super::corners::{Corners, NIL, VKind};
use super::ops::fan_keeps_orientation;
use super::walk::{self, Sheet};
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

/// What the pass did (the step report's `counts.fit`).
#[derive(Debug, Clone, Copy, Default, Serialize, PartialEq)]
pub struct FitReport {
    /// Free vertices moved off the input.
    pub vertices: usize,
    /// Mean and largest distance a vertex moved, in mesh units.
    pub mean_offset: f64,
    pub max_offset: f64,
}

/// Jacobi rounds and their step: neighbours move together, so each moves by [`DAMPING`] of
/// the offset that is best for it alone (docs/remeshing.md has the measurements).
const ROUNDS: usize = 2;
const DAMPING: f64 = 0.7;
/// The anchor's weight (see the module documentation).
const ANCHOR: f64 = 0.5;
/// Samples farther than this share of their triangle's longest edge from the input are
/// left out.
const OUTLIER: f64 = 0.25;

/// Fits the free vertices of `c`, projected onto the input (`sheet`).
/// Returns, beside the report, the input triangle each face's centroid was found closest
/// to before the fit ([`NIL`] for a dead face): the vertices moved by a small fraction of
/// an edge since, so it is a close start for a later search from the same centroid.
pub fn fit(c: &mut Corners, sheet: &Sheet) -> (FitReport, Vec<u32>) {
    let (feet, under): (Vec<Option<DVec3>>, Vec<u32>) = feet(c, sheet).into_iter().unzip();
    let fitted: Vec<u32> = (0..c.pos.len() as u32)
        .filter(|&v| {
            let i = v as usize;
            !c.vertex_dead[i] && !c.locked[i] && c.kind[i] == VKind::Free
        })
        .collect();
    let anchors: Vec<DVec3> = fitted.iter().map(|&v| c.pos[v as usize]).collect();
    for _ in 0..ROUNDS {
        let moved: Vec<DVec3> = fitted
            .par_iter()
            .with_max_len(PIECE)
            .zip(&anchors)
            .map(|(&v, &anchor)| step(c, &feet, v, anchor))
            .collect();
        for (&v, p) in fitted.iter().zip(moved) {
            c.pos[v as usize] = p;
        }
    }
    let offsets = fitted
        .iter()
        .zip(&anchors)
        .map(|(&v, a)| c.pos[v as usize].distance(*a));
    let report = FitReport {
        vertices: offsets.clone().filter(|&d| d > 0.0).count(),
        mean_offset: offsets.clone().sum::<f64>() / fitted.len().max(1) as f64,
        max_offset: offsets.fold(0.0, f64::max),
    };
    (report, under)
}

/// The closest input point of every live face's centroid (`None` for a dead face or a
/// centroid left out), and the input triangle it is on ([`NIL`] for a dead face).
fn feet(c: &Corners, sheet: &Sheet) -> Vec<(Option<DVec3>, u32)> {
    (0..c.face_count())
        .into_par_iter()
        .with_max_len(PIECE)
        .map(|f| {
            if c.face_dead[f] {
                return (None, NIL);
            }
            let p = c.face_positions(f);
            let longest = (0..3)
                .map(|k| p[k].distance(p[(k + 1) % 3]))
                .fold(0.0, f64::max);
            let s = (p[0] + p[1] + p[2]) / 3.0;
            // Every vertex has the input triangle it was last projected onto (or, for an
            // input vertex never moved, one of its own).
            let foot = walk::walk(sheet, c.vtri[c.vtx[3 * f] as usize], s, |_| true);
            let kept = foot.point.distance(s) <= OUTLIER * longest;
            (kept.then_some(foot.point), foot.triangle)
        })
        .collect()
}

/// v's position after one Jacobi round (see the module documentation).
fn step(c: &Corners, feet: &[Option<DVec3>], v: u32, anchor: DVec3) -> DVec3 {
    let x = c.pos[v as usize];
    let (mut normal, mut area) = (DVec3::ZERO, 0.0);
    for h in c.fan_iter(v) {
        let cross = c.face_cross((h / 3) as usize);
        normal += cross;
        area += 0.5 * cross.length();
    }
    let n = normal.normalize_or_zero();
    if n == DVec3::ZERO {
        return x;
    }
    let w0 = ANCHOR * area / 3.0;
    let (mut num, mut den) = (w0 * n.dot(anchor - x), w0);
    for h in c.fan_iter(v) {
        let f = (h / 3) as usize;
        let Some(foot) = feet[f] else { continue };
        let cross = c.face_cross(f);
        let (nf, area) = (cross.normalize_or_zero(), 0.5 * cross.length());
        // Moving v by t along n moves the face's plane at its centroid by t·(n·nf)/3.
        let slope = nf.dot(n) / 3.0;
        num += area * slope * nf.dot(foot - x);
        den += area * slope * slope;
    }
    if den <= 0.0 || !den.is_finite() {
        return x;
    }
    let target = x + n * (DAMPING * num / den);
    if fan_keeps_orientation(c, v, target) {
        target
    } else {
        x
    }
}
