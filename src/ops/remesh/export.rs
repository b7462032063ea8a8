//! The working mesh back to a [`Mesh`]: live vertices and faces compacted, each corner's
//! texture coordinate taken from the input within the face's own chart, per-vertex colours
//! from the input, and the input triangle each face descends from.
//!
//! Texture rule: a corner at vertex `v` of face `f` is located on the input by the closest
//! point, among the triangles of `f`'s chart, to `v` moved a little into `f`; its texture
//! coordinate is that input triangle's, interpolated at `v` (barycentric). Nudging into the
//! face picks the right side of a seam that runs inside one chart; searching only the chart
//! keeps every corner in the chart its face was cut from, so the photo stays where it was.
//! At a line's end or a junction of lines the faces between two line edges take one
//! coordinate, the one most of them find ([`corner_vertex_uvs`]).
//! The searches walk over the chart's triangles from the input triangle the vertex was last
//! projected onto ([`walk`]); a chart's tree is built only for a search that cannot walk.

use super::corners::{Corners, NIL, VKind};
use super::lines::Lines;
use super::walk::{self, Sheet};
use crate::geom::bvh::TriangleBvh;
use crate::geom::closest_on_triangle;
use crate::mesh::{Index, Mesh, Wedge};
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::OnceLock;

/// How far into its face a corner is moved before its chart is searched (fraction of the
/// way to the face's centroid).
const NUDGE: f64 = 1e-3;

/// Two texture coordinates of one vertex closer than this (texture units, 1/250 of a texel
/// of a 4096² image) are one wedge: they differ by rounding only.
const SAME_UV: f64 = 1e-6;

/// The input's charts for the searches of the export: the chart label of each input
/// triangle, and per label a tree over its triangles (the whole input's when there is one
/// chart), built on first use: most searches end in a walk from a triangle of the chart.
struct ChartIndex<'a> {
    input: &'a Mesh,
    sheet: &'a Sheet<'a>,
    chart_of_input: &'a [u32],
    slot: HashMap<u32, usize>,
    members: Vec<Vec<u32>>,
    bvhs: Vec<OnceLock<TriangleBvh<'a>>>,
    whole: &'a TriangleBvh<'a>,
}

impl<'a> ChartIndex<'a> {
    fn new(sheet: &'a Sheet<'a>, chart_of_input: &'a [u32], whole: &'a TriangleBvh<'a>) -> Self {
        let mut slot = HashMap::new();
        let mut members: Vec<Vec<u32>> = Vec::new();
        for (t, &ch) in chart_of_input.iter().enumerate() {
            let k = *slot.entry(ch).or_insert_with(|| {
                members.push(Vec::new());
                members.len() - 1
            });
            members[k].push(t as u32);
        }
        ChartIndex {
            input: sheet.mesh,
            sheet,
            chart_of_input,
            slot,
            bvhs: members.iter().map(|_| OnceLock::new()).collect(),
            members,
            whole,
        }
    }

    /// The tree over the triangles of `chart` (`None` for a label no input triangle has).
    fn tree(&self, chart: u32) -> Option<&TriangleBvh<'a>> {
        if self.members.len() == 1 {
            return Some(self.whole);
        }
        let k = *self.slot.get(&chart)?;
        Some(self.bvhs[k].get_or_init(|| TriangleBvh::new(self.input, self.members[k].clone())))
    }

    /// The input triangle of `chart` closest to `p`: walked to from input triangle `hint`
    /// when that is in the chart, searched in the chart's tree otherwise.
    fn closest(&self, chart: u32, p: DVec3, hint: u32) -> Option<u32> {
        if self.chart_of_input[hint as usize] != chart {
            return self.tree(chart)?.closest(p, None).map(|h| h.triangle);
        }
        let within = |t: u32| self.chart_of_input[t as usize] == chart;
        let foot = walk::walk(self.sheet, hint, p, within);
        if foot.settled {
            return Some(foot.triangle);
        }
        walk::settle(self.tree(chart)?, p, foot).map(|f| f.triangle)
    }

    /// The texture coordinate at `p` (a point of the input) in `chart`, located from
    /// `inside` (a point just inside the output face), starting from input triangle `hint`.
    fn uv(&self, chart: u32, p: DVec3, inside: DVec3, hint: u32) -> Option<DVec2> {
        self.uv_on(self.closest(chart, inside, hint)?, p)
    }

    /// The texture coordinate of the point of input triangle `t` closest to `p`.
    fn uv_on(&self, t: u32, p: DVec3) -> Option<DVec2> {
        let input = self.input;
        let [a, b, c] = input.triangle_positions(t as usize);
        let (_, w) = closest_on_triangle(p, a, b, c);
        let uv = input.triangles[t as usize].map(|k| input.wedge_texcoord(k));
        Some(uv[0]? * w.x + uv[1]? * w.y + uv[2]? * w.z)
    }
}

