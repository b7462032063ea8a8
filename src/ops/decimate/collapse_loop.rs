//! The collapse loop of both collapse operators, in the lazy framework (thesis
//! §1.3.3): the heap holds triangle indices; a triangle touched by a collapse
//! is re-costed. What a triangle's candidate is and how it collapses is the operator's
//! ([`CollapseOperator`]): [`FaceCollapse`], algorithm f (§3.2, face collapse with the
//! wedge-aware quadric), or [`super::edge_collapse::EdgeCollapse`], where a triangle's
//! candidate is the cheapest of its three sides.

use super::heap::IndexedHeap;
use super::work::{NIL, Plan, Scratch, Work};
use super::{Priority, Refusal, RefusedCounts};
use rayon::prelude::*;

/// A collapse operator the loop applies (the role of baby_shark's `CollapseStrategy`): what
/// triangle `t`'s candidate is and what it costs, how it is collapsed, how the triangles
/// around a collapse are re-costed, and which candidates are left when the loop stops.
pub trait CollapseOperator: Sync {
    /// What is collapsed, for the report's note when the loop stops short.
    const NAME: &'static str;

    /// The priority of triangle `t`'s candidate, or why it has none. An operator with more
    /// than one candidate per triangle writes the one it chose (0..3) into `side`.
    fn candidate<const M: usize>(
        &self,
        work: &Work<M>,
        t: usize,
        side: &mut u8,
    ) -> Result<f64, Refusal>;

    /// Tries to collapse triangle `t`'s candidate; on success the scratch holds the merge.
    /// `best` is the candidate's side and cost as the heap holds them, when known.
    fn attempt<const M: usize>(
        &self,
        work: &mut Work<M>,
        t: usize,
        best: Option<(usize, f64)>,
        max_error: f64,
        sc: &mut Scratch<M>,
        stats: &mut LoopStats,
    ) -> Result<Plan, Refusal>;

    /// The priority of triangle `u`, whose corner `k` is the vertex a collapse left; `side`
    /// as in [`CollapseOperator::candidate`], `memo` shared by the fan of one collapse. By
    /// default the candidate is costed afresh; an operator that can reuse what it knows of
    /// the fan (its current key, costs shared by two triangles) overrides this.
    #[allow(clippy::too_many_arguments)]
    fn rekey<const M: usize>(
        &self,
        work: &Work<M>,
        u: usize,
        _k: usize,
        _heap: &IndexedHeap,
        side: &mut u8,
        _memo: &mut Vec<(u32, Result<f64, Refusal>)>,
    ) -> Result<f64, Refusal> {
        self.candidate(work, u, side)
    }

    /// Calls `f` with the vertices of every candidate left, each once.
    fn for_each_candidate<const M: usize>(&self, work: &Work<M>, f: &mut dyn FnMut(&[u32]));
}

/// Algorithm f (thesis §3.2): a triangle collapses to one vertex.
pub struct FaceCollapse {
    pub priority: Priority,
}

impl CollapseOperator for FaceCollapse {
    const NAME: &'static str = "face collapses";

    fn candidate<const M: usize>(
        &self,
        work: &Work<M>,
        t: usize,
        _side: &mut u8,
    ) -> Result<f64, Refusal> {
        match self.priority {
            Priority::Estimate => Ok(work.estimate(t)),
            Priority::Quadric => work.quick_cost(&vertices(work, t)),
        }
    }

    fn attempt<const M: usize>(
        &self,
        work: &mut Work<M>,
        t: usize,
        _best: Option<(usize, f64)>,
        max_error: f64,
        sc: &mut Scratch<M>,
        stats: &mut LoopStats,
    ) -> Result<Plan, Refusal> {
        collapse(work, &vertices(work, t), max_error, sc, stats)
    }

    fn for_each_candidate<const M: usize>(&self, work: &Work<M>, f: &mut dyn FnMut(&[u32])) {
        for t in live_triangles(work) {
            f(&work.tv[t]);
        }
    }
}

/// Collapses the vertices `s` if the merge's error is within `max_error` and it passes the
/// guards; on success the scratch holds the merge. Both operators' one collapse.
pub(super) fn collapse<const M: usize>(
    work: &mut Work<M>,
    s: &[u32],
    max_error: f64,
    sc: &mut Scratch<M>,
    stats: &mut LoopStats,
) -> Result<Plan, Refusal> {
    stats.evaluations += 1;
    let plan = work.evaluate(s, sc)?;
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

/// The triangles not yet collapsed.
pub(super) fn live_triangles<'a, const M: usize>(
    work: &'a Work<M>,
) -> impl Iterator<Item = usize> + 'a {
    (0..work.tv.len()).filter(|&t| work.tv[t][0] != NIL)
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

