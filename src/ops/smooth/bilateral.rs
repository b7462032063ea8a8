//! Bilateral mesh denoising (thesis §3.5; the thesis gives no formula, so the update is
//! Fleishman, Drori & Cohen-Or 2003, "DenoisePoint", spec §6.2):
//!
//! ```text
//! N(v) = { q_k : ‖v − q_k‖ < ρ },  t_k = ‖v − q_k‖,  h_k = ⟨n, v − q_k⟩
//! w_k = exp(−t_k²/2σ_c²) · exp(−h_k²/2σ_s²)
//! v̂ = v − n · Σ w_k h_k / Σ w_k
//! ```
//!
//! Choices where the thesis is silent (spec pitfall 5), each following Fleishman et al.
//! unless said otherwise:
//! - ρ = 2σ_c unless `radius` is given.
//! - The candidates are the vertex's order-k neighbourhood (thesis §2.4.2, Fig. 2.1; spec §1
//!   notes the thesis never says which order its BMDS used), `rings = 3` by default, of which
//!   those inside the ρ-ball count. Gathering through the mesh rather than from all vertices
//!   in space needs no spatial index, and a thin part (a lip, an ear) is not pulled towards
//!   the surface across the gap. With the default ρ = 1.8 mean edges the 3-ring holds
//!   99.995 % of the vertices a breadth-first search inside the ball finds on igea (the
//!   2-ring only 94 %). The rings are topology, so they are built once per step; each
//!   iteration only filters them by distance, twice as fast as searching every time. The
//!   order within a vertex's list (those inside the ball at the start first) only decides
//!   how fast the filter skips the rest, and the order of the sums.
//! - The vertex itself is left out of N(v) (spec §1 and pitfall 7); it would only add weight
//!   1 with h = 0 and damp the move.
//! - n is the area-weighted average of the 1-ring face normals, recomputed from the current
//!   mesh before every iteration; updates are buffered.
//! - An empty neighbourhood, a zero normal or underflowing weights leave the vertex where it
//!   is (counted in the report).
//! - The filter computes in single precision, on positions taken relative to the bounding
//!   box's centre, and adds each move to the double-precision position. The weights and the
//!   move need no more: the compare metrics on igea, lucy and the bunny (σ = 0.2 noise) are
//!   the same to the four digits printed as in double precision, and a pass is faster
//!   (half the bytes per candidate, four lanes per vector; docs/smoothing.md, "Speed").

use super::{BilateralParams, CHUNK, SmoothGraph};
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

/// Each vertex's order-k neighbourhood without the vertex itself (CSR), those inside the
/// ρ-ball when the rings were built first, padded to whole groups of [`LANES`] with the
/// index n (a point far outside every ball). Candidates of the outermost ring carry
/// [`OUTER`]: one of them inside the ρ-ball means the ball may reach beyond the rings.
#[derive(Debug, Clone, Default)]
pub struct Rings {
    offsets: Vec<u32>,
    list: Vec<u32>,
}

/// Flag bit of a candidate from the outermost ring.
const OUTER: u32 = 1 << 31;

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
        let parts: Vec<(Vec<u32>, Vec<u32>)> = (0..n.div_ceil(block))
            .into_par_iter()
            .map(|b| {
                let (first, last) = (b * block, ((b + 1) * block).min(n));
                // mark[j] == i + 1: j already listed for vertex i (zeroed pages are free).
                let mut mark = vec![0u32; n];
                let (mut counts, mut list) = (Vec::with_capacity(last - first), Vec::new());
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
                }
                (counts, list)
            })
            .collect();
        let mut rings = Rings {
            offsets: Vec::with_capacity(n + 1),
            list: Vec::with_capacity(parts.iter().map(|p| p.1.len()).sum()),
        };
        rings.offsets.push(0);
        for (counts, list) in parts {
            for c in counts {
                let last = *rings.offsets.last().expect("starts with 0");
                rings.offsets.push(last + c);
            }
            rings.list.extend(list);
        }
        rings
    }

    #[inline]
    fn of(&self, i: usize) -> &[u32] {
        &self.list[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }
}

