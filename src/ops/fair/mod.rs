//! Curvature fairing and the non-uniformity pre-pass (docs/fairing.md; M. Matýsková,
//! *Filtrace diskrétního povrchu*, MFF UK 2006): the recipe steps `relax` (non-uniformity
//! only) and `fair` (both criteria).
//!
//! - [`curve`]: closed and open curves (ch. 2);
//! - [`surface`]: closed surfaces (ch. 3);
//! - [`boundary`]: surfaces with boundary (ch. 4): boundary loops faired as closed curves,
//!   then the interior as a closed surface;
//! - [`schedule`]: the `T_h`/`T_u` scheme and both stopping rules;
//! - [`guards`]: fixed vertices and safe moves.
//!
//! Positions move; connectivity, wedges, texture coordinates and seams stay as they are.
//!
//! Two schedules. `thesis` is the method as written: Gauss–Seidel over the interior in
//! index order, every quantity from the current positions (§3.5.1), with the given λ and
//! iteration counts. `fast` (the default) reaches the same result in parallel: Jacobi
//! sweeps (deterministic whatever the thread count) and time-scaled steps: `m` thesis
//! iterations become one with `mλ`, `mλ_u` (see [`schedule`]); the convergence test is
//! the thesis' displacement threshold scaled alike. Boundary curves are small and use the
//! thesis' own (Jacobi) curve order in both.

pub mod boundary;
pub mod curve;
pub mod guards;
pub mod neighbourhood;
pub mod schedule;
pub mod surface;

use crate::mesh::{BoundaryChain, Mesh, Topology};
use crate::ops::border::{self, Border};
use glam::DVec3;
use guards::{FixedCounts, GuardCounts};
use neighbourhood::Neighbourhood;
use rayon::prelude::*;
use schedule::{Phase, PhaseParams, RunStats, StopIn};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// The largest per-iteration λ or λ_u the fast schedule scales up to. Measured: Jacobi
/// sweeps at this step reach the thesis' Gauss–Seidel result at λ = 0.01 (see the tests).
pub const FAST_MAX_STEP: f64 = 0.25;

/// Which iteration order runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Schedule {
    /// Exact thesis: Gauss–Seidel in index order with the given λ and counts.
    Thesis,
    /// Parallel Jacobi with time-scaled steps: the same result, much faster.
    #[default]
    Fast,
}

