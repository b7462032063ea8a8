//! Closed surfaces (thesis ch. 3): the squared-area curvature vector, the reconstruction of
//! its sign by local orientation, the step along the fixed line that gives a vertex the
//! diffused curvature magnitude, and the non-uniformity vector and step.
//!
//! Everything here works on one vertex and its ordered closed 1-ring `a_1..a_n` (the fan
//! triangles are `(a, a_i, a_{i+1})`), with the other vertices held still, as the thesis
//! derives it. Positions are taken relative to the vertex (`x_i = a_i - a`): the formulas
//! are translation invariant and this keeps them accurate far from the origin.

use super::guards::{
    Fan, GuardCounts, Guarded, MoveCheck, Reference, check_crosses, cross_of, guarded_move,
};
use super::neighbourhood::Neighbourhood;
use super::positive;
use super::schedule::Sweep;
use crate::geom::closest_on_fan;
use glam::{DMat3, DVec3};
use rayon::prelude::*;

/// Curvature of one vertex with a closed fan (§3.6.1, eqs. 3.13, 3.19, 3.20).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct VertexCurvature {
    /// The curvature vector **H** (3.13). It points away from the neighbours' side at a
    /// convex vertex (outward), see [`curvature`].
    pub vector: DVec3,
    /// `H = ‖H‖`.
    pub magnitude: f64,
    /// `a* − a`: the position that minimises the sum of squared areas (`B⁻¹ b`, §3.6.1),
    /// relative to the vertex. `None` when **B** is singular (a degenerate fan), which
    /// makes the step (3.28) undefined.
    pub to_minimiser: Option<DVec3>,
    /// `P = g / (g + d)` of (3.31), in [0, 1]: one minus the ratio of the smallest
    /// reachable sum of squared areas to the current one.
    pub p: f64,
}

/// Curvature vector and step data at vertex `a` with closed ring `ring` (positions).
///
/// Thesis (3.13): `H = 3/2 · Σ B_i (a − a_i) / Σ (a − a_i)ᵀ B_i (a − a_i)` with
/// `B_i = b_i² E − b_i b_iᵀ`, `b_i = a_i − a_{i+1}`.
///
/// Factor: the thesis' (3.8) writes `3/2 · ∇ΣA_i² / ΣA_i²`, which is twice (3.13) when the
/// gradient is carried through (docs/fairing.md, reading F1). (3.13) is the one with
/// `H = 1/r` on regular polyhedra, as §3.3.1 states, so (3.13) is implemented. The factor
/// does not change the motion, only reported values and the zero test.
///
/// Direction: the thesis (§3.3.1) says **H** points into the centre of a regular
/// polyhedron; (3.13) points outward. Irrelevant to the algorithm, which only
/// uses signs relative to a local orientation.
pub fn curvature(a: DVec3, ring: &[DVec3]) -> VertexCurvature {
    let n = ring.len();
    // B = Σ B_i = (Σ b_i²)·I − Σ b_i b_iᵀ, summed as the scalar and the six distinct
    // entries of the symmetric part.
    let mut sum_b2 = 0.0;
    let (mut bxx, mut bxy, mut bxz, mut byy, mut byz, mut bzz) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    // b' = Σ B_i x_i and c' = Σ x_iᵀ B_i x_i with x_i = a_i − a (the substitutions of
    // §3.6.1 in coordinates centred on a, where `â = B·0 − b' = −b'`).
    let mut bvec = DVec3::ZERO;
    let mut c = 0.0;
    for i in 0..n {
        let xi = ring[i] - a;
        let bi = ring[i] - ring[(i + 1) % n];
        let b2 = bi.length_squared();
        // B_i x = b_i² x − b_i (b_i · x)
        let bx = b2 * xi - bi * bi.dot(xi);
        bvec += bx;
        c += xi.dot(bx);
        sum_b2 += b2;
        bxx += bi.x * bi.x;
        bxy += bi.x * bi.y;
        bxz += bi.x * bi.z;
        byy += bi.y * bi.y;
        byz += bi.y * bi.z;
        bzz += bi.z * bi.z;
    }
    let bmat = DMat3::from_cols(
        DVec3::new(sum_b2 - bxx, -bxy, -bxz),
        DVec3::new(-bxy, sum_b2 - byy, -byz),
        DVec3::new(-bxz, -byz, sum_b2 - bzz),
    );
    // c' = 4 Σ A_i²: zero only when every fan triangle has zero area.
    if !positive(c) || !c.is_finite() {
        return VertexCurvature::default();
    }
    let a_hat = -bvec;
    let vector = 1.5 * a_hat / c;
    let magnitude = vector.length();
    // B is regular as soon as two opposite edges are independent (§3.6.3 note); test its
    // conditioning relative to its scale rather than det = 0.
    let scale = bmat.x_axis.x + bmat.y_axis.y + bmat.z_axis.z;
    let det = bmat.determinant();
    let (to_minimiser, p) = if scale > 0.0 && det > 1e-12 * scale * scale * scale {
        let astar = bmat.inverse() * bvec;
        // g = âᵀ B⁻¹ â = b'ᵀ a*; d = c' − g ≥ 0 (the minimum of the quadratic).
        let g = bvec.dot(astar).max(0.0);
        (Some(astar), (g / c).clamp(0.0, 1.0))
    } else {
        (None, 0.0)
    };
    VertexCurvature {
        vector,
        magnitude,
        to_minimiser,
        p,
    }
}