/// The working copy the filter reads: positions in single precision, relative to `centre`
/// so that differences of nearby vertices keep their precision (a scan far from the origin
/// loses none), one 16-byte vector each (w = 0), and one point more, far away, that the
/// padding of the candidate lists refers to.
fn local_positions(x: &[DVec3], centre: DVec3, out: &mut Vec<Vec4>) {
    out.clear();
    out.par_extend(x.par_iter().map(|&p| (p - centre).as_vec3().extend(0.0)));
    out.push(Vec4::new(FAR, FAR, FAR, 0.0));
}

/// Area-weighted vertex normals (unit, or zero where every face around is degenerate).
fn vertex_normals(topology: &Topology, x: &[Vec4], faces: &mut Vec<Vec3A>, out: &mut [Vec3A]) {
    faces.clear();
    faces.par_extend(
        (0..topology.triangle_count() as u32)
            .into_par_iter()
            .map(|t| {
                let [a, b, c] = topology
                    .triangle_vertices(t)
                    .map(|v| Vec3A::from_vec4(x[v as usize]));
                // |(b − a) × (c − a)| is twice the area: the sum below is area-weighted.
                (b - a).cross(c - a)
            }),
    );
    out.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(chunk, out)| {
            for (k, n) in out.iter_mut().enumerate() {
                let v = (chunk * CHUNK + k) as u32;
                let sum: Vec3A = topology
                    .vertex_triangles(v)
                    .map(|t| faces[t as usize])
                    .sum();
                *n = sum.normalize_or_zero();
            }
        });
}

/// Lengths converted to model units, ready for the inner loop.
#[derive(Clone, Copy)]
struct Kernel {
    radius_sq: f32,
    inv_2sc2: f32,
    inv_2ss2: f32,
}

/// Candidates weighed side by side, one per lane of a 4-wide vector; the candidate lists
/// are padded to whole groups.
const LANES: usize = 4;

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
/// the filter's time on igea (perf).
#[inline]
fn exp_neg4(x: Vec4) -> Vec4 {
    // 1.5·2²³: the sum leaves 2²² + k in the mantissa bits.
    const ROUND: f32 = 12_582_912.0;
    let y = x * std::f32::consts::LOG2_E;
    // Also false for NaN.
    let normal = y.cmpge(Vec4::splat(-126.0));
    let y = Vec4::select(normal, y, Vec4::splat(-126.0));
    let shifted = y + ROUND;
    let k = shifted - ROUND;
    let r = (y - k) * std::f32::consts::LN_2;
    let p = Vec4::ONE
        + r * (Vec4::ONE
            + r * (Vec4::splat(0.5)
                + r * (Vec4::splat(1.0 / 6.0)
                    + r * (Vec4::splat(1.0 / 24.0)
                        + r * (Vec4::splat(1.0 / 120.0) + r * (1.0 / 720.0))))));
    // 2^k: the low 9 bits of (2²² + k) + 127 are k + 127 ∈ [1, 127] (k ∈ [−126, 0]);
    // shifting them into the exponent field drops everything above, and the sign bit is 0.
    let s = shifted.to_array();
    let scale = |s: f32| f32::from_bits(s.to_bits().wrapping_add(127) << 23);
    let scale = Vec4::new(scale(s[0]), scale(s[1]), scale(s[2]), scale(s[3]));
    Vec4::select(normal, p * scale, Vec4::ZERO)
}

