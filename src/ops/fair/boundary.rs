//! Surfaces with boundary (thesis ch. 4): the boundary loops are found (§4.1) and each is
//! faired with the closed-curve algorithm (§4.3), its interior neighbours held still; the
//! interior is then faired with the closed-surface algorithm with the boundary held still
//! (§4.4), which is [`super::surface`] with boundary neighbours left out of `H̄`.
//! As in all the thesis' experiments and the Matlab default (§4.5, App. B), the boundary is
//! faired completely first, then the interior; the thesis found alternation unnecessary
//! (§4.6.4).

use super::curve::{self, CurveShape};
use super::guards::{Fan, GuardCounts, Reference, guarded_move};
use super::neighbourhood::Neighbourhood;
use super::positive;
use super::schedule::{self, Phase, PhaseParams, RunStats, Sweep};
use crate::mesh::BoundaryChain;
use glam::DVec3;

/// Boundary walks shorter than this are held still. The curve step keeps a vertex on the
/// rising branch of its curvature (§2.7.3): one sharper than 90° is moved to the other
/// position with the same curvature, nearer its neighbours' midpoint. A regular polygon is
/// a fixed point only when its angles are at least 90° (4 or more vertices; the thesis'
/// "regular polygons are fixed points", §2.11.1, is wrong for the triangle, whose vertices
/// jump inwards every iteration), and a small ragged hole has sharp corners everywhere:
/// measured on james.obj, 3- to 6-vertex holes collapsed or blew up. Below 8 vertices a
/// hole is a few edges across and has no noise a curve filter could remove.
pub const MIN_CURVE_VERTICES: usize = 8;

/// How far a step may let a closed boundary curve (a hole) close or grow: its enclosed
/// area may change by `f × perimeter²` (what a uniform shift across the curve by
/// `f × perimeter` gives) and its perimeter may grow by `f`. Measured on the ggg_sfm
/// scans: thin ragged slit holes (area ≈ 0.02 P²) lost up to 82% of their area as relax +
/// fair straightened them, and a small one grew its perimeter by 5%. A curve that goes
/// further stops, its last iteration undone; 1% per step keeps `relax` then `fair` within
/// the 2% of perimeter the holes may move.
pub const HOLE_TOLERANCE: f64 = 0.01;

/// Perimeter of a closed polygon.
fn perimeter(pts: &[DVec3]) -> f64 {
    let n = pts.len();
    (0..n).map(|i| (pts[(i + 1) % n] - pts[i]).length()).sum()
}

/// Area enclosed by a closed 3D polygon (half the length of its vector area).
pub fn enclosed_area(pts: &[DVec3]) -> f64 {
    let n = pts.len();
    if n < 3 {
        return 0.0;
    }
    let c = pts.iter().copied().sum::<DVec3>() / n as f64;
    (0..n)
        .map(|i| (pts[i] - c).cross(pts[(i + 1) % n] - c))
        .sum::<DVec3>()
        .length()
        / 2.0
}

/// One boundary walk to fair as a curve.
#[derive(Debug, Clone)]
pub struct BoundaryCurve {
    pub vertices: Vec<u32>,
    pub closed: bool,
    /// Per vertex of the walk: held still (non-manifold pinch, crease, high valence).
    pub fixed: Vec<bool>,
}

/// The boundary walks of the mesh as curves. A closed walk is a closed curve; an open walk
/// (only next to inconsistently oriented or non-manifold edges) is an open curve whose ends
/// stay (§2.9). Walks of fewer than [`MIN_CURVE_VERTICES`] vertices are returned as `held`
/// instead.
pub fn boundary_curves(chains: &[BoundaryChain], fixed: &[bool]) -> (Vec<BoundaryCurve>, Vec<u32>) {
    let mut curves = Vec::new();
    let mut held = Vec::new();
    for chain in chains {
        if chain.vertices.len() < MIN_CURVE_VERTICES {
            held.extend_from_slice(&chain.vertices);
            continue;
        }
        curves.push(BoundaryCurve {
            fixed: chain.vertices.iter().map(|&v| fixed[v as usize]).collect(),
            vertices: chain.vertices.clone(),
            closed: chain.closed,
        });
    }
    (curves, held)
}