/// Side of the curvature vector `h` relative to the fan of `a` in ring order (§3.6.2,
/// "Rekonstrukce znamének", eqs. 3.23–3.26): +1, −1, or 0 when it cannot be decided.
///
/// The fan triangle `t_i = (a, a_i, a_{i+1})` has normal `N_i = (a_i − a) × (a_{i+1} − a)`
/// (the orientation (1.13) of the ring order). `h` is projected into every triangle's
/// plane (3.23); the triangle whose planar angle at `a` contains the projection (3.24,
/// 3.25) decides: `s = sign((h − p_i) · N_i)` (3.26), which equals `sign(h · N_i)`.
///
/// Choices where the thesis is silent (docs/fairing.md, reading F4): mixed-sign `(β, γ)` count
/// as outside; exact comparisons use a relative tolerance; in the last case ("choose any
/// p_i") we take the triangle where the sign is most decisive (largest `|ĥ · N̂_i|`),
/// which is deterministic and never picks a triangle nearly parallel to `h`.
/// Zero-area triangles are skipped.
pub fn side(a: DVec3, ring: &[DVec3], h: DVec3) -> f64 {
    let hlen2 = h.length_squared();
    if !positive(hlen2) {
        return 0.0;
    }
    match common_side(a, ring, h, hlen2) {
        Some(s) => s,
        None => chosen_side(a, ring, h, hlen2),
    }
}

/// The triangle choice of [`side`] (3.23)–(3.26), made in full.
fn chosen_side(a: DVec3, ring: &[DVec3], h: DVec3, hlen2: f64) -> f64 {
    let n = ring.len();
    // (category, key, sign): category 0 = inside, 1 = on an edge, 2 = elsewhere.
    let mut best: Option<(u8, f64, f64)> = None;
    for i in 0..n {
        let r2 = ring[i] - a; // r_i2
        let r1 = ring[(i + 1) % n] - a; // r_i1
        let normal = r2.cross(r1);
        let nn = normal.length_squared();
        let (r11, r12, r22) = (r1.length_squared(), r1.dot(r2), r2.length_squared());
        let scale = r11 * r22;
        if !positive(nn - 1e-24 * scale) || !positive(scale) {
            continue; // zero-area triangle: no plane
        }
        let hn = h.dot(normal);
        // (3.23) projects h into the plane: p = h − N (h·N)/|N|². (3.25) solves
        // [r1·r1 r1·r2; r2·r1 r2·r2] [β γ]ᵀ = [r1·p r2·p]ᵀ with det = |r1 × r2|² = |N|².
        // r1 and r2 are orthogonal to N, so r1·p = r1·h and r2·p = r2·h: p itself is not
        // needed. β and γ are kept multiplied by det > 0, which changes neither their signs
        // nor the relative tolerance below (and saves the divisions).
        let (q1, q2) = (r1.dot(h), r2.dot(h));
        let beta = q1 * r22 - q2 * r12;
        let gamma = q2 * r11 - q1 * r12;
        let tol = 1e-9 * (beta.abs() + gamma.abs());
        let pos = |x: f64| x > tol;
        let zero = |x: f64| x.abs() <= tol;
        let category = if pos(beta) && pos(gamma) {
            0
        } else if (zero(beta) && pos(gamma)) || (pos(beta) && zero(gamma)) {
            1
        } else {
            2
        };
        // ‖h − p_i‖² / ‖h‖² = cos² of the angle between h and N_i.
        let cos2 = hn * hn / (nn * hlen2);
        let sign = if cos2 <= 1e-24 { 0.0 } else { hn.signum() };
        // Inside / on an edge: minimise ‖h − p_i‖; elsewhere: the most decisive.
        let key = if category == 2 { -cos2 } else { cos2 };
        if best.is_none_or(|(bc, bk, _)| (category, key) < (bc, bk)) {
            best = Some((category, key, sign));
        }
    }
    best.map_or(0.0, |(_, _, s)| s)
}

/// [`side`] when every fan triangle with a plane has `h` decisively on the same side of
/// it: whichever triangle (3.24)–(3.26) would pick then gives that sign, so the projections
/// and their categories are not needed. `None` when the signs differ, one of them is not
/// decisive (`cos² ≤ 1e-24`, which [`side`] reads as 0) or no triangle has a plane; [`side`]
/// then makes the full choice. On a scan nearly every vertex takes this path: the fan
/// triangles face roughly one way and `h` lies along them (perf on the 400k-triangle face:
/// `side` was 6 % of the whole run's CPU time, issue #8).
#[inline]
fn common_side(a: DVec3, ring: &[DVec3], h: DVec3, hlen2: f64) -> Option<f64> {
    let n = ring.len();
    let mut common = None;
    for i in 0..n {
        let r2 = ring[i] - a;
        let r1 = ring[if i + 1 == n { 0 } else { i + 1 }] - a;
        let normal = r2.cross(r1);
        let nn = normal.length_squared();
        let scale = r1.length_squared() * r2.length_squared();
        // The same test for "no plane" as in `side`.
        if !positive(nn - 1e-24 * scale) || !positive(scale) {
            continue;
        }
        let hn = h.dot(normal);
        let cos2 = hn * hn / (nn * hlen2);
        if cos2.is_nan() || cos2 <= 1e-24 {
            return None;
        }
        let sign = hn.signum();
        match common {
            None => common = Some(sign),
            Some(s) if s != sign => return None,
            Some(_) => {}
        }
    }
    common
}

