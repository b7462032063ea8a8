//! Normal recompute (the decimation thesis' "Recompute normals", §6.4).
//!
//! The thesis: the new normal of a vertex is the normalised sum of the normals of its triangles.
//! It does not say whether face normals are weighted; we offer area weighting
//! (raw cross products, the plainest reading and our default) and angle weighting
//! (Thürmer & Wüthrich), which is less sensitive to irregular tessellation.
//! The result is written to every wedge of the vertex, which removes normal
//! discontinuities; with `crease_angle`, corners across an edge sharper than that angle
//! keep separate normals (the wedges split there), so hard edges stay hard.

use crate::mesh::wedges::WedgeInterner;
use crate::mesh::{Index, Mesh, Wedge};
use glam::DVec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum NormalWeighting {
    /// Face normals weighted by triangle area (the plainest reading of the thesis).
    #[default]
    Area,
    /// Face normals weighted by the corner angle at the vertex.
    Angle,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct NormalsParams {
    pub weighting: NormalWeighting,
    /// Degrees. Edges whose faces meet at a larger angle keep separate normals on each side.
    pub crease_angle: Option<f64>,
}

impl NormalsParams {
    pub fn validate(&self) -> Result<(), String> {
        match self.crease_angle {
            Some(a) if !(a > 0.0 && a <= 180.0) => {
                Err(format!("crease_angle must be in (0, 180] degrees, got {a}"))
            }
            _ => Ok(()),
        }
    }
}

/// What the step did.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct NormalsReport {
    pub normals: usize,
    pub wedges_before: usize,
    pub wedges_after: usize,
    /// Vertices that received more than one normal because of creases.
    pub crease_vertices: usize,
    /// Normals whose weighted sum was zero (only degenerate triangles around them); set to +Z.
    pub zero_normals: usize,
}

fn find(parent: &mut [Index], mut x: Index) -> Index {
    while parent[x as usize] != x {
        parent[x as usize] = parent[parent[x as usize] as usize];
        x = parent[x as usize];
    }
    x
}

/// For every corner (3t + k), the class of corners that share its normal, as dense ids in
/// order of first appearance; and each class's vertex. With no crease angle a class is a
/// vertex (ids = vertex indices); with one, the corners joined across smooth manifold edges.
fn corner_classes(mesh: &Mesh, crease_angle: Option<f64>) -> (Vec<Index>, Vec<Index>) {
    let corner_vertex = |c: usize| mesh.wedges[mesh.triangles[c / 3][c % 3] as usize].vertex;
    let corners = mesh.triangles.len() * 3;
    let Some(angle) = crease_angle else {
        let classes = (0..corners).map(corner_vertex).collect();
        return (classes, (0..mesh.positions.len() as Index).collect());
    };
    let cos_limit = angle.to_radians().cos();
    let unit = |t: usize| mesh.triangle_cross(t).normalize_or_zero();
    // Half-edges keyed by their sorted vertex pair; sorting groups the sides of each edge.
    let mut half: Vec<(Index, Index, Index)> = Vec::with_capacity(corners);
    for t in 0..mesh.triangles.len() {
        let v = mesh.triangle_vertices(t);
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            half.push((a.min(b), a.max(b), (3 * t + k) as Index));
        }
    }
    half.par_sort_unstable();
    let mut parent: Vec<Index> = (0..corners as Index).collect();
    let mut i = 0;
    while i < half.len() {
        let mut j = i + 1;
        while j < half.len() && half[j].0 == half[i].0 && half[j].1 == half[i].1 {
            j += 1;
        }
        if j - i == 2 {
            let (c1, c2) = (half[i].2 as usize, half[i + 1].2 as usize);
            let (t1, t2) = (c1 / 3, c2 / 3);
            if unit(t1).dot(unit(t2)) >= cos_limit {
                // Join the corners at both ends of the edge across the two triangles.
                for end in [(c1 % 3), (c1 % 3 + 1) % 3] {
                    let vertex = mesh.triangle_vertices(t1)[end];
                    let k2 = mesh
                        .triangle_vertices(t2)
                        .iter()
                        .position(|&x| x == vertex)
                        .expect("shared edge vertex");
                    let (a, b) = (
                        find(&mut parent, (3 * t1 + end) as Index),
                        find(&mut parent, (3 * t2 + k2) as Index),
                    );
                    if a != b {
                        parent[a.max(b) as usize] = a.min(b);
                    }
                }
            }
        }
        i = j;
    }
    drop(half);
    // Dense ids in order of first appearance, reusing `parent` as the root → id table.
    let mut class_vertex = Vec::new();
    let mut classes = Vec::with_capacity(corners);
    let mut id_of_root = vec![Index::MAX; corners];
    for c in 0..corners {
        let root = find(&mut parent, c as Index) as usize;
        if id_of_root[root] == Index::MAX {
            id_of_root[root] = class_vertex.len() as Index;
            class_vertex.push(corner_vertex(c));
        }
        classes.push(id_of_root[root]);
    }
    (classes, class_vertex)
}

