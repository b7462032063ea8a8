//! Closed and open curves (thesis ch. 2): curvature vector (2.9), sign transfer
//! (2.16–2.17), magnitude diffusion (2.15, 2.47–2.48), the new vertex from the quadratic
//! with the thesis' root selection (2.18–2.37), the special cases (§2.7.4) and the
//! non-uniformity step (2.38–2.46). The update order is Jacobi (§2.6.1): every quantity of
//! an iteration is computed from the positions at its start, and all vertices are
//! replaced together at its end.

use super::positive;
use super::schedule::{self, Phase, PhaseParams, RunStats};
use glam::DVec3;

/// A curve's vertex roles. End vertices of an open curve are "invalid" (§2.9): never
/// moved, and their curvature is not transferred to their neighbour.
#[derive(Debug, Clone, Copy)]
pub struct CurveShape<'a> {
    pub closed: bool,
    /// Vertices that must not move (non-manifold pinches, creases, …). Their curvature is
    /// still computed and transferred: they have two neighbours. Empty = none fixed.
    pub fixed: &'a [bool],
}

impl CurveShape<'_> {
    fn is_fixed(&self, i: usize) -> bool {
        self.fixed.get(i).copied().unwrap_or(false)
    }
}

/// Curvature vector (2.9)/(2.14): `H_i = 2 (d_i1 + d_i2) / (d_i1² + d_i2²)` with
/// `d_i1 = a_i − a_{i−1}`, `d_i2 = a_i − a_{i+1}`. Zero when both edges vanish.
pub fn curvature(prev: DVec3, cur: DVec3, next: DVec3) -> DVec3 {
    let (d1, d2) = (cur - prev, cur - next);
    let s = d1.length_squared() + d2.length_squared();
    if s > 0.0 {
        2.0 * (d1 + d2) / s
    } else {
        DVec3::ZERO
    }
}

/// The sign with which the neighbour's curvature vector `h_nbr` is transferred to the
/// vertex with curvature vector `h_cur`; `edge` joins them (§2.7.2, eqs. 2.16–2.17 and the
/// thesis' decision table on `a = h_nbrᵀ h_cur`, `b = (h_nbr·u)(u·h_cur)`).
///
/// The thesis compares `a` and `b` exactly; in floating point "equal" is within a relative
/// tolerance (docs/fairing.md, reading F4). A zero-length edge has no direction: (2.17) alone.
pub fn transfer_sign(h_nbr: DVec3, h_cur: DVec3, edge: DVec3) -> f64 {
    let a = h_nbr.dot(h_cur);
    let el = edge.length();
    let b = if el > 0.0 {
        let u = edge / el;
        h_nbr.dot(u) * u.dot(h_cur)
    } else {
        a
    };
    let tol = 1e-12 * h_nbr.length() * h_cur.length();
    if a - b > tol || ((a - b).abs() <= tol && a > tol) {
        1.0
    } else if b - a > tol || ((a - b).abs() <= tol && a < -tol) {
        -1.0
    } else {
        0.0
    }
}

/// The factor `t*` by which the offset from the neighbours' midpoint is scaled to give the
/// ratio `r = H^{k+1}/H^k` (§2.7.3, eqs. 2.27–2.37, solved in closed form): with `A = ‖d1 + d2‖²/(2S)`, `B = ‖d1 − d2‖²/(2S)`, (2.28) is
/// `r = t/(A t² + B)` in `t = 1 + 2α`. The root on the rising branch between α_min and α_max
/// (2.29, 2.30), or the extremum of the same sign as `r` when there is no root (2.37).
/// This is the same function as for surfaces, so [`super::surface::step_scale`] does it
/// with `P = A`.
fn midpoint_scale(d1: DVec3, d2: DVec3, r: f64) -> f64 {
    let s = d1.length_squared() + d2.length_squared();
    let a = ((d1 + d2).length_squared() / (2.0 * s)).clamp(0.0, 1.0);
    super::surface::step_scale(a, r)
}

/// Per-vertex curvature at the start of an iteration (invalid ends get zero).
fn curvatures(pts: &[DVec3], closed: bool) -> Vec<DVec3> {
    let n = pts.len();
    (0..n)
        .map(|i| match neighbours(n, closed, i) {
            Some((p, q)) => curvature(pts[p], pts[i], pts[q]),
            None => DVec3::ZERO,
        })
        .collect()
}

/// The two neighbours of vertex `i`, `None` for an open curve's ends.
fn neighbours(n: usize, closed: bool, i: usize) -> Option<(usize, usize)> {
    if closed {
        Some(((i + n - 1) % n, (i + 1) % n))
    } else if i == 0 || i + 1 >= n {
        None
    } else {
        Some((i - 1, i + 1))
    }
}