/// Every triangle's first key, evaluated in parallel, with `aux` filled in the same pass, in
/// place, so that no second array of keys is needed (peak memory).
fn initial_heap<const M: usize, O: CollapseOperator>(
    work: &Work<M>,
    op: &O,
    aux: &mut [u8],
) -> IndexedHeap {
    IndexedHeap::build(work.tris.len(), |entries| {
        entries
            .par_iter_mut()
            .zip(aux.par_iter_mut())
            .enumerate()
            .for_each(|(t, (e, a))| {
                let k = match op.candidate(work, t, a) {
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
    })
}

/// The fan's new priorities into the heap: a refused triangle leaves it (for good, FROZEN,
/// when two fixed vertices would merge).
fn set_keys(
    heap: &mut IndexedHeap,
    aux: &mut [u8],
    fan: &[(u32, Result<f64, Refusal>)],
    stats: &mut LoopStats,
) {
    for &(u, r) in fan {
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

/// The priority of each triangle around the vertex a collapse left (the fan in
/// `sc.corners`), skipping those refused for good.
fn fan_candidates<const M: usize, O: CollapseOperator>(
    work: &Work<M>,
    op: &O,
    sc: &Scratch<M>,
    heap: &IndexedHeap,
    aux: &mut [u8],
    memo: &mut Vec<(u32, Result<f64, Refusal>)>,
    out: &mut Vec<(u32, Result<f64, Refusal>)>,
) {
    out.clear();
    memo.clear();
    // Re-keying a fan triangle reads its byte in `aux`, where it sits in the heap, and then
    // its heap entry (its key now, to be changed after): asked for in two passes, the
    // positions first and the entries once the positions are in, these misses overlap
    // instead of coming one after another (docs/decimation.md, "Where the collapse loop
    // waits").
    for &c in &sc.corners {
        heap.prefetch(c / 3);
        super::prefetch::prefetch(aux, c as usize / 3);
    }
    for &c in &sc.corners {
        heap.prefetch_entry(c / 3);
    }
    for &c in &sc.corners {
        let (u, k) = (c as usize / 3, c as usize % 3);
        if aux[u] & FROZEN != 0 {
            continue;
        }
        let r = op.rekey(work, u, k, heap, &mut aux[u], memo);
        out.push((u as u32, r));
    }
}

/// Why each candidate left is refused, found by evaluating it in full. Runs only when the
/// loop stopped short of its target, so that the report can say why.
fn census<const M: usize, O: CollapseOperator>(
    work: &Work<M>,
    op: &O,
    max_error: f64,
    sc: &mut Scratch<M>,
) -> RefusedCounts {
    let mut why = |s: &[u32]| -> Option<Refusal> {
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
    op.for_each_candidate(work, &mut |s| {
        if let Some(c) = why(s) {
            counts.count(c);
        }
    });
    counts
}

/// Collapses until at most `target` triangles are left (within one operation: 4 faces
/// for face collapse, 2 for edge collapse, §3.2) or no candidate is left.
/// `max_error` (normalised units) refuses collapses with a larger error.
///
/// The thesis' lazy scheme (§3.2: mark the triangles around a collapse
/// stale, re-cost them when they reach the top) is kept in effect but done at once: the
/// triangles around a collapse are re-keyed in an indexed heap right after it, which is
/// the same greedy order without the stale entries' extra heap traffic.
pub fn run<const M: usize, O: CollapseOperator>(
    work: &mut Work<M>,
    op: &O,
    target: usize,
    max_error: f64,
) -> LoopStats {
    let mut stats = LoopStats::default();
    let nt = work.tris.len();
    let (t0, cpu0) = (std::time::Instant::now(), super::cpu_seconds());
    // Per triangle one byte: its cheapest side for edge collapse (see `fan_candidates`;
    // 3 = unknown) and the FROZEN bit.
    let mut aux = vec![3u8; nt];
    let mut heap = initial_heap(work, op, &mut aux);
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
        // The next candidate's records are fetched while this one collapses.
        if let Some(next) = heap.peek() {
            work.prefetch_triangle(next as usize);
        }
        // The candidate's side and its cost, as keyed, when the operator chose one.
        let best = (aux[t] & !FROZEN < 3).then(|| ((aux[t] & !FROZEN) as usize, f64::from_bits(k)));
        match op.attempt(work, t, best, max_error, &mut sc, &mut stats) {
            Ok(plan) => {
                stats.collapses += 1;
                stats.max_error = stats.max_error.max(plan.error);
                for &d in &sc.dead {
                    heap.remove(d);
                }
                fan_candidates(work, op, &sc, &heap, &mut aux, &mut memo, &mut fan);
                stats.evaluations += fan.len();
                set_keys(&mut heap, &mut aux, &fan, &mut stats);
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
