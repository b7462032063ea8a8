//! The three local operations on the working mesh and the checks that keep the
//! decimation's guarantees: no face turns over, no edge gets a third face (the link
//! condition, `decimate::guards::link_shape`), no zero-area face, lines stay lines.

use super::corners::{Corners, NIL, VKind, next, prev};
use super::sizing::Sizing;
use crate::ops::decimate::guards::{
    DEGENERATE_QUALITY, LinkScratch, LinkShape, link_shape, quality,
};
use glam::DVec3;

/// Scratch reused by the operations so that the passes do not allocate.
#[derive(Debug, Default)]
pub struct Scratch {
    hs: Vec<u32>,
    link: Vec<(u32, u32)>,
    link_scratch: LinkScratch,
}

fn q(p: [DVec3; 3]) -> f64 {
    quality(p[0].to_array(), p[1].to_array(), p[2].to_array())
}

/// A face with corners `p` is too thin to have an orientation (the rule of [`face_ok`]).
pub fn degenerate(p: [DVec3; 3]) -> bool {
    q(p) <= DEGENERATE_QUALITY
}

/// A face with corners `p` may replace one whose (unnormalised) normal was `before`: it
/// does not turn by more than 90° and is not degenerate.
pub fn face_ok(p: [DVec3; 3], before: DVec3) -> bool {
    let n = (p[1] - p[0]).cross(p[2] - p[0]);
    n.dot(before) > 0.0 && !degenerate(p)
}

/// Splits the edge of half-edge `h` at `m` (a point of the edge, or of its line for a
/// constrained edge with `seg` the segment found there). Returns the new vertex.
pub fn split(c: &mut Corners, h: u32, m: DVec3, seg: u32) -> u32 {
    let g = c.opp[h as usize];
    let (a, b) = (c.vtx[h as usize], c.dest(h));
    let constrained = c.is_constrained(h);
    let kind = if constrained {
        VKind::Line
    } else {
        VKind::Free
    };
    let vtri = c.vtri[a as usize];
    let mv = c.add_vertex(m, kind, seg, vtri);
    let hseg = if constrained { seg } else { NIL };
    let f3 = split_side(c, h, mv);
    c.seg[h as usize] = hseg;
    c.seg[f3 as usize] = hseg;
    if g == NIL {
        c.fix_out(mv, f3);
    } else {
        let f4 = split_side(c, g, mv);
        c.seg[g as usize] = hseg;
        c.seg[f4 as usize] = hseg;
        // h: a→m, f4: m→a; g: b→m, f3: m→b.
        c.link(h, f4);
        c.link(g, f3);
        c.fix_out(mv, f3);
    }
    c.fix_out(b, next(f3));
    c.fix_out(a, h);
    mv
}

/// Splits the face of `h` (x→y, third vertex z) at the new vertex `m` on x→y: the face
/// becomes (x, m, z) and a new face (m, y, z) is added. Returns the new face's first
/// half-edge (m→y).
fn split_side(c: &mut Corners, h: u32, m: u32) -> u32 {
    let (y, z) = (c.dest(h), c.vtx[prev(h) as usize]);
    let hn = next(h);
    let o_yz = c.opp[hn as usize];
    let seg_yz = c.seg[hn as usize];
    c.vtx[hn as usize] = m;
    let f = c.add_face([m, y, z], (h / 3) as usize);
    // New face: f: m→y, f+1: y→z, f+2: z→m.
    c.link(f + 1, o_yz);
    c.seg[(f + 1) as usize] = seg_yz;
    c.seg[hn as usize] = NIL;
    c.link(hn, f + 2);
    f
}

/// Whether `a` may go into `b` by collapsing the edge of `h` (either half-edge of a–b),
/// under the split bound of `sizing` for the edges that `b` then has.
pub fn can_collapse(
    c: &Corners,
    h: u32,
    a: u32,
    b: u32,
    sizing: &Sizing,
    sc: &mut Scratch,
) -> bool {
    if !may_go(c, h, a, b) {
        return false;
    }
    // The length bound first: one ring walk, and it rejects most candidates.
    let pb = c.pos[b as usize];
    if c.neighbours(a)
        .any(|x| x != b && c.pos[x as usize].distance_squared(pb) > sizing.hi(x, b).powi(2))
    {
        return false;
    }
    removed_sides_ok(c, h) && link_ok(c, a, b, sc) && faces_ok(c, a, b)
}

