//! Quad regions and their Doo–Sabin points (remeshing thesis §4.4–§4.5).
//!
//! Each triangular region is split into three quads from its centre (the Eck / thesis §3.6
//! fallback, reading P3) instead of being paired with a neighbour: the split always exists
//! (no matching, no backtracking, no odd region count, no bridge in the dual), and every
//! quad's corners are a cell centre, two border midpoints and the region centre.
//!
//! Each quad is refined 4×4; the Doo–Sabin point of sub-quad (i, j) is the quad's
//! parametrisation at ((2i+1)/8, (2j+1)/8) (thesis §4.5, reading P5), taken in the harmonic
//! chart of the quad's cell ([`super::charts`], reading P9).

use super::UniqueSides;
use super::charts::Charts;
use super::layout::Layout;
use glam::DVec3;
use rayon::prelude::*;
use std::collections::HashMap;

/// Sub-quads per quad side (the 4×4 Doo–Sabin grid).
pub const SUB: usize = 4;

/// The refined quad mesh: `faces` are counter-clockwise vertex quads (vertex ids are
/// combinatorial only), `points` the Doo–Sabin point of each face, `origin` the input
/// triangle each point lies on.
pub struct FineQuads {
    pub vertex_count: usize,
    pub faces: Vec<[u32; 4]>,
    pub points: Vec<DVec3>,
    pub origin: Vec<u32>,
}

/// Builds the coarse quads of `layout` (three per region), refines them 4×4 with shared
/// vertices along shared sides, and samples the Doo–Sabin points in the cells' charts.
pub fn build(layout: &Layout, charts: &Charts) -> FineQuads {
    let quads = coarse_quads(layout);
    let coarse_count =
        layout.cells + UniqueSides::of(&layout.regions).ends.len() + layout.regions.len();
    let (faces, samples, vertex_count) = refine(&quads, coarse_count as u32);
    let lifted: Vec<_> = samples
        .par_iter()
        .map(|&(qi, u, v)| charts.quad_point(layout, qi / 3, qi % 3, u, v))
        .collect();
    FineQuads {
        vertex_count,
        faces,
        points: lifted.iter().map(|p| p.point).collect(),
        origin: lifted.iter().map(|p| p.triangle).collect(),
    }
}

/// Three quads per region `[a, b, c]`, one at each cell: the cell centre, the middle of the
/// border with the next cell, the region centre, the middle of the border with the previous
/// one (counter-clockwise). The ids are combinatorial: the cells, then one per region
/// border, then one per region centre.
fn coarse_quads(layout: &Layout) -> Vec<[u32; 4]> {
    let borders = UniqueSides::of(&layout.regions);
    let e = |a: u32, b: u32| (layout.cells + borders.of_ends(a, b)) as u32;
    let first_centre = layout.cells + borders.ends.len();
    let mut quads: Vec<[u32; 4]> = Vec::with_capacity(3 * layout.regions.len());
    for (ri, r) in layout.regions.iter().enumerate() {
        let g = (first_centre + ri) as u32;
        let [a, b, c] = *r;
        quads.push([a, e(a, b), g, e(c, a)]);
        quads.push([b, e(b, c), g, e(a, b)]);
        quads.push([c, e(c, a), g, e(b, c)]);
    }
    quads
}

/// A sub-quad's Doo–Sabin sample: (coarse quad, u, v).
type Sample = (usize, f64, f64);

/// Refines every quad SUB×SUB. Coarse vertices keep their ids; SUB−1 new ones per coarse
/// side, shared by the two quads along it (keyed by the side's ends and the step from the
/// lower end); (SUB−1)² inside each quad. The fine faces, their samples at
/// ((2i+1)/8, (2j+1)/8), and the vertex count.
fn refine(quads: &[[u32; 4]], coarse_count: u32) -> (Vec<[u32; 4]>, Vec<Sample>, usize) {
    let mut next = coarse_count;
    let mut side: HashMap<(u32, u32, usize), u32> = HashMap::new();
    let mut faces = Vec::with_capacity(quads.len() * SUB * SUB);
    let mut samples: Vec<Sample> = Vec::with_capacity(quads.len() * SUB * SUB);
    for (qi, q) in quads.iter().enumerate() {
        let mut id = [[0u32; SUB + 1]; SUB + 1];
        for (i, row) in id.iter_mut().enumerate() {
            for (j, slot) in row.iter_mut().enumerate() {
                *slot = grid_vertex(q, i, j, &mut side, &mut next);
            }
        }
        for i in 0..SUB {
            for j in 0..SUB {
                faces.push([id[i][j], id[i + 1][j], id[i + 1][j + 1], id[i][j + 1]]);
                samples.push((
                    qi,
                    (2 * i + 1) as f64 / (2 * SUB) as f64,
                    (2 * j + 1) as f64 / (2 * SUB) as f64,
                ));
            }
        }
    }
    (faces, samples, next as usize)
}

/// The id of grid vertex (i, j) of quad `q`: its corner, the shared vertex of its side, or a
/// new interior one.
fn grid_vertex(
    q: &[u32; 4],
    i: usize,
    j: usize,
    side: &mut HashMap<(u32, u32, usize), u32>,
    next: &mut u32,
) -> u32 {
    let mut fresh = || {
        *next += 1;
        *next - 1
    };
    match (i, j) {
        (0, 0) => return q[0],
        (SUB, 0) => return q[1],
        (SUB, SUB) => return q[2],
        (0, SUB) => return q[3],
        _ => {}
    }
    let along = if j == 0 {
        (q[0], q[1], i)
    } else if i == SUB {
        (q[1], q[2], j)
    } else if j == SUB {
        (q[3], q[2], i)
    } else if i == 0 {
        (q[0], q[3], j)
    } else {
        return fresh();
    };
    let (from, to, k) = along;
    let key = if from < to {
        (from, to, k)
    } else {
        (to, from, SUB - k)
    };
    *side.entry(key).or_insert_with(fresh)
}
