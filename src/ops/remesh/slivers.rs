//! After the repair pass of `isotropic`: slivers inside the surface.
//!
//! Issue #24 asks for no triangle with an angle below 10° except where a border or seam
//! forces it. The rounds leave nearly none: a needle (one short edge) is collapsed as too
//! short, a cap (one angle near 180°) is flipped by the angle flips. What they can leave
//! sits where the input folds over itself, and there the fit and the repair pass move
//! vertices after the last flips. On james (uniform, 1 %, 3 iterations) one face of 6.9°
//! was left: its short edge (0.58, 0.14 L) is an input edge whose two input triangles face
//! 165° apart, kept by the remesh with both ends where the input has them, between a vertex
//! of valence 4 and one of valence 9. Its collapse one way breaks the link condition (the
//! ends share a third neighbour), the other way makes an edge longer than the split length;
//! flipping the short edge, flipping the third neighbour's edge away and collapsing, or
//! removing the valence-4 vertex would each lay a face across the fold, against the input;
//! and the relaxation's place for either end turned a face over (docs/remeshing.md,
//! "Slivers inside the surface").
//!
//! This pass takes the faces with a smallest angle under [`SLIVER_ANGLE`] whose three
//! corners are free (on no border, seam or other line: a line vertex may not leave its line,
//! and a thin face there is the line's), and gives each the first of these remedies after
//! which the faces it changes have a larger smallest angle than they had:
//!
//! 1. flip one of its edges, the longest first (a cap);
//! 2. collapse its shortest edge, either way (a needle);
//! 3. move one of its corners on the input: to the place, among a few around it, that
//!    raises the smallest angle of its faces most (optimisation-based smoothing, Freitag &
//!    Ollivier-Gooch 1997, tried at a few points rather than solved): where the input folds,
//!    a needle's short edge can grow along the fold where it cannot across it.
//!
//! Each under the remesher's guards ([`ops::can_flip`], [`ops::can_collapse`],
//! [`ops::fan_keeps_orientation`]: no face turned over or degenerate, no edge with a third
//! face, no edge longer than the split length, lines untouched) and the repair pass's: the
//! faces it changes do not disagree with the input more than before ([`Input::badness`]),
//! so no face turns against the input. The faces are taken in index order, one at a time:
//! the output does not depend on the thread count. After the first scan only the faces next
//! to a change are looked at again.

use super::PIECE;
use super::corners::{Corners, NIL, VKind, prev};
use super::ops::{self, Scratch};
use super::quality::min_angle;
use super::repair::{Input, Mending, mend_in_rounds};
use super::sizing::Sizing;
use crate::geom::bvh::TriangleHit;
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

/// Issue #24's bar: no smallest angle below this (degrees) away from borders and seams.
pub const SLIVER_ANGLE: f64 = 10.0;

/// At most this many rounds: a remedy raises the smallest angle of the faces it changes
/// but can leave one of them under the bar, which the next round takes. A move to one of a
/// few places may raise a needle's angle only a little at a time: four rounds left one on
/// james adaptive (docs/remeshing.md, "The input in Morton order").
const MAX_ROUNDS: usize = 8;

/// What the pass did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Slivers {
    /// Faces under [`SLIVER_ANGLE`] with three free corners before the pass.
    pub found: usize,
    pub flips: usize,
    pub collapses: usize,
    pub moves: usize,
    /// Such faces after it (a remedy needs a change that raises the smallest angle and
    /// turns no face; on the esp32cam scan, 25 of 60 at 1 %, crumpled photogrammetry).
    pub left: usize,
}

/// A vertex on no line that may move and go: free, not locked, not on a border.
fn free(c: &Corners, v: u32) -> bool {
    c.kind[v as usize] == VKind::Free && !c.locked[v as usize] && !c.is_border_vertex(v)
}

/// Face `f` is live, its three corners are [`free`] and its smallest angle is under
/// [`SLIVER_ANGLE`].
fn is_sliver(c: &Corners, f: usize) -> bool {
    !c.face_dead[f] && thin(c.face_positions(f)) && (0..3).all(|i| free(c, c.vtx[3 * f + i]))
}

/// The smallest angle of the triangle with corners `p` is under [`SLIVER_ANGLE`] (one with
/// two corners at one place reads 0°, as with [`min_angle`]): the angle opposite the
/// shortest edge has a cosine above the bar's. Without the arc cosine: the scan of every
/// face costs 0.6 ms on james with it and 1.0 ms with [`min_angle`] (one thread).
fn thin(p: [DVec3; 3]) -> bool {
    let opposite = |k: usize| p[(k + 1) % 3].distance_squared(p[(k + 2) % 3]);
    let k = (1..3).fold(0, |k, j| if opposite(j) < opposite(k) { j } else { k });
    let (u, v) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
    let (dot, lengths) = (u.dot(v), u.length_squared() * v.length_squared());
    lengths == 0.0 || (dot > 0.0 && dot * dot > COS_SQUARED * lengths)
}

/// cos² of [`SLIVER_ANGLE`] (`cos` is not `const`).
const COS_SQUARED: f64 = 0.969_846_310_392_954_2;

