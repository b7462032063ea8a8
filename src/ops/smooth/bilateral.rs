//! Bilateral mesh denoising (thesis §3.5; the thesis gives no formula, so the update is
//! Fleishman, Drori & Cohen-Or 2003, "Bilateral mesh denoising", its "DenoisePoint"):
//!
//! ```text
//! N(v) = { q_k : ‖v − q_k‖ < ρ },  t_k = ‖v − q_k‖,  h_k = ⟨n, v − q_k⟩
//! w_k = exp(−t_k²/2σ_c²) · exp(−h_k²/2σ_s²)
//! v̂ = v − n · Σ w_k h_k / Σ w_k
//! ```
//!
//! Choices where the thesis is silent, each following Fleishman et al.
//! unless said otherwise:
//! - ρ = 2σ_c unless `radius` is given.
//! - The candidates are the vertex's order-k neighbourhood (thesis §2.4.2, Fig. 2.1; the
//!   thesis never says which order its BMDS used), `rings = 3` by default, of which
//!   those inside the ρ-ball count. Gathering through the mesh rather than from all vertices
//!   in space needs no spatial index, and a thin part (a lip, an ear) is not pulled towards
//!   the surface across the gap. With the default ρ = 1.8 mean edges the 3-ring holds
//!   99.995 % of the vertices a breadth-first search inside the ball finds on igea (the
//!   2-ring only 94 %). The rings are topology, so they are built once per step; each
//!   iteration only filters them by distance, twice as fast as searching every time. The
//!   order within a vertex's list (those inside the ball at the start first) only decides
//!   how fast the filter skips the rest, and the order of the sums.
//! - The vertex itself is left out of N(v) (thesis §2.4.2); it would only add weight
//!   1 with h = 0 and damp the move.
//! - n is the area-weighted average of the 1-ring face normals, recomputed from the current
//!   mesh before every iteration; updates are buffered.
//! - An empty neighbourhood, a zero normal or underflowing weights leave the vertex where it
//!   is (counted in the report).
//! - The filter computes in single precision, on positions taken relative to the bounding
//!   box's centre, and adds each move to the double-precision position. The weights and the
//!   move need no more: the compare metrics on igea, lucy and the bunny (σ = 0.2 noise) are
//!   the same to the four digits printed as in double precision, and a pass is faster
//!   (half the bytes per candidate, four or eight lanes per vector; docs/smoothing.md,
//!   "Speed").

use super::{BilateralParams, CHUNK, SmoothGraph, par_for_each_indexed};
use crate::mesh::model::bounding_box_of;
use crate::mesh::topology::Topology;
use glam::{DVec3, Mat4, Vec3A, Vec4};
use rayon::prelude::*;

pub(super) struct BilateralOutcome {
    pub passes: u32,
    pub empty_neighbourhoods: u64,
    /// Neighbours used (inside the ρ-ball), summed over all updates.
    pub neighbours: u64,
    /// How many of them came from the outermost ring searched.
    pub outer_ring_neighbours: u64,
}

/// What the filter needs of the mesh's connectivity, built once per step: each vertex's
/// candidates ([`Rings`]) and the triangles' order for the vertex normals ([`NormalPlan`]).
#[derive(Default)]
pub struct Prepared {
    rings: Rings,
    normals: NormalPlan,
}

impl Prepared {
    /// See [`Rings::new`] for `order`, `positions` and `radius`.
    pub fn new(topology: &Topology, order: u32, positions: &[DVec3], radius: f64) -> Prepared {
        Prepared {
            rings: Rings::new(topology, order, positions, radius),
            normals: NormalPlan::new(topology),
        }
    }
}

/// Each vertex's order-k neighbourhood without the vertex itself (CSR), those inside the
/// ρ-ball when the rings were built first, padded to whole groups of [`LANES`] with the
/// index n (a point far outside every ball). Each group has a byte saying which of its
/// candidates come from the outermost ring: one of them inside the ρ-ball means the ball
/// may reach beyond the rings.
#[derive(Debug, Clone, Default)]
pub struct Rings {
    offsets: Vec<u32>,
    list: Vec<u32>,
    /// Per group of [`LANES`] candidates, bit l: lane l is from the outermost ring.
    outer: Vec<u8>,
    /// The vertex count n: every index in `list` is at most n.
    vertices: usize,
}

/// Flag bit of a candidate from the outermost ring, while the lists are built.
const OUTER: u32 = 1 << 31;

/// One vertex's candidates. Only [`Rings::of`] makes one, and every index in it is at most
/// `bound`: the AVX2 kernel relies on that for its unchecked loads.
#[derive(Clone, Copy)]
struct Candidates<'a> {
    /// Vertex indices, whole groups of [`LANES`], each at most `bound`.
    ids: &'a [u32],
    /// One byte per group: bit l for a candidate of the outermost ring in lane l.
    outer: &'a [u8],
    bound: usize,
}