/// The working mesh's live faces, and its live vertices numbered in order of first use.
pub struct Live {
    pub faces: Vec<usize>,
    /// Working vertex of each output vertex.
    pub vertices: Vec<u32>,
    /// Output vertex of each working vertex (`u32::MAX` for a dead one).
    pub index: Vec<u32>,
}

impl Live {
    pub fn of(c: &Corners) -> Live {
        let faces: Vec<usize> = (0..c.face_count()).filter(|&f| !c.face_dead[f]).collect();
        let mut index = vec![u32::MAX; c.pos.len()];
        let mut vertices = Vec::new();
        for &f in &faces {
            for k in 0..3 {
                let v = c.vtx[3 * f + k] as usize;
                if index[v] == u32::MAX {
                    index[v] = vertices.len() as u32;
                    vertices.push(v as u32);
                }
            }
        }
        Live {
            faces,
            vertices,
            index,
        }
    }

    /// Face `f`'s corners as output vertices.
    pub fn triangle(&self, c: &Corners, f: usize) -> [u32; 3] {
        [0, 1, 2].map(|k| self.index[c.vtx[3 * f + k] as usize])
    }
}

/// Builds the output mesh. `chart_of_input` is the chart label of each input triangle
/// (the labels the working faces carry).
pub fn export(
    c: &Corners,
    lines: &Lines,
    sheet: &Sheet,
    chart_of_input: &[u32],
    bvh: &TriangleBvh,
) -> Mesh {
    let input = sheet.mesh;
    let live = Live::of(c);
    let faces = &live.faces;
    let charts = ChartIndex::new(sheet, chart_of_input, bvh);
    let mut uvs = corner_uvs(c, lines, input, &charts, faces);
    if let Some(uvs) = &mut uvs {
        agree_along_lines(c, faces, uvs);
    }
    let mut out = Mesh {
        positions: live.vertices.iter().map(|&v| c.pos[v as usize]).collect(),
        materials: input.materials.clone(),
        ..Mesh::default()
    };
    let mut wedges = Wedges::new(live.vertices.len());
    for (i, &f) in faces.iter().enumerate() {
        let vs = live.triangle(c, f);
        let tri = [0, 1, 2].map(|k| {
            let uv = uvs.as_ref().and_then(|u| u[i][k]);
            wedges.of(&mut out, vs[k], uv)
        });
        out.triangles.push(tri);
    }
    if !input.triangle_materials.is_empty() {
        out.triangle_materials = faces.iter().map(|&f| c.material[f]).collect();
    }
    let hints: Vec<u32> = live.vertices.iter().map(|&v| c.vtri[v as usize]).collect();
    let face_charts: Vec<u32> = faces.iter().map(|&f| c.chart[f]).collect();
    out.triangle_origins = origins(&out, &charts, &face_charts, &hints);
    if !input.colors.is_empty() {
        out.colors = colours(&out, sheet, bvh, &hints);
    }
    out
}