/// The checks of [`can_collapse`] that do not look at positions: [`may_go`], the removed
/// faces' sides and the link condition.
pub fn can_collapse_topologically(c: &Corners, h: u32, a: u32, b: u32, sc: &mut Scratch) -> bool {
    may_go(c, h, a, b) && removed_sides_ok(c, h) && link_ok(c, a, b, sc)
}

/// Neither vertex locked, and `a` free to go along `h`: a line vertex only along its line,
/// a border vertex only along the border.
fn may_go(c: &Corners, h: u32, a: u32, b: u32) -> bool {
    if c.locked[a as usize] || c.locked[b as usize] || c.kind[a as usize] == VKind::Corner {
        return false;
    }
    // Along a constrained edge anything may go; off one, only a free vertex inside.
    c.is_constrained(h) || (c.kind[a as usize] != VKind::Line && !c.is_border_vertex(a))
}

/// [`sides_ok`] for both faces the collapse of `h` removes.
fn removed_sides_ok(c: &Corners, h: u32) -> bool {
    let g = c.opp[h as usize];
    sides_ok(c, h) && (g == NIL || sides_ok(c, g))
}

/// A face removed by a collapse: its two other edges are not both constrained (they
/// become one edge) and not both borders, and its third vertex keeps at least three
/// neighbours.
fn sides_ok(c: &Corners, h: u32) -> bool {
    let (n, p) = (next(h), prev(h));
    if c.is_constrained(n) && c.is_constrained(p) {
        return false;
    }
    let x = c.vtx[p as usize];
    let neighbours = c.neighbours(x).count();
    neighbours > 3 || (c.is_border_vertex(x) && neighbours > 2)
}

/// The link condition after merging: the faces around the merged vertex form one disk or
/// one half-disk (`decimate::guards::link_shape`).
fn link_ok(c: &Corners, a: u32, b: u32, sc: &mut Scratch) -> bool {
    sc.link.clear();
    for v in [a, b] {
        for h in c.fan_iter(v) {
            let (x, y) = (c.dest(h), c.vtx[prev(h) as usize]);
            if x == a || x == b || y == a || y == b {
                continue;
            }
            sc.link.push((x, y));
        }
    }
    let border = c.is_border_vertex(a) || c.is_border_vertex(b);
    match link_shape(&sc.link, &mut sc.link_scratch) {
        Some(LinkShape::Cycle) => !border,
        Some(LinkShape::Path) => border,
        None => false,
    }
}

/// Every face of `a` that stays keeps its orientation and area with `a` at `b`'s place.
fn faces_ok(c: &Corners, a: u32, b: u32) -> bool {
    let pb = c.pos[b as usize];
    c.fan_iter(a).all(|h| {
        let (x, y) = (c.dest(h), c.vtx[prev(h) as usize]);
        if x == b || y == b {
            return true;
        }
        let before = c.face_cross((h / 3) as usize);
        face_ok([pb, c.pos[x as usize], c.pos[y as usize]], before)
    })
}

/// Collapses `a` into `b` along `h` (either half-edge of a–b); [`can_collapse`] said yes.
pub fn collapse(c: &mut Corners, h: u32, a: u32, b: u32, sc: &mut Scratch) {
    let g = c.opp[h as usize];
    c.fan(a, &mut sc.hs);
    for &k in &sc.hs {
        c.vtx[k as usize] = b;
    }
    remove_face(c, h);
    if g != NIL {
        remove_face(c, g);
    }
    c.vertex_dead[a as usize] = true;
}