impl Rings {
    /// `positions` and `radius` (the ρ-ball's, model units) order each list: the candidates
    /// inside the ball as the mesh stands first, so that they fill the first groups and the
    /// filter skips the weights of the groups after, wholly outside (the ball moves little
    /// between iterations).
    pub fn new(topology: &Topology, order: u32, positions: &[DVec3], radius: f64) -> Rings {
        let radius_sq = radius * radius;
        let n = topology.vertex_count();
        assert!(n < OUTER as usize, "too many vertices for the ring lists");
        let block = n.div_ceil(4 * rayon::current_num_threads()).max(1024);
        // Blocks of vertices in parallel, each with its own marks; concatenated in order.
        let parts: Vec<(Vec<u32>, Vec<u32>, Vec<u8>)> = (0..n.div_ceil(block))
            .into_par_iter()
            .map(|b| {
                let (first, last) = (b * block, ((b + 1) * block).min(n));
                // mark[j] == i + 1: j already listed for vertex i (zeroed pages are free).
                let mut mark = vec![0u32; n];
                let (mut counts, mut list) = (Vec::with_capacity(last - first), Vec::new());
                let mut outer = Vec::new();
                let (mut by_ball, mut outside): (Vec<u32>, Vec<u32>) = (Vec::new(), Vec::new());
                for i in first..last {
                    let stamp = i as u32 + 1;
                    mark[i] = stamp;
                    let start = list.len();
                    let mut ring_start = start;
                    list.extend(topology.vertex_neighbours(i as u32).iter().copied());
                    for &j in &list[start..] {
                        mark[j as usize] = stamp;
                    }
                    for _ in 1..order {
                        let ring_end = list.len();
                        for r in ring_start..ring_end {
                            for &j in topology.vertex_neighbours(list[r]) {
                                if mark[j as usize] != stamp {
                                    mark[j as usize] = stamp;
                                    list.push(j);
                                }
                            }
                        }
                        ring_start = ring_end;
                    }
                    for j in &mut list[ring_start..] {
                        *j |= OUTER;
                    }
                    // Those inside the ball first, each part in breadth-first order (a
                    // stable partition, linear).
                    let centre = positions[i];
                    by_ball.clear();
                    outside.clear();
                    for &j in &list[start..] {
                        let p = positions[(j & !OUTER) as usize];
                        if p.distance_squared(centre) < radius_sq {
                            by_ball.push(j);
                        } else {
                            outside.push(j);
                        }
                    }
                    by_ball.extend_from_slice(&outside);
                    list[start..].copy_from_slice(&by_ball);
                    let padded = (list.len() - start).next_multiple_of(LANES);
                    list.resize(start + padded, n as u32);
                    counts.push(padded as u32);
                    // The flags move to a byte per group, so that the lists hold plain
                    // indices the filter can load without masking them.
                    for group in list[start..].chunks_exact_mut(LANES) {
                        outer.push(
                            group
                                .iter()
                                .rev()
                                .fold(0u8, |m, &j| m << 1 | u8::from(j & OUTER != 0)),
                        );
                        for j in group {
                            *j &= !OUTER;
                        }
                    }
                }
                (counts, list, outer)
            })
            .collect();
        Rings::joined(parts, n)
    }

    /// The blocks' lists (per block: each vertex's padded count, the lists, the groups'
    /// outer flags) in one table of `n` vertices.
    fn joined(parts: Vec<(Vec<u32>, Vec<u32>, Vec<u8>)>, n: usize) -> Rings {
        let mut rings = Rings {
            offsets: Vec::with_capacity(n + 1),
            list: Vec::with_capacity(parts.iter().map(|p| p.1.len()).sum()),
            outer: Vec::with_capacity(parts.iter().map(|p| p.2.len()).sum()),
            vertices: n,
        };
        rings.offsets.push(0);
        for (counts, list, outer) in parts {
            for c in counts {
                let last = *rings.offsets.last().expect("starts with 0");
                rings.offsets.push(last + c);
            }
            rings.list.extend(list);
            rings.outer.extend(outer);
        }
        rings
    }

    #[inline]
    fn of(&self, i: usize) -> Candidates<'_> {
        let (first, last) = (self.offsets[i] as usize, self.offsets[i + 1] as usize);
        Candidates {
            ids: &self.list[first..last],
            outer: &self.outer[first / LANES..last / LANES],
            bound: self.vertices,
        }
    }
}

/// The working copy the filter reads: positions in single precision, relative to `centre`
/// so that differences of nearby vertices keep their precision (a scan far from the origin
/// loses none), one 16-byte vector each (w = 0). Its length is a power of two above the
/// vertex count, the rest filled with a point far away (the padding of the candidate lists
/// refers to index n). The normals index it with `index & (len − 1)`, in bounds by
/// construction, so that their loops need no bounds check; the AVX2 filter, whose
/// candidates are all at most n, loads them unchecked after one assertion per vertex.
struct WorkingCopy {
    x: Vec<Vec4>,
}

impl WorkingCopy {
    fn new(n: usize) -> WorkingCopy {
        WorkingCopy {
            x: vec![Vec4::new(FAR, FAR, FAR, 0.0); (n + 1).next_power_of_two()],
        }
    }

    fn update(&mut self, positions: &[DVec3], centre: DVec3) {
        self.x[..positions.len()]
            .par_iter_mut()
            .zip(positions.par_iter())
            .for_each(|(l, &p)| *l = WorkingCopy::point(p, centre));
    }

    #[inline]
    fn point(p: DVec3, centre: DVec3) -> Vec4 {
        (p - centre).as_vec3().extend(0.0)
    }
}

/// The mask that keeps a vertex index inside the working copy `x` (see [`WorkingCopy`]):
/// `len − 1`. The compiler sees `i & (len − 1) < len`, so the lookups after it carry no
/// bounds check.
#[inline]
fn index_mask(x: &[Vec4]) -> usize {
    assert!(
        x.len().is_power_of_two(),
        "the working copy's length is a power of two"
    );
    x.len() - 1
}

