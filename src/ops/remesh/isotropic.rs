//! Isotropic remeshing after Botsch & Kobbelt (2004), *A remeshing approach to
//! multiresolution modeling*, §4: per iteration, split edges longer than 4/3·L, collapse
//! edges shorter than 4/5·L when no edge of the result is longer than 4/3·L, flip edges
//! towards valence 6 (4 on a border), relax every vertex tangentially and project it back
//! onto the input. Lines (borders, seams, features) are split and collapsed only along
//! themselves, their vertices relax along them and are projected onto them.
//!
//! The topological passes are sequential in half-edge order; relaxation and projection
//! compute every vertex from the previous positions in parallel, so the result does not
//! depend on the thread count.

use super::PIECE;
use super::corners::{Corners, NIL, VKind, next, prev};
use super::fit::{self, FitReport};
use super::lines::Lines;
use super::ops::{self, Scratch};
use super::repair::{self, Repairs};
use super::sizing::Sizing;
use super::slivers::{self, Slivers};
use super::walk::{self, Sheet};
use crate::geom::bvh::TriangleBvh;
use crate::mesh::Mesh;
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::HashMap;

/// What the passes did, summed over the iterations.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Counts {
    pub splits: usize,
    pub collapses: usize,
    pub valence_flips: usize,
    pub angle_flips: usize,
    /// The least-squares fit of the free vertices to the input ([`fit`]; zeros with
    /// `on_surface`).
    pub fit: FitReport,
    /// Faces turned against the input, and their repair ([`repair`]).
    pub turned: Repairs,
    /// The last pass: slivers with three free corners ([`slivers`]).
    pub slivers: Slivers,
}

/// At most this many collapse sweeps per iteration: a dense input needs several to come
/// down to the target length, each sweep removes most of what it can.
const COLLAPSE_SWEEPS: usize = 8;

/// One canonical half-edge per live edge: `h` itself unless its opposite has a lower index.
#[inline]
fn canonical(c: &Corners, h: u32) -> bool {
    !c.face_dead[(h / 3) as usize] && {
        let g = c.opp[h as usize];
        g == NIL || h < g
    }
}

/// Splits every edge longer than its `sizing.hi` at its middle, in passes over the edges
/// until a pass splits none (at most [`SPLIT_PASSES`]), each edge at most once a pass, as
/// pmp-library does: all long edges halve together, so the triangles stay shaped like their
/// parents. Halving one edge again and again instead fans long slivers out of the vertex
/// opposite it. More than one pass is also needed because a split hands the side opposite
/// it to a new face: an edge whose two sides were both handed on during a pass is not met
/// again in it (on a coarse cube whole sides stayed unsplit for three iterations that way).
///
/// The first pass looks at every edge. A split moves no vertex and changes no size but the
/// new vertex's, and every edge it makes ends at the new vertex; so an edge that was not
/// too long when a pass began is still not too long after it unless it ends at a vertex
/// the pass made, and each later pass looks at those edges only (the same list, in the
/// same order, as looking at every edge).
pub fn split_long(c: &mut Corners, lines: &Lines, sizing: &mut Sizing) -> usize {
    let mut n = 0;
    let mut hs = Vec::new();
    let mut long: Vec<u32> = (0..c.vtx.len() as u32)
        .filter(|&h| canonical(c, h) && too_long(c, sizing, h))
        .collect();
    for _ in 0..SPLIT_PASSES {
        if long.is_empty() {
            break;
        }
        let first_new = c.pos.len() as u32;
        n += split_pass(c, lines, sizing, &long, &mut hs);
        long = long_edges_at(c, sizing, first_new..c.pos.len() as u32);
    }
    n
}

/// Split passes per iteration at most: enough to halve an edge 1,000-fold; what is left
/// waits for the next iteration.
const SPLIT_PASSES: usize = 10;