/// The output's wedges of each vertex, in the order they were made: a vertex's first
/// wedge, and after each wedge the next one of the same vertex (most vertices have one,
/// a vertex on a seam one per chart), without a list per vertex.
struct Wedges {
    first: Vec<Index>,
    next: Vec<Index>,
}

impl Wedges {
    const NONE: Index = Index::MAX;

    fn new(vertices: usize) -> Wedges {
        Wedges {
            first: vec![Self::NONE; vertices],
            next: Vec::new(),
        }
    }

    /// The wedge of vertex `v` with texture coordinate `uv`: the first of `v`'s within
    /// [`SAME_UV`], or a new one.
    fn of(&mut self, out: &mut Mesh, v: u32, uv: Option<DVec2>) -> Index {
        let mut last = Self::NONE;
        let mut w = self.first[v as usize];
        while w != Self::NONE {
            if same_uv(out.wedge_texcoord(w), uv) {
                return w;
            }
            last = w;
            w = self.next[w as usize];
        }
        let texcoord = uv.map(|p| {
            out.texcoords.push(p);
            (out.texcoords.len() - 1) as Index
        });
        out.wedges.push(Wedge {
            vertex: v,
            texcoord,
            normal: None,
        });
        let w = (out.wedges.len() - 1) as Index;
        self.next.push(Self::NONE);
        match last {
            Self::NONE => self.first[v as usize] = w,
            _ => self.next[last as usize] = w,
        }
        w
    }
}

type FaceUvs = Vec<[Option<DVec2>; 3]>;

/// Each face corner's texture coordinate: a free vertex (inside one chart, on the input
/// triangle it was projected onto) from that triangle; a line vertex from the chart's
/// triangle found just inside the face.
fn corner_uvs(
    c: &Corners,
    lines: &Lines,
    input: &Mesh,
    charts: &ChartIndex,
    faces: &[usize],
) -> Option<FaceUvs> {
    if !input.has_texcoords() {
        return None;
    }
    let chart_of_input = charts.chart_of_input;
    let at_corners = corner_vertex_uvs(c, charts);
    let at_free = free_vertex_uvs(c, charts);
    Some(
        faces
            .par_iter()
            .map(|&f| {
                let p = c.face_positions(f);
                let centre = (p[0] + p[1] + p[2]) / 3.0;
                let chart = c.chart[f];
                [0, 1, 2].map(|k| {
                    let v = c.vtx[3 * f + k] as usize;
                    let hint = c.vtri[v];
                    let inside = p[k] + NUDGE * (centre - p[k]);
                    match c.kind[v] {
                        VKind::Free if chart_of_input[hint as usize] == chart => at_free[v],
                        VKind::Line if c.vseg[v] != NIL => {
                            let side =
                                line_side(input, lines, c.vseg[v], chart, chart_of_input, inside);
                            match side {
                                Some(t) => charts.uv_on(t, p[k]),
                                None => charts.uv(chart, p[k], inside, hint),
                            }
                        }
                        VKind::Corner => match at_corners.get(&(3 * f as u32 + k as u32)) {
                            Some(&uv) => uv,
                            None => charts.uv(chart, p[k], inside, hint),
                        },
                        _ => charts.uv(chart, p[k], inside, hint),
                    }
                })
            })
            .collect(),
    )
}

/// The texture coordinate of each live free vertex on the input triangle it was projected
/// onto (`None` for other vertices): the coordinate of each of its corners whose face is in
/// that triangle's chart, computed once for the six or so corners.
fn free_vertex_uvs(c: &Corners, charts: &ChartIndex) -> Vec<Option<DVec2>> {
    (0..c.pos.len())
        .into_par_iter()
        .map(|v| {
            (c.kind[v] == VKind::Free && !c.vertex_dead[v])
                .then(|| charts.uv_on(c.vtri[v], c.pos[v]))
                .flatten()
        })
        .collect()
}

