//! Small generated meshes with known properties, for unit tests and examples across the
//! crate (a flat grid with texture coordinates, a cube, a UV sphere, a torus, the regular
//! tetrahedron, octahedron and icosahedron, a vase with high-valence cap hubs).

use super::model::{Index, Mesh, Wedge};
use glam::{DVec2, DVec3};

/// A flat `nx` × `ny` grid of unit squares in the z = 0 plane, two triangles per square,
/// counter-clockwise seen from +Z, one wedge per vertex with texture coordinates in \[0,1\]².
pub fn grid(nx: usize, ny: usize) -> Mesh {
    let mut m = Mesh::default();
    for j in 0..=ny {
        for i in 0..=nx {
            m.positions.push(DVec3::new(i as f64, j as f64, 0.0));
            m.texcoords
                .push(DVec2::new(i as f64 / nx as f64, j as f64 / ny as f64));
            let id = m.positions.len() as Index - 1;
            m.wedges.push(Wedge {
                vertex: id,
                texcoord: Some(id),
                normal: None,
            });
        }
    }
    let at = |i: usize, j: usize| (j * (nx + 1) + i) as Index;
    for j in 0..ny {
        for i in 0..nx {
            m.triangles.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            m.triangles.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    m
}

/// The cube [-1,1]³, 12 triangles, outward-facing, one wedge per vertex, no attributes.
pub fn cube() -> Mesh {
    let mut m = Mesh::default();
    for k in 0..8 {
        m.positions.push(DVec3::new(
            if k & 1 != 0 { 1.0 } else { -1.0 },
            if k & 2 != 0 { 1.0 } else { -1.0 },
            if k & 4 != 0 { 1.0 } else { -1.0 },
        ));
        m.wedges.push(Wedge {
            vertex: k,
            texcoord: None,
            normal: None,
        });
    }
    let quads: [[Index; 4]; 6] = [
        [0, 2, 3, 1], // z = -1
        [4, 5, 7, 6], // z = +1
        [0, 1, 5, 4], // y = -1
        [2, 6, 7, 3], // y = +1
        [0, 4, 6, 2], // x = -1
        [1, 3, 7, 5], // x = +1
    ];
    for [a, b, c, d] in quads {
        m.triangles.push([a, b, c]);
        m.triangles.push([a, c, d]);
    }
    m
}

/// A closed UV sphere of radius `r` with `rings` latitude bands and `segments` longitudes.
pub fn uv_sphere(r: f64, rings: usize, segments: usize) -> Mesh {
    let mut m = Mesh::default();
    m.positions.push(DVec3::new(0.0, 0.0, r));
    for i in 1..rings {
        let theta = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let phi = std::f64::consts::TAU * j as f64 / segments as f64;
            m.positions.push(
                r * DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                ),
            );
        }
    }
    m.positions.push(DVec3::new(0.0, 0.0, -r));
    let south = (m.positions.len() - 1) as Index;
    let ring = |i: usize, j: usize| (1 + (i - 1) * segments + j % segments) as Index;
    for j in 0..segments {
        m.triangles.push([0, ring(1, j), ring(1, j + 1)]);
        m.triangles
            .push([south, ring(rings - 1, j + 1), ring(rings - 1, j)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            m.triangles
                .push([ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)]);
            m.triangles
                .push([ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)]);
        }
    }
    plain_wedges(&mut m);
    m
}

/// One wedge per position, no attributes.
fn plain_wedges(m: &mut Mesh) {
    m.wedges = (0..m.positions.len() as Index)
        .map(|v| Wedge {
            vertex: v,
            texcoord: None,
            normal: None,
        })
        .collect();
}