/// Declares the parameters of a fairing step (`relax`, `fair`): the step's own fields, then
/// the block both steps share (the boundary curves, the guards, the schedule), written once
/// here with its documentation and defaults. The struct stays flat, as the recipe's table
/// is: serde's `flatten` would let a shared struct be embedded, but a flattened struct
/// cannot refuse unknown keys (`deny_unknown_fields`), and a typo must stay an error that
/// names the valid keys. `c_max_iterations` is the one shared default that differs.
macro_rules! fairing_params {
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $( $(#[$field_meta:meta])* pub $field:ident: $ty:ty = $default:expr, )*
        }
        c_max_iterations = $c_max_iterations:expr;
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
        #[serde(deny_unknown_fields, default)]
        pub struct $name {
            $( $(#[$field_meta])* pub $field: $ty, )*
            /// What happens at the border loops: `curve` (recorded as `fair`: every loop is
            /// faired with the curve algorithm first, ch. 4) or `fixed` (held still); see
            /// [`Border`].
            #[serde(with = "border::fairing")]
            pub boundary: Border,
            /// C_λ: boundary curvature diffusion (2.15). 0.1 (§2.11.5, §4.6).
            pub c_lambda: f64,
            /// C_λu: boundary non-uniformity decay. 0.01.
            pub c_lambda_u: f64,
            pub c_t_h: u32,
            pub c_t_u: u32,
            /// C_maxIter.
            pub c_max_iterations: u32,
            /// C_sum: 1e-4 × the loop's mean edge length.
            pub c_stop: f64,
            /// Zero tolerance for curvature magnitudes, × 1/(mean edge length). 1e-4 (App.
            /// A/B).
            pub epsilon: f64,
            /// Degrees: vertices on sharper edges stay fixed. None = no crease protection
            /// (the thesis rounds sharp edges off, §1.2.2).
            pub feature_angle: Option<f64>,
            /// Vertices of higher valence stay fixed (vase, §3.8.1). None = 2.5 × median,
            /// ≥ 12.
            pub max_valence: Option<u32>,
            pub schedule: Schedule,
        }

        impl Default for $name {
            fn default() -> Self {
                let c = PhaseParams::curve();
                $name {
                    $( $field: $default, )*
                    boundary: Border::Curve,
                    c_lambda: c.lambda,
                    c_lambda_u: c.lambda_u,
                    c_t_h: c.t_h,
                    c_t_u: c.t_u,
                    c_max_iterations: $c_max_iterations,
                    c_stop: c.stop,
                    epsilon: 1e-4,
                    feature_angle: None,
                    max_valence: None,
                    schedule: Schedule::Fast,
                }
            }
        }

        impl $name {
            /// The plan: the step's interior phase (`surface`) with the shared block.
            fn plan_with(&self, surface: PhaseParams, tangential: bool) -> Plan {
                Plan {
                    surface,
                    curve: PhaseParams {
                        lambda: self.c_lambda,
                        lambda_u: self.c_lambda_u,
                        t_h: self.c_t_h,
                        t_u: self.c_t_u,
                        max_iterations: self.c_max_iterations,
                        stop: self.c_stop,
                        stop_in: StopIn::Any,
                    },
                    boundary: self.boundary,
                    epsilon: self.epsilon,
                    feature_angle: self.feature_angle,
                    max_valence: self.max_valence,
                    schedule: self.schedule,
                    tangential,
                }
            }

            pub fn validate(&self) -> Result<(), String> {
                self.plan().validate()
            }
        }
    };
}

fairing_params! {
    /// Parameters of the `fair` step. Names follow the thesis' symbols (§2.10, §4.5, App. B):
    /// unprefixed = the surface (interior, `S_*`), `c_` = the boundary curves (`C_*`).
    /// `stop` and `epsilon` are relative to the mean edge length of the input.
    pub struct FairParams {
        /// λ, curvature diffusion (3.21). Thesis recommendation 0.01 (§3.8.5).
        pub lambda: f64 = PhaseParams::surface().lambda,
        /// λ_u, non-uniformity decay (3.18). 0.01 (§3.8.5).
        pub lambda_u: f64 = PhaseParams::surface().lambda_u,
        /// T_h: curvature iterations per cycle. 50 (§3.8.4).
        pub t_h: u32 = PhaseParams::surface().t_h,
        /// T_u: non-uniformity iterations per cycle. 50.
        pub t_u: u32 = PhaseParams::surface().t_u,
        /// I: the most interior iterations, both criteria counted. The thesis ran 5000–10000
        /// iterations on its extremely noisy reconstructions (§3.8, §4.6.3); full
        /// convergence is not wanted (§2.2) and the cap sets how much is faired: the
        /// displacement stop S never fires on noisy scans before shape is lost
        /// (curvature-magnitude diffusion keeps moving vertices while H is not yet
        /// harmonic). 500 is where the distance to the clean scan is least on the noise
        /// protocol's scans (docs/fairing.md, "Measurements behind rules in the code"); the
        /// thesis' 5000 stays reachable.
        pub max_iterations: u32 = 500,
        /// S: stop when an iteration's mean displacement < `stop` × mean edge length. 1e-5.
        pub stop: f64 = PhaseParams::surface().stop,
        /// Matlab `S_end_way`: `any` phase may stop the run, or only `curvature` phases.
        pub stop_in: StopIn = StopIn::Any,
    }
    // The thesis ran boundary curves to the threshold. Borders are as smooth after 200
    // iterations as after 10000 (docs/fairing.md), while later iterations only grind against
    // the guards and change hole areas more.
    c_max_iterations = 200;
}

fairing_params! {
    /// Parameters of the `relax` step: the non-uniformity criterion alone on the interior,
    /// the thesis' pre-pass for badly triangulated scans (§4.6.3, pass 1: 50 iterations,
    /// `S_λu = 0.1`, boundary `C_λ = 0.1`, `C_λu = 0.01`, `C_maxIter = 50`).
    pub struct RelaxParams {
        pub lambda_u: f64 = 0.1,
        pub max_iterations: u32 = 50,
        pub stop: f64 = 1e-5,
    }
    c_max_iterations = 50;
}

/// Everything a run needs, whichever step asked.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    pub surface: PhaseParams,
    pub curve: PhaseParams,
    pub boundary: Border,
    pub epsilon: f64,
    pub feature_angle: Option<f64>,
    pub max_valence: Option<u32>,
    pub schedule: Schedule,
    /// A tangential step (`relax`): every triangle keeps within
    /// [`guards::BORDER_TILT_DEGREES`] of where it started, not only border ones, and every
    /// interior move is put back onto the input surface (the closest point of the vertex's
    /// fan as it was at the start of the step). Relax is meant to even the triangulation,
    /// not to turn triangles or change the shape: measured on the crumpled ggg_sfm Angel,
    /// relax then fair otherwise turned 20 triangles over; and the thesis' move `a + λ_u U`
    /// (3.37) lies in the plane of the ring's chords, which noise tilts, so on the noise
    /// protocol 50 iterations raised the distance to the clean scan by 2–6% (and fair after
    /// it ended 1.01–1.26× Taubin's distance instead of 0.97–1.23×). Projected, relax
    /// alone lowers it to 0.89–0.92× the noisy distance.
    pub tangential: bool,
}

fn check_step(name: &str, x: f64) -> Result<(), String> {
    if (0.0..1.0).contains(&x) {
        Ok(())
    } else {
        Err(format!("{name} must be in [0, 1), got {x}"))
    }
}

impl Plan {
    pub fn validate(&self) -> Result<(), String> {
        border::FAIRING.check(self.boundary)?;
        check_step("lambda", self.surface.lambda)?;
        check_step("lambda_u", self.surface.lambda_u)?;
        check_step("c_lambda", self.curve.lambda)?;
        check_step("c_lambda_u", self.curve.lambda_u)?;
        for (name, x) in [
            ("stop", self.surface.stop),
            ("c_stop", self.curve.stop),
            ("epsilon", self.epsilon),
        ] {
            if !(x >= 0.0 && x.is_finite()) {
                return Err(format!("{name} must be a finite number ≥ 0, got {x}"));
            }
        }
        if let Some(a) = self.feature_angle
            && !(positive(a) && a <= 180.0)
        {
            return Err(format!(
                "feature_angle must be in (0, 180] degrees, got {a}"
            ));
        }
        if self.max_valence.is_some_and(|v| v < 3) {
            return Err("max_valence must be at least 3".into());
        }
        Ok(())
    }
}

impl FairParams {
    pub fn plan(&self) -> Plan {
        let surface = PhaseParams {
            lambda: self.lambda,
            lambda_u: self.lambda_u,
            t_h: self.t_h,
            t_u: self.t_u,
            max_iterations: self.max_iterations,
            stop: self.stop,
            stop_in: self.stop_in,
        };
        self.plan_with(surface, false)
    }
}

impl RelaxParams {
    pub fn plan(&self) -> Plan {
        // Only the non-uniformity criterion: T_h = 0 rather than λ = 0, which would still
        // move vertices beyond the curvature maximum (docs/fairing.md, reading F3).
        let surface = PhaseParams {
            lambda: 0.0,
            lambda_u: self.lambda_u,
            t_h: 0,
            // One phase for the whole run (a length of 1 would keep the fast schedule from
            // scaling time).
            t_u: self.max_iterations.max(1),
            max_iterations: self.max_iterations,
            stop: self.stop,
            stop_in: StopIn::Any,
        };
        self.plan_with(surface, true)
    }
}

/// The figures a `relax` or `fair` step reports.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct FairReport {
    pub schedule: Schedule,
    /// Thesis iterations per run iteration (1 for `thesis`).
    pub time_scale: u32,
    /// Interior iterations run (both criteria).
    pub iterations: u32,
    pub curvature_iterations: u32,
    pub nonuniformity_iterations: u32,
    /// True if the interior stopped on the displacement threshold, false on the cap.
    pub converged: bool,
    /// Boundary curves faired, and the most iterations any of them ran.
    pub boundary_curves: usize,
    pub boundary_iterations: u32,
    /// Vertices the step may move (interior + boundary).
    pub movable_vertices: usize,
    /// Distance from input to output position, over the movable vertices.
    pub mean_displacement: f64,
    pub max_displacement: f64,
    /// Moves shortened or skipped so as not to flip a triangle.
    pub flips_avoided: u64,
    /// Moves shortened or skipped so as not to make a zero-area or needle triangle.
    pub degenerate_avoided: u64,
    /// Of those, moves skipped entirely.
    pub moves_skipped: u64,
    /// Triangles whose normal ends more than 90° from its input direction: folds of the
    /// input turned back (the guards let no other triangle turn over).
    pub flipped_vs_input: usize,
    pub fixed: FixedCounts,
    pub valence_limit: u32,
    pub vertex_updates: u64,
    pub updates_per_second: f64,
    pub time_ms: f64,
}

