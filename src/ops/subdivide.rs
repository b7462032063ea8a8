//! Seam-keeping 1→4 midpoint subdivision. Used to make scanner-sized meshes (about 400,000
//! triangles) from the real scans for benchmarks: positions do not move (midpoints only), so
//! the surface stays the same, and texture seams stay seams because each side of a seam
//! edge interpolates its own texture coordinates.

use crate::mesh::{Index, Mesh, Wedge};
// The maps are only looked up (the output order follows the triangles), so a fast
// non-cryptographic hash changes nothing but the time.
use rustc_hash::FxHashMap as HashMap;

/// A midpoint is shared by everything that references the same unordered pair.
fn pair(a: Index, b: Index) -> (Index, Index) {
    (a.min(b), a.max(b))
}

/// Splits every triangle into four at its edge midpoints. Materials and triangle origins are
/// inherited from the parent triangle.
pub fn subdivide(mesh: &Mesh) -> Mesh {
    let mut out = Mesh {
        triangles: Vec::with_capacity(mesh.triangles.len() * 4),
        triangle_origins: Vec::with_capacity(mesh.triangles.len() * 4),
        ..mesh.without_triangles()
    };
    let mut mids = Midpoints::new(mesh);
    for t in 0..mesh.triangles.len() {
        let w = mesh.triangles[t].map(|i| mesh.wedges[i as usize]);
        let m: [Index; 3] = std::array::from_fn(|k| mids.wedge(&mut out, w[k], w[(k + 1) % 3]));
        push_children(&mut out, mesh, t, m);
    }
    out
}

/// The four children of triangle `t` whose edge midpoints are the wedges `m`, with its
/// origin and material.
fn push_children(out: &mut Mesh, mesh: &Mesh, t: usize, m: [Index; 3]) {
    let c = mesh.triangles[t];
    out.triangles.push([c[0], m[0], m[2]]);
    out.triangles.push([m[0], c[1], m[1]]);
    out.triangles.push([m[2], m[1], c[2]]);
    out.triangles.push([m[0], m[1], m[2]]);
    let origin = mesh.triangle_origin(t);
    out.triangle_origins.extend([origin; 4]);
    if !mesh.triangle_materials.is_empty() {
        out.triangle_materials
            .extend([mesh.triangle_materials[t]; 4]);
    }
}

/// The midpoints made so far, each once: of vertices, texture coordinates, normals and
/// wedges, as indices into the output mesh.
struct Midpoints<'a> {
    mesh: &'a Mesh,
    vertex: HashMap<(Index, Index), Index>,
    texcoord: HashMap<(Index, Index), Index>,
    normal: HashMap<(Index, Index), Index>,
    wedge: HashMap<Wedge, Index>,
}

impl<'a> Midpoints<'a> {
    fn new(mesh: &'a Mesh) -> Self {
        Midpoints {
            mesh,
            vertex: HashMap::default(),
            texcoord: HashMap::default(),
            normal: HashMap::default(),
            wedge: HashMap::default(),
        }
    }

    /// The midpoint wedge of the edge from wedge `a` to wedge `b`.
    fn wedge(&mut self, out: &mut Mesh, a: Wedge, b: Wedge) -> Index {
        let wedge = Wedge {
            vertex: self.vertex(out, a.vertex, b.vertex),
            texcoord: match (a.texcoord, b.texcoord) {
                (Some(ta), Some(tb)) => Some(self.texcoord(out, ta, tb)),
                _ => None,
            },
            normal: match (a.normal, b.normal) {
                (Some(na), Some(nb)) => Some(self.normal(out, na, nb)),
                _ => None,
            },
        };
        *self.wedge.entry(wedge).or_insert_with(|| {
            out.wedges.push(wedge);
            (out.wedges.len() - 1) as Index
        })
    }

    /// The midpoint vertex of `a` and `b`, with the mean of their colours.
    fn vertex(&mut self, out: &mut Mesh, a: Index, b: Index) -> Index {
        let mesh = self.mesh;
        *self.vertex.entry(pair(a, b)).or_insert_with(|| {
            let (pa, pb) = (mesh.positions[a as usize], mesh.positions[b as usize]);
            out.positions.push((pa + pb) * 0.5);
            if !mesh.colors.is_empty() {
                let (ca, cb) = (mesh.colors[a as usize], mesh.colors[b as usize]);
                out.colors.push(std::array::from_fn(|i| {
                    ((ca[i] as u16 + cb[i] as u16) / 2) as u8
                }));
            }
            (out.positions.len() - 1) as Index
        })
    }

