//! The crop box (the decimation thesis' "Scene cut", §6.4): an axis-aligned box
//! given as `min`/`max` or as a symmetric `abs_max` (|x| ≤ X, |y| ≤ Y, |z| ≤ Z), optionally
//! in a frame whose origin sits at `translation` in the scan's coordinates (scanners place
//! their origin differently: the box in scan coordinates is the given box + `translation`).
//!
//! Modes. The thesis does not define "outside" (reading R15 in docs/decimation.md):
//! - `any-corner-outside` (default): a triangle with any corner outside the box goes;
//! - `all-corners-outside`: only triangles with every corner outside go (a triangle whose
//!   corners are all outside but which crosses the box goes too);
//! - `clip`: triangles are cut at the box faces (Sutherland–Hodgman against each plane, then
//!   a fan), interpolating texture coordinates, normals and colours, so the new border is
//!   straight. A point on the box face counts as inside.
//!
//! Watertight cuts: a cut point on a mesh edge is computed from the edge's two end vertices
//! in a fixed (low index → high index) order and keyed by (edge, plane), so both triangles
//! of the edge get the same vertex, bit for bit, and no crack opens. Each side keeps its
//! own texture coordinates (a seam edge stays a seam), but sides with the same wedges share
//! the new wedge (no new seam). The coordinate of the cut plane is set exactly, so every
//! new border vertex lies on the box. Afterwards unused vertices, wedges, texture
//! coordinates and normals are compacted; `triangle_origins` maps every piece to the input
//! triangle it came from, and pieces keep their material.

use crate::mesh::{Index, Mesh, Wedge};
use glam::{DVec2, DVec3};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum CropMode {
    #[default]
    AnyCornerOutside,
    AllCornersOutside,
    Clip,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct CropParams {
    /// Lower corner of the box (with `max`).
    #[serde(default)]
    pub min: Option<[f64; 3]>,
    /// Upper corner of the box (with `min`).
    #[serde(default)]
    pub max: Option<[f64; 3]>,
    /// Symmetric box: |x| ≤ X, |y| ≤ Y, |z| ≤ Z (instead of `min`/`max`).
    #[serde(default)]
    pub abs_max: Option<[f64; 3]>,
    /// Origin of the box's frame in the scan's coordinates.
    #[serde(default)]
    pub translation: [f64; 3],
    #[serde(default)]
    pub mode: CropMode,
}

impl CropParams {
    pub fn validate(&self) -> Result<(), String> {
        let finite = |name: &str, v: &[f64; 3]| {
            if v.iter().all(|x| x.is_finite()) {
                Ok(())
            } else {
                Err(format!("{name} must be three finite numbers, got {v:?}"))
            }
        };
        finite("translation", &self.translation)?;
        match (self.min, self.max, self.abs_max) {
            (None, None, Some(a)) => {
                finite("abs_max", &a)?;
                if a.iter().any(|&x| x <= 0.0) {
                    return Err(format!("abs_max must be positive on every axis, got {a:?}"));
                }
            }
            (Some(lo), Some(hi), None) => {
                finite("min", &lo)?;
                finite("max", &hi)?;
                if (0..3).any(|i| lo[i] >= hi[i]) {
                    return Err(format!(
                        "min must be below max on every axis, got min {lo:?}, max {hi:?}"
                    ));
                }
            }
            (_, _, Some(_)) => return Err("give either abs_max or min and max, not both".into()),
            _ => return Err("give the box as min and max, or as abs_max".into()),
        }
        Ok(())
    }

    /// The box in the scan's coordinates. Call after [`CropParams::validate`].
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let t = DVec3::from_array(self.translation);
        match (self.min, self.max, self.abs_max) {
            (Some(lo), Some(hi), _) => (DVec3::from_array(lo) + t, DVec3::from_array(hi) + t),
            (_, _, Some(a)) => (-DVec3::from_array(a) + t, DVec3::from_array(a) + t),
            _ => (DVec3::splat(f64::NEG_INFINITY), DVec3::splat(f64::INFINITY)),
        }
    }
}