/// Splits each edge of `long` (canonical half-edges, in increasing order). The edges are
/// looked up again by their ends: a split renumbers the half-edges next to it.
fn split_pass(
    c: &mut Corners,
    lines: &Lines,
    sizing: &mut Sizing,
    long: &[u32],
    hs: &mut Vec<u32>,
) -> usize {
    let ends: Vec<(u32, u32)> = long
        .iter()
        .map(|&h| (c.vtx[h as usize], c.dest(h)))
        .collect();
    for &(a, b) in &ends {
        let Some(h) = c.half_edge(a, b, hs) else {
            continue;
        };
        let mid = 0.5 * (c.pos[a as usize] + c.pos[b as usize]);
        let seg = c.seg[h as usize];
        let seg = if c.is_constrained(h) && seg != NIL {
            lines.project(mid, seg).1
        } else {
            NIL
        };
        let m = ops::split(c, h, mid, seg);
        sizing.split(a, b, m);
    }
    ends.len()
}

/// The canonical half-edges of the edges at `vertices` that are too long, in increasing
/// order without repeats.
fn long_edges_at(c: &Corners, sizing: &Sizing, vertices: std::ops::Range<u32>) -> Vec<u32> {
    let mut long = Vec::new();
    for v in vertices {
        // Each face at v holds one edge leaving v and one coming in (a border's last
        // incoming edge too); an edge's canonical half-edge is one of its two.
        for k in c.fan_iter(v) {
            for h in [k, prev(k)] {
                let g = c.opp[h as usize];
                let h = if g != NIL && g < h { g } else { h };
                if canonical(c, h) && too_long(c, sizing, h) {
                    long.push(h);
                }
            }
        }
    }
    long.sort_unstable();
    long.dedup();
    long
}

/// The edge of `h` is longer than its `sizing.hi`, and neither end is locked.
fn too_long(c: &Corners, sizing: &Sizing, h: u32) -> bool {
    let (a, b) = (c.vtx[h as usize], c.dest(h));
    let length = c.pos[a as usize].distance(c.pos[b as usize]);
    length.partial_cmp(&sizing.hi(a, b)) == Some(std::cmp::Ordering::Greater)
        && !c.locked[a as usize]
        && !c.locked[b as usize]
}

/// The vertex that should go: the one with the freer kind, `a` on a tie.
fn order(c: &Corners, a: u32, b: u32) -> [(u32, u32); 2] {
    if c.kind[b as usize] < c.kind[a as usize] {
        [(b, a), (a, b)]
    } else {
        [(a, b), (b, a)]
    }
}

/// Collapses edges shorter than `sizing.lo` in half-edge order, in sweeps until one makes
/// none. A candidate's checks read only its two ends, the two vertices opposite it and
/// their rings, so after the first sweep an edge is tried again only when one of those four
/// was touched (a survivor of a collapse, or in its ring) since it last failed: the same
/// result as trying every edge, without re-trying the thousands that failed unchanged.
/// A sweep after the first reads only the faces next to a touched vertex ([`FaceMarks`]),
/// not every half-edge.
pub fn collapse_short(c: &mut Corners, sizing: &Sizing, sc: &mut Scratch) -> usize {
    let mut total = 0;
    let mut touched_before = vec![true; c.pos.len()];
    let mut touched = vec![false; c.pos.len()];
    let mut marks = FaceMarks::all(c);
    let (mut hs, mut ring) = (Vec::new(), Vec::new());
    for sweep in 0..COLLAPSE_SWEEPS {
        let mut n = 0;
        let mut from = 0;
        while let Some(f) = marks.first_from(from) {
            from = f + 1;
            for h in 3 * f as u32..3 * f as u32 + 3 {
                if !canonical(c, h) {
                    continue;
                }
                let (a, b) = (c.vtx[h as usize], c.dest(h));
                if c.pos[a as usize].distance(c.pos[b as usize]) >= sizing.lo(a, b) {
                    continue;
                }
                let g = c.opp[h as usize];
                let opposite =
                    [Some(h), (g != NIL).then_some(g)].map(|k| k.map(|k| c.vtx[prev(k) as usize]));
                let near = [Some(a), Some(b), opposite[0], opposite[1]];
                if !near
                    .iter()
                    .flatten()
                    .any(|&v| touched_before[v as usize] || touched[v as usize])
                {
                    continue;
                }
                for (x, y) in order(c, a, b) {
                    if ops::can_collapse(c, h, x, y, sizing, sc) {
                        ops::collapse(c, h, x, y, sc);
                        c.ring(y, &mut ring);
                        for &v in ring.iter().chain([&y]) {
                            touched[v as usize] = true;
                            // Candidates later in this sweep (the first reads every face).
                            if sweep > 0 {
                                marks.around(c, v, &mut hs);
                            }
                        }
                        n += 1;
                        break;
                    }
                }
            }
        }
        total += n;
        if n == 0 {
            break;
        }
        std::mem::swap(&mut touched_before, &mut touched);
        touched.fill(false);
        marks.clear();
        for v in 0..c.pos.len() as u32 {
            if touched_before[v as usize] && !c.vertex_dead[v as usize] {
                marks.around(c, v, &mut hs);
            }
        }
    }
    total
}