    fn texcoord(&mut self, out: &mut Mesh, ta: Index, tb: Index) -> Index {
        let mesh = self.mesh;
        *self.texcoord.entry(pair(ta, tb)).or_insert_with(|| {
            out.texcoords
                .push((mesh.texcoords[ta as usize] + mesh.texcoords[tb as usize]) * 0.5);
            (out.texcoords.len() - 1) as Index
        })
    }

    fn normal(&mut self, out: &mut Mesh, na: Index, nb: Index) -> Index {
        let mesh = self.mesh;
        *self.normal.entry(pair(na, nb)).or_insert_with(|| {
            let n = (mesh.normals[na as usize] + mesh.normals[nb as usize]).normalize_or_zero();
            out.normals.push(n);
            (out.normals.len() - 1) as Index
        })
    }
}

/// A scanner-sized test scan made from a real one: subdivided until it has at least `faces`
/// triangles, then the `faces` triangles whose centroids lie nearest the mesh's centre are
/// kept (one coherent patch, as a scanner's field of view gives, rather than the first
/// `faces` in file order, which leaves hundreds of scattered pieces). Used by benchmarks and
/// `examples/scanner_sized`.
pub fn scanner_sized(mesh: &Mesh, faces: usize) -> Mesh {
    let mut mesh = mesh.clone();
    while mesh.triangles.len() < faces && !mesh.triangles.is_empty() {
        mesh = subdivide(&mesh);
    }
    if mesh.triangles.len() <= faces {
        return mesh;
    }
    let centroids: Vec<glam::DVec3> = (0..mesh.triangles.len())
        .map(|t| {
            let [a, b, c] = mesh.triangle_positions(t);
            (a + b + c) / 3.0
        })
        .collect();
    let centre = centroids.iter().sum::<glam::DVec3>() / centroids.len() as f64;
    let mut order: Vec<usize> = (0..centroids.len()).collect();
    order.sort_by(|&a, &b| {
        centroids[a]
            .distance_squared(centre)
            .total_cmp(&centroids[b].distance_squared(centre))
            .then(a.cmp(&b))
    });
    let mut keep = vec![false; centroids.len()];
    for &t in &order[..faces] {
        keep[t] = true;
    }
    let mut kept = keep.iter();
    mesh.triangles.retain(|_| *kept.next().unwrap_or(&false));
    if !mesh.triangle_materials.is_empty() {
        let mut kept = keep.iter();
        mesh.triangle_materials
            .retain(|_| *kept.next().unwrap_or(&false));
    }
    mesh.triangle_origins.clear();
    mesh.compact();
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::{grid, uv_sphere};

    #[test]
    fn scanner_sized_is_one_patch_of_the_size_asked() {
        let s = scanner_sized(&grid(10, 10), 500);
        assert_eq!(s.triangles.len(), 500);
        assert_eq!(crate::mesh::Topology::new(&s).component_count(), 1);
        assert!(s.check_invariants().is_ok());
        // Already big enough: unchanged.
        assert_eq!(scanner_sized(&grid(3, 3), 18).triangles.len(), 18);
    }

    #[test]
    fn quadruples_faces_and_keeps_area() {
        let m = uv_sphere(1.0, 6, 8);
        let s = subdivide(&m);
        s.check_invariants().unwrap();
        assert_eq!(s.triangles.len(), 4 * m.triangles.len());
        let area = |m: &Mesh| {
            (0..m.triangles.len())
                .map(|t| m.triangle_area(t))
                .sum::<f64>()
        };
        assert!((area(&m) - area(&s)).abs() < 1e-12);
        // Euler characteristic of a closed sphere stays 2: V' = V + E, E = 3F/2.
        assert_eq!(
            s.positions.len(),
            m.positions.len() + 3 * m.triangles.len() / 2
        );
        assert_eq!(s.triangle_origins[7], 1);
    }

    #[test]
    fn seam_edges_get_two_midpoint_wedges() {
        // A 1x1 grid whose two triangles use separate texture coordinates along the diagonal.
        let mut m = grid(1, 1);
        let diag_far = m.wedges[3];
        m.texcoords.push(glam::DVec2::new(0.9, 0.9));
        let t = (m.texcoords.len() - 1) as Index;
        m.wedges.push(Wedge {
            texcoord: Some(t),
            ..diag_far
        });
        m.triangles[1][1] = 4; // second triangle uses the seam copy of vertex 3
        let s = subdivide(&m);
        s.check_invariants().unwrap();
        // 4 corners + 5 edge midpoints; the diagonal midpoint has two wedges.
        assert_eq!(s.positions.len(), 9);
        let diag_mid = s
            .positions
            .iter()
            .position(|p| (*p - glam::DVec3::new(0.5, 0.5, 0.0)).length() < 1e-12)
            .unwrap() as Index;
        assert_eq!(s.wedges.iter().filter(|w| w.vertex == diag_mid).count(), 2);
    }
}