/// The triangles in the order the vertex normals read them best.
///
/// Summing each vertex's face normals from a per-triangle array gathers from all over that
/// array when the file lists its triangles in long strips (igea): a vertex's triangles lie
/// in two strips far apart. That gather took twice as long as the same sums read in order
/// (docs/smoothing.md, "Speed"). Here the triangles are sorted by their lowest vertex, so
/// that a vertex's triangles sit near each other and near its neighbours'; each vertex
/// keeps its triangles' places in that order, listed in the original triangle order, so
/// the sums are added in the same order as before: the normals are bit for bit the same.
#[derive(Default)]
struct NormalPlan {
    /// The triangles sorted by their lowest vertex (each keeps its vertex order).
    triangles: Vec<[u32; 3]>,
    /// Per vertex (CSR), the places of its triangles in `triangles`, by ascending original
    /// triangle index.
    offsets: Vec<u32>,
    places: Vec<u32>,
}

impl NormalPlan {
    fn new(topology: &Topology) -> NormalPlan {
        let count = topology.triangle_count();
        let mut order: Vec<u64> = (0..count as u32)
            .into_par_iter()
            .map(|t| {
                let lowest = topology.triangle_vertices(t).into_iter().min();
                u64::from(lowest.expect("three vertices")) << 32 | u64::from(t)
            })
            .collect();
        order.par_sort_unstable();
        let mut place = vec![0u32; count];
        for (p, &key) in order.iter().enumerate() {
            place[key as u32 as usize] = p as u32;
        }
        let triangles = order
            .par_iter()
            .map(|&key| topology.triangle_vertices(key as u32))
            .collect();
        let n = topology.vertex_count();
        let mut offsets = Vec::with_capacity(n + 1);
        let mut places = Vec::with_capacity(3 * count);
        offsets.push(0);
        for v in 0..n as u32 {
            places.extend(topology.vertex_triangles(v).map(|t| place[t as usize]));
            offsets.push(places.len() as u32);
        }
        NormalPlan {
            triangles,
            offsets,
            places,
        }
    }