/// Faces marked in a bit set, read in increasing order while more are being marked.
struct FaceMarks {
    bits: Vec<u64>,
    faces: usize,
    /// The faces at each locked vertex, whose fan need not reach them all. A collapse
    /// never moves a locked vertex, so no face comes to it during the collapses.
    at_locked: HashMap<u32, Vec<u32>>,
}

impl FaceMarks {
    /// Every face marked.
    fn all(c: &Corners) -> FaceMarks {
        let mut at_locked: HashMap<u32, Vec<u32>> = HashMap::new();
        for (h, &v) in c.vtx.iter().enumerate() {
            if c.locked[v as usize] {
                at_locked.entry(v).or_default().push((h / 3) as u32);
            }
        }
        FaceMarks {
            bits: vec![u64::MAX; c.face_count().div_ceil(64)],
            faces: c.face_count(),
            at_locked,
        }
    }

    fn clear(&mut self) {
        self.bits.fill(0);
    }

    fn mark(&mut self, f: u32) {
        self.bits[(f / 64) as usize] |= 1 << (f % 64);
    }

    /// Marks every face holding a half-edge that has `v` among its ends or its opposite
    /// vertices: the faces around `v`, and the faces across their sides opposite `v`.
    fn around(&mut self, c: &Corners, v: u32, hs: &mut Vec<u32>) {
        match self.at_locked.get(&v) {
            Some(faces) => {
                hs.clear();
                let leaving = |f: &u32| (3 * f..3 * f + 3).filter(|&h| c.vtx[h as usize] == v);
                hs.extend(faces.iter().flat_map(leaving));
            }
            None => c.fan(v, hs),
        }
        for &k in hs.iter() {
            self.mark(k / 3);
            let across = c.opp[next(k) as usize];
            if across != NIL {
                self.mark(across / 3);
            }
        }
    }

    /// The first marked face at or after `f`.
    fn first_from(&self, f: usize) -> Option<usize> {
        let mut w = f / 64;
        let mut word = *self.bits.get(w)? & (u64::MAX << (f % 64));
        while word == 0 {
            w += 1;
            word = *self.bits.get(w)?;
        }
        Some(64 * w + word.trailing_zeros() as usize).filter(|&g| g < self.faces)
    }
}

/// Neighbour counts of every vertex.
fn valences(c: &Corners) -> Vec<i32> {
    let mut val = vec![0i32; c.pos.len()];
    for h in 0..c.vtx.len() as u32 {
        if c.face_dead[(h / 3) as usize] {
            continue;
        }
        val[c.vtx[h as usize] as usize] += 1;
        if c.is_border(h) {
            val[c.dest(h) as usize] += 1;
        }
    }
    val
}