/// The smallest angle of the faces with corners `faces` (degrees).
fn smallest(faces: &[[DVec3; 3]]) -> f64 {
    faces
        .iter()
        .map(|&p| min_angle(p))
        .fold(f64::INFINITY, f64::min)
}

/// Runs the pass (see the module's documentation).
pub(super) fn clean(c: &mut Corners, input: &Input, sizing: &Sizing, sc: &mut Scratch) -> Slivers {
    let found: Vec<usize> = (0..c.face_count())
        .into_par_iter()
        .with_max_len(PIECE)
        .filter(|&f| is_sliver(c, f))
        .collect();
    let mut pass = Pass {
        input,
        sizing,
        sc,
        hs: Vec::new(),
        changed: Vec::new(),
        r: Slivers {
            found: found.len(),
            ..Slivers::default()
        },
    };
    let left = mend_in_rounds(&mut pass, c, found, MAX_ROUNDS);
    Slivers {
        left: left.len(),
        ..pass.r
    }
}

/// One pass's working state.
struct Pass<'a> {
    input: &'a Input<'a>,
    sizing: &'a Sizing,
    sc: &'a mut Scratch,
    hs: Vec<u32>,
    /// Vertices whose faces a remedy of this round changed.
    changed: Vec<u32>,
    r: Slivers,
}

impl Mending for Pass<'_> {
    fn needs(&self, c: &Corners, f: usize) -> bool {
        is_sliver(c, f)
    }

    fn try_face(&mut self, c: &mut Corners, f: usize) {
        if self.try_flips(c, f) {
            self.r.flips += 1;
        } else if self.try_collapse(c, f) {
            self.r.collapses += 1;
        } else if self.try_moves(c, f) {
            self.r.moves += 1;
        }
    }

    fn changed(&mut self) -> (&mut Vec<u32>, &mut Vec<u32>) {
        (&mut self.changed, &mut self.hs)
    }
}

/// Faces as they were before a change: their corners and how much they disagreed with the
/// input ([`Input::badness`], summed).
struct Before {
    positions: Vec<[DVec3; 3]>,
    badness: usize,
}

impl Pass<'_> {
    /// Faces `faces` as they are now.
    fn before(&self, c: &Corners, faces: impl Iterator<Item = usize>) -> Before {
        let (mut positions, mut badness) = (Vec::new(), 0);
        for f in faces {
            positions.push(c.face_positions(f));
            badness += self.input.face_badness(c, f);
        }
        Before { positions, badness }
    }

    /// The faces around `v` as they are now.
    fn fan_before(&mut self, c: &Corners, v: u32) -> Before {
        c.fan(v, &mut self.hs);
        let hs = std::mem::take(&mut self.hs);
        let before = self.before(c, hs.iter().map(|&h| (h / 3) as usize));
        self.hs = hs;
        before
    }

    /// The change from faces `old` to faces with corners `new` (searched for their input
    /// triangles from `hint`) is kept: it raises the smallest angle, and the new faces
    /// disagree with the input no more than the old ones did.
    fn better(&self, old: &Before, new: &[[DVec3; 3]], hint: u32) -> bool {
        if smallest(new) <= smallest(&old.positions) {
            return false;
        }
        let after: usize = new.iter().map(|&p| self.input.badness(p, hint)).sum();
        after <= old.badness
    }

    /// Flips the first edge of face `f`, longest first, whose two new faces are
    /// [`Pass::better`] than the two old ones: a cap's long edge, where the angle flips
    /// (which flip towards the pair whose opposite angles sum to less than π) left it.
    fn try_flips(&mut self, c: &mut Corners, f: usize) -> bool {
        for h in by_length(c, f).into_iter().rev() {
            let g = c.opp[h as usize];
            if g == NIL || !ops::can_flip(c, h) {
                continue;
            }
            let (a, b) = (c.vtx[h as usize], c.dest(h));
            let (cc, d) = (c.vtx[prev(h) as usize], c.vtx[prev(g) as usize]);
            let p = |v: u32| c.pos[v as usize];
            let new = [[p(cc), p(a), p(d)], [p(d), p(b), p(cc)]];
            let old = self.before(c, [f, (g / 3) as usize].into_iter());
            if self.better(&old, &new, c.vtri[cc as usize]) {
                ops::flip(c, h);
                self.changed.extend([a, b, cc, d]);
                return true;
            }
        }
        false
    }

    /// Collapses the shortest edge of face `f`, either way, when the remesher's collapse
    /// allows it and the faces that stay are [`Pass::better`] than the going end's faces.
    fn try_collapse(&mut self, c: &mut Corners, f: usize) -> bool {
        let h = by_length(c, f)[0];
        let (a, b) = (c.vtx[h as usize], c.dest(h));
        for (x, y) in [(a, b), (b, a)] {
            if !ops::can_collapse(c, h, x, y, self.sizing, self.sc) {
                continue;
            }
            let old = self.fan_before(c, x);
            if self.better(&old, &collapsed(c, x, y), c.vtri[y as usize]) {
                ops::collapse(c, h, x, y, self.sc);
                self.changed.push(y);
                return true;
            }
        }
        false
    }

    /// Moves one corner of face `f` to the place that raises the smallest angle of its
    /// faces most, among the input's closest points to its fan's centroid and to the
    /// points [`STEP`] of the way towards and away from each of its neighbours: where the
    /// input folds, the relaxation's one place (the centroid) can turn a face over, and a
    /// needle's short edge may need to grow along the fold rather than across it. Kept
    /// only when no face around it turns over or becomes degenerate
    /// ([`ops::fan_keeps_orientation`]) and they disagree with the input no more than
    /// before. On the input, as after a round's projection (the fit's offset, a few
    /// thousandths of a per cent of the diagonal, is given up at that one vertex).
    fn try_moves(&mut self, c: &mut Corners, f: usize) -> bool {
        let bvh = self.input.bvh;
        let mut ring = Vec::new();
        // (smallest angle after, vertex, hit)
        let mut best: Option<(f64, u32, TriangleHit)> = None;
        for i in 0..3 {
            let v = c.vtx[3 * f + i];
            let here = c.pos[v as usize];
            let old = self.fan_before(c, v);
            let floor = smallest(&old.positions);
            c.ring(v, &mut ring);
            let (centroid, _) = ops::fan_centroid(c, v);
            let queries = ring.iter().flat_map(|&u| {
                let there = c.pos[u as usize];
                [here.lerp(there, STEP), here.lerp(there, -STEP)]
            });
            for query in std::iter::once(centroid).chain(queries) {
                let hint = c.vtri[v as usize];
                let Some(hit) = bvh.closest(query, Some(bvh.hit_on(query, hint))) else {
                    continue;
                };
                let new: Vec<[DVec3; 3]> = c
                    .fan_iter(v)
                    .map(|h| {
                        let (x, y) = (c.dest(h), c.vtx[prev(h) as usize]);
                        [hit.point, c.pos[x as usize], c.pos[y as usize]]
                    })
                    .collect();
                let angle = smallest(&new);
                if angle <= floor.max(best.map_or(0.0, |b| b.0))
                    || !ops::fan_keeps_orientation(c, v, hit.point)
                {
                    continue;
                }
                let after: usize = new
                    .iter()
                    .map(|&p| self.input.badness(p, hit.triangle))
                    .sum();
                if after <= old.badness {
                    best = Some((angle, v, hit));
                }
            }
        }
        let Some((_, v, hit)) = best else {
            return false;
        };
        c.pos[v as usize] = hit.point;
        c.vtri[v as usize] = hit.triangle;
        self.changed.push(v);
        true
    }
}

