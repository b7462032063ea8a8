//! The shape every recipe step has: [`RecipeStep`], run on the mesh against a
//! [`StepContext`] that carries what steps hand each other.
//!
//! A step's parameters (the struct its `[[step]]` table deserialises into) implement
//! [`RecipeStep`]; [`Step::as_recipe_step`] maps the recipe's `kind` to it. The runner
//! (`runner.rs`) knows nothing of any particular step: it times each, reports its figures and
//! keeps the context between them.

use super::Step;
use crate::geom::bvh::DetachedTree;
use crate::mesh::Mesh;
use crate::metrics::TextureCache;
use crate::ops;
use serde_json::Value;
use std::sync::{Arc, OnceLock};

/// One recipe step. `run` changes the mesh in place and returns the step's figures (any
/// serialisable report, see [`figures`]) or a one-line error, which fails the run.
pub trait RecipeStep {
    fn run(&self, mesh: &mut Mesh, cx: &mut StepContext) -> Result<Value, String>;

    /// The step only moves vertices: same wedges, texture coordinates and triangles. The
    /// runner then carries the texture along the surface after a run of such steps
    /// (`ops::texture_follow`).
    fn moves_vertices(&self) -> bool {
        false
    }

    /// The step uses (and leaves) [`StepContext::fairing`]: the connectivity one fairing
    /// step hands the next, kept only between such steps.
    fn uses_fairing_connectivity(&self) -> bool {
        false
    }

    /// The step reads [`StepContext::seam_reference`], so the runner keeps a copy of the
    /// input while the steps run.
    fn needs_seam_reference(&self) -> bool {
        false
    }

    /// The step removes surface on purpose (`crop`): the final metrics measure against the
    /// mesh as it leaves it (see `metrics::schedule`).
    fn removes_surface(&self) -> bool {
        false
    }

    /// The step writes every wedge's normal afresh (`normals`): what the steps before it
    /// do with the scan's own normals is lost, so the runner drops those first.
    fn replaces_normals(&self) -> bool {
        false
    }

    /// How long the step, run on `mesh` with `cx`, keeps only one core busy: work that does
    /// not depend on it (the metrics' reference) can run beside it.
    fn idle_core(&self, _mesh: &Mesh, _cx: &StepContext) -> IdleCore {
        IdleCore::No
    }
}

/// How much of a step leaves a core idle ([`RecipeStep::idle_core`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IdleCore {
    No,
    /// A sequential stretch of ~10 ms on a 400k-triangle scan: room for the metrics'
    /// samples of the reference, not for its closest-point index.
    Briefly,
    /// Most of the step (a sequential loop of 100 ms and more).
    Mostly,
}

/// What steps hand each other while a recipe runs.
#[derive(Default)]
pub struct StepContext {
    /// The mesh `seam_fix` projects onto: the input as loaded until a replacing step
    /// (`decimate`) runs after another step, then the mesh that step started from (positions
    /// and texture coordinates as the decimator saw them). `None` when no step reads it.
    ///
    /// Why not the loaded input: after `relax` and `fair` the loaded positions are up to a
    /// few edge lengths away, and projecting the faired corners onto them smeared texture
    /// along the eyebrows of Lee Perry-Smith. Triangle origins always index the loaded mesh;
    /// `seam_fix` maps them through the snapshot's own origins when a crop changed them.
    pub seam_reference: Option<Arc<Mesh>>,
    /// `seam_fix`'s closest-point tree over the seam reference, when the step that made
    /// that reference built it already (`decimate`, beside its collapse loop).
    pub seam_tree: Option<DetachedTree>,
    /// The connectivity a `relax` or `fair` step leaves for the next one (see
    /// [`RecipeStep::uses_fairing_connectivity`]).
    pub fairing: Option<ops::fair::Connectivity>,
    /// Decoded texture images, shared by the steps that read them (`remesh`'s bake) and the
    /// final metrics and preview, so that each image is decoded once in the run and a baked
    /// one not at all.
    pub textures: TextureCache,
    /// A step has run already.
    pub(super) changed: bool,
}