/// The scaled offset `t*` from the minimiser that gives the ratio `r = H^{k+1}/H^k`
/// (§3.6.3, eqs. 3.30–3.35), solved in closed form.
///
/// With `t = 1 + α`, (3.30) reads `r = f(t) = t / (P t² + (1 − P))`. The thesis takes the
/// root of the quadratic (3.31) inside `(α_min, α_max)` (3.32, 3.33), the rising branch
/// `|t| < √((1−P)/P)`, and when there is no root the extremum whose ratio has the sign of
/// `r` (3.34, 3.35). That whole rule is `t* = 2r(1−P) / (1 + √(1 − 4r²P(1−P)))` when the
/// root exists, else `sign(r)·√((1−P)/P)`; the stable form never divides by a vanishing
/// leading coefficient. (Checked against the literal quadratic + interval rule in the
/// tests.)
pub fn step_scale(p: f64, r: f64) -> f64 {
    let (a, b) = (p, 1.0 - p);
    let disc = 1.0 - 4.0 * r * r * a * b;
    if disc >= 0.0 {
        2.0 * r * b / (1.0 + disc.sqrt())
    } else {
        r.signum() * (b / a).sqrt()
    }
}

/// The non-uniformity vector **U** of vertex `a` with closed ring `ring` (§3.7.1, eq. 3.36,
/// i.e. 3.17): `U = 1/n Σ −P_{d_i}((a − a_{i−1}) + (a − a_{i+1})) / 2` with
/// `d_i = a_{i+1} − a_{i−1}` and `P_{d_i}` the projection onto `d_i` (3.14).
/// Terms with `d_i = 0` (coincident ring vertices) contribute nothing.
pub fn nonuniformity(a: DVec3, ring: &[DVec3]) -> DVec3 {
    let n = ring.len();
    if n == 0 {
        return DVec3::ZERO;
    }
    let mut sum = DVec3::ZERO;
    for i in 0..n {
        let prev = ring[(i + n - 1) % n];
        let next = ring[(i + 1) % n];
        let d = next - prev;
        let dd = d.length_squared();
        if !positive(dd) {
            continue;
        }
        let w = (a - prev) + (a - next);
        sum -= d * (d.dot(w) / (2.0 * dd));
    }
    sum / n as f64
}

// ---------------------------------------------------------------------------------------
// Sweeps over the mesh: the thesis' Gauss–Seidel order and the fast parallel Jacobi order.
// ---------------------------------------------------------------------------------------

/// The interior a surface sweep works on.
pub struct Interior<'a> {
    pub nb: &'a Neighbourhood,
    /// Vertices the surface step may move: a closed fan and not fixed by a guard.
    pub movable: &'a [bool],
    /// How many entries of `movable` are true (the divisor of the mean displacement).
    pub movable_count: usize,
    /// Every triangle's vertices, for the fast sweep's global flip check.
    pub triangles: &'a [[u32; 3]],
    /// Every triangle's reference at the start of the step (see
    /// [`check_triangle`](super::guards::check_triangle)).
    pub references: &'a [Reference],
    /// Zero tolerance on `H`, absolute (the thesis' `epsilon` divided by the mean edge
    /// length: docs/fairing.md reading F6; an absolute 1e-4 in 1/length would depend on units).
    pub eps: f64,
    /// `relax`: the positions at the start of the step; non-uniformity moves are put
    /// back onto the surface the vertex's fan had then (see [`super::Plan::tangential`]).
    /// `None` for `fair`.
    pub input: Option<&'a [DVec3]>,
}

impl Interior<'_> {
    /// `c` put back onto `v`'s fan as it was at the start of the step (relax only): the
    /// closest point of its triangles. The move then slides the vertex over the surface
    /// it had and changes its shape by no more than resampling it.
    #[inline]
    fn on_input_surface(&self, v: usize, c: DVec3) -> DVec3 {
        let Some(input) = self.input else {
            return c;
        };
        let ring = self.nb.ring(v);
        closest_on_fan(c, input[v], ring.len(), |i| input[ring[i] as usize])
    }
}

/// What a thesis-order sweep has moved so far: the sum and the largest of the distances.
#[derive(Default)]
struct Moved {
    sum: f64,
    max: f64,
}

impl Moved {
    /// Moves vertex `v` from `a` towards `candidate` as far as the guards on its closed fan
    /// (`ring`, `references`) allow, writing the new position back at once.
    #[allow(clippy::too_many_arguments)]
    fn guarded(
        &mut self,
        positions: &mut [DVec3],
        v: usize,
        a: DVec3,
        candidate: DVec3,
        ring: &[DVec3],
        references: &[Reference],
        guards: &mut GuardCounts,
    ) {
        let fan = Fan {
            ring,
            closed: true,
            references,
        };
        let (p, g) = guarded_move(a, candidate, fan);
        guards.record(g);
        positions[v] = p;
        let d = (p - a).length();
        self.sum += d;
        self.max = self.max.max(d);
    }

    /// The sweep's figures: every movable vertex counts as updated.
    fn sweep(self, it: &Interior) -> Sweep {
        Sweep {
            mean: self.sum / it.movable_count.max(1) as f64,
            max: self.max,
            updates: it.movable_count,
            halt: false,
        }
    }
}

