//! When the final metrics' reference is prepared, and from which mesh, while a recipe runs.
//!
//! The reference is the input *after the recipe's crop steps* (the input itself when there
//! are none): a crop removes surface on purpose, and measuring it would drown what the other
//! steps did in the distance to the cropped-away parts and count the new border as cracks.
//! The decimation thesis the product follows (a Charles University bachelor thesis on
//! decimating Vectra face scans, program "MeshDecimation") compares its decimations with the
//! cropped scans too (its §4.1). `metrics.reference` in the JSON says which it was.
//!
//! What the metrics need of the reference alone ([`PreparedReference`]: its closest-point
//! index and samples) is prepared on a thread of its own while a step that leaves a core
//! idle runs (a one-pass collapse loop is sequential), when no crop comes after it. It starts
//! no earlier, so that it does not add to the memory peak of the fairing steps before it.
//! Otherwise it is prepared after the steps, the reference's topology beside its index.
//! When a run of vertex-moving steps starts from the reference itself, the index is built
//! at the texture follow after them, which reads the surface as it was through it, and
//! kept: one index over the scan instead of two ([`ReferenceSchedule::input_index`]).
//! The history of these choices, with figures, is in docs/face-scan.md.

use super::surface::SurfaceIndex;
use super::topology::ReferenceTopology;
use super::{MetricsError, MetricsOptions, PreparedReference, TextureCache};
use crate::geom::bvh::TriangleBvh;
use crate::mesh::Mesh;
use crate::mesh::topology::Topology;
use serde_json::Value;
use std::sync::{Arc, OnceLock};
use std::thread::{Scope, ScopedJoinHandle};

type Preparation<'env> = Result<PreparedReference<'env>, MetricsError>;

/// The final metrics' reference while the steps run. `'env` is the life of the slot that
/// holds the reference for the preparation thread (created outside the thread scope).
pub struct ReferenceSchedule<'scope, 'env> {
    options: MetricsOptions,
    /// Final metrics are wanted (the reference may serve the preview alone).
    metrics: bool,
    slot: &'env OnceLock<Arc<Mesh>>,
    reference: Arc<Mesh>,
    cropped: bool,
    preparing: Option<ScopedJoinHandle<'scope, Preparation<'env>>>,
    /// The input's topology, when a step built it before any step changed the mesh.
    topology: Option<ReferenceTopology>,
    /// The reference's closest-point index, when the texture follow built it
    /// ([`ReferenceSchedule::input_index`]).
    index: Option<SurfaceIndex<'env>>,
}

impl<'scope, 'env> ReferenceSchedule<'scope, 'env> {
    pub fn new(
        input: Arc<Mesh>,
        options: MetricsOptions,
        metrics: bool,
        slot: &'env OnceLock<Arc<Mesh>>,
    ) -> Self {
        ReferenceSchedule {
            options,
            metrics,
            slot,
            reference: input,
            cropped: false,
            preparing: None,
            topology: None,
            index: None,
        }
    }

    /// A step removed surface on purpose: `mesh` is the reference from now on.
    pub fn reference_cropped(&mut self, mesh: &Mesh) {
        self.reference = Arc::new(mesh.clone());
        self.cropped = true;
    }

    /// Whether [`ReferenceSchedule::prepare_beside_step`] would start anything.
    pub fn can_prepare_early(&self) -> bool {
        self.metrics && self.preparing.is_none()
    }

    /// Whether the reference's index is built already ([`ReferenceSchedule::input_index`]),
    /// so that preparing it is only its samples (~12 ms on one core for 400k triangles).
    pub fn only_samples_left(&self) -> bool {
        self.index.is_some()
    }

    /// Starts preparing the reference on a thread of `scope`, beside a step that keeps one
    /// core busy. The reference must not change after this (no crop may follow).
    pub fn prepare_beside_step(&mut self, scope: &'scope Scope<'scope, 'env>) {
        if !self.can_prepare_early() {
            return;
        }
        let reference = self.slot.get_or_init(|| Arc::clone(&self.reference));
        let options = self.options;
        let index = self.index.take();
        self.preparing = Some(scope.spawn(move || prepare_beside(reference, &options, index)));
    }

