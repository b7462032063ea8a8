//! The output mesh (remeshing thesis §4.7): every patch sampled on an n×n grid.
//! Samples on a patch's corners and sides are made once and shared by both patches that
//! meet there (a side is evaluated as its own quadratic curve, from its lower vertex id),
//! so the output is watertight by construction: no welding tolerance (reading P8).
//! Each grid cell is split along its shorter diagonal (the thesis' proposed improvement).

use super::UniqueSides;
use super::bezier::{Nets, control_net, curve, surface};
use super::quads::FineQuads;
use crate::mesh::model::{Index, Mesh, Wedge};
use glam::DVec3;
use rayon::prelude::*;

/// The output mesh of the refined quads `q` with their control nets, n×n samples per patch.
pub fn tessellate(q: &FineQuads, nets: &Nets, n: usize) -> Mesh {
    let n = n.max(1);
    let sides = UniqueSides::of(&q.faces);
    let mut positions: Vec<DVec3> = nets.corner.clone();
    let side_base = positions.len();
    positions.extend(side_samples(&sides, nets, n));
    let face_base = positions.len();
    positions.extend(face_samples(q, nets, n));
    let grid = Grid {
        q,
        n,
        sides: &sides,
        side_base,
        face_base,
    };
    let triangles = grid.triangles(&positions);
    mesh_of(positions, triangles)
}

/// The n−1 inner samples of every side, as the side's own quadratic curve.
fn side_samples(sides: &UniqueSides, nets: &Nets, n: usize) -> Vec<DVec3> {
    sides
        .ends
        .par_iter()
        .flat_map_iter(|&(a, b)| {
            let p = [
                nets.corner[a as usize],
                nets.side[&(a, b)],
                nets.corner[b as usize],
            ];
            (1..n).map(move |k| curve(p, k as f64 / n as f64))
        })
        .collect()
}

/// The (n−1)² inner samples of every patch.
fn face_samples(q: &FineQuads, nets: &Nets, n: usize) -> Vec<DVec3> {
    let nets_per_face: Vec<[[DVec3; 3]; 3]> = (0..q.faces.len())
        .into_par_iter()
        .map(|f| control_net(q, nets, f))
        .collect();
    nets_per_face
        .par_iter()
        .flat_map_iter(|b| {
            (1..n).flat_map(move |i| {
                (1..n).map(move |j| surface(b, i as f64 / n as f64, j as f64 / n as f64))
            })
        })
        .collect()
}

/// Where each patch's grid samples are among the output positions.
struct Grid<'a> {
    q: &'a FineQuads,
    n: usize,
    sides: &'a UniqueSides,
    side_base: usize,
    face_base: usize,
}

impl Grid<'_> {
    /// The output vertex of face `f` at grid point (i, j) in [0, n]².
    fn id(&self, f: usize, i: usize, j: usize) -> u32 {
        let (n, inner) = (self.n, self.n - 1);
        let c = self.q.faces[f];
        let on_side = |a: u32, b: u32, k: usize| -> u32 {
            let k = if a < b { k } else { n - k };
            (self.side_base + self.sides.of_ends(a, b) * inner + (k - 1)) as u32
        };
        match (i, j) {
            (0, 0) => c[0],
            (i, 0) if i == n => c[1],
            (i, j) if i == n && j == n => c[2],
            (0, j) if j == n => c[3],
            (i, 0) => on_side(c[0], c[1], i),
            (i, j) if i == n => on_side(c[1], c[2], j),
            (i, j) if j == n => on_side(c[3], c[2], i),
            (0, j) => on_side(c[0], c[3], j),
            (i, j) => (self.face_base + f * inner * inner + (i - 1) * inner + (j - 1)) as u32,
        }
    }

    /// Two triangles per grid cell, split along the shorter diagonal, each with the input
    /// triangle its patch's Doo–Sabin point was projected onto.
    fn triangles(&self, positions: &[DVec3]) -> Vec<([Index; 3], Index)> {
        let n = self.n;
        (0..self.q.faces.len())
            .into_par_iter()
            .flat_map_iter(|f| {
                let origin = self.q.origin[f];
                let mut out = Vec::with_capacity(2 * n * n);
                for i in 0..n {
                    for j in 0..n {
                        let (a, b, c, d) = (
                            self.id(f, i, j),
                            self.id(f, i + 1, j),
                            self.id(f, i + 1, j + 1),
                            self.id(f, i, j + 1),
                        );
                        for t in super::split_quad([a, b, c, d], |v| positions[v as usize]) {
                            out.push((t, origin));
                        }
                    }
                }
                out
            })
            .collect()
    }
}

/// A mesh of bare positions: one wedge per vertex, no texture coordinates or normals.
pub(in crate::ops::remesh) fn mesh_of(
    positions: Vec<DVec3>,
    triangles: Vec<([Index; 3], Index)>,
) -> Mesh {
    let mut m = Mesh {
        wedges: (0..positions.len() as Index)
            .map(|v| Wedge {
                vertex: v,
                texcoord: None,
                normal: None,
            })
            .collect(),
        positions,
        ..Mesh::default()
    };
    m.triangles = triangles.iter().map(|t| t.0).collect();
    m.triangle_origins = triangles.iter().map(|t| t.1).collect();
    m
}
