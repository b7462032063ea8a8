//! Quality metrics of a processed mesh against a reference (usually the input): surface
//! distance, volume, angular deviation of normals, texture deviation and topology. Used by
//! the report, the daemon's job records, tests and benchmarks.
//!
//! Everything here is deterministic: samples come from a seeded generator in a fixed order,
//! the parallel closest-point queries are collected in sample order, and every sum runs
//! sequentially in that order, so the figures do not depend on the thread count.

/// The closest-point index, kept at its old path (it lives in [`crate::geom`]).
pub use crate::geom::bvh;
pub mod distance;
pub mod noise;
pub mod normals;
pub mod schedule;
pub mod surface;
pub mod texture;
pub mod topology;
pub mod volume;

use serde::{Deserialize, Serialize};
use std::time::Instant;

use crate::mesh::Mesh;
pub use distance::{SurfaceDistance, VertexDeviation};
pub use normals::AngularDeviation;
pub use texture::{TextureCache, TextureDeviation};
pub use topology::TopologyComparison;
pub use volume::{Volume, VolumeChange};

/// The default number of surface samples per direction. Measured on the 400k-triangle face
/// scan (benches/metrics.rs): with both BVH builds this keeps the surface distance under a
/// second on two cores, and the mean's sampling error is far below 1 % of its value.
pub const DEFAULT_SAMPLES: usize = 100_000;

#[derive(Debug, thiserror::Error)]
pub enum MetricsError {
    #[error("the {which} mesh has no triangles to measure")]
    Empty { which: &'static str },
    #[error("the {which} mesh has a non-finite position at vertex {vertex}")]
    NonFinite { which: &'static str, vertex: usize },
    #[error("cannot index the {which} mesh for closest-point queries: {message}")]
    Index {
        which: &'static str,
        message: String,
    },
}

/// How the metrics are computed (the recipe's `[metrics]` table fills it).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MetricsOptions {
    /// Surface samples per direction for the distance and texture metrics.
    pub samples: usize,
    pub seed: u64,
    /// A result boundary edge farther than this many mean reference edge lengths from
    /// every reference boundary edge is a crack (see [`topology`]).
    pub crack_distance_factor: f64,
}

impl Default for MetricsOptions {
    fn default() -> Self {
        MetricsOptions {
            samples: DEFAULT_SAMPLES,
            seed: 1,
            crack_distance_factor: 2.0,
        }
    }
}

impl MetricsOptions {
    pub fn validate(&self) -> Result<(), String> {
        if self.samples == 0 {
            return Err("samples must be at least 1".into());
        }
        if !(self.crack_distance_factor.is_finite() && self.crack_distance_factor > 0.0) {
            return Err(format!(
                "crack_distance_factor must be a positive number, got {}",
                self.crack_distance_factor
            ));
        }
        Ok(())
    }
}

/// Every metric of a result against its reference, as the report carries it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FinalMetrics {
    pub distance: SurfaceDistance,
    /// The smoothing protocol's per-vertex offset along the reference normal; only when
    /// vertices and triangles correspond one to one.
    pub vertex_deviation: Option<VertexDeviation>,
    pub volume: VolumeChange,
    pub normals: AngularDeviation,
    pub texture: TextureDeviation,
    pub topology: TopologyComparison,
    pub wall_ms: f64,
}

/// All metrics of `result` against `reference`, decoding textures as needed.
pub fn compare(
    result: &Mesh,
    reference: &Mesh,
    options: &MetricsOptions,
) -> Result<FinalMetrics, MetricsError> {
    compare_with_cache(result, reference, options, &mut TextureCache::new())
}

/// [`compare`] with a texture cache the caller keeps across comparisons.
pub fn compare_with_cache(
    result: &Mesh,
    reference: &Mesh,
    options: &MetricsOptions,
    cache: &mut TextureCache,
) -> Result<FinalMetrics, MetricsError> {
    let prepared = PreparedReference::with_topology(reference, options, None)?;
    compare_prepared(result, &prepared, cache)
}

/// What the metrics need of the reference alone and is costly: its closest-point index, its
/// surface samples and, when asked, its topology. Preparing it does not need the result,
/// so the recipe runner may do it on a thread of its own while the decimation's sequential
/// collapse loop leaves a core idle; the preview reuses its index.
pub struct PreparedReference<'a> {
    options: MetricsOptions,
    index: surface::SurfaceIndex<'a>,
    samples: Vec<surface::SurfacePoint>,
    /// The reference's topology counts and boundary, when prepared here too
    /// ([`PreparedReference::with_topology`]); otherwise made in [`compare_prepared`].
    topology: Option<topology::ReferenceTopology>,
    prepare_ms: f64,
}

