//! Octree vertex clustering (thesis §3.1): algorithm v (`cluster`, the
//! attribute-extended quadric of each cell minimised, §3.1.2) and algorithm vo
//! (`cluster-keep`, the cell's best original vertex by the vertex–plane metric plus simple
//! attribute terms, §3.1.1).
//!
//! The adaptive octree (§3.1) is built implicitly from the vertices sorted by Morton key
//! (the key of Schaefer–Warren, §3.1): a cell is a run of equal key prefixes, so every
//! node is a contiguous range of the sorted vertices, and only cells that hold a vertex
//! exist. Chains of single-child cells are skipped (they do not change the leaves). Points
//! that share a cell at the maximum depth (21 levels, about 5·10⁻⁷ of the box) form one
//! leaf (§3.1 point equality with tolerance 0, depth-capped as reading R13 asks).
//!
//! Pruning (§3.1, reading (b)): the heap holds the inner nodes whose children are all leaves;
//! the cheapest becomes a leaf (a cell collapse), and its parent joins the heap once all of
//! its children are leaves. The errors never change while a node waits, so the heap needs
//! no stale entries. It stops when the triangles that keep three distinct cells number at
//! most `target_faces` (counted incrementally), or when `max_error` would be exceeded.
//!
//! Mesh generation (§3.1): every input triangle whose corners fall into three distinct
//! leaves survives, with its corners re-mapped, in input order; of triangles that map to the
//! same three cells only the first is kept. Never-collapsed leaves keep their vertex and its
//! wedges; a collapsed cell of `cluster` gets one new vertex with one wedge (its attributes
//! from the quadric; §3.1.2 as we read it: one attribute set per output vertex, so seams
//! inside a cell close, which the `seam_fix` step then repairs); a collapsed cell of
//! `cluster-keep` is represented by its chosen original vertex, each corner taking that
//! vertex's wedge whose texture coordinate is nearest to the corner's own. Clustering does
//! not preserve manifoldness (our note on §3.1); the guards of the collapse methods do not
//! apply here.

use super::quadric::{Quadric, Reduced, Weights, dot, sym_mul};
use super::{DecimateParams, DecimateReport, Fallback, Method};
use crate::mesh::{Index, Mesh, Wedge};
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashSet};

const LEVELS: u32 = 21;
const NIL: u32 = u32::MAX;

fn spread(mut x: u64) -> u64 {
    x &= 0x1f_ffff;
    x = (x | x << 32) & 0x1f00000000ffff;
    x = (x | x << 16) & 0x1f0000ff0000ff;
    x = (x | x << 8) & 0x100f00f00f00f00f;
    x = (x | x << 4) & 0x10c30c30c30c30c3;
    x = (x | x << 2) & 0x1249249249249249;
    x
}

/// The octal digit of `key` at `depth` (0 = root's children).
#[inline]
fn digit(key: u64, depth: u32) -> u64 {
    (key >> (3 * (LEVELS - 1 - depth))) & 7
}

struct Node {
    lo: u32,
    hi: u32,
    parent: u32,
    /// Children that are not leaves yet.
    inner_children: u32,
    leaf: bool,
}

/// Per-vertex data of the vo metric (§3.1.1, eqs. 3.1–3.3 rearranged by us into O(1) form).
#[derive(Clone, Copy, Default)]
struct VoSums {
    geo: Reduced,
    k: f64,
    t: [f64; 2],
    tt: f64,
    n: [f64; 3],
    nn: f64,
}

impl VoSums {
    fn add(&mut self, o: &VoSums) {
        self.geo.add(&o.geo);
        self.k += o.k;
        for i in 0..2 {
            self.t[i] += o.t[i];
        }
        self.tt += o.tt;
        for i in 0..3 {
            self.n[i] += o.n[i];
        }
        self.nn += o.nn;
    }
}

/// A cell collapse as evaluated: error (quadric value), position, attributes (v) and the
/// chosen original vertex (vo).
type CellPlan<const M: usize> = (f64, [f64; 3], [f64; M], u32);

/// Cells by cost, cheapest first: (the cost's bits, the cell).
type CostHeap = BinaryHeap<Reverse<(u64, u32)>>;