/// The references of `v`'s fan triangles.
#[inline]
fn gather_references(it: &Interior, v: usize, buf: &mut Vec<Reference>) {
    buf.clear();
    buf.extend(it.nb.fan(v).iter().map(|&t| it.references[t as usize]));
}

#[inline]
fn gather(positions: &[DVec3], ring: &[u32], buf: &mut Vec<DVec3>) {
    buf.clear();
    buf.extend(ring.iter().map(|&j| positions[j as usize]));
}

/// Curvature and its side in the vertex's own ring orientation.
#[derive(Debug, Clone, Copy, Default)]
struct Sided {
    c: VertexCurvature,
    side: f64,
}

/// Vertex `v`'s [`Sided`], its ring gathered into `buf`.
fn sided(positions: &[DVec3], nb: &Neighbourhood, v: usize, buf: &mut Vec<DVec3>) -> Sided {
    gather(positions, nb.ring(v), buf);
    sided_at(positions[v], buf)
}

/// The [`Sided`] of a vertex at `a` whose ring is at `ring`.
fn sided_at(a: DVec3, ring: &[DVec3]) -> Sided {
    let c = curvature(a, ring);
    let side = side(a, ring, c.vector);
    Sided { c, side }
}

/// The new position of a vertex from its curvature and `H̄` (3.21, 3.22, 3.28, §3.6.4);
/// `None` when it does not move.
fn curvature_target(a: DVec3, own: &Sided, hbar: f64, lambda: f64, eps: f64) -> Option<DVec3> {
    let h = own.c.magnitude;
    if h < eps {
        return None; // §3.6.4 case 1: H = 0 → α = 0
    }
    let to_min = own.c.to_minimiser?; // singular B (degenerate fan): no step defined
    let target = (1.0 - lambda) * h + lambda * hbar;
    // H^{k+1} = H^k: α = 0 is a root of (3.31) and the vertex stays. The thesis' rule takes
    // the root on the rising branch (§3.6.3), which for a vertex beyond the curvature peak
    // is the other one: the regular tetrahedron (P = 0.89) and octahedron (P = 0.67) would
    // then move, although §3.8.1 reports every regular polyhedron unchanged. Correctness
    // wins: a vertex whose curvature already has its target value does not move.
    if (target - h).abs() < eps {
        return None;
    }
    // §3.6.4 case 2: H^{k+1} = 0 → α = −1, the vertex jumps to a*.
    let t = if target.abs() < eps {
        0.0
    } else {
        step_scale(own.c.p, target / h)
    };
    // (3.28) a + α B⁻¹â = a* + (1 + α)(a − a*), with t = 1 + α; relative to a: (1 − t)(a* − a).
    Some(a + (1.0 - t) * to_min)
}

/// `H̄` (3.22) restricted to neighbours with a closed fan (4.1–4.3): boundary and
/// non-manifold neighbours have no curvature and are left out, and with none left
/// `H̄ = 0`, which is (4.4). Transfer sign = own side × neighbour's side × relative
/// orientation of their rings (§3.6.2: a negative own side flips all neighbour signs).
/// Neighbours with sign 0 still count in `n` (the thesis is silent; the curves' divisor
/// stays 2 when a sign is 0, and this follows it).
///
/// `signed(j)` is neighbour j's side × its curvature magnitude. Sides and orientations are
/// ±1 or 0, so the product is exact in any order; the fast sweep keeps these in an array
/// of their own (8 bytes a vertex instead of the 80 of [`Sided`]: the neighbours' reads were
/// a tenth of `fair`'s time on the 400k-triangle face, perf).
fn mean_neighbour_curvature(
    own_side: f64,
    ring: &[u32],
    orient: &[i8],
    mut signed: impl FnMut(usize) -> f64,
) -> f64 {
    let mut sum = 0.0;
    let mut count = 0u32;
    for (&j, &o) in ring.iter().zip(orient) {
        if o == 0 {
            continue;
        }
        sum += own_side * o as f64 * signed(j as usize);
        count += 1;
    }
    if count == 0 { 0.0 } else { sum / count as f64 }
}

/// One iteration in the thesis' order (§3.5.1): the movable vertices one after another in
/// index order, each moved (guarded) at once to `target(positions, v, ring)`, where `ring`
/// holds its neighbours' current positions; `None` leaves it where it is. Later vertices
/// so see the moves of earlier ones.
fn thesis_sweep(
    positions: &mut [DVec3],
    it: &Interior,
    guards: &mut GuardCounts,
    mut target: impl FnMut(&[DVec3], usize, &[DVec3]) -> Option<DVec3>,
) -> Sweep {
    let mut buf = Vec::new();
    let mut rbuf = Vec::new();
    let mut moved = Moved::default();
    for v in 0..positions.len() {
        if !it.movable[v] {
            continue;
        }
        gather(positions, it.nb.ring(v), &mut buf);
        let Some(candidate) = target(positions, v, &buf) else {
            continue;
        };
        gather_references(it, v, &mut rbuf);
        let a = positions[v];
        moved.guarded(positions, v, a, candidate, &buf, &rbuf, guards);
    }
    moved.sweep(it)
}

