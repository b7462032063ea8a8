//! The input's constrained polylines: borders, texture seams, material changes,
//! non-manifold edges and (with `feature_angle`) sharp edges. Each input edge on one of
//! them is a *segment*; a vertex of the working mesh that lies on a line keeps a segment
//! hint and is projected onto the line by walking from segment to neighbouring segment.

use crate::geom::closest_on_segment;
use crate::mesh::Mesh;
use crate::mesh::topology::Topology;
use glam::DVec3;

use super::corners::NIL;

/// Why an input edge is constrained (the report counts them).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineKind {
    Border,
    Seam,
    Material,
    Feature,
    NonManifold,
}

/// The segments of all input lines.
#[derive(Debug, Default)]
pub struct Lines {
    pub ends: Vec<[DVec3; 2]>,
    /// The input vertices of each segment.
    pub verts: Vec<[u32; 2]>,
    /// The input triangles on each segment (`NIL` for a missing second one; the first two
    /// of a non-manifold edge).
    pub tris: Vec<[u32; 2]>,
    /// The segment continuing the line at each end, `NIL` at a corner.
    pub nb: Vec<[u32; 2]>,
    pub kind: Vec<LineKind>,
    /// Per input edge, its segment or `NIL`.
    pub of_edge: Vec<u32>,
    /// Per input vertex: constrained edges met there.
    pub degree: Vec<u32>,
    /// Per input vertex: a corner although exactly two segments meet there (see
    /// [`Lines::mark_corners`]).
    pub corner: Vec<bool>,
}

/// Walking more than this many segments from the hint is not tried: a vertex moves by
/// less than an edge length per step, so a long walk means the hint is lost.
const MAX_WALK: usize = 512;

fn kind_of(mesh: &Mesh, topo: &Topology, e: u32, cos_feature: Option<f64>) -> Option<LineKind> {
    let sides = topo.edge_sides(e);
    if sides.len() == 1 {
        return Some(LineKind::Border);
    }
    if sides.len() > 2 || topo.is_inconsistent_edge(e) {
        return Some(LineKind::NonManifold);
    }
    if topo.is_texture_seam_edge(e) {
        return Some(LineKind::Seam);
    }
    let (t1, t2) = (sides[0] as usize / 3, sides[1] as usize / 3);
    if mesh.triangle_material(t1) != mesh.triangle_material(t2) {
        return Some(LineKind::Material);
    }
    let cos = cos_feature?;
    let (n1, n2) = (mesh.triangle_cross(t1), mesh.triangle_cross(t2));
    let d = n1.normalize_or_zero().dot(n2.normalize_or_zero());
    (d < cos).then_some(LineKind::Feature)
}

impl Lines {
    /// The lines of `mesh`; `feature_angle` in degrees (edges whose faces' normals differ
    /// by more are features).
    pub fn new(mesh: &Mesh, topo: &Topology, feature_angle: Option<f64>) -> Lines {
        let cos_feature = feature_angle.map(|a| a.to_radians().cos());
        let mut l = Lines {
            of_edge: vec![NIL; topo.edge_count()],
            degree: vec![0; mesh.positions.len()],
            ..Lines::default()
        };
        for e in 0..topo.edge_count() as u32 {
            let Some(kind) = kind_of(mesh, topo, e, cos_feature) else {
                continue;
            };
            let [x, y] = topo.edge_vertices(e);
            l.of_edge[e as usize] = l.ends.len() as u32;
            l.ends
                .push([mesh.positions[x as usize], mesh.positions[y as usize]]);
            l.verts.push([x, y]);
            let sides = topo.edge_sides(e);
            let side = |i: usize| sides.get(i).map_or(NIL, |s| s / 3);
            l.tris.push([side(0), side(1)]);
            l.kind.push(kind);
            l.degree[x as usize] += 1;
            l.degree[y as usize] += 1;
        }
        l.corner = vec![false; mesh.positions.len()];
        if let Some(cos) = cos_feature {
            l.mark_corners(cos);
        }
        l.link_neighbours(topo);
        l
    }