/// The `fair` step: both criteria (thesis ch. 2–4).
pub fn fair(mesh: &mut Mesh, params: &FairParams) -> FairReport {
    run(mesh, &params.plan())
}

/// The `relax` step: the non-uniformity criterion only (§4.6.3, pass 1).
pub fn relax(mesh: &mut Mesh, params: &RelaxParams) -> FairReport {
    run(mesh, &params.plan())
}

/// What a fairing step builds of the mesh's connectivity: every vertex's ordered ring and
/// fan, and the boundary chains. `relax` and `fair` move positions only, so the next of
/// them on the same mesh can start from the last one's instead of building the topology
/// and the rings again (on the 400k-triangle face about 260 ms of mostly sequential work,
/// issue #8). It knows the triangles it was built from and is used only on the same ones.
#[derive(Debug, Clone)]
pub struct Connectivity {
    nb: Neighbourhood,
    chains: Vec<BoundaryChain>,
    /// The triangles' vertices it was built from, as a fingerprint.
    triangles: usize,
    fingerprint: u64,
}

impl Connectivity {
    /// The connectivity of `mesh`, whose topology `topo` is.
    pub fn of(mesh: &Mesh, topo: &Topology) -> Connectivity {
        Connectivity {
            nb: Neighbourhood::new(topo),
            chains: topo.boundary_chains().to_vec(),
            triangles: mesh.triangles.len(),
            fingerprint: triangle_fingerprint(mesh),
        }
    }

