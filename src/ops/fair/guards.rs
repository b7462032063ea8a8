//! Guards against the failures the thesis reports or implies (docs/fairing.md, reading F8):
//! which vertices stay fixed (non-manifold, creases, very high valence), and the check
//! that a move neither flips a triangle nor makes a zero-area or needle triangle (a move
//! that would is shortened, then skipped, and counted).

use super::neighbourhood::Neighbourhood;
use super::positive;
use crate::mesh::{Mesh, Topology};
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use serde::Serialize;

/// Quality `4√3·area / Σ edge²` (1 for an equilateral triangle, 0 for a degenerate one)
/// below which a move may not push a triangle, unless it improves it.
pub const MIN_QUALITY: f64 = 0.05;

/// How far a step may turn a triangle with a boundary vertex from its own orientation at
/// the start of the step. The boundary curves are faired in 3D without regard to the
/// surface and swing border triangles round, and at a border the surroundings are few
/// triangles that swing with them: measured on james.obj and the ggg_sfm scans, relax +
/// fair turned 23 to 27 border triangles over without this limit.
pub const BORDER_TILT_DEGREES: f64 = 45.0;
const BORDER_TILT_COS: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// What a triangle may not turn away from during a step (see [`check_triangle`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Reference {
    /// The direction of the surface around it at the start of the step (zero = unknown).
    /// Unit vectors in f32: only directions are compared, and one Reference per triangle
    /// of a 400k-triangle scan is 11 MB instead of 22 MB in f64 (issue #8's memory budget).
    pub around: Vec3,
    /// Its own normal direction at the start of the step.
    pub own: Vec3,
    /// It has a boundary vertex: [`BORDER_TILT_DEGREES`] from `own` at most.
    pub border: bool,
}

impl Reference {
    pub fn new(around: DVec3, own: DVec3, border: bool) -> Self {
        Reference {
            around: around.normalize_or_zero().as_vec3(),
            own: own.normalize_or_zero().as_vec3(),
            border,
        }
    }
}

/// Why the vertices that stay fixed do.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct FixedCounts {
    /// No single fan (pinch, bowtie, non-manifold edge) or a triangle repeating a vertex:
    /// the thesis assumes a manifold (§1.2.1; docs/fairing.md reading F8).
    pub non_manifold: usize,
    /// On an edge sharper than `feature_angle`.
    pub crease: usize,
    /// Valence above the limit, and their neighbours (the vase that lost its top, §3.8.1;
    /// reading F8).
    pub high_valence: usize,
    /// Boundary vertices held because `boundary = "fixed"`, because their boundary walk is
    /// open or shorter than 3 vertices, or because they are the ends of an open walk.
    pub boundary: usize,
}

/// The default valence limit: 2.5 × the median valence of manifold interior vertices, at
/// least 12. The vase's hub had about 5× the typical valence; face scans range from 3 to 30
/// (§4.6.3), and a limit that low only fixes the few extreme hubs.
pub fn default_valence_limit(nb: &Neighbourhood) -> u32 {
    let mut valences: Vec<u32> = (0..nb.vertex_count())
        .filter(|&v| nb.is_closed(v))
        .map(|v| nb.ring(v).len() as u32)
        .collect();
    if valences.is_empty() {
        return 12;
    }
    let mid = valences.len() / 2;
    let (_, median, _) = valences.select_nth_unstable(mid);
    ((*median as f64 * 2.5).ceil() as u32).max(12)
}

/// Marks vertices on edges whose dihedral angle exceeds `feature_angle` degrees
/// (the angle between the two face normals, 0 for a flat edge).
pub fn crease_vertices(mesh: &Mesh, topo: &Topology, feature_angle: f64) -> Vec<bool> {
    let mut crease = vec![false; mesh.positions.len()];
    let cos_limit = feature_angle.to_radians().cos();
    for e in 0..topo.edge_count() as u32 {
        let mut tris = topo.edge_triangles(e);
        if tris.len() != 2 {
            continue;
        }
        let (t0, t1) = (tris.next().unwrap(), tris.next().unwrap());
        let (n0, n1) = (
            mesh.triangle_cross(t0 as usize),
            mesh.triangle_cross(t1 as usize),
        );
        let denom = n0.length() * n1.length();
        if !positive(denom) {
            continue;
        }
        // On an inconsistently oriented edge one normal is reversed.
        let sign = if topo.is_inconsistent_edge(e) {
            -1.0
        } else {
            1.0
        };
        if sign * n0.dot(n1) / denom < cos_limit {
            for v in topo.edge_vertices(e) {
                crease[v as usize] = true;
            }
        }
    }
    crease
}

