//! The working mesh of the collapse decimators (the thesis' `WedgeScene`, §6.4):
//! unit-box-normalised f64 positions, wedges with their attributes and (3+m) quadrics,
//! triangles of wedge indices, and per-vertex corner lists kept as linked lists so that a
//! merge relinks in place (no allocation per collapse).
//!
//! One merge operation serves both face collapse (three vertices, §3.2) and edge collapse
//! (two): [`Work::evaluate`] places the new vertex, [`Work::check`] runs the guards and
//! [`Work::apply`] performs it.

use super::guards::{
    DEGENERATE_QUALITY, LinkScratch, LinkShape, SLIVER_QUALITY, VClass, link_shape, quality,
    uv_area,
};
use super::prefetch::prefetch;
use super::quadric::{
    AttrPart, Quadric, Reduced, WedgeAttrs, WedgeQuadrics, Weights, cross, dense_condition_number,
    dot, sub,
};
use super::{Conditioning, Fallback, Refusal};
use crate::mesh::{Index, Mesh, Wedge};
use crate::ops::border::Border;
use glam::{DVec2, DVec3};
use rayon::prelude::*;

pub const NIL: u32 = u32::MAX;

/// Most corners the vertices of one merge may have together ([`Work::star`]). A merge walks
/// its vertices' corners and checks every triangle that survives around them, so one
/// attempt costs time in their number; around a vertex of valence k (a fan of 50,000
/// triangles) each of its k edges would cost k, O(k²) in all. Larger merges are refused
/// ([`Refusal::Valence`]) before any walk, which keeps every attempt O(`MAX_STAR`). Scan
/// vertices have a few dozen corners at most, even late in a decimation to a fifteenth
/// (tests/quadratic_corners.rs counts the refusals on the scans: none).
pub const MAX_STAR: u32 = 256;

/// Distinct `u32` keys in the order they were first met, and the place of each: a plain
/// scan while there are few (a vertex has one to four wedges), a hash map from
/// [`KeyIndex::SCAN`] keys on, so that a vertex with k wedges costs O(k), not O(k²).
#[derive(Debug, Default)]
pub struct KeyIndex {
    keys: Vec<u32>,
    places: rustc_hash::FxHashMap<u32, u32>,
}

impl KeyIndex {
    /// Up to this many keys a scan is cheaper than hashing.
    const SCAN: usize = 16;

    pub fn clear(&mut self) {
        self.keys.clear();
        self.places.clear();
    }

    pub fn keys(&self) -> &[u32] {
        &self.keys
    }

    pub fn len(&self) -> usize {
        self.keys.len()
    }

    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// The place of `key`, if met.
    #[inline]
    pub fn get(&self, key: u32) -> Option<usize> {
        if self.keys.len() <= Self::SCAN {
            self.keys.iter().position(|&k| k == key)
        } else {
            self.places.get(&key).map(|&i| i as usize)
        }
    }

    /// The place of `key`, adding it at the end if new; `true` when it was new.
    #[inline]
    pub fn insert(&mut self, key: u32) -> (usize, bool) {
        if let Some(i) = self.get(key) {
            return (i, false);
        }
        let i = self.keys.len();
        self.keys.push(key);
        if self.keys.len() == Self::SCAN + 1 {
            self.places
                .extend(self.keys.iter().enumerate().map(|(i, &k)| (k, i as u32)));
        } else if self.keys.len() > Self::SCAN + 1 {
            self.places.insert(key, i as u32);
        }
        (i, true)
    }
}

/// Octahedral encoding of a direction (any length; zero stays zero) in two signed 16-bit
/// halves: the direction is projected onto the octahedron |x| + |y| + |z| = 1 and the
/// lower half folded over onto the upper. Angular error below 1e-4 rad. The zero vector
/// (a degenerate input triangle) gets a code of its own ([`OCT_ZERO`]: −32768 never
/// comes out of the quantiser).
pub fn oct_encode(n: [f64; 3]) -> u32 {
    let l1 = n[0].abs() + n[1].abs() + n[2].abs();
    if !(l1 > 0.0) || !l1.is_finite() {
        return OCT_ZERO;
    }
    let (mut x, mut y) = (n[0] / l1, n[1] / l1);
    if n[2] < 0.0 {
        (x, y) = ((1.0 - y.abs()) * x.signum(), (1.0 - x.abs()) * y.signum());
    }
    let q = |v: f64| ((v.clamp(-1.0, 1.0) * 32767.0).round() as i16) as u16 as u32;
    q(x) | (q(y) << 16)
}

pub const OCT_ZERO: u32 = 0x8000_8000;

/// Inverse of [`oct_encode`], up to length (not normalised); zero for zero.
pub fn oct_decode(e: u32) -> [f64; 3] {
    if e == OCT_ZERO {
        return [0.0; 3];
    }
    let x = (e as u16 as i16) as f64 / 32767.0;
    let y = ((e >> 16) as u16 as i16) as f64 / 32767.0;
    let z = 1.0 - x.abs() - y.abs();
    if z < 0.0 {
        [
            (1.0 - y.abs()) * x.signum(),
            (1.0 - x.abs()) * y.signum(),
            z,
        ]
    } else {
        [x, y, z]
    }
}

/// Most (vertex, corner) entries around one vertex that its classification scans rather
/// than sorts (see [`Work::new`]'s classification): about valence 20.
const SCAN_TOUCHING: usize = 64;

/// Reusable buffers of one vertex's classification (one per thread).
#[derive(Default)]
struct ClassifyScratch {
    corners: Vec<u32>,
    link: Vec<(u32, u32)>,
    lsc: LinkScratch,
    /// (vertex, place in `corners`) for each vertex of each corner's triangle.
    touching: Vec<(u32, u32)>,
    /// `touching` is sorted by vertex (more than [`SCAN_TOUCHING`] entries).
    sorted: bool,
    /// The constraint planes of the vertex's seam and border edges, in the order met.
    planes: Vec<Plane>,
}

/// A constraint plane as (unit normal, point, weight).
type Plane = ([f64; 3], [f64; 3], f64);

/// One vertex's classification (its constraint planes are left in the scratch).
struct VertexInfo {
    class: VClass,
    border: bool,
    /// Inner-loop steps, for [`Work::classify_steps`].
    steps: u64,
}

/// The seam and border edges around one vertex, and their constraint planes.
#[derive(Default)]
struct StarEdges {
    seam: usize,
    border: usize,
    planes: Vec<Plane>,
}

/// Binary digits of `n` (⌈log₂(n + 1)⌉): the steps of a binary search over `n` items.
fn bits(n: usize) -> usize {
    (usize::BITS - n.leading_zeros()) as usize
}

/// Settings of the merge machinery, resolved from the step parameters.
#[derive(Debug, Clone, Copy)]
pub struct Config {
    pub boundary: Border,
    pub boundary_weight: f64,
    pub seam_weight: f64,
    pub conditioning: Conditioning,
    pub max_condition: f64,
    pub fallback: Fallback,
    /// Cosine of the largest normal change a collapse may cause on a surviving triangle.
    pub cos_max_normal_change: f64,
    /// Run the guards (link condition, flips, degeneracy); off = thesis-literal.
    pub guards: bool,
}