struct Cluster<'a, const M: usize> {
    mesh: &'a Mesh,
    params: &'a DecimateParams,
    w: Weights<M>,
    pos: Vec<[f64; 3]>,
    /// Vertices sorted by Morton key; `rank[v]` is v's place.
    order: Vec<u32>,
    rank: Vec<u32>,
    nodes: Vec<Node>,
    /// Quadric per vertex (v) or vo sums per vertex.
    vq: Vec<Quadric<M>>,
    vo: Vec<VoSums>,
    /// Vertex → triangles (CSR).
    vt_off: Vec<u32>,
    vt: Vec<u32>,
    dead: Vec<bool>,
    live: usize,
    /// Representative of each collapsed node: position, attributes (v) or vertex (vo).
    rep_pos: Vec<[f64; 3]>,
    rep_attr: Vec<[f64; M]>,
    rep_vertex: Vec<u32>,
    /// Node of each vertex's leaf after pruning.
    leaf_of: Vec<u32>,
}

impl<'a, const M: usize> Cluster<'a, M> {
    fn new(mesh: &'a Mesh, params: &'a DecimateParams, w: Weights<M>) -> Self {
        let (lo, hi) = mesh.bounding_box().unwrap_or((DVec3::ZERO, DVec3::ONE));
        let extent = (hi - lo).max_element().max(f64::MIN_POSITIVE);
        let pos: Vec<[f64; 3]> = mesh
            .positions
            .iter()
            .map(|&p| ((p - lo) / extent).to_array())
            .collect();
        let scale = (1u64 << LEVELS) as f64;
        let keys: Vec<u64> = pos
            .iter()
            .map(|p| {
                let q = p.map(|c| ((c * scale) as u64).min((1 << LEVELS) - 1));
                spread(q[0]) << 2 | spread(q[1]) << 1 | spread(q[2])
            })
            .collect();
        let mut order: Vec<u32> = (0..pos.len() as u32).collect();
        order.sort_unstable_by_key(|&v| (keys[v as usize], v));
        let mut rank = vec![0u32; pos.len()];
        for (i, &v) in order.iter().enumerate() {
            rank[v as usize] = i as u32;
        }
        // Vertex → triangles.
        let nv = pos.len();
        let mut vt_off = vec![0u32; nv + 1];
        for t in 0..mesh.triangles.len() {
            for v in mesh.triangle_vertices(t) {
                vt_off[v as usize + 1] += 1;
            }
        }
        for i in 0..nv {
            vt_off[i + 1] += vt_off[i];
        }
        let mut fill = vt_off.clone();
        let mut vt = vec![0u32; mesh.triangles.len() * 3];
        for t in 0..mesh.triangles.len() {
            for v in mesh.triangle_vertices(t) {
                vt[fill[v as usize] as usize] = t as u32;
                fill[v as usize] += 1;
            }
        }
        let mut c = Cluster {
            mesh,
            params,
            w,
            pos,
            order,
            rank,
            nodes: Vec::new(),
            vq: Vec::new(),
            vo: Vec::new(),
            vt_off,
            vt,
            dead: vec![false; mesh.triangles.len()],
            live: mesh.triangles.len(),
            rep_pos: Vec::new(),
            rep_attr: Vec::new(),
            rep_vertex: Vec::new(),
            leaf_of: vec![NIL; nv],
        };
        c.build(&keys);
        c.vertex_data();
        c
    }

    /// The compressed octree over the sorted keys.
    fn build(&mut self, keys: &[u64]) {
        let n = self.order.len() as u32;
        // (lo, hi, depth, parent)
        let mut stack = vec![(0u32, n, 0u32, NIL)];
        while let Some((lo, hi, mut depth, parent)) = stack.pop() {
            let key = |i: u32| keys[self.order[i as usize] as usize];
            // Skip levels where every point shares the digit (single-child chains).
            while depth < LEVELS && digit(key(lo), depth) == digit(key(hi - 1), depth) {
                depth += 1;
            }
            let id = self.nodes.len() as u32;
            let leaf = hi - lo == 1 || depth >= LEVELS;
            self.nodes.push(Node {
                lo,
                hi,
                parent,
                inner_children: 0,
                leaf,
            });
            if parent != NIL && !leaf {
                self.nodes[parent as usize].inner_children += 1;
            }
            if leaf {
                continue;
            }
            let mut start = lo;
            while start < hi {
                let d = digit(key(start), depth);
                let mut end = start + 1;
                while end < hi && digit(key(end), depth) == d {
                    end += 1;
                }
                stack.push((start, end, depth + 1, id));
                start = end;
            }
        }
    }