/// Each class's sum of the weighted normals of the faces at its corners (sequential: a
/// scatter). `class_of(c)` is corner `c`'s (`3t + k`) class, `None` for a corner that takes
/// no part.
fn class_sums(
    mesh: &Mesh,
    weighting: NormalWeighting,
    classes: usize,
    class_of: impl Fn(usize) -> Option<usize>,
) -> Vec<DVec3> {
    let mut sums = vec![DVec3::ZERO; classes];
    for t in 0..mesh.triangles.len() {
        let cross = mesh.triangle_cross(t);
        if !cross.is_finite() {
            continue;
        }
        let p = mesh.triangle_positions(t);
        for k in 0..3 {
            let Some(class) = class_of(3 * t + k) else {
                continue;
            };
            let weight = match weighting {
                NormalWeighting::Area => cross,
                NormalWeighting::Angle => {
                    let (e1, e2) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
                    cross.normalize_or_zero() * e1.angle_between(e2).max(0.0)
                }
            };
            if weight.is_finite() {
                sums[class] += weight;
            }
        }
    }
    sums
}

/// Recomputes normals and writes them to the wedges.
pub fn recompute_normals(mesh: &mut Mesh, params: &NormalsParams) -> NormalsReport {
    let wedges_before = mesh.wedges.len();
    let (corner_class, class_vertex) = corner_classes(mesh, params.crease_angle);

    let sums = class_sums(mesh, params.weighting, class_vertex.len(), |c| {
        Some(corner_class[c] as usize)
    });
    let mut zero_normals = 0;
    let normals: Vec<DVec3> = sums
        .iter()
        .map(|s| {
            let n = s.normalize_or_zero();
            if n == DVec3::ZERO {
                zero_normals += 1;
                DVec3::Z
            } else {
                n
            }
        })
        .collect();
    drop(sums);

    let mut per_vertex = vec![0u32; mesh.positions.len()];
    for &v in &class_vertex {
        per_vertex[v as usize] += 1;
    }
    let crease_vertices = per_vertex.iter().filter(|&&n| n > 1).count();

    // Rebuild the wedges: a wedge is now (vertex, texcoord, class normal).
    let mut interner = WedgeInterner::new(mesh.positions.len());
    for (c, &class) in corner_class.iter().enumerate() {
        let (t, k) = (c / 3, c % 3);
        let old = mesh.wedges[mesh.triangles[t][k] as usize];
        mesh.triangles[t][k] = interner.intern(Wedge {
            vertex: old.vertex,
            texcoord: old.texcoord,
            normal: Some(class),
        });
    }
    mesh.wedges = interner.into_wedges();
    mesh.normals = normals;
    NormalsReport {
        normals: mesh.normals.len(),
        wedges_before,
        wedges_after: mesh.wedges.len(),
        crease_vertices,
        zero_normals,
    }
}

/// What [`refresh_normals`] did.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct NormalsRefresh {
    /// Normals written: one for each group of a vertex's corners that shared a normal.
    pub normals: usize,
    /// Of those, normals left as they were because every triangle around them has zero area.
    pub kept: usize,
}

/// Two normals of one vertex closer than this (degrees) were one smooth normal that a file
/// stored twice (a vertex repeated at a texture seam, its normal rounded differently); they
/// are refreshed as one, so the seam gets no crease. A hard edge or a flat-shaded face turns
/// its normals by far more.
const SAME_NORMAL_DEGREES: f64 = 1.0;