impl StepContext {
    /// A context whose seam reference is `input` (see [`StepContext::seam_reference`]) and
    /// whose texture cache is `textures` (a clone shares its images).
    pub fn new(seam_reference: Option<Arc<Mesh>>, textures: TextureCache) -> StepContext {
        StepContext {
            seam_reference,
            textures,
            ..StepContext::default()
        }
    }

    /// A step replaced the mesh; `old` is the mesh it started from. It becomes the seam
    /// reference when there is one and a step ran before (no copy is made: the replacing
    /// step needed it whole until its output was built anyway), with `seam_tree`, `seam_fix`'s
    /// tree over it, if the step built that ([`StepContext::replacing_makes_seam_reference`]).
    pub fn replaced(&mut self, old: Arc<Mesh>, seam_tree: Option<DetachedTree>) {
        if self.replacing_makes_seam_reference() {
            self.seam_reference = Some(old);
            self.seam_tree = seam_tree;
        }
    }

    /// Whether the mesh a replacing step starts from becomes the seam reference
    /// ([`StepContext::replaced`]).
    pub fn replacing_makes_seam_reference(&self) -> bool {
        self.changed && self.seam_reference.is_some()
    }
}

/// A step's report as the JSON figures of the run's report.
pub fn figures<T: serde::Serialize>(value: T) -> Value {
    serde_json::to_value(value).expect("step figures always serialise")
}

impl Step {
    /// The step's parameters as the step itself.
    pub fn as_recipe_step(&self) -> &dyn RecipeStep {
        match self {
            Step::Crop(p) => p,
            Step::Relax(p) => p,
            Step::Fair(p) => p,
            Step::Smooth(p) => p,
            Step::Decimate(p) => p,
            Step::Remesh(p) => p,
            Step::SeamFix(p) => p,
            Step::Normals(p) => p,
        }
    }
}

impl RecipeStep for ops::normals::NormalsParams {
    fn run(&self, mesh: &mut Mesh, _: &mut StepContext) -> Result<Value, String> {
        Ok(figures(ops::normals::recompute_normals(mesh, self)))
    }

    fn replaces_normals(&self) -> bool {
        true
    }
}

impl RecipeStep for ops::crop::CropParams {
    fn run(&self, mesh: &mut Mesh, _: &mut StepContext) -> Result<Value, String> {
        ops::crop::crop(mesh, self)
            .map(figures)
            .map_err(|e| e.to_string())
    }

    fn removes_surface(&self) -> bool {
        true
    }
}

impl RecipeStep for ops::decimate::DecimateParams {
    fn run(&self, mesh: &mut Mesh, cx: &mut StepContext) -> Result<Value, String> {
        let input = Arc::new(std::mem::take(mesh));
        // When the input becomes the seam reference, `seam_fix`'s tree over it is built
        // beside the collapse loop, where a core is idle (on a 400k-triangle scan ~28 ms of
        // `seam_fix` on two cores otherwise; docs/face-scan.md).
        let seam_tree = OnceLock::new();
        let builds_tree =
            cx.replacing_makes_seam_reference() && ops::seam_fix::reads_tree_over(&input);
        let beside = || {
            if builds_tree {
                seam_tree.get_or_init(|| ops::seam_fix::reference_tree(&input).detach());
            }
        };
        let (out, report) = match ops::decimate::decimate_beside(&input, self, &beside) {
            Ok(done) => done,
            Err(e) => {
                // The mesh as it was (the only handle: nothing was cloned).
                *mesh = Arc::unwrap_or_clone(input);
                return Err(e.to_string());
            }
        };
        *mesh = out;
        cx.replaced(input, seam_tree.into_inner());
        Ok(figures(report))
    }

    /// A one-pass collapse loop is sequential; a decimation in halves keeps both cores busy
    /// itself.
    fn idle_core(&self, mesh: &Mesh, _cx: &StepContext) -> IdleCore {
        match ops::decimate::halves::wanted(mesh, self) {
            None => IdleCore::Mostly,
            Some(_) => IdleCore::No,
        }
    }
}

impl RecipeStep for ops::remesh::RemeshParams {
    fn run(&self, mesh: &mut Mesh, cx: &mut StepContext) -> Result<Value, String> {
        let (out, report) =
            ops::remesh::remesh_with(mesh, self, &mut cx.textures).map_err(|e| e.to_string())?;
        cx.replaced(Arc::new(std::mem::replace(mesh, out)), None);
        Ok(figures(report))
    }
}