    #[inline]
    fn places_of(&self, v: usize) -> &[u32] {
        &self.places[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }
}

/// Area-weighted vertex normals (unit, or zero where every face around is degenerate).
fn vertex_normals(plan: &NormalPlan, x: &[Vec4], faces: &mut Vec<Vec3A>, out: &mut [Vec3A]) {
    let mask = index_mask(x);
    faces.clear();
    faces.par_extend(plan.triangles.par_iter().map(|&[a, b, c]| {
        let [a, b, c] = [a, b, c].map(|v| Vec3A::from_vec4(x[v as usize & mask]));
        // |(b − a) × (c − a)| is twice the area: the sum below is area-weighted.
        (b - a).cross(c - a)
    }));
    par_for_each_indexed(out, |v, n| {
        let sum: Vec3A = plan.places_of(v).iter().map(|&p| faces[p as usize]).sum();
        *n = sum.normalize_or_zero();
    });
}

/// Lengths converted to model units, ready for the inner loop.
#[derive(Clone, Copy)]
struct Kernel {
    radius_sq: f32,
    inv_2sc2: f32,
    inv_2ss2: f32,
}

/// Candidates weighed side by side: one group fills the eight lanes of an AVX vector, or
/// two 4-wide vectors where AVX2 is missing. The candidate lists are padded to whole groups.
const LANES: usize = 8;

/// The padding's position: far outside any ball, yet its squared distance still finite in
/// single precision.
const FAR: f32 = 1e18;

/// e^x on four lanes, x ≤ 0, in single precision: relative error below 4e-7 + 1e-7·|x|
/// (x·log₂e is rounded to single precision first), and exactly 0 below e^−87 and for NaN.
/// 2^(x·log₂e) is split into an integer power k (set in the exponent bits) and a fraction
/// in [−½, ½] (degree-6 Taylor series of e^(f·ln 2), truncation error below 1.3e-7). Plain
/// IEEE arithmetic, so it is deterministic on every platform, and branch-free, in vector
/// operations; only 2^k is put together lane by lane (the compiler still keeps it in the
/// register). The weights need nowhere near libm's precision, and libm's `exp` was 45 % of
/// the filter's time on igea (perf). [`avx2::exp_neg8`] does the same operations in the
/// same order on eight lanes, so both give the same bits.
#[inline]
fn exp_neg4(x: Vec4) -> Vec4 {
    let y = x * std::f32::consts::LOG2_E;
    // Also false for NaN.
    let normal = y.cmpge(Vec4::splat(-126.0));
    let y = Vec4::select(normal, y, Vec4::splat(-126.0));
    let shifted = y + EXP_ROUND;
    let k = shifted - EXP_ROUND;
    let r = (y - k) * std::f32::consts::LN_2;
    // Horner's scheme, each step one fused multiply-add.
    let step = |coefficient: f32, inner: Vec4| r.mul_add(inner, Vec4::splat(coefficient));
    let p = step(1.0 / 120.0, Vec4::splat(1.0 / 720.0));
    let p = step(1.0 / 24.0, p);
    let p = step(1.0 / 6.0, p);
    let p = step(0.5, p);
    let p = step(1.0, p);
    let p = step(1.0, p);
    // 2^k: the low 9 bits of (2²² + k) + 127 are k + 127 ∈ [1, 127] (k ∈ [−126, 0]);
    // shifting them into the exponent field drops everything above, and the sign bit is 0.
    let s = shifted.to_array();
    let scale = |s: f32| f32::from_bits(s.to_bits().wrapping_add(127) << 23);
    let scale = Vec4::new(scale(s[0]), scale(s[1]), scale(s[2]), scale(s[3]));
    Vec4::select(normal, p * scale, Vec4::ZERO)
}

/// 1.5·2²³: y + EXP_ROUND leaves 2²² + round(y) in the mantissa bits.
const EXP_ROUND: f32 = 12_582_912.0;

/// What [`denoise_vertex`] sums over a vertex's candidates: Σ w·h and Σ w, the neighbours
/// inside the ball, and how many of them came from the outermost ring.
///
/// Each kernel keeps one sum per lane and adds the lanes up in the same fixed order,
/// `((l0 + l1) + (l2 + l3)) + ((l4 + l5) + (l6 + l7))` ([`add_lanes`]), so that the
/// result depends neither on the thread count nor on which kernel ran.
struct LaneSums {
    wh: f32,
    w: f32,
    inside: u32,
    outer: u32,
}

impl LaneSums {
    /// The move along `n`, or `None` when the weights vanished.
    fn moved(&self, n: Vec3A) -> Option<Vec3A> {
        (self.w > 0.0 && self.wh.is_finite()).then(|| n * -(self.wh / self.w))
    }
}

/// The lanes of a group's sums added up in the order every kernel uses (see [`LaneSums`]).
#[inline]
fn add_lanes(l: [f32; LANES]) -> f32 {
    ((l[0] + l[1]) + (l[2] + l[3])) + ((l[4] + l[5]) + (l[6] + l[7]))
}

/// Fleishman's DenoisePoint (the sums; [`LaneSums::moved`] gives the move), on 4-wide
/// vectors, each group as two halves.
///
/// Written for the vector unit: a group's offsets are loaded as vectors and transposed, so
/// that each coordinate fills one vector. A group with a candidate inside the ball
/// computes all its weights and zeroes those outside (no compaction); a group wholly
/// outside skips them, and since the rings list the ball's candidates first, that is most
/// groups after the first two. Each lane keeps its own sums.
#[inline]
fn denoise_vertex(x: &[Vec4], v: Vec4, n: Vec3A, candidates: Candidates, k: Kernel) -> LaneSums {
    let (nx, ny, nz) = (Vec4::splat(n.x), Vec4::splat(n.y), Vec4::splat(n.z));
    let (radius_sq, inv_2sc2, inv_2ss2) = (
        Vec4::splat(k.radius_sq),
        Vec4::splat(k.inv_2sc2),
        Vec4::splat(k.inv_2ss2),
    );
    let mut sum_wh = [Vec4::ZERO; 2];
    let mut sum_w = [Vec4::ZERO; 2];
    let (mut inside, mut outer) = (0u32, 0u32);
    for (ids, &outer_lanes) in candidates.ids.chunks_exact(LANES).zip(candidates.outer) {
        let half = |o: usize| {
            let at = |l: usize| v - x[ids[o + l] as usize];
            let d = Mat4::from_cols(at(0), at(1), at(2), at(3)).transpose();
            let t2 = d
                .z_axis
                .mul_add(d.z_axis, d.y_axis.mul_add(d.y_axis, d.x_axis * d.x_axis));
            (d, t2, t2.cmplt(radius_sq))
        };
        let halves = [half(0), half(4)];
        let bits = halves[0].2.bitmask() | halves[1].2.bitmask() << 4;
        if bits == 0 {
            // Those inside the ball come first: the last groups usually lie wholly outside.
            continue;
        }
        for (s, (d, t2, hit)) in halves.into_iter().enumerate() {
            let h = nz.mul_add(d.z_axis, ny.mul_add(d.y_axis, nx * d.x_axis));
            let arg = (-(h * h)).mul_add(inv_2ss2, -t2 * inv_2sc2);
            let w = Vec4::select(hit, exp_neg4(arg), Vec4::ZERO);
            sum_wh[s] = w.mul_add(h, sum_wh[s]);
            sum_w[s] += w;
        }
        inside += bits.count_ones();
        outer += (bits & u32::from(outer_lanes)).count_ones();
    }
    let lanes = |s: [Vec4; 2]| {
        let (a, b) = (s[0].to_array(), s[1].to_array());
        [a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]]
    };
    LaneSums {
        wh: add_lanes(lanes(sum_wh)),
        w: add_lanes(lanes(sum_w)),
        inside,
        outer,
    }
}