/// The neighbours of vertex `i` when it may move: neither an open end nor fixed.
fn free_neighbours(n: usize, shape: CurveShape, i: usize) -> Option<(usize, usize)> {
    neighbours(n, shape.closed, i).filter(|_| !shape.is_fixed(i))
}

/// One curvature iteration (§2.7), Jacobi: the candidate new position of every vertex
/// (unchanged for fixed vertices and open ends). `eps` is the zero tolerance on `H`,
/// already in the curve's units.
pub fn curvature_sweep(pts: &[DVec3], shape: CurveShape, lambda: f64, eps: f64) -> Vec<DVec3> {
    let n = pts.len();
    let h = curvatures(pts, shape.closed);
    let valid = |j: usize| neighbours(n, shape.closed, j).is_some();
    (0..n)
        .map(|i| {
            let Some((p, q)) = free_neighbours(n, shape, i) else {
                return pts[i];
            };
            let hi = h[i].length();
            if hi < eps {
                return pts[i]; // §2.7.4 special case 1: H = 0, α = 0
            }
            let (d1, d2) = (pts[i] - pts[p], pts[i] - pts[q]);
            // (2.15): H̄ = (s1 H_{i−1} + s2 H_{i+1}) / 2; next to an open end, (2.48):
            // the one valid neighbour, not halved.
            let mut sum = 0.0;
            let mut count = 0.0;
            for (j, d) in [(p, d1), (q, d2)] {
                if valid(j) {
                    sum += transfer_sign(h[j], h[i], d) * h[j].length();
                    count += 1.0;
                }
            }
            let hbar = if count > 0.0 { sum / count } else { 0.0 };
            let target = (1.0 - lambda) * hi + lambda * hbar;
            // H^{k+1} = H^k: stay (α = 0 solves (2.27)). The rising-branch rule would move a
            // vertex sharper than 90° even then, so the regular triangle would not be the
            // fixed point §2.11.1 says every regular polygon is (see surface.rs).
            if (target - hi).abs() < eps {
                return pts[i];
            }
            let mid = 0.5 * (pts[p] + pts[q]);
            // §2.7.4 special case 2: H^{k+1} = 0 gives α = −1/2, the midpoint.
            let t = if target.abs() < eps {
                0.0
            } else {
                midpoint_scale(d1, d2, target / hi)
            };
            // (2.18) a + α(d1 + d2) = m + (1 + 2α)(a − m).
            mid + t * (pts[i] - mid)
        })
        .collect()
}

/// One non-uniformity iteration (§2.8, eqs. 2.38, 2.46), Jacobi:
/// `a ← a + λ_u U`, `U = P_b (m − a)` with `b = a_{i+1} − a_{i−1}` (2.10, 2.12).
pub fn nonuniformity_sweep(pts: &[DVec3], shape: CurveShape, lambda_u: f64) -> Vec<DVec3> {
    let n = pts.len();
    (0..n)
        .map(|i| {
            let Some((p, q)) = free_neighbours(n, shape, i) else {
                return pts[i];
            };
            pts[i] + lambda_u * nonuniformity(pts[p], pts[i], pts[q])
        })
        .collect()
}

/// The non-uniformity vector (2.12): the tangential part of the way to the neighbours'
/// midpoint. Zero when the neighbours coincide (`b = 0`: (2.10) is undefined there).
pub fn nonuniformity(prev: DVec3, cur: DVec3, next: DVec3) -> DVec3 {
    let b = next - prev;
    let bb = b.length_squared();
    if !positive(bb) {
        return DVec3::ZERO;
    }
    let to_mid = 0.5 * (prev + next) - cur;
    b * (b.dot(to_mid) / bb)
}

/// Mean edge length of a polyline (closing edge included when closed).
pub fn mean_edge_length(pts: &[DVec3], closed: bool) -> f64 {
    let n = pts.len();
    let edges = if closed { n } else { n.saturating_sub(1) };
    if edges == 0 {
        return 0.0;
    }
    let sum: f64 = (0..edges)
        .map(|i| (pts[(i + 1) % n] - pts[i]).length())
        .sum();
    sum / edges as f64
}