/// What a proposed move would do to a triangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MoveCheck {
    Ok,
    /// The normal would turn by more than 90° in this one move.
    Flip,
    /// The triangle would fall below [`MIN_QUALITY`] (and get worse): zero-area, needle.
    Degenerate,
}

/// Squared quality, `(4√3·area / Σ edge²)² = 12 |N|² / (Σ edge²)²` from the cross product
/// `N` and the corners (no square root: this runs for every triangle every iteration).
#[inline]
fn quality_squared(cross: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let sum = (b - a).length_squared() + (c - b).length_squared() + (a - c).length_squared();
    if sum > 0.0 {
        12.0 * cross.length_squared() / (sum * sum)
    } else {
        0.0
    }
}

/// Checks triangle `(a, b, c)` → `(a2, b2, c2)`. No triangle turns by more than 90°: not
/// in the single move, nor from its own orientation at the start of the step (so no
/// sequence of small moves turns it over either). A triangle facing the same side as the
/// surface around it at the start of the step (see [`triangle_references`]) may not come
/// to face away from it, which keeps later steps from turning it further (a fold, facing
/// away at the start, may turn back). A border triangle may not turn more than
/// [`BORDER_TILT_DEGREES`] from where it started.
#[inline]
pub fn check_triangle(old: [DVec3; 3], new: [DVec3; 3], reference: Reference) -> MoveCheck {
    check_crosses(cross_of(old), || old, cross_of(new), new, reference)
}

/// A triangle's cross product `(b − a) × (c − a)`: twice its area along its normal.
#[inline]
pub fn cross_of([a, b, c]: [DVec3; 3]) -> DVec3 {
    (b - a).cross(c - a)
}

/// [`check_triangle`] given both cross products ([`cross_of`]) of the triangle, `n_old` at
/// `old` and `n_new` at `new`: the same rule, for callers that keep the cross products
/// from one iteration to the next. `old` is asked for only when the new triangle is a
/// needle (the quality is compared).
#[inline]
pub fn check_crosses(
    n_old: DVec3,
    old: impl FnOnce() -> [DVec3; 3],
    n_new: DVec3,
    new: [DVec3; 3],
    reference: Reference,
) -> MoveCheck {
    if n_old.length_squared() > 0.0 && n_new.dot(n_old) < 0.0 {
        return MoveCheck::Flip;
    }
    if within_cone(n_old, reference) && !within_cone(n_new, reference) {
        return MoveCheck::Flip;
    }
    let own = reference.own.as_dvec3();
    if own.dot(n_new) < 0.0 || (reference.border && !within_border_cone(n_new, own)) {
        return MoveCheck::Flip;
    }
    let q_new = quality_squared(n_new, new[0], new[1], new[2]);
    if q_new < MIN_QUALITY * MIN_QUALITY {
        let [a, b, c] = old();
        if q_new < quality_squared(n_old, a, b, c) {
            return MoveCheck::Degenerate;
        }
    }
    MoveCheck::Ok
}

/// `n` faces the side of the surroundings (true when either is zero).
#[inline]
fn within_cone(n: DVec3, reference: Reference) -> bool {
    n.dot(reference.around.as_dvec3()) >= 0.0
}

/// `n` is within [`BORDER_TILT_DEGREES`] of `own` (true when either is zero).
#[inline]
fn within_border_cone(n: DVec3, own: DVec3) -> bool {
    let d = n.dot(own);
    let cos2 = BORDER_TILT_COS * BORDER_TILT_COS;
    d >= 0.0 && d * d >= cos2 * n.length_squared() * own.length_squared()
}

/// A fan as the guards see it: the ring positions, closed or open, and the references of
/// its triangles `(a, ring[i], ring[i+1])` (empty = unknown).
#[derive(Debug, Clone, Copy)]
pub struct Fan<'a> {
    pub ring: &'a [DVec3],
    pub closed: bool,
    pub references: &'a [Reference],
}