/// The same filter on 8-wide AVX vectors with fused multiply-adds (AVX2 and FMA),
/// operation for operation as [`denoise_vertex`], so that it gives the same bits. The
/// portable kernel fuses in the same places (`mul_add`: one rounding, exact in IEEE
/// arithmetic on every platform, in hardware where the processor has it), so its bits do
/// not depend on the processor either. This kernel takes about two thirds of the portable
/// one's time on igea, and the fused operations a further tenth (docs/smoothing.md,
/// "Speed").
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{Candidates, Kernel, LANES, LaneSums};
    use glam::{Vec3A, Vec4};
    use std::arch::x86_64::*;

    /// Whether this processor can run [`denoise_vertex`] (it needs both).
    pub(super) fn available() -> bool {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }

    #[inline]
    #[target_feature(enable = "avx2,fma")]
    #[cfg(test)]
    pub(super) fn lanes(v: __m256) -> [f32; LANES] {
        let lo = Vec4::from(_mm256_castps256_ps128(v)).to_array();
        let hi = Vec4::from(_mm256_extractf128_ps::<1>(v)).to_array();
        [lo[0], lo[1], lo[2], lo[3], hi[0], hi[1], hi[2], hi[3]]
    }

    /// [`super::add_lanes`] of both sums at once, adding the same pairs in the same
    /// order: each `hadd` adds neighbouring lanes, and addition is commutative bit for
    /// bit, so `l1 + l0` is `l0 + l1`.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn add_lanes(wh: __m256, w: __m256) -> (f32, f32) {
        // (wh0+wh1, wh2+wh3, w0+w1, w2+w3 | wh4+wh5, wh6+wh7, w4+w5, w6+w7)
        let pairs = _mm256_hadd_ps(wh, w);
        // (wh0123, w0123, … | wh4567, w4567, …)
        let quads = _mm256_hadd_ps(pairs, pairs);
        let total = _mm_add_ps(
            _mm256_castps256_ps128(quads),
            _mm256_extractf128_ps::<1>(quads),
        );
        let total = Vec4::from(total);
        (total.x, total.y)
    }

    /// [`super::exp_neg4`] on eight lanes.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn exp_neg8(x: __m256) -> __m256 {
        let c = _mm256_set1_ps;
        let y = _mm256_mul_ps(x, c(std::f32::consts::LOG2_E));
        let normal = _mm256_cmp_ps::<_CMP_GE_OQ>(y, c(-126.0));
        let y = _mm256_blendv_ps(c(-126.0), y, normal);
        let shifted = _mm256_add_ps(y, c(super::EXP_ROUND));
        let k = _mm256_sub_ps(shifted, c(super::EXP_ROUND));
        let r = _mm256_mul_ps(_mm256_sub_ps(y, k), c(std::f32::consts::LN_2));
        let step = |coefficient: f32, inner: __m256| _mm256_fmadd_ps(r, inner, c(coefficient));
        let p = step(1.0 / 120.0, c(1.0 / 720.0));
        let p = step(1.0 / 24.0, p);
        let p = step(1.0 / 6.0, p);
        let p = step(0.5, p);
        let p = step(1.0, p);
        let p = step(1.0, p);
        let bits = _mm256_add_epi32(_mm256_castps_si256(shifted), _mm256_set1_epi32(127));
        let scale = _mm256_castsi256_ps(_mm256_slli_epi32::<23>(bits));
        _mm256_and_ps(normal, _mm256_mul_ps(p, scale))
    }

    /// [`super::denoise_vertex`] with each group in one vector: lanes 0–3 from the low half
    /// of each register, 4–7 from the high half, as the two halves there.
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn denoise_vertex(
        x: &[Vec4],
        v: Vec4,
        n: Vec3A,
        candidates: Candidates,
        k: Kernel,
    ) -> LaneSums {
        // Every candidate is at most `bound` (Rings::new), so below `x.len()`: the loads
        // below need no bounds check (with one, or a mask, they were about a quarter of a
        // group's instructions).
        assert!(
            candidates.bound < x.len(),
            "the working copy covers the rings"
        );
        let c = _mm256_set1_ps;
        let (nx, ny, nz) = (c(n.x), c(n.y), c(n.z));
        let (radius_sq, inv_2sc2, inv_2ss2) = (c(k.radius_sq), c(k.inv_2sc2), c(k.inv_2ss2));
        let sign = c(-0.0);
        let (mut sum_wh, mut sum_w) = (_mm256_setzero_ps(), _mm256_setzero_ps());
        let (mut inside, mut outer) = (0u32, 0u32);
        for (ids, &outer_lanes) in candidates.ids.chunks_exact(LANES).zip(candidates.outer) {
            // SAFETY: ids[l] ≤ candidates.bound < x.len() (asserted above).
            let d = |l: usize| __m128::from(v - unsafe { *x.get_unchecked(ids[l] as usize) });
            let r0 = _mm256_set_m128(d(4), d(0));
            let r1 = _mm256_set_m128(d(5), d(1));
            let r2 = _mm256_set_m128(d(6), d(2));
            let r3 = _mm256_set_m128(d(7), d(3));
            // A 4×4 transpose in each half: rows (x, y, z, w) become one vector per axis.
            let xy01 = _mm256_unpacklo_ps(r0, r1);
            let xy23 = _mm256_unpacklo_ps(r2, r3);
            let zw01 = _mm256_unpackhi_ps(r0, r1);
            let zw23 = _mm256_unpackhi_ps(r2, r3);
            let dx = _mm256_shuffle_ps::<0x44>(xy01, xy23);
            let dy = _mm256_shuffle_ps::<0xEE>(xy01, xy23);
            let dz = _mm256_shuffle_ps::<0x44>(zw01, zw23);
            let t2 = _mm256_fmadd_ps(dz, dz, _mm256_fmadd_ps(dy, dy, _mm256_mul_ps(dx, dx)));
            let hit = _mm256_cmp_ps::<_CMP_LT_OQ>(t2, radius_sq);
            let bits = _mm256_movemask_ps(hit) as u32;
            if bits == 0 {
                continue;
            }
            let h = _mm256_fmadd_ps(nz, dz, _mm256_fmadd_ps(ny, dy, _mm256_mul_ps(nx, dx)));
            let arg = _mm256_fnmadd_ps(
                _mm256_mul_ps(h, h),
                inv_2ss2,
                _mm256_mul_ps(_mm256_xor_ps(sign, t2), inv_2sc2),
            );
            let w = _mm256_and_ps(hit, exp_neg8(arg));
            sum_wh = _mm256_fmadd_ps(w, h, sum_wh);
            sum_w = _mm256_add_ps(sum_w, w);
            inside += bits.count_ones();
            outer += (bits & u32::from(outer_lanes)).count_ones();
        }
        let (wh, w) = add_lanes(sum_wh, sum_w);
        LaneSums {
            wh,
            w,
            inside,
            outer,
        }
    }
}

