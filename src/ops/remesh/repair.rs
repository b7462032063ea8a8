//! The last pass of `isotropic`: faces turned against the input.
//!
//! Every operation of the remesher checks its faces against their orientation just before
//! it (`ops::face_ok`), so no single step turns a face over; but a face can turn by steps
//! that are each under 90°, and where the input is crumpled (a ragged scan border folded
//! over itself) the projection can lay a face across a fold. The decimation promises no
//! face against the input; so does this pass, with the input's orientation read the way
//! the metrics read it: the input triangle closest to the face's centroid, or, where that
//! point is on a crease or fold shared by several triangles as near, any of them.
//!
//! Each turned face, in index order, gets the first of these after which the faces it
//! changes disagree less with the input (each turned face counts 1, a degenerate one more
//! than any number of turned ones, so no repair trades turned faces for one without area):
//! flip one of its free edges; move one of its corners nearby (a free vertex to the input's
//! closest point to the centroid of its fan or to itself, or halfway to the first; a line
//! vertex along its line towards the middle of its line neighbours, or halfway); collapse
//! one of its edges under the remesher's topological rules; move a corner farther (a free
//! vertex to the input's closest point to a point 0.3 of the way to each neighbour, a line
//! vertex to one of seven points of its line between its line neighbours), which bends the
//! faces more than a collapse; split one of its edges at the input's closest point to the
//! edge's middle, so that four smaller faces can follow a fold that the two larger ones lay
//! across. A face's agreement depends on its own corners only,
//! so each repair lowers the total and the pass ends. It goes round again, over the
//! faces still turned and those around what changed, while a round repairs something: a
//! face that could not be repaired may be once its neighbours have moved.
//!
//! What it cannot repair is left and counted: where the input folds over itself (james's
//! ragged border, where a quarter to four fifths of the input triangles within two edge
//! lengths face against the closest one), no placement of the few corners nearby agrees
//! with every closest triangle.

use super::PIECE;
use super::build;
use super::corners::{Corners, NIL, VKind, prev};
use super::export::Live;
use super::lines::Lines;
use super::ops::{self, Scratch};
use super::patches::tessellate::mesh_of;
use crate::geom::bvh::{TriangleBvh, TriangleHit};
use crate::mesh::Mesh;
use crate::mesh::topology::Topology;
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

/// What the pass did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Repairs {
    /// Faces turned against the input (or degenerate) before the pass.
    pub turned: usize,
    pub flips: usize,
    pub moves: usize,
    pub collapses: usize,
    pub splits: usize,
    /// Faces still turned after it.
    pub left: usize,
    /// Of those, the faces whose corners may not move (line ends, junctions and locked
    /// vertices).
    pub left_unmovable: usize,
}

impl Repairs {
    /// Whether the pass changed the mesh.
    pub fn changed(&self) -> bool {
        self.flips + self.moves + self.collapses + self.splits > 0
    }
}

/// How far a repair's move may take a vertex (see [`Pass::try_moves`]).
#[derive(Clone, Copy)]
enum Reach {
    Near,
    Far,
}

/// A line vertex's move also tries its line's points nearest to 1/8, 2/8 … 7/8 of the way
/// between its line neighbours (docs/remeshing.md, "the repair pass").
const LINE_TARGETS: usize = 8;

/// A free vertex's move tries the input's closest point to the point this far towards each
/// of its neighbours (0.3: well inside the fan, so its faces keep their shape).
const TOWARDS_NEIGHBOUR: f64 = 0.3;

/// At most this many rounds (james: 16 faces turned, 2 left after the second round).
const MAX_ROUNDS: usize = 8;

/// The closest point of the input to the centroid of the face with corners `p`, searched
/// from input triangle `hint`.
fn input_hit(bvh: &TriangleBvh, p: [DVec3; 3], hint: u32) -> (DVec3, TriangleHit) {
    let centroid = (p[0] + p[1] + p[2]) / 3.0;
    let start = bvh.hit_on(centroid, hint);
    (
        centroid,
        bvh.closest(centroid, Some(start)).unwrap_or(start),
    )
}

/// The input triangle closest to the centroid of the face with corners `p`, searched from
/// `hint`.
fn input_under(bvh: &TriangleBvh, p: [DVec3; 3], hint: u32) -> u32 {
    input_hit(bvh, p, hint).1.triangle
}

/// The input as the pass reads it (also the sliver clean-up's, [`super::slivers`]).
pub(super) struct Input<'a> {
    pub(super) bvh: &'a TriangleBvh<'a>,
    pub(super) mesh: &'a Mesh,
    pub(super) lines: &'a Lines,
}