/// Fleishman's DenoisePoint: the move along the normal (`None` when the vertex cannot
/// move), the number of neighbours inside the ball, and how many of them are in the
/// outermost ring searched (many there means the ball probably reaches beyond the rings).
///
/// Written for the vector unit: candidates go four at a time (their offsets loaded as
/// four vectors and transposed, so that each coordinate fills one vector). A group with a
/// candidate inside the ball computes all four weights and zeroes those outside (no
/// compaction); a group wholly outside skips them, and since the rings list the ball's
/// candidates first, that is most groups after the first few. Each lane keeps its own
/// sums, added up in a fixed order at the end, so the result does not depend on the
/// thread count.
#[inline]
fn denoise_vertex(
    x: &[Vec4],
    i: usize,
    n: Vec3A,
    candidates: &[u32],
    k: Kernel,
) -> (Option<Vec3A>, u32, u32) {
    if n == Vec3A::ZERO {
        return (None, 0, 0);
    }
    let v = x[i];
    let (nx, ny, nz) = (Vec4::splat(n.x), Vec4::splat(n.y), Vec4::splat(n.z));
    let (radius_sq, inv_2sc2, inv_2ss2) = (
        Vec4::splat(k.radius_sq),
        Vec4::splat(k.inv_2sc2),
        Vec4::splat(k.inv_2ss2),
    );
    let (mut sum_wh, mut sum_w) = (Vec4::ZERO, Vec4::ZERO);
    let (mut inside, mut outer) = (0u32, 0u32);
    for ids in candidates.chunks_exact(LANES) {
        let at = |l: usize| x[(ids[l] & !OUTER) as usize];
        let d = Mat4::from_cols(v - at(0), v - at(1), v - at(2), v - at(3)).transpose();
        let (dx, dy, dz) = (d.x_axis, d.y_axis, d.z_axis);
        let t2 = dx * dx + dy * dy + dz * dz;
        let hit = t2.cmplt(radius_sq);
        let bits = hit.bitmask();
        if bits == 0 {
            // Those inside the ball come first: the last groups usually lie wholly outside.
            continue;
        }
        let h = nx * dx + ny * dy + nz * dz;
        let w = Vec4::select(hit, exp_neg4(-t2 * inv_2sc2 - h * h * inv_2ss2), Vec4::ZERO);
        sum_wh += w * h;
        sum_w += w;
        inside += bits.count_ones();
        let from_outer = (0..LANES).fold(0, |m, l| m | (ids[l] >> 31) << l);
        outer += (bits & from_outer).count_ones();
    }
    let (wh, w) = (sum_wh.to_array(), sum_w.to_array());
    let wh = (wh[0] + wh[1]) + (wh[2] + wh[3]);
    let w = (w[0] + w[1]) + (w[2] + w[3]);
    let moved = (w > 0.0 && wh.is_finite()).then(|| n * -(wh / w));
    (moved, inside, outer)
}

/// The ρ-ball's radius in model units: `radius`, else 2σ_c (Fleishman et al.). `unit`
/// converts the parameters to model units (the mean edge length, or 1).
pub(super) fn ball_radius(params: &BilateralParams, unit: f64) -> f64 {
    params.radius.unwrap_or(2.0 * params.sigma_c) * unit
}

/// `unit` converts the parameters to model units (the mean edge length, or 1).
pub(super) fn run(
    topology: &Topology,
    rings: &Rings,
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
    let mut local = Vec::with_capacity(n);
    let mut faces = Vec::with_capacity(topology.triangle_count());
    let mut normals = vec![Vec3A::ZERO; n];
    let mut next = vec![DVec3::ZERO; n];
    for _ in 0..iterations {
        local_positions(positions, centre, &mut local);
        vertex_normals(topology, &local, &mut faces, &mut normals);
        let (x, xl) = (&*positions, &*local);
        let (empty, inside, outer): (u64, u64, u64) = next
            .par_chunks_mut(CHUNK)
            .enumerate()
            .map(|(chunk, out)| {
                let (mut empty, mut inside, mut outer) = (0u64, 0u64, 0u64);
                for (k, p) in out.iter_mut().enumerate() {
                    let i = chunk * CHUNK + k;
                    *p = x[i];
                    if !graph.moves(i) {
                        continue;
                    }
                    let (moved, used, from_outer) =
                        denoise_vertex(xl, i, normals[i], rings.of(i), kernel);
                    inside += u64::from(used);
                    outer += u64::from(from_outer);
                    match moved {
                        Some(moved) => *p += moved.as_dvec3(),
                        None => empty += 1,
                    }
                }
                (empty, inside, outer)
            })
            .reduce(|| (0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
        outcome.empty_neighbourhoods += empty;
        outcome.neighbours += inside;
        outcome.outer_ring_neighbours += outer;
        std::mem::swap(positions, &mut next);
    }
    outcome
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

    /// A vertex's list without the padding and the flag: (vertex, from the outermost ring).
    fn listed(rings: &Rings, v: usize, n: usize) -> Vec<(u32, bool)> {
        let list = rings.of(v);
        assert_eq!(list.len() % LANES, 0, "whole groups");
        list.iter()
            .filter(|&&j| j != n as u32)
            .map(|&j| (j & !OUTER, j & OUTER != 0))
            .collect()
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