fn target_valence(c: &Corners, v: u32) -> i32 {
    if c.is_border_vertex(v) { 4 } else { 6 }
}

/// The four vertices of the flip of `h`: a, b (losing the edge), c, d (gaining it).
fn quad(c: &Corners, h: u32) -> [u32; 4] {
    let g = c.opp[h as usize];
    [
        c.vtx[h as usize],
        c.dest(h),
        c.vtx[prev(h) as usize],
        c.vtx[prev(g) as usize],
    ]
}

pub fn equalize_valences(c: &mut Corners) -> usize {
    let mut val = valences(c);
    let mut n = 0;
    for h in 0..c.vtx.len() as u32 {
        if !canonical(c, h) || c.is_constrained(h) {
            continue;
        }
        let q = quad(c, h);
        let dev = |v: &[i32; 4]| -> i32 {
            (0..4)
                .map(|i| (v[i] - target_valence(c, q[i])).pow(2))
                .sum()
        };
        let before = q.map(|v| val[v as usize]);
        let after = [before[0] - 1, before[1] - 1, before[2] + 1, before[3] + 1];
        if after[0] < 3 || after[1] < 3 || dev(&after) >= dev(&before) {
            continue;
        }
        if ops::can_flip(c, h) {
            ops::flip(c, h);
            for (i, v) in q.iter().enumerate() {
                val[*v as usize] = after[i];
            }
            n += 1;
        }
    }
    n
}

fn angle_at(p: DVec3, x: DVec3, y: DVec3) -> f64 {
    (x - p).angle_between(y - p)
}

/// The angles at `pc` and at `pd` of the triangles they make with `pa pb` sum to less than π,
/// told without a trigonometric call: sin(α + β) = sin α cos β + cos α sin β is positive
/// with a margin far above rounding (α + β < π, as both are in (0, π)). Most edges of a
/// remesh pass this; the few that do not get the exact sum.
fn clearly_under_pi(pc: DVec3, pd: DVec3, pa: DVec3, pb: DVec3) -> bool {
    let (u1, v1, u2, v2) = (pa - pc, pb - pc, pa - pd, pb - pd);
    let (cos1, sin1) = (u1.dot(v1), u1.cross(v1).length());
    let (cos2, sin2) = (u2.dot(v2), u2.cross(v2).length());
    let scale =
        (u1.length_squared() * v1.length_squared() * u2.length_squared() * v2.length_squared())
            .sqrt();
    sin1 * cos2 + cos1 * sin2 > 1e-9 * scale
}

/// Flips an edge when the two angles opposite it sum to more than π (plus a margin, so a
/// flip is never undone by the next): the flipped pair has a larger smallest angle.
pub fn flip_angles(c: &mut Corners) -> usize {
    let val = valences(c);
    let mut n = 0;
    for h in 0..c.vtx.len() as u32 {
        if !canonical(c, h) || c.is_constrained(h) {
            continue;
        }
        let [a, b, cc, d] = quad(c, h).map(|v| v as usize);
        if val[a] <= 3 || val[b] <= 3 {
            continue;
        }
        let [pa, pb, pc, pd] = [a, b, cc, d].map(|v| c.pos[v]);
        if clearly_under_pi(pc, pd, pa, pb) {
            continue;
        }
        let opposite = angle_at(pc, pa, pb) + angle_at(pd, pa, pb);
        if opposite > std::f64::consts::PI + 1e-3 && ops::can_flip(c, h) {
            ops::flip(c, h);
            n += 1;
        }
    }
    n
}

/// Tangential relaxation: a free vertex moves towards the area-weighted centroid of its
/// faces within its tangent plane, a line vertex along its line ([`relaxed_on_line`]). A
/// move that would turn a face over is not made. With an adaptive size, a face's weight is
/// its area over its squared size (pmp-library's weighting), so vertices do not drift
/// towards the large triangles of the coarse parts.
pub fn relax(c: &mut Corners, lines: &Lines, sizing: &Sizing, before: &Placement) {
    c.pos = (0..c.pos.len() as u32)
        .into_par_iter()
        .with_max_len(PIECE)
        .map_init(Scratch::default, |sc, v| relaxed(c, lines, sizing, v, sc))
        .collect();
    undo_turns(c, before);
}