/// One curvature iteration in the thesis' order ([`thesis_sweep`]), every quantity from
/// the current positions (the neighbours' curvature included, docs/fairing.md reading F2:
/// the literal reading).
pub fn thesis_curvature_sweep(
    positions: &mut [DVec3],
    it: &Interior,
    lambda: f64,
    guards: &mut GuardCounts,
) -> Sweep {
    let mut nbuf = Vec::new();
    thesis_sweep(positions, it, guards, |positions, v, ring| {
        let a = positions[v];
        let own = sided_at(a, ring);
        let hbar = mean_neighbour_curvature(own.side, it.nb.ring(v), it.nb.orientations(v), |j| {
            let s = sided(positions, it.nb, j, &mut nbuf);
            s.side * s.c.magnitude
        });
        curvature_target(a, &own, hbar, lambda, it.eps)
    })
}

/// One non-uniformity iteration in the thesis' order ([`thesis_sweep`]; §3.7, eq. 3.37
/// with β = λ_u).
pub fn thesis_nonuniformity_sweep(
    positions: &mut [DVec3],
    it: &Interior,
    lambda_u: f64,
    guards: &mut GuardCounts,
) -> Sweep {
    thesis_sweep(positions, it, guards, |positions, v, ring| {
        let a = positions[v];
        Some(it.on_input_surface(v, a + lambda_u * nonuniformity(a, ring)))
    })
}

/// Reusable buffers of the fast sweeps (no allocation per iteration).
#[derive(Debug, Default)]
pub struct FastScratch {
    curv: Vec<Sided>,
    /// Each vertex's side × curvature magnitude, what its neighbours read.
    signed: Vec<f64>,
    candidate: Vec<DVec3>,
    new: Vec<DVec3>,
    /// How many times a vertex's move was halved this iteration (3 = put back).
    level: Vec<u8>,
    /// Why it was first shortened.
    why: Vec<MoveCheck>,
    /// Each triangle's cross product ([`cross_of`]) at the current positions, kept from one
    /// iteration to the next (empty until the step's first commit), so that the flip check
    /// of every triangle gathers its corners once, at the candidate positions.
    cross: Vec<DVec3>,
    /// Whether a vertex's candidate differs from its current position.
    moved: Vec<bool>,
}

/// One curvature iteration of the fast schedule: Jacobi (every vertex from the positions
/// at the start of the iteration), in parallel; deterministic whatever the thread count
/// since every vertex is computed on its own and reductions run in a fixed order.
pub fn fast_curvature_sweep(
    positions: &mut [DVec3],
    it: &Interior,
    lambda: f64,
    guards: &mut GuardCounts,
    scratch: &mut FastScratch,
) -> Sweep {
    let nb = it.nb;
    let old: &[DVec3] = positions;
    scratch.curv.resize(old.len(), Sided::default());
    scratch.signed.resize(old.len(), 0.0);
    scratch
        .curv
        .par_iter_mut()
        .zip(scratch.signed.par_iter_mut())
        .enumerate()
        .for_each_init(Vec::new, |buf, (v, (c, signed))| {
            *c = if nb.is_closed(v) {
                sided(old, nb, v, buf)
            } else {
                Sided::default()
            };
            *signed = c.side * c.c.magnitude;
        });
    let (curv, signed) = (&scratch.curv, &scratch.signed);
    fast_candidates(old, it, &mut scratch.candidate, |v, _| {
        let own = &curv[v];
        let hbar =
            mean_neighbour_curvature(own.side, nb.ring(v), nb.orientations(v), |j| signed[j]);
        curvature_target(old[v], own, hbar, lambda, it.eps)
    });
    commit_parallel(positions, it, guards, scratch)
}

/// One non-uniformity iteration of the fast schedule (Jacobi, parallel).
pub fn fast_nonuniformity_sweep(
    positions: &mut [DVec3],
    it: &Interior,
    lambda_u: f64,
    guards: &mut GuardCounts,
    scratch: &mut FastScratch,
) -> Sweep {
    let old: &[DVec3] = positions;
    fast_candidates(old, it, &mut scratch.candidate, |v, buf| {
        gather(old, it.nb.ring(v), buf);
        let a = old[v];
        Some(it.on_input_surface(v, a + lambda_u * nonuniformity(a, buf)))
    });
    commit_parallel(positions, it, guards, scratch)
}

/// The candidate positions of a fast (Jacobi) iteration, in parallel, all from `old`: a
/// movable vertex `v` goes to `target(v, buf)` (`buf` a scratch vector of the thread) when
/// that is some finite position; every other vertex stays.
fn fast_candidates(
    old: &[DVec3],
    it: &Interior,
    candidate: &mut Vec<DVec3>,
    target: impl Fn(usize, &mut Vec<DVec3>) -> Option<DVec3> + Sync,
) {
    candidate.resize(old.len(), DVec3::ZERO);
    candidate
        .par_iter_mut()
        .enumerate()
        .for_each_init(Vec::new, |buf, (v, out)| {
            *out = old[v];
            if it.movable[v]
                && let Some(c) = target(v, buf)
                && c.is_finite()
            {
                *out = c;
            }
        });
}

/// Vertices per chunk of the fixed-order parallel reductions.
const CHUNK: usize = 4096;

