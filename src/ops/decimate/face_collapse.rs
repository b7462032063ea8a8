//! Algorithm f (spec/decimation.md §5.6): face collapse with the wedge-aware quadric, in
//! the lazy framework (§2.4, thesis §1.3.3). The heap holds triangle indices; a triangle
//! touched by a collapse is only marked stale, and re-costed when it reaches the top.
//! The same loop drives edge collapse ([`super::edge_collapse`]): there a triangle's
//! candidate is the cheapest of its three sides.

use super::edge_collapse;
use super::heap::IndexedHeap;
use super::work::{NIL, Plan, Scratch, Work};
use super::{Priority, Refusal, RefusedCounts};
use rayon::prelude::*;

/// Which operator the loop applies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Operator {
    Face,
    Edge,
}

/// What the loop did.
#[derive(Debug, Clone, Default)]
pub struct LoopStats {
    pub collapses: usize,
    pub refused: RefusedCounts,
    pub evaluations: usize,
    pub ill_conditioned: usize,
    /// Largest error (normalised units) of an applied collapse.
    pub max_error: f64,
    pub stopped_by: super::StopReason,
    /// When the loop stopped short of the target: every candidate left (edges for edge
    /// collapse, triangles for face collapse), by the reason it is refused.
    pub blocked: Option<RefusedCounts>,
}

/// Bit of the per-triangle byte in [`run`]: refused for good (see there).
const FROZEN: u8 = 0x80;

/// Heap key: non-negative f64 bits order like the values; ties go to the lower index.
#[inline]
fn key(cost: f64) -> u64 {
    (cost.max(0.0) + 0.0).to_bits()
}

fn vertices<const M: usize>(work: &Work<M>, t: usize) -> [u32; 3] {
    work.tv[t]
}

/// The priority of triangle `t`'s candidate, or why it has none.
fn candidate<const M: usize>(
    work: &Work<M>,
    op: Operator,
    priority: Priority,
    t: usize,
) -> Result<f64, Refusal> {
    match op {
        Operator::Face => match priority {
            Priority::Estimate => Ok(work.estimate(t)),
            Priority::Quadric => work.quick_cost(&vertices(work, t)),
        },
        Operator::Edge => edge_collapse::best_side(work, t).map(|(_, cost)| cost),
    }
}

/// Tries to collapse triangle `t`'s candidate; on success the scratch holds the merge.
fn attempt<const M: usize>(
    work: &mut Work<M>,
    op: Operator,
    t: usize,
    best: Option<(usize, f64)>,
    max_error: f64,
    sc: &mut Scratch<M>,
    stats: &mut LoopStats,
) -> Result<Plan, Refusal> {
    match op {
        Operator::Face => {
            let s = vertices(work, t);
            stats.evaluations += 1;
            let plan = work.evaluate(&s, sc)?;
            if plan.error > max_error {
                return Err(Refusal::MaxError);
            }
            work.check(&plan, sc)?;
            if plan.fallback {
                stats.ill_conditioned += 1;
            }
            work.apply(&plan, sc);
            Ok(plan)
        }
        Operator::Edge => edge_collapse::attempt(work, t, best, max_error, sc, stats),
    }
}

/// The priority of each triangle around the vertex a collapse left (the fan in
/// `sc.corners`). For edge collapse each side at the new vertex is shared by two fan
/// triangles, so its cost is computed once (`memo`); the side opposite the vertex did not
/// change, and when it was the triangle's cheapest side (`argmin`) its cost is the
/// triangle's current key, so only the other sides are recomputed.
#[allow(clippy::too_many_arguments)]
fn fan_candidates<const M: usize>(
    work: &Work<M>,
    op: Operator,
    priority: Priority,
    sc: &Scratch<M>,
    heap: &IndexedHeap,
    aux: &mut [u8],
    memo: &mut Vec<(u32, Result<f64, Refusal>)>,
    out: &mut Vec<(u32, Result<f64, Refusal>)>,
) {
    out.clear();
    memo.clear();
    for &c in &sc.corners {
        let (u, k) = (c as usize / 3, c as usize % 3);
        if aux[u] & FROZEN != 0 {
            continue;
        }
        let r = match op {
            Operator::Face => candidate(work, op, priority, u),
            Operator::Edge => {
                let vs = work.tv[u];
                let n = vs[k];
                let mut side = |x: u32| match memo.iter().find(|e| e.0 == x) {
                    Some(e) => e.1,
                    None => {
                        let r = work.quick_cost(&[n, x]);
                        memo.push((x, r));
                        r
                    }
                };
                // Sides in the triangle's own order: (v0,v1), (v1,v2), (v2,v0).
                let opposite = (k + 1) % 3;
                let mut costs = [Err(Refusal::Locked); 3];
                costs[k] = side(vs[(k + 1) % 3]);
                costs[(k + 2) % 3] = side(vs[(k + 2) % 3]);
                costs[opposite] = match heap.key(u as u32) {
                    Some(key) if aux[u] as usize == opposite => Ok(f64::from_bits(key)),
                    _ => work.quick_cost(&[vs[opposite], vs[(opposite + 1) % 3]]),
                };
                edge_collapse::combine(costs).map(|(i, cost)| {
                    aux[u] = i as u8;
                    cost
                })
            }
        };
        out.push((u as u32, r));
    }
}