/// Removes the face of `h` and glues its two other edges into one. Fixes `out` of the
/// vertices that keep faces.
fn remove_face(c: &mut Corners, h: u32) {
    let (n, p) = (next(h), prev(h));
    let across = c.opp[h as usize];
    if across != NIL && c.opp[across as usize] == h {
        c.opp[across as usize] = NIL;
    }
    let (o1, o2) = (c.opp[n as usize], c.opp[p as usize]);
    let seg = if c.seg[n as usize] != NIL {
        c.seg[n as usize]
    } else {
        c.seg[p as usize]
    };
    let x = c.vtx[p as usize];
    let b = c.vtx[n as usize];
    c.link(o1, o2);
    for o in [o1, o2] {
        if o != NIL {
            c.seg[o as usize] = seg;
        }
    }
    c.face_dead[(h / 3) as usize] = true;
    for k in [h, n, p] {
        c.opp[k as usize] = NIL;
    }
    // o1 runs x→b, o2 runs b→x (b is already the merged vertex).
    let (hx, hb) = if o1 != NIL {
        (o1, next(o1))
    } else {
        (next(o2), o2)
    };
    c.fix_out(x, hx);
    c.fix_out(b, hb);
}

/// Whether flipping the edge of `h` (a→b, faces a b c and b a d) to c–d is allowed, and
/// the two new faces are fine.
pub fn can_flip(c: &Corners, h: u32) -> bool {
    if !can_flip_topologically(c, h) {
        return false;
    }
    let g = c.opp[h as usize];
    let (a, b) = (c.vtx[h as usize], c.dest(h));
    let (cc, d) = (c.vtx[prev(h) as usize], c.vtx[prev(g) as usize]);
    let (pa, pb, pc, pd) = (
        c.pos[a as usize],
        c.pos[b as usize],
        c.pos[cc as usize],
        c.pos[d as usize],
    );
    let (n1, n2) = (
        c.face_cross((h / 3) as usize),
        c.face_cross((g / 3) as usize),
    );
    let before = n1.normalize_or_zero() + n2.normalize_or_zero();
    face_ok([pc, pa, pd], before)
        && face_ok([pd, pb, pc], before)
        && face_ok([pc, pa, pd], n1)
        && face_ok([pd, pb, pc], n2)
}

/// Whether the edge of `h` (a→b, faces a b c and b a d) is free, its four vertices are not
/// locked, and c–d is not an edge already (the flip would make it non-manifold).
pub fn can_flip_topologically(c: &Corners, h: u32) -> bool {
    if c.is_constrained(h) {
        return false;
    }
    let g = c.opp[h as usize];
    let (a, b) = (c.vtx[h as usize], c.dest(h));
    let (cc, d) = (c.vtx[prev(h) as usize], c.vtx[prev(g) as usize]);
    if cc == d || [a, b, cc, d].iter().any(|&v| c.locked[v as usize]) {
        return false;
    }
    !c.neighbours(cc).any(|x| x == d)
}

/// Flips the edge of `h` (a→b, faces a b c and b a d) to c–d; [`can_flip`] said yes.
pub fn flip(c: &mut Corners, h: u32) {
    let g = c.opp[h as usize];
    let (a, b) = (c.vtx[h as usize], c.dest(h));
    let (cc, d) = (c.vtx[prev(h) as usize], c.vtx[prev(g) as usize]);
    let (hn, hp, gn, gp) = (next(h), prev(h), next(g), prev(g));
    // Outer edges: b→c (hn), c→a (hp), a→d (gn), d→b (gp).
    let (o_bc, o_ca, o_ad, o_db) = (
        c.opp[hn as usize],
        c.opp[hp as usize],
        c.opp[gn as usize],
        c.opp[gp as usize],
    );
    let (s_bc, s_ca, s_ad, s_db) = (
        c.seg[hn as usize],
        c.seg[hp as usize],
        c.seg[gn as usize],
        c.seg[gp as usize],
    );
    // Face of h becomes (c, a, d): h: c→a, hn: a→d, hp: d→c.
    // Face of g becomes (d, b, c): g: d→b, gn: b→c, gp: c→d.
    c.vtx[h as usize] = cc;
    c.vtx[hn as usize] = a;
    c.vtx[hp as usize] = d;
    c.vtx[g as usize] = d;
    c.vtx[gn as usize] = b;
    c.vtx[gp as usize] = cc;
    c.link(h, o_ca);
    c.seg[h as usize] = s_ca;
    c.link(hn, o_ad);
    c.seg[hn as usize] = s_ad;
    c.link(g, o_db);
    c.seg[g as usize] = s_db;
    c.link(gn, o_bc);
    c.seg[gn as usize] = s_bc;
    c.link(hp, gp);
    c.seg[hp as usize] = NIL;
    c.seg[gp as usize] = NIL;
    c.fix_out(a, hn);
    c.fix_out(b, gn);
    c.fix_out(cc, h);
    c.fix_out(d, g);
}

