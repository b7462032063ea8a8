//! The point of a triangle closest to a point, a lower bound of that distance (the
//! triangle's plane), and a point's distance to a segment.

use glam::DVec3;

/// The point of triangle `a b c` closest to `p`, and its barycentric weights, by the
/// Voronoi-region case analysis (Ericson, *Real-Time Collision Detection*, §5.1.5): every
/// corner and edge region is tested before the interior, so a degenerate triangle still
/// gives a point on it.
///
/// The one degenerate rule: when the interior case's denominator (twice the squared area,
/// in effect) is zero, subnormal or not finite, the answer is corner `a` (weights `(1, 0, 0)`).
/// Only a zero-area triangle whose edge regions all failed reaches it.
///
/// Always inlined: it is the innermost call of every closest-point search (metrics, preview,
/// fairing's projection), and a caller that wants only the point lets the compiler drop the
/// weights. Left to its own judgement the compiler kept one shared out-of-line copy, which
/// made the face-scan run measurably slower (docs/face-scan.md).
#[inline(always)]
pub fn closest_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> (DVec3, DVec3) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let corner_b = || {
        let bp = p - b;
        (ab.dot(bp), ac.dot(bp))
    };
    let corner_c = || {
        let cp = p - c;
        (ab.dot(cp), ac.dot(cp))
    };
    regions(
        [a, b, c],
        ab,
        ac,
        (ab.dot(ap), ac.dot(ap)),
        corner_b,
        corner_c,
    )
}

/// The case analysis of [`closest_on_triangle`] from the dot products it reads, with the
/// products `(d3, d4)` (of `p − b`) and `(d5, d6)` (of `p − c`) made only when a case needs
/// them. One copy of the rule for both callers: a lone triangle, and a fan whose triangles
/// share their edges' products ([`closest_on_fan`]).
#[inline(always)]
fn regions(
    [a, b, c]: [DVec3; 3],
    ab: DVec3,
    ac: DVec3,
    (d1, d2): (f64, f64),
    corner_b: impl FnOnce() -> (f64, f64),
    corner_c: impl FnOnce() -> (f64, f64),
) -> (DVec3, DVec3) {
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, DVec3::X);
    }
    let (d3, d4) = corner_b();
    if d3 >= 0.0 && d4 <= d3 {
        return (b, DVec3::Y);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, DVec3::new(1.0 - v, v, 0.0));
    }
    let (d5, d6) = corner_c();
    if d6 >= 0.0 && d5 <= d6 {
        return (c, DVec3::Z);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, DVec3::new(1.0 - w, 0.0, w));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, DVec3::new(0.0, 1.0 - w, w));
    }
    let denom = va + vb + vc;
    if denom.abs() <= f64::MIN_POSITIVE || !denom.is_finite() {
        return (a, DVec3::X);
    }
    let v = vb / denom;
    let w = vc / denom;
    (a + ab * v + ac * w, DVec3::new(1.0 - v - w, v, w))
}