    /// Whether it describes `mesh`'s triangles (same count, same vertices in order).
    fn fits(&self, mesh: &Mesh) -> bool {
        self.nb.vertex_count() == mesh.positions.len()
            && self.triangles == mesh.triangles.len()
            && self.fingerprint == triangle_fingerprint(mesh)
    }
}

/// A hash of the triangles' vertex indices in order: FNV-1a over each block of
/// [`FINGERPRINT_BLOCK`] triangles, in parallel, then over the blocks' hashes in order (the
/// same value whatever the thread count). Positions, wedges and texture coordinates do not
/// enter: the rings and chains depend on the vertex indices alone. On one thread it took
/// ~3 ms for 400k triangles at the start of every `relax` and `fair`, with the other core
/// idle.
fn triangle_fingerprint(mesh: &Mesh) -> u64 {
    const BASIS: u64 = 0xcbf2_9ce4_8422_2325;
    fn fnv(h: u64, x: u64) -> u64 {
        (h ^ x).wrapping_mul(0x0000_0100_0000_01b3)
    }
    let blocks: Vec<u64> = (0..mesh.triangles.len().div_ceil(FINGERPRINT_BLOCK))
        .into_par_iter()
        .map(|b| {
            let end = ((b + 1) * FINGERPRINT_BLOCK).min(mesh.triangles.len());
            (b * FINGERPRINT_BLOCK..end)
                .flat_map(|t| mesh.triangle_vertices(t))
                .fold(BASIS, |h, v| fnv(h, u64::from(v)))
        })
        .collect();
    blocks.into_iter().fold(BASIS, fnv)
}