/// What the crop did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CropReport {
    pub mode: CropMode,
    /// The box in the scan's coordinates.
    pub box_min: [f64; 3],
    pub box_max: [f64; 3],
    pub faces_before: usize,
    /// Input triangles kept unchanged.
    pub faces_kept: usize,
    /// Input triangles cut at the box (`clip` only); each left one or more pieces.
    pub faces_clipped: usize,
    /// Input triangles removed entirely.
    pub faces_removed: usize,
    pub faces_after: usize,
    /// Vertices created on the box faces (`clip` only).
    pub vertices_added: usize,
    pub vertices_removed: usize,
    pub wedges_removed: usize,
    pub texcoords_removed: usize,
    pub normals_removed: usize,
}

#[derive(Debug, thiserror::Error)]
pub enum CropError {
    #[error("invalid crop box: {0}")]
    Invalid(String),
    #[error(
        "the crop box {min:?}..{max:?} ({mode:?}) removes every triangle; the scan's bounding box is {mesh_min:?}..{mesh_max:?}"
    )]
    Everything {
        min: [f64; 3],
        max: [f64; 3],
        mode: CropMode,
        mesh_min: [f64; 3],
        mesh_max: [f64; 3],
    },
}

/// One of the six box planes: `axis`, and whether it bounds from above.
#[derive(Debug, Clone, Copy)]
struct Plane {
    axis: usize,
    upper: bool,
    value: f64,
}

impl Plane {
    /// Positive inside, zero on the plane.
    fn inside(&self, p: DVec3) -> f64 {
        if self.upper {
            self.value - p[self.axis]
        } else {
            p[self.axis] - self.value
        }
    }
}

fn planes(lo: DVec3, hi: DVec3) -> [Plane; 6] {
    std::array::from_fn(|i| {
        let (axis, upper) = (i / 2, i % 2 == 1);
        Plane {
            axis,
            upper,
            value: if upper { hi[axis] } else { lo[axis] },
        }
    })
}

fn inside_box(p: DVec3, lo: DVec3, hi: DVec3) -> bool {
    p.cmpge(lo).all() && p.cmple(hi).all()
}

/// Crops `mesh` in place.
pub fn crop(mesh: &mut Mesh, params: &CropParams) -> Result<CropReport, CropError> {
    params.validate().map_err(CropError::Invalid)?;
    let (lo, hi) = params.bounds();
    let faces_before = mesh.triangles.len();
    let vertices_before = mesh.positions.len();
    let (faces_kept, faces_clipped) = match params.mode {
        CropMode::Clip => clip(mesh, lo, hi),
        mode => {
            let outside: Vec<bool> = mesh
                .positions
                .iter()
                .map(|&p| !inside_box(p, lo, hi))
                .collect();
            let keep: Vec<bool> = (0..mesh.triangles.len())
                .map(|t| {
                    let v = mesh.triangle_vertices(t).map(|v| outside[v as usize]);
                    match mode {
                        CropMode::AllCornersOutside => !(v[0] && v[1] && v[2]),
                        _ => !(v[0] || v[1] || v[2]),
                    }
                })
                .collect();
            retain_triangles(mesh, &keep);
            (mesh.triangles.len(), 0)
        }
    };
    if mesh.triangles.is_empty() {
        let (mesh_min, mesh_max) = mesh.bounding_box().unwrap_or_default();
        return Err(CropError::Everything {
            min: lo.to_array(),
            max: hi.to_array(),
            mode: params.mode,
            mesh_min: mesh_min.to_array(),
            mesh_max: mesh_max.to_array(),
        });
    }
    let vertices_added = mesh.positions.len() - vertices_before;
    let compacted = mesh.compact();
    Ok(CropReport {
        mode: params.mode,
        box_min: lo.to_array(),
        box_max: hi.to_array(),
        faces_before,
        faces_kept,
        faces_clipped,
        faces_removed: faces_before - faces_kept - faces_clipped,
        faces_after: mesh.triangles.len(),
        vertices_added,
        vertices_removed: compacted.vertices,
        wedges_removed: compacted.wedges,
        texcoords_removed: compacted.texcoords,
        normals_removed: compacted.normals,
    })
}

