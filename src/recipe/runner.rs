//! Runs a recipe's steps in order on a mesh, timing each and collecting its figures, then
//! measures the result and draws the preview. The steps themselves are
//! [`RecipeStep`]s; what they hand each other is the
//! [`StepContext`].

use super::step::{self, IdleCore, RecipeStep, StepContext};
use super::{Recipe, Step};
use crate::mesh::{InputLimits, Mesh};
use crate::metrics::TextureCache;
pub use crate::metrics::schedule::metrics_value;
use crate::metrics::schedule::{FinalReference, ReferenceSchedule};
use crate::ops;
use crate::ops::texture_follow::FollowReport;
use crate::preview::{self, Preview};
use crate::report::StepReport;
use glam::DVec3;
use serde_json::Value;
use std::sync::{Arc, OnceLock};
use std::time::Instant;

/// Receives progress while a scan is processed. The command line draws a progress bar with
/// it; the daemon logs. Implementations must be cheap: they are called between steps only.
pub trait Progress: Sync {
    /// A stage (loading, a step, writing) begins; `index` counts from 0 to `total` - 1.
    fn stage(&self, _index: usize, _total: usize, _name: &str) {}
}

/// Progress that goes nowhere.
pub struct NoProgress;
impl Progress for NoProgress {}

#[derive(Debug, thiserror::Error)]
#[error("step {index} ({kind}): {message}")]
pub struct StepError {
    /// 1-based position of the step in the recipe.
    pub index: usize,
    pub kind: String,
    pub message: String,
}

/// The steps' reports, the final metrics and the preview.
#[derive(Debug)]
pub struct RunOutcome {
    pub steps: Vec<StepReport>,
    /// `metrics::FinalMetrics` of the result against the input as JSON (the input as the
    /// recipe's crop steps left it, see `metrics::schedule`), or `Null` when the recipe turns
    /// metrics off.
    pub metrics: Value,
    /// The picture of input, result and distance (`None` when the recipe turns it off or
    /// it could not be drawn, which is logged and does not fail the run).
    pub preview: Option<Preview>,
}

/// Where the steps stand in the caller's overall progress (loading comes before them,
/// writing after).
#[derive(Clone, Copy)]
struct Stages<'a> {
    progress: &'a dyn Progress,
    first: usize,
    total: usize,
}

/// Runs the steps and, unless the recipe's `[metrics]` say otherwise, measures the result
/// against the input and draws the preview (the input is kept while the steps run if
/// either wants it). `progress` gets one more stage after the steps, "preview", when the
/// recipe draws one. Which mesh the metrics measure against, and when it is prepared, is
/// `metrics::schedule`'s business. Every texture the steps, the metrics and the preview
/// decode stays within `limits`, the limits the scan was loaded under.
pub fn run_recipe(
    recipe: &Recipe,
    mesh: &mut Mesh,
    limits: &InputLimits,
    progress: &dyn Progress,
    first_stage: usize,
    total_stages: usize,
) -> Result<RunOutcome, StepError> {
    let stages = Stages {
        progress,
        first: first_stage,
        total: total_stages,
    };
    // One decoded copy of each texture for the steps, the metrics and the preview.
    let textures = TextureCache::with_limits(limits.clone());
    if !recipe.metrics.enabled && !recipe.preview.enabled {
        let cx = StepContext::new(seam_reference_of(recipe, mesh), textures);
        return Ok(RunOutcome {
            steps: run_steps_with(recipe, mesh, stages, cx, &mut NoHooks)?,
            metrics: Value::Null,
            preview: None,
        });
    }
    // One copy of the input serves both the final metrics and `seam_fix` (a 400k-triangle
    // scan's copy is ~30 MB).
    let input = Arc::new(mesh.clone());
    // Holds the reference the early preparation measures; it must outlive the thread scope.
    let slot = OnceLock::new();
    std::thread::scope(|scope| {
        let options = recipe.metrics.options();
        let mut hooks = MetricsHooks {
            schedule: ReferenceSchedule::new(
                Arc::clone(&input),
                options,
                recipe.metrics.enabled,
                &slot,
            ),
            scope,
            recipe,
        };
        let seam_reference = needs_seam_reference(recipe).then_some(input);
        let cx = StepContext::new(seam_reference, textures.clone());
        let steps = run_steps_with(recipe, mesh, stages, cx, &mut hooks)?;
        let reference = hooks.schedule.finish();
        // The preparation's threads freed their working memory in arenas of their own.
        crate::memory::release_freed();
        let (metrics, preview) = measure_and_draw(recipe, mesh, &reference, stages, textures);
        Ok(RunOutcome {
            steps,
            metrics,
            preview,
        })
    })
}

