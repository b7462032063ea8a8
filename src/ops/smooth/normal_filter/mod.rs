//! Normal-filtering denoising (method `normal-filter`): the triangles' normals are filtered
//! with an edge-aware weight ([`filter`]: bilateral, Zheng et al. 2011, or guided, Zhang
//! et al. 2015), then the vertices move so that the triangles fit the filtered normals
//! ([`vertices`]: Sun et al. 2007). Unlike the Laplacian filters, which damp every bump of
//! a given size, this keeps creases and fine relief (lips, eyelids, wrinkles) whose normals
//! differ clearly from their neighbours', and removes the noise whose normals scatter.
//!
//! One round is `normal_passes` filter passes on the normals of the current mesh, then
//! `vertex_passes` vertex passes; `iterations` rounds in all (or the default rounds ×
//! `strength`). Every pass is buffered and
//! parallel, and each sum runs over a CSR row in ascending order, so the result is the same
//! bits whatever the thread count. Borders follow `boundary` as for the other methods (the
//! [`SmoothGraph`] rows say which vertices may move); only positions change.

mod faces;
mod filter;
mod rings;
mod vertices;

use super::{SmoothGraph, SmoothParamsFile};
use crate::mesh::topology::Topology;
use glam::DVec3;
use serde::{Deserialize, Serialize};

pub use filter::Widths;

/// How the range weight of the normal filter is decided.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum NormalVariant {
    /// Zheng et al. 2011: on the difference between the two faces' own normals.
    #[default]
    Bilateral,
    /// Zhang et al. 2015: on the difference between their guidance normals.
    Guided,
}

/// The method's parameters, resolved (lengths in mean edges).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalFilterParams {
    pub variant: NormalVariant,
    /// Spatial width of the normal filter, in mean edge lengths.
    pub sigma_c: f64,
    /// Range width, in units of the input's mean normal difference ‖n_i − n_j‖ across an
    /// edge (its roughness, measured when the step starts): a neighbour whose normal
    /// differs by σ_r has its weight down to e^(−1/2). Relative, so that the same default
    /// holds at every noise level and on every scan.
    pub sigma_r: f64,
    /// Filter passes per round.
    pub normal_passes: u32,
    /// Vertex passes per round.
    pub vertex_passes: u32,
}

/// What the filter needs of the connectivity, built once per step.
#[derive(Default)]
pub struct Prepared {
    rings: rings::Rings,
}

impl Prepared {
    pub fn new(topology: &Topology) -> Prepared {
        Prepared {
            rings: rings::Rings::new(topology),
        }
    }
}

pub(super) struct Outcome {
    pub passes: u32,
    /// Vertex updates undone because a triangle would have flipped.
    pub undone: u64,
}

/// The method's own recipe parameters (besides `iterations`, `update`, `boundary`).
pub(super) const PARAMETERS: &[&str] = &[
    "variant",
    "strength",
    "sigma_c",
    "sigma_r",
    "normal_passes",
    "vertex_passes",
];

/// Upper bound on the passes per round (as `MAX_ITERATIONS` for the rounds).
const MAX_PASSES: u32 = 1000;

/// Rounds when neither `iterations` nor `strength` is given.
const DEFAULT_ROUNDS: f64 = 4.0;

/// Defaults, tuned on facefuns, lucy, igea and the bunny with the noise protocol
/// (docs/smoothing.md, "normal-filter"): σ_c in mean edges, σ_r in the scan's mean normal
/// difference, one filter and three vertex passes per round.
impl Default for NormalFilterParams {
    fn default() -> Self {
        NormalFilterParams {
            variant: NormalVariant::default(),
            sigma_c: 1.0,
            sigma_r: 1.2,
            normal_passes: 1,
            vertex_passes: 3,
        }
    }
}

/// Largest `strength`: 10 × the default rounds, far past any useful denoising.
const MAX_STRENGTH: f64 = 10.0;