/// Fairs one boundary curve in place in `positions` (the C sub-algorithm of §4.5). The
/// thesis' curve order is Jacobi (§2.6.1): candidates come from the positions at the start
/// of the iteration; they are then written one by one, each checked against its fan as it
/// is at that moment, so no move flips or degenerates a triangle.
pub fn fair_boundary_curve(
    positions: &mut [DVec3],
    nb: &Neighbourhood,
    curve: &BoundaryCurve,
    params: &PhaseParams,
    epsilon: f64,
    references: &[Reference],
    guards: &mut GuardCounts,
) -> RunStats {
    let mut pts: Vec<DVec3> = curve
        .vertices
        .iter()
        .map(|&v| positions[v as usize])
        .collect();
    // Thresholds relative to the mean edge length of the input curve (§2.11, App. A).
    let scale = curve::mean_edge_length(&pts, curve.closed);
    if !positive(scale) {
        return RunStats::default();
    }
    let shape = CurveShape {
        closed: curve.closed,
        fixed: &curve.fixed,
    };
    let eps = epsilon / scale;
    let n = pts.len();
    let movable = (0..n)
        .filter(|&i| !curve.fixed[i] && (curve.closed || (i > 0 && i + 1 < n)))
        .count();
    if movable == 0 {
        return RunStats::default();
    }
    let mut fans = FanReader {
        nb,
        references,
        ring: Vec::new(),
        fan_references: Vec::new(),
    };
    let hole = HoleLimits::new(&pts, scale, curve.closed);
    schedule::run(params, scale, |phase| {
        let before = pts.clone();
        let candidates = match phase {
            Phase::Curvature => curve::curvature_sweep(&pts, shape, params.lambda, eps),
            Phase::Nonuniformity => curve::nonuniformity_sweep(&pts, shape, params.lambda_u),
        };
        let (sum, max) = write_guarded(positions, &mut pts, candidates, curve, &mut fans, guards);
        let halt = curve.closed && hole.exceeded(&pts);
        if halt {
            for (i, p) in before.iter().enumerate() {
                positions[curve.vertices[i] as usize] = *p;
            }
            pts = before;
        }
        Sweep {
            mean: sum / movable as f64,
            max,
            updates: movable,
            halt,
        }
    })
}

/// How far one step may let a closed curve move ([`HOLE_TOLERANCE`]): its enclosed area
/// and its perimeter as they were at the start of the step.
struct HoleLimits {
    area0: f64,
    max_area_change: f64,
    max_perimeter: f64,
}

impl HoleLimits {
    /// The limits of the curve `pts` whose mean edge is `scale`.
    fn new(pts: &[DVec3], scale: f64, closed: bool) -> HoleLimits {
        let n = pts.len();
        let perimeter0 = scale * if closed { n } else { n - 1 } as f64;
        HoleLimits {
            area0: enclosed_area(pts),
            max_area_change: HOLE_TOLERANCE * perimeter0 * perimeter0,
            max_perimeter: (1.0 + HOLE_TOLERANCE) * perimeter0,
        }
    }

    /// Whether the curve at `pts` went past the limits.
    fn exceeded(&self, pts: &[DVec3]) -> bool {
        (enclosed_area(pts) - self.area0).abs() > self.max_area_change
            || perimeter(pts) > self.max_perimeter
    }
}

/// Each vertex's fan as the positions are now, in reused buffers.
struct FanReader<'a> {
    nb: &'a Neighbourhood,
    references: &'a [Reference],
    ring: Vec<DVec3>,
    fan_references: Vec<Reference>,
}