/// Where the merged vertex goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Placement {
    /// Minimiser of the wedge-aware quadric (§3.2).
    Free,
    /// At the position of `S[i]`, which keeps its place and its wedges' attributes (a
    /// fixed, seam or border vertex absorbing neighbours: a half-edge collapse onto it).
    Anchor(usize),
}

/// A merge as evaluated: new position, cost (quadric value), error (RMS distance in
/// normalised units) and whether the ill-conditioned fallback was used.
#[derive(Debug, Clone, Copy)]
pub struct Plan {
    pub p: [f64; 3],
    pub placement: Placement,
    pub cost: f64,
    pub error: f64,
    pub fallback: bool,
    /// The merged vertex's reduced position system.
    pub red: Reduced,
}

/// Wedges of the merged vertices that end up as one wedge (thesis §3.2, Fig. 3.3).
#[derive(Debug, Clone, Copy)]
pub struct Group<const M: usize> {
    pub rep: u32,
    /// Number of wedges merged into this group.
    pub size: u32,
    pub q: AttrPart<M>,
    /// The wedge of `S[i]` in this group, or NIL.
    pub at: [u32; 3],
    pub attr: [f64; M],
}

/// Reusable buffers for one merge (one per thread during the parallel set-up).
pub struct Scratch<const M: usize> {
    pub s: [u32; 3],
    pub ns: usize,
    /// Corners at S of the triangles that survive (exactly one corner in S).
    pub corners: Vec<u32>,
    /// Triangles that the merge deletes (two or more corners in S).
    pub dead: Vec<u32>,
    /// The wedges at S, in the order met.
    lw: KeyIndex,
    lw_si: Vec<u8>,
    lw_parent: Vec<u32>,
    lw_group: Vec<u32>,
    pub groups: Vec<Group<M>>,
    link: Vec<(u32, u32)>,
    link_sc: LinkScratch,
    dense: Vec<Quadric<M>>,
}

impl<const M: usize> Default for Scratch<M> {
    fn default() -> Self {
        Scratch {
            s: [NIL; 3],
            ns: 0,
            corners: Vec::with_capacity(64),
            dead: Vec::with_capacity(8),
            lw: KeyIndex::default(),
            lw_si: Vec::with_capacity(16),
            lw_parent: Vec::with_capacity(16),
            lw_group: Vec::with_capacity(16),
            groups: Vec::with_capacity(8),
            link: Vec::with_capacity(64),
            link_sc: LinkScratch::default(),
            dense: Vec::new(),
        }
    }
}

impl<const M: usize> Scratch<M> {
    /// Empties the scratch for a merge of `s`.
    #[inline]
    fn reset(&mut self, s: &[u32]) {
        self.ns = s.len();
        self.s = [NIL; 3];
        self.s[..s.len()].copy_from_slice(s);
        self.corners.clear();
        self.dead.clear();
        self.lw.clear();
        self.lw_si.clear();
        self.groups.clear();
    }
    #[inline]
    fn local(&self, w: u32) -> usize {
        self.lw.get(w).unwrap_or(usize::MAX)
    }
    fn find(&mut self, mut i: usize) -> usize {
        while self.lw_parent[i] as usize != i {
            let p = self.lw_parent[i] as usize;
            self.lw_parent[i] = self.lw_parent[p];
            i = p;
        }
        i
    }
    /// The group a wedge of S belongs to.
    #[inline]
    pub fn group_of(&self, w: u32) -> &Group<M> {
        &self.groups[self.lw_group[self.local(w)] as usize]
    }
}

/// Vertex counts by class, for the report.
#[derive(Debug, Clone, Copy, Default)]
pub struct ClassCounts {
    pub interior: usize,
    pub border: usize,
    pub seam: usize,
    pub fixed: usize,
}

pub struct Work<const M: usize> {
    pub center: DVec3,
    /// Normalised = (p − center) · inv_scale; the largest box side becomes 1.
    pub inv_scale: f64,
    pub pos: Vec<[f64; 3]>,
    pub moved: Vec<bool>,
    pub class: Vec<VClass>,
    /// Vertex has border edges.
    pub border: Vec<bool>,
    pub vfirst: Vec<u32>,
    pub cnext: Vec<u32>,
    /// Length of each vertex's corner list (live and dead corners: what a walk costs).
    pub star: Vec<u32>,
    /// Wedge indices of each triangle.
    pub tris: Vec<[u32; 3]>,
    /// Material of each triangle, or empty when the input's triangles all have one (the
    /// only use is to compare two triangles' materials). The working mesh keeps no
    /// reference to its input, so that a caller that owns the input may drop parts of it
    /// while the collapse loop runs (the halves, `halves.rs`).
    tmat: Vec<Index>,
    /// Vertex indices of each triangle; `[NIL; 3]` once deleted.
    pub tv: Vec<[u32; 3]>,
    pub wvert: Vec<u32>,
    pub wattr: WedgeAttrs<M>,
    /// Unit normal of each input triangle, octahedron-encoded in 2 × 16 bits (only the
    /// sign of its dot product with a new normal is tested, and it is read once per
    /// surviving triangle per collapse, so it should be compact: 4 instead of 12 bytes).
    pub onormal: Vec<u32>,
    /// Attribute part of each wedge quadric.
    pub wq: WedgeQuadrics<M>,
    /// Position part of each vertex quadric, summed over its wedges and reduced (their
    /// attribute blocks eliminated, §2.3.3).
    pub vred: Vec<Reduced>,
    pub wchanged: Vec<bool>,
    pub live: usize,
    pub w: Weights<M>,
    pub has_uv: bool,
    pub has_normals: bool,
    pub cfg: Config,
    pub classes: ClassCounts,
    /// Inner-loop steps of the vertex classification (corners and neighbours visited,
    /// sort and search steps), for the cost tests: it must grow like the corner count, not
    /// like the square of a vertex's valence.
    #[doc(hidden)]
    pub classify_steps: u64,
}

impl<const M: usize> Work<M> {
    /// Builds the working mesh: normalised positions, corner lists, vertex classes and
    /// the wedge quadrics (in parallel).
    ///
    /// `origin`, when given, is the mesh that `input`'s `triangle_origins` index (an
    /// earlier decimation's input): the flip guard then holds each triangle against the
    /// normal of its triangle there instead of its own, so that a second decimation of a
    /// decimated mesh keeps the guarantee against the first one's input.
    pub fn new(input: &Mesh, w: Weights<M>, cfg: Config, origin: Option<&Mesh>) -> Self {
        let mut work = Self::copied(input, w, cfg, origin);
        work.prepare();
        work
    }