/// After the relax: each vertex checked its own move against its neighbours' positions
/// before it, so two neighbours moving together can still turn a face over. Every face
/// that now faces against (or across, or is degenerate where it was not) its orientation
/// before the round gets its moved corners put back ([`put_back`]). (Not after the
/// projection: putting a vertex back there would leave it off the surface; the last pass,
/// [`repair`], sees to what turns there.)
fn undo_turns(c: &mut Corners, before: &Placement) {
    put_back(c, before, |c, f, v| {
        let b = v.map(|v| before.pos[v]);
        !ops::face_ok(c.face_positions(f), (b[1] - b[0]).cross(b[2] - b[0]))
    });
}

/// Where the vertices were, and what they were on, before a round's relax and projection.
pub struct Placement {
    pos: Vec<DVec3>,
    vseg: Vec<u32>,
    vtri: Vec<u32>,
}

impl Placement {
    fn of(c: &Corners) -> Placement {
        Placement {
            pos: c.pos.clone(),
            vseg: c.vseg.clone(),
            vtri: c.vtri.clone(),
        }
    }

    fn moved(&self, c: &Corners, v: usize) -> bool {
        c.pos[v] != self.pos[v]
    }
}

/// After the relax and the projection of a round: a face they made degenerate gets its
/// moved corners put back ([`put_back`]). Each vertex checks its own projection against
/// its neighbours' positions before it, so two line vertices projected together can land
/// on one straight segment with a third corner: where a short line turns sharply, as the
/// border of an input triangle hanging off the scan by one vertex does (james), the face
/// across the turn would have no area. Only faces with a moved line vertex are looked at:
/// free vertices land on a surface, not on one segment, and checking every face cost 5 %
/// of a james remesh. Turned faces are left to [`repair`], which can move or collapse them
/// (it cannot mend a face of three line edges).
fn undo_degenerate(c: &mut Corners, before: &Placement) {
    put_back(c, before, |c, f, v| {
        v.iter()
            .any(|&v| c.kind[v] == VKind::Line && before.moved(c, v))
            && ops::degenerate(c.face_positions(f))
            && !ops::degenerate(v.map(|v| before.pos[v]))
    });
}

/// Puts the moved corners of every live face that `bad` (face, its corners) picks back
/// where `before` had them (position, line segment, input triangle), repeated until no
/// face with a moved corner is picked. Terminates: each round puts back at least one moved
/// vertex.
fn put_back(
    c: &mut Corners,
    before: &Placement,
    bad: impl Fn(&Corners, usize, [usize; 3]) -> bool + Sync,
) {
    loop {
        let picked: Vec<usize> = (0..c.face_count())
            .into_par_iter()
            .with_max_len(PIECE)
            .filter(|&f| {
                let v = [0, 1, 2].map(|i| c.vtx[3 * f + i] as usize);
                !c.face_dead[f] && v.iter().any(|&v| before.moved(c, v)) && bad(c, f, v)
            })
            .collect();
        let mut put = 0;
        for f in picked {
            for i in 0..3 {
                let v = c.vtx[3 * f + i] as usize;
                if before.moved(c, v) {
                    c.pos[v] = before.pos[v];
                    c.vseg[v] = before.vseg[v];
                    c.vtri[v] = before.vtri[v];
                    put += 1;
                }
            }
        }
        if put == 0 {
            return;
        }
    }
}