/// The final metrics and the preview. Side by side when the reference's topology is
/// prepared already: each is parallel inside but leaves part of the second core idle, and
/// neither reads what the other computes. Otherwise one after the other: the metrics then
/// build the reference's topology, which with the preview's buffers would raise the run's
/// memory peak (docs/face-scan.md). Both read textures through `textures`, the run's cache,
/// where the steps may have left them decoded.
fn measure_and_draw(
    recipe: &Recipe,
    mesh: &Mesh,
    reference: &FinalReference<'_>,
    stages: Stages<'_>,
    textures: TextureCache,
) -> (Value, Option<Preview>) {
    let measure = || reference.measure_with(mesh, &mut textures.clone());
    // Drawn on whichever thread is free: under the job's span, so its log line names the job.
    let span = tracing::Span::current();
    let draw =
        || span.in_scope(|| draw_preview(recipe, mesh, reference, stages, &mut textures.clone()));
    if reference.has_topology() {
        rayon::join(measure, draw)
    } else {
        let metrics = measure();
        crate::memory::release_freed();
        (metrics, draw())
    }
}

/// The preview, drawn with the metrics' closest-point index when there is one; `None` when
/// the recipe turns it off or it cannot be drawn (logged).
fn draw_preview(
    recipe: &Recipe,
    mesh: &Mesh,
    reference: &FinalReference<'_>,
    stages: Stages<'_>,
    textures: &mut TextureCache,
) -> Option<Preview> {
    if !recipe.preview.enabled {
        return None;
    }
    let stage = stages.first + recipe.steps.len();
    stages.progress.stage(stage, stages.total, "preview");
    let (input, index) = match &reference.prepared {
        Some(Ok(prepared)) => (prepared.mesh(), Some(prepared.index())),
        _ => (reference.reference, None),
    };
    let drawn = preview::render_with_textures(input, index, mesh, &recipe.preview, textures);
    drawn
        .inspect(|p| tracing::info!(ms = p.figures.render_ms, "preview drawn"))
        .inspect_err(|e| tracing::warn!(error = %e, "no preview"))
        .ok()
}

/// Runs every step of `recipe` on `mesh`. `first_stage`/`total_stages` place the steps
/// within the caller's overall progress (loading comes before, writing after).
pub fn run_steps(
    recipe: &Recipe,
    mesh: &mut Mesh,
    progress: &dyn Progress,
    first_stage: usize,
    total_stages: usize,
) -> Result<Vec<StepReport>, StepError> {
    let stages = Stages {
        progress,
        first: first_stage,
        total: total_stages,
    };
    let cx = StepContext::new(seam_reference_of(recipe, mesh), TextureCache::new());
    run_steps_with(recipe, mesh, stages, cx, &mut NoHooks)
}

/// Whether a step reads the seam reference (the input, then a snapshot).
fn needs_seam_reference(recipe: &Recipe) -> bool {
    recipe
        .steps
        .iter()
        .any(|s| s.as_recipe_step().needs_seam_reference())
}

/// A copy of the input for the seam reference, when a step reads it.
fn seam_reference_of(recipe: &Recipe, mesh: &Mesh) -> Option<Arc<Mesh>> {
    needs_seam_reference(recipe).then(|| Arc::new(mesh.clone()))
}

/// What runs around each step besides the step itself.
trait StepHooks {
    fn before(&mut self, _index: usize, _step: &Step, _mesh: &Mesh, _cx: &mut StepContext) {}
    fn after(&mut self, _index: usize, _step: &Step, _mesh: &Mesh) {}

    /// Carries the texture of `mesh` from the surface at `before` to where its vertices
    /// are now, after step `index` ([`TextureFollow`]).
    fn follow(&mut self, _index: usize, mesh: &mut Mesh, before: Vec<DVec3>) -> FollowReport {
        ops::texture_follow::follow(mesh, before)
    }
}

