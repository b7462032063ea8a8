//! Runs a recipe's steps in order on a mesh, timing each and collecting its figures.

use super::{Recipe, Step};
use crate::mesh::Mesh;
use crate::metrics::{self, MetricsOptions};
use crate::ops;
use crate::report::StepReport;
use serde_json::Value;
use std::sync::Arc;
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
fn apply(step: &Step, mesh: &mut Mesh, input: Option<&Mesh>) -> Result<serde_json::Value, String> {
    match step {
        Step::Normals(p) => Ok(figures(ops::normals::recompute_normals(mesh, p))),
        Step::Crop(p) => ops::crop::crop(mesh, p)
            .map(figures)
            .map_err(|e| e.to_string()),
        Step::Decimate(p) => {
            let (out, report) = ops::decimate::decimate(mesh, p).map_err(|e| e.to_string())?;
            *mesh = out;
            Ok(figures(report))
        }
        Step::SeamFix(p) => {
            let input = input.ok_or("seam_fix needs the loaded input mesh")?;
            Ok(figures(ops::seam_fix::seam_fix(mesh, input, p)))
        }
        Step::Relax(p) => Ok(with_texture_follow(mesh, |m| {
            figures(ops::fair::relax(m, p))
        })),
        Step::Fair(p) => Ok(with_texture_follow(mesh, |m| {
            figures(ops::fair::fair(m, p))
        })),
        Step::Smooth(p) => Ok(with_texture_follow(mesh, |m| {
            figures(ops::smooth::smooth(m, p))
        })),
    }
}

/// Runs a step that only moves vertices, then carries the texture along the surface
/// (`ops::texture_follow`); its figures go into the step's figures as `texture_follow`.
fn with_texture_follow(
    mesh: &mut Mesh,
    step: impl FnOnce(&mut Mesh) -> serde_json::Value,
) -> serde_json::Value {
    let before = mesh.has_texcoords().then(|| mesh.positions.clone());
    let mut value = step(mesh);
    if let (Some(before), Value::Object(map)) = (before, &mut value) {
        let report = ops::texture_follow::follow(mesh, before);
        map.insert("texture_follow".into(), figures(report));
    }
    value
}

/// Metrics of `result` against `reference` as report JSON; a failure (which only a bug in a
/// step can cause: an empty or non-finite mesh) is recorded in the report, not raised.
pub fn metrics_value(result: &Mesh, reference: &Mesh, options: &MetricsOptions) -> Value {
    match metrics::compare(result, reference, options) {
        Ok(m) => serde_json::to_value(m).expect("metrics always serialise"),
        Err(e) => {
            tracing::warn!(error = %e, "metrics not computed");
            serde_json::json!({ "error": e.to_string() })
        }
    }
}

/// The steps' reports and the final metrics.
#[derive(Debug, Clone)]
pub struct RunOutcome {
    pub steps: Vec<StepReport>,
    /// `metrics::FinalMetrics` of the result against the input as JSON (the input as the
    /// recipe's crop steps left it, see [`run_recipe`]), or `Null` when the recipe turns
    /// metrics off.
    pub metrics: Value,
    /// The reference the metrics measured against (the input, after the recipe's crop
    /// steps), kept for the preview; `None` when the recipe wants neither.
    pub reference: Option<Arc<Mesh>>,
}