    /// With `feature_angle` (its cosine `cos_feature`), a vertex where exactly two segments
    /// meet is nevertheless a corner when the line turns there by more than the angle (a
    /// square's corner, a border's sharp turn), or when a feature line meets a line of
    /// another kind: it stays fixed like a line's end, so that the corner is not cut
    /// (pmp-library locks such vertices too; Botsch & Kobbelt 2004 keep feature vertices
    /// where feature lines do not continue smoothly). Without `feature_angle` no vertex is
    /// made a corner here: the borders of scans are jagged and every step would be one.
    fn mark_corners(&mut self, cos_feature: f64) {
        let mut first = vec![NIL; self.corner.len()];
        for s in 0..self.ends.len() as u32 {
            for end in 0..2 {
                let v = self.verts[s as usize][end] as usize;
                if self.degree[v] != 2 {
                    continue;
                }
                if first[v] == NIL {
                    first[v] = s;
                    continue;
                }
                let t = first[v];
                let (p, a, b) = (
                    self.end_at(s, v as u32, 0),
                    self.end_at(t, v as u32, 1),
                    self.end_at(s, v as u32, 1),
                );
                // The directions into and out of v along the line; their angle is the turn.
                let (din, dout) = ((p - a).normalize_or_zero(), (b - p).normalize_or_zero());
                let kinds = [self.kind[s as usize], self.kind[t as usize]];
                let mixed_feature = kinds[0] != kinds[1] && kinds.contains(&LineKind::Feature);
                if din.dot(dout) < cos_feature || mixed_feature {
                    self.corner[v] = true;
                }
            }
        }
    }

    /// Segment `s`'s end at input vertex `v` (`which` 0) or its other end (`which` 1).
    fn end_at(&self, s: u32, v: u32, which: usize) -> DVec3 {
        let k = usize::from(self.verts[s as usize][0] != v);
        self.ends[s as usize][if which == 0 { k } else { 1 - k }]
    }

    /// A vertex of a line where exactly two segments meet continues it; any other is a
    /// corner (an end, a junction, a sharp turn) and never moves, and projection does not
    /// walk across it.
    fn link_neighbours(&mut self, topo: &Topology) {
        self.nb = vec![[NIL; 2]; self.ends.len()];
        for s in 0..self.ends.len() {
            for end in 0..2 {
                let v = self.verts[s][end];
                if self.degree[v as usize] != 2 || self.corner[v as usize] {
                    continue;
                }
                let other = topo
                    .vertex_neighbours(v)
                    .iter()
                    .filter_map(|&w| topo.find_edge(v, w))
                    .map(|e| self.of_edge[e as usize])
                    .find(|&o| o != NIL && o != s as u32);
                self.nb[s][end] = other.unwrap_or(NIL);
            }
        }
    }

    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }

    pub fn count(&self, kind: LineKind) -> usize {
        self.kind.iter().filter(|&&k| k == kind).count()
    }

    fn distance2(&self, s: u32, p: DVec3) -> (DVec3, f64) {
        let [a, b] = self.ends[s as usize];
        let q = closest_on_segment(p, a, b);
        (q, q.distance_squared(p))
    }

    /// The point of the line through segment `hint` closest to `p`, found by walking to
    /// neighbouring segments while they are closer; returns it with its segment.
    pub fn project(&self, p: DVec3, hint: u32) -> (DVec3, u32) {
        let (mut q, mut d) = self.distance2(hint, p);
        let mut s = hint;
        for _ in 0..MAX_WALK {
            let mut moved = false;
            for n in self.nb[s as usize] {
                if n == NIL {
                    continue;
                }
                let (qn, dn) = self.distance2(n, p);
                if dn < d {
                    (q, d, s, moved) = (qn, dn, n, true);
                }
            }
            if !moved {
                break;
            }
        }
        (q, s)
    }
}