/// A line vertex's two line neighbours (`None` when it does not have exactly two).
pub fn line_neighbours(c: &Corners, v: u32, sc: &mut Scratch) -> Option<[u32; 2]> {
    c.fan(v, &mut sc.hs);
    let mut found = [NIL; 2];
    let mut k = 0;
    let last = *sc.hs.last()?;
    let border_in = (c.rotate(last) == NIL).then(|| prev(last));
    for h in sc.hs.iter().copied().chain(border_in) {
        if c.is_constrained(h) {
            if k == 2 {
                return None;
            }
            found[k] = if c.vtx[h as usize] == v {
                c.dest(h)
            } else {
                c.vtx[h as usize]
            };
            k += 1;
        }
    }
    (k == 2).then_some(found)
}

/// The area-weighted centroid of the faces around `v` and their unit area-weighted normal.
pub fn fan_centroid(c: &Corners, v: u32) -> (DVec3, DVec3) {
    weighted_fan_centroid(c, v, |_| 1.0)
}

/// As [`fan_centroid`], each face weighted by its area over the square of its mean vertex
/// size (`size`), so that the centroid of a graded fan is not pulled towards its larger
/// faces (pmp-library's adaptive relaxation weights).
pub fn fan_centroid_sized(c: &Corners, v: u32, size: &[f64]) -> (DVec3, DVec3) {
    weighted_fan_centroid(c, v, |f| {
        let s = (0..3).map(|i| size[c.vtx[3 * f + i] as usize]).sum::<f64>() / 3.0;
        s * s
    })
}

/// The centroid of the faces around `v`, face f weighted by its area over `divisor(f)`, and
/// their unit area-weighted normal; `v` itself and no normal when the weights vanish.
fn weighted_fan_centroid(c: &Corners, v: u32, divisor: impl Fn(usize) -> f64) -> (DVec3, DVec3) {
    let (mut sum, mut weight, mut normal) = (DVec3::ZERO, 0.0, DVec3::ZERO);
    for h in c.fan_iter(v) {
        let f = (h / 3) as usize;
        let n = c.face_cross(f);
        let [a, b, d] = c.face_positions(f);
        let w = n.length() / divisor(f);
        sum += w * (a + b + d) / 3.0;
        weight += w;
        normal += n;
    }
    if weight > 0.0 && weight.is_finite() {
        (sum / weight, normal.normalize_or_zero())
    } else {
        (c.pos[v as usize], DVec3::ZERO)
    }
}

/// The worst shape quality (`decimate::guards::quality`) of `v`'s faces with `v` at `p`.
pub fn fan_min_quality(c: &Corners, v: u32, p: DVec3) -> f64 {
    c.fan_iter(v)
        .map(|h| {
            q([
                p,
                c.pos[c.dest(h) as usize],
                c.pos[c.vtx[prev(h) as usize] as usize],
            ])
        })
        .fold(f64::INFINITY, f64::min)
}

/// Moving `v` to `p` keeps every face around it facing the way it faced and not degenerate.
pub fn fan_keeps_orientation(c: &Corners, v: u32, p: DVec3) -> bool {
    c.fan_iter(v).all(|h| {
        let (x, y) = (c.dest(h), c.vtx[prev(h) as usize]);
        let before = c.face_cross((h / 3) as usize);
        face_ok([p, c.pos[x as usize], c.pos[y as usize]], before)
    })
}