impl Input<'_> {
    /// A face with corners `p` is not degenerate and faces the input's way under its
    /// centroid: the way of the input triangle closest to it, or, where that closest point
    /// is on an edge or corner shared with other triangles as near (a crease, a fold), of
    /// any of them ([`TriangleBvh::facing`]; the metrics read flipped faces the same way).
    /// An input triangle of zero area has no way: it does not object.
    fn agrees(&self, p: [DVec3; 3], hint: u32) -> bool {
        if ops::degenerate(p) {
            return false;
        }
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        let facing = |t: u32| {
            let m = self.mesh.triangle_cross(t as usize);
            m == DVec3::ZERO || n.dot(m) > 0.0
        };
        let centroid = (p[0] + p[1] + p[2]) / 3.0;
        let start = self.bvh.hit_on(centroid, hint);
        // The closest triangle is no farther than `hint`'s: when every triangle that near
        // faces this way, so does the closest, whichever it is. Nearly every face is
        // settled so, without the search for it.
        if facing(hint)
            && self
                .bvh
                .all_facing_within(centroid, start.distance_squared, n)
        {
            return true;
        }
        let hit = self.bvh.closest(centroid, Some(start)).unwrap_or(start);
        facing(hit.triangle) || facing(self.bvh.facing(centroid, &hit, n.normalize()))
    }

    fn face_agrees(&self, c: &Corners, f: usize) -> bool {
        self.agrees(c.face_positions(f), face_hint(c, f))
    }

    pub(super) fn face_badness(&self, c: &Corners, f: usize) -> usize {
        self.badness(c.face_positions(f), face_hint(c, f))
    }

    /// How much a face with corners `p` counts against a repair: 0 when it agrees, 1 when
    /// it is turned, [`DEGENERATE_WEIGHT`] when it has no area. A repair must lower the sum
    /// over the faces it changes, so it never trades turned faces for a degenerate one.
    pub(super) fn badness(&self, p: [DVec3; 3], hint: u32) -> usize {
        if ops::degenerate(p) {
            DEGENERATE_WEIGHT
        } else {
            usize::from(!self.agrees(p, hint))
        }
    }
}

/// Where the search for face `f`'s input triangle starts: its first corner's last one.
fn face_hint(c: &Corners, f: usize) -> u32 {
    c.vtri[c.vtx[3 * f] as usize]
}

/// A degenerate face outweighs any number of turned faces around one vertex or edge: its
/// normal is undefined, which breaks shading and normals downstream (a turned face only
/// looks wrong). More than the faces any fan has.
const DEGENERATE_WEIGHT: usize = 1 << 16;

/// The live faces turned against the input, in index order. `under`, when given, has an
/// input triangle near each face's centroid to start its search from (any triangle gives
/// the same answer; a near one prunes the tree sooner).
fn turned_faces(c: &Corners, input: &Input, under: Option<&[u32]>) -> Vec<usize> {
    (0..c.face_count())
        .into_par_iter()
        .with_max_len(PIECE)
        .filter(|&f| {
            let hint = match under.and_then(|u| u.get(f)) {
                Some(&t) if t != NIL => t,
                _ => face_hint(c, f),
            };
            !c.face_dead[f] && !input.agrees(c.face_positions(f), hint)
        })
        .collect()
}

/// Runs the pass (see the module's documentation). `under`, when given, is an input
/// triangle near each face's centroid (the fit's, [`super::fit::fit`]), where the first
/// search for the face's closest input triangle starts.
pub fn repair(
    c: &mut Corners,
    lines: &Lines,
    bvh: &TriangleBvh,
    mesh: &Mesh,
    sc: &mut Scratch,
    under: Option<&[u32]>,
) -> Repairs {
    let input = Input { bvh, mesh, lines };
    let turned = turned_faces(c, &input, under);
    let mut pass = Pass {
        input,
        sc,
        hs: Vec::new(),
        moved: Vec::new(),
        r: Repairs {
            turned: turned.len(),
            ..Repairs::default()
        },
    };
    let left = mend_in_rounds(&mut pass, c, turned, MAX_ROUNDS);
    let mut r = pass.r;
    r.left = left.len();
    r.left_unmovable = left
        .iter()
        .filter(|&&f| (0..3).all(|i| !movable(c, c.vtx[3 * f + i])))
        .count();
    r
}