/// The texture coordinate of each corner at a `Corner` vertex (a line's end or a junction
/// of lines), by half-edge. The faces around such a vertex fall into sectors between its
/// line edges; all corners of one sector take one coordinate, the one most of the sector's
/// faces find just inside themselves (ties to the first in fan order). Found face by face,
/// a thin face beside a line could land across the input's seam where the line's chord
/// leaves the input's polyline, and where a seam ends inside its chart (a slit: the input
/// vertex has two coordinates in one chart) two faces of one sector then read different
/// coordinates, which makes a seam no line runs along (james at 0.3–0.5 % of the diagonal).
fn corner_vertex_uvs(c: &Corners, charts: &ChartIndex) -> HashMap<u32, Option<DVec2>> {
    let corners: Vec<u32> = (0..c.pos.len() as u32)
        .filter(|&v| c.kind[v as usize] == VKind::Corner && !c.vertex_dead[v as usize])
        .collect();
    corners
        .par_iter()
        .map_init(Vec::new, |hs, &v| sector_uvs(c, charts, v, hs))
        .flatten_iter()
        .collect()
}

/// [`corner_vertex_uvs`] at vertex `v`: (half-edge, coordinate) for each face around it.
fn sector_uvs(
    c: &Corners,
    charts: &ChartIndex,
    v: u32,
    hs: &mut Vec<u32>,
) -> Vec<(u32, Option<DVec2>)> {
    c.fan(v, hs);
    let found: Vec<Option<DVec2>> = hs
        .iter()
        .map(|&h| {
            let f = (h / 3) as usize;
            let p = c.face_positions(f);
            let k = (h % 3) as usize;
            let inside = p[k] + NUDGE * ((p[0] + p[1] + p[2]) / 3.0 - p[k]);
            charts.uv(c.chart[f], p[k], inside, c.vtri[v as usize])
        })
        .collect();
    hs.iter().copied().zip(by_sector(c, hs, &found)).collect()
}

/// The sector of each face of the fan `hs` around a vertex: a new one starts across a line
/// (or border) edge, and a closed fan's last sector is its first when no line crosses there.
fn sectors(c: &Corners, hs: &[u32]) -> Vec<usize> {
    let n = hs.len();
    let mut sector = vec![0usize; n];
    for i in 1..n {
        sector[i] = sector[i - 1] + usize::from(c.is_constrained(hs[i]));
    }
    let closed = n > 1 && c.rotate(hs[n - 1]) == hs[0];
    if closed && !c.is_constrained(hs[0]) {
        let last = sector[n - 1];
        for s in sector.iter_mut().filter(|s| **s == last) {
            *s = 0;
        }
    }
    sector
}

/// The coordinate each face of the fan `hs` takes: the one most faces of its sector
/// `found` (ties to the first in fan order).
fn by_sector(c: &Corners, hs: &[u32], found: &[Option<DVec2>]) -> Vec<Option<DVec2>> {
    let sector = sectors(c, hs);
    let n = hs.len();
    let votes = |i: usize| {
        (0..n)
            .filter(|&j| sector[j] == sector[i] && same_uv(found[j], found[i]))
            .count()
    };
    let mut chosen: HashMap<usize, usize> = HashMap::new();
    for (i, &s) in sector.iter().enumerate() {
        let best = chosen.entry(s).or_insert(i);
        if votes(i) > votes(*best) {
            *best = i;
        }
    }
    (0..n).map(|i| found[chosen[&sector[i]]]).collect()
}