/// Every triangle's check for the move from `old` to `new`, in index order: the bad ones.
/// `cross` holds each triangle's cross product at `old` and is left holding it at `new`;
/// a triangle none of whose corners `moved` is not checked (nothing changed).
fn bad_triangles_all(
    old: &[DVec3],
    new: &[DVec3],
    moved: &[bool],
    cross: &mut [DVec3],
    it: &Interior,
) -> Vec<(u32, MoveCheck)> {
    cross
        .par_iter_mut()
        .enumerate()
        .filter_map(|(t, cross)| {
            let [a, b, c] = it.triangles[t].map(|v| v as usize);
            if !(moved[a] || moved[b] || moved[c]) {
                return None;
            }
            let at_new = [new[a], new[b], new[c]];
            let n_new = cross_of(at_new);
            let n_old = std::mem::replace(cross, n_new);
            let at_old = || [old[a], old[b], old[c]];
            match check_crosses(n_old, at_old, n_new, at_new, it.references[t]) {
                MoveCheck::Ok => None,
                bad => Some((t as u32, bad)),
            }
        })
        .collect()
}

/// [`bad_triangles_all`] for some triangles (ascending) after their corners' moves were
/// shortened: each with its cross product at `new`, which the caller writes back.
fn bad_triangles_again(
    old: &[DVec3],
    new: &[DVec3],
    triangles: &[u32],
    it: &Interior,
) -> Vec<(u32, DVec3, MoveCheck)> {
    triangles
        .par_iter()
        .map(|&t| {
            let [a, b, c] = it.triangles[t as usize].map(|v| v as usize);
            let at_new = [new[a], new[b], new[c]];
            let n_new = cross_of(at_new);
            let check = if new[a] == old[a] && new[b] == old[b] && new[c] == old[c] {
                MoveCheck::Ok
            } else {
                let at_old = [old[a], old[b], old[c]];
                let reference = it.references[t as usize];
                check_crosses(cross_of(at_old), || at_old, n_new, at_new, reference)
            };
            (t, n_new, check)
        })
        .collect()
}

/// Writes the candidate moves, shortened where they would flip or degenerate a triangle
/// (the same rule as [`guarded_move`], applied to all vertices at once): every moved
/// vertex of a bad triangle has its move halved, up to twice, then put back, and the
/// triangles around it are checked again, until no triangle is bad. Each pass is a
/// parallel filter with an ordered result, so the outcome does not depend on threads.
fn commit_parallel(
    positions: &mut [DVec3],
    it: &Interior,
    guards: &mut GuardCounts,
    scratch: &mut FastScratch,
) -> Sweep {
    let n = positions.len();
    let FastScratch {
        candidate,
        new,
        level,
        why,
        cross,
        moved,
        ..
    } = scratch;
    // The copies and the counts below run on both cores: between the sweep's parallel
    // passes, one core copying 4.8 MB (a 400k-triangle scan) left the other idle, about
    // 1 ms a sweep. A copy and a count of integers are the same in any order.
    new.clear();
    new.par_extend(candidate.par_iter().copied());
    level.clear();
    level.resize(n, 0);
    why.clear();
    why.resize(n, MoveCheck::Ok);
    if cross.len() != it.triangles.len() {
        *cross = it
            .triangles
            .par_iter()
            .map(|tri| cross_of(tri.map(|v| positions[v as usize])))
            .collect();
    }
    debug_assert!(
        it.triangles
            .iter()
            .zip(cross.iter())
            .all(|(tri, c)| { cross_of(tri.map(|v| positions[v as usize])) == *c })
    );
    moved.clear();
    moved.par_extend(new.par_iter().zip(&*positions).map(|(n, o)| n != o));
    let moves = Moves {
        old: positions,
        candidate,
        moved,
    };
    shorten_bad_moves(&moves, new, level, why, cross, it);
    let counts = level
        .par_iter()
        .zip(why.par_iter())
        .fold(GuardCounts::default, |mut g, (l, w)| {
            match *l {
                0 => {}
                1 | 2 => g.record(Guarded::Shortened(*w)),
                _ => g.record(Guarded::Skipped(*w)),
            }
            g
        })
        .reduce(GuardCounts::default, |mut a, b| {
            a.add(b);
            a
        });
    guards.add(counts);
    let (sum, max) = move_lengths(new, positions);
    positions
        .par_iter_mut()
        .zip(new.par_iter())
        .for_each(|(p, n)| *p = *n);
    Sweep {
        mean: sum / it.movable_count.max(1) as f64,
        max,
        updates: it.movable_count,
        halt: false,
    }
}

/// The passes of [`commit_parallel`]: while a triangle is bad, each moved vertex of a bad
/// triangle goes one `level` back (half, a quarter of its `candidate` move, then none),
/// `why` keeps the first reason, and only the triangles around those vertices are checked
/// again.
fn shorten_bad_moves(
    moves: &Moves,
    new: &mut [DVec3],
    level: &mut [u8],
    why: &mut [MoveCheck],
    cross: &mut [DVec3],
    it: &Interior,
) {
    let Moves {
        old,
        candidate,
        moved,
    } = *moves;
    let mut bad = bad_triangles_all(old, new, moved, cross, it);
    if bad.is_empty() {
        return;
    }
    let (mut touched, mut around) = (Vec::new(), Vec::new());
    let mut vertex_marks = Marks::new(old.len());
    let mut triangle_marks = Marks::new(it.triangles.len());
    while !bad.is_empty() {
        for &(t, reason) in &bad {
            for v in it.triangles[t as usize] {
                let vi = v as usize;
                if new[vi] != old[vi] {
                    vertex_marks.insert(v);
                    if why[vi] == MoveCheck::Ok {
                        why[vi] = reason;
                    }
                }
            }
        }
        vertex_marks.take_into(&mut touched);
        for &v in &touched {
            let vi = v as usize;
            level[vi] += 1;
            let f = match level[vi] {
                1 => 0.5,
                2 => 0.25,
                _ => 0.0,
            };
            new[vi] = old[vi] + f * (candidate[vi] - old[vi]);
        }
        // Moved vertices are movable, so manifold with a closed fan: their fan is all the
        // triangles around them.
        for &v in &touched {
            for &t in it.nb.fan(v as usize) {
                triangle_marks.insert(t);
            }
        }
        triangle_marks.take_into(&mut around);
        let checked = bad_triangles_again(old, new, &around, it);
        bad.clear();
        for (t, n_new, check) in checked {
            cross[t as usize] = n_new;
            if check != MoveCheck::Ok {
                bad.push((t, check));
            }
        }
    }
}

