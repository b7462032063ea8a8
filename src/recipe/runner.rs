//! Runs a recipe's steps in order on a mesh, timing each and collecting its figures.

use super::{Recipe, Step};
use crate::mesh::Mesh;
use crate::metrics::topology::ReferenceTopology;
use crate::metrics::{self, MetricsOptions, PreparedReference, TextureCache};
use crate::ops;
use crate::preview::{self, Preview};
use crate::report::StepReport;
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
    pub kind: &'static str,
    pub message: String,
}

fn figures<T: serde::Serialize>(value: T) -> serde_json::Value {
    serde_json::to_value(value).expect("step figures always serialise")
}

/// Applies one step to the mesh and returns its figures. `input` is the mesh `seam_fix`
/// projects onto (see [`run_steps_observed`]), kept only when a step needs it.
/// A step that replaces the mesh (`decimate`) leaves the old one in `replaced`.
/// `fairing` is the connectivity a `relax` or `fair` step leaves for the next one.
fn apply(
    step: &Step,
    mesh: &mut Mesh,
    input: Option<&Mesh>,
    replaced: &mut Option<Mesh>,
    fairing: &mut Option<ops::fair::Connectivity>,
) -> Result<serde_json::Value, String> {
    let mut fair = |plan: ops::fair::Plan| {
        let (report, connectivity) = ops::fair::run_with(mesh, &plan, fairing.take());
        *fairing = connectivity;
        Ok(figures(report))
    };
    match step {
        Step::Normals(p) => Ok(figures(ops::normals::recompute_normals(mesh, p))),
        Step::Crop(p) => ops::crop::crop(mesh, p)
            .map(figures)
            .map_err(|e| e.to_string()),
        Step::Decimate(p) => {
            let (out, report) = ops::decimate::decimate(mesh, p).map_err(|e| e.to_string())?;
            *replaced = Some(std::mem::replace(mesh, out));
            Ok(figures(report))
        }
        Step::SeamFix(p) => {
            let input = input.ok_or("seam_fix needs the loaded input mesh")?;
            Ok(figures(ops::seam_fix::seam_fix(mesh, input, p)))
        }
        Step::Relax(p) => fair(p.plan()),
        Step::Fair(p) => fair(p.plan()),
        Step::Smooth(p) => Ok(figures(ops::smooth::smooth(mesh, p))),
    }
}

/// Whether a step only moves vertices (same wedges, texture coordinates and triangles), so
/// that the texture must be carried along the surface after it (`ops::texture_follow`).
fn moves_vertices(step: &Step) -> bool {
    matches!(step, Step::Relax(_) | Step::Fair(_) | Step::Smooth(_))
}

/// Metrics of `result` against `reference` as report JSON; a failure (which only a bug in a
/// step can cause: an empty or non-finite mesh) is recorded in the report, not raised.
pub fn metrics_value(result: &Mesh, reference: &Mesh, options: &MetricsOptions) -> Value {
    match metrics::compare(result, reference, options) {
        Ok(m) => serde_json::to_value(m).expect("metrics always serialise"),
        Err(e) => metrics_error(&e),
    }
}

/// The steps' reports, the final metrics and the preview.
#[derive(Debug)]
pub struct RunOutcome {
    pub steps: Vec<StepReport>,
    /// `metrics::FinalMetrics` of the result against the input as JSON (the input as the
    /// recipe's crop steps left it, see [`run_recipe`]), or `Null` when the recipe turns
    /// metrics off.
    pub metrics: Value,
    /// The picture of input, result and distance (`None` when the recipe turns it off or
    /// it could not be drawn, which is logged and does not fail the run).
    pub preview: Option<Preview>,
}

