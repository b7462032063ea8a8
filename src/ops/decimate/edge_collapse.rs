//! Edge collapse over the same wedge-aware quadrics and guards (thesis §1.2.1,
//! the full-edge variant): a triangle's candidate is the cheapest of its three
//! sides, so the lazy triangle heap of face collapse drives it unchanged
//! ([`super::collapse_loop`]).

use super::Refusal;
use super::collapse_loop::{CollapseOperator, LoopStats, collapse, live_triangles};
use super::heap::IndexedHeap;
use super::work::{Plan, Scratch, Work};

fn sides<const M: usize>(work: &Work<M>, t: usize) -> [[u32; 2]; 3] {
    let v = work.tv[t];
    [[v[0], v[1]], [v[1], v[2]], [v[2], v[0]]]
}

/// The cheapest side of triangle `t` by the quick key that the placement rules allow.
pub fn best_side<const M: usize>(work: &Work<M>, t: usize) -> Result<(usize, f64), Refusal> {
    let all = sides(work, t);
    combine([0, 1, 2].map(|i| work.quick_cost(&all[i])))
}

/// The cheapest of a triangle's three side costs (the first on ties), or why none is
/// allowed: the last refusal other than `Locked`, `Locked` only if every side is (then it
/// stays so until the triangle dies).
pub fn combine(costs: [Result<f64, Refusal>; 3]) -> Result<(usize, f64), Refusal> {
    let mut best: Option<(usize, f64)> = None;
    let mut cause = Refusal::Locked;
    for (i, c) in costs.into_iter().enumerate() {
        match c {
            Ok(cost) => {
                if best.is_none_or(|(_, b)| cost < b) {
                    best = Some((i, cost));
                }
            }
            Err(c) if c != Refusal::Locked => cause = c,
            Err(_) => {}
        }
    }
    best.ok_or(cause)
}

/// Edge collapse as the loop's operator: a triangle's candidate is its cheapest side.
pub struct EdgeCollapse;

impl CollapseOperator for EdgeCollapse {
    const NAME: &'static str = "edge collapses";

    fn candidate<const M: usize>(
        &self,
        work: &Work<M>,
        t: usize,
        side: &mut u8,
    ) -> Result<f64, Refusal> {
        best_side(work, t).map(|(i, cost)| {
            *side = i as u8;
            cost
        })
    }

    /// Collapses the cheapest side of `t` that passes the guards. `best` is the triangle's
    /// cheapest side and its cost as the heap holds them (the loop keeps both current); that
    /// side is evaluated first, and the other two are costed only when it is refused, so a
    /// collapse that goes through at once (most of them) skips two quick costs. The order in
    /// which sides are tried, and so the result, is the same as costing all three first.
    fn attempt<const M: usize>(
        &self,
        work: &mut Work<M>,
        t: usize,
        best: Option<(usize, f64)>,
        max_error: f64,
        sc: &mut Scratch<M>,
        stats: &mut LoopStats,
    ) -> Result<Plan, Refusal> {
        let all = sides(work, t);
        debug_assert!(
            best.is_none_or(|b| best_side(work, t).map(|(i, c)| (i, c.max(0.0) + 0.0)) == Ok(b)),
            "stale cheapest side of triangle {t}: {best:?} vs {:?}",
            best_side(work, t)
        );
        // Why the last side was refused: the last full evaluation's cause, else the last
        // quick cost's (as when every side is costed first, sides in order).
        let mut eval_cause: Option<Refusal> = None;
        let mut try_side = |work: &mut Work<M>,
                            i: usize,
                            sc: &mut Scratch<M>,
                            stats: &mut LoopStats|
         -> Option<Plan> {
            collapse(work, &all[i], max_error, sc, stats)
                .map_err(|c| eval_cause = Some(c))
                .ok()
        };
        let first = best.filter(|b| b.1.is_finite()).map(|b| b.0);
        if let Some(i) = first
            && let Some(plan) = try_side(work, i, sc, stats)
        {
            return Ok(plan);
        }
        let mut costs: [(f64, usize); 3] = [(f64::INFINITY, 0); 3];
        let mut quick_cause = Refusal::Link;
        for (i, side) in all.iter().enumerate() {
            if Some(i) == first {
                // Already tried (and refused): it stays out of the order below.
                costs[i] = (f64::INFINITY, i);
                continue;
            }
            match work.quick_cost(side) {
                Ok(cost) => costs[i] = (cost, i),
                Err(c) => quick_cause = c,
            }
        }
        costs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for &(cost, i) in &costs {
            if !cost.is_finite() {
                break;
            }
            if let Some(plan) = try_side(work, i, sc, stats) {
                return Ok(plan);
            }
        }
        Err(eval_cause.unwrap_or(quick_cause))
    }

    /// Each side at the new vertex is shared by two fan triangles, so its cost is computed
    /// once (`memo`); the side opposite the vertex did not change, and when it was the
    /// triangle's cheapest side (`side`) its cost is the triangle's current key, so only the
    /// other sides are recomputed.
    fn rekey<const M: usize>(
        &self,
        work: &Work<M>,
        u: usize,
        k: usize,
        heap: &IndexedHeap,
        side: &mut u8,
        memo: &mut Vec<(u32, Result<f64, Refusal>)>,
    ) -> Result<f64, Refusal> {
        let vs = work.tv[u];
        let n = vs[k];
        let mut cost_to = |x: u32| match memo.iter().find(|e| e.0 == x) {
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
        costs[k] = cost_to(vs[(k + 1) % 3]);
        costs[(k + 2) % 3] = cost_to(vs[(k + 2) % 3]);
        costs[opposite] = match heap.key(u as u32) {
            Some(key) if *side as usize == opposite => Ok(f64::from_bits(key)),
            _ => work.quick_cost(&[vs[opposite], vs[(opposite + 1) % 3]]),
        };
        combine(costs).map(|(i, cost)| {
            *side = i as u8;
            cost
        })
    }

    fn for_each_candidate<const M: usize>(&self, work: &Work<M>, f: &mut dyn FnMut(&[u32])) {
        let mut edges: Vec<(u32, u32)> = live_triangles(work)
            .flat_map(|t| {
                let v = work.tv[t];
                [(v[0], v[1]), (v[1], v[2]), (v[2], v[0])]
            })
            .map(|(a, b)| (a.min(b), a.max(b)))
            .collect();
        edges.sort_unstable();
        edges.dedup();
        for (a, b) in edges {
            f(&[a, b]);
        }
    }
}