/// Checks moving the centre of a fan from `old` to `new`, its ring held still.
pub fn check_fan(old: DVec3, new: DVec3, fan: Fan) -> MoveCheck {
    let ring = fan.ring;
    let n = ring.len();
    let tris = if fan.closed { n } else { n.saturating_sub(1) };
    let mut worst = MoveCheck::Ok;
    for i in 0..tris {
        let (p, q) = (ring[i], ring[(i + 1) % n]);
        let reference = fan.references.get(i).copied().unwrap_or_default();
        match check_triangle([old, p, q], [new, p, q], reference) {
            MoveCheck::Ok => {}
            MoveCheck::Flip => return MoveCheck::Flip,
            MoveCheck::Degenerate => worst = MoveCheck::Degenerate,
        }
    }
    worst
}

/// How a guarded move ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Guarded {
    Full,
    /// Shortened because the full move would have flipped / degenerated a triangle.
    Shortened(MoveCheck),
    /// Skipped: even a quarter of the move was unsafe.
    Skipped(MoveCheck),
}

/// The move from `old` towards `candidate`, shortened to 1/2 or 1/4 if the full move is
/// unsafe for the fan, skipped if all are.
pub fn guarded_move(old: DVec3, candidate: DVec3, fan: Fan) -> (DVec3, Guarded) {
    if !candidate.is_finite() {
        return (old, Guarded::Skipped(MoveCheck::Degenerate));
    }
    let first = check_fan(old, candidate, fan);
    if first == MoveCheck::Ok {
        return (candidate, Guarded::Full);
    }
    for f in [0.5, 0.25] {
        let p = old + f * (candidate - old);
        if check_fan(old, p, fan) == MoveCheck::Ok {
            return (p, Guarded::Shortened(first));
        }
    }
    (old, Guarded::Skipped(first))
}

/// Counts of guarded moves.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct GuardCounts {
    /// Moves shortened or skipped because they would have flipped a triangle.
    pub flips_avoided: u64,
    /// Moves shortened or skipped because they would have made a zero-area or needle
    /// triangle.
    pub degenerate_avoided: u64,
    /// Of the above, moves skipped entirely.
    pub skipped: u64,
}

impl GuardCounts {
    pub fn record(&mut self, g: Guarded) {
        let reason = match g {
            Guarded::Full => return,
            Guarded::Shortened(r) => r,
            Guarded::Skipped(r) => {
                self.skipped += 1;
                r
            }
        };
        match reason {
            MoveCheck::Flip => self.flips_avoided += 1,
            MoveCheck::Degenerate => self.degenerate_avoided += 1,
            MoveCheck::Ok => {}
        }
    }

    pub fn add(&mut self, o: GuardCounts) {
        self.flips_avoided += o.flips_avoided;
        self.degenerate_avoided += o.degenerate_avoided;
        self.skipped += o.skipped;
    }
}

/// Every triangle's vertices (indices of the mesh's positions), the table the fairing
/// reads triangles from: one indirection less than the mesh's wedges, made once per step.
pub fn triangle_vertices(mesh: &Mesh) -> Vec<[u32; 3]> {
    (0..mesh.triangles.len())
        .into_par_iter()
        .map(|t| mesh.triangle_vertices(t))
        .collect()
}

/// Every triangle's normal (cross product) at `positions`; `triangles` from
/// [`triangle_vertices`].
pub fn triangle_normals(triangles: &[[u32; 3]], positions: &[DVec3]) -> Vec<DVec3> {
    triangles
        .par_iter()
        .map(|tri| {
            let [a, b, c] = tri.map(|v| positions[v as usize]);
            (b - a).cross(c - a)
        })
        .collect()
}

