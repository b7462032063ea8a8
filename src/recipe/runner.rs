//! Runs a recipe's steps in order on a mesh, timing each and collecting its figures.

use super::{Recipe, Step};
use crate::mesh::Mesh;
use crate::ops;
use crate::report::StepReport;
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

/// Applies one step to the mesh and returns its figures.
fn apply(step: &Step, mesh: &mut Mesh) -> Result<serde_json::Value, String> {
    match step {
        Step::Normals(p) => Ok(figures(ops::normals::recompute_normals(mesh, p))),
        Step::Smooth(p) => Ok(figures(ops::smooth::smooth(mesh, p))),
        other => Err(format!(
            "step kind `{}` is not implemented in this version",
            other.kind()
        )),
    }
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
    let mut reports = Vec::with_capacity(recipe.steps.len());
    for (i, step) in recipe.steps.iter().enumerate() {
        progress.stage(first_stage + i, total_stages, step.kind());
        let (vertices_before, faces_before) = (mesh.positions.len(), mesh.triangles.len());
        let start = Instant::now();
        let span = tracing::info_span!("step", index = i + 1, kind = step.kind());
        let _guard = span.enter();
        let figures = apply(step, mesh).map_err(|message| StepError {
            index: i + 1,
            kind: step.kind(),
            message,
        })?;
        debug_assert!(mesh.check_invariants().is_ok(), "{}", step.kind());
        let wall_ms = start.elapsed().as_secs_f64() * 1e3;
        tracing::debug!(wall_ms, faces = mesh.triangles.len(), "step done");
        reports.push(StepReport {
            kind: step.kind().to_string(),
            wall_ms,
            vertices_before,
            vertices_after: mesh.positions.len(),
            faces_before,
            faces_after: mesh.triangles.len(),
            figures,
        });
    }
    Ok(reports)
}
