//! Quad regions and their Doo–Sabin points (remeshing thesis §4.4–§4.5).
//!
//! Each triangular region is split into three quads from its centre (the Eck / thesis §3.6
//! fallback, reading P3) instead of being paired with a neighbour: the split always exists
//! (no matching, no backtracking, no odd region count, no bridge in the dual), and every
//! quad's corners are a cell centre, two border midpoints and the region centre.
//!
//! Each quad is refined 4×4; the Doo–Sabin point of sub-quad (i, j) is the quad's
//! parametrisation at ((2i+1)/8, (2j+1)/8) (thesis §4.5, reading P5). The parametrisation
//! built here is the bilinear map of the quad's corners (projected onto the input) followed
//! by a closest-point projection onto the input surface; the thesis' harmonic map of the
//! traced region is NOT built (see docs/remeshing.md).

use super::UniqueSides;
use super::layout::Layout;
use crate::geom::bvh::TriangleBvh;
use glam::DVec3;
use rayon::prelude::*;
use std::collections::HashMap;

/// Sub-quads per quad side (the 4×4 Doo–Sabin grid).
pub const SUB: usize = 4;

/// The refined quad mesh: `faces` are counter-clockwise vertex quads (vertex ids are
/// combinatorial only), `points` the Doo–Sabin point of each face, `origin` the input
/// triangle each point was projected onto.
pub struct FineQuads {
    pub vertex_count: usize,
    pub faces: Vec<[u32; 4]>,
    pub points: Vec<DVec3>,
    pub origin: Vec<u32>,
}

fn project(bvh: &TriangleBvh<'_>, p: DVec3) -> (DVec3, u32) {
    match bvh.closest(p, None) {
        Some(hit) => (hit.point, hit.triangle),
        None => (p, 0),
    }
}

fn bilinear(q: &[DVec3; 4], u: f64, v: f64) -> DVec3 {
    q[0] * ((1.0 - u) * (1.0 - v))
        + q[1] * (u * (1.0 - v))
        + q[2] * (u * v)
        + q[3] * ((1.0 - u) * v)
}

/// Builds the coarse quads of `layout` (three per region), refines them 4×4 with shared
/// vertices along shared sides, and samples the Doo–Sabin points.
pub fn build(layout: &Layout, centres: &[DVec3], bvh: &TriangleBvh<'_>) -> FineQuads {
    let coarse = Coarse::new(layout, centres, bvh);
    let quads = coarse.quads(layout);
    let (faces, samples, vertex_count) = refine(&quads, coarse.points.len() as u32);
    let projected: Vec<(DVec3, u32)> = samples
        .par_iter()
        .map(|&(qi, u, v)| {
            let q = quads[qi].map(|c| coarse.points[c as usize]);
            project(bvh, bilinear(&q, u, v))
        })
        .collect();
    FineQuads {
        vertex_count,
        faces,
        points: projected.iter().map(|p| p.0).collect(),
        origin: projected.iter().map(|p| p.1).collect(),
    }
}

/// The coarse vertices: the cell centres, then one per region border (dual edge), then one
/// per region centre, all on the input surface.
struct Coarse {
    points: Vec<DVec3>,
    /// The region borders; border i is coarse vertex `cells + i`.
    borders: UniqueSides,
    cells: usize,
}

impl Coarse {
    fn new(layout: &Layout, centres: &[DVec3], bvh: &TriangleBvh<'_>) -> Coarse {
        let nc = layout.cells;
        let borders = UniqueSides::of(&layout.regions);
        let mut flat: Vec<DVec3> = centres.to_vec();
        flat.extend(
            borders
                .ends
                .iter()
                .map(|&(a, b)| (centres[a as usize] + centres[b as usize]) * 0.5),
        );
        flat.extend(layout.regions.iter().map(|r| {
            (centres[r[0] as usize] + centres[r[1] as usize] + centres[r[2] as usize]) / 3.0
        }));
        // Onto the surface (cell centres are on it already).
        let points = flat
            .par_iter()
            .enumerate()
            .map(|(i, &p)| if i < nc { p } else { project(bvh, p).0 })
            .collect();
        Coarse {
            points,
            borders,
            cells: nc,
        }
    }

    /// Three quads per region: corner, border midpoint, region centre, border midpoint.
    fn quads(&self, layout: &Layout) -> Vec<[u32; 4]> {
        let e = |a: u32, b: u32| (self.cells + self.borders.of_ends(a, b)) as u32;
        let first_centre = self.cells + self.borders.ends.len();
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