struct NoHooks;
impl StepHooks for NoHooks {}

/// Tells the final metrics' [`ReferenceSchedule`] what the steps do.
struct MetricsHooks<'scope, 'env, 'r> {
    schedule: ReferenceSchedule<'scope, 'env>,
    scope: &'scope std::thread::Scope<'scope, 'env>,
    recipe: &'r Recipe,
}

impl StepHooks for MetricsHooks<'_, '_, '_> {
    fn before(&mut self, index: usize, step: &Step, mesh: &Mesh, cx: &mut StepContext) {
        let step = step.as_recipe_step();
        // The first step fairs the input as loaded: one topology serves it and the metrics.
        if index == 0 && step.uses_fairing_connectivity() {
            cx.fairing = self
                .schedule
                .share_input_topology(mesh, |t| ops::fair::Connectivity::of(mesh, t));
            // The input's topology is gone; its memory would otherwise stay in the
            // allocator's arenas under the fairing's working arrays.
            crate::memory::release_freed();
        }
        let crop_follows = self.recipe.steps[index..]
            .iter()
            .any(|s| s.as_recipe_step().removes_surface());
        let room = match step.idle_core(mesh, cx) {
            IdleCore::Mostly => true,
            IdleCore::Briefly => self.schedule.only_samples_left(),
            IdleCore::No => false,
        };
        if self.schedule.can_prepare_early() && room && !crop_follows {
            self.schedule.prepare_beside_step(self.scope);
        }
    }

    fn after(&mut self, _index: usize, step: &Step, mesh: &Mesh) {
        if step.as_recipe_step().removes_surface() {
            self.schedule.reference_cropped(mesh);
        }
    }

    /// Through the metrics' index over the reference when the surface before the run is
    /// the reference (see [`ReferenceSchedule::input_index`]).
    fn follow(&mut self, index: usize, mesh: &mut Mesh, before: Vec<DVec3>) -> FollowReport {
        let crop_follows = self.recipe.steps[index + 1..]
            .iter()
            .any(|s| s.as_recipe_step().removes_surface());
        let schedule = &mut self.schedule;
        ops::texture_follow::follow_with(mesh, before, |before| {
            schedule.input_index(before, crop_follows)
        })
    }
}

/// The texture is carried along the surface once per run of vertex-moving steps (relax,
/// fair, smooth): from the surface before the first to the positions after the last. One
/// read-back instead of one per step halves its cost (a closest-point index over the whole
/// scan and a query per corner) and projects onto the surface as it was scanned rather than
/// onto an intermediate one. It is done early when a step asks for its own metrics, so that
/// those see the texture where it belongs.
#[derive(Default)]
struct TextureFollow {
    from: Option<Vec<DVec3>>,
}

impl TextureFollow {
    fn begin(&mut self, step: &dyn RecipeStep, mesh: &Mesh) {
        if step.moves_vertices() && self.from.is_none() && mesh.has_texcoords() {
            self.from = Some(mesh.positions.clone());
        }
    }

    /// After a step: follows unless `unseen_run_goes_on` (the run of vertex-moving steps
    /// goes on and nothing measures the mesh in between), adding `texture_follow` to the
    /// step's figures.
    fn end(
        &mut self,
        mesh: &mut Mesh,
        unseen_run_goes_on: bool,
        figures: &mut Value,
        follow: impl FnOnce(&mut Mesh, Vec<DVec3>) -> FollowReport,
    ) {
        if !unseen_run_goes_on && let (Some(from), Value::Object(map)) = (self.from.take(), figures)
        {
            let report = follow(mesh, from);
            map.insert("texture_follow".into(), step::figures(report));
        }
    }
}

/// The scan's own normals after a run of vertex-moving steps: recomputed from the moved
/// surface, shared as the scan shared them, adding `normals_refresh` to the step's figures.
/// Without this they would be written as the scanner computed them, for a surface the
/// steps have since smoothed. A mesh without normals, or one whose recipe has a `normals`
/// step (the runner dropped them before the steps), has none to refresh. (`decimate`
/// carries normals as attributes by its own rule, `normal_weight`; what it writes is left
/// as it is.)
fn refresh_scan_normals(mesh: &mut Mesh, figures: &mut Value) {
    if mesh.normals.is_empty() {
        return;
    }
    let report = ops::normals::refresh_normals(mesh);
    if let Value::Object(map) = figures {
        map.insert("normals_refresh".into(), step::figures(report));
    }
}

