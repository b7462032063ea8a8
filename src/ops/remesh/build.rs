//! The working mesh from a [`Mesh`]: corner table, opposite half-edges, face labels
//! (texture chart, material), vertex kinds from the input lines, locked vertices.

use super::corners::{Corners, NIL, VKind};
use super::lines::{LineKind, Lines};
use crate::mesh::Mesh;
use crate::mesh::topology::Topology;
use crate::ops::decimate::audit::charts;

pub fn build(mesh: &Mesh, topo: &Topology, lines: &Lines) -> Corners {
    let nf = mesh.triangles.len();
    let nv = mesh.positions.len();
    let mut c = Corners {
        vtx: (0..nf).flat_map(|t| mesh.triangle_vertices(t)).collect(),
        opp: vec![NIL; 3 * nf],
        seg: vec![NIL; 3 * nf],
        face_dead: vec![false; nf],
        chart: if mesh.has_texcoords() {
            charts(mesh, topo)
        } else {
            vec![0; nf]
        },
        material: (0..nf).map(|t| mesh.triangle_material(t)).collect(),
        pos: mesh.positions.clone(),
        out: vec![NIL; nv],
        locked: vec![false; nv],
        vertex_dead: vec![true; nv],
        kind: vec![VKind::Free; nv],
        vseg: vec![NIL; nv],
        vtri: vec![0; nv],
    };
    for e in 0..topo.edge_count() as u32 {
        let sides = topo.edge_sides(e);
        let s = lines.of_edge[e as usize];
        // A non-manifold or inconsistent edge stays open on every side.
        if sides.len() == 2 && (s == NIL || lines.kind[s as usize] != LineKind::NonManifold) {
            c.link(sides[0], sides[1]);
        }
        for &h in sides {
            c.seg[h as usize] = s;
        }
        if s != NIL {
            for v in topo.edge_vertices(e) {
                c.vseg[v as usize] = s;
                if lines.kind[s as usize] == LineKind::NonManifold {
                    c.locked[v as usize] = true;
                }
            }
        }
    }
    for h in 0..3 * nf as u32 {
        let v = c.vtx[h as usize] as usize;
        c.out[v] = h;
        c.vertex_dead[v] = false;
        c.vtri[v] = h / 3;
    }
    classify_vertices(&mut c, topo, lines);
    c
}

/// Border half-edges first in `out`, locked vertices (more than one fan), vertex kinds.
fn classify_vertices(c: &mut Corners, topo: &Topology, lines: &Lines) {
    let mut hs = Vec::new();
    for v in 0..c.pos.len() as u32 {
        if c.vertex_dead[v as usize] {
            continue;
        }
        c.fix_out(v, c.out[v as usize]);
        c.fan(v, &mut hs);
        if hs.len() != topo.vertex_corners(v).len() || topo.is_non_manifold_vertex(v) {
            c.locked[v as usize] = true;
        }
        c.kind[v as usize] = match lines.degree[v as usize] {
            _ if c.locked[v as usize] => VKind::Corner,
            0 => VKind::Free,
            2 if !lines.corner[v as usize] => VKind::Line,
            _ => VKind::Corner,
        };
    }
}
