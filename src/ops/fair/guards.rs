//! Guards against the failures the thesis reports or implies (fairing.md §12):
//! which vertices stay fixed (non-manifold, creases, very high valence), and the check
//! that a move neither flips a triangle nor makes a zero-area or needle triangle (a move
//! that would is shortened, then skipped, and counted).

use super::neighbourhood::Neighbourhood;
use super::positive;
use crate::mesh::{Mesh, Topology};
use glam::DVec3;
use serde::Serialize;

/// Quality `4√3·area / Σ edge²` (1 for an equilateral triangle, 0 for a degenerate one)
/// below which a move may not push a triangle, unless it improves it.
pub const MIN_QUALITY: f64 = 0.05;

/// Why the vertices that stay fixed do.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct FixedCounts {
    /// No single fan (pinch, bowtie, non-manifold edge) or a triangle repeating a vertex:
    /// the thesis assumes a manifold (§1.2.1, pitfall 28).
    pub non_manifold: usize,
    /// On an edge sharper than `feature_angle`.
    pub crease: usize,
    /// Valence above the limit (the vase that lost its top, §3.8.1, pitfall 25).
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

/// `4√3·area / Σ edge²` from the cross product and the corners.
fn quality(cross: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let sum = (b - a).length_squared() + (c - b).length_squared() + (a - c).length_squared();
    if sum > 0.0 {
        2.0 * 3f64.sqrt() * cross.length() / sum
    } else {
        0.0
    }
}

/// Checks triangle `(a, b, c)` → `(a2, b2, c2)`.
#[inline]
pub fn check_triangle(old: [DVec3; 3], new: [DVec3; 3]) -> MoveCheck {
    let n_old = (old[1] - old[0]).cross(old[2] - old[0]);
    let n_new = (new[1] - new[0]).cross(new[2] - new[0]);
    let q_new = quality(n_new, new[0], new[1], new[2]);
    if n_old.length_squared() > 0.0 && n_new.dot(n_old) < 0.0 {
        return MoveCheck::Flip;
    }
    if q_new < MIN_QUALITY && q_new < quality(n_old, old[0], old[1], old[2]) {
        return MoveCheck::Degenerate;
    }
    MoveCheck::Ok
}

/// Checks moving the centre of a fan from `old` to `new`, its ring held still. The fan
/// triangles are `(a, ring[i], ring[i+1])`, wrapping when `closed`.
pub fn check_fan(old: DVec3, new: DVec3, ring: &[DVec3], closed: bool) -> MoveCheck {
    let n = ring.len();
    let tris = if closed { n } else { n.saturating_sub(1) };
    let mut worst = MoveCheck::Ok;
    for i in 0..tris {
        let (p, q) = (ring[i], ring[(i + 1) % n]);
        match check_triangle([old, p, q], [new, p, q]) {
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
pub fn guarded_move(
    old: DVec3,
    candidate: DVec3,
    ring: &[DVec3],
    closed: bool,
) -> (DVec3, Guarded) {
    if !candidate.is_finite() {
        return (old, Guarded::Skipped(MoveCheck::Degenerate));
    }
    let first = check_fan(old, candidate, ring, closed);
    if first == MoveCheck::Ok {
        return (candidate, Guarded::Full);
    }
    for f in [0.5, 0.25] {
        let p = old + f * (candidate - old);
        if check_fan(old, p, ring, closed) == MoveCheck::Ok {
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

/// Triangles whose normal turned by more than 90° from `reference` (the input).
pub fn flipped_triangles(mesh: &Mesh, reference: &[DVec3], positions: &[DVec3]) -> usize {
    (0..mesh.triangles.len())
        .filter(|&t| {
            let [a, b, c] = mesh.triangle_vertices(t).map(|v| v as usize);
            let n0 = (reference[b] - reference[a]).cross(reference[c] - reference[a]);
            let n1 = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
            n0.length_squared() > 0.0 && n0.dot(n1) < 0.0
        })
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flip_and_needle_are_caught() {
        let ring = [DVec3::X, DVec3::Y, DVec3::NEG_X, DVec3::NEG_Y];
        let c = DVec3::ZERO;
        assert_eq!(
            check_fan(c, DVec3::new(0.1, 0.1, 0.2), &ring, true),
            MoveCheck::Ok
        );
        // Past the ring: triangles flip.
        assert_eq!(
            check_fan(c, DVec3::new(1.5, 0.0, 0.0), &ring, true),
            MoveCheck::Flip
        );
        // Onto an edge's line: zero area.
        assert_eq!(
            check_fan(c, DVec3::new(0.5, 0.5, 0.0), &ring, true),
            MoveCheck::Degenerate
        );
        let (p, g) = guarded_move(c, DVec3::new(1.5, 0.0, 0.0), &ring, true);
        assert_eq!(g, Guarded::Shortened(MoveCheck::Flip));
        assert!((p.x - 0.75).abs() < 1e-12);
        let (p, g) = guarded_move(c, DVec3::new(9.0, 0.0, 0.0), &ring, true);
        assert_eq!((p, g), (c, Guarded::Skipped(MoveCheck::Flip)));
    }
}