/// The point nearest to `p` of the closed fan of triangles `(a, r_i, r_{i+1})` around `a`,
/// `r_i = ring(i)` for `i` in `0..k` (the last triangle closes on `r_0`); the first nearest
/// in ring order on a tie, and `p` itself when the ring is empty.
///
/// Each triangle's point is [`closest_on_triangle`]'s, bit for bit: two neighbouring
/// triangles share the edge `a r_i`, and the products of that edge with `p − a` and
/// `p − r_i` (which the case analysis reads of both) are made once, the same numbers from
/// the same operands. The fairing projects every moved vertex onto its fan this way in
/// each sweep of `relax`: two million fans on a 400k-triangle scan.
#[inline]
pub fn closest_on_fan(p: DVec3, a: DVec3, k: usize, ring: impl Fn(usize) -> DVec3) -> DVec3 {
    if k == 0 {
        return p;
    }
    let ap = p - a;
    // Corner `r`: the edge `e = r − a`, `q = p − r`, `e·(p − a)` and `e·q`.
    let corner = |r: DVec3| {
        let e = r - a;
        let q = p - r;
        (r, e, q, e.dot(ap), e.dot(q))
    };
    let first = corner(ring(0));
    let mut current = first;
    let mut best = (f64::INFINITY, p);
    for i in 0..k {
        let next = if i + 1 == k {
            first
        } else {
            corner(ring(i + 1))
        };
        let ((b, eb, qb, db, sb), (c, ec, qc, dc, sc)) = (current, next);
        // In closest_on_triangle(p, a, b, c): ab = eb, ac = ec, d1 = db, d2 = dc,
        // d3 = ab·(p − b) = sb, d4 = ac·(p − b), d5 = ab·(p − c), d6 = ac·(p − c) = sc.
        let (point, _) = regions(
            [a, b, c],
            eb,
            ec,
            (db, dc),
            || (sb, ec.dot(qb)),
            || (eb.dot(qc), sc),
        );
        let d = (point - p).length_squared();
        if d < best.0 {
            best = (d, point);
        }
        current = next;
    }
    best.1
}

/// A triangle's plane: unit normal and offset (a zero normal for a triangle without area).
#[derive(Debug, Clone, Copy)]
pub struct Plane {
    normal: DVec3,
    offset: f64,
}

impl Plane {
    pub fn of([a, b, c]: [DVec3; 3]) -> Plane {
        let normal = (b - a).cross(c - a).normalize_or_zero();
        Plane {
            normal,
            offset: normal.dot(a),
        }
    }

    /// Every point of the triangle is farther from `q` than `sqrt(d2)`: its plane is, by a
    /// margin far above the rounding of either distance. The distance to the plane is a
    /// lower bound of the distance to the triangle, so a search that skips such a
    /// triangle chooses what it chose when it computed the triangle's closest point
    /// ([`closest_on_triangle`] costs about three times this test).
    /// The margin is absolute (relative to the coordinates' size): a point on the surface
    /// has a distance near zero, where a relative margin would cover nothing.
    #[inline]
    pub fn farther_than(&self, q: DVec3, d2: f64) -> bool {
        let rounding = 1e-12 * (q.abs().element_sum() + self.offset.abs());
        let e = (self.normal.dot(q) - self.offset).abs() - rounding;
        e > 0.0 && e * e > d2
    }
}