/// Triangles per block of [`triangle_fingerprint`].
const FINGERPRINT_BLOCK: usize = 1 << 14;

/// Runs a plan on a mesh. Never fails: degenerate or non-manifold parts are held still.
pub fn run(mesh: &mut Mesh, plan: &Plan) -> FairReport {
    run_with(mesh, plan, None).0
}

/// [`run`], starting from the connectivity a previous `relax` or `fair` on the same
/// triangles left (built afresh when there is none or it does not fit), and returning the
/// connectivity for the next. The phases: choose the fixed vertices, fair the border curves,
/// fair the interior with the border held still, report.
pub fn run_with(
    mesh: &mut Mesh,
    plan: &Plan,
    carried: Option<Connectivity>,
) -> (FairReport, Option<Connectivity>) {
    let start = Instant::now();
    let mut report = FairReport {
        schedule: plan.schedule,
        time_scale: 1,
        ..FairReport::default()
    };
    if mesh.positions.is_empty() || mesh.triangles.is_empty() {
        return (report, None);
    }
    // The full topology is needed only to build the connectivity and for creases.
    let mut topo = None;
    let connectivity = match carried.filter(|c| c.fits(mesh)) {
        Some(c) => c,
        None => Connectivity::of(mesh, topo.insert(mesh.topology())),
    };
    let nb = &connectivity.nb;
    let input = mesh.positions.clone();
    let scale = mesh.mean_edge_length();
    if !positive(scale) {
        return (report, Some(connectivity));
    }
    let triangles = guards::triangle_vertices(mesh);
    let fixed = fixed_vertices(mesh, &triangles, nb, plan, &mut topo, &mut report);
    let references = guards::triangle_references(&triangles, &input, |v| {
        plan.tangential || (nb.is_manifold(v as usize) && !nb.is_closed(v as usize))
    });
    let mut positions = std::mem::take(&mut mesh.positions);
    let mut guard_counts = GuardCounts::default();
    let sweep = Sweep {
        nb,
        plan,
        triangles: &triangles,
        references: &references,
        fixed: &fixed,
    };
    let border_movable = sweep.fair_borders(
        &connectivity.chains,
        &mut positions,
        &mut guard_counts,
        &mut report,
    );
    // The mesh's full topology is not needed past this point; the neighbourhood has
    // what the sweeps use (a 400k-triangle scan's is ~40 MB).
    drop(topo);
    let (stats, interior_movable) = sweep.fair_interior(
        &input,
        scale,
        &mut positions,
        &mut guard_counts,
        &mut report,
    );
    mesh.positions = positions;
    report.movable_vertices = border_movable + interior_movable;
    finish_report(
        &mut report,
        mesh,
        &triangles,
        &input,
        &stats,
        &guard_counts,
        start,
    );
    tracing::debug!(?report, "fairing done");
    (report, Some(connectivity))
}