/// Resolves the recipe's parameters; returns them and the number of rounds when
/// `iterations` is not given: the default rounds × `strength`, at least one.
pub(super) fn resolve(f: &SmoothParamsFile) -> Result<(NormalFilterParams, u32), String> {
    let strength = f.strength.unwrap_or(1.0);
    if !(strength.is_finite() && strength > 0.0 && strength <= MAX_STRENGTH) {
        return Err(format!(
            "`strength` must be in (0, {MAX_STRENGTH}], got {strength}"
        ));
    }
    if f.strength.is_some() && f.iterations.is_some() {
        return Err(
            "give `strength` or `iterations`, not both (strength sets the number of rounds)".into(),
        );
    }
    let p = recipe_or_default! {
        f, NormalFilterParams { variant, sigma_c, sigma_r, normal_passes, vertex_passes }
    };
    for (name, v) in [("sigma_c", p.sigma_c), ("sigma_r", p.sigma_r)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(format!("`{name}` must be positive, got {v}"));
        }
    }
    for (name, v) in [
        ("normal_passes", p.normal_passes),
        ("vertex_passes", p.vertex_passes),
    ] {
        if !(1..=MAX_PASSES).contains(&v) {
            return Err(format!("`{name}` must be in 1..={MAX_PASSES}, got {v}"));
        }
    }
    Ok((p, (DEFAULT_ROUNDS * strength).round().max(1.0) as u32))
}

/// The resolved parameters in recipe form.
pub(super) fn write_back(p: &NormalFilterParams, f: &mut SmoothParamsFile) {
    f.variant = Some(p.variant);
    f.sigma_c = Some(p.sigma_c);
    f.sigma_r = Some(p.sigma_r);
    f.normal_passes = Some(p.normal_passes);
    f.vertex_passes = Some(p.vertex_passes);
}

pub(super) fn run(
    prepared: &Prepared,
    graph: &SmoothGraph,
    positions: &mut Vec<DVec3>,
    params: &NormalFilterParams,
    mean_edge: f64,
    rounds: u32,
) -> Outcome {
    let rings = &prepared.rings;
    let t_count = rings.triangle_count();
    let input_cross = faces::cross_products(rings.corners(), positions);
    let mut faces = faces::Faces::new(t_count);
    faces.update(rings.corners(), positions);
    let roughness = filter::mean_edge_difference(rings, &faces);
    let widths = Widths {
        sigma_s: params.sigma_c * mean_edge,
        sigma_r: params.sigma_r * roughness,
    };
    let (mut normals, mut scratch) = (vec![DVec3::ZERO; t_count], vec![DVec3::ZERO; t_count]);
    let mut guide = match params.variant {
        NormalVariant::Bilateral => Vec::new(),
        NormalVariant::Guided => vec![DVec3::ZERO; t_count],
    };
    let mut next = positions.clone();
    let moves = |v: usize| graph.moves(v);
    let mut outcome = Outcome {
        passes: 0,
        undone: 0,
    };
    for _ in 0..rounds {
        faces.update(rings.corners(), positions);
        for _ in 0..params.normal_passes {
            let range: &[DVec3] = match params.variant {
                NormalVariant::Bilateral => &faces.normal,
                NormalVariant::Guided => {
                    filter::guidance(rings, &faces, &mut guide);
                    &guide
                }
            };
            filter::pass(rings, &faces, range, widths, &mut scratch);
            std::mem::swap(&mut faces.normal, &mut scratch);
            outcome.passes += 1;
        }
        normals.copy_from_slice(&faces.normal);
        for _ in 0..params.vertex_passes {
            faces.update(rings.corners(), positions);
            vertices::pass(rings, &faces, &normals, &moves, positions, &mut next);
            outcome.undone += vertices::undo_flips(rings, &input_cross, positions, &mut next);
            std::mem::swap(positions, &mut next);
            outcome.passes += 1;
        }
    }
    outcome
}

#[cfg(test)]
mod tests;