/// The point of the segment `a b` closest to `p` (`a` when `a == b`).
pub fn closest_on_segment(p: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let ab = b - a;
    let t = if ab.length_squared() > 0.0 {
        ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    a + ab * t
}

/// The distance from `p` to the segment `a b` (a point when `a == b`).
pub fn segment_distance(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    closest_on_segment(p, a, b).distance(p)
}

#[cfg(test)]
mod tests {
    use super::{Plane, closest_on_fan, closest_on_triangle};
    use crate::metrics::surface::rng;
    use glam::DVec3;
    use rand::RngExt;

    /// The plane test never rules out a triangle nearer than the bound, points on the
    /// triangle's own plane included (where the distance is zero up to rounding), and rules
    /// out most of those clearly farther.
    #[test]
    fn plane_rules_out_only_farther_triangles() {
        let mut r = rng(11);
        let mut ruled_out = 0;
        let mut clearly_farther = 0;
        for i in 0..20_000 {
            let mut point = || {
                DVec3::new(
                    r.random_range(90.0..110.0),
                    r.random_range(-110.0..-90.0),
                    r.random_range(-5.0..5.0),
                )
            };
            let t = [point(), point(), point()];
            let on_plane = t[0] + 0.3 * (t[1] - t[0]) + 0.5 * (t[2] - t[0]);
            let q = if i % 2 == 0 { point() } else { on_plane };
            let (p, _) = closest_on_triangle(q, t[0], t[1], t[2]);
            let d2 = p.distance_squared(q);
            let plane = Plane::of(t);
            for bound in [0.0, 0.5 * d2, d2, 2.0 * d2, 1e-30] {
                if plane.farther_than(q, bound) {
                    assert!(d2 > bound, "{t:?} {q:?} {bound}");
                    ruled_out += 1;
                }
                if (plane.normal.dot(q) - plane.offset).powi(2) > 1.01 * bound + 1e-6 {
                    clearly_farther += 1;
                }
            }
        }
        assert!(
            ruled_out > clearly_farther / 2,
            "{ruled_out} of {clearly_farther}"
        );
    }

    /// The fan's point is the nearest of its triangles' closest points, bit for bit, on
    /// random fans around points near them, with degenerate triangles (repeated and
    /// coincident corners) among them, and rings of one and two vertices.
    #[test]
    fn fan_is_its_triangles_bit_for_bit() {
        let mut r = rng(29);
        for round in 0..20_000 {
            let k = 1 + round % 9;
            let mut point = |s: f64| {
                DVec3::new(
                    r.random_range(-s..s),
                    r.random_range(-s..s),
                    r.random_range(-s..s),
                )
            };
            let a = DVec3::new(100.0, -50.0, 3.0) + point(1.0);
            let mut ring: Vec<DVec3> = (0..k).map(|_| a + point(1.0)).collect();
            if round % 7 == 0 && k > 2 {
                ring[1] = ring[0];
            }
            if round % 11 == 0 {
                ring[0] = a;
            }
            let p = a + point(1.5);
            let mut expected = (f64::INFINITY, p);
            for i in 0..k {
                let (q, _) = closest_on_triangle(p, a, ring[i], ring[(i + 1) % k]);
                let d = (p - q).length_squared();
                if d < expected.0 {
                    expected = (d, q);
                }
            }
            let got = closest_on_fan(p, a, k, |i| ring[i]);
            assert_eq!(
                got.to_array().map(f64::to_bits),
                expected.1.to_array().map(f64::to_bits),
                "round {round}"
            );
        }
        assert_eq!(
            closest_on_fan(DVec3::ONE, DVec3::ZERO, 0, |_| DVec3::X),
            DVec3::ONE
        );
    }

    #[test]
    fn regions_and_the_degenerate_rule() {
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        // Interior: straight down onto the plane.
        let (q, w) = closest_on_triangle(DVec3::new(0.25, 0.25, 3.0), a, b, c);
        assert!((q - DVec3::new(0.25, 0.25, 0.0)).length() < 1e-15);
        assert!((w - DVec3::new(0.5, 0.25, 0.25)).length() < 1e-15);
        // Corner and edge regions.
        assert_eq!(
            closest_on_triangle(DVec3::new(-1.0, -1.0, 0.0), a, b, c).0,
            a
        );
        assert_eq!(
            closest_on_triangle(DVec3::new(2.0, -0.5, 0.0), a, b, c).0,
            b
        );
        let (q, _) = closest_on_triangle(DVec3::new(0.5, -1.0, 0.0), a, b, c);
        assert_eq!(q, DVec3::new(0.5, 0.0, 0.0));
        let (q, _) = closest_on_triangle(DVec3::new(1.0, 1.0, 0.0), a, b, c);
        assert!((q - DVec3::new(0.5, 0.5, 0.0)).length() < 1e-15, "{q}");
        // A triangle whose corners coincide: the point, whatever p is.
        let (q, w) = closest_on_triangle(DVec3::new(1.0, 2.0, 3.0), b, b, b);
        assert_eq!((q, w), (b, DVec3::X));
        // Collinear corners: a point on the segment, never NaN.
        let (q, _) = closest_on_triangle(DVec3::new(0.5, 1.0, 0.0), a, b, 2.0 * b);
        assert!(
            q.is_finite() && q.y == 0.0 && (0.0..=2.0).contains(&q.x),
            "{q}"
        );
    }
}