/// Keeps the triangles marked, with their materials and origins.
fn retain_triangles(mesh: &mut Mesh, keep: &[bool]) {
    if mesh.triangle_origins.is_empty() {
        mesh.triangle_origins = (0..mesh.triangles.len() as Index).collect();
    }
    let filter = |v: &mut Vec<Index>| {
        let mut i = 0;
        v.retain(|_| {
            i += 1;
            keep[i - 1]
        });
    };
    filter(&mut mesh.triangle_origins);
    if !mesh.triangle_materials.is_empty() {
        filter(&mut mesh.triangle_materials);
    }
    let mut i = 0;
    mesh.triangles.retain(|_| {
        i += 1;
        keep[i - 1]
    });
}

/// Where a polygon vertex lies on its original triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Carrier {
    /// An original vertex.
    Vertex(Index),
    /// On the original edge between two vertices (low, high).
    Edge(Index, Index),
    /// Inside the triangle (a box edge crossing it).
    Interior,
}

impl Carrier {
    fn vertices(self) -> ([Index; 2], usize) {
        match self {
            Carrier::Vertex(a) => ([a, a], 1),
            Carrier::Edge(a, b) => ([a, b], 2),
            Carrier::Interior => ([0, 0], 0),
        }
    }

    /// The original edge both points lie on, if any.
    fn common_edge(self, other: Carrier) -> Option<(Index, Index)> {
        let ((p, np), (q, nq)) = (self.vertices(), other.vertices());
        if np == 0 || nq == 0 {
            return None;
        }
        let mut all: Vec<Index> = p[..np].iter().chain(&q[..nq]).copied().collect();
        all.sort_unstable();
        all.dedup();
        (all.len() == 2).then(|| (all[0], all[1]))
    }
}

#[derive(Debug, Clone, Copy)]
struct PolyVertex {
    wedge: Index,
    position: DVec3,
    texcoord: Option<DVec2>,
    normal: Option<DVec3>,
    color: Option<[u8; 4]>,
    carrier: Carrier,
}

fn lerp_color(a: [u8; 4], b: [u8; 4], t: f64) -> [u8; 4] {
    std::array::from_fn(|i| (a[i] as f64 + (b[i] as f64 - a[i] as f64) * t).round() as u8)
}

/// Position, texture coordinate, normal and colour where the segment `a → b` crosses
/// `plane`, each interpolated linearly (the normal renormalised, the position put exactly
/// on the plane).
type Crossing = (DVec3, Option<DVec2>, Option<DVec3>, Option<[u8; 4]>);

fn crossing(a: &PolyVertex, b: &PolyVertex, plane: &Plane) -> Crossing {
    let (da, db) = (plane.inside(a.position), plane.inside(b.position));
    let t = da / (da - db);
    let mut position = a.position + (b.position - a.position) * t;
    position[plane.axis] = plane.value;
    let texcoord = a.texcoord.zip(b.texcoord).map(|(x, y)| x + (y - x) * t);
    let normal = a
        .normal
        .zip(b.normal)
        .map(|(x, y)| (x + (y - x) * t).normalize_or(x));
    let color = a.color.zip(b.color).map(|(x, y)| lerp_color(x, y, t));
    (position, texcoord, normal, color)
}

/// Key of a cut point's wedge on an original edge: edge, plane and the two end wedges'
/// attribute indices (so sides with the same attributes share it).
type EdgeWedgeKey = (
    Index,
    Index,
    usize,
    Option<Index>,
    Option<Index>,
    Option<Index>,
    Option<Index>,
);