/// Which vertices stay fixed, counted by reason in `report.fixed`: non-manifold ones,
/// creases (with a feature angle) and high-valence hubs with their 1-ring.
fn fixed_vertices(
    mesh: &Mesh,
    triangles: &[[u32; 3]],
    nb: &Neighbourhood,
    plan: &Plan,
    topo: &mut Option<Topology>,
    report: &mut FairReport,
) -> Vec<bool> {
    let n = mesh.positions.len();
    let mut fixed = vec![false; n];
    let mut used = vec![false; n];
    for tri in triangles {
        for &v in tri {
            used[v as usize] = true;
        }
    }
    for v in 0..n {
        if used[v] && !nb.is_manifold(v) {
            fixed[v] = true;
            report.fixed.non_manifold += 1;
        }
    }
    if let Some(angle) = plan.feature_angle {
        let topo = topo.get_or_insert_with(|| mesh.topology());
        for (v, c) in guards::crease_vertices(mesh, topo, angle)
            .into_iter()
            .enumerate()
        {
            if c && !fixed[v] {
                fixed[v] = true;
                report.fixed.crease += 1;
            }
        }
    }
    let limit = plan
        .max_valence
        .unwrap_or_else(|| guards::default_valence_limit(nb));
    report.valence_limit = limit;
    // A hub and its whole 1-ring: fixing the hub alone does not save the vase (§3.8.1 of the
    // fairing thesis): its neighbours' curvature is dominated by the hub's long triangles,
    // whose squared areas pull them towards the hub, and the cap contracts around it
    // (docs/fairing.md has the measurement).
    let hubs: Vec<usize> = (0..n)
        .filter(|&v| nb.ring(v).len() > limit as usize)
        .collect();
    for v in hubs {
        for u in std::iter::once(v).chain(nb.ring(v).iter().map(|&u| u as usize)) {
            if !fixed[u] {
                fixed[u] = true;
                report.fixed.high_valence += 1;
            }
        }
    }
    fixed
}

/// What both fairing phases read.
struct Sweep<'a> {
    nb: &'a Neighbourhood,
    plan: &'a Plan,
    /// Every triangle's vertices ([`guards::triangle_vertices`]).
    triangles: &'a [[u32; 3]],
    references: &'a [guards::Reference],
    fixed: &'a [bool],
}

impl Sweep<'_> {
    /// C: the boundary curves first, completely (§4.5, App. B default), or, with the border
    /// fixed, counts it as held. Returns how many border vertices could move.
    fn fair_borders(
        &self,
        chains: &[BoundaryChain],
        positions: &mut [DVec3],
        guard_counts: &mut GuardCounts,
        report: &mut FairReport,
    ) -> usize {
        let (nb, plan, fixed) = (self.nb, self.plan, self.fixed);
        let (curves, held) = boundary::boundary_curves(chains, fixed);
        let boundary_fair = plan.boundary == Border::Curve
            && plan.curve.max_iterations > 0
            && plan.curve.t_h + plan.curve.t_u > 0;
        if !boundary_fair {
            report.fixed.boundary += (0..positions.len())
                .filter(|&v| nb.is_manifold(v) && !nb.is_closed(v) && !fixed[v])
                .count();
            return 0;
        }
        report.fixed.boundary += held.iter().filter(|&&v| !fixed[v as usize]).count();
        let mut movable = 0;
        for c in &curves {
            let s = boundary::fair_boundary_curve(
                positions,
                nb,
                c,
                &plan.curve,
                plan.epsilon,
                self.references,
                guard_counts,
            );
            report.boundary_iterations = report.boundary_iterations.max(s.iterations);
            report.vertex_updates += s.vertex_updates;
            movable += c
                .fixed
                .iter()
                .enumerate()
                .filter(|&(i, &f)| !f && (c.closed || (i > 0 && i + 1 < c.vertices.len())))
                .count();
        }
        report.boundary_curves = curves.len();
        movable
    }

    /// S: the interior, the border held still (§4.4). Returns the run's statistics and how
    /// many interior vertices could move.
    fn fair_interior(
        &self,
        input: &[DVec3],
        scale: f64,
        positions: &mut [DVec3],
        guard_counts: &mut GuardCounts,
        report: &mut FairReport,
    ) -> (RunStats, usize) {
        let (nb, plan) = (self.nb, self.plan);
        let movable: Vec<bool> = (0..positions.len())
            .map(|v| nb.is_closed(v) && !self.fixed[v])
            .collect();
        let movable_count = movable.iter().filter(|&&m| m).count();
        let interior = surface::Interior {
            nb,
            movable: &movable,
            movable_count,
            triangles: self.triangles,
            references: self.references,
            eps: plan.epsilon / scale,
            input: plan.tangential.then_some(input),
        };
        let (params, m) = match plan.schedule {
            Schedule::Thesis => (plan.surface, 1),
            Schedule::Fast => {
                let m = plan.surface.fast_time_scale(FAST_MAX_STEP);
                (plan.surface.time_scaled(m), m)
            }
        };
        report.time_scale = m;
        if movable_count == 0 {
            return (RunStats::default(), 0);
        }
        let mut scratch = surface::FastScratch::default();
        let stats = schedule::run(&params, scale, |phase| match (plan.schedule, phase) {
            (Schedule::Thesis, Phase::Curvature) => {
                surface::thesis_curvature_sweep(positions, &interior, params.lambda, guard_counts)
            }
            (Schedule::Thesis, Phase::Nonuniformity) => surface::thesis_nonuniformity_sweep(
                positions,
                &interior,
                params.lambda_u,
                guard_counts,
            ),
            (Schedule::Fast, Phase::Curvature) => surface::fast_curvature_sweep(
                positions,
                &interior,
                params.lambda,
                guard_counts,
                &mut scratch,
            ),
            (Schedule::Fast, Phase::Nonuniformity) => surface::fast_nonuniformity_sweep(
                positions,
                &interior,
                params.lambda_u,
                guard_counts,
                &mut scratch,
            ),
        });
        (stats, movable_count)
    }
}