/// Makes the faces of one sector around each line vertex (between its two line edges) take
/// one coordinate, the one most of them found. Each face reads the vertex's coordinate on
/// the line segment's input triangle on its own side, but where the chord of a thin face
/// leaves the input's polyline or a seam ends inside its chart, two faces of one side can
/// find different ones; the edge between them would then be a seam with no line along it
/// (the USNM coral: 25 such seam vertices at 1 % of the diagonal).
fn agree_along_lines(c: &Corners, faces: &[usize], uvs: &mut FaceUvs) {
    let line_vertices: Vec<u32> = (0..c.pos.len() as u32)
        .filter(|&v| {
            let v = v as usize;
            c.kind[v] == VKind::Line && c.vseg[v] != NIL && !c.vertex_dead[v]
        })
        .collect();
    let slot = |h: u32| {
        let i = faces.binary_search(&((h / 3) as usize)).ok()?;
        Some((i, (h % 3) as usize))
    };
    let changes: Vec<((usize, usize), Option<DVec2>)> = line_vertices
        .par_iter()
        .map_init(Vec::new, |hs, &v| {
            c.fan(v, hs);
            let at: Option<Vec<(usize, usize)>> = hs.iter().map(|&h| slot(h)).collect();
            let Some(at) = at else {
                return Vec::new();
            };
            let found: Vec<Option<DVec2>> = at.iter().map(|&(i, k)| uvs[i][k]).collect();
            let agreed = by_sector(c, hs, &found);
            at.into_iter()
                .zip(agreed)
                .zip(found)
                .filter(|((_, a), f)| !same_uv(*a, *f))
                .map(|((at, a), _)| (at, a))
                .collect()
        })
        .flatten_iter()
        .collect();
    for ((i, k), uv) in changes {
        uvs[i][k] = uv;
    }
}

/// Two texture coordinates that are one wedge ([`SAME_UV`]).
fn same_uv(a: Option<DVec2>, b: Option<DVec2>) -> bool {
    match (a, b) {
        (Some(a), Some(b)) => a.distance(b) <= SAME_UV,
        (None, None) => true,
        _ => false,
    }
}

/// The input triangle of line segment `seg` in `chart` on the side of `inside` (a line
/// vertex lies on its segment, so that triangle holds it exactly).
fn line_side(
    input: &Mesh,
    lines: &Lines,
    seg: u32,
    chart: u32,
    chart_of_input: &[u32],
    inside: DVec3,
) -> Option<u32> {
    let input_tris = lines.tris[seg as usize];
    let mut best: Option<(f64, u32)> = None;
    for t in input_tris {
        if t == NIL || chart_of_input[t as usize] != chart {
            continue;
        }
        let [a, b, c] = input.triangle_positions(t as usize);
        let d = closest_on_triangle(inside, a, b, c)
            .0
            .distance_squared(inside);
        if best.is_none_or(|(bd, _)| d < bd) {
            best = Some((d, t));
        }
    }
    best.map(|(_, t)| t)
}

/// The input triangle of the face's own chart closest to each output face's centroid
/// (mapped through the input's own origins); `hints` are the output vertices' last input
/// triangles.
fn origins(out: &Mesh, charts: &ChartIndex, face_charts: &[u32], hints: &[u32]) -> Vec<Index> {
    (0..out.triangles.len())
        .into_par_iter()
        .map(|t| {
            let [a, b, c] = out.triangle_positions(t);
            let centre = (a + b + c) / 3.0;
            let hint = hints[out.triangle_vertices(t)[0] as usize];
            let hit = charts.closest(face_charts[t], centre, hint);
            hit.map_or(0, |h| charts.input.triangle_origin(h as usize))
        })
        .collect()
}

/// Per-vertex colours interpolated at each output vertex's closest input point.
fn colours(out: &Mesh, sheet: &Sheet, bvh: &TriangleBvh, hints: &[u32]) -> Vec<[u8; 4]> {
    let input = sheet.mesh;
    out.positions
        .par_iter()
        .zip(hints.par_iter())
        .map(|(&p, &hint)| {
            let Some(foot) = walk::walk_or_search(sheet, bvh, hint, p, |_| true) else {
                return [255; 4];
            };
            let vs = input.triangle_vertices(foot.triangle as usize);
            let w = foot.bary.to_array();
            let mut rgba = [0u8; 4];
            for (ch, slot) in rgba.iter_mut().enumerate() {
                let x: f64 = (0..3)
                    .map(|k| w[k] * input.colors[vs[k] as usize][ch] as f64)
                    .sum();
                *slot = x.round().clamp(0.0, 255.0) as u8;
            }
            rgba
        })
        .collect()
}