impl RecipeStep for ops::seam_fix::SeamFixParams {
    fn run(&self, mesh: &mut Mesh, cx: &mut StepContext) -> Result<Value, String> {
        let input = cx
            .seam_reference
            .as_deref()
            .ok_or("seam_fix needs the loaded input mesh")?;
        let tree = cx.seam_tree.take();
        Ok(figures(ops::seam_fix::seam_fix_with(
            mesh, input, self, tree,
        )))
    }

    fn needs_seam_reference(&self) -> bool {
        true
    }

    /// With its tree over the reference handed over, what is left (the reference's charts,
    /// the loop over the result's triangles) is sequential: ~12 ms after a 400k-triangle
    /// decimation, as long as the metrics' samples of the reference on one core.
    fn idle_core(&self, _mesh: &Mesh, cx: &StepContext) -> IdleCore {
        match cx.seam_tree {
            Some(_) => IdleCore::Briefly,
            None => IdleCore::No,
        }
    }
}

/// `relax` and `fair` run the same fairing loop with different plans.
fn fair(mesh: &mut Mesh, plan: &ops::fair::Plan, cx: &mut StepContext) -> Result<Value, String> {
    let (report, connectivity) = ops::fair::run_with(mesh, plan, cx.fairing.take());
    cx.fairing = connectivity;
    Ok(figures(report))
}

/// The contract of a fairing step: its plan through [`fair`], vertices moved, the
/// connectivity handed on.
macro_rules! fairing_step {
    ($params:ty) => {
        impl RecipeStep for $params {
            fn run(&self, mesh: &mut Mesh, cx: &mut StepContext) -> Result<Value, String> {
                fair(mesh, &self.plan(), cx)
            }

            fn moves_vertices(&self) -> bool {
                true
            }

            fn uses_fairing_connectivity(&self) -> bool {
                true
            }
        }
    };
}

fairing_step!(ops::fair::RelaxParams);
fairing_step!(ops::fair::FairParams);

impl RecipeStep for ops::smooth::SmoothParams {
    fn run(&self, mesh: &mut Mesh, _: &mut StepContext) -> Result<Value, String> {
        Ok(figures(ops::smooth::smooth(mesh, self)))
    }

    fn moves_vertices(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::grid;
    use crate::ops::decimate::DecimateParams;
    use crate::ops::seam_fix::SeamFixParams;

    /// A bumpy textured grid of 1,800 triangles.
    fn scan() -> Mesh {
        let mut m = grid(30, 30);
        for p in &mut m.positions {
            p.z = 0.3 * ((p.x * 0.4).sin() * (p.y * 0.3).cos());
        }
        m
    }

    /// A decimation after another step makes its input the seam reference and hands
    /// `seam_fix` the tree over it, which `seam_fix` takes (and, with it, leaves a core idle
    /// briefly); a decimation as the first step leaves the input the reference, treeless.
    #[test]
    fn a_decimation_after_another_step_hands_seam_fix_its_tree() {
        let input = scan();
        let decimate = DecimateParams {
            target_faces: Some(400),
            ..Default::default()
        };
        let seam_fix = SeamFixParams::default();
        let mut cx = StepContext::new(Some(Arc::new(input.clone())), TextureCache::new());
        let mut first = input.clone();
        decimate.run(&mut first, &mut cx).unwrap();
        assert!(cx.seam_tree.is_none());
        assert_eq!(seam_fix.idle_core(&first, &cx), IdleCore::No);

        cx.changed = true;
        let mut before = input.clone();
        before.positions[40].z += 0.01;
        let mut after = before.clone();
        decimate.run(&mut after, &mut cx).unwrap();
        assert_eq!(after.triangles.len(), 400);
        let reference = cx.seam_reference.clone().unwrap();
        assert_eq!(reference.positions, before.positions);
        assert!(cx.seam_tree.is_some());
        assert_eq!(seam_fix.idle_core(&after, &cx), IdleCore::Briefly);
        seam_fix.run(&mut after, &mut cx).unwrap();
        assert!(cx.seam_tree.is_none());
    }
}