/// Which filter kernel this processor runs: the AVX2 one where it can (AVX2 and FMA), else
/// the portable one. Both give the same bits.
#[derive(Clone, Copy)]
struct Isa {
    /// Only ever true when the processor has AVX2 and FMA ([`Isa::detect`]).
    avx2: bool,
}

impl Isa {
    fn detect() -> Isa {
        #[cfg(target_arch = "x86_64")]
        let avx2 = avx2::available();
        #[cfg(not(target_arch = "x86_64"))]
        let avx2 = false;
        Isa { avx2 }
    }

    #[inline]
    fn denoise_vertex(
        self,
        x: &[Vec4],
        v: Vec4,
        n: Vec3A,
        candidates: Candidates,
        k: Kernel,
    ) -> LaneSums {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is true only where the processor has AVX2 and FMA (`detect`).
            return unsafe { avx2::denoise_vertex(x, v, n, candidates, k) };
        }
        denoise_vertex(x, v, n, candidates, k)
    }
}

/// The ρ-ball's radius in model units: `radius`, else 2σ_c (Fleishman et al.). `unit`
/// converts the parameters to model units (the mean edge length, or 1).
pub(super) fn ball_radius(params: &BilateralParams, unit: f64) -> f64 {
    params.radius.unwrap_or(2.0 * params.sigma_c) * unit
}