/// New elements created while clipping, shared between triangles where they must be.
struct Clipper<'a> {
    mesh: &'a mut Mesh,
    edge_vertices: HashMap<(Index, Index, usize), Index>,
    edge_wedges: HashMap<EdgeWedgeKey, Index>,
}

impl Clipper<'_> {
    fn push_vertex(&mut self, p: DVec3, color: Option<[u8; 4]>) -> Index {
        self.mesh.positions.push(p);
        if !self.mesh.colors.is_empty() {
            self.mesh.colors.push(color.unwrap_or([255; 4]));
        }
        (self.mesh.positions.len() - 1) as Index
    }

    fn push_wedge(
        &mut self,
        vertex: Index,
        texcoord: Option<DVec2>,
        normal: Option<DVec3>,
    ) -> Index {
        let texcoord = texcoord.map(|t| {
            self.mesh.texcoords.push(t);
            (self.mesh.texcoords.len() - 1) as Index
        });
        let normal = normal.map(|n| {
            self.mesh.normals.push(n);
            (self.mesh.normals.len() - 1) as Index
        });
        self.mesh.wedges.push(Wedge {
            vertex,
            texcoord,
            normal,
        });
        (self.mesh.wedges.len() - 1) as Index
    }

    /// The point where segment P→Q crosses `plane` (P and Q strictly on opposite sides).
    /// `corners` are the triangle's original polygon vertices, for edge cuts.
    fn cut(
        &mut self,
        p: &PolyVertex,
        q: &PolyVertex,
        plane: &Plane,
        k: usize,
        corners: &[PolyVertex; 3],
    ) -> PolyVertex {
        if let Some((a, b)) = p.carrier.common_edge(q.carrier) {
            let end = |v: Index| {
                *corners
                    .iter()
                    .find(|c| c.carrier == Carrier::Vertex(v))
                    .expect("an edge of the triangle joins two of its corners")
            };
            let (ca, cb) = (end(a), end(b));
            let (position, texcoord, normal, color) = crossing(&ca, &cb, plane);
            let vertex = match self.edge_vertices.get(&(a, b, k)) {
                Some(&v) => v,
                None => {
                    let v = self.push_vertex(position, color);
                    self.edge_vertices.insert((a, b, k), v);
                    v
                }
            };
            let (wa, wb) = (
                self.mesh.wedges[ca.wedge as usize],
                self.mesh.wedges[cb.wedge as usize],
            );
            let key = (a, b, k, wa.texcoord, wa.normal, wb.texcoord, wb.normal);
            let wedge = match self.edge_wedges.get(&key) {
                Some(&w) => w,
                None => {
                    let w = self.push_wedge(vertex, texcoord, normal);
                    self.edge_wedges.insert(key, w);
                    w
                }
            };
            return PolyVertex {
                wedge,
                position: self.mesh.positions[vertex as usize],
                texcoord,
                normal,
                color,
                carrier: Carrier::Edge(a, b),
            };
        }
        let (position, texcoord, normal, color) = crossing(p, q, plane);
        let vertex = self.push_vertex(position, color);
        let wedge = self.push_wedge(vertex, texcoord, normal);
        PolyVertex {
            wedge,
            position,
            texcoord,
            normal,
            color,
            carrier: Carrier::Interior,
        }
    }
}

