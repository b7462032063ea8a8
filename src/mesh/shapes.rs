//! Small generated meshes with known properties, for unit tests and examples across the
//! crate (a flat grid with texture coordinates, a cube, a UV sphere).

use super::model::{Index, Mesh, Wedge};
use glam::{DVec2, DVec3};

/// A flat `nx` × `ny` grid of unit squares in the z = 0 plane, two triangles per square,
/// counter-clockwise seen from +Z, one wedge per vertex with texture coordinates in [0,1]².
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
    m.wedges = (0..m.positions.len() as Index)
        .map(|v| Wedge {
            vertex: v,
            texcoord: None,
            normal: None,
        })
        .collect();
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
        let s = uv_sphere(1.0, 8, 12);
        for t in 0..s.triangles.len() {
            let p = s.triangle_positions(t);
            let centre = (p[0] + p[1] + p[2]) / 3.0;
            assert!(
                s.triangle_cross(t).dot(centre) > 0.0,
                "triangle {t} faces inwards"
            );
        }
        let c = cube();
        for t in 0..c.triangles.len() {
            let p = c.triangle_positions(t);
            let centre = (p[0] + p[1] + p[2]) / 3.0;
            assert!(
                c.triangle_cross(t).dot(centre) > 0.0,
                "cube triangle {t} faces inwards"
            );
        }
    }
}