    /// [`Work::new`] without the quadrics and vertex classes ([`Work::prepare`] adds them):
    /// what the working mesh copies from `input`. The input is not read again until
    /// [`Work::into_mesh`], so a caller that owns it may drop parts of it before the
    /// quadrics, the set-up's largest arrays, are allocated.
    pub fn copied(input: &Mesh, w: Weights<M>, cfg: Config, origin: Option<&Mesh>) -> Self {
        let has_uv = !input.texcoords.is_empty() && M >= 2;
        let has_normals = !input.normals.is_empty() && (M == 3 || M == 5);
        let (center, inv_scale, pos) = normalised_positions(input);
        let nv = pos.len();
        let tris = input.triangles.clone();
        let wvert: Vec<u32> = input.wedges.iter().map(|w| w.vertex).collect();
        let wattr = wedge_attributes(input, has_uv, has_normals);
        let (vfirst, cnext, star) = corner_lists(&tris, &wvert, nv);
        let nw = wvert.len();
        let tv: Vec<[u32; 3]> = tris.iter().map(|t| t.map(|w| wvert[w as usize])).collect();
        let tmat = match input.triangle_materials.split_first() {
            Some((first, rest)) if rest.iter().any(|m| m != first) => {
                input.triangle_materials.clone()
            }
            _ => Vec::new(),
        };
        Work {
            center,
            inv_scale,
            pos,
            moved: vec![false; nv],
            class: vec![VClass::Interior; nv],
            border: vec![false; nv],
            vfirst,
            cnext,
            star,
            live: tris.len(),
            tris,
            tmat,
            tv,
            wvert,
            wattr,
            wq: WedgeQuadrics::default(),
            vred: Vec::new(),
            onormal: origin_normals(input, origin),
            wchanged: vec![false; nw],
            w,
            has_uv,
            has_normals,
            cfg,
            classes: ClassCounts::default(),
            classify_steps: 0,
        }
    }

    /// The quadrics, then the vertex classes (which add border planes to the quadrics).
    pub fn prepare(&mut self) {
        let (t0, c0) = (std::time::Instant::now(), super::cpu_seconds());
        self.quadrics();
        let (t1, c1) = (std::time::Instant::now(), super::cpu_seconds());
        self.classify();
        tracing::debug!(
            quadrics_ms = (t1 - t0).as_secs_f64() * 1e3,
            classify_ms = t1.elapsed().as_secs_f64() * 1e3,
            quadrics_cpu_ms = (c1 - c0) * 1e3,
            classify_cpu_ms = (super::cpu_seconds() - c1) * 1e3,
            classify_steps = self.classify_steps,
            "decimate set-up"
        );
    }

    /// Each wedge's quadric is the sum of the face quadrics of its triangles (§3.2
    /// "Initial quadrics"); each vertex keeps the position part of its wedges' sum, reduced.
    /// One pass in parallel over vertices: each face quadric is built once per corner, its
    /// position part summed into the vertex and its attribute part into the corner's wedge
    /// (a wedge belongs to one vertex, so each wedge is summed by one task), each sum in
    /// ascending corner order, so the result is the same whatever the thread count.
    fn quadrics(&mut self) {
        let nw = self.wvert.len();
        let mut wq = WedgeQuadrics::<M>::new(nw, self.has_normals);
        let out = wq.raw_writer();
        let this = &*self;
        let vred: Vec<Reduced> = (0..this.pos.len())
            .into_par_iter()
            .map_init(
                || (KeyIndex::default(), Vec::<AttrPart<M>>::new()),
                |(wedges, sums), v| {
                    let out = &out;
                    wedges.clear();
                    sums.clear();
                    let mut red = Reduced::default();
                    let mut c = this.vfirst[v];
                    while c != NIL {
                        let (t, k) = (c as usize / 3, c as usize % 3);
                        let (i, new) = wedges.insert(this.tris[t][k]);
                        if new {
                            sums.push(AttrPart::default());
                        }
                        if let Some(q) = this.face_quadric(t) {
                            let (geo, attr) = q.split();
                            red.add(&geo);
                            sums[i].add(&attr);
                        }
                        c = this.cnext[c as usize];
                    }
                    for (&w, a) in wedges.keys().iter().zip(sums.iter()) {
                        red.schur(a, &this.w, -1.0);
                        // SAFETY: `wq` outlives this loop and nothing else touches it
                        // meanwhile. Wedge `w` is reached only through the corners of its own
                        // vertex `v` (the corner lists are built from `wvert`), and each
                        // vertex is one task, so no two tasks write the same wedge.
                        unsafe { out.set(w as usize, a) };
                    }
                    red
                },
            )
            .collect();
        self.wq = wq;
        self.vred = vred;
    }

    fn face_quadric(&self, t: usize) -> Option<Quadric<M>> {
        let tri = self.tris[t];
        let p = tri.map(|w| self.pos[self.wvert[w as usize] as usize]);
        let s = tri.map(|w| self.wattr.get(w as usize));
        Quadric::from_triangle(p, s, &self.w)
    }

    #[inline]
    pub fn vertex_of(&self, c: u32) -> u32 {
        self.wvert[self.tris[c as usize / 3][c as usize % 3] as usize]
    }

    /// Vertex classes (see [`VClass`]) from each vertex's star, in parallel; adds the
    /// border planes of `boundary = "weighted"` to the border wedges.
    ///
    /// Each task writes its own vertex's class, border flag and reduced quadric in place:
    /// no per-vertex record (nor a box of planes per seam vertex) is collected first, since
    /// this runs at the decimation's memory peak (the halves' set-up). A vertex's planes are
    /// added in the order met, as a sequential pass would, so the sums are the same whatever
    /// the thread count.
    fn classify(&mut self) {
        let mut class = std::mem::take(&mut self.class);
        let mut border = std::mem::take(&mut self.border);
        let mut vred = std::mem::take(&mut self.vred);
        let this = &*self;
        let steps: u64 = class
            .par_iter_mut()
            .zip(border.par_iter_mut())
            .zip(vred.par_iter_mut())
            .enumerate()
            .map_init(
                ClassifyScratch::default,
                |sc, (v, ((class, border), red))| {
                    let info = this.classify_vertex(v, sc);
                    *class = match (info.class, this.cfg.boundary) {
                        (VClass::Border, Border::Fixed) => VClass::Fixed,
                        (c, _) => c,
                    };
                    *border = info.border;
                    for &(n, point, weight) in &sc.planes {
                        red.add_plane(&Quadric::<M>::plane(n, point, weight));
                    }
                    info.steps
                },
            )
            .sum();
        self.classify_steps += steps;
        for &c in &class {
            match c {
                VClass::Interior => self.classes.interior += 1,
                VClass::Border => self.classes.border += 1,
                VClass::Seam => self.classes.seam += 1,
                VClass::Fixed => self.classes.fixed += 1,
            }
        }
        (self.class, self.border, self.vred) = (class, border, vred);
    }