fn relaxed(c: &Corners, lines: &Lines, sizing: &Sizing, v: u32, sc: &mut Scratch) -> DVec3 {
    let p = c.pos[v as usize];
    if c.vertex_dead[v as usize] || c.locked[v as usize] {
        return p;
    }
    let target = match c.kind[v as usize] {
        VKind::Corner => return p,
        VKind::Line => return relaxed_on_line(c, lines, v, sc),
        VKind::Free => {
            let (centroid, normal) = match sizing {
                Sizing::Uniform { .. } => ops::fan_centroid(c, v),
                Sizing::Adaptive { size, .. } => ops::fan_centroid_sized(c, v, size),
            };
            let d = centroid - p;
            p + d - normal * normal.dot(d)
        }
    };
    if ops::fan_keeps_orientation(c, v, target) {
        target
    } else {
        p
    }
}

/// A line vertex moves along its line only: towards the middle of its two line neighbours
/// along their chord, then onto the line, where the move is checked. It stays where it is
/// when no face around it may take that point: a face would turn over, or become thinner
/// than [`LINE_MOVE_QUALITY`] (or than the thinnest around it now, if that is thinner).
///
/// Why on the line at once: a move along the chord that the round's projection then
/// refused (a face would have turned) left the vertex off its line, a seam vertex off the
/// input's seam, which puts one chart's photo on the other side. Why the quality floor: a
/// move is checked against its neighbours' old positions while they move too, and a border
/// vertex put on a ragged border beside a moving free vertex made needles of hundredths of
/// a degree (docs/remeshing.md, "Line vertices on their lines").
fn relaxed_on_line(c: &Corners, lines: &Lines, v: u32, sc: &mut Scratch) -> DVec3 {
    let p = c.pos[v as usize];
    let Some([x, y]) = ops::line_neighbours(c, v, sc) else {
        return p;
    };
    let (px, py) = (c.pos[x as usize], c.pos[y as usize]);
    let t = (py - px).normalize_or_zero();
    let along = p + t * t.dot(0.5 * (px + py) - p);
    let ok = match c.vseg[v as usize] {
        // Not on a segment of the input's lines (nothing to project onto): along the chord.
        NIL => ops::fan_keeps_orientation(c, v, along).then_some(along),
        seg => {
            let (target, _) = lines.project(along, seg);
            let floor = || LINE_MOVE_QUALITY.min(ops::fan_min_quality(c, v, p));
            (ops::fan_keeps_orientation(c, v, target)
                && ops::fan_min_quality(c, v, target) >= floor())
            .then_some(target)
        }
    };
    ok.unwrap_or(p)
}

/// The thinnest face a line vertex's move may make (shape quality, 1 for equilateral; 0.2
/// is a needle of about 7°), unless one around it is thinner already. 0.1–0.3 gave the same
/// seams and angles on james, esp32cam and the coral (docs/remeshing.md).
const LINE_MOVE_QUALITY: f64 = 0.2;

/// Projection back onto the input: free vertices onto the closest point of the surface near
/// the input triangle they were last projected onto ([`walk::walk_or_search`]: a relaxed
/// vertex moved by less than an edge, so a walk of a few triangles finds it, and stays on
/// the vertex's sheet where the input folds), line vertices onto their line. A projection
/// that would turn a face over is not made.
pub fn project(c: &mut Corners, input: &Input) {
    let new: Vec<(DVec3, u32, u32)> = (0..c.pos.len() as u32)
        .into_par_iter()
        .with_max_len(PIECE)
        .map(|v| projected(c, input, v))
        .collect();
    for (v, (p, seg, tri)) in new.into_iter().enumerate() {
        c.pos[v] = p;
        c.vseg[v] = seg;
        c.vtri[v] = tri;
    }
}