/// The report's figures of a finished run: iterations, displacement, guards, flips, time.
fn finish_report(
    report: &mut FairReport,
    mesh: &Mesh,
    triangles: &[[u32; 3]],
    input: &[DVec3],
    stats: &RunStats,
    guard_counts: &GuardCounts,
    start: Instant,
) {
    report.iterations = stats.iterations;
    report.curvature_iterations = stats.curvature_iterations;
    report.nonuniformity_iterations = stats.nonuniformity_iterations;
    report.converged = stats.stopped_by_displacement;
    report.vertex_updates += stats.vertex_updates;
    let (sum, max) = displacement(input, &mesh.positions);
    report.mean_displacement = if report.movable_vertices > 0 {
        sum / report.movable_vertices as f64
    } else {
        0.0
    };
    report.max_displacement = max;
    report.flips_avoided = guard_counts.flips_avoided;
    report.degenerate_avoided = guard_counts.degenerate_avoided;
    report.moves_skipped = guard_counts.skipped;
    let input_normals = guards::triangle_normals(triangles, input);
    report.flipped_vs_input = guards::turned_over(triangles, &input_normals, &mesh.positions);
    let secs = start.elapsed().as_secs_f64();
    report.time_ms = secs * 1e3;
    report.updates_per_second = if secs > 0.0 {
        report.vertex_updates as f64 / secs
    } else {
        0.0
    };
}

/// `x > 0`, false for NaN: degenerate-geometry tests written so that NaN counts as
/// degenerate.
#[inline]
pub(crate) fn positive(x: f64) -> bool {
    x > 0.0
}