impl<'a> PreparedReference<'a> {
    /// `index`, when given, is the reference's index built already (over `reference`,
    /// [`schedule::ReferenceSchedule::input_index`]): only the samples are made then.
    pub fn new(
        reference: &'a Mesh,
        options: &MetricsOptions,
        index: Option<surface::SurfaceIndex<'a>>,
    ) -> Result<Self, MetricsError> {
        let start = Instant::now();
        debug_assert!(
            index
                .as_ref()
                .is_none_or(|i| std::ptr::eq(i.mesh(), reference))
        );
        // The reference's topology is not prepared here but beside the result's in
        // [`compare_prepared`]: its full form is ~40 MB for a 400k-triangle scan, and the
        // preparation runs beside the decimation, which is the memory peak of the face-scan
        // recipe (issue #8's budget).
        // The index (parallel) beside the samples (one thread): neither reads the other.
        let (index, samples) = rayon::join(
            || match index {
                Some(index) => Ok(index),
                None => surface::SurfaceIndex::new(reference, "reference"),
            },
            || {
                surface::sample_surface(
                    reference,
                    options.samples,
                    distance::reference_seed(options.seed),
                )
            },
        );
        let index = index?;
        Ok(PreparedReference {
            options: *options,
            index,
            samples,
            topology: None,
            prepare_ms: start.elapsed().as_secs_f64() * 1e3,
        })
    }

    /// [`PreparedReference::new`] and the reference's topology too, side by side: the
    /// topology is built on one thread (~160 ms for a 400k-triangle scan), beside the index
    /// and the samples. For when its ~40 MB do not meet a memory peak (the runner uses it
    /// after the steps, the plain `new` beside the decimation).
    pub fn with_topology(
        reference: &'a Mesh,
        options: &MetricsOptions,
        index: Option<surface::SurfaceIndex<'a>>,
    ) -> Result<Self, MetricsError> {
        let start = Instant::now();
        let (topology, prepared) = rayon::join(
            || topology::ReferenceTopology::of(reference, options.crack_distance_factor),
            || PreparedReference::new(reference, options, index),
        );
        Ok(PreparedReference {
            topology: Some(topology),
            prepare_ms: start.elapsed().as_secs_f64() * 1e3,
            ..prepared?
        })
    }

    /// This preparation with the reference's topology made elsewhere already
    /// ([`topology::ReferenceTopology::from_topology`] on the reference's own triangles and
    /// positions).
    pub fn with_reference_topology(self, topology: topology::ReferenceTopology) -> Self {
        PreparedReference {
            topology: Some(topology),
            ..self
        }
    }

    pub fn mesh(&self) -> &'a Mesh {
        self.index.mesh()
    }

    /// Whether the reference's topology was prepared too ([`PreparedReference::with_topology`]).
    pub fn has_topology(&self) -> bool {
        self.topology.is_some()
    }

    /// The closest-point index over the reference's surface.
    pub fn index(&self) -> &surface::SurfaceIndex<'a> {
        &self.index
    }
}

