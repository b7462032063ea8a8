//! The last pass of `isotropic`: faces turned against the input.
//!
//! Every operation of the remesher checks its faces against their orientation just before
//! it (`ops::face_ok`), so no single step turns a face over; but a face can turn by steps
//! that are each under 90°, and where the input is crumpled (a ragged scan border folded
//! over itself) the projection can lay a face across a fold. The decimation promises no
//! face against the input; so does this pass, with the input's orientation read the way
//! the metrics and the output's triangle origins read it: the input triangle closest to
//! the face's centroid.
//!
//! Each turned face, in index order, gets the first of these after which the faces it
//! changes disagree less with the input (each turned face counts 1, a degenerate one more
//! than any number of turned ones, so no repair trades turned faces for one without area):
//! flip one of its free edges; move one of its corners (a free vertex to the input's
//! closest point to the centroid of its fan or to itself, or halfway to the first; a line
//! vertex along its line towards the middle of its line neighbours); collapse one of its
//! edges under the remesher's topological rules. A face's agreement depends on its own
//! corners only, so each repair lowers the total and the pass ends. It goes round again, over the
//! faces still turned and those around what changed, while a round repairs something: a
//! face that could not be repaired may be once its neighbours have moved.
//!
//! What it cannot repair is left and counted: where the input folds over itself (james's
//! ragged border, where a quarter to four fifths of the input triangles within two edge
//! lengths face against the closest one), no placement of the few corners nearby agrees
//! with every closest triangle.

use super::build;
use super::corners::{Corners, NIL, VKind, prev};
use super::export::Live;
use super::lines::Lines;
use super::ops::{self, Scratch};
use super::patches::tessellate::mesh_of;
use crate::geom::bvh::TriangleBvh;
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
    /// Faces still turned after it.
    pub left: usize,
    /// Of those, the faces whose corners may not move (line ends, junctions and locked
    /// vertices).
    pub left_unmovable: usize,
}

/// At most this many rounds (james: 16 faces turned, 2 left after the second round).
const MAX_ROUNDS: usize = 8;

/// The input's orientation under the face with corners `p`: the normal (not normalised) of
/// the input triangle closest to its centroid, searched from `hint`.
fn input_normal(bvh: &TriangleBvh, input: &Mesh, p: [DVec3; 3], hint: u32) -> DVec3 {
    let centroid = (p[0] + p[1] + p[2]) / 3.0;
    let start = bvh.hit_on(centroid, hint);
    let t = bvh
        .closest(centroid, Some(start))
        .map_or(hint, |h| h.triangle);
    input.triangle_cross(t as usize)
}

struct Input<'a> {
    bvh: &'a TriangleBvh<'a>,
    mesh: &'a Mesh,
    lines: &'a Lines,
}