    /// The reference's closest-point index (built at the first call and kept for the final
    /// metrics) when the texture follow can read the surface as it was through it: when
    /// that surface, `before`, is the reference itself (the run of vertex-moving steps
    /// started before any step changed the mesh; its texture coordinates are still read from
    /// `before`). Then the run builds one index over the scan instead of two (a
    /// 400k-triangle tree is 22 ms on two cores) and holds it, about 13 MB, to the end.
    /// `None` (the follow builds its own) when the metrics are off, the reference is being
    /// prepared already, a crop may still change it (`crop_follows`), the surfaces differ
    /// (a later run, after a remesh or a decimation: checked at every call), or the
    /// reference has triangles without area (which its index leaves out and the follow's
    /// does not).
    pub fn input_index(&mut self, before: &Mesh, crop_follows: bool) -> Option<&TriangleBvh<'env>> {
        // The same triangles over the same vertices at the same positions (their wedges may
        // differ: the scan's own normals are dropped from the steps' mesh when a step writes
        // fresh ones).
        if !self.metrics || self.cropped || crop_follows {
            return None;
        }
        let same_surface = super::same_connectivity(&self.reference, before)
            && self.reference.positions == before.positions;
        if !same_surface {
            return None;
        }
        if self.index.is_none() {
            if self.preparing.is_some() {
                return None;
            }
            let reference: &'env Mesh = self.slot.get_or_init(|| Arc::clone(&self.reference));
            self.index = SurfaceIndex::new(reference, "reference").ok();
        }
        self.index.as_ref().and_then(SurfaceIndex::whole_mesh_tree)
    }

    /// Runs `f` on the topology of `mesh`, the untouched input, and keeps the reference's
    /// topology built from the same [`Topology`] beside it, so that the metrics need not build
    /// it again after the steps (a fairing step builds the input's topology anyway). `None`,
    /// without calling `f`, when there are no final metrics.
    pub fn share_input_topology<T: Send>(
        &mut self,
        mesh: &Mesh,
        f: impl FnOnce(&Topology) -> T + Send,
    ) -> Option<T> {
        if !self.metrics {
            return None;
        }
        let topology = mesh.topology();
        let factor = self.options.crack_distance_factor;
        let (reference, shared) = rayon::join(
            || ReferenceTopology::from_topology(mesh, &topology, factor),
            || f(&topology),
        );
        self.topology = Some(reference);
        Some(shared)
    }

    /// The steps are done: the reference, prepared (waiting for the early preparation).
    pub fn finish(self) -> FinalReference<'env> {
        let reference: &'env Mesh = self.slot.get_or_init(|| self.reference);
        // A crop after the fairing made another reference than the one handed over.
        let known_topology = self.topology.filter(|_| !self.cropped);
        let preparing = self.preparing;
        let options = self.options;
        let prepared = self.metrics.then(|| {
            let prepared = match (preparing, &known_topology) {
                (Some(thread), _) => thread
                    .join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
                (None, Some(_)) => PreparedReference::new(reference, &options, self.index),
                // After the steps the memory peak is past: the reference's topology is
                // prepared too, beside its index.
                (None, None) => PreparedReference::with_topology(reference, &options, self.index),
            };
            prepared.map(|p| match known_topology {
                Some(t) => p.with_reference_topology(t),
                None => p,
            })
        });
        FinalReference {
            reference,
            prepared,
            cropped: self.cropped,
        }
    }
}

/// The final metrics' reference after the steps.
pub struct FinalReference<'a> {
    pub reference: &'a Mesh,
    /// `None` when the recipe turns the metrics off.
    pub prepared: Option<Preparation<'a>>,
    cropped: bool,
}