fn projected(c: &Corners, input: &Input, v: u32) -> (DVec3, u32, u32) {
    let i = v as usize;
    let (p, seg, tri) = (c.pos[i], c.vseg[i], c.vtri[i]);
    if c.vertex_dead[i] || c.locked[i] {
        return (p, seg, tri);
    }
    let (q, seg, tri) = match c.kind[i] {
        VKind::Corner => return (p, seg, tri),
        VKind::Line if seg != NIL => {
            let (q, s) = input.lines.project(p, seg);
            (q, s, tri)
        }
        VKind::Line => return (p, seg, tri),
        VKind::Free => match input.closest_near(p, tri) {
            Some(foot) => (foot.point, seg, foot.triangle),
            None => return (p, seg, tri),
        },
    };
    if ops::fan_keeps_orientation(c, v, q) {
        (q, seg, tri)
    } else {
        (p, c.vseg[i], tri)
    }
}

/// The input as the passes see it: the mesh, its sheet (its topology and the walks' flat
/// tables, [`Sheet`]), its search tree and its lines.
pub struct Input<'a> {
    pub mesh: &'a Mesh,
    pub sheet: &'a Sheet<'a>,
    pub bvh: &'a TriangleBvh<'a>,
    pub lines: &'a Lines,
}

impl Input<'_> {
    /// The closest point of the input to `p` near input triangle `tri` (see [`project`]).
    fn closest_near(&self, p: DVec3, tri: u32) -> Option<walk::Foot> {
        walk::walk_or_search(self.sheet, self.bvh, tri, p, |_| true)
    }
}