    /// One vertex's class from its link's shape, its wedges and the seam and border edges
    /// around it, with the constraint planes of those edges.
    fn classify_vertex(&self, v: usize, sc: &mut ClassifyScratch) -> VertexInfo {
        sc.corners.clear();
        sc.planes.clear();
        let mut c = self.vfirst[v];
        while c != NIL {
            sc.corners.push(c);
            c = self.cnext[c as usize];
        }
        if sc.corners.is_empty() {
            return VertexInfo {
                class: VClass::Fixed,
                border: false,
                steps: 1,
            };
        }
        let nwedges = self.link_and_wedges(sc);
        let shape = link_shape(&sc.link, &mut sc.lsc);
        let mut steps = sc.corners.len() as u64 + self.index_touching(sc);
        let planes = std::mem::take(&mut sc.planes);
        let edges = self.star_edges(v, sc, &mut steps, planes);
        let class = match shape {
            None => VClass::Fixed,
            Some(_) if edges.seam > 0 && edges.border > 0 => VClass::Fixed,
            Some(LinkShape::Path) if edges.seam == 0 && nwedges == 1 => VClass::Border,
            Some(LinkShape::Cycle) if edges.seam == 0 && nwedges == 1 => VClass::Interior,
            Some(LinkShape::Cycle) if edges.seam == 2 && nwedges == 2 => VClass::Seam,
            _ => VClass::Fixed,
        };
        let border = edges.border > 0 || shape == Some(LinkShape::Path);
        sc.planes = edges.planes;
        VertexInfo {
            class,
            border,
            steps,
        }
    }

    /// Fills the link (the edge opposite each corner) and counts the vertex's distinct
    /// wedges (counting on past four, which is enough to tell one and two from more).
    #[inline]
    fn link_and_wedges(&self, sc: &mut ClassifyScratch) -> usize {
        sc.link.clear();
        let mut wedges: [u32; 4] = [NIL; 4];
        let mut nwedges = 0;
        for &c in sc.corners.iter() {
            let (t, k) = (c as usize / 3, c as usize % 3);
            let tri = self.tris[t];
            sc.link.push((
                self.wvert[tri[(k + 1) % 3] as usize],
                self.wvert[tri[(k + 2) % 3] as usize],
            ));
            let w = tri[k];
            if !wedges[..nwedges.min(4)].contains(&w) {
                if nwedges < 4 {
                    wedges[nwedges] = w;
                }
                nwedges += 1;
            }
        }
        nwedges
    }

    /// Which corners' triangles touch each vertex: (vertex, corner's place in `corners`),
    /// in corner order. Around a vertex of high valence they are sorted, so that the
    /// triangles on an edge (v, x) are one run found by a binary search (O(k log k) for
    /// valence k, not O(k²)); around the usual few corners a scan finds them sooner than a
    /// sort would. Returns the sort's steps.
    #[inline]
    fn index_touching(&self, sc: &mut ClassifyScratch) -> u64 {
        sc.touching.clear();
        for (i, &c) in sc.corners.iter().enumerate() {
            let tv = self.tris[c as usize / 3].map(|w| self.wvert[w as usize]);
            for (k, &y) in tv.iter().enumerate() {
                if !tv[..k].contains(&y) {
                    sc.touching.push((y, i as u32));
                }
            }
        }
        sc.sorted = sc.touching.len() > SCAN_TOUCHING;
        if sc.sorted {
            sc.touching.sort_unstable();
            (sc.touching.len() * bits(sc.touching.len())) as u64
        } else {
            0
        }
    }

    /// Every edge (v, x) of v's star, once: border and seam edges counted, with their
    /// constraint planes where the configuration weights them (appended to `planes`, a
    /// reused buffer).
    #[inline]
    fn star_edges(
        &self,
        v: usize,
        sc: &ClassifyScratch,
        steps: &mut u64,
        planes: Vec<Plane>,
    ) -> StarEdges {
        let mut edges = StarEdges {
            planes,
            ..StarEdges::default()
        };
        let touching = &sc.touching[..];
        for (i, &ci) in sc.corners.iter().enumerate() {
            let (ti, ki) = (ci as usize / 3, ci as usize % 3);
            for side in [1, 2] {
                let x_w = self.tris[ti][(ki + side) % 3];
                let x = self.wvert[x_w as usize];
                // The corners whose triangles have x, in order; corner i's is one.
                let (lo, hi) = if sc.sorted {
                    *steps += 2 * bits(touching.len()) as u64;
                    (
                        touching.partition_point(|e| e.0 < x),
                        touching.partition_point(|e| e.0 <= x),
                    )
                } else {
                    *steps += touching.len() as u64;
                    (0, touching.len())
                };
                let mut run = touching[lo..hi].iter().filter(|e| e.0 == x);
                // Count each edge once: from the first corner that has it.
                if run.next().is_some_and(|e| e.1 < i as u32) {
                    continue;
                }
                *steps += 2;
                let mut others = run.map(|e| sc.corners[e.1 as usize]);
                match (others.next(), others.next()) {
                    (None, _) => self.border_edge(v, x, ti, &mut edges),
                    (Some(cj), None) => self.inner_edge(v, x_w, ci, cj, &mut edges),
                    _ => {} // non-manifold edge: the link test fails
                }
            }
        }
        edges
    }

    /// A border edge (v, x) of triangle `t`.
    #[inline]
    fn border_edge(&self, v: usize, x: u32, t: usize, edges: &mut StarEdges) {
        edges.border += 1;
        if self.cfg.boundary == Border::Weighted {
            let w = self.cfg.boundary_weight;
            edges.planes.extend(self.edge_plane(v, x, t, w));
        }
    }

    /// An edge (v, x) between the triangles of corners `ci` and `cj` (at v), where `x_w` is
    /// x's wedge in `ci`'s triangle: a seam edge when the wedges at either end or the
    /// materials differ.
    #[inline]
    fn inner_edge(&self, v: usize, x_w: u32, ci: u32, cj: u32, edges: &mut StarEdges) {
        let x = self.wvert[x_w as usize];
        let (ti, ki) = (ci as usize / 3, ci as usize % 3);
        let (tj, kj) = (cj as usize / 3, cj as usize % 3);
        let (tri_i, tri_j) = (self.tris[ti], self.tris[tj]);
        let xw_j = *tri_j
            .iter()
            .find(|&&w| self.wvert[w as usize] == x)
            .unwrap_or(&NIL);
        if tri_j[kj] != tri_i[ki] || xw_j != x_w || self.material(ti) != self.material(tj) {
            edges.seam += 1;
            if self.cfg.seam_weight > 0.0 {
                // One plane per side, each with half the weight.
                let w = 0.5 * self.cfg.seam_weight;
                for t in [ti, tj] {
                    edges.planes.extend(self.edge_plane(v, x, t, w));
                }
            }
        }
    }

    /// The constraint plane (Garland–Heckbert) through edge (v, x), perpendicular to
    /// triangle `t`, of weight `weight` × |e|² as (unit normal, point, weight); `None` when
    /// the edge or the triangle is degenerate.
    fn edge_plane(&self, v: usize, x: u32, t: usize, weight: f64) -> Option<Plane> {
        let pv = self.pos[v];
        let e = sub(self.pos[x as usize], pv);
        let pn = cross(e, self.unit_normal(t));
        let l = dot(pn, pn).sqrt();
        (l > 0.0).then(|| (pn.map(|c| c / l), pv, weight * dot(e, e)))
    }