/// A pass that mends faces one at a time ([`mend_in_rounds`]): the repair of turned faces
/// here, the sliver pass ([`super::slivers`]).
pub(super) trait Mending {
    /// Face `f` (live or dead) still needs mending.
    fn needs(&self, c: &Corners, f: usize) -> bool;
    /// Tries to mend face `f`. A try that fails changes nothing; one that succeeds puts the
    /// vertices whose faces it changed into [`Mending::changed`]'s list.
    fn try_face(&mut self, c: &mut Corners, f: usize);
    /// The vertices changed this round, and a scratch list for [`faces_near`].
    fn changed(&mut self) -> (&mut Vec<u32>, &mut Vec<u32>);
}

/// Tries to mend each of `faces` that still needs it, in index order, in at most
/// `max_rounds` rounds, and returns those that still need it, in index order.
///
/// What a try on face f reads is the corners of f and their neighbours only, and a try that
/// fails changes nothing: so a face with no corner next to a change would fail again. The
/// next round takes the faces that need mending among those near a change; the others wait,
/// and are tried again once a change comes near them.
pub(super) fn mend_in_rounds(
    m: &mut impl Mending,
    c: &mut Corners,
    mut faces: Vec<usize>,
    max_rounds: usize,
) -> Vec<usize> {
    let mut waiting: Vec<usize> = Vec::new();
    for _ in 0..max_rounds {
        m.changed().0.clear();
        for &f in &faces {
            if m.needs(c, f) {
                m.try_face(c, f);
            }
        }
        let (changed, hs) = m.changed();
        if changed.is_empty() {
            break;
        }
        let near = faces_near(c, changed, hs);
        waiting.extend(faces.iter().filter(|f| near.binary_search(f).is_err()));
        faces = near.into_iter().filter(|&f| m.needs(c, f)).collect();
    }
    // Waiting faces a later change came near were taken again (and are in `faces` if they
    // still need it); the rest are as they were.
    faces.extend(waiting);
    faces.sort_unstable();
    faces.dedup();
    faces.retain(|&f| m.needs(c, f));
    faces
}

/// The live faces with a corner at or next to one of the live vertices `changed`, in index
/// order.
pub(super) fn faces_near(c: &Corners, changed: &[u32], hs: &mut Vec<u32>) -> Vec<usize> {
    let mut ring = Vec::new();
    let mut near = Vec::new();
    for &v in changed {
        if c.vertex_dead[v as usize] {
            continue;
        }
        c.ring(v, &mut ring);
        for &u in ring.iter().chain([&v]) {
            c.fan(u, hs);
            near.extend(hs.iter().map(|&h| (h / 3) as usize));
        }
    }
    near.sort_unstable();
    near.dedup();
    near.retain(|&f| !c.face_dead[f]);
    near
}

/// The pass on a mesh `patches` made from `input` (closed, without texture coordinates;
/// `triangle_origins` index `input`). Only where the pass changed something is the mesh
/// rebuilt: its faces keep their origins, a flipped pair those of its two old faces, and a
/// split's new faces take the input triangle closest to their centroid.
pub fn repair_mesh(input: &Mesh, out: Mesh) -> (Mesh, Repairs) {
    let topo = Topology::new(&out);
    let lines = Lines::new(&out, &topo, None);
    let mut c = build::build(&out, &topo, &lines);
    // `build` points each vertex at a face of `out`; the pass wants input triangles.
    for t in c.vtri.iter_mut() {
        *t = out.triangle_origin(*t as usize);
    }
    let bvh = TriangleBvh::new(input, (0..input.triangles.len() as u32).collect());
    let r = repair(&mut c, &lines, &bvh, input, &mut Scratch::default(), None);
    if !r.changed() {
        return (out, r);
    }
    let live = Live::of(&c);
    let positions = live.vertices.iter().map(|&v| c.pos[v as usize]).collect();
    // A face a split added has no origin in `out`: it takes the input triangle closest to
    // its centroid, as the remesher's faces do.
    let origin = |f: usize| {
        if f < out.triangles.len() {
            return out.triangle_origin(f);
        }
        input_under(&bvh, c.face_positions(f), face_hint(&c, f))
    };
    let triangles = live
        .faces
        .iter()
        .map(|&f| (live.triangle(&c, f), origin(f)))
        .collect();
    (mesh_of(positions, triangles), r)
}

/// One pass's working state: the input, and scratch shared by the repairs.
struct Pass<'a> {
    input: Input<'a>,
    sc: &'a mut Scratch,
    hs: Vec<u32>,
    /// Vertices whose faces a repair of this round changed.
    moved: Vec<u32>,
    r: Repairs,
}

