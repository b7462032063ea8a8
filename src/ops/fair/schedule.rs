//! The iteration scheme (thesis §2.5, §2.10, §3.5): `T_h` curvature iterations, then `T_u`
//! non-uniformity iterations, repeated, starting with curvature; a run stops after
//! `max_iterations` iterations (both criteria counted) or when the mean displacement of an
//! iteration falls below `stop` × the mean edge length of the input.
//!
//! Also the time scaling of the fast schedule: `m` iterations with `λ, λ_u` are replaced
//! by one with `mλ, mλ_u` (the diffusions (2.7)/(3.7) and (2.13)/(3.18) are explicit Euler
//! steps of `∂H/∂t = λΔH`; for small steps only the product `λ·k` matters), so phase
//! lengths and the iteration cap shrink by `m` and the displacement threshold grows by `m`.

use serde::{Deserialize, Serialize};

/// Which criterion an iteration applies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    Curvature,
    Nonuniformity,
}

/// In which phases the displacement stop may end the run: Matlab `S_end_way` (App. B):
/// 0 = either criterion (the default), 1 = only during curvature iterations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum StopIn {
    #[default]
    Any,
    Curvature,
}

/// The constants of one (sub-)algorithm: C (boundary curves) or S (interior), §4.5.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhaseParams {
    /// λ: curvature diffusion step (2.7)/(3.7).
    pub lambda: f64,
    /// λ_u: non-uniformity decay (2.13)/(3.18).
    pub lambda_u: f64,
    /// T_h: curvature iterations per cycle.
    pub t_h: u32,
    /// T_u: non-uniformity iterations per cycle.
    pub t_u: u32,
    /// I: the most iterations, both criteria counted (§2.10).
    pub max_iterations: u32,
    /// S_h = S_u: stop when an iteration's mean displacement < `stop` × mean edge length.
    pub stop: f64,
    pub stop_in: StopIn,
}

impl PhaseParams {
    /// The thesis' recommendation for curves and boundary loops (§2.11.5, §4.6.4).
    pub fn curve() -> Self {
        PhaseParams {
            lambda: 0.1,
            lambda_u: 0.01,
            t_h: 50,
            t_u: 50,
            max_iterations: 10_000,
            stop: 1e-4,
            stop_in: StopIn::Any,
        }
    }

    /// The thesis' recommendation for closed surfaces and interiors (§3.8.5).
    pub fn surface() -> Self {
        PhaseParams {
            lambda: 0.01,
            lambda_u: 0.01,
            t_h: 50,
            t_u: 50,
            max_iterations: 5000,
            stop: 1e-5,
            stop_in: StopIn::Any,
        }
    }

    /// The same run in `m` times fewer, `m` times longer iterations (see module docs).
    pub fn time_scaled(&self, m: u32) -> PhaseParams {
        if m <= 1 {
            return *self;
        }
        let shrink = |t: u32| if t == 0 { 0 } else { t.div_ceil(m).max(1) };
        PhaseParams {
            lambda: self.lambda * m as f64,
            lambda_u: self.lambda_u * m as f64,
            t_h: shrink(self.t_h),
            t_u: shrink(self.t_u),
            max_iterations: shrink(self.max_iterations),
            stop: self.stop * m as f64,
            stop_in: self.stop_in,
        }
    }

    /// The largest time scale `m` that keeps both steps at or below `max_step` and every
    /// non-empty phase at least one iteration long.
    pub fn fast_time_scale(&self, max_step: f64) -> u32 {
        let step = self.lambda.max(self.lambda_u);
        let mut m = if step > 0.0 {
            (max_step / step).floor().max(1.0) as u32
        } else {
            1
        };
        for t in [self.t_h, self.t_u] {
            if t > 0 {
                m = m.min(t);
            }
        }
        m.max(1)
    }
}

/// What one iteration did.
#[derive(Debug, Clone, Copy, Default)]
pub struct Sweep {
    /// Mean displacement over the vertices the iteration may move.
    pub mean: f64,
    pub max: f64,
    /// Vertex updates computed.
    pub updates: usize,
}