    fn unit_normal(&self, t: usize) -> [f64; 3] {
        let tri = self.tris[t];
        let p = tri.map(|w| self.pos[self.wvert[w as usize] as usize]);
        let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        let l = dot(n, n).sqrt();
        if l > 0.0 { n.map(|c| c / l) } else { n }
    }

    /// The class a vertex has for placement: in `free` mode border vertices move like
    /// interior ones.
    #[inline]
    fn placement_class(&self, v: u32) -> VClass {
        match (self.class[v as usize], self.cfg.boundary) {
            (VClass::Border, Border::LikeInterior) => VClass::Interior,
            (c, _) => c,
        }
    }

    /// The placement rules from the vertex classes (seam and border rules). A seam
    /// (border) vertex only moves along its seam (border): onto a neighbour across a seam
    /// (border) edge, so that output seams run through input seam vertices only (as
    /// meshoptimizer's seam collapses); a fixed vertex may absorb such a
    /// neighbour the same way, and interior vertices merge into whichever of these they
    /// meet. Returns up to two candidate anchors (indices into S; none = free placement).
    /// `along(i, j)` says whether `S[i]`–`S[j]` is a seam (border) edge; `None` skips that
    /// test (the cheap heap key).
    fn rules(
        &self,
        s: &[u32],
        along: Option<&dyn Fn(usize, usize, bool) -> bool>,
    ) -> Result<[usize; 2], Refusal> {
        let ns = s.len();
        if s.iter()
            .all(|&v| self.placement_class(v) == VClass::Interior)
        {
            return Ok([usize::MAX; 2]);
        }
        let classes = [0, 1, 2].map(|i| {
            if i < ns {
                self.placement_class(s[i])
            } else {
                VClass::Interior
            }
        });
        let count = |c: VClass| classes[..ns].iter().filter(|&&x| x == c).count();
        let (fixed, seam, border) = (
            count(VClass::Fixed),
            count(VClass::Seam),
            count(VClass::Border),
        );
        let feature = |c: VClass| c == VClass::Seam || c == VClass::Border;
        let first = |f: &dyn Fn(VClass) -> bool| classes[..ns].iter().position(|&c| f(c));
        let on = |i: usize, j: usize| along.is_none_or(|f| f(i, j, seam > 0));
        let cause = if seam > 0 {
            Refusal::Seam
        } else {
            Refusal::Boundary
        };
        let mut anchors: [usize; 2] = [usize::MAX; 2];
        if fixed >= 2 {
            return Err(Refusal::Locked);
        } else if seam > 0 && border > 0 {
            return Err(Refusal::Seam);
        } else if fixed == 1 {
            let f = first(&|c| c == VClass::Fixed).unwrap_or(0);
            match seam + border {
                0 => anchors[0] = f,
                1 => {
                    let i = first(&feature).unwrap_or(0);
                    if !on(f, i) {
                        return Err(cause);
                    }
                    anchors[0] = f;
                }
                _ => return Err(Refusal::Locked),
            }
        } else {
            match seam + border {
                0 => {}
                1 => anchors[0] = first(&feature).unwrap_or(0),
                2 => {
                    let i = first(&feature).unwrap_or(0);
                    let j = (i + 1..ns).find(|&j| feature(classes[j])).unwrap_or(i);
                    if !on(i, j) {
                        return Err(cause);
                    }
                    anchors = [i, j];
                }
                _ => return Err(cause),
            }
        }
        Ok(anchors)
    }

    /// Places the merged vertex for a reduced system: free (minimiser, with the
    /// ill-conditioned fallback) or at the cheaper of the anchors.
    fn place(
        &self,
        s: &[u32],
        anchors: [usize; 2],
        red: &Reduced,
        dense: Option<&mut Vec<Quadric<M>>>,
    ) -> ([f64; 3], Placement, bool) {
        if anchors[0] != usize::MAX {
            let i = anchors[0];
            let pi = self.pos[s[i] as usize];
            if anchors[1] != usize::MAX {
                let j = anchors[1];
                let pj = self.pos[s[j] as usize];
                if red.eval(pj) < red.eval(pi) {
                    return (pj, Placement::Anchor(j), false);
                }
            }
            return (pi, Placement::Anchor(i), false);
        }
        // The mean of the merged vertices: only the ill-conditioned fallback needs it, so it
        // is computed only then (most placements in the collapse loop never do).
        let mean = || {
            let mut mean = [0.0; 3];
            for &v in s {
                let pv = self.pos[v as usize];
                for k in 0..3 {
                    mean[k] += pv[k] / s.len() as f64;
                }
            }
            mean
        };
        let regularise = self.cfg.fallback == Fallback::Regularised;
        match (self.cfg.conditioning, dense) {
            (Conditioning::ThesisLiteral, Some(dense)) => {
                let cond = dense_condition_number(dense, &self.w);
                if cond > self.cfg.max_condition {
                    (mean(), Placement::Free, true)
                } else {
                    let (p, fb) = red.minimise_with(mean, f64::INFINITY, regularise);
                    (p, Placement::Free, fb)
                }
            }
            _ => {
                let (p, fb) = red.minimise_with(mean, self.cfg.max_condition, regularise);
                (p, Placement::Free, fb)
            }
        }
    }

    /// Asks the memory for the records of triangle `t`'s vertices that evaluating its sides
    /// reads first (reduced quadric, first corner, position, star size, class), without
    /// waiting for them. The collapse loop calls it for the heap's next triangle before it
    /// collapses the current one: the heap jumps across the mesh from one cheapest merge to
    /// the next, so those records are rarely in cache, and the collapse in between hides
    /// their latency. No effect on what is computed.
    #[inline]
    pub fn prefetch_triangle(&self, t: usize) {
        for v in self.tv[t] {
            let v = v as usize;
            prefetch(&self.vred, v);
            prefetch(&self.vfirst, v);
            prefetch(&self.pos, v);
            prefetch(&self.star, v);
            prefetch(&self.class, v);
        }
    }

    /// Asks the memory for what the rest of a collapse reads of a surviving corner's
    /// triangle `t` and of its next vertex `x` (met as the star is gathered): the guards read
    /// `x`'s position, `t`'s input normal and its wedges' texture coordinates, and re-keying
    /// the fan costs the side to `x` from its reduced quadric, class and star size. Every
    /// vertex of a closed ring is the next vertex of one surviving corner.
    #[inline]
    fn prefetch_ring_corner(&self, t: usize, x: usize, wx: usize) {
        prefetch(&self.pos, x);
        prefetch(&self.onormal, t);
        prefetch(&self.vred, x);
        prefetch(&self.star, x);
        prefetch(&self.class, x);
        if self.has_uv {
            self.wattr.prefetch(wx);
        }
    }

    /// The heap key of merging S without gathering its star: the vertices' reduced systems
    /// summed (wedge merging ignored, which only changes the attribute terms) and placed by
    /// the class rules. [`Work::evaluate`] computes the exact plan when the key comes up.
    pub fn quick_cost(&self, s: &[u32]) -> Result<f64, Refusal> {
        let anchors = self.rules(s, None)?;
        self.star_fits(s)?;
        let mut red = Reduced::default();
        for &v in s {
            red.add(&self.vred[v as usize]);
        }
        let (p, _, _) = self.place(s, anchors, &red, None);
        let cost = red.eval(p);
        // A NaN (only from degenerate geometry; none occurs on the scans in ../shared/data)
        // would become the heap's cheapest key (`key` clamps with `max`, which drops NaN):
        // refuse it instead.
        if cost.is_nan() {
            return Err(Refusal::Degenerate);
        }
        Ok(cost)
    }