    fn corner_attr(&self, w: Index) -> [f64; M] {
        let wd = self.mesh.wedges[w as usize];
        let mut a = [0.0; M];
        let mut k = 0;
        if !self.mesh.texcoords.is_empty() && M >= 2 {
            if let Some(t) = wd.texcoord {
                let uv = self.mesh.texcoords[t as usize];
                a[0] = uv.x;
                a[1] = uv.y;
            }
            k = 2;
        }
        if !self.mesh.normals.is_empty()
            && M >= k + 3
            && let Some(n) = wd.normal
        {
            let n = self.mesh.normals[n as usize];
            a[k] = n.x;
            a[k + 1] = n.y;
            a[k + 2] = n.z;
        }
        a
    }

    /// Per-vertex quadric (v: the (vertex, face) items of §3.1.2 summed) or vo sums (§3.1.1).
    fn vertex_data(&mut self) {
        let keep = self.params.method == Method::ClusterKeep;
        let this = &*self;
        let per: Vec<(Quadric<M>, VoSums)> = (0..this.pos.len())
            .into_par_iter()
            .map(|v| {
                let mut q = Quadric::<M>::default();
                let mut s = VoSums::default();
                for &t in &this.vt[this.vt_off[v] as usize..this.vt_off[v + 1] as usize] {
                    let t = t as usize;
                    let tri = this.mesh.triangles[t];
                    let p = tri.map(|w| this.pos[this.mesh.wedges[w as usize].vertex as usize]);
                    let a = tri.map(|w| this.corner_attr(w));
                    let Some(fq) = Quadric::from_triangle(p, a, &this.w) else {
                        continue;
                    };
                    if keep {
                        // vo: one unit-weight plane per item (eq. 3.1), corner attributes.
                        let unit = Quadric::<M>::from_triangle(
                            p,
                            [[0.0; M]; 3],
                            &Weights {
                                geom: 1.0,
                                attr: [0.0; M],
                            },
                        )
                        .map(|q| q.split().0)
                        .unwrap_or_default();
                        // from_triangle weights by area; eq. 3.1 sums unit planes.
                        let area = fq.attr.alpha.max(f64::MIN_POSITIVE);
                        let mut g = unit;
                        for x in g.m.iter_mut() {
                            *x /= area;
                        }
                        for x in g.r.iter_mut() {
                            *x /= area;
                        }
                        g.c /= area;
                        s.geo.add(&g);
                        s.k += 1.0;
                        let k = tri
                            .iter()
                            .position(|&w| this.mesh.wedges[w as usize].vertex as usize == v)
                            .unwrap_or(0);
                        let at = a[k];
                        if M >= 2 && !this.mesh.texcoords.is_empty() {
                            s.t[0] += at[0];
                            s.t[1] += at[1];
                            s.tt += at[0] * at[0] + at[1] * at[1];
                        }
                    } else {
                        q.add(&fq);
                    }
                }
                (q, s)
            })
            .collect();
        if keep {
            self.vo = per.into_iter().map(|(_, s)| s).collect();
        } else {
            self.vq = per.into_iter().map(|(q, _)| q).collect();
        }
    }