/// What a run did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct RunStats {
    pub iterations: u32,
    pub curvature_iterations: u32,
    pub nonuniformity_iterations: u32,
    /// True when the displacement threshold ended the run, false for the cap (or nothing
    /// to do).
    pub stopped_by_displacement: bool,
    /// Mean displacement of the last iteration.
    pub last_mean_displacement: f64,
    /// Largest single-iteration move of any vertex.
    pub max_step: f64,
    pub vertex_updates: u64,
}

/// Phase of iteration `k` (0-based): the cycle starts with curvature (§2.5; the hexagon
/// of §2.11.2 stops at 241, inside the third curvature phase). Empty phases are skipped.
pub fn phase_of(params: &PhaseParams, k: u32) -> Option<Phase> {
    let cycle = params.t_h + params.t_u;
    if cycle == 0 {
        return None;
    }
    Some(if k % cycle < params.t_h {
        Phase::Curvature
    } else {
        Phase::Nonuniformity
    })
}

/// Runs the scheme; `sweep` performs one iteration of the given phase in place.
/// `scale` is the mean edge length of the input (thresholds are relative to it, §2.11).
pub fn run(params: &PhaseParams, scale: f64, mut sweep: impl FnMut(Phase) -> Sweep) -> RunStats {
    let mut stats = RunStats::default();
    let threshold = params.stop * scale;
    for k in 0..params.max_iterations {
        let Some(phase) = phase_of(params, k) else {
            break;
        };
        let s = sweep(phase);
        stats.iterations += 1;
        match phase {
            Phase::Curvature => stats.curvature_iterations += 1,
            Phase::Nonuniformity => stats.nonuniformity_iterations += 1,
        }
        stats.last_mean_displacement = s.mean;
        stats.max_step = stats.max_step.max(s.max);
        stats.vertex_updates += s.updates as u64;
        let may_stop = params.stop_in == StopIn::Any || phase == Phase::Curvature;
        if may_stop && s.mean < threshold {
            stats.stopped_by_displacement = true;
            break;
        }
    }
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phases_alternate_starting_with_curvature() {
        let p = PhaseParams {
            t_h: 2,
            t_u: 3,
            ..PhaseParams::surface()
        };
        let phases: Vec<_> = (0..6).map(|k| phase_of(&p, k).unwrap()).collect();
        use Phase::*;
        assert_eq!(
            phases,
            [
                Curvature,
                Curvature,
                Nonuniformity,
                Nonuniformity,
                Nonuniformity,
                Curvature
            ]
        );
        let only_u = PhaseParams { t_h: 0, ..p };
        assert_eq!(phase_of(&only_u, 0), Some(Nonuniformity));
        let none = PhaseParams {
            t_h: 0,
            t_u: 0,
            ..p
        };
        assert_eq!(phase_of(&none, 0), None);
    }

    #[test]
    fn stops_on_cap_and_on_displacement() {
        let p = PhaseParams {
            max_iterations: 7,
            ..PhaseParams::surface()
        };
        let s = run(&p, 1.0, |_| Sweep {
            mean: 1.0,
            max: 1.0,
            updates: 3,
        });
        assert_eq!((s.iterations, s.vertex_updates), (7, 21));
        assert!(!s.stopped_by_displacement);
        let mut k = 0;
        let s = run(&p, 1.0, |_| {
            k += 1;
            Sweep {
                mean: if k == 3 { 0.0 } else { 1.0 },
                ..Sweep::default()
            }
        });
        assert_eq!(s.iterations, 3);
        assert!(s.stopped_by_displacement);
        // S_end_way = 1: a tiny step in a non-uniformity phase does not stop the run.
        let p = PhaseParams {
            t_h: 1,
            t_u: 1,
            stop_in: StopIn::Curvature,
            ..p
        };
        let s = run(&p, 1.0, |ph| Sweep {
            mean: if ph == Phase::Nonuniformity { 0.0 } else { 1.0 },
            ..Sweep::default()
        });
        assert_eq!(s.iterations, 7);
    }

    #[test]
    fn time_scaling_keeps_products() {
        let p = PhaseParams::surface();
        let m = p.fast_time_scale(0.25);
        assert_eq!(m, 25);
        let q = p.time_scaled(m);
        assert!((q.lambda - 0.25).abs() < 1e-15);
        assert_eq!((q.t_h, q.t_u, q.max_iterations), (2, 2, 200));
        assert!((q.stop - 25e-5).abs() < 1e-18);
    }
}