impl FanReader<'_> {
    fn fan(&mut self, positions: &[DVec3], v: usize) -> Fan<'_> {
        self.ring.clear();
        self.ring
            .extend(self.nb.ring(v).iter().map(|&j| positions[j as usize]));
        self.fan_references.clear();
        self.fan_references
            .extend(self.nb.fan(v).iter().map(|&t| self.references[t as usize]));
        Fan {
            ring: &self.ring,
            closed: self.nb.is_closed(v),
            references: &self.fan_references,
        }
    }
}

/// Writes one sweep's `candidates` for the curve's vertices one by one, each checked
/// against its fan as it is at that moment (so in vertex order); returns the sum and the
/// largest of the moves.
fn write_guarded(
    positions: &mut [DVec3],
    pts: &mut [DVec3],
    candidates: Vec<DVec3>,
    curve: &BoundaryCurve,
    fans: &mut FanReader,
    guards: &mut GuardCounts,
) -> (f64, f64) {
    let (mut sum, mut max) = (0.0, 0.0f64);
    for (i, candidate) in candidates.into_iter().enumerate() {
        let v = curve.vertices[i] as usize;
        let old = positions[v];
        if candidate == old {
            continue;
        }
        let (p, g) = guarded_move(old, candidate, fans.fan(positions, v));
        guards.record(g);
        positions[v] = p;
        pts[i] = p;
        let d = (p - old).length();
        sum += d;
        max = max.max(d);
    }
    (sum, max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;

    #[test]
    fn grid_has_one_closed_boundary_curve() {
        let m = shapes::grid(4, 3);
        let topo = m.topology();
        let (curves, held) =
            boundary_curves(topo.boundary_chains(), &vec![false; m.positions.len()]);
        assert_eq!(curves.len(), 1);
        assert!(curves[0].closed);
        assert_eq!(curves[0].vertices.len(), 14);
        assert!(held.is_empty());
    }

    #[test]
    fn ragged_border_is_smoothed_without_flips() {
        let mut m = shapes::grid(12, 12);
        // Jag the border in-plane.
        for (i, p) in m.positions.iter_mut().enumerate() {
            let on_border = p.x == 0.0 || p.y == 0.0 || p.x == 12.0 || p.y == 12.0;
            if on_border && i % 2 == 1 {
                let inward = (DVec3::new(6.0, 6.0, 0.0) - *p).normalize();
                *p += 0.3 * inward;
            }
        }
        let topo = m.topology();
        let nb = Neighbourhood::new(&topo);
        let (curves, _) = boundary_curves(topo.boundary_chains(), &vec![false; m.positions.len()]);
        let before = m.positions.clone();
        let mut guards = GuardCounts::default();
        let params = PhaseParams {
            max_iterations: 200,
            ..PhaseParams::curve()
        };
        let triangles = super::super::guards::triangle_vertices(&m);
        let normals = super::super::guards::triangle_references(&triangles, &m.positions, |v| {
            topo.is_boundary_vertex(v)
        });
        let stats = fair_boundary_curve(
            &mut m.positions,
            &nb,
            &curves[0],
            &params,
            1e-4,
            &normals,
            &mut guards,
        );
        assert!(stats.iterations > 0);
        assert_eq!(
            super::super::guards::turned_over(
                &triangles,
                &super::super::guards::triangle_normals(&triangles, &before),
                &m.positions
            ),
            0
        );
        // The jag (the alternating part of the second difference across the bottom side)
        // is gone; what remains is the rounding of the corners.
        let v = |i: usize, j: usize| m.positions[j * 13 + i];
        let jag = |f: &dyn Fn(usize) -> f64| {
            (2..11)
                .map(|i| {
                    let s = if i % 2 == 0 { 1.0 } else { -1.0 };
                    s * (f(i) - 0.5 * (f(i - 1) + f(i + 1)))
                })
                .sum::<f64>()
                .abs()
                / 9.0
        };
        let jag0 = jag(&|i| before[i].y);
        let jag1 = jag(&|i| v(i, 0).y);
        assert!(jag1 < 0.05 * jag0, "{jag0} -> {jag1}");
    }
}
