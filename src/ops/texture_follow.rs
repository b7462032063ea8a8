//! Keeping the texture on the surface when vertices slide along it.
//!
//! `relax` moves vertices tangentially (the non-uniformity criterion of the fairing thesis, ch. 3)
//! and `fair` moves border vertices along the border and interior ones off their old spot;
//! the thesis keeps every texture coordinate as it was, so the photo slides with the
//! vertices: on james_face_stereo_capture `relax` alone left a mean texture deviation of 6.0
//! (colour units, 0–255) and `fair` 7.5, visible as smeared eyebrows and lips. After such a
//! step, each corner (wedge) gets the texture coordinates of the point of the surface
//! *before the step* closest to its vertex's new position, as long as that point lies in the
//! corner's own texture chart; otherwise (a vertex that slid across a seam) the closest
//! point among the corner's own triangles, which are in its chart by definition. Seams and
//! wedges stay as they are; only texture coordinate values change.

use crate::geom::bvh::{TriangleBvh, TriangleHit};
use crate::mesh::{Index, Mesh};
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use serde::Serialize;

#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct FollowReport {
    /// Corners whose texture coordinates were re-read from the surface.
    pub corners: usize,
    /// Of those, corners whose closest point lay in another chart (read from their own
    /// triangles instead).
    pub across_seam: usize,
    /// Mean and largest change of a corner's texture coordinates (texture space, [0, 1]).
    pub mean_shift: f64,
    pub max_shift: f64,
}

/// Chart of each triangle (`u32::MAX` without texture coordinates): triangles that share a
/// texture coordinate (by index) are in one chart. Coordinates are deduplicated on load, so
/// two triangles meeting at a point of the texture image are joined; across a seam the two
/// sides have different coordinates and stay apart. Union-find over texture coordinate
/// indices: 4 bytes per coordinate, no edge list.
pub(crate) fn charts(mesh: &Mesh) -> Vec<u32> {
    let mut parent: Vec<u32> = (0..mesh.texcoords.len() as u32).collect();
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            parent[x as usize] = parent[parent[x as usize] as usize];
            x = parent[x as usize];
        }
        x
    }
    let corner_texcoords = |t: usize| mesh.triangles[t].map(|w| mesh.wedges[w as usize].texcoord);
    for t in 0..mesh.triangles.len() {
        if let [Some(a), Some(b), Some(c)] = corner_texcoords(t) {
            for (x, y) in [(a, b), (a, c)] {
                let (rx, ry) = (find(&mut parent, x), find(&mut parent, y));
                if rx != ry {
                    // The smaller root wins: the result does not depend on visiting order.
                    parent[rx.max(ry) as usize] = rx.min(ry);
                }
            }
        }
    }
    (0..mesh.triangles.len())
        .map(|t| match corner_texcoords(t) {
            [Some(a), Some(_), Some(_)] => find(&mut parent, a),
            _ => u32::MAX,
        })
        .collect()
}

/// The triangles around each wedge (CSR).
pub(crate) struct WedgeTriangles {
    offsets: Vec<u32>,
    triangles: Vec<u32>,
}

impl WedgeTriangles {
    pub(crate) fn of(mesh: &Mesh) -> Self {
        let mut offsets = vec![0u32; mesh.wedges.len() + 1];
        for tri in &mesh.triangles {
            for &w in tri {
                offsets[w as usize + 1] += 1;
            }
        }
        for i in 1..offsets.len() {
            offsets[i] += offsets[i - 1];
        }
        let mut next = offsets.clone();
        let mut triangles = vec![0u32; 3 * mesh.triangles.len()];
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for &w in tri {
                triangles[next[w as usize] as usize] = t as u32;
                next[w as usize] += 1;
            }
        }
        WedgeTriangles { offsets, triangles }
    }

    pub(crate) fn of_wedge(&self, w: Index) -> &[u32] {
        &self.triangles[self.offsets[w as usize] as usize..self.offsets[w as usize + 1] as usize]
    }
}