/// Clips every triangle to the box; returns (triangles kept whole, triangles cut).
fn clip(mesh: &mut Mesh, lo: DVec3, hi: DVec3) -> (usize, usize) {
    let planes = planes(lo, hi);
    let old_triangles = std::mem::take(&mut mesh.triangles);
    let old_materials = std::mem::take(&mut mesh.triangle_materials);
    let old_origins = std::mem::take(&mut mesh.triangle_origins);
    let mut out = Emitted {
        triangles: Vec::with_capacity(old_triangles.len()),
        materials: Vec::new(),
        origins: Vec::with_capacity(old_triangles.len()),
        has_materials: !old_materials.is_empty(),
    };
    let (mut kept, mut clipped) = (0, 0);
    let mut clipper = Clipper {
        mesh,
        edge_vertices: HashMap::new(),
        edge_wedges: HashMap::new(),
    };
    for (t, &tri) in old_triangles.iter().enumerate() {
        let origin = old_origins.get(t).copied().unwrap_or(t as Index);
        let material = old_materials.get(t).copied().unwrap_or(0);
        let corners = clipper.corners(tri);
        if corners.iter().all(|c| inside_box(c.position, lo, hi)) {
            out.emit(tri, origin, material);
            kept += 1;
            continue;
        }
        if planes
            .iter()
            .any(|pl| corners.iter().all(|c| pl.inside(c.position) < 0.0))
        {
            continue; // wholly outside one plane
        }
        let polygon = clipper.clip_polygon(&corners, &planes);
        let mut pieces = 0;
        for piece in clipper.fan(&polygon) {
            out.emit(piece, origin, material);
            pieces += 1;
        }
        if pieces > 0 {
            clipped += 1;
        }
    }
    mesh.triangles = out.triangles;
    mesh.triangle_origins = out.origins;
    mesh.triangle_materials = out.materials;
    (kept, clipped)
}

/// The triangles the clip keeps or makes, with their origins and materials.
struct Emitted {
    triangles: Vec<[Index; 3]>,
    materials: Vec<Index>,
    origins: Vec<Index>,
    has_materials: bool,
}

impl Emitted {
    fn emit(&mut self, tri: [Index; 3], origin: Index, material: Index) {
        self.triangles.push(tri);
        self.origins.push(origin);
        if self.has_materials {
            self.materials.push(material);
        }
    }
}