    /// Refuses a merge whose vertices have more than [`MAX_STAR`] corners together.
    fn star_fits(&self, s: &[u32]) -> Result<(), Refusal> {
        let corners: u64 = s.iter().map(|&v| u64::from(self.star[v as usize])).sum();
        if corners > u64::from(MAX_STAR) {
            return Err(Refusal::Valence);
        }
        Ok(())
    }

    /// Gathers the star of S, groups the wedges and places the merged vertex.
    pub fn evaluate(&self, s: &[u32], sc: &mut Scratch<M>) -> Result<Plan, Refusal> {
        sc.reset(s);
        self.star_fits(s)?;
        self.gather_star(s, sc);
        if sc.dead.is_empty() {
            return Err(Refusal::Link);
        }
        self.unite_dead_wedges(s, sc);
        let mut red = Reduced::default();
        for &v in s {
            red.add(&self.vred[v as usize]);
        }
        self.group_wedges(sc, &mut red)?;
        let along = |i: usize, j: usize, seam: bool| {
            if seam {
                self.is_seam_edge(s[i], s[j], &sc.dead)
            } else {
                self.is_border_edge(s[i], s[j], &sc.dead)
            }
        };
        let anchors = self.rules(s, Some(&along))?;
        let dense = if self.cfg.conditioning == Conditioning::ThesisLiteral {
            Some(dense_system(sc, &red))
        } else {
            None
        };
        let (p, placement, fallback) = self.place(s, anchors, &red, dense);
        if !p.iter().all(|c| c.is_finite()) {
            return Err(Refusal::Degenerate);
        }
        let (cost, error) = self.merged_attributes(sc, p, placement, &red);
        Ok(Plan {
            p,
            placement,
            cost,
            error,
            fallback,
            red,
        })
    }

    /// Fills the (reset) scratch with S's star: the corners of the triangles that survive (one
    /// corner in S), the triangles that die (two or more, each listed once) and the wedges
    /// at S in the order met, each with the place in S of its vertex.
    #[inline]
    fn gather_star(&self, s: &[u32], sc: &mut Scratch<M>) {
        let ns = s.len();
        for (si, &v) in s.iter().enumerate() {
            let mut c = self.vfirst[v as usize];
            while c != NIL {
                let (t, k) = (c as usize / 3, c as usize % 3);
                let vs = self.tv[t];
                if vs[0] != NIL {
                    let mut count = 0;
                    let mut first = 3;
                    for (kk, &x) in vs.iter().enumerate() {
                        if x == s[0] || (ns > 1 && x == s[1]) || (ns > 2 && x == s[2]) {
                            count += 1;
                            first = first.min(kk);
                        }
                    }
                    if count >= 2 {
                        if first == k {
                            sc.dead.push(t as u32);
                        }
                    } else {
                        sc.corners.push(c);
                        let next = (k + 1) % 3;
                        self.prefetch_ring_corner(
                            t,
                            vs[next] as usize,
                            self.tris[t][next] as usize,
                        );
                    }
                    let w = self.tris[t][k];
                    if sc.lw.insert(w).1 {
                        // Its quadric is read when the wedges are grouped, next.
                        self.wq.prefetch(w as usize);
                        sc.lw_si.push(si as u8);
                    }
                }
                c = self.cnext[c as usize];
            }
        }
    }

    /// Wedge merging (§3.2, Fig. 3.3): the wedges at S of each deleted triangle unite
    /// (union-find over the scratch's wedges, the smaller place as the root).
    #[inline]
    fn unite_dead_wedges(&self, s: &[u32], sc: &mut Scratch<M>) {
        sc.lw_parent.clear();
        sc.lw_parent.extend(0..sc.lw.len() as u32);
        for d in 0..sc.dead.len() {
            let t = sc.dead[d] as usize;
            let (tri, vs) = (self.tris[t], self.tv[t]);
            let mut root = usize::MAX;
            for k in 0..3 {
                if !s.contains(&vs[k]) {
                    continue;
                }
                let l = sc.local(tri[k]);
                let r = sc.find(l);
                if root == usize::MAX {
                    root = r;
                } else if r != root {
                    let (a, b) = (root.min(r), root.max(r));
                    sc.lw_parent[b] = a as u32;
                    root = a;
                }
            }
        }
    }

    /// One [`Group`] for each set of united wedges, with their summed attribute quadrics;
    /// in `red`, the Schur terms of merged wedges give way to their merged block's.
    /// Refuses a merge that would unite two wedges of one vertex (a seam would close).
    #[inline]
    fn group_wedges(&self, sc: &mut Scratch<M>, red: &mut Reduced) -> Result<(), Refusal> {
        sc.lw_group.clear();
        sc.lw_group.resize(sc.lw.len(), NIL);
        for l in 0..sc.lw.len() {
            let r = sc.find(l);
            if sc.lw_group[r] == NIL {
                sc.lw_group[r] = sc.groups.len() as u32;
                sc.groups.push(Group {
                    rep: sc.lw.keys()[r],
                    size: 0,
                    q: AttrPart::default(),
                    at: [NIL; 3],
                    attr: [0.0; M],
                });
            }
            let g = sc.lw_group[r];
            sc.lw_group[l] = g;
            let w = sc.lw.keys()[l];
            let si = sc.lw_si[l] as usize;
            let group = &mut sc.groups[g as usize];
            if group.at[si] != NIL {
                return Err(Refusal::Seam);
            }
            group.at[si] = w;
            group.rep = group.rep.min(w);
            group.size += 1;
            group.q.add(&self.wq.get(w as usize));
        }
        if sc.groups.len() < sc.lw.len() {
            for l in 0..sc.lw.len() {
                if sc.groups[sc.lw_group[l] as usize].size > 1 {
                    red.schur(&self.wq.get(sc.lw.keys()[l] as usize), &self.w, 1.0);
                }
            }
            for g in &sc.groups {
                if g.size > 1 {
                    red.schur(&g.q, &self.w, -1.0);
                }
            }
        }
        Ok(())
    }

    /// Each merged wedge's attributes at `p` (an anchor's wedge keeps its own); returns
    /// the merge's cost (quadric value, with the anchored wedges' excess) and error (RMS
    /// distance: the cost over the area, square-rooted).
    #[inline]
    fn merged_attributes(
        &self,
        sc: &mut Scratch<M>,
        p: [f64; 3],
        placement: Placement,
        red: &Reduced,
    ) -> (f64, f64) {
        let mut cost = red.eval(p);
        let mut area = 0.0;
        for g in sc.groups.iter_mut() {
            let anchored = match placement {
                Placement::Anchor(i) if g.at[i] != NIL => Some(g.at[i]),
                _ => None,
            };
            g.attr = match anchored {
                // The anchor's wedge keeps its identity and its attributes.
                Some(w) => {
                    g.rep = w;
                    self.wattr.get(w as usize)
                }
                None => {
                    g.q.attributes_at(p)
                        .unwrap_or_else(|| self.wattr.get(g.rep as usize))
                }
            };
            if anchored.is_some() {
                cost += g.q.excess(p, &g.attr, &self.w);
            }
            area += g.q.alpha;
        }
        let cost = cost.max(0.0);
        let error = if area > 0.0 {
            (cost / area).sqrt()
        } else {
            0.0
        };
        (cost, error)
    }

