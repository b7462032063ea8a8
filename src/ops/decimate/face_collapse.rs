//! Algorithm f (spec/decimation.md §5.6): face collapse with the wedge-aware quadric, in
//! the lazy framework (§2.4, thesis §1.3.3). The heap holds triangle indices; a triangle
//! touched by a collapse is only marked stale, and re-costed when it reaches the top.
//! The same loop drives edge collapse ([`super::edge_collapse`]): there a triangle's
//! candidate is the cheapest of its three sides.

use super::edge_collapse;
use super::work::{NIL, Plan, Scratch, Work};
use super::{Priority, Refusal, RefusedCounts};
use rayon::prelude::*;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

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
    pub stopped_by: &'static str,
}

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
        Operator::Edge => edge_collapse::attempt(work, t, max_error, sc, stats),
    }
}

/// Collapses until at most `target` triangles are left (within one operation: 4 faces
/// for face collapse, 2 for edge collapse, §5.6 step 9) or no candidate is left.
/// `max_error` (normalised units) refuses collapses with a larger error.
pub fn run<const M: usize>(
    work: &mut Work<M>,
    op: Operator,
    priority: Priority,
    target: usize,
    max_error: f64,
) -> LoopStats {
    let mut stats = LoopStats::default();
    let nt = work.tris.len();
    // Initial keys in parallel; u64::MAX marks "locked for good", MAX − 1 "refused now".
    const LOCKED: u64 = u64::MAX;
    const REFUSED: u64 = u64::MAX - 1;
    let initial: Vec<u64> = {
        let w: &Work<M> = work;
        (0..nt)
            .into_par_iter()
            .map(|t| match candidate(w, op, priority, t) {
                Ok(k) => key(k),
                Err(Refusal::Locked) => LOCKED,
                Err(_) => REFUSED,
            })
            .collect()
    };
    stats.evaluations += nt;
    let mut queued: Vec<bool> = initial.iter().map(|&k| k < REFUSED).collect();
    let mut dirty = vec![false; nt];
    // A triangle refused because two fixed vertices would merge stays refused until it is
    // deleted (fixed vertices never go away), so it is never re-queued.
    let mut frozen: Vec<bool> = initial.iter().map(|&k| k == LOCKED).collect();
    let entries: Vec<Reverse<(u64, u32)>> = initial
        .iter()
        .enumerate()
        .filter(|&(_, &k)| k < REFUSED)
        .map(|(t, &k)| Reverse((k, t as u32)))
        .collect();
    drop(initial);
    let mut heap = BinaryHeap::from(entries);
    let mut sc = Scratch::<M>::default();
    stats.stopped_by = "target";
    while work.live > target {
        let Some(Reverse((k, t))) = heap.pop() else {
            stats.stopped_by = "no-candidates";
            break;
        };
        let t = t as usize;
        queued[t] = false;
        if work.tv[t][0] == NIL {
            continue;
        }
        if dirty[t] {
            dirty[t] = false;
            stats.evaluations += 1;
            match candidate(work, op, priority, t) {
                Ok(cost) => {
                    heap.push(Reverse((key(cost), t as u32)));
                    queued[t] = true;
                }
                Err(cause) => {
                    frozen[t] = cause == Refusal::Locked;
                    stats.refused.count(cause)
                }
            }
            continue;
        }
        match attempt(work, op, t, max_error, &mut sc, &mut stats) {
            Ok(plan) => {
                stats.collapses += 1;
                stats.max_error = stats.max_error.max(plan.error);
                for &c in &sc.corners {
                    let u = c as usize / 3;
                    dirty[u] = true;
                    if !queued[u] && !frozen[u] {
                        heap.push(Reverse((k, u as u32)));
                        queued[u] = true;
                    }
                }
            }
            Err(cause) => stats.refused.count(cause),
        }
    }
    if work.live > target && stats.stopped_by == "target" {
        stats.stopped_by = "no-candidates";
    }
    stats
}