/// A set of indices below a fixed bound, handed out in ascending order: what sorting a list
/// of indices and removing its repeats gives, without the sort. On a photogrammetry scan the
/// flip check shortens many moves per iteration, and sorting the shortened vertices' fans
/// was about 1 % of the face-scan run's CPU on the 400k coral (perf), on one core while the
/// other waited.
struct Marks {
    words: Vec<u64>,
}

impl Marks {
    /// An empty set of indices below `n`.
    fn new(n: usize) -> Self {
        Marks {
            words: vec![0; n.div_ceil(64)],
        }
    }

    #[inline]
    fn insert(&mut self, i: u32) {
        self.words[i as usize / 64] |= 1 << (i % 64);
    }

    /// The indices in ascending order into `out` (cleared first); the set is left empty.
    fn take_into(&mut self, out: &mut Vec<u32>) {
        out.clear();
        for (k, word) in self.words.iter_mut().enumerate() {
            let mut bits = std::mem::take(word);
            while bits != 0 {
                out.push((k * 64) as u32 + bits.trailing_zeros());
                bits &= bits - 1;
            }
        }
    }
}

/// One iteration's moves: from `old` towards `candidate`, `moved` where they differ.
#[derive(Clone, Copy)]
struct Moves<'a> {
    old: &'a [DVec3],
    candidate: &'a [DVec3],
    moved: &'a [bool],
}