/// Why each candidate left is refused, found by evaluating it in full: each edge once
/// (edge collapse) or each triangle (face collapse). Runs only when the loop stopped short
/// of its target, so that the report can say why.
fn census<const M: usize>(
    work: &Work<M>,
    op: Operator,
    max_error: f64,
    sc: &mut Scratch<M>,
) -> RefusedCounts {
    let why = |s: &[u32], sc: &mut Scratch<M>| -> Option<Refusal> {
        if let Err(c) = work.quick_cost(s) {
            return Some(c);
        }
        let plan = match work.evaluate(s, sc) {
            Ok(p) => p,
            Err(c) => return Some(c),
        };
        if plan.error > max_error {
            return Some(Refusal::MaxError);
        }
        work.check(&plan, sc).err()
    };
    let mut counts = RefusedCounts::default();
    let live = (0..work.tv.len()).filter(|&t| work.tv[t][0] != NIL);
    match op {
        Operator::Face => {
            for t in live {
                if let Some(c) = why(&work.tv[t], sc) {
                    counts.count(c);
                }
            }
        }
        Operator::Edge => {
            let mut edges: Vec<(u32, u32)> = live
                .flat_map(|t| {
                    let v = work.tv[t];
                    [(v[0], v[1]), (v[1], v[2]), (v[2], v[0])]
                })
                .map(|(a, b)| (a.min(b), a.max(b)))
                .collect();
            edges.sort_unstable();
            edges.dedup();
            for (a, b) in edges {
                if let Some(c) = why(&[a, b], sc) {
                    counts.count(c);
                }
            }
        }
    }
    counts
}

/// Collapses until at most `target` triangles are left (within one operation: 4 faces
/// for face collapse, 2 for edge collapse, §5.6 step 9) or no candidate is left.
/// `max_error` (normalised units) refuses collapses with a larger error.
///
/// The thesis' lazy scheme (§5.6 steps 1 and 8: mark the triangles around a collapse
/// stale, re-cost them when they reach the top) is kept in effect but done at once: the
/// triangles around a collapse are re-keyed in an indexed heap right after it, which is
/// the same greedy order without the stale entries' extra heap traffic.
pub fn run<const M: usize>(
    work: &mut Work<M>,
    op: Operator,
    priority: Priority,
    target: usize,
    max_error: f64,
) -> LoopStats {
    let mut stats = LoopStats::default();
    let nt = work.tris.len();
    let (t0, cpu0) = (std::time::Instant::now(), super::cpu_seconds());
    // Per triangle one byte: its cheapest side for edge collapse (see `fan_candidates`;
    // 3 = unknown) and the FROZEN bit. Filled in the same parallel pass as the keys, in
    // place, so that no second array of keys is needed (peak memory).
    let mut aux = vec![3u8; nt];
    let w: &Work<M> = work;
    let mut heap = IndexedHeap::build(nt, |entries| {
        entries
            .par_iter_mut()
            .zip(aux.par_iter_mut())
            .enumerate()
            .for_each(|(t, (e, a))| {
                let r = match op {
                    Operator::Edge => edge_collapse::best_side(w, t).map(|(i, cost)| {
                        *a = i as u8;
                        cost
                    }),
                    Operator::Face => candidate(w, op, priority, t),
                };
                let k = match r {
                    Ok(k) => key(k),
                    // Refused because two fixed vertices would merge: that stays so until
                    // the triangle is deleted (fixed vertices never go away), so it is
                    // never re-keyed.
                    Err(Refusal::Locked) => {
                        *a |= FROZEN;
                        u64::MAX
                    }
                    Err(_) => u64::MAX,
                };
                *e = (k, t as u32);
            });
    });
    stats.evaluations += nt;
    let mut sc = Scratch::<M>::default();
    let mut memo = Vec::with_capacity(16);
    let mut fan = Vec::with_capacity(32);
    let t1 = std::time::Instant::now();
    let cpu1 = super::cpu_seconds();
    let mut pops = 0usize;
    stats.stopped_by = super::StopReason::Target;
    while work.live > target {
        let Some((k, t)) = heap.pop() else {
            stats.stopped_by = super::StopReason::NoCandidates;
            break;
        };
        pops += 1;
        let t = t as usize;
        // Edge collapse: the cheapest side and its cost, as keyed (see `fan_candidates`).
        let best = (op == Operator::Edge && aux[t] & !FROZEN < 3)
            .then(|| ((aux[t] & !FROZEN) as usize, f64::from_bits(k)));
        match attempt(work, op, t, best, max_error, &mut sc, &mut stats) {
            Ok(plan) => {
                stats.collapses += 1;
                stats.max_error = stats.max_error.max(plan.error);
                for &d in &sc.dead {
                    heap.remove(d);
                }
                fan_candidates(
                    work, op, priority, &sc, &heap, &mut aux, &mut memo, &mut fan,
                );
                stats.evaluations += fan.len();
                for &(u, r) in &fan {
                    match r {
                        Ok(cost) => heap.set(u, key(cost)),
                        Err(cause) => {
                            heap.remove(u);
                            if cause == Refusal::Locked {
                                aux[u as usize] |= FROZEN;
                            }
                            stats.refused.count(cause);
                        }
                    }
                }
            }
            // Refused: out of the heap until a collapse next to it re-keys it.
            Err(cause) => stats.refused.count(cause),
        }
    }
    if work.live > target && stats.stopped_by == super::StopReason::Target {
        stats.stopped_by = super::StopReason::NoCandidates;
    }
    if work.live > target {
        stats.blocked = Some(census(work, op, max_error, &mut sc));
    }
    tracing::debug!(
        initial_ms = (t1 - t0).as_secs_f64() * 1e3,
        initial_cpu_ms = (cpu1 - cpu0) * 1e3,
        loop_ms = t1.elapsed().as_secs_f64() * 1e3,
        loop_cpu_ms = (super::cpu_seconds() - cpu1) * 1e3,
        pops,
        "decimate loop"
    );
    stats
}