    /// Is the edge between `a` and `b` (both in S) a seam edge? Its triangles are among the
    /// deleted ones.
    fn is_seam_edge(&self, a: u32, b: u32, dead: &[u32]) -> bool {
        let mut found: [usize; 2] = [usize::MAX; 2];
        let mut n = 0;
        for &t in dead {
            let vs = self.tv[t as usize];
            if vs.contains(&a) && vs.contains(&b) {
                if n < 2 {
                    found[n] = t as usize;
                }
                n += 1;
            }
        }
        if n != 2 {
            return false;
        }
        let wedge_at = |t: usize, v: u32| {
            let k = self.tv[t].iter().position(|&x| x == v).unwrap_or(0);
            self.tris[t][k]
        };
        let (t0, t1) = (found[0], found[1]);
        wedge_at(t0, a) != wedge_at(t1, a)
            || wedge_at(t0, b) != wedge_at(t1, b)
            || self.material(t0) != self.material(t1)
    }

    fn is_border_edge(&self, a: u32, b: u32, dead: &[u32]) -> bool {
        dead.iter()
            .filter(|&&t| {
                let vs = self.tv[t as usize];
                vs.contains(&a) && vs.contains(&b)
            })
            .count()
            == 1
    }

    /// The guards on the triangles that survive the merge (after [`Work::evaluate`] filled
    /// the scratch): degeneracy, normal flip (against the triangle before the merge and
    /// against its input triangle), texture flip, and the link condition.
    pub fn check(&self, plan: &Plan, sc: &mut Scratch<M>) -> Result<(), Refusal> {
        if !self.cfg.guards {
            return Ok(());
        }
        let p = plan.p;
        sc.link.clear();
        for i in 0..sc.corners.len() {
            let c = sc.corners[i] as usize;
            let (t, k) = (c / 3, c % 3);
            let tri = self.tris[t];
            let vs = self.tv[t];
            let (wx, wy) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
            let (vx, vy) = (vs[(k + 1) % 3], vs[(k + 2) % 3]);
            sc.link.push((vx, vy));
            let x = self.pos[vx as usize];
            let y = self.pos[vy as usize];
            let old = self.pos[vs[k] as usize];
            let q_new = quality(p, x, y);
            if q_new < DEGENERATE_QUALITY || (q_new < SLIVER_QUALITY && q_new < quality(old, x, y))
            {
                return Err(Refusal::Degenerate);
            }
            let n0 = cross(sub(x, old), sub(y, old));
            let n1 = cross(sub(x, p), sub(y, p));
            let (l0, l1) = (dot(n0, n0).sqrt(), dot(n1, n1).sqrt());
            if dot(n0, n1) < self.cfg.cos_max_normal_change * l0 * l1 {
                return Err(Refusal::Flip);
            }
            let origin = oct_decode(self.onormal[t]);
            if dot(origin, n1) <= 0.0 {
                return Err(Refusal::Flip);
            }
            if self.has_uv {
                let a_old = self.wattr.uv(tri[k] as usize);
                let g = sc.group_of(tri[k]);
                let a_new = g.attr;
                let ux = self.wattr.uv(wx as usize);
                let uy = self.wattr.uv(wy as usize);
                let before = uv_area([a_old[0], a_old[1]], [ux[0], ux[1]], [uy[0], uy[1]]);
                let after = uv_area([a_new[0], a_new[1]], [ux[0], ux[1]], [uy[0], uy[1]]);
                if before != 0.0 && (after * before <= 0.0 || after.abs() < 1e-14) {
                    return Err(Refusal::TextureFlip);
                }
            }
        }
        let expect = if sc.s[..sc.ns].iter().any(|&v| self.border[v as usize]) {
            LinkShape::Path
        } else {
            LinkShape::Cycle
        };
        match link_shape(&sc.link, &mut sc.link_sc) {
            Some(shape) if shape == expect => Ok(()),
            _ => Err(Refusal::Link),
        }
    }

    /// Performs the merge evaluated into `sc`. Returns the surviving vertex.
    pub fn apply(&mut self, plan: &Plan, sc: &Scratch<M>) -> u32 {
        let ns = sc.ns;
        let s = &sc.s[..ns];
        let n = match plan.placement {
            Placement::Anchor(i) => s[i],
            _ => s[0],
        };
        if !matches!(plan.placement, Placement::Anchor(_)) {
            self.pos[n as usize] = plan.p;
            self.moved[n as usize] = true;
        }
        let class = s
            .iter()
            .map(|&v| self.class[v as usize])
            .max()
            .unwrap_or(VClass::Fixed);
        let border = s.iter().any(|&v| self.border[v as usize]);
        for &v in s {
            if v != n {
                self.vfirst[v as usize] = NIL;
            }
        }
        self.class[n as usize] = class;
        self.border[n as usize] = border;
        self.vred[n as usize] = plan.red;
        for g in &sc.groups {
            let r = g.rep as usize;
            self.wq.set(r, &g.q);
            self.wvert[r] = n;
            if self.wattr.get(r) != g.attr {
                self.wattr.set(r, &g.attr);
                self.wchanged[r] = true;
            }
        }
        for &t in &sc.dead {
            self.tv[t as usize] = [NIL; 3];
        }
        self.live -= sc.dead.len();
        for &c in &sc.corners {
            let (t, k) = (c as usize / 3, c as usize % 3);
            let w = self.tris[t][k];
            self.tris[t][k] = sc.group_of(w).rep;
            self.tv[t][k] = n;
        }
        // Relink n's corner list: exactly the surviving corners.
        let mut next = NIL;
        for &c in sc.corners.iter().rev() {
            self.cnext[c as usize] = next;
            next = c;
        }
        self.vfirst[n as usize] = next;
        for &v in s {
            self.star[v as usize] = 0;
        }
        self.star[n as usize] = sc.corners.len() as u32;
        n
    }

    /// The thesis' cost estimate for a face (§3.2 "Cost estimate"; the formula as we read
    /// it): weighted mean squared deviation of the corner values from their mean.
    pub fn estimate(&self, t: usize) -> f64 {
        let tri = self.tris[t];
        let p = self.tv[t].map(|v| self.pos[v as usize]);
        let a = tri.map(|w| self.wattr.get(w as usize));
        let mut e = 0.0;
        for k in 0..3 {
            let mean = (p[0][k] + p[1][k] + p[2][k]) / 3.0;
            e += self.w.geom * p.iter().map(|q| (q[k] - mean).powi(2)).sum::<f64>();
        }
        for j in 0..M {
            let mean = (a[0][j] + a[1][j] + a[2][j]) / 3.0;
            e += self.w.attr[j] * a.iter().map(|q| (q[j] - mean).powi(2)).sum::<f64>();
        }
        e / 3.0
    }