/// The sum and the largest of the distances from `old` to `new`, in fixed-size chunks
/// summed in order, so the result does not depend on threads.
fn move_lengths(new: &[DVec3], old: &[DVec3]) -> (f64, f64) {
    let partial: Vec<(f64, f64)> = new
        .par_chunks(CHUNK)
        .zip(old.par_chunks(CHUNK))
        .map(|(n, o)| {
            n.iter().zip(o).fold((0.0, 0.0f64), |(s, m), (p, q)| {
                let d = (*p - *q).length();
                (s + d, m.max(d))
            })
        })
        .collect();
    partial
        .into_iter()
        .fold((0.0, 0.0f64), |(s, m), (a, b)| (s + a, m.max(b)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hexagon_fan(height: f64) -> (DVec3, Vec<DVec3>) {
        let ring = (0..6)
            .map(|i| {
                let t = std::f64::consts::TAU * i as f64 / 6.0;
                DVec3::new(t.cos(), t.sin(), 0.0)
            })
            .collect();
        (DVec3::new(0.0, 0.0, height), ring)
    }

    #[test]
    fn marks_hand_out_what_sorting_and_dedup_give() {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = |bound: u64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % bound) as u32
        };
        let mut marks = Marks::new(1000);
        let mut out = vec![7, 7, 7];
        for round in 0..20 {
            let count = next(300) as usize;
            let mut list: Vec<u32> = (0..count).map(|_| next(1000)).collect();
            if round == 0 {
                list = vec![0, 999, 63, 64, 64, 0];
            }
            for &i in &list {
                marks.insert(i);
            }
            marks.take_into(&mut out);
            list.sort_unstable();
            list.dedup();
            assert_eq!(out, list, "round {round}");
        }
        marks.take_into(&mut out);
        assert!(out.is_empty(), "taking empties the set");
    }

    #[test]
    fn pyramid_over_hexagon_matches_the_closed_form() {
        // Derived from (3.13): H(h) = 3/2 · h / (h² + 3/4) over a unit hexagon.
        for h in [0.1, 0.5, 3f64.sqrt() / 2.0, 2.0] {
            let (a, ring) = hexagon_fan(h);
            let c = curvature(a, &ring);
            let expected = 1.5 * h / (h * h + 0.75);
            assert!((c.magnitude - expected).abs() < 1e-12, "{h}");
            assert!(c.vector.z > 0.0, "outward at a convex apex");
            let astar = a + c.to_minimiser.unwrap();
            assert!(astar.length() < 1e-12, "minimiser is the hexagon centre");
        }
    }

    #[test]
    fn planar_square_fan_slides_tangentially() {
        // From (3.13): neighbours at (±1,0,0), (0,±1,0); H = 0, 0.288, 0.6, 0.732.
        let ring = [DVec3::X, DVec3::Y, DVec3::NEG_X, DVec3::NEG_Y];
        for (x, h) in [(0.0, 0.0), (0.2, 0.288), (0.5, 0.6), (0.8, 0.732)] {
            let c = curvature(DVec3::new(x, 0.0, 0.0), &ring);
            assert!((c.magnitude - h).abs() < 1e-3, "{x}: {}", c.magnitude);
        }
    }

    #[test]
    fn side_follows_orientation() {
        let (a, ring) = hexagon_fan(0.3);
        let c = curvature(a, &ring);
        // Ring counter-clockwise seen from +z: fan normals point up, H points up.
        assert_eq!(side(a, &ring, c.vector), 1.0);
        assert_eq!(side(a, &ring, -c.vector), -1.0);
        let reversed: Vec<_> = ring.iter().rev().copied().collect();
        assert_eq!(side(a, &reversed, c.vector), -1.0);
        assert_eq!(side(a, &ring, DVec3::ZERO), 0.0);
    }

    /// The shortcut for fans on one side of `h` gives what the full choice gives, on fans
    /// that are flat, curved, saddle-shaped, folded or with a zero-area triangle, and for
    /// `h` along the fan, across it and in its plane.
    #[test]
    fn common_side_agrees_with_the_full_choice() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut rand = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let (mut shortcut, mut full) = (0, 0);
        for case in 0..20_000 {
            let n = 3 + case % 7;
            let a = DVec3::new(rand(), rand(), rand()) * 0.2;
            let mut ring: Vec<DVec3> = (0..n)
                .map(|i| {
                    let t = std::f64::consts::TAU * (i as f64 + 0.4 * rand()) / n as f64;
                    let height = match case % 4 {
                        0 => 0.05 * rand(),         // nearly flat
                        1 => 0.5 * rand(),          // rough
                        2 => 0.4 * (2.0 * t).cos(), // saddle
                        _ => {
                            if i % 2 == 0 {
                                0.8
                            } else {
                                -0.8
                            }
                        } // folded
                    };
                    DVec3::new(t.cos(), t.sin(), height)
                })
                .collect();
            if case % 11 == 0 {
                ring[1] = ring[0]; // a zero-area triangle
            }
            let c = curvature(a, &ring);
            let along_plane = (ring[1] - ring[0]).normalize_or_zero();
            for h in [
                c.vector,
                -c.vector,
                DVec3::new(rand(), rand(), rand()),
                along_plane,
            ] {
                let hlen2 = h.length_squared();
                let expected = if positive(hlen2) {
                    chosen_side(a, &ring, h, hlen2)
                } else {
                    0.0
                };
                assert_eq!(side(a, &ring, h), expected, "case {case}, h {h}");
                if positive(hlen2) && common_side(a, &ring, h, hlen2).is_some() {
                    shortcut += 1;
                } else {
                    full += 1;
                }
            }
        }
        // Both paths were exercised.
        assert!(shortcut > 10_000 && full > 10_000, "{shortcut} {full}");
    }

    /// The thesis' literal rule (3.31–3.35): the quadratic's root inside (α_min, α_max),
    /// or the extremum of matching sign when there is none.
    fn literal_alpha(p: f64, h: f64, hn: f64) -> f64 {
        let ratio = |alpha: f64| {
            let t = 1.0 + alpha;
            t / (p * t * t + 1.0 - p)
        };
        let g_over_d = p / (1.0 - p);
        let root = (1.0 / g_over_d).sqrt();
        let (amin, amax) = (-1.0 - root, -1.0 + root);
        let (qa, qb, qc) = (hn * p, 2.0 * hn * p - h, hn - h);
        let disc = qb * qb - 4.0 * qa * qc;
        if disc >= 0.0 && qa != 0.0 {
            let s = disc.sqrt();
            for alpha in [(-qb - s) / (2.0 * qa), (-qb + s) / (2.0 * qa)] {
                if alpha > amin && alpha < amax {
                    return alpha;
                }
            }
        }
        let r = hn / h;
        if r.signum() == ratio(amin).signum() {
            amin
        } else {
            amax
        }
    }

    #[test]
    fn closed_form_root_matches_the_thesis_selection() {
        let mut lcg = crate::testing::Lcg(12345);
        let mut rand = || lcg.unit();
        for _ in 0..20000 {
            let p = 0.02 + 0.96 * rand();
            let h = 0.1 + rand();
            let hn = (rand() * 4.0 - 2.0) * h;
            if hn.abs() < 1e-3 {
                continue;
            }
            let alpha = step_scale(p, hn / h) - 1.0;
            let literal = literal_alpha(p, h, hn);
            assert!(
                (alpha - literal).abs() < 1e-6 * (1.0 + literal.abs()),
                "p {p} r {}: {alpha} vs {literal}",
                hn / h
            );
        }
    }

    #[test]
    fn step_reaches_the_target_curvature() {
        let (a, ring) = hexagon_fan(0.4);
        let c = curvature(a, &ring);
        for r in [0.9, 0.5, 1.1, -0.3] {
            let t = step_scale(c.p, r);
            let astar = a + c.to_minimiser.unwrap();
            let moved = astar + t * (a - astar);
            let after = curvature(moved, &ring);
            let signed = after.magnitude * after.vector.dot(c.vector).signum();
            assert!((signed - r * c.magnitude).abs() < 1e-9, "{r}");
        }
    }

    #[test]
    fn nonuniformity_is_zero_at_the_centre_and_tangential() {
        let (a, ring) = hexagon_fan(0.0);
        assert!(nonuniformity(a, &ring).length() < 1e-15);
        let off = DVec3::new(0.2, 0.1, 0.3);
        let u = nonuniformity(off, &ring);
        assert!(u.z.abs() < 1e-15, "parallel to the neighbours' plane");
        assert!(u.dot(off) < 0.0, "points back to the centre");
    }
}