/// Fairs a free polyline in place with the thesis' closed/open-curve algorithm (ch. 2) and
/// its iteration scheme (§2.10). `params.stop` and `epsilon` are relative to the mean
/// edge length of the input curve (§2.11, App. A).
pub fn fair_polyline(
    pts: &mut [DVec3],
    shape: CurveShape,
    params: &PhaseParams,
    epsilon: f64,
) -> RunStats {
    let scale = mean_edge_length(pts, shape.closed);
    if pts.len() < 3 || !positive(scale) {
        return RunStats::default();
    }
    let eps = epsilon / scale;
    let movable = (0..pts.len())
        .filter(|&i| neighbours(pts.len(), shape.closed, i).is_some() && !shape.is_fixed(i))
        .count()
        .max(1);
    schedule::run(params, scale, |phase| {
        let new = match phase {
            Phase::Curvature => curvature_sweep(pts, shape, params.lambda, eps),
            Phase::Nonuniformity => nonuniformity_sweep(pts, shape, params.lambda_u),
        };
        let mut sum = 0.0;
        let mut max: f64 = 0.0;
        for (p, q) in pts.iter_mut().zip(new) {
            let d = (q - *p).length();
            sum += d;
            max = max.max(d);
            *p = q;
        }
        schedule::Sweep {
            mean: sum / movable as f64,
            max,
            updates: movable,
            halt: false,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn polygon(n: usize, r: f64) -> Vec<DVec3> {
        (0..n)
            .map(|i| {
                let t = std::f64::consts::TAU * i as f64 / n as f64;
                DVec3::new(r * t.cos(), r * t.sin(), 0.0)
            })
            .collect()
    }

    fn closed() -> CurveShape<'static> {
        CurveShape {
            closed: true,
            fixed: &[],
        }
    }

    #[test]
    fn regular_polygon_curvature_is_one_over_r() {
        // §2.3.1: H = 1/r, pointing away from the centre.
        let pts = polygon(12, 2.5);
        let h = curvature(pts[11], pts[0], pts[1]);
        assert!((h.length() - 0.4).abs() < 1e-12);
        assert!(h.dot(pts[0]) > 0.0);
    }

    #[test]
    fn curvature_is_not_monotone_in_height() {
        // Derived from (2.9): neighbours 2w apart, height h: H = 2h/(w² + h²).
        let (p, q) = (DVec3::new(-1.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0));
        for h in [0.2, 1.0, 3.0] {
            let k = curvature(p, DVec3::new(0.0, h, 0.0), q).length();
            assert!((k - 2.0 * h / (1.0 + h * h)).abs() < 1e-12);
        }
    }

    #[test]
    fn transfer_signs() {
        let e = DVec3::X;
        assert_eq!(transfer_sign(DVec3::Y, DVec3::Y, e), 1.0);
        assert_eq!(transfer_sign(DVec3::Y, -DVec3::Y, e), -1.0);
        assert_eq!(transfer_sign(DVec3::ZERO, DVec3::Y, e), 0.0);
        // Both along the edge: (2.16) gives 0, (2.17) decides.
        assert_eq!(transfer_sign(DVec3::X, DVec3::X, e), 1.0);
        assert_eq!(transfer_sign(DVec3::X, -DVec3::X, e), -1.0);
        // Perpendicular, one on the edge line: undecidable.
        assert_eq!(transfer_sign(DVec3::X, DVec3::Y, e), 0.0);
    }

    #[test]
    fn curvature_step_reaches_target() {
        let (p, c, q) = (
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::new(0.3, 0.4, 0.0),
            DVec3::new(1.2, 0.1, 0.0),
        );
        let h = curvature(p, c, q);
        let mid = 0.5 * (p + q);
        for r in [0.5, 0.9, 1.2, -0.4] {
            let t = midpoint_scale(c - p, c - q, r);
            let moved = mid + t * (c - mid);
            let after = curvature(p, moved, q);
            let signed = after.length() * after.dot(h).signum();
            assert!((signed - r * h.length()).abs() < 1e-9, "{r}: {signed}");
        }
    }

    #[test]
    fn regular_polygon_is_a_fixed_point() {
        // §2.11.1: stops after the first iteration, unchanged.
        let mut pts = polygon(12, 1.0);
        let before = pts.clone();
        let stats = fair_polyline(&mut pts, closed(), &PhaseParams::curve(), 1e-4);
        assert_eq!(stats.iterations, 1);
        for (a, b) in pts.iter().zip(&before) {
            assert!((*a - *b).length() < 1e-12);
        }
    }

    /// Uniform noise per coordinate in the plane, `amp` × the edge length: a reading of the
    /// thesis' "Rand" inputs (§2.11; the thesis gives no model, docs/fairing.md reading F7).
    fn noisy_circle(n: usize, amp: f64, seed: u64) -> Vec<DVec3> {
        let mut rand = lcg(seed);
        let edge = std::f64::consts::TAU / n as f64;
        polygon(n, 1.0)
            .into_iter()
            .map(|p| p + amp * edge * DVec3::new(rand(), rand(), 0.0))
            .collect()
    }

    /// Uniform in [-1, 1], fixed seed.
    fn lcg(seed: u64) -> impl FnMut() -> f64 {
        let mut lcg = crate::testing::Lcg(seed);
        move || lcg.signed()
    }

    fn polygon_area(pts: &[DVec3]) -> f64 {
        let n = pts.len();
        0.5 * (0..n)
            .map(|i| pts[i].x * pts[(i + 1) % n].y - pts[(i + 1) % n].x * pts[i].y)
            .sum::<f64>()
    }

    /// Coefficient of variation of the curvature magnitude: 0 on a regular polygon, about
    /// 1 or more on a noisy one.
    fn roughness(pts: &[DVec3]) -> f64 {
        let h: Vec<f64> = curvatures(pts, true).iter().map(|h| h.length()).collect();
        let mean = h.iter().sum::<f64>() / h.len() as f64;
        let var = h.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / h.len() as f64;
        var.sqrt() / mean
    }

    #[test]
    fn noisy_circle_becomes_smooth_and_keeps_its_area() {
        let mut pts = noisy_circle(60, 0.5, 7);
        let rough0 = roughness(&pts);
        let area0 = polygon_area(&pts);
        let stats = fair_polyline(&mut pts, closed(), &PhaseParams::curve(), 1e-4);
        let rough = roughness(&pts);
        assert!(rough0 > 0.5 && rough < 0.2 * rough0, "{rough0} -> {rough}");
        let area = polygon_area(&pts);
        assert!((area / area0 - 1.0).abs() < 0.03, "{area0} -> {area}");
        assert!(stats.iterations > 10 && stats.stopped_by_displacement);
    }

    #[test]
    fn renoised_circle_returns_to_the_same_shape() {
        // §2.11.2 stability: smooth, re-noise, smooth again → the same shape.
        let mut pts = noisy_circle(60, 0.5, 11);
        let s1 = fair_polyline(&mut pts, closed(), &PhaseParams::curve(), 1e-4);
        let first = pts.clone();
        let mut rand = lcg(99);
        let edge = std::f64::consts::TAU / 60.0;
        for p in pts.iter_mut() {
            *p += 0.5 * edge * DVec3::new(rand(), rand(), 0.0);
        }
        let s2 = fair_polyline(&mut pts, closed(), &PhaseParams::curve(), 1e-4);
        assert!(s1.stopped_by_displacement && s2.stopped_by_displacement);
        // The same shape: every vertex of the second result lies near the first curve
        // (point-to-polyline distance; vertices may slide along it).
        let to_first = |p: DVec3| {
            (0..60)
                .map(|i| {
                    let (a, b) = (first[i], first[(i + 1) % 60]);
                    let t = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
                    (p - (a + t * (b - a))).length()
                })
                .fold(f64::INFINITY, f64::min)
        };
        let apart = pts.iter().map(|&p| to_first(p)).sum::<f64>() / 60.0;
        let h_avg =
            |q: &[DVec3]| curvatures(q, true).iter().map(|h| h.length()).sum::<f64>() / 60.0;
        let (h1, h2) = (h_avg(&first), h_avg(&pts));
        // The re-noise moved vertices by 0.38 edge lengths on average.
        assert!(apart < 0.15 * edge, "{} edges", apart / edge);
        // Not rougher than the first result (like the thesis' star, §2.11.2, it may end
        // smoother: H_avg 1.16 → 1.06 here, 1 being the circle).
        assert!(h2 < 1.05 * h1, "{h1} {h2}");
    }

    #[test]
    fn open_curve_keeps_its_ends_and_straightens() {
        let mut pts: Vec<DVec3> = (0..21)
            .map(|i| DVec3::new(i as f64, if i % 2 == 1 { 0.3 } else { -0.3 }, 0.0))
            .collect();
        pts[0].y = 0.0;
        pts[20].y = 0.0;
        let ends = (pts[0], pts[20]);
        let shape = CurveShape {
            closed: false,
            fixed: &[],
        };
        fair_polyline(&mut pts, shape, &PhaseParams::curve(), 1e-4);
        assert_eq!((pts[0], pts[20]), ends);
        let wiggle = pts.iter().map(|p| p.y.abs()).fold(0.0, f64::max);
        assert!(wiggle < 0.1, "{wiggle}");
    }

    #[test]
    fn fixed_vertices_stay() {
        let mut pts = noisy_circle(30, 0.5, 3);
        let mut fixed = vec![false; 30];
        fixed[4] = true;
        let p4 = pts[4];
        let shape = CurveShape {
            closed: true,
            fixed: &fixed,
        };
        fair_polyline(&mut pts, shape, &PhaseParams::curve(), 1e-4);
        assert_eq!(pts[4], p4);
    }
}