/// Runs the steps and, unless the recipe's `[metrics]` say otherwise, measures the result
/// against the input and draws the preview (the input is kept while the steps run if
/// either wants it). `progress` gets one more stage after the steps, "preview", when the
/// recipe draws one.
///
/// The reference is the input *after the recipe's crop steps* (the input itself when there
/// are none): a crop removes surface on purpose, and measuring it would drown what the
/// other steps did in the distance to the cropped-away parts and count the new border as
/// cracks. The thesis compares its decimations with the cropped scans too
/// (spec/decimation.md §8.1). `metrics.reference` in the JSON says which it was.
///
/// What the metrics need of the reference alone (its closest-point index and samples,
/// [`PreparedReference`]) is prepared on a thread of its own from the start of the first
/// decimation after the last crop, unless that decimation runs in halves: a one-pass
/// collapse loop is sequential and leaves the other core idle (400k-triangle face: about
/// 0.4 s of the whole run's wall time hidden this way). It starts no earlier so that it
/// does not add to the memory peak of `relax` and `fair`. Otherwise it is prepared after
/// the steps, the reference's topology beside its index.
pub fn run_recipe(
    recipe: &Recipe,
    mesh: &mut Mesh,
    progress: &dyn Progress,
    first_stage: usize,
    total_stages: usize,
) -> Result<RunOutcome, StepError> {
    if !recipe.metrics.enabled && !recipe.preview.enabled {
        let steps = run_steps(recipe, mesh, progress, first_stage, total_stages)?;
        return Ok(RunOutcome {
            steps,
            metrics: Value::Null,
            preview: None,
        });
    }
    // One copy of the input serves both the final metrics and `seam_fix` (a 400k-triangle
    // scan's copy is ~30 MB); after a crop the metrics' reference becomes the cropped mesh.
    let input = Arc::new(mesh.clone());
    let options = recipe.metrics.options();
    // The reference the early preparation measures; it must outlive the thread scope.
    let early_reference: OnceLock<Arc<Mesh>> = OnceLock::new();
    let mut handover = Handover {
        crack_distance_factor: recipe
            .metrics
            .enabled
            .then_some(options.crack_distance_factor),
        reference_topology: None,
    };
    std::thread::scope(|scope| {
        let mut reference = Arc::clone(&input);
        let mut cropped = false;
        let mut preparing = None;
        let steps = run_steps_observed(
            recipe,
            mesh,
            progress,
            first_stage,
            total_stages,
            needs_input(recipe).then_some(input),
            &mut handover,
            &mut |i, when, step, current| match (when, step) {
                (When::After, Step::Crop(_)) => {
                    reference = Arc::new(current.clone());
                    cropped = true;
                }
                // Not beside a decimation in halves: that keeps both cores busy itself, and
                // the preparation's memory (~25 MB on the 400k-triangle face) would add to
                // the run's peak, there or beside `seam_fix` after it (measured: 165–177 MB
                // against 146–150 MB; issue #8's budget is 160 MB for that scan). It is
                // then made after the steps.
                (When::Before, Step::Decimate(p))
                    if recipe.metrics.enabled
                        && preparing.is_none()
                        && ops::decimate::halves::wanted(current, p).is_none()
                        && !recipe.steps[i..].iter().any(|s| matches!(s, Step::Crop(_))) =>
                {
                    let reference = early_reference.get_or_init(|| Arc::clone(&reference));
                    preparing = Some(scope.spawn(move || prepare_beside(reference, &options)));
                }
                _ => {}
            },
        )?;
        let reference = early_reference.get().unwrap_or(&reference);
        // A crop after the fairing made another reference than the one handed over.
        let known_topology = handover.reference_topology.take().filter(|_| !cropped);
        let prepared = recipe.metrics.enabled.then(|| {
            let prepared = match (preparing, &known_topology) {
                (Some(thread), _) => thread
                    .join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
                (None, Some(_)) => PreparedReference::new(reference, &options),
                // After the steps the memory peak is past: the reference's topology is
                // prepared too, beside its index.
                (None, None) => PreparedReference::with_topology(reference, &options),
            };
            prepared.map(|p| match known_topology {
                Some(t) => p.with_reference_topology(t),
                None => p,
            })
        });
        // The preparation's threads freed their working memory in arenas of their own.
        crate::memory::release_freed();
        let measure = || match &prepared {
            None => Value::Null,
            Some(Err(e)) => metrics_error(e),
            Some(Ok(prepared)) => {
                match metrics::compare_prepared(mesh, prepared, &mut TextureCache::new()) {
                    Ok(m) => {
                        let mut value = serde_json::to_value(m).expect("metrics always serialise");
                        if let Value::Object(map) = &mut value {
                            let which = if cropped { "input-after-crop" } else { "input" };
                            map.insert("reference".into(), Value::from(which));
                        }
                        value
                    }
                    Err(e) => metrics_error(&e),
                }
            }
        };
        let draw = || {
            if !recipe.preview.enabled {
                return None;
            }
            progress.stage(first_stage + recipe.steps.len(), total_stages, "preview");
            let drawn = match &prepared {
                Some(Ok(prepared)) => {
                    preview::render_with_index(prepared.index(), mesh, &recipe.preview)
                }
                _ => preview::render(reference, mesh, &recipe.preview),
            };
            drawn
                .inspect(|p| tracing::info!(ms = p.figures.render_ms, "preview drawn"))
                .inspect_err(|e| tracing::warn!(error = %e, "no preview"))
                .ok()
        };
        // Side by side when the reference's topology is prepared already: each is parallel
        // inside but leaves part of the second core idle, and neither reads what the other
        // computes. Otherwise one after the other: the metrics then build the reference's
        // topology (~40 MB on the 400k-triangle face), which with the preview's buffers
        // took the run's peak from 148 to 169 MB, over issue #8's 400 bytes per triangle.
        let side_by_side = matches!(&prepared, Some(Ok(p)) if p.has_topology());
        let (metrics, preview) = if side_by_side {
            rayon::join(measure, draw)
        } else {
            let metrics = measure();
            crate::memory::release_freed();
            (metrics, draw())
        };
        Ok(RunOutcome {
            steps,
            metrics,
            preview,
        })
    })
}