    /// Representative and error of collapsing node `id` into one cell.
    fn evaluate(&self, id: usize) -> CellPlan<M> {
        let node = &self.nodes[id];
        let range = &self.order[node.lo as usize..node.hi as usize];
        let n = range.len() as f64;
        let mut mean = [0.0; 3];
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for &v in range {
            for k in 0..3 {
                let x = self.pos[v as usize][k];
                mean[k] += x / n;
                lo[k] = lo[k].min(x);
                hi[k] = hi[k].max(x);
            }
        }
        if self.params.method == Method::ClusterKeep {
            let mut s = VoSums::default();
            for &v in range {
                s.add(&self.vo[v as usize]);
            }
            let (wg, wt) = (
                self.params.weight(self.params.geometry_weight),
                self.params.weight(self.params.texture_weight),
            );
            let mut best = (f64::INFINITY, range[0]);
            for &v in range {
                let p = self.pos[v as usize];
                let e_geo =
                    (dot(p, sym_mul(&s.geo.m, p)) + 2.0 * dot(s.geo.r, p) + s.geo.c).max(0.0);
                let t = self.first_uv(v);
                let e_tex = s.k * (t[0] * t[0] + t[1] * t[1])
                    - 2.0 * (t[0] * s.t[0] + t[1] * s.t[1])
                    + s.tt;
                let e = wg * e_geo + wt * e_tex.max(0.0);
                if e < best.0 {
                    best = (e, v);
                }
            }
            return (best.0, self.pos[best.1 as usize], [0.0; M], best.1);
        }
        let mut q = Quadric::<M>::default();
        for &v in range {
            q.add(&self.vq[v as usize]);
        }
        let mut red = Reduced::default();
        red.add_wedge(&q, &self.w);
        let regularise = self.params.fallback == Fallback::Regularised;
        let (mut p, _) = red.minimise(mean, self.params.max_condition, regularise);
        // Guard (not in the thesis, §3.1.2 algorithm v): the minimiser of a cell whose
        // quadric is nearly singular along some direction can lie far outside the cell
        // although the conditioning test passed (it happens on real scans: docs/decimation.md).
        // A representative farther than a
        // quarter of the cluster's extent outside the box of its vertices falls back to
        // their mean, as out-of-core clustering keeps its representative in the cell.
        let margin = 0.25 * (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        if (0..3).any(|k| !(p[k] >= lo[k] - margin && p[k] <= hi[k] + margin)) {
            p = mean;
        }
        let attr = q.attributes_at(p).unwrap_or([0.0; M]);
        (red.eval(p), p, attr, NIL)
    }

    fn first_uv(&self, v: u32) -> [f64; 2] {
        let t = self.vt[self.vt_off[v as usize] as usize] as usize;
        let tri = self.mesh.triangles[t];
        let w = *tri
            .iter()
            .find(|&&w| self.mesh.wedges[w as usize].vertex == v)
            .unwrap_or(&tri[0]);
        self.mesh
            .wedge_texcoord(w)
            .map(|t| [t.x, t.y])
            .unwrap_or([0.0; 2])
    }

    /// Turns node `id` into a leaf: triangles with two corners in it die.
    fn collapse(&mut self, id: usize) {
        let (lo, hi) = (self.nodes[id].lo, self.nodes[id].hi);
        self.nodes[id].leaf = true;
        for i in lo..hi {
            let v = self.order[i as usize] as usize;
            for &t in &self.vt[self.vt_off[v] as usize..self.vt_off[v + 1] as usize] {
                let t = t as usize;
                if self.dead[t] {
                    continue;
                }
                let inside = self
                    .mesh
                    .triangle_vertices(t)
                    .iter()
                    .filter(|&&x| (lo..hi).contains(&self.rank[x as usize]))
                    .count();
                if inside >= 2 {
                    self.dead[t] = true;
                    self.live -= 1;
                }
            }
        }
    }

    fn run(mut self) -> (Mesh, DecimateReport) {
        let nn = self.nodes.len();
        self.rep_pos = vec![[0.0; 3]; nn];
        self.rep_attr = vec![[0.0; M]; nn];
        self.rep_vertex = vec![NIL; nn];
        let mut collapsed = vec![false; nn];
        self.collapse_coincident_leaves(&mut collapsed);
        let diag = self.mesh.bounding_box_diagonal();
        let (lo, hi) = self
            .mesh
            .bounding_box()
            .unwrap_or((DVec3::ZERO, DVec3::ONE));
        let to_diag = (hi - lo).max_element() / diag.max(f64::MIN_POSITIVE);
        let max_error = self.params.max_error.map_or(f64::INFINITY, |e| e / to_diag);
        let target = self.params.target_faces.unwrap_or(0);
        let (mut plans, mut heap) = self.frontier_plans();
        let mut report = DecimateReport {
            stopped_by: super::StopReason::Target,
            ..Default::default()
        };
        let mut error_reached = 0.0f64;
        while self.live > target {
            let Some(Reverse((_, id))) = heap.pop() else {
                report.stopped_by = super::StopReason::NoCandidates;
                break;
            };
            let id = id as usize;
            let Some((cost, p, a, r)) = plans[id].take() else {
                continue;
            };
            let area: f64 = if self.params.method == Method::ClusterKeep {
                1.0
            } else {
                let node = &self.nodes[id];
                self.order[node.lo as usize..node.hi as usize]
                    .iter()
                    .map(|&v| self.vq[v as usize].attr.alpha)
                    .sum()
            };
            let error = (cost.max(0.0) / area.max(f64::MIN_POSITIVE)).sqrt();
            if error > max_error {
                report.stopped_by = super::StopReason::MaxError;
                break;
            }
            error_reached = error_reached.max(error);
            (self.rep_pos[id], self.rep_attr[id], self.rep_vertex[id]) = (p, a, r);
            collapsed[id] = true;
            self.collapse(id);
            report.collapses += 1;
            let parent = self.nodes[id].parent;
            if parent != NIL {
                let par = &mut self.nodes[parent as usize];
                par.inner_children -= 1;
                if par.inner_children == 0 {
                    let plan = self.evaluate(parent as usize);
                    heap.push(Reverse(((plan.0.max(0.0) + 0.0).to_bits(), parent)));
                    plans[parent as usize] = Some(plan);
                }
            }
        }
        self.assign_cells(&collapsed);
        report.clusters = Some({
            let mut leaves: Vec<u32> = self.leaf_of.clone();
            leaves.sort_unstable();
            leaves.dedup();
            leaves.len()
        });
        report.error_reached = error_reached * to_diag;
        let out = self.into_mesh(&collapsed, lo, (hi - lo).max_element());
        (out, report)
    }

    /// Leaves holding several (coincident) points are collapsed from the start.
    fn collapse_coincident_leaves(&mut self, collapsed: &mut [bool]) {
        for id in 0..self.nodes.len() {
            let node = &self.nodes[id];
            if node.leaf && node.hi - node.lo > 1 {
                let (_, p, a, r) = self.evaluate(id);
                (self.rep_pos[id], self.rep_attr[id], self.rep_vertex[id]) = (p, a, r);
                collapsed[id] = true;
                self.collapse(id);
            }
        }
    }

    /// The plans of the cells whose children are all leaves (the first candidates, evaluated
    /// in parallel), and the heap of their costs.
    fn frontier_plans(&self) -> (Vec<Option<CellPlan<M>>>, CostHeap) {
        let nn = self.nodes.len();
        let frontier: Vec<usize> = (0..nn)
            .filter(|&id| !self.nodes[id].leaf && self.nodes[id].inner_children == 0)
            .collect();
        let mut plans: Vec<Option<CellPlan<M>>> = (0..nn).map(|_| None).collect();
        let mut heap = BinaryHeap::new();
        let evaluated: Vec<(usize, CellPlan<M>)> = frontier
            .par_iter()
            .map(|&id| (id, self.evaluate(id)))
            .collect();
        for (id, plan) in evaluated {
            heap.push(Reverse(((plan.0.max(0.0) + 0.0).to_bits(), id as u32)));
            plans[id] = Some(plan);
        }
        (plans, heap)
    }

    /// The cell of every vertex (`leaf_of`): the highest collapsed ancestor of its leaf, else
    /// the leaf itself. Nodes were created parents-first, so a pass in creation order
    /// suffices; collapsed nodes that are not leaves of the creation tree hand their cell
    /// down to their subtree's vertices through `top`.
    fn assign_cells(&mut self, collapsed: &[bool]) {
        let nn = self.nodes.len();
        let mut top: Vec<u32> = vec![NIL; nn];
        for id in 0..nn {
            let parent = self.nodes[id].parent;
            let inherited = if parent == NIL {
                NIL
            } else {
                top[parent as usize]
            };
            top[id] = if inherited != NIL {
                inherited
            } else if collapsed[id] {
                id as u32
            } else {
                NIL
            };
            if self.nodes[id].leaf && self.nodes[id].hi - self.nodes[id].lo >= 1 {
                for i in self.nodes[id].lo..self.nodes[id].hi {
                    let v = self.order[i as usize] as usize;
                    self.leaf_of[v] = if top[id] != NIL { top[id] } else { id as u32 };
                }
            }
        }
    }

    fn into_mesh(self, collapsed: &[bool], lo: DVec3, extent: f64) -> Mesh {
        let mesh = self.mesh;
        let keep = self.params.method == Method::ClusterKeep;
        let mut out = mesh.without_triangles();
        let cell_wedge = if keep {
            Vec::new()
        } else {
            self.add_cell_vertices(&mut out, collapsed, lo, extent)
        };
        let mut seen: HashSet<[u32; 3]> = HashSet::new();
        for t in 0..mesh.triangles.len() {
            let vs = mesh.triangle_vertices(t);
            let cells = vs.map(|v| self.leaf_of[v as usize]);
            if cells[0] == cells[1] || cells[1] == cells[2] || cells[0] == cells[2] {
                continue;
            }
            let mut key = cells;
            key.sort_unstable();
            if !seen.insert(key) {
                continue;
            }
            let mut tri = mesh.triangles[t];
            for k in 0..3 {
                let cell = cells[k] as usize;
                if !collapsed[cell] {
                    continue;
                }
                if keep {
                    let r = self.rep_vertex[cell];
                    if r != vs[k] {
                        tri[k] = self.nearest_wedge(r, tri[k]);
                    }
                } else {
                    tri[k] = cell_wedge[cell];
                }
            }
            out.triangles.push(tri);
            if !mesh.triangle_materials.is_empty() {
                out.triangle_materials.push(mesh.triangle_materials[t]);
            }
            out.triangle_origins.push(mesh.triangle_origin(t));
        }
        out.compact();
        out
    }

    /// One new vertex and wedge per collapsed cell in use, at its representative position
    /// (scaled back by `lo` and `extent`) with its representative attributes; returns each
    /// cell's wedge (`NIL` for the others).
    fn add_cell_vertices(
        &self,
        out: &mut Mesh,
        collapsed: &[bool],
        lo: DVec3,
        extent: f64,
    ) -> Vec<u32> {
        let mesh = self.mesh;
        let nn = self.nodes.len();
        let has_uv = !mesh.texcoords.is_empty() && M >= 2;
        let has_n = !mesh.normals.is_empty() && M >= if has_uv { 5 } else { 3 };
        let mut is_cell = vec![false; nn];
        for &c in &self.leaf_of {
            if c != NIL {
                is_cell[c as usize] = true;
            }
        }
        let mut cell_wedge = vec![NIL; nn];
        for id in 0..nn {
            if !collapsed[id] || !is_cell[id] {
                continue;
            }
            let p = DVec3::from_array(self.rep_pos[id]) * extent + lo;
            out.positions.push(p);
            if !out.colors.is_empty() {
                let v = self.order[self.nodes[id].lo as usize] as usize;
                out.colors.push(mesh.colors[v]);
            }
            let vertex = (out.positions.len() - 1) as u32;
            let a = self.rep_attr[id];
            let texcoord = has_uv.then(|| {
                out.texcoords.push(DVec2::new(a[0], a[1]));
                (out.texcoords.len() - 1) as Index
            });
            let k = if has_uv { 2 } else { 0 };
            let normal = has_n.then(|| {
                let n = DVec3::new(a[k], a[k + 1], a[k + 2])
                    .try_normalize()
                    .unwrap_or(DVec3::Z);
                out.normals.push(n);
                (out.normals.len() - 1) as Index
            });
            out.wedges.push(Wedge {
                vertex,
                texcoord,
                normal,
            });
            cell_wedge[id] = (out.wedges.len() - 1) as u32;
        }
        cell_wedge
    }

    /// `cluster-keep`: the wedge of representative vertex `r` whose texture coordinate is
    /// nearest that of wedge `own` (the corner's own), lowest index on a tie; `own` when `r`
    /// has none.
    fn nearest_wedge(&self, r: u32, own: Index) -> Index {
        let mesh = self.mesh;
        let own_uv = mesh.wedge_texcoord(own).unwrap_or_default();
        let mut ws: Vec<Index> = self.vt
            [self.vt_off[r as usize] as usize..self.vt_off[r as usize + 1] as usize]
            .iter()
            .flat_map(|&t| mesh.triangles[t as usize])
            .filter(|&w| mesh.wedges[w as usize].vertex == r)
            .collect();
        ws.sort_unstable();
        ws.dedup();
        ws.iter()
            .copied()
            .min_by(|&a, &b| {
                let da = mesh.wedge_texcoord(a).unwrap_or_default().distance(own_uv);
                let db = mesh.wedge_texcoord(b).unwrap_or_default().distance(own_uv);
                da.total_cmp(&db).then(a.cmp(&b))
            })
            .unwrap_or(own)
    }
}

pub fn run<const M: usize>(
    mesh: &Mesh,
    params: &DecimateParams,
    w: Weights<M>,
) -> (Mesh, DecimateReport) {
    Cluster::<M>::new(mesh, params, w).run()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_digits() {
        let k = spread(0b101) << 2 | spread(0b011) << 1 | spread(0b110);
        // Lowest level: x=1, y=1, z=0 → 0b110; next: x=0,y=1,z=1 → 0b011; top: x=1,y=0,z=1.
        assert_eq!(k & 7, 0b110);
        assert_eq!((k >> 3) & 7, 0b011);
        assert_eq!((k >> 6) & 7, 0b101);
        assert_eq!(digit(k, LEVELS - 1), 0b110);
    }
}