/// Recomputes the normals a mesh already has, after its vertices moved, without changing
/// how they are shared: the corners of a vertex that shared a normal share the new one, and
/// corners that had their own (a hard edge, a flat-shaded face) keep their own. Each is the
/// normalised sum of the area-weighted normals of the triangles whose corners use it, the
/// `normals` step's default weighting (thesis §6.4). Wedges and their numbering are
/// unchanged; a wedge without a normal stays without one. The runner calls this after a
/// run of vertex-moving steps (`relax`, `fair`, `smooth`) that no `normals` step follows, so
/// that the scan's own normals are not written stale.
pub fn refresh_normals(mesh: &mut Mesh) -> NormalsRefresh {
    const NONE: Index = Index::MAX;
    let same = SAME_NORMAL_DEGREES.to_radians().cos();
    // The groups ("classes") of each vertex, numbered in wedge order: a list per vertex
    // through `first` and `next`, each class with the normal it had.
    let mut first = vec![NONE; mesh.positions.len()];
    let mut next: Vec<Index> = Vec::new();
    let mut old_normal: Vec<DVec3> = Vec::new();
    let mut wedge_class = Vec::with_capacity(mesh.wedges.len());
    for w in &mesh.wedges {
        let Some(n) = w.normal else {
            wedge_class.push(NONE);
            continue;
        };
        let normal = mesh.normals[n as usize];
        let unit = normal.normalize_or_zero();
        let mut class = first[w.vertex as usize];
        while class != NONE {
            let had = old_normal[class as usize];
            if had == normal || had.normalize_or_zero().dot(unit) >= same {
                break;
            }
            class = next[class as usize];
        }
        if class == NONE {
            class = old_normal.len() as Index;
            old_normal.push(normal);
            next.push(first[w.vertex as usize]);
            first[w.vertex as usize] = class;
        }
        wedge_class.push(class);
    }
    drop((first, next));
    let sums = class_sums(mesh, NormalWeighting::Area, old_normal.len(), |c| {
        let class = wedge_class[mesh.triangles[c / 3][c % 3] as usize];
        (class != NONE).then_some(class as usize)
    });
    let mut kept = 0;
    mesh.normals = sums
        .iter()
        .zip(&old_normal)
        .map(|(s, &old)| {
            let n = s.normalize_or_zero();
            if n == DVec3::ZERO {
                kept += 1;
                old
            } else {
                n
            }
        })
        .collect();
    for (w, &class) in mesh.wedges.iter_mut().zip(&wedge_class) {
        if class != NONE {
            w.normal = Some(class);
        }
    }
    NormalsRefresh {
        normals: mesh.normals.len(),
        kept,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::{cube, grid, uv_sphere, with_a_normal_per_triangle};

    #[test]
    fn flat_grid_normals_point_up() {
        let mut m = grid(4, 4);
        let r = recompute_normals(&mut m, &NormalsParams::default());
        assert_eq!(r.normals, m.positions.len());
        for n in &m.normals {
            assert!((*n - DVec3::Z).length() < 1e-12);
        }
        m.check_invariants().unwrap();
    }

    #[test]
    fn cube_smooth_vs_crease() {
        let mut smooth = cube();
        recompute_normals(&mut smooth, &NormalsParams::default());
        assert_eq!(smooth.normals.len(), 8);
        for (w, n) in smooth
            .wedges
            .iter()
            .map(|w| (w, smooth.normals[w.normal.unwrap() as usize]))
        {
            // Area weighting depends on the triangulation, so only "outwards" is certain.
            let p = smooth.positions[w.vertex as usize];
            assert!(n.dot(p.normalize()) > 0.5, "{n} at {p}");
        }
        let mut creased = cube();
        let r = recompute_normals(
            &mut creased,
            &NormalsParams {
                crease_angle: Some(45.0),
                ..Default::default()
            },
        );
        // Each of the 8 corners touches 3 faces: 24 normals, all axis-aligned.
        assert_eq!(r.normals, 24);
        assert_eq!(r.crease_vertices, 8);
        for n in &creased.normals {
            assert!((n.abs().max_element() - 1.0).abs() < 1e-12);
        }
        creased.check_invariants().unwrap();
    }

    #[test]
    fn angle_weighting_is_unit_and_outward() {
        let mut m = cube();
        recompute_normals(
            &mut m,
            &NormalsParams {
                weighting: NormalWeighting::Angle,
                crease_angle: None,
            },
        );
        // The angles of each face at a cube corner sum to 90° whatever the triangulation,
        // so angle weighting gives exactly the diagonal.
        for w in &m.wedges {
            let (n, p) = (
                m.normals[w.normal.unwrap() as usize],
                m.positions[w.vertex as usize],
            );
            assert!((n - p.normalize()).length() < 1e-12, "{n} at {p}");
        }
    }

    /// A sphere whose normals are stale. Shared: one per vertex, every one along +Z.
    /// Flat-shaded: each triangle's corners have that triangle's own normal, computed before
    /// the sphere was stretched along Z.
    fn sphere_with_stale_normals(shared: bool) -> Mesh {
        let mut m = uv_sphere(1.0, 8, 12);
        if shared {
            for w in &mut m.wedges {
                w.normal = Some(0);
            }
            m.normals = vec![DVec3::Z];
        } else {
            m = with_a_normal_per_triangle(m);
            m.normals = (0..m.triangles.len())
                .map(|t| m.triangle_cross(t).normalize())
                .collect();
            for p in &mut m.positions {
                p.z *= 1.5;
            }
        }
        m
    }

    #[test]
    fn refreshed_normals_follow_the_surface_and_keep_their_sharing() {
        // One normal per vertex: each becomes the vertex's smooth normal (outward on a
        // sphere), the wedges untouched.
        let mut smooth = sphere_with_stale_normals(true);
        let wedges = smooth.wedges.clone();
        let r = refresh_normals(&mut smooth);
        assert_eq!((r.normals, r.kept), (smooth.positions.len(), 0));
        assert_eq!(smooth.wedges.len(), wedges.len());
        for (w, old) in smooth.wedges.iter().zip(&wedges) {
            assert_eq!((w.vertex, w.texcoord), (old.vertex, old.texcoord));
            let (n, p) = (
                smooth.normals[w.normal.unwrap() as usize],
                smooth.positions[w.vertex as usize],
            );
            assert!(n.dot(p.normalize()) > 0.95, "{n} at {p}");
        }
        // Flat shading: each corner's normal becomes its own triangle's, so the faces stay
        // flat on the stretched sphere. (The two triangles of a quad between two rings lie
        // in one plane, so their corners at a vertex share one normal: fewer than 3 a
        // triangle, more than one a vertex.)
        let mut flat = sphere_with_stale_normals(false);
        let corner_normals = |m: &Mesh| -> Vec<DVec3> {
            (m.triangles.iter().flatten())
                .map(|&w| m.normals[m.wedges[w as usize].normal.unwrap() as usize])
                .collect()
        };
        let stale = corner_normals(&flat);
        let r = refresh_normals(&mut flat);
        assert!(r.normals > 2 * flat.positions.len(), "{}", r.normals);
        for t in 0..flat.triangles.len() {
            let face = flat.triangle_cross(t).normalize();
            for &w in &flat.triangles[t] {
                let n = flat.normals[flat.wedges[w as usize].normal.unwrap() as usize];
                assert!((n - face).length() < 1e-12, "{n} against {face}");
            }
        }
        let fresh = corner_normals(&flat);
        assert!(fresh.iter().zip(&stale).any(|(n, s)| n.dot(*s) < 0.99));
        flat.check_invariants().unwrap();
        smooth.check_invariants().unwrap();
    }

    #[test]
    fn a_normal_stored_twice_is_refreshed_as_one() {
        // A vertex's corners split between two normals that differ in the last digits, as
        // a file that repeats a vertex at a texture seam may store them.
        let mut m = sphere_with_stale_normals(true);
        m.normals.push(DVec3::new(1e-9, 0.0, 1.0));
        let vertex = m.wedges[m.triangles[20][0] as usize].vertex;
        let twin = m.wedges.len() as Index;
        m.wedges.push(Wedge {
            normal: Some(1),
            ..m.wedges[m.triangles[20][0] as usize]
        });
        m.triangles[20][0] = twin;
        let users: Vec<Index> = (0..m.wedges.len() as Index)
            .filter(|&w| m.wedges[w as usize].vertex == vertex)
            .collect();
        assert_eq!(users.len(), 2);
        let r = refresh_normals(&mut m);
        assert_eq!(r.normals, m.positions.len());
        let [a, b] = [users[0], users[1]].map(|w| m.wedges[w as usize].normal);
        assert_eq!(a, b);
        // Two normals far apart at one vertex (a hard edge) stay two.
        let mut m = sphere_with_stale_normals(true);
        m.normals.push(DVec3::X);
        let twin = m.wedges.len() as Index;
        m.wedges.push(Wedge {
            normal: Some(1),
            ..m.wedges[m.triangles[20][0] as usize]
        });
        m.triangles[20][0] = twin;
        assert_eq!(refresh_normals(&mut m).normals, m.positions.len() + 1);
    }

    #[test]
    fn refresh_keeps_what_it_cannot_recompute() {
        let mut m = sphere_with_stale_normals(true);
        // A wedge without a normal stays without one.
        let bare = m.wedges.len();
        let first = m.triangles[0][0];
        m.wedges.push(Wedge {
            normal: None,
            ..m.wedges[first as usize]
        });
        m.triangles[0][0] = bare as Index;
        // A vertex whose triangles all have zero area keeps its normal.
        let pole = m.wedges[m.triangles[5][1] as usize].vertex;
        let stuck: Vec<usize> = (0..m.triangles.len())
            .filter(|&t| m.triangle_vertices(t).contains(&pole))
            .collect();
        for &t in &stuck {
            for v in m.triangle_vertices(t) {
                m.positions[v as usize] = m.positions[pole as usize];
            }
        }
        let r = refresh_normals(&mut m);
        assert!(r.kept >= 1);
        assert_eq!(m.wedges[bare].normal, None);
        let at_pole = m
            .wedges
            .iter()
            .find(|w| w.vertex == pole && w.normal.is_some())
            .unwrap();
        assert_eq!(m.normals[at_pole.normal.unwrap() as usize], DVec3::Z);
        m.check_invariants().unwrap();
    }

    #[test]
    fn rejects_bad_crease_angle() {
        let p = NormalsParams {
            crease_angle: Some(0.0),
            ..Default::default()
        };
        assert!(p.validate().is_err());
    }
}