/// A closed torus around the z axis: tube centre radius `big_r`, tube radius `r`, `nu`
/// segments around the axis and `nv` around the tube, outward-facing.
pub fn torus(big_r: f64, r: f64, nu: usize, nv: usize) -> Mesh {
    let mut m = Mesh::default();
    for i in 0..nu {
        let u = std::f64::consts::TAU * i as f64 / nu as f64;
        for j in 0..nv {
            let v = std::f64::consts::TAU * j as f64 / nv as f64;
            let w = big_r + r * v.cos();
            m.positions
                .push(DVec3::new(w * u.cos(), w * u.sin(), r * v.sin()));
        }
    }
    let at = |i: usize, j: usize| ((i % nu) * nv + j % nv) as Index;
    for i in 0..nu {
        for j in 0..nv {
            m.triangles.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            m.triangles.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    plain_wedges(&mut m);
    m
}

/// How far triangle `t` of `m` faces away from the origin: its normal (unnormalised) along
/// the sum of its corners; positive when it faces away, negative when it faces the origin.
fn outwardness(m: &Mesh, t: usize) -> f64 {
    let p = m.triangle_positions(t);
    m.triangle_cross(t).dot(p[0] + p[1] + p[2])
}

/// Builds a convex polyhedron centred at the origin from vertices and triangles, turning
/// every triangle outward.
fn convex(positions: Vec<DVec3>, triangles: Vec<[Index; 3]>) -> Mesh {
    let mut m = Mesh {
        positions,
        triangles,
        ..Mesh::default()
    };
    plain_wedges(&mut m);
    for t in 0..m.triangles.len() {
        if outwardness(&m, t) < 0.0 {
            m.triangles[t].swap(1, 2);
        }
    }
    m
}

/// The regular tetrahedron with circumradius `sqrt(3)`.
pub fn tetrahedron() -> Mesh {
    convex(
        vec![
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(1.0, -1.0, -1.0),
            DVec3::new(-1.0, 1.0, -1.0),
            DVec3::new(-1.0, -1.0, 1.0),
        ],
        vec![[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]],
    )
}

/// The regular octahedron with circumradius 1.
pub fn octahedron() -> Mesh {
    let p = vec![
        DVec3::X,
        DVec3::NEG_X,
        DVec3::Y,
        DVec3::NEG_Y,
        DVec3::Z,
        DVec3::NEG_Z,
    ];
    let mut t = Vec::new();
    for x in [0, 1] {
        for y in [2, 3] {
            for z in [4, 5] {
                t.push([x, y, z]);
            }
        }
    }
    convex(p, t)
}

/// The regular icosahedron with vertices `(0, ±1, ±φ)` and their cyclic permutations
/// (circumradius `sqrt(1 + φ²)`).
pub fn icosahedron() -> Mesh {
    let phi = (1.0 + 5f64.sqrt()) / 2.0;
    let mut p = Vec::new();
    for s1 in [-1.0, 1.0] {
        for s2 in [-1.0, 1.0] {
            p.push(DVec3::new(0.0, s1, s2 * phi));
            p.push(DVec3::new(s1, s2 * phi, 0.0));
            p.push(DVec3::new(s2 * phi, 0.0, s1));
        }
    }
    // Faces: the triples of mutually adjacent vertices (edge length 2).
    let n = p.len();
    let adjacent = |a: usize, b: usize| ((p[a] - p[b]).length() - 2.0).abs() < 1e-9;
    let mut t = Vec::new();
    for a in 0..n {
        for b in a + 1..n {
            for c in b + 1..n {
                if adjacent(a, b) && adjacent(b, c) && adjacent(a, c) {
                    t.push([a as Index, b as Index, c as Index]);
                }
            }
        }
    }
    convex(p, t)
}

/// A closed vase: a surface of revolution (radius `1 + 0.35·sin(1.2 z)` for z in [0, 3])
/// with `segments` vertices around and `rings` rings, closed at the bottom and the top by
/// a fan to one hub vertex each, so the hubs have valence `segments` against about 6
/// elsewhere (the thesis' vase, §3.8.1).
pub fn vase(segments: usize, rings: usize) -> Mesh {
    let mut m = Mesh::default();
    let height = 3.0;
    for i in 0..rings {
        let z = height * i as f64 / (rings - 1) as f64;
        let r = 1.0 + 0.35 * (1.2 * z).sin();
        // Alternate rings are turned by half a segment so the sides are near-equilateral.
        let shift = if i % 2 == 1 { 0.5 } else { 0.0 };
        for j in 0..segments {
            let a = std::f64::consts::TAU * (j as f64 + shift) / segments as f64;
            m.positions.push(DVec3::new(r * a.cos(), r * a.sin(), z));
        }
    }
    let bottom = m.positions.len() as Index;
    m.positions.push(DVec3::new(0.0, 0.0, 0.0));
    let top = bottom + 1;
    m.positions.push(DVec3::new(0.0, 0.0, height));
    let at = |i: usize, j: usize| (i * segments + j % segments) as Index;
    for i in 0..rings - 1 {
        for j in 0..segments {
            if i % 2 == 0 {
                m.triangles.push([at(i, j), at(i, j + 1), at(i + 1, j)]);
                m.triangles
                    .push([at(i, j + 1), at(i + 1, j + 1), at(i + 1, j)]);
            } else {
                m.triangles.push([at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
                m.triangles.push([at(i, j), at(i, j + 1), at(i + 1, j + 1)]);
            }
        }
    }
    for j in 0..segments {
        m.triangles.push([bottom, at(0, j + 1), at(0, j)]);
        m.triangles
            .push([top, at(rings - 1, j), at(rings - 1, j + 1)]);
    }
    plain_wedges(&mut m);
    m
}

/// Panics unless every triangle of `m` faces away from the origin ([`outwardness`]):
/// "outward" for a closed shape that is star-shaped about the origin, as these shapes and
/// what the decimators make of a sphere are.
#[cfg(test)]
pub(crate) fn assert_faces_outward(m: &Mesh) {
    for t in 0..m.triangles.len() {
        assert!(outwardness(m, t) > 0.0, "triangle {t} faces inwards");
    }
}

/// `m` with a normal of its own on every triangle (+Z), so that each corner has a wedge of
/// its own: a scan whose normals split every vertex.
#[cfg(test)]
pub(crate) fn with_a_normal_per_triangle(mut m: Mesh) -> Mesh {
    let mut wedges = Vec::with_capacity(3 * m.triangles.len());
    for (t, triangle) in m.triangles.iter_mut().enumerate() {
        for w in triangle.iter_mut() {
            wedges.push(Wedge {
                normal: Some(t as Index),
                ..m.wedges[*w as usize]
            });
            *w = (wedges.len() - 1) as Index;
        }
    }
    m.wedges = wedges;
    m.normals = vec![DVec3::Z; m.triangles.len()];
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_are_valid_and_outward() {
        for m in [grid(3, 2), cube(), uv_sphere(2.0, 8, 12)] {
            m.check_invariants().unwrap();
        }
        for s in [
            uv_sphere(1.0, 8, 12),
            tetrahedron(),
            octahedron(),
            icosahedron(),
        ] {
            s.check_invariants().unwrap();
            assert_faces_outward(&s);
        }
        assert_eq!(tetrahedron().triangles.len(), 4);
        assert_eq!(octahedron().triangles.len(), 8);
        assert_eq!(icosahedron().triangles.len(), 20);
        assert_faces_outward(&cube());
    }

    #[test]
    fn torus_and_vase_are_closed_and_outward() {
        let t = torus(2.0, 0.7, 24, 12);
        t.check_invariants().unwrap();
        let topo = t.topology();
        assert_eq!(topo.counts().boundary_edges, 0);
        assert_eq!(topo.euler_characteristic(), 0);
        for k in 0..t.triangles.len() {
            let p = t.triangle_positions(k);
            let c = (p[0] + p[1] + p[2]) / 3.0;
            let axis = DVec3::new(c.x, c.y, 0.0).normalize() * 2.0;
            assert!(t.triangle_cross(k).dot(c - axis) > 0.0, "{k}");
        }
        let v = vase(30, 12);
        v.check_invariants().unwrap();
        let topo = v.topology();
        assert_eq!(topo.counts().boundary_edges, 0);
        assert_eq!(topo.counts().inconsistent_edges, 0);
        assert_eq!(topo.euler_characteristic(), 2);
        assert_eq!(
            topo.vertex_neighbours(v.positions.len() as u32 - 1).len(),
            30
        );
        // Outward: the signed volume is positive.
        let vol: f64 = (0..v.triangles.len())
            .map(|k| {
                let [a, b, c] = v.triangle_positions(k);
                a.dot(b.cross(c)) / 6.0
            })
            .sum();
        assert!(vol > 0.0);
    }
}