/// Prepares the reference's half of the metrics on fewer threads than the machine has:
/// it runs beside the decimation, whose sequential loop keeps one core busy.
fn prepare_beside<'a>(
    reference: &'a Mesh,
    options: &MetricsOptions,
) -> Result<PreparedReference<'a>, metrics::MetricsError> {
    let threads = rayon::current_num_threads().saturating_sub(1).max(1);
    match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
        Ok(pool) => pool.install(|| PreparedReference::new(reference, options)),
        Err(_) => PreparedReference::new(reference, options),
    }
}

/// A metrics failure (which only a bug in a step can cause: an empty or non-finite mesh)
/// is recorded in the report, not raised.
fn metrics_error(e: &metrics::MetricsError) -> Value {
    tracing::warn!(error = %e, "metrics not computed");
    serde_json::json!({ "error": e.to_string() })
}

/// When an observer of the steps is called: before a step runs, or after it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum When {
    Before,
    After,
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
    let input = needs_input(recipe).then(|| Arc::new(mesh.clone()));
    run_steps_observed(
        recipe,
        mesh,
        progress,
        first_stage,
        total_stages,
        input,
        &mut Handover::default(),
        &mut |_, _, _, _| {},
    )
}

/// Whether a step refers back to the loaded input through `triangle_origins`.
fn needs_input(recipe: &Recipe) -> bool {
    recipe.steps.iter().any(|s| matches!(s, Step::SeamFix(_)))
}

/// What the steps hand on to the final metrics: the reference's topology, when the first
/// step is a fairing step, which builds the topology of the untouched input anyway. The
/// metrics would otherwise build it again after the steps (about 160 ms of one core on the
/// 400k-triangle face, issue #8). What is kept is small: counts and the border's segments.
#[derive(Default)]
struct Handover {
    /// The final metrics' crack distance factor; `None` when there are no final metrics.
    crack_distance_factor: Option<f64>,
    /// The input's reference topology, as the steps found it before any of them ran.
    reference_topology: Option<ReferenceTopology>,
}