/// All metrics of `result` against a prepared reference. `wall_ms` counts the preparation
/// too, though it may have run beside other work.
pub fn compare_prepared(
    result: &Mesh,
    prepared: &PreparedReference<'_>,
    cache: &mut TextureCache,
) -> Result<FinalMetrics, MetricsError> {
    let start = Instant::now();
    let reference = prepared.mesh();
    let options = &prepared.options;
    // The combinatorial metrics first, then the sample-based ones (each parallel inside).
    let (topology, vertex_deviation) = rayon::join(
        || match &prepared.topology {
            Some(prepared) => topology::compare_with_reference(result, prepared),
            None => topology::compare(result, reference, options.crack_distance_factor),
        },
        || distance::vertex_deviation(result, reference),
    );
    // The result's index, its samples and the hints each way, side by side.
    let ((result_index, on_result), (to_reference, to_result)) = rayon::join(
        || {
            rayon::join(
                || surface::SurfaceIndex::new(result, "result"),
                || surface::sample_surface(result, options.samples, options.seed),
            )
        },
        || {
            rayon::join(
                || surface::counterparts(result, reference),
                || surface::counterparts(reference, result),
            )
        },
    );
    let result_index = result_index?;
    let forward = prepared
        .index
        .closest_to_samples(&on_result, to_reference.as_deref());
    let backward = result_index.closest_to_samples(&prepared.samples, to_result.as_deref());
    drop(to_result);
    drop(result_index);
    let distance = distance::from_queries(&forward, &backward, reference, options.seed);
    let normals = normals::angular_deviation_with(result, &prepared.index, to_reference.as_deref());
    let texture = texture::deviation_with(result, reference, &on_result, &forward, cache);
    let volume = volume::change(
        volume::volume_from_counts(result, &topology.after.counts),
        volume::volume_from_counts(reference, &topology.before.counts),
    );
    let metrics = FinalMetrics {
        distance,
        vertex_deviation,
        volume,
        normals,
        texture,
        topology,
        wall_ms: prepared.prepare_ms + start.elapsed().as_secs_f64() * 1e3,
    };
    tracing::debug!(wall_ms = metrics.wall_ms, "metrics computed");
    Ok(metrics)
}

/// Whether the two meshes have the same vertices (by index) and the same triangles over
/// them, so that elements can be compared one to one (smoothing, fairing).
pub fn same_connectivity(a: &Mesh, b: &Mesh) -> bool {
    a.positions.len() == b.positions.len()
        && a.triangles.len() == b.triangles.len()
        && (0..a.triangles.len()).all(|t| a.triangle_vertices(t) == b.triangle_vertices(t))
}

/// Mean, RMS, sample standard deviation, 99th percentile and maximum of some values, summed
/// in their given order.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Summary {
    pub count: usize,
    pub mean: f64,
    pub rms: f64,
    pub std: f64,
    pub p99: f64,
    pub max: f64,
}

impl Summary {
    pub fn of(values: &[f64]) -> Summary {
        let count = values.len();
        if count == 0 {
            return Summary::default();
        }
        let n = count as f64;
        let mean = values.iter().sum::<f64>() / n;
        let rms = (values.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
        let std = if count > 1 {
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        } else {
            0.0
        };
        let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Summary {
            count,
            mean,
            rms,
            std,
            p99: percentile(values, 0.99),
            max,
        }
    }
}

/// Nearest-rank percentile (`q` in (0, 1]).
pub fn percentile(values: &[f64], q: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut sorted = values.to_vec();
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len()) - 1;
    let (_, value, _) = sorted.select_nth_unstable_by(rank, f64::total_cmp);
    *value
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::uv_sphere;

    #[test]
    fn summary_and_percentile() {
        let v: Vec<f64> = (1..=200).map(f64::from).collect();
        let s = Summary::of(&v);
        assert_eq!((s.count, s.mean, s.max, s.p99), (200, 100.5, 200.0, 198.0));
        assert_eq!(Summary::of(&[]).count, 0);
        assert_eq!(percentile(&[3.0], 0.99), 3.0);
    }

    #[test]
    fn itself_is_zero_everywhere() {
        let m = uv_sphere(1.0, 16, 24);
        let f = compare(&m, &m, &MetricsOptions::default()).unwrap();
        assert!(f.distance.max < 1e-12);
        assert_eq!(f.normals.max, 0.0);
        assert_eq!(f.volume.change_percent, Some(0.0));
        assert_eq!(f.topology.cracks, 0);
        assert!(matches!(f.texture, TextureDeviation::Skipped { .. }));
        let json = serde_json::to_value(&f).unwrap();
        assert_eq!(json["volume"]["result"]["status"], "closed");
        assert_eq!(json["topology"]["after"]["boundary_edges"], 0);
    }

    #[test]
    fn empty_or_non_finite_is_an_error() {
        let m = uv_sphere(1.0, 4, 4);
        let empty = crate::mesh::Mesh::default();
        assert!(matches!(
            compare(&empty, &m, &MetricsOptions::default()),
            Err(MetricsError::Empty { which: "result" })
        ));
        let mut bad = m.clone();
        bad.positions[3].x = f64::NAN;
        assert!(matches!(
            compare(&m, &bad, &MetricsOptions::default()),
            Err(MetricsError::NonFinite {
                which: "reference",
                vertex: 3
            })
        ));
    }
}