/// Sum and max of the per-vertex distances.
fn displacement(a: &[DVec3], b: &[DVec3]) -> (f64, f64) {
    a.iter()
        .zip(b)
        .map(|(p, q)| (*p - *q).length())
        .fold((0.0, 0.0f64), |(s, m), d| (s + d, m.max(d)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recipe::{Recipe, Step};
    use std::path::Path;

    #[test]
    fn recipe_steps_parse_with_thesis_names() {
        let r = Recipe::from_toml(
            "[[step]]\nkind = \"relax\"\n\n[[step]]\nkind = \"fair\"\nlambda = 0.01\nlambda_u = 0.001\nt_h = 30\nt_u = 70\nmax_iterations = 500\nstop = 1e-5\nboundary = \"fixed\"\nfeature_angle = 60.0\nschedule = \"thesis\"\n",
            Path::new("r.toml"),
        )
        .unwrap();
        assert_eq!(r.steps[0], Step::Relax(RelaxParams::default()));
        let Step::Fair(p) = &r.steps[1] else {
            panic!("not fair")
        };
        assert_eq!((p.t_h, p.t_u, p.max_iterations), (30, 70, 500));
        assert_eq!(p.boundary, Border::Fixed);
        assert_eq!(p.schedule, Schedule::Thesis);
        assert_eq!(p.feature_angle, Some(60.0));
    }

    #[test]
    fn bad_parameters_are_errors() {
        for bad in [
            "lambda = 1.5",
            "lambda_u = -0.1",
            "feature_angle = 0.0",
            "stop = -1.0",
            "sigma = 2.0",
            "schedule = \"quick\"",
        ] {
            let text = format!("[[step]]\nkind = \"fair\"\n{bad}\n");
            assert!(
                Recipe::from_toml(&text, Path::new("r.toml")).is_err(),
                "{bad}"
            );
        }
    }

    /// A grid (so with a border) with its interior and border jagged.
    fn jagged_grid() -> Mesh {
        let mut m = crate::mesh::shapes::grid(10, 8);
        for (i, p) in m.positions.iter_mut().enumerate() {
            let k = i as f64;
            *p += DVec3::new(
                0.2 * (k * 1.7).sin(),
                0.2 * (k * 2.3).cos(),
                0.3 * (k * 0.9).sin(),
            );
        }
        m
    }

    #[test]
    fn carried_connectivity_gives_the_same_result_and_is_rebuilt_when_it_does_not_fit() {
        let relax_plan = RelaxParams::default().plan();
        let fair_plan = FairParams {
            max_iterations: 100,
            ..FairParams::default()
        }
        .plan();
        // Each step on its own, building everything.
        let mut fresh = jagged_grid();
        let fresh_relax = run(&mut fresh, &relax_plan);
        let fresh_fair = run(&mut fresh, &fair_plan);
        // relax handing its connectivity to fair.
        let mut carried = jagged_grid();
        let (relax_report, connectivity) = run_with(&mut carried, &relax_plan, None);
        let connectivity = connectivity.expect("relax returns its connectivity");
        assert!(connectivity.fits(&carried));
        let (fair_report, _) = run_with(&mut carried, &fair_plan, Some(connectivity.clone()));
        assert_eq!(carried.positions, fresh.positions);
        assert_eq!(relax_report.vertex_updates, fresh_relax.vertex_updates);
        assert_eq!(fair_report.vertex_updates, fresh_fair.vertex_updates);
        assert_eq!(fair_report.boundary_curves, 1);

        // Another mesh's connectivity does not fit and is not used.
        let mut other = crate::mesh::shapes::uv_sphere(1.0, 6, 8);
        assert!(!connectivity.fits(&other));
        let mut other_fresh = other.clone();
        run(&mut other_fresh, &fair_plan);
        let (_, rebuilt) = run_with(&mut other, &fair_plan, Some(connectivity.clone()));
        assert_eq!(other.positions, other_fresh.positions);
        assert!(rebuilt.is_some_and(|c| c.fits(&other)));
        // Same counts, other triangles: the fingerprint tells them apart.
        let mut flipped = jagged_grid();
        flipped.triangles.swap(0, 1);
        assert!(!connectivity.fits(&flipped));
    }

    #[test]
    fn empty_and_degenerate_meshes_do_nothing() {
        let mut m = Mesh::default();
        let r = fair(&mut m, &FairParams::default());
        assert_eq!(r.iterations, 0);
        let mut m = crate::mesh::shapes::grid(1, 1);
        for p in m.positions.iter_mut() {
            *p = DVec3::ZERO;
        }
        let r = fair(&mut m, &FairParams::default());
        assert_eq!(r.iterations, 0);
    }
}