/// Each triangle's [`Reference`] at `positions`: the surface around it is the sum of the
/// area-weighted vertex normals of its corners (its own and every triangle sharing a
/// vertex with it); `is_border` tells the boundary vertices.
///
/// Why not the triangle's own normal: a step can only compare with its own input, and a
/// recipe runs several. Measured on james.obj and the ggg_sfm scans, `relax` then `fair`,
/// each keeping its triangles within 90° of their own normals at its start, together
/// turned up to 99 triangles over; a tighter 45° cone stopped that but blocked the
/// smoothing of thin noisy triangles (a million moves refused on a 200k-vertex scan). The
/// surroundings move little from step to step, and a triangle tilted by noise still faces
/// their side.
pub fn triangle_references(
    triangles: &[[u32; 3]],
    positions: &[DVec3],
    is_border: impl Fn(u32) -> bool + Sync,
) -> Vec<Reference> {
    let normals = triangle_normals(triangles, positions);
    let mut at_vertex = vec![DVec3::ZERO; positions.len()];
    for (tri, n) in triangles.iter().zip(&normals) {
        for &v in tri {
            at_vertex[v as usize] += *n;
        }
    }
    // The sums per vertex stay sequential (their order is their rounding); the rest is
    // per triangle.
    triangles
        .par_iter()
        .zip(&normals)
        .map(|(&vs, &own)| {
            Reference::new(
                vs.into_iter().map(|v| at_vertex[v as usize]).sum(),
                own,
                vs.into_iter().any(&is_border),
            )
        })
        .collect()
}

/// Triangles whose normal ends more than 90° from `references` (e.g. the input normals).
pub fn turned_over(triangles: &[[u32; 3]], references: &[DVec3], positions: &[DVec3]) -> usize {
    triangles
        .par_iter()
        .zip(references)
        .filter(|&(tri, r)| {
            let [a, b, c] = tri.map(|v| positions[v as usize]);
            r.length_squared() > 0.0 && (b - a).cross(c - a).dot(*r) < 0.0
        })
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flip_and_needle_are_caught() {
        let ring = [DVec3::X, DVec3::Y, DVec3::NEG_X, DVec3::NEG_Y];
        let fan = Fan {
            ring: &ring,
            closed: true,
            references: &[],
        };
        let c = DVec3::ZERO;
        assert_eq!(check_fan(c, DVec3::new(0.1, 0.1, 0.2), fan), MoveCheck::Ok);
        // Past the ring: triangles flip.
        assert_eq!(
            check_fan(c, DVec3::new(1.5, 0.0, 0.0), fan),
            MoveCheck::Flip
        );
        // Onto an edge's line: zero area.
        assert_eq!(
            check_fan(c, DVec3::new(0.5, 0.5, 0.0), fan),
            MoveCheck::Degenerate
        );
        let (p, g) = guarded_move(c, DVec3::new(1.5, 0.0, 0.0), fan);
        assert_eq!(g, Guarded::Shortened(MoveCheck::Flip));
        assert!((p.x - 0.75).abs() < 1e-12);
        let (p, g) = guarded_move(c, DVec3::new(9.0, 0.0, 0.0), fan);
        assert_eq!((p, g), (c, Guarded::Skipped(MoveCheck::Flip)));
        // Against the surroundings: a triangle tilted 60° from them may tilt back, or on
        // to 80°, but not past 90° even in a step smaller than 90°.
        let at = |deg: f64| {
            let r = deg.to_radians();
            [DVec3::ZERO, DVec3::X, DVec3::new(0.0, r.cos(), r.sin())]
        };
        let own = |deg: f64| {
            let [a, b, c] = at(deg);
            (b - a).cross(c - a)
        };
        let inner = |start: f64| Reference::new(DVec3::Z, own(start), false);
        assert_eq!(
            check_triangle(at(60.0), at(10.0), inner(60.0)),
            MoveCheck::Ok
        );
        assert_eq!(
            check_triangle(at(60.0), at(80.0), inner(60.0)),
            MoveCheck::Ok
        );
        assert_eq!(
            check_triangle(at(60.0), at(100.0), inner(60.0)),
            MoveCheck::Flip
        );
        let unknown = Reference::default();
        assert_eq!(check_triangle(at(60.0), at(100.0), unknown), MoveCheck::Ok);
        // A fold (facing away from its surroundings) may turn back.
        assert_eq!(
            check_triangle(at(120.0), at(60.0), inner(120.0)),
            MoveCheck::Ok
        );
        // A border triangle: 45° from where it started.
        let border = Reference {
            border: true,
            ..inner(60.0)
        };
        assert_eq!(check_triangle(at(60.0), at(20.0), border), MoveCheck::Ok);
        assert_eq!(check_triangle(at(60.0), at(10.0), border), MoveCheck::Flip);
    }
}