    /// Material of triangle `t` (see [`Work::tmat`]).
    #[inline]
    fn material(&self, t: usize) -> Index {
        self.tmat.get(t).copied().unwrap_or(0)
    }

    /// Frees what only the collapse loop needs (the quadrics, the corner lists, the origin
    /// normals), so that the output is built in the memory they held (peak memory, issue
    /// #5). [`Work::into_mesh`] does it first; a caller that must bring back parts of the
    /// input before the output is built does it before that.
    pub fn release_loop_state(&mut self) {
        self.wq = WedgeQuadrics::default();
        self.vred = Vec::new();
        self.cnext = Vec::new();
        self.vfirst = Vec::new();
        self.star = Vec::new();
        self.onormal = Vec::new();
    }

    /// The output mesh: surviving triangles in their input order with their origins and
    /// materials; moved vertices mapped back from the unit box, unmoved ones bit-exact;
    /// changed attributes appended as new texture coordinates / normals (reading R10), normals
    /// renormalised (reading R9). `input` is the mesh the working mesh was built from; its
    /// triangles are not read (the working mesh has its own).
    pub fn into_mesh(mut self, input: &Mesh) -> Mesh {
        self.release_loop_state();
        let scale = 1.0 / self.inv_scale;
        let positions: Vec<DVec3> = (0..self.pos.len())
            .map(|v| {
                if self.moved[v] {
                    DVec3::from_array(self.pos[v]) * scale + self.center
                } else {
                    input.positions[v]
                }
            })
            .collect();
        let mut texcoords = input.texcoords.clone();
        let mut normals = input.normals.clone();
        let wedges: Vec<Wedge> = input
            .wedges
            .iter()
            .enumerate()
            .map(|(w, orig)| {
                let mut wedge = Wedge {
                    vertex: self.wvert[w],
                    ..*orig
                };
                if self.wchanged[w] {
                    let a = self.wattr.get(w);
                    let mut k = 0;
                    if self.has_uv {
                        if orig.texcoord.is_some() {
                            texcoords.push(DVec2::new(a[0], a[1]));
                            wedge.texcoord = Some((texcoords.len() - 1) as Index);
                        }
                        k = 2;
                    }
                    if self.has_normals && orig.normal.is_some() {
                        let n = DVec3::new(a[k], a[k + 1], a[k + 2]);
                        let n = n
                            .try_normalize()
                            .unwrap_or(input.normals[orig.normal.unwrap_or(0) as usize]);
                        normals.push(n);
                        wedge.normal = Some((normals.len() - 1) as Index);
                    }
                }
                wedge
            })
            .collect();
        let keep: Vec<usize> = (0..self.tris.len())
            .filter(|&t| self.tv[t][0] != NIL)
            .collect();
        let mut mesh = Mesh {
            positions,
            texcoords,
            normals,
            colors: input.colors.clone(),
            wedges,
            triangles: keep.iter().map(|&t| self.tris[t]).collect(),
            triangle_materials: if input.triangle_materials.is_empty() {
                Vec::new()
            } else {
                keep.iter().map(|&t| input.triangle_materials[t]).collect()
            },
            materials: input.materials.clone(),
            triangle_origins: keep.iter().map(|&t| input.triangle_origin(t)).collect(),
        };
        mesh.compact();
        mesh
    }
}

/// The merged vertex's dense system for `conditioning = "thesis-literal"`: one quadric per
/// wedge group, the position block kept in the first only (it appears once).
fn dense_system<'s, const M: usize>(
    sc: &'s mut Scratch<M>,
    red: &Reduced,
) -> &'s mut Vec<Quadric<M>> {
    sc.dense.clear();
    for g in &sc.groups {
        let mut q = Quadric::<M>::default();
        q.attr = g.q;
        q.pos.m = red.m;
        q.pos.r = red.r;
        sc.dense.push(q);
    }
    for q in sc.dense.iter_mut().skip(1) {
        q.pos = Reduced::default();
    }
    &mut sc.dense
}

/// The input's positions moved and scaled into the unit box (largest side 1, centred on
/// the origin), with the centre and the inverse scale that undo it.
fn normalised_positions(input: &Mesh) -> (DVec3, f64, Vec<[f64; 3]>) {
    let (lo, hi) = input.bounding_box().unwrap_or((DVec3::ZERO, DVec3::ONE));
    let center = (lo + hi) * 0.5;
    let extent = (hi - lo).max_element();
    let inv_scale = if extent > 0.0 { 1.0 / extent } else { 1.0 };
    let pos = input
        .positions
        .par_iter()
        .map(|&p| ((p - center) * inv_scale).to_array())
        .collect();
    (center, inv_scale, pos)
}

/// Each wedge's attribute vector: texture coordinates (when `has_uv`), then the normal
/// (when `has_normals`); zero where a wedge has none.
fn wedge_attributes<const M: usize>(
    input: &Mesh,
    has_uv: bool,
    has_normals: bool,
) -> WedgeAttrs<M> {
    let attributes = input.wedges.iter().map(|wd| {
        let mut a = [0.0; M];
        let mut k = 0;
        if has_uv {
            if let Some(t) = wd.texcoord {
                let uv = input.texcoords[t as usize];
                a[0] = uv.x;
                a[1] = uv.y;
            }
            k = 2;
        }
        if has_normals && let Some(n) = wd.normal {
            let n = input.normals[n as usize];
            a[k] = n.x;
            a[k + 1] = n.y;
            a[k + 2] = n.z;
        }
        a
    });
    WedgeAttrs::new(attributes, has_normals)
}

/// Each vertex's corner list, ascending (built by prepending in reverse): the first
/// corner of each vertex, the next corner of each corner, and each list's length.
fn corner_lists(tris: &[[u32; 3]], wvert: &[u32], nv: usize) -> (Vec<u32>, Vec<u32>, Vec<u32>) {
    let mut vfirst = vec![NIL; nv];
    let mut cnext = vec![NIL; tris.len() * 3];
    let mut star = vec![0u32; nv];
    for c in (0..tris.len() * 3).rev() {
        let v = wvert[tris[c / 3][c % 3] as usize] as usize;
        cnext[c] = vfirst[v];
        vfirst[v] = c as u32;
        star[v] += 1;
    }
    (vfirst, cnext, star)
}

/// The normal each triangle is held against by the flip guard, octahedron-encoded: its
/// own, or with `origin`, its origin triangle's there.
fn origin_normals(input: &Mesh, origin: Option<&Mesh>) -> Vec<u32> {
    (0..input.triangles.len())
        .into_par_iter()
        .map(|t| {
            let n = match origin {
                Some(o) => o.triangle_cross(input.triangle_origin(t) as usize),
                None => input.triangle_cross(t),
            };
            oct_encode(n.to_array())
        })
        .collect()
}