impl FinalReference<'_> {
    /// The reference's topology is prepared already, so measuring needs little memory.
    pub fn has_topology(&self) -> bool {
        matches!(&self.prepared, Some(Ok(p)) if p.has_topology())
    }

    /// `FinalMetrics` of `mesh` against the reference as report JSON, with
    /// `reference` = "input" or "input-after-crop"; `Null` without metrics.
    pub fn measure(&self, mesh: &Mesh) -> Value {
        self.measure_with(mesh, &mut TextureCache::new())
    }

    /// [`FinalReference::measure`] reading the textures through `textures` (shared with the
    /// preview).
    pub fn measure_with(&self, mesh: &Mesh, textures: &mut TextureCache) -> Value {
        let prepared = match &self.prepared {
            None => return Value::Null,
            Some(Err(e)) => return error_value(e),
            Some(Ok(prepared)) => prepared,
        };
        match super::compare_prepared(mesh, prepared, textures) {
            Ok(m) => {
                let mut value = serde_json::to_value(m).expect("metrics always serialise");
                if let Value::Object(map) = &mut value {
                    let which = if self.cropped {
                        "input-after-crop"
                    } else {
                        "input"
                    };
                    map.insert("reference".into(), Value::from(which));
                }
                value
            }
            Err(e) => error_value(&e),
        }
    }
}

/// Prepares the reference's half of the metrics on fewer threads than the machine has:
/// it runs beside a step whose sequential loop keeps one core busy.
fn prepare_beside<'a>(
    reference: &'a Mesh,
    options: &MetricsOptions,
    index: Option<SurfaceIndex<'a>>,
) -> Preparation<'a> {
    let threads = rayon::current_num_threads().saturating_sub(1).max(1);
    match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
        Ok(pool) => pool.install(|| PreparedReference::new(reference, options, index)),
        Err(_) => PreparedReference::new(reference, options, index),
    }
}

/// Metrics of `result` against `reference` as report JSON; a failure (which only a bug in a
/// step can cause: an empty or non-finite mesh) is recorded in the report, not raised.
pub fn metrics_value(result: &Mesh, reference: &Mesh, options: &MetricsOptions) -> Value {
    match super::compare(result, reference, options) {
        Ok(m) => serde_json::to_value(m).expect("metrics always serialise"),
        Err(e) => error_value(&e),
    }
}

/// A metrics failure as report JSON (logged).
fn error_value(e: &MetricsError) -> Value {
    tracing::warn!(error = %e, "metrics not computed");
    serde_json::json!({ "error": e.to_string() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::grid;

    fn schedule<'s>(
        input: &Arc<Mesh>,
        metrics: bool,
        slot: &'s OnceLock<Arc<Mesh>>,
    ) -> ReferenceSchedule<'s, 's> {
        ReferenceSchedule::new(Arc::clone(input), MetricsOptions::default(), metrics, slot)
    }

    /// The input's index is handed to the texture follow only for the surface it indexes,
    /// with every triangle in it, while a crop cannot still change the reference, and kept
    /// for the final metrics.
    #[test]
    fn input_index_only_for_the_reference_surface() {
        let input = Arc::new(grid(6, 5));
        let slot = OnceLock::new();
        let mut s = schedule(&input, true, &slot);
        let tree = s.input_index(&input, false).expect("the same surface");
        assert_eq!(tree.len(), input.triangles.len());
        assert!(s.index.is_some());
        // A later run of vertex-moving steps starts from another surface: not through it.
        let mut moved = (*input).clone();
        moved.positions[7].z += 0.01;
        assert!(s.input_index(&moved, false).is_none());
        assert!(s.input_index(&input, false).is_some());
        assert!(matches!(s.finish().prepared, Some(Ok(_))));

        let slot = OnceLock::new();
        assert!(
            schedule(&input, true, &slot)
                .input_index(&moved, false)
                .is_none()
        );
        let slot = OnceLock::new();
        assert!(
            schedule(&input, true, &slot)
                .input_index(&input, true)
                .is_none()
        );
        let slot = OnceLock::new();
        assert!(
            schedule(&input, false, &slot)
                .input_index(&input, false)
                .is_none()
        );

        // A zero-area triangle: the metrics' index leaves it out, so it is not the follow's.
        let mut flat = grid(6, 5);
        let t = flat.triangles[0];
        flat.triangles.push([t[0], t[0], t[1]]);
        let flat = Arc::new(flat);
        let slot = OnceLock::new();
        let mut s = schedule(&flat, true, &slot);
        assert!(s.input_index(&flat, false).is_none());
        assert!(s.index.is_some(), "kept for the metrics all the same");
    }
}