/// `unit` converts the parameters to model units (the mean edge length, or 1).
pub(super) fn run(
    prepared: &Prepared,
    graph: &SmoothGraph,
    positions: &mut Vec<DVec3>,
    params: &BilateralParams,
    unit: f64,
    iterations: u32,
) -> BilateralOutcome {
    let n = positions.len();
    let sigma_c = params.sigma_c * unit;
    let sigma_s = params.sigma_s * unit;
    let radius = ball_radius(params, unit);
    let kernel = Kernel {
        // Kept below the padding's squared distance (3·FAR²), so that padding is never
        // inside, whatever radius is asked for.
        radius_sq: (radius * radius).min(1e36) as f32,
        inv_2sc2: (1.0 / (2.0 * sigma_c * sigma_c)) as f32,
        inv_2ss2: (1.0 / (2.0 * sigma_s * sigma_s)) as f32,
    };
    let mut outcome = BilateralOutcome {
        passes: iterations,
        empty_neighbourhoods: 0,
        neighbours: 0,
        outer_ring_neighbours: 0,
    };
    if !(radius > 0.0 && kernel.inv_2sc2.is_finite() && kernel.inv_2ss2.is_finite()) {
        // A mesh whose edges all have length 0 has no scale to smooth at.
        outcome.empty_neighbourhoods = graph.smoothed_vertices() as u64 * u64::from(iterations);
        return outcome;
    }
    // The bounding box's centre: single-precision differences are then as precise as the
    // scan's extent allows, wherever the scanner put its origin.
    let centre = bounding_box_of(positions).map_or(DVec3::ZERO, |(lo, hi)| (lo + hi) / 2.0);
    let mut local = WorkingCopy::new(n);
    let (rings, plan) = (&prepared.rings, &prepared.normals);
    let mut faces = Vec::with_capacity(plan.triangles.len());
    let mut normals = vec![Vec3A::ZERO; n];
    let mut next = vec![DVec3::ZERO; n];
    // Each pass reads one working copy and writes the next beside the new positions, so
    // that the conversion needs no pass of its own.
    local.update(positions, centre);
    let mut following = WorkingCopy::new(n);
    let pass = Pass {
        graph,
        rings,
        kernel,
        isa: Isa::detect(),
        centre,
    };
    for _ in 0..iterations {
        vertex_normals(plan, &local.x, &mut faces, &mut normals);
        let (x, xl, normals) = (&*positions, &*local.x, &*normals);
        let (empty, inside, outer): (u64, u64, u64) = next
            .par_chunks_mut(CHUNK)
            .zip(following.x[..n].par_chunks_mut(CHUNK))
            .enumerate()
            .map(|(chunk, (out, out_local))| {
                pass.denoise_chunk(x, xl, normals, chunk * CHUNK, out, out_local)
            })
            .reduce(|| (0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
        outcome.empty_neighbourhoods += empty;
        outcome.neighbours += inside;
        outcome.outer_ring_neighbours += outer;
        std::mem::swap(positions, &mut next);
        std::mem::swap(&mut local, &mut following);
    }
    outcome
}

/// What every vertex update of one pass shares.
struct Pass<'a> {
    graph: &'a SmoothGraph,
    rings: &'a Rings,
    kernel: Kernel,
    isa: Isa,
    centre: DVec3,
}

impl Pass<'_> {
    /// Denoises the vertices from `start` on into `out` (positions) and `out_local` (the
    /// next working copy), reading `x` (positions), `xl` (the working copy) and `normals`;
    /// returns the vertices with no neighbourhood, the neighbours used, and how many of
    /// them came from the outermost ring.
    fn denoise_chunk(
        &self,
        x: &[DVec3],
        xl: &[Vec4],
        normals: &[Vec3A],
        start: usize,
        out: &mut [DVec3],
        out_local: &mut [Vec4],
    ) -> (u64, u64, u64) {
        let (mut empty, mut inside, mut outer) = (0u64, 0u64, 0u64);
        for (k, (p, l)) in out.iter_mut().zip(out_local).enumerate() {
            let i = start + k;
            *p = x[i];
            let n = normals[i];
            if self.graph.moves(i) {
                let sums = (n != Vec3A::ZERO).then(|| {
                    self.isa
                        .denoise_vertex(xl, xl[i], n, self.rings.of(i), self.kernel)
                });
                if let Some(sums) = &sums {
                    inside += u64::from(sums.inside);
                    outer += u64::from(sums.outer);
                }
                match sums.and_then(|sums| sums.moved(n)) {
                    Some(moved) => *p += moved.as_dvec3(),
                    None => empty += 1,
                }
            }
            *l = WorkingCopy::point(*p, self.centre);
        }
        (empty, inside, outer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::grid;

    #[test]
    fn fast_exp_matches_libm() {
        let mut x = 0.0f32;
        while x > -100.0 {
            let xs = [x, x - 0.3, x - 0.6, x - 0.9];
            let got = exp_neg4(Vec4::from_array(xs)).to_array();
            for (&x, &a) in xs.iter().zip(&got) {
                let (a, b) = (f64::from(a), f64::from(x).exp());
                // A few f32 ulps (x·log₂e is rounded to f32 first); below e^−87 the result
                // is 0 (b < 2e-38).
                let tolerance =
                    (4e-7 + 1e-7 * f64::from(-x)) * b + if x < -87.0 { 2e-38 } else { 0.0 };
                assert!((a - b).abs() <= tolerance, "{x}: {a} vs {b}");
            }
            x -= 0.00137;
        }
        let edge = Vec4::new(0.0, f32::NEG_INFINITY, f32::NAN, -1e30);
        assert_eq!(exp_neg4(edge).to_array(), [1.0, 0.0, 0.0, 0.0]);
    }

    /// A machine without AVX2 and FMA would run the portable kernel only; the tests that
    /// compare the two must then say they did not check the AVX2 one, not pass (CI's
    /// machines have both).
    #[cfg(target_arch = "x86_64")]
    fn require_avx2() {
        assert!(
            avx2::available(),
            "no AVX2 and FMA on this machine: the AVX2 kernel cannot be compared here"
        );
    }

    /// exp(x) of eight lanes by the AVX2 kernel and by the portable one (two groups of
    /// four), as bits.
    #[cfg(target_arch = "x86_64")]
    fn exp8_both(xs: &[f32; 8]) -> ([u32; 8], [u32; 8]) {
        use std::arch::x86_64::_mm256_loadu_ps;
        require_avx2();
        // SAFETY: AVX2 and FMA are available, checked above.
        let got = unsafe { avx2::lanes(avx2::exp_neg8(_mm256_loadu_ps(xs.as_ptr()))) };
        let lo = exp_neg4(Vec4::from_slice(&xs[..4])).to_array();
        let hi = exp_neg4(Vec4::from_slice(&xs[4..])).to_array();
        let want = std::array::from_fn(|l| if l < 4 { lo[l] } else { hi[l - 4] });
        (got.map(f32::to_bits), want.map(f32::to_bits))
    }

    /// The AVX2 exponential gives the same bits as the portable one on every lane.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_exp_matches_the_portable_one() {
        let mut x = 0.5f32;
        while x > -130.0 {
            let (got, want) = exp8_both(&std::array::from_fn(|l| x - 0.07 * l as f32));
            assert_eq!(got, want, "exp at {x}");
            x -= 0.013;
        }
        let edge = [
            0.0,
            f32::NEG_INFINITY,
            f32::NAN,
            -1e30,
            -87.5,
            -126.0,
            1e-30,
            -0.0,
        ];
        let (got, want) = exp8_both(&edge);
        assert_eq!(got, want);
    }

    /// The AVX2 kernel gives the same bits as the portable one: every vertex's sums on a
    /// noisy torus, through three passes' worth of positions moving (so that groups change
    /// between inside and outside the ball).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_kernel_matches_the_portable_one() {
        require_avx2();
        let mut mesh = crate::mesh::shapes::torus(2.0, 0.7, 90, 40);
        let topology = mesh.topology();
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for p in &mut mesh.positions {
            let mut r = || {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1);
                (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            };
            *p += DVec3::new(r(), r(), r()) * 0.03;
        }
        let radius = 0.15;
        let rings = Rings::new(&topology, 3, &mesh.positions, radius);
        let kernel = Kernel {
            radius_sq: (radius * radius) as f32,
            inv_2sc2: 1.0 / (2.0 * 0.075f32 * 0.075),
            inv_2ss2: 1.0 / (2.0 * 0.02f32 * 0.02),
        };
        let n = mesh.positions.len();
        let mut local = WorkingCopy::new(n);
        let plan = NormalPlan::new(&topology);
        let (mut faces, mut normals) = (Vec::new(), vec![Vec3A::ZERO; n]);
        let mut compared = 0;
        for pass in 0..3 {
            local.update(&mesh.positions, DVec3::ZERO);
            vertex_normals(&plan, &local.x, &mut faces, &mut normals);
            for (i, &normal) in normals.iter().enumerate() {
                let (v, c) = (local.x[i], rings.of(i));
                let a = denoise_vertex(&local.x, v, normal, c, kernel);
                // SAFETY: AVX2 and FMA are available (checked above).
                let b = unsafe { avx2::denoise_vertex(&local.x, v, normal, c, kernel) };
                assert_eq!(
                    (a.wh.to_bits(), a.w.to_bits()),
                    (b.wh.to_bits(), b.w.to_bits()),
                    "pass {pass}, {i}"
                );
                assert_eq!((a.inside, a.outer), (b.inside, b.outer));
                compared += usize::from(a.inside > 0);
                if let Some(m) = a.moved(normal) {
                    mesh.positions[i] += m.as_dvec3();
                }
            }
        }
        assert!(compared > 2 * n, "the ball held neighbours: {compared}");
    }

    /// A vertex's list without the padding: (vertex, from the outermost ring).
    fn listed(rings: &Rings, v: usize, n: usize) -> Vec<(u32, bool)> {
        let c = rings.of(v);
        assert_eq!(
            c.ids.len(),
            LANES * c.outer.len(),
            "whole groups, a byte each"
        );
        c.ids
            .iter()
            .enumerate()
            .filter(|&(_, &j)| j != n as u32)
            .map(|(k, &j)| (j, c.outer[k / LANES] >> (k % LANES) & 1 != 0))
            .collect()
    }

    /// The normals read through [`NormalPlan`] are bit for bit those summed straight from
    /// each vertex's triangles in the mesh's own order, here with the triangles listed in a
    /// scrambled order (so that the sorted order differs from it everywhere).
    #[test]
    fn planned_normals_are_the_direct_sums() {
        let mut mesh = crate::mesh::shapes::torus(2.0, 0.7, 40, 24);
        let count = mesh.triangles.len();
        // A stride coprime with the count visits every triangle once, far from its neighbours.
        let stride = (count / 3..)
            .find(|s| gcd(*s, count) == 1)
            .expect("a stride");
        mesh.triangles = (0..count)
            .map(|k| mesh.triangles[k * stride % count])
            .collect();
        for (k, p) in mesh.positions.iter_mut().enumerate() {
            *p += DVec3::new((k % 7) as f64, (k % 5) as f64, (k % 3) as f64) * 0.01;
        }
        let topology = mesh.topology();
        let n = mesh.positions.len();
        let mut local = WorkingCopy::new(n);
        local.update(&mesh.positions, DVec3::ZERO);
        let (mut faces, mut normals) = (Vec::new(), vec![Vec3A::ZERO; n]);
        vertex_normals(
            &NormalPlan::new(&topology),
            &local.x,
            &mut faces,
            &mut normals,
        );
        let at = |v: u32| Vec3A::from_vec4(local.x[v as usize]);
        for (v, got) in normals.iter().enumerate() {
            let want = topology
                .vertex_triangles(v as u32)
                .fold(Vec3A::ZERO, |sum, t| {
                    let [a, b, c] = topology.triangle_vertices(t).map(at);
                    sum + (b - a).cross(c - a)
                })
                .normalize_or_zero();
            assert_ne!(want, Vec3A::ZERO);
            assert_eq!(
                got.to_array().map(f32::to_bits),
                want.to_array().map(f32::to_bits),
                "{v}"
            );
        }
    }

    fn gcd(a: usize, b: usize) -> usize {
        if b == 0 { a } else { gcd(b, a % b) }
    }

    #[test]
    fn rings_of_a_grid_vertex() {
        let m = grid(6, 6);
        let (topo, n) = (m.topology(), m.positions.len());
        // Vertex (3, 3) = index 3·7 + 3 of the 7×7 unit grid: 6 in its 1-ring, 4 of them
        // at distance 1 and 2 diagonal ones at √2.
        let v = 3 * 7 + 3;
        let one = Rings::new(&topo, 1, &m.positions, 0.0);
        let got = listed(&one, v, n);
        // Radius 0: nothing inside, so the breadth-first order; every one in the outer ring.
        assert_eq!(
            got.iter().map(|e| e.0).collect::<Vec<_>>(),
            topo.vertex_neighbours(v as u32)
        );
        assert!(got.iter().all(|e| e.1));
        // Radius 1.2: the four at distance 1 first, each part in breadth-first order.
        let near = Rings::new(&topo, 1, &m.positions, 1.2);
        let got: Vec<u32> = listed(&near, v, n).iter().map(|e| e.0).collect();
        let d = |j: u32| m.positions[j as usize].distance(m.positions[v]);
        assert!(got[..4].iter().all(|&j| d(j) < 1.2));
        assert!(got[4..].iter().all(|&j| d(j) > 1.2));
        assert!(got[..4].is_sorted() && got[4..].is_sorted());
        // Order 2: 18 distinct, the 12 of the second ring flagged.
        let two = Rings::new(&topo, 2, &m.positions, 1.5);
        let got = listed(&two, v, n);
        let mut ids: Vec<u32> = got.iter().map(|e| e.0).collect();
        assert!(!ids.contains(&(v as u32)));
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids.len(), 18, "no duplicates");
        assert_eq!(got.iter().filter(|e| e.1).count(), 12);
        // Inside the ball (radius 1.5) are exactly the 1-ring, listed first.
        assert!(got[..6].iter().all(|e| !e.1 && d(e.0) < 1.5));
        assert_eq!(
            Rings::new(&topo, 2, &m.positions, 1.5).list,
            two.list,
            "deterministic"
        );
    }
}