/// Runs the steps and, unless the recipe's `[metrics]` say otherwise, measures the result
/// against the input (which is kept and returned if the metrics or the preview want it).
///
/// The reference is the input *after the recipe's crop steps* (the input itself when there
/// are none): a crop removes surface on purpose, and measuring it would drown what the
/// other steps did in the distance to the cropped-away parts and count the new border as
/// cracks. The thesis compares its decimations with the cropped scans too
/// (spec/decimation.md §8.1). `metrics.reference` in the JSON says which it was.
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
            reference: None,
        });
    }
    // One copy of the input serves both the final metrics and `seam_fix` (a 400k-triangle
    // scan's copy is ~30 MB); after a crop the metrics' reference becomes the cropped mesh.
    let input = Arc::new(mesh.clone());
    let mut reference = Arc::clone(&input);
    let mut cropped = false;
    let steps = run_steps_observed(
        recipe,
        mesh,
        progress,
        first_stage,
        total_stages,
        needs_input(recipe).then_some(input),
        &mut |step, after| {
            if matches!(step, Step::Crop(_)) {
                reference = Arc::new(after.clone());
                cropped = true;
            }
        },
    )?;
    if !recipe.metrics.enabled {
        return Ok(RunOutcome {
            steps,
            metrics: Value::Null,
            reference: Some(reference),
        });
    }
    let mut metrics = metrics_value(mesh, &reference, &recipe.metrics.options());
    if let Value::Object(map) = &mut metrics {
        let which = if cropped { "input-after-crop" } else { "input" };
        map.insert("reference".into(), Value::from(which));
    }
    Ok(RunOutcome {
        steps,
        metrics,
        reference: Some(reference),
    })
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
        &mut |_, _| {},
    )
}

/// Whether a step refers back to the loaded input through `triangle_origins`.
fn needs_input(recipe: &Recipe) -> bool {
    recipe.steps.iter().any(|s| matches!(s, Step::SeamFix(_)))
}

/// [`run_steps`], calling `after_step` with each step and the mesh it left.
fn run_steps_observed(
    recipe: &Recipe,
    mesh: &mut Mesh,
    progress: &dyn Progress,
    first_stage: usize,
    total_stages: usize,
    input: Option<Arc<Mesh>>,
    after_step: &mut dyn FnMut(&Step, &Mesh),
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
    for (i, step) in recipe.steps.iter().enumerate() {
        if changed && seam_reference.is_some() && matches!(step, Step::Decimate(_)) {
            seam_reference = Some(Arc::new(mesh.clone()));
        }
        let before = recipe.step_metrics.contains(&(i + 1)).then(|| mesh.clone());
        progress.stage(first_stage + i, total_stages, step.kind());
        let (vertices_before, faces_before) = (mesh.positions.len(), mesh.triangles.len());
        let start = Instant::now();
        let span = tracing::info_span!("step", index = i + 1, kind = step.kind());
        let _guard = span.enter();
        let figures =
            apply(step, mesh, seam_reference.as_deref()).map_err(|message| StepError {
                index: i + 1,
                kind: step.kind(),
                message,
            })?;
        debug_assert!(mesh.check_invariants().is_ok(), "{}", step.kind());
        changed = true;
        let wall_ms = start.elapsed().as_secs_f64() * 1e3;
        tracing::debug!(wall_ms, faces = mesh.triangles.len(), "step done");
        let metrics = before.map(|b| metrics_value(mesh, &b, &recipe.metrics.options()));
        after_step(step, mesh);
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
    fn metrics_off_and_crop_errors() {
        let r = recipe("[metrics]\nenabled = false\n[[step]]\nkind = \"normals\"\n");
        let mut mesh = uv_sphere(1.0, 6, 8);
        let out = run_recipe(&r, &mut mesh, &NoProgress, 0, 1).unwrap();
        assert!(out.metrics.is_null());
        // Kept for the preview: the input before the steps (normals moved nothing).
        let reference = out.reference.expect("kept for the preview");
        assert_eq!(reference.positions, mesh.positions);
        assert!(reference.normals.is_empty() && !mesh.normals.is_empty());
        let r = recipe("[metrics]\nenabled = false\n[preview]\nenabled = false\n");
        assert!(
            run_recipe(&r, &mut mesh, &NoProgress, 0, 1)
                .unwrap()
                .reference
                .is_none()
        );
        let r = recipe("[[step]]\nkind = \"crop\"\nmin = [5, 5, 5]\nmax = [6, 6, 6]\n");
        let e = run_recipe(&r, &mut mesh, &NoProgress, 0, 1).unwrap_err();
        assert_eq!((e.index, e.kind), (1, "crop"));
        assert!(e.message.contains("removes every triangle"), "{e}");
    }
}