/// Runs the steps in order, each between `hooks.before` and `hooks.after`.
fn run_steps_with(
    recipe: &Recipe,
    mesh: &mut Mesh,
    stages: Stages<'_>,
    mut cx: StepContext,
    hooks: &mut dyn StepHooks,
) -> Result<Vec<StepReport>, StepError> {
    let mut reports = Vec::with_capacity(recipe.steps.len());
    let mut follow = TextureFollow::default();
    // The steps before one that replaces the normals would only carry the scan's own along
    // (the decimation as three more attribute channels on every wedge; docs/face-scan.md
    // measures what that cost). The input the metrics and the preview read keeps them.
    if recipe
        .steps
        .iter()
        .any(|s| s.as_recipe_step().replaces_normals())
    {
        mesh.drop_normals();
    }
    for (i, step) in recipe.steps.iter().enumerate() {
        hooks.before(i, step, mesh, &mut cx);
        let report = run_one(recipe, i, mesh, stages, &mut cx, &mut follow, hooks)?;
        hooks.after(i, step, mesh);
        crate::memory::release_freed();
        reports.push(report);
    }
    Ok(reports)
}

/// Runs step `i` of the recipe: times it, carries the texture along, measures it when the
/// recipe asks for the step's own metrics, and reports it.
fn run_one(
    recipe: &Recipe,
    i: usize,
    mesh: &mut Mesh,
    stages: Stages<'_>,
    cx: &mut StepContext,
    follow: &mut TextureFollow,
    hooks: &mut dyn StepHooks,
) -> Result<StepReport, StepError> {
    let step = &recipe.steps[i];
    let next = recipe.steps.get(i + 1).map(Step::as_recipe_step);
    let before = recipe.step_metrics.contains(&(i + 1)).then(|| mesh.clone());
    let kind = step.kind();
    stages.progress.stage(stages.first + i, stages.total, &kind);
    let (vertices_before, faces_before) = (mesh.positions.len(), mesh.triangles.len());
    let start = Instant::now();
    let span = tracing::info_span!("step", index = i + 1, kind = kind.as_str());
    let _guard = span.enter();
    follow.begin(step.as_recipe_step(), mesh);
    let mut figures = step
        .as_recipe_step()
        .run(mesh, cx)
        .map_err(|message| StepError {
            index: i + 1,
            kind: kind.clone(),
            message,
        })?;
    // Kept from one fairing step to the next only (`relax` then `fair`): no other step uses
    // it, and it must not add to the memory of the decimation after them.
    if !next.is_some_and(|s| s.uses_fairing_connectivity()) {
        cx.fairing = None;
    }
    // The run of vertex-moving steps goes on and nothing measures the mesh in between: the
    // texture and the scan's own normals follow once, after the run's last step.
    let unseen_run_goes_on = next.is_some_and(|s| s.moves_vertices()) && before.is_none();
    follow.end(mesh, unseen_run_goes_on, &mut figures, |mesh, before| {
        hooks.follow(i, mesh, before)
    });
    if step.as_recipe_step().moves_vertices() && !unseen_run_goes_on {
        refresh_scan_normals(mesh, &mut figures);
    }
    debug_assert!(mesh.check_invariants().is_ok(), "{kind}");
    cx.changed = true;
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    tracing::debug!(wall_ms, faces = mesh.triangles.len(), "step done");
    let metrics = before.map(|b| metrics_value(mesh, &b, &recipe.metrics.options()));
    Ok(StepReport {
        kind,
        wall_ms,
        vertices_before,
        vertices_after: mesh.positions.len(),
        faces_before,
        faces_after: mesh.triangles.len(),
        figures,
        metrics,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::uv_sphere;
    use std::path::Path;

    fn recipe(text: &str) -> Recipe {
        Recipe::from_toml(text, Path::new("r.toml")).unwrap()
    }

    #[test]
    fn final_metrics_against_the_cropped_input_and_per_step_metrics() {
        let r = recipe(
            "[metrics]\nsamples = 2000\n[[step]]\nkind = \"crop\"\nabs_max = [2, 2, 0.5]\nmode = \"clip\"\nmetrics = true\n[[step]]\nkind = \"normals\"\n",
        );
        let mut mesh = uv_sphere(1.0, 12, 16);
        let out = run_recipe(&r, &mut mesh, &InputLimits::default(), &NoProgress, 1, 4).unwrap();
        assert_eq!(out.metrics["reference"], "input-after-crop");
        // Normals move nothing: the result is the cropped input.
        assert!(out.metrics["distance"]["max"].as_f64().unwrap() < 1e-12);
        assert_eq!(out.metrics["topology"]["cracks"], 0);
        let step = out.steps[0].metrics.as_ref().unwrap();
        assert_eq!(step["volume"]["result"]["status"], "not-closed");
        assert_eq!(step["volume"]["reference"]["status"], "closed");
        assert!(out.steps[1].metrics.is_none());
        assert_eq!(out.steps[0].figures["mode"], "clip");
    }

    #[test]
    fn reference_topology_handed_over_by_a_first_relax_is_the_inputs() {
        let r = recipe(
            "[metrics]\nsamples = 2000\n[[step]]\nkind = \"relax\"\nmax_iterations = 4\n[[step]]\nkind = \"normals\"\n",
        );
        // A grid (it has a border) with its interior jagged, so that relax moves it.
        let mut input = crate::mesh::shapes::grid(8, 6);
        for (i, p) in input.positions.iter_mut().enumerate() {
            p.x += 0.2 * (i as f64 * 1.7).sin();
            p.y += 0.2 * (i as f64 * 2.3).cos();
        }
        let mut mesh = input.clone();
        let out = run_recipe(&r, &mut mesh, &InputLimits::default(), &NoProgress, 0, 1).unwrap();
        assert!(mesh.positions != input.positions);
        let fresh = metrics_value(&mesh, &input, &r.metrics.options());
        assert_eq!(out.metrics["topology"], fresh["topology"]);
        assert!(out.metrics["topology"]["crack_distance"].as_f64().unwrap() > 0.0);
    }

    /// The texture follow reads the input through the final metrics' index (one index
    /// for both): the mesh, its texture coordinates and the metrics are those of a run
    /// where each builds its own; and a second run of vertex-moving steps, after a remesh,
    /// reads its own surface, not the input.
    #[test]
    fn one_input_index_for_the_texture_follow_and_the_metrics() {
        let fairing = "[[step]]\nkind = \"relax\"\nmax_iterations = 4\n[[step]]\nkind = \"fair\"\nmax_iterations = 3\n";
        let later = "[[step]]\nkind = \"remesh\"\nedge_fraction = 0.08\n[[step]]\nkind = \"smooth\"\nmethod = \"laplace\"\niterations = 3\n";
        let mut input = crate::mesh::shapes::grid(12, 10);
        for (i, p) in input.positions.iter_mut().enumerate() {
            p.z += 0.15 * (i as f64 * 1.7).sin();
            p.x += 0.1 * (i as f64 * 2.3).cos();
        }
        for steps in [fairing.to_string(), format!("{fairing}{later}")] {
            let r = recipe(&format!("[metrics]\nsamples = 3000\n{steps}"));
            let mut shared = input.clone();
            let out =
                run_recipe(&r, &mut shared, &InputLimits::default(), &NoProgress, 0, 1).unwrap();
            let mut separate = input.clone();
            let reports = run_steps(&r, &mut separate, &NoProgress, 0, 1).unwrap();
            assert!(shared.positions != input.positions, "the steps moved it");
            let corners = &reports[1].figures["texture_follow"]["corners"];
            assert!(corners.as_u64().unwrap() > 0);
            assert_eq!(shared.positions, separate.positions);
            assert_eq!(shared.texcoords, separate.texcoords);
            assert_eq!(shared.wedges, separate.wedges);
            for (a, b) in out.steps.iter().zip(&reports) {
                assert_eq!(a.figures["texture_follow"], b.figures["texture_follow"]);
            }
            let fresh = metrics_value(&separate, &input, &r.metrics.options());
            for key in ["distance", "texture", "normals"] {
                assert_eq!(out.metrics[key], fresh[key], "{key}");
            }
        }
    }

    #[test]
    fn the_scans_normals_are_dropped_only_before_a_step_that_replaces_them() {
        let scan = crate::mesh::shapes::with_a_normal_per_triangle(crate::mesh::shapes::grid(4, 3));
        let (vertices, corners) = (scan.positions.len(), 3 * scan.triangles.len());
        // A normals step: it finds one wedge per vertex, the scan's normals gone before it.
        let r = recipe(
            "[[step]]\nkind = \"relax\"\nmax_iterations = 2\n[[step]]\nkind = \"normals\"\n",
        );
        let mut mesh = scan.clone();
        let steps = run_steps(&r, &mut mesh, &NoProgress, 0, 2).unwrap();
        assert_eq!(steps[1].figures["wedges_before"], vertices);
        assert_eq!(mesh.normals.len(), vertices);
        // No normals step: the scan's wedges stay (one per corner), and their normals,
        // all equal, are refreshed as one per vertex after relax.
        let r = recipe("[[step]]\nkind = \"relax\"\nmax_iterations = 2\n");
        let mut mesh = scan.clone();
        run_steps(&r, &mut mesh, &NoProgress, 0, 1).unwrap();
        assert_eq!((mesh.wedges.len(), mesh.normals.len()), (corners, vertices));
    }

    #[test]
    fn a_scans_normals_follow_the_steps_that_move_its_vertices() {
        // A sphere whose normals all point along +Z, shared by each vertex's wedges.
        let mut scan = uv_sphere(1.0, 10, 16);
        for w in &mut scan.wedges {
            w.normal = Some(0);
        }
        scan.normals = vec![glam::DVec3::Z];
        let outward = |mesh: &Mesh| {
            mesh.wedges.iter().all(|w| {
                let n = mesh.normals[w.normal.unwrap() as usize];
                n.dot(mesh.positions[w.vertex as usize].normalize()) > 0.95
            })
        };
        assert!(!outward(&scan));
        // Two smoothing steps: refreshed once, after the second, and reported there.
        let r = recipe(
            "[[step]]\nkind = \"smooth\"\nmethod = \"laplace\"\niterations = 2\n\
             [[step]]\nkind = \"smooth\"\nmethod = \"taubin\"\niterations = 2\n",
        );
        let mut mesh = scan.clone();
        let steps = run_steps(&r, &mut mesh, &NoProgress, 0, 2).unwrap();
        assert!(mesh.positions != scan.positions);
        assert!(outward(&mesh));
        assert_eq!(mesh.normals.len(), scan.positions.len());
        assert!(steps[0].figures.get("normals_refresh").is_none());
        assert_eq!(
            steps[1].figures["normals_refresh"]["normals"],
            scan.positions.len()
        );
        // A step that does not move vertices leaves them as they are.
        let r = recipe("[[step]]\nkind = \"seam_fix\"\n");
        let mut mesh = scan.clone();
        run_steps(&r, &mut mesh, &NoProgress, 0, 1).unwrap();
        assert_eq!(mesh.normals, scan.normals);
    }

    #[test]
    fn metrics_off_and_crop_errors() {
        let r = recipe("[metrics]\nenabled = false\n[[step]]\nkind = \"normals\"\n");
        let mut mesh = uv_sphere(1.0, 6, 8);
        let out = run_recipe(&r, &mut mesh, &InputLimits::default(), &NoProgress, 0, 1).unwrap();
        assert!(out.metrics.is_null());
        // Drawn though the metrics are off.
        assert!(out.preview.is_some());
        let r = recipe("[metrics]\nenabled = false\n[preview]\nenabled = false\n");
        assert!(
            run_recipe(&r, &mut mesh, &InputLimits::default(), &NoProgress, 0, 1)
                .unwrap()
                .preview
                .is_none()
        );
        let r = recipe("[[step]]\nkind = \"crop\"\nmin = [5, 5, 5]\nmax = [6, 6, 6]\n");
        let e = run_recipe(&r, &mut mesh, &InputLimits::default(), &NoProgress, 0, 1).unwrap_err();
        assert_eq!((e.index, e.kind.as_str()), (1, "crop"));
        assert!(e.message.contains("removes every triangle"), "{e}");
    }
}