/// How far towards or away from a neighbour a move of [`Pass::try_moves`] looks (the
/// repair pass's far moves look as far towards each neighbour).
const STEP: f64 = 0.3;

/// The half-edges of face `f`, shortest edge first.
fn by_length(c: &Corners, f: usize) -> [u32; 3] {
    let length = |h: u32| c.pos[c.vtx[h as usize] as usize].distance(c.pos[c.dest(h) as usize]);
    let mut hs = [0, 1, 2].map(|i| 3 * f as u32 + i);
    hs.sort_by(|&g, &h| length(g).total_cmp(&length(h)));
    hs
}

/// The faces that stay when `x` goes into `y`: those of `x` without `y`, with `y`'s
/// position for `x`'s.
fn collapsed(c: &Corners, x: u32, y: u32) -> Vec<[DVec3; 3]> {
    let py = c.pos[y as usize];
    c.fan_iter(x)
        .filter_map(|h| {
            let (u, w) = (c.dest(h), c.vtx[prev(h) as usize]);
            (u != y && w != y).then(|| [py, c.pos[u as usize], c.pos[w as usize]])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::surface::rng;
    use rand::RngExt;

    /// [`thin`] says what [`min_angle`] says about the bar, on random triangles, needles
    /// and caps among them, and on triangles with corners at one place.
    #[test]
    fn thin_agrees_with_the_smallest_angle() {
        let mut r = rng(11);
        let mut point = |spread: f64| {
            DVec3::new(
                r.random_range(-1.0..1.0),
                spread * r.random_range(-1.0..1.0),
                0.0,
            )
        };
        let mut thin_ones = 0;
        for i in 0..20_000 {
            let spread = [1.0, 0.1, 0.01][i % 3];
            let p = [point(spread), point(spread), point(spread)];
            let angle = min_angle(p);
            if (angle - SLIVER_ANGLE).abs() > 1e-9 {
                assert_eq!(thin(p), angle < SLIVER_ANGLE, "{p:?}: {angle}");
                thin_ones += usize::from(angle < SLIVER_ANGLE);
            }
        }
        assert!(thin_ones > 1000, "{thin_ones}");
        let (o, x) = (DVec3::ZERO, DVec3::X);
        assert!(thin([o, o, x]) && thin([x, x, x]));
        assert!((COS_SQUARED - SLIVER_ANGLE.to_radians().cos().powi(2)).abs() < 1e-15);
    }
}
