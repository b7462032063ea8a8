//! Hostile mesh shapes for the cost tests of issue #22 finding 6 (tests/quadratic_corners.rs,
//! benches/quadratic_corners.rs): inputs on which a closest-point index or the decimation
//! set-up can do work quadratic in the triangle count.
//!
//! - [`soup`]: `n` independent triangles, each corner anywhere in the unit cube, so that
//!   every triangle crosses most of the others and no box separates them.
//! - [`stacked`]: `n` copies of one triangle, each lifted by a hair (nearly coincident).
//! - [`fan`]: a flat disc of `n` triangles around one centre vertex of valence `n`.
//! - [`fan_with_seams`]: the same disc with texture coordinates that differ per triangle at
//!   every corner, so that the centre vertex also has `n` wedges (a seam along every spoke).
//!
//! All are deterministic (a fixed-seed SplitMix64), so a count measured on one is the same
//! on every run.

#![allow(dead_code)] // each includer uses some of the shapes

use glam::{DVec2, DVec3};
use scanmill::mesh::{Index, Mesh, Wedge};

/// SplitMix64: a tiny fixed generator, so the shapes never change with a crate version.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Adds a vertex with one wedge (no attributes) and returns the wedge.
fn vertex(m: &mut Mesh, p: DVec3) -> Index {
    m.positions.push(p);
    let v = m.positions.len() as Index - 1;
    m.wedges.push(Wedge {
        vertex: v,
        texcoord: None,
        normal: None,
    });
    m.wedges.len() as Index - 1
}

/// `n` large triangles crossing each other in the unit cube, three vertices of their own each.
pub fn soup(n: usize, seed: u64) -> Mesh {
    let mut rng = SplitMix(seed);
    let mut m = Mesh::default();
    for _ in 0..n {
        let mut corner = || DVec3::new(rng.unit(), rng.unit(), rng.unit());
        let (a, b, c) = (corner(), corner(), corner());
        let t = [vertex(&mut m, a), vertex(&mut m, b), vertex(&mut m, c)];
        m.triangles.push(t);
    }
    m
}

/// `n` near-identical triangles: one unit right triangle, copy `i` lifted by `i` × 1e-9
/// along z and its corners jittered by up to 1e-9, three vertices of its own each.
pub fn stacked(n: usize, seed: u64) -> Mesh {
    let mut rng = SplitMix(seed);
    let mut m = Mesh::default();
    let base = [DVec3::ZERO, DVec3::X, DVec3::Y];
    for i in 0..n {
        let lift = DVec3::Z * (i as f64 * 1e-9);
        let t = base.map(|p| {
            let jitter = DVec3::new(rng.unit(), rng.unit(), rng.unit()) * 1e-9;
            vertex(&mut m, p + lift + jitter)
        });
        m.triangles.push(t);
    }
    m
}

/// The rim point `i` of `n` on the unit circle in the z = 0 plane.
fn rim(i: usize, n: usize) -> DVec3 {
    let a = std::f64::consts::TAU * i as f64 / n as f64;
    DVec3::new(a.cos(), a.sin(), 0.0)
}

/// A closed disc of `n` triangles around the centre vertex 0 (valence `n`), `n` rim
/// vertices, counter-clockwise seen from +Z.
pub fn fan(n: usize) -> Mesh {
    let mut m = Mesh::default();
    let centre = vertex(&mut m, DVec3::ZERO);
    let rims: Vec<Index> = (0..n).map(|i| vertex(&mut m, rim(i, n))).collect();
    for i in 0..n {
        m.triangles.push([centre, rims[i], rims[(i + 1) % n]]);
    }
    m
}

/// [`fan`] with texture coordinates of its own per triangle: every corner of every
/// triangle is a wedge of its own, so the centre has `n` wedges and every spoke is a seam.
pub fn fan_with_seams(n: usize) -> Mesh {
    let mut m = Mesh::default();
    m.positions.push(DVec3::ZERO);
    m.positions.extend((0..n).map(|i| rim(i, n)));
    for i in 0..n {
        let corners = [0, 1 + i, 1 + (i + 1) % n];
        // Triangle i's chart: a small right triangle in a row of its own.
        let origin = DVec2::new(0.0, i as f64 / n as f64);
        let uvs = [
            origin,
            origin + DVec2::X * 0.5,
            origin + DVec2::Y * (0.5 / n as f64),
        ];
        let mut tri = [0; 3];
        for k in 0..3 {
            m.texcoords.push(uvs[k]);
            m.wedges.push(Wedge {
                vertex: corners[k] as Index,
                texcoord: Some(m.texcoords.len() as Index - 1),
                normal: None,
            });
            tri[k] = m.wedges.len() as Index - 1;
        }
        m.triangles.push(tri);
    }
    m
}
