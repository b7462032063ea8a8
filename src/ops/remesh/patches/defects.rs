//! Isolated non-manifold defects cut off before `patches` (the thesis' §5.4 experiment: a
//! sphere with one non-manifold edge, which its program remeshed as if the defect were not
//! there). A cell that holds a non-manifold edge or vertex is not a disc, so the harmonic
//! maps cannot be built on it (digest pitfall 19); rather than refuse such a mesh, the
//! defect is taken off:
//!
//! 1. the triangles are grouped into *sheets*: triangles joined across edges with two
//!    triangles (a non-manifold edge joins nothing);
//! 2. each sheet gets its own copy of the vertices it shares with another sheet, so two
//!    triangles of one sheet on a non-manifold edge meet there as on any manifold edge;
//! 3. a sheet with fewer than [`DEFECT_SHARE`] of the triangles that touches a larger
//!    sheet (shares a vertex with it) is a defect — a fin, a flap, a doubled triangle —
//!    and is dropped.
//!
//! What is left is checked as any input is: where a sheet still touches itself or stays
//! open, `patches` refuses it with the reason.

use crate::mesh::topology::Topology;
use crate::mesh::topology::union_find::UnionFind;
use crate::mesh::{Mesh, Wedge};
use serde::Serialize;

/// A sheet touching a larger one is a defect below this share of the mesh's triangles.
/// The thesis' fin is 2 of 322 triangles (0.6 %); a part of the object worth remeshing on
/// its own is far larger than one in twenty triangles, and a small sheet cannot hold even
/// one cell of the layout at the spacings `patches` allows.
pub const DEFECT_SHARE: f64 = 0.05;

/// What was cut off (the report's `defects`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Defects {
    pub non_manifold_edges: usize,
    pub non_manifold_vertices: usize,
    pub sheets_dropped: usize,
    pub triangles_dropped: usize,
}

/// The mesh without its isolated defects, or `None` when it has no non-manifold edge or
/// vertex (then it is used as it is). Texture coordinates, normals and materials are not
/// carried: `patches` drops them anyway.
pub fn without_defects(mesh: &Mesh, topo: &Topology) -> Option<(Mesh, Defects)> {
    let non_manifold_edges = topo.non_manifold_edges().count();
    let non_manifold_vertices = topo.non_manifold_vertices().len();
    if non_manifold_edges == 0 && non_manifold_vertices == 0 {
        return None;
    }
    let sheet = sheets(topo);
    let n = topo.triangle_count();
    let mut size = vec![0usize; n];
    for &s in &sheet {
        size[s as usize] += 1;
    }
    // The largest sheet at each vertex.
    let mut largest = vec![0usize; mesh.positions.len()];
    for t in 0..n as u32 {
        for v in topo.triangle_vertices(t) {
            largest[v as usize] = largest[v as usize].max(size[sheet[t as usize] as usize]);
        }
    }
    let small = (DEFECT_SHARE * n as f64).ceil() as usize;
    let mut defect = vec![false; n];
    for t in 0..n as u32 {
        let own = size[sheet[t as usize] as usize];
        if own < small
            && topo
                .triangle_vertices(t)
                .iter()
                .any(|&v| largest[v as usize] > own)
        {
            defect[sheet[t as usize] as usize] = true;
        }
    }
    let mut dropped = Defects {
        non_manifold_edges,
        non_manifold_vertices,
        ..Defects::default()
    };
    // Every (vertex, sheet) pair a kept triangle uses becomes one vertex, numbered in the
    // input's vertex order, so a mesh whose defect is only dropped keeps its numbering
    // (and `patches`, which scans the vertices in order for seeds, its result).
    let mut pairs = Vec::new();
    for t in 0..n as u32 {
        let s = sheet[t as usize];
        if defect[s as usize] {
            dropped.triangles_dropped += 1;
            dropped.sheets_dropped += usize::from(s == t);
        } else {
            pairs.extend(topo.triangle_vertices(t).map(|v| (v, s)));
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    let mut out = Mesh {
        positions: pairs
            .iter()
            .map(|&(v, _)| mesh.positions[v as usize])
            .collect(),
        wedges: (0..pairs.len() as u32)
            .map(|vertex| Wedge {
                vertex,
                texcoord: None,
                normal: None,
            })
            .collect(),
        ..Mesh::default()
    };
    // Every pair looked up was collected above from the same kept triangles.
    let index = |v: u32, s: u32| pairs.binary_search(&(v, s)).unwrap() as u32;
    out.triangles = (0..n as u32)
        .filter(|&t| !defect[sheet[t as usize] as usize])
        .map(|t| {
            topo.triangle_vertices(t)
                .map(|v| index(v, sheet[t as usize]))
        })
        .collect();
    Some((out, dropped))
}

/// Each triangle's sheet, numbered by its lowest triangle: triangles joined across edges
/// with exactly two triangles. Across an edge whose two triangles disagree on orientation
/// they are joined too, so that a turned patch stays in its sheet and is refused as
/// inconsistent rather than cut out as a part.
fn sheets(topo: &Topology) -> Vec<u32> {
    let n = topo.triangle_count();
    let mut sets = UnionFind::new(n);
    for e in 0..topo.edge_count() as u32 {
        if let [a, b] = *topo.edge_sides(e) {
            sets.union(a / 3, b / 3);
        }
    }
    (0..n as u32).map(|t| sets.find(t)).collect()
}