impl Input<'_> {
    /// A face with corners `p` faces the input's way (an input triangle of zero area has no
    /// way: it does not object) and is not degenerate.
    fn agrees(&self, p: [DVec3; 3], hint: u32) -> bool {
        let n = input_normal(self.bvh, self.mesh, p, hint);
        let n = if n == DVec3::ZERO {
            (p[1] - p[0]).cross(p[2] - p[0])
        } else {
            n
        };
        ops::face_ok(p, n)
    }

    fn face_agrees(&self, c: &Corners, f: usize) -> bool {
        self.agrees(c.face_positions(f), face_hint(c, f))
    }

    fn face_badness(&self, c: &Corners, f: usize) -> usize {
        self.badness(c.face_positions(f), face_hint(c, f))
    }

    /// How much a face with corners `p` counts against a repair: 0 when it agrees, 1 when
    /// it is turned, [`DEGENERATE_WEIGHT`] when it has no area. A repair must lower the sum
    /// over the faces it changes, so it never trades turned faces for a degenerate one.
    fn badness(&self, p: [DVec3; 3], hint: u32) -> usize {
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

/// The live faces turned against the input, in index order.
fn turned_faces(c: &Corners, input: &Input) -> Vec<usize> {
    (0..c.face_count())
        .into_par_iter()
        .filter(|&f| !c.face_dead[f] && !input.face_agrees(c, f))
        .collect()
}

/// Runs the pass (see the module's documentation).
pub fn repair(
    c: &mut Corners,
    lines: &Lines,
    bvh: &TriangleBvh,
    mesh: &Mesh,
    sc: &mut Scratch,
) -> Repairs {
    let input = Input { bvh, mesh, lines };
    let mut turned = turned_faces(c, &input);
    let mut r = Repairs {
        turned: turned.len(),
        ..Repairs::default()
    };
    let mut pass = Pass {
        input,
        sc,
        hs: Vec::new(),
        moved: Vec::new(),
    };
    for _ in 0..MAX_ROUNDS {
        pass.moved.clear();
        for &f in &turned {
            if c.face_dead[f] || pass.input.face_agrees(c, f) {
                continue;
            }
            if pass.try_flips(c, f) {
                r.flips += 1;
            } else if pass.try_moves(c, f) {
                r.moves += 1;
            } else if pass.try_collapses(c, f) {
                r.collapses += 1;
            }
        }
        if pass.moved.is_empty() {
            break;
        }
        // Only the faces around a changed vertex can have changed their agreement.
        let mut candidates = turned;
        for &v in &pass.moved {
            if !c.vertex_dead[v as usize] {
                c.fan(v, &mut pass.hs);
                candidates.extend(pass.hs.iter().map(|&h| (h / 3) as usize));
            }
        }
        candidates.sort_unstable();
        candidates.dedup();
        turned = candidates
            .into_iter()
            .filter(|&f| !c.face_dead[f] && !pass.input.face_agrees(c, f))
            .collect();
        if turned.is_empty() {
            break;
        }
    }
    r.left = turned.len();
    r.left_unmovable = turned
        .iter()
        .filter(|&&f| (0..3).all(|i| !movable(c, c.vtx[3 * f + i])))
        .count();
    r
}

/// The pass on a mesh `patches` made from `input` (closed, without texture coordinates;
/// `triangle_origins` index `input`). Only where the pass changed something is the mesh
/// rebuilt: its faces keep their origins, a flipped pair those of its two old faces.
pub fn repair_mesh(input: &Mesh, out: Mesh) -> (Mesh, Repairs) {
    let topo = Topology::new(&out);
    let lines = Lines::new(&out, &topo, None);
    let mut c = build::build(&out, &topo, &lines);
    // `build` points each vertex at a face of `out`; the pass wants input triangles.
    for t in c.vtri.iter_mut() {
        *t = out.triangle_origin(*t as usize);
    }
    let bvh = TriangleBvh::new(input, (0..input.triangles.len() as u32).collect());
    let r = repair(&mut c, &lines, &bvh, input, &mut Scratch::default());
    if r.flips + r.moves + r.collapses == 0 {
        return (out, r);
    }
    let live = Live::of(&c);
    let positions = live.vertices.iter().map(|&v| c.pos[v as usize]).collect();
    let triangles = live
        .faces
        .iter()
        .map(|&f| (live.triangle(&c, f), out.triangle_origin(f)))
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
}

impl Pass<'_> {
    /// Flips the first edge of face `f` whose two new faces disagree with the input less
    /// than the two old ones.
    fn try_flips(&mut self, c: &mut Corners, f: usize) -> bool {
        for h in (3 * f as u32)..(3 * f as u32 + 3) {
            let g = c.opp[h as usize];
            if g == NIL || !ops::can_flip_topologically(c, h, self.sc) {
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
    /// disagree with the input: a free vertex to the input's closest point to the centroid
    /// of its fan or to itself, or halfway to the first; a line vertex to the point of its
    /// line closest to the middle of its two line neighbours, or halfway there.
    fn try_moves(&mut self, c: &mut Corners, f: usize) -> bool {
        (0..3).any(|i| {
            let v = c.vtx[3 * f + i];
            let done = match c.kind[v as usize] {
                _ if c.locked[v as usize] => false,
                VKind::Free => self.try_free_move(c, v),
                VKind::Line => self.try_line_move(c, v),
                VKind::Corner => false,
            };
            if done {
                self.moved.push(v);
            }
            done
        })
    }

    fn try_line_move(&mut self, c: &mut Corners, v: u32) -> bool {
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
        let (on_line, seg) = lines.project(0.5 * (c.pos[x as usize] + c.pos[y as usize]), seg);
        for target in [on_line, lines.project(0.5 * (here + on_line), seg).0] {
            if self.disagreements(c, v, target, None) < before {
                c.pos[v as usize] = target;
                c.vseg[v as usize] = seg;
                return true;
            }
        }
        false
    }

    fn try_free_move(&mut self, c: &mut Corners, v: u32) -> bool {
        let here = c.pos[v as usize];
        let before = self.disagreements(c, v, here, None);
        let (centroid, _) = ops::fan_centroid(c, v, self.sc);
        let hint = c.vtri[v as usize];
        let bvh = self.input.bvh;
        for (query, halfway) in [(centroid, false), (centroid, true), (here, false)] {
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