impl Mending for Pass<'_> {
    fn needs(&self, c: &Corners, f: usize) -> bool {
        !c.face_dead[f] && !self.input.face_agrees(c, f)
    }

    /// The near moves and the collapses first: they keep the faces' shapes best; the far
    /// moves and the splits only where those fail.
    fn try_face(&mut self, c: &mut Corners, f: usize) {
        if self.try_flips(c, f) {
            self.r.flips += 1;
        } else if self.try_moves(c, f, Reach::Near) {
            self.r.moves += 1;
        } else if self.try_collapses(c, f) {
            self.r.collapses += 1;
        } else if self.try_moves(c, f, Reach::Far) {
            self.r.moves += 1;
        } else if self.try_splits(c, f) {
            self.r.splits += 1;
        }
    }

    fn changed(&mut self) -> (&mut Vec<u32>, &mut Vec<u32>) {
        (&mut self.moved, &mut self.hs)
    }
}

impl Pass<'_> {
    /// Flips the first edge of face `f` whose two new faces disagree with the input less
    /// than the two old ones.
    fn try_flips(&mut self, c: &mut Corners, f: usize) -> bool {
        for h in (3 * f as u32)..(3 * f as u32 + 3) {
            let g = c.opp[h as usize];
            if g == NIL || !ops::can_flip_topologically(c, h) {
                continue;
            }
            let (a, b) = (c.vtx[h as usize], c.dest(h));
            let (cc, d) = (c.vtx[prev(h) as usize], c.vtx[prev(g) as usize]);
            let p = |v: u32| c.pos[v as usize];
            let hint = c.vtri[cc as usize];
            let before: usize = [h, g]
                .iter()
                .map(|&k| self.input.face_badness(c, (k / 3) as usize))
                .sum();
            let after: usize = [[p(cc), p(a), p(d)], [p(d), p(b), p(cc)]]
                .iter()
                .map(|&q| self.input.badness(q, hint))
                .sum();
            if after < before {
                ops::flip(c, h);
                self.moved.extend([a, b, cc, d]);
                return true;
            }
        }
        false
    }

    /// Moves the first vertex of face `f` that can go somewhere where fewer faces around it
    /// disagree with the input. Near: a free vertex to the input's closest point to the
    /// centroid of its fan or to itself, or halfway to the first; a line vertex to the point
    /// of its line closest to the middle of its two line neighbours, or halfway there. Far:
    /// a free vertex to the input's closest point to a point [`TOWARDS_NEIGHBOUR`] of the
    /// way to each neighbour; a line vertex to its line's points at 1/8 … 7/8 of the way
    /// between its line neighbours.
    fn try_moves(&mut self, c: &mut Corners, f: usize, reach: Reach) -> bool {
        (0..3).any(|i| {
            let v = c.vtx[3 * f + i];
            let done = match c.kind[v as usize] {
                _ if c.locked[v as usize] => false,
                VKind::Free => self.try_free_move(c, v, reach),
                VKind::Line => self.try_line_move(c, v, reach),
                VKind::Corner => false,
            };
            if done {
                self.moved.push(v);
            }
            done
        })
    }

    fn try_line_move(&mut self, c: &mut Corners, v: u32, reach: Reach) -> bool {
        let seg = c.vseg[v as usize];
        let Some([x, y]) = ops::line_neighbours(c, v, self.sc) else {
            return false;
        };
        if seg == NIL {
            return false;
        }
        let here = c.pos[v as usize];
        let before = self.disagreements(c, v, here, None);
        let lines = self.input.lines;
        let (px, py) = (c.pos[x as usize], c.pos[y as usize]);
        let (on_line, seg) = lines.project(0.5 * (px + py), seg);
        let targets: Vec<(DVec3, u32)> = match reach {
            Reach::Near => {
                let halfway = lines.project(0.5 * (here + on_line), seg);
                vec![(on_line, seg), halfway]
            }
            // Where the input folds under the line, the one place that agrees may be well
            // off the middle (james's border).
            Reach::Far => (1..LINE_TARGETS)
                .map(|k| lines.project(px.lerp(py, k as f64 / LINE_TARGETS as f64), seg))
                .collect(),
        };
        for (target, seg) in targets {
            if self.disagreements(c, v, target, None) < before {
                c.pos[v as usize] = target;
                c.vseg[v as usize] = seg;
                return true;
            }
        }
        false
    }

    fn try_free_move(&mut self, c: &mut Corners, v: u32, reach: Reach) -> bool {
        let here = c.pos[v as usize];
        let before = self.disagreements(c, v, here, None);
        let hint = c.vtri[v as usize];
        let bvh = self.input.bvh;
        let queries = match reach {
            Reach::Near => {
                let (centroid, _) = ops::fan_centroid(c, v);
                vec![(centroid, false), (centroid, true), (here, false)]
            }
            // Across a fold the closest point of a point nearby can be on the sheet the
            // faces around agree with.
            Reach::Far => {
                let mut ring = Vec::new();
                c.ring(v, &mut ring);
                ring.iter()
                    .map(|&u| (here.lerp(c.pos[u as usize], TOWARDS_NEIGHBOUR), false))
                    .collect()
            }
        };
        for (query, halfway) in queries {
            let Some(hit) = bvh.closest(query, Some(bvh.hit_on(query, hint))) else {
                continue;
            };
            let target = if halfway {
                0.5 * (here + hit.point)
            } else {
                hit.point
            };
            if self.disagreements(c, v, target, None) < before {
                c.pos[v as usize] = target;
                c.vtri[v as usize] = hit.triangle;
                return true;
            }
        }
        false
    }

    /// Collapses the first edge of face `f` (either way) after which fewer faces disagree
    /// with the input: the faces of the going vertex, the two removed ones among them.
    fn try_collapses(&mut self, c: &mut Corners, f: usize) -> bool {
        for h in (3 * f as u32)..(3 * f as u32 + 3) {
            let (a, b) = (c.vtx[h as usize], c.dest(h));
            for (x, y) in [(a, b), (b, a)] {
                if !ops::can_collapse_topologically(c, h, x, y, self.sc) {
                    continue;
                }
                let before = self.disagreements(c, x, c.pos[x as usize], None);
                if self.disagreements(c, x, c.pos[y as usize], Some(y)) < before {
                    ops::collapse(c, h, x, y, self.sc);
                    self.moved.push(y);
                    return true;
                }
            }
        }
        false
    }

    /// Splits the first edge of face `f` whose four new faces disagree with the input less
    /// than the two old ones, at the input's closest point to the edge's middle (a line
    /// edge: at its line's point closest to the middle). Where the input folds, smaller
    /// faces can follow what larger ones could only lie across.
    fn try_splits(&mut self, c: &mut Corners, f: usize) -> bool {
        for h in (3 * f as u32)..(3 * f as u32 + 3) {
            let (a, b) = (c.vtx[h as usize], c.dest(h));
            if c.locked[a as usize] || c.locked[b as usize] {
                continue;
            }
            let mid = 0.5 * (c.pos[a as usize] + c.pos[b as usize]);
            let hint = c.vtri[a as usize];
            let (m, seg, vtri) = if c.is_constrained(h) {
                let seg = c.seg[h as usize];
                if seg == NIL {
                    continue;
                }
                let (p, seg) = self.input.lines.project(mid, seg);
                (p, seg, hint)
            } else {
                let bvh = self.input.bvh;
                let Some(hit) = bvh.closest(mid, Some(bvh.hit_on(mid, hint))) else {
                    continue;
                };
                (hit.point, NIL, hit.triangle)
            };
            let g = c.opp[h as usize];
            let p = |v: u32| c.pos[v as usize];
            let mut before = self.input.face_badness(c, f);
            let z = c.vtx[prev(h) as usize];
            let mut after = self.input.badness([p(a), m, p(z)], vtri)
                + self.input.badness([m, p(b), p(z)], vtri);
            let w = (g != NIL).then(|| c.vtx[prev(g) as usize]);
            if let Some(w) = w {
                before += self.input.face_badness(c, (g / 3) as usize);
                after += self.input.badness([p(b), m, p(w)], vtri)
                    + self.input.badness([m, p(a), p(w)], vtri);
            }
            if after < before {
                let v = ops::split(c, h, m, seg);
                c.vtri[v as usize] = vtri;
                self.moved.extend([a, b, z, v].into_iter().chain(w));
                return true;
            }
        }
        false
    }

    /// With `v` at `p`, how much the faces around it disagree with the input (the sum of
    /// [`Input::badness`]); with `into`, as after `v` goes into that neighbour (the faces
    /// they share are gone).
    fn disagreements(&mut self, c: &Corners, v: u32, p: DVec3, into: Option<u32>) -> usize {
        let hint = c.vtri[into.unwrap_or(v) as usize];
        c.fan(v, &mut self.hs);
        self.hs
            .iter()
            .map(|&h| {
                let (x, y) = (c.dest(h), c.vtx[prev(h) as usize]);
                if into.is_some_and(|n| x == n || y == n) {
                    return 0;
                }
                self.input
                    .badness([p, c.pos[x as usize], c.pos[y as usize]], hint)
            })
            .sum()
    }
}

fn movable(c: &Corners, v: u32) -> bool {
    c.kind[v as usize] != VKind::Corner && !c.locked[v as usize]
}