impl Clipper<'_> {
    /// The corners of a triangle of wedges, with their attributes.
    fn corners(&self, tri: [Index; 3]) -> [PolyVertex; 3] {
        let m = &*self.mesh;
        tri.map(|w| {
            let wedge = m.wedges[w as usize];
            PolyVertex {
                wedge: w,
                position: m.positions[wedge.vertex as usize],
                texcoord: wedge.texcoord.map(|i| m.texcoords[i as usize]),
                normal: wedge.normal.map(|i| m.normals[i as usize]),
                color: m.colors.get(wedge.vertex as usize).copied(),
                carrier: Carrier::Vertex(wedge.vertex),
            }
        })
    }

    /// The triangle `corners` clipped by each plane in turn (Sutherland–Hodgman).
    fn clip_polygon(&mut self, corners: &[PolyVertex; 3], planes: &[Plane; 6]) -> Vec<PolyVertex> {
        let mut polygon: Vec<PolyVertex> = corners.to_vec();
        for (k, plane) in planes.iter().enumerate() {
            if polygon.len() < 3 {
                break;
            }
            let mut next = Vec::with_capacity(polygon.len() + 2);
            for i in 0..polygon.len() {
                let (p, q) = (polygon[i], polygon[(i + 1) % polygon.len()]);
                let (dp, dq) = (plane.inside(p.position), plane.inside(q.position));
                if dp >= 0.0 {
                    next.push(p);
                }
                if (dp > 0.0 && dq < 0.0) || (dp < 0.0 && dq > 0.0) {
                    next.push(self.cut(&p, &q, plane, k, corners));
                }
            }
            polygon = next;
        }
        polygon
    }

    /// The clipped polygon as a fan of triangles, without those that have no surface.
    fn fan<'p>(&'p self, polygon: &'p [PolyVertex]) -> impl Iterator<Item = [Index; 3]> + 'p {
        (1..polygon.len().saturating_sub(1)).filter_map(move |i| {
            let (a, b, c) = (polygon[0], polygon[i], polygon[i + 1]);
            let vertex = |p: &PolyVertex| self.mesh.wedges[p.wedge as usize].vertex;
            let (va, vb, vc) = (vertex(&a), vertex(&b), vertex(&c));
            if va == vb || vb == vc || va == vc {
                return None;
            }
            if (b.position - a.position).cross(c.position - a.position) == DVec3::ZERO {
                return None; // collinear cut points: no surface
            }
            Some([a.wedge, b.wedge, c.wedge])
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::{grid, uv_sphere};
    use crate::mesh::topology::Topology;

    fn params(min: [f64; 3], max: [f64; 3], mode: CropMode) -> CropParams {
        CropParams {
            min: Some(min),
            max: Some(max),
            mode,
            ..Default::default()
        }
    }

    #[test]
    fn validation() {
        assert!(CropParams::default().validate().is_err());
        let mut p = params([0.0; 3], [1.0; 3], CropMode::Clip);
        assert!(p.validate().is_ok());
        p.abs_max = Some([1.0; 3]);
        assert!(p.validate().unwrap_err().contains("not both"));
        assert!(
            params([0.0; 3], [1.0, 0.0, 1.0], CropMode::Clip)
                .validate()
                .is_err()
        );
        let sym = CropParams {
            abs_max: Some([1.0, 2.0, 3.0]),
            translation: [10.0, 0.0, 0.0],
            ..Default::default()
        };
        assert_eq!(
            sym.bounds(),
            (DVec3::new(9.0, -2.0, -3.0), DVec3::new(11.0, 2.0, 3.0))
        );
    }

    #[test]
    fn corner_modes() {
        // 4x4 grid, box x <= 2.5: column 2 (x in [2,3]) straddles the box face.
        let p = |mode| params([-1.0; 3], [2.5, 10.0, 1.0], mode);
        let mut any = grid(4, 4);
        let r = crop(&mut any, &p(CropMode::AnyCornerOutside)).unwrap();
        assert_eq!(
            (r.faces_before, r.faces_after, r.faces_removed),
            (32, 16, 16)
        );
        any.check_invariants().unwrap();
        assert!(any.positions.iter().all(|p| p.x <= 2.0));
        let mut all = grid(4, 4);
        let r = crop(&mut all, &p(CropMode::AllCornersOutside)).unwrap();
        assert_eq!(r.faces_after, 24);
        assert_eq!(all.triangle_origins.len(), 24);
        assert_eq!(all.triangle_origin(23), 29);
    }

    #[test]
    fn clip_makes_a_straight_watertight_border_with_interpolated_uvs() {
        let mut m = grid(4, 4);
        // A diagonal cut through a corner region: box x <= 2.5 and y >= 0.75.
        let r = crop(
            &mut m,
            &params([-1.0, 0.75, -1.0], [2.5, 10.0, 1.0], CropMode::Clip),
        )
        .unwrap();
        m.check_invariants().unwrap();
        assert!(r.faces_clipped > 0 && r.vertices_added > 0);
        let topo = Topology::new(&m);
        let counts = topo.counts();
        assert_eq!(counts.non_manifold_edges, 0);
        assert_eq!(counts.boundary_loops, 1, "a crack would add boundary");
        // Area is exactly the box ∩ grid: 2.5 × 3.25.
        let area: f64 = (0..m.triangles.len()).map(|t| m.triangle_area(t)).sum();
        assert!((area - 2.5 * 3.25).abs() < 1e-12, "{area}");
        // Every texture coordinate is still position / 4 (interpolated, not invented).
        for w in &m.wedges {
            let p = m.positions[w.vertex as usize];
            let uv = m.texcoords[w.texcoord.unwrap() as usize];
            assert!((uv - DVec2::new(p.x, p.y) / 4.0).length() < 1e-12);
        }
        for e in topo.boundary_edges() {
            for v in topo.edge_vertices(e) {
                let p = m.positions[v as usize];
                assert!(p.x == 0.0 || p.x == 2.5 || p.y == 0.75 || p.y == 4.0, "{p}");
            }
        }
    }

    #[test]
    fn clip_keeps_seams_and_closes_nothing_it_should_not() {
        let mut m = uv_sphere(1.0, 12, 16);
        let r = crop(
            &mut m,
            &CropParams {
                abs_max: Some([0.6, 2.0, 0.5]),
                mode: CropMode::Clip,
                ..Default::default()
            },
        )
        .unwrap();
        m.check_invariants().unwrap();
        assert!(r.faces_clipped > 0);
        let counts = Topology::new(&m).counts();
        // The sphere cut by x = ±0.6 and z = ±0.5: a band split into two pieces... each
        // piece is a disc-like patch with one boundary loop; nothing else opens.
        assert_eq!(counts.non_manifold_edges, 0);
        assert_eq!(counts.inconsistent_edges, 0);
        assert_eq!(counts.boundary_loops, counts.components);
        for p in &m.positions {
            assert!(p.x.abs() <= 0.6 && p.z.abs() <= 0.5);
        }
    }

    #[test]
    fn cropping_everything_is_an_error() {
        let mut m = grid(2, 2);
        for mode in [
            CropMode::AnyCornerOutside,
            CropMode::AllCornersOutside,
            CropMode::Clip,
        ] {
            let e = crop(&mut m.clone(), &params([5.0; 3], [6.0; 3], mode)).unwrap_err();
            assert!(e.to_string().contains("removes every triangle"), "{e}");
        }
        assert!(crop(&mut m, &CropParams::default()).is_err());
    }

    #[test]
    fn clip_across_a_seam_keeps_both_sides_texture_coordinates() {
        // Two unit squares; the right one uses its own texture coordinates along x = 1 (a
        // seam edge between vertices 1 and 4), shifted by 0.5 in u.
        let mut m = grid(2, 1);
        for v in [1, 4] {
            let uv = m.texcoords[v] + DVec2::new(0.5, 0.0);
            m.texcoords.push(uv);
            m.wedges.push(Wedge {
                vertex: v as Index,
                texcoord: Some((m.texcoords.len() - 1) as Index),
                normal: None,
            });
        }
        let (w1, w4) = ((m.wedges.len() - 2) as Index, (m.wedges.len() - 1) as Index);
        m.triangles[2][0] = w1; // [1, 2, 5]
        m.triangles[3] = [w1, 5, w4]; // [1, 5, 4]
        assert_eq!(Topology::new(&m).counts().texture_seam_edges, 1);
        crop(&mut m, &params([-1.0; 3], [3.0, 0.5, 1.0], CropMode::Clip)).unwrap();
        m.check_invariants().unwrap();
        let counts = Topology::new(&m).counts();
        assert_eq!((counts.texture_seam_edges, counts.boundary_loops), (1, 1));
        let mid = m
            .positions
            .iter()
            .position(|p| *p == DVec3::new(1.0, 0.5, 0.0))
            .unwrap() as Index;
        let mut uvs: Vec<DVec2> = m
            .wedges
            .iter()
            .filter(|w| w.vertex == mid)
            .map(|w| m.texcoords[w.texcoord.unwrap() as usize])
            .collect();
        uvs.sort_by(|a, b| a.x.total_cmp(&b.x));
        assert_eq!(uvs, vec![DVec2::new(0.5, 0.5), DVec2::new(1.0, 0.5)]);
        // Cut points elsewhere are shared with one wedge (no new seams): 5 cut vertices (two
        // borders, two diagonals, the seam), 6 wedges.
        assert_eq!(m.positions.iter().filter(|p| p.y == 0.5).count(), 5);
        let cut_wedges = m
            .wedges
            .iter()
            .filter(|w| m.positions[w.vertex as usize].y == 0.5)
            .count();
        assert_eq!(cut_wedges, 6);
    }
}