/// Texture coordinates of `mesh` at a point found on it.
pub(crate) fn uv_at(mesh: &Mesh, hit: &TriangleHit) -> Option<DVec2> {
    let [a, b, c] = mesh.triangles[hit.triangle as usize].map(|w| mesh.wedge_texcoord(w));
    Some(a? * hit.bary.x + b? * hit.bary.y + c? * hit.bary.z)
}

/// Re-reads the texture coordinates of `mesh` from the surface it had before a step moved
/// its vertices (same wedges and triangles; `before_positions` are its old positions: only
/// those are kept, not a copy of the mesh). Does nothing to an untextured mesh.
pub fn follow(mesh: &mut Mesh, before_positions: Vec<DVec3>) -> FollowReport {
    follow_with(mesh, before_positions, |_| None)
}

/// [`follow`] with a closest-point index over the surface as it was from `index`, when it
/// has one: `index` gets the mesh as it was (at `before_positions`) and may answer with an
/// index of its own over the same triangles at the same positions, all of them indexed (a
/// copy of the surface the caller keeps for more queries). It is asked beside the reads
/// that do not need it, as building the follow's own index would be.
pub fn follow_with<'t>(
    mesh: &mut Mesh,
    before_positions: Vec<DVec3>,
    index: impl FnOnce(&Mesh) -> Option<&'t TriangleBvh<'t>> + Send,
) -> FollowReport {
    if !mesh.has_texcoords()
        || mesh.triangles.is_empty()
        || before_positions.len() != mesh.positions.len()
        || !before_positions.iter().all(|p| p.is_finite())
        || !mesh.positions.iter().all(|p| p.is_finite())
    {
        return FollowReport::default();
    }
    // The mesh as it was, and the new positions beside it.
    let moved = std::mem::replace(&mut mesh.positions, before_positions);
    let (updates, across) = read_back(mesh, &moved, index);
    mesh.positions = moved;
    apply(mesh, updates, across)
}

/// Per wedge of `before`, the texture coordinates at its vertex's new position (or none),
/// and how many came from the corner's own triangles (across a seam).
fn read_back<'t>(
    before: &Mesh,
    moved: &[DVec3],
    index: impl FnOnce(&Mesh) -> Option<&'t TriangleBvh<'t>> + Send,
) -> (Vec<Option<DVec2>>, usize) {
    // The charts and the triangles of each wedge (their chart is the wedge's: a wedge never
    // spans a seam) are sequential; they are made beside the tree, whose build is parallel.
    let ((chart, around), (given, own)) = rayon::join(
        || rayon::join(|| charts(before), || WedgeTriangles::of(before)),
        || match index(before) {
            Some(tree) => (Some(tree), None),
            None => (
                None,
                Some(TriangleBvh::new(
                    before,
                    (0..before.triangles.len() as u32).collect(),
                )),
            ),
        },
    );
    let bvh = given.or(own.as_ref()).expect("an index, given or built");
    // Per wedge: new texture coordinates (or none) and whether it went across a seam.
    let updates: Vec<Option<(DVec2, bool)>> = (0..before.wedges.len())
        .into_par_iter()
        .map(|w| {
            let own_triangles = around.of_wedge(w as Index);
            let &own = own_triangles.first()?;
            let wedge = before.wedges[w];
            wedge.texcoord?;
            let p: DVec3 = moved[wedge.vertex as usize];
            let start = bvh.hit_on(p, own);
            let hit = bvh.closest(p, Some(start)).unwrap_or(start);
            if chart[hit.triangle as usize] == chart[own as usize] {
                return uv_at(before, &hit).map(|uv| (uv, false));
            }
            // Across a seam: the nearest of the wedge's own triangles.
            let best = own_triangles
                .iter()
                .map(|&t| bvh.hit_on(p, t))
                .min_by(|a, b| a.distance_squared.total_cmp(&b.distance_squared))
                .unwrap_or(start);
            uv_at(before, &best).map(|uv| (uv, true))
        })
        .collect();
    let across = updates
        .iter()
        .filter(|u| matches!(u, Some((_, true))))
        .count();
    (
        updates.into_iter().map(|u| u.map(|(uv, _)| uv)).collect(),
        across,
    )
}

