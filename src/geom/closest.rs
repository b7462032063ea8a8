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
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, DVec3::X);
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, DVec3::Y);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, DVec3::new(1.0 - v, v, 0.0));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
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
    use super::{Plane, closest_on_triangle};
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