/// Runs `iterations` rounds towards the edge lengths of `sizing`, then, with `fit`, fits
/// the free vertices to the input, repairs faces turned against it, and last mends the
/// slivers away from lines that are left ([`slivers`]).
pub fn run(
    c: &mut Corners,
    input: &Input,
    sizing: &mut Sizing,
    iterations: usize,
    fit: bool,
) -> Counts {
    let Input {
        mesh,
        sheet,
        bvh,
        lines,
    } = *input;
    let mut sc = Scratch::default();
    let mut counts = Counts::default();
    for _ in 0..iterations {
        counts.splits += split_long(c, lines, sizing);
        counts.collapses += collapse_short(c, sizing, &mut sc);
        counts.valence_flips += equalize_valences(c);
        let before = Placement::of(c);
        relax(c, lines, sizing, &before);
        project(c, input);
        undo_degenerate(c, &before);
        sizing.follow(c, lines, mesh);
        counts.angle_flips += flip_angles(c);
    }
    let under = fit.then(|| {
        let (report, under) = fit::fit(c, sheet);
        counts.fit = report;
        under
    });
    counts.turned = repair::repair(c, lines, bvh, mesh, &mut sc, under.as_deref());
    let against = repair::Input { bvh, mesh, lines };
    sizing.cover(c);
    counts.slivers = slivers::clean(c, &against, sizing, &mut sc);
    counts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::surface::rng;
    use rand::RngExt;

    /// The shortcut never says "under π" where the exact sum of the two angles is π or more,
    /// and says it for most edges whose sum is clearly under (on random quads, near-flat
    /// ones included).
    #[test]
    fn clearly_under_pi_agrees_with_the_angles() {
        let mut r = rng(5);
        let mut point = |spread: f64| {
            DVec3::new(
                r.random_range(-1.0..1.0),
                r.random_range(-1.0..1.0),
                spread * r.random_range(-1.0..1.0),
            )
        };
        let (mut under, mut said) = (0, 0);
        for i in 0..20_000 {
            let spread = if i % 2 == 0 { 1.0 } else { 1e-6 };
            let [pa, pb, pc, pd] = [point(spread), point(spread), point(spread), point(spread)];
            let sum = angle_at(pc, pa, pb) + angle_at(pd, pa, pb);
            let quick = clearly_under_pi(pc, pd, pa, pb);
            assert!(
                !quick || sum < std::f64::consts::PI,
                "{pa} {pb} {pc} {pd}: {sum}"
            );
            if sum < std::f64::consts::PI - 1e-3 {
                under += 1;
                said += usize::from(quick);
            }
        }
        assert!(said == under, "{said} of {under}");
    }

    /// Every split pass listing every long edge, as [`split_long`] did before it looked only
    /// at the edges of the vertices the last pass made.
    fn split_scanning_every_edge(c: &mut Corners, lines: &Lines, sizing: &mut Sizing) -> usize {
        let (mut n, mut hs) = (0, Vec::new());
        for _ in 0..SPLIT_PASSES {
            let long: Vec<u32> = (0..c.vtx.len() as u32)
                .filter(|&h| canonical(c, h) && too_long(c, sizing, h))
                .collect();
            if long.is_empty() {
                break;
            }
            n += split_pass(c, lines, sizing, &long, &mut hs);
        }
        n
    }

    /// Every collapse sweep trying every short edge.
    fn collapse_trying_every_edge(c: &mut Corners, sizing: &Sizing) -> usize {
        let (mut total, mut sc) = (0, Scratch::default());
        for _ in 0..COLLAPSE_SWEEPS {
            let mut n = 0;
            for h in 0..c.vtx.len() as u32 {
                let (a, b) = (c.vtx[h as usize], c.dest(h));
                if !canonical(c, h)
                    || c.pos[a as usize].distance(c.pos[b as usize]) >= sizing.lo(a, b)
                {
                    continue;
                }
                if let Some((x, y)) = order(c, a, b)
                    .into_iter()
                    .find(|&(x, y)| ops::can_collapse(c, h, x, y, sizing, &mut sc))
                {
                    ops::collapse(c, h, x, y, &mut sc);
                    n += 1;
                }
            }
            total += n;
            if n == 0 {
                break;
            }
        }
        total
    }

    /// The split passes after the first and the collapse sweeps after the first look only
    /// where the last one changed something; on a real scan (james: ragged borders, seams,
    /// five locked vertices) at two lengths in turn, they do exactly what passes over every
    /// edge do.
    #[test]
    fn passes_that_look_only_near_changes_match_passes_over_every_edge() {
        let path = "../shared/data/textured/james_face_stereo_capture/james.obj";
        let options = crate::mesh::LoadOptions {
            check_textures: false,
            ..Default::default()
        };
        let mesh = crate::mesh::load(std::path::Path::new(path), &options)
            .unwrap_or_else(|e| panic!("{path}: {e}"))
            .0;
        let topo = crate::mesh::topology::Topology::new(&mesh);
        let lines = Lines::new(&mesh, &topo, None);
        let mut fast = super::super::build::build(&mesh, &topo, &lines);
        assert!(fast.locked.iter().any(|&l| l));
        let mut every = fast.clone();
        let diagonal = mesh.bounding_box_diagonal();
        let mut r = rng(7);
        for fraction in [0.01, 0.006, 0.01, 0.004, 0.008] {
            // Every vertex jittered by up to a third of the length, the same in both.
            let l = fraction * diagonal;
            for (p, q) in fast.pos.iter_mut().zip(every.pos.iter_mut()) {
                let d = DVec3::new(
                    r.random_range(-1.0..1.0),
                    r.random_range(-1.0..1.0),
                    r.random_range(-1.0..1.0),
                );
                *p += l / 3.0 * d;
                *q = *p;
            }
            let mut sizing = Sizing::uniform(l);
            let mut sizing_every = sizing.clone();
            let splits = split_long(&mut fast, &lines, &mut sizing);
            assert!(splits > 0);
            assert_eq!(
                splits,
                split_scanning_every_edge(&mut every, &lines, &mut sizing_every)
            );
            let collapses = collapse_short(&mut fast, &sizing, &mut Scratch::default());
            assert!(collapses > 0);
            assert_eq!(collapses, collapse_trying_every_edge(&mut every, &sizing));
            fast.check().unwrap();
            assert_eq!(fast.vtx, every.vtx);
            assert_eq!(fast.opp, every.opp);
            assert_eq!(fast.pos, every.pos);
            assert_eq!(fast.face_dead, every.face_dead);
        }
    }
}