fn apply(mesh: &mut Mesh, updates: Vec<Option<DVec2>>, across_seam: usize) -> FollowReport {
    let mut report = FollowReport {
        across_seam,
        ..FollowReport::default()
    };
    let mut total_shift = 0.0;
    // Room for exactly the appended coordinates: growing by doubling would leave the mesh,
    // which lives on as the decimation's input and seam reference, up to four times the
    // texture coordinates it keeps.
    mesh.texcoords
        .reserve_exact(updates.iter().filter(|u| u.is_some()).count());
    for (w, update) in updates.into_iter().enumerate() {
        let Some(uv) = update else { continue };
        let old = mesh.wedge_texcoord(w as Index).unwrap_or(uv);
        let shift = old.distance(uv);
        total_shift += shift;
        report.max_shift = report.max_shift.max(shift);
        report.corners += 1;
        mesh.texcoords.push(uv);
        mesh.wedges[w].texcoord = Some((mesh.texcoords.len() - 1) as Index);
    }
    if report.corners > 0 {
        report.mean_shift = total_shift / report.corners as f64;
    }
    mesh.compact();
    report
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::grid;

    #[test]
    fn sliding_vertices_take_the_texture_of_where_they_land() {
        // A flat grid with texture = position / size: after sliding interior vertices in the
        // plane, each corner's texture must again be its position / size.
        let before = grid(6, 6);
        let mut moved = before.clone();
        for (i, p) in moved.positions.iter_mut().enumerate() {
            let (x, y) = (p.x, p.y);
            if x > 0.0 && x < 6.0 && y > 0.0 && y < 6.0 {
                p.x += 0.3 * ((i % 3) as f64 - 1.0);
                p.y += 0.2 * ((i % 5) as f64 - 2.0) * 0.5;
            }
        }
        let r = follow(&mut moved, before.positions.clone());
        assert_eq!(r.corners, before.wedges.len());
        assert_eq!(r.across_seam, 0);
        assert!(r.max_shift > 0.0);
        // One coordinate per wedge now, and no room for the old ones: the mesh lives on
        // through the decimation's memory peak.
        assert_eq!(moved.texcoords.len(), before.wedges.len());
        assert_eq!(moved.texcoords.capacity(), moved.texcoords.len());
        for w in 0..moved.wedges.len() {
            let p = moved.positions[moved.wedges[w].vertex as usize];
            let uv = moved.wedge_texcoord(w as Index).unwrap();
            assert!(
                (uv - DVec2::new(p.x / 6.0, p.y / 6.0)).length() < 1e-12,
                "{w}"
            );
        }
    }

    #[test]
    fn unmoved_mesh_keeps_its_texture_and_untextured_is_untouched() {
        let before = grid(3, 3);
        let mut same = before.clone();
        let r = follow(&mut same, before.positions.clone());
        assert_eq!(r.max_shift, 0.0);
        for w in 0..same.wedges.len() {
            let a = same.wedge_texcoord(w as Index).unwrap();
            let b = before.wedge_texcoord(w as Index).unwrap();
            assert!((a - b).length() < 1e-15);
        }
        let mut bare = crate::mesh::shapes::cube();
        let old = bare.positions.clone();
        assert_eq!(follow(&mut bare, old), FollowReport::default());
    }

    #[test]
    fn charts_split_at_seams() {
        let mut m = grid(2, 1);
        // Give the right square's corners their own texture coordinates: a seam at x = 1.
        let mut copies = std::collections::BTreeMap::new();
        for t in 2..4 {
            for k in 0..3 {
                let w = m.triangles[t][k];
                let copy = *copies.entry(w).or_insert_with(|| {
                    let mut wedge = m.wedges[w as usize];
                    m.texcoords.push(DVec2::new(0.9, 0.9));
                    wedge.texcoord = Some((m.texcoords.len() - 1) as Index);
                    m.wedges.push(wedge);
                    (m.wedges.len() - 1) as Index
                });
                m.triangles[t][k] = copy;
            }
        }
        let c = charts(&m);
        assert_eq!(c[0], c[1]);
        assert_ne!(c[1], c[2]);
        assert_eq!(c[2], c[3]);
    }
}