/// [`run_steps`], calling `observe` with each step's index and the mesh before and after it.
#[allow(clippy::too_many_arguments)]
fn run_steps_observed(
    recipe: &Recipe,
    mesh: &mut Mesh,
    progress: &dyn Progress,
    first_stage: usize,
    total_stages: usize,
    input: Option<Arc<Mesh>>,
    handover: &mut Handover,
    observe: &mut dyn FnMut(usize, When, &Step, &Mesh),
) -> Result<Vec<StepReport>, StepError> {
    let mut reports = Vec::with_capacity(recipe.steps.len());
    // `seam_fix` projects onto the mesh as it was just before the decimation (positions
    // and texture coordinates as the decimator saw them), not onto the mesh as loaded:
    // after `relax` and `fair` the loaded positions are up to a few edge lengths away, and
    // projecting the faired corners onto them smeared texture along the eyebrows of Lee
    // Perry-Smith. Triangle origins always index the loaded mesh; seam_fix maps them
    // through the snapshot's own origins when a crop changed its triangles.
    let mut seam_reference = input;
    let mut changed = false;
    // The texture is carried along the surface once per run of vertex-moving steps
    // (relax, fair, smooth): from the surface before the first to the positions after the
    // last. One read-back instead of one per step halves its cost (a closest-point index
    // over the whole scan and a query per corner) and projects onto the surface as it was
    // scanned rather than onto an intermediate one. It is done early when a step asks for
    // its own metrics, so that those see the texture where it belongs.
    let mut follow_from: Option<Vec<glam::DVec3>> = None;
    // Kept from one fairing step to the next only (`relax` then `fair`): no other step
    // uses it, and it must not add to the memory of the decimation after them.
    let mut fairing = None;
    for (i, step) in recipe.steps.iter().enumerate() {
        observe(i, When::Before, step, mesh);
        let before = recipe.step_metrics.contains(&(i + 1)).then(|| mesh.clone());
        progress.stage(first_stage + i, total_stages, step.kind());
        let (vertices_before, faces_before) = (mesh.positions.len(), mesh.triangles.len());
        let start = Instant::now();
        let span = tracing::info_span!("step", index = i + 1, kind = step.kind());
        let _guard = span.enter();
        if moves_vertices(step) && follow_from.is_none() && mesh.has_texcoords() {
            follow_from = Some(mesh.positions.clone());
        }
        // The first step fairs the input as loaded: one topology serves both.
        if !changed
            && fairing.is_none()
            && matches!(step, Step::Relax(_) | Step::Fair(_))
            && let Some(factor) = handover.crack_distance_factor
        {
            let topology = mesh.topology();
            let (reference, connectivity) = rayon::join(
                || ReferenceTopology::from_topology(mesh, &topology, factor),
                || ops::fair::Connectivity::of(mesh, &topology),
            );
            handover.reference_topology = Some(reference);
            fairing = Some(connectivity);
        }
        let mut replaced = None;
        let mut figures = apply(
            step,
            mesh,
            seam_reference.as_deref(),
            &mut replaced,
            &mut fairing,
        )
        .map_err(|message| StepError {
            index: i + 1,
            kind: step.kind(),
            message,
        })?;
        // The mesh the decimation started from becomes the snapshot (no copy of it is
        // made: the decimator needed it whole until its output was built anyway).
        if let Some(old) = replaced
            && changed
            && seam_reference.is_some()
        {
            seam_reference = Some(Arc::new(old));
        }
        if !matches!(
            recipe.steps.get(i + 1),
            Some(Step::Relax(_) | Step::Fair(_))
        ) {
            fairing = None;
        }
        let run_goes_on = recipe.steps.get(i + 1).is_some_and(moves_vertices);
        if (!run_goes_on || before.is_some())
            && let (Some(from), Value::Object(map)) = (follow_from.take(), &mut figures)
        {
            let report = ops::texture_follow::follow(mesh, from);
            map.insert("texture_follow".into(), self::figures(report));
        }
        debug_assert!(mesh.check_invariants().is_ok(), "{}", step.kind());
        changed = true;
        let wall_ms = start.elapsed().as_secs_f64() * 1e3;
        tracing::debug!(wall_ms, faces = mesh.triangles.len(), "step done");
        let metrics = before.map(|b| metrics_value(mesh, &b, &recipe.metrics.options()));
        observe(i, When::After, step, mesh);
        crate::memory::release_freed();
        reports.push(StepReport {
            kind: step.kind().to_string(),
            wall_ms,
            vertices_before,
            vertices_after: mesh.positions.len(),
            faces_before,
            faces_after: mesh.triangles.len(),
            figures,
            metrics,
        });
    }
    Ok(reports)
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
        let out = run_recipe(&r, &mut mesh, &NoProgress, 1, 4).unwrap();
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
        let out = run_recipe(&r, &mut mesh, &NoProgress, 0, 1).unwrap();
        assert!(mesh.positions != input.positions);
        let fresh = metrics_value(&mesh, &input, &r.metrics.options());
        assert_eq!(out.metrics["topology"], fresh["topology"]);
        assert!(out.metrics["topology"]["crack_distance"].as_f64().unwrap() > 0.0);
    }

    #[test]
    fn metrics_off_and_crop_errors() {
        let r = recipe("[metrics]\nenabled = false\n[[step]]\nkind = \"normals\"\n");
        let mut mesh = uv_sphere(1.0, 6, 8);
        let out = run_recipe(&r, &mut mesh, &NoProgress, 0, 1).unwrap();
        assert!(out.metrics.is_null());
        // Drawn though the metrics are off.
        assert!(out.preview.is_some());
        let r = recipe("[metrics]\nenabled = false\n[preview]\nenabled = false\n");
        assert!(
            run_recipe(&r, &mut mesh, &NoProgress, 0, 1)
                .unwrap()
                .preview
                .is_none()
        );
        let r = recipe("[[step]]\nkind = \"crop\"\nmin = [5, 5, 5]\nmax = [6, 6, 6]\n");
        let e = run_recipe(&r, &mut mesh, &NoProgress, 0, 1).unwrap_err();
        assert_eq!((e.index, e.kind), (1, "crop"));
        assert!(e.message.contains("removes every triangle"), "{e}");
    }
}
