//! The `smooth` step: the four vertex-moving denoising filters compared in the smoothing
//! thesis (R. Svěchovský, *Vyhlazování polygonálních modelů* (Polygonal Models
//! Smoothing), bachelor's thesis, FIT VUT Brno, 2010; § are its sections): Laplace (§3.2), Laplace-HC (§3.3, Vollmer et al. 1999),
//! Taubin λ|μ (§3.4, Taubin 1995) and bilateral mesh denoising (§3.5, Fleishman et al. 2003);
//! and, beyond the thesis, normal filtering (`normal-filter`, issue #26; see its module).
//!
//! Only positions move (none of the thesis' filters changes topology): wedges, texture
//! coordinates and seams are untouched, so seams stay closed by construction. Stored
//! normals become stale; a recipe recomputes them with a later `normals` step.
//!
//! Updates are buffered by default (every vertex computed from the same snapshot, then all
//! replaced; the thesis' "sequential" mode of §3.1, Jacobi style). That is naturally
//! deterministic and parallel: each vertex's new position depends only on the snapshot and
//! sums over its CSR row in a fixed order, whatever the thread count. `update = "in-place"`
//! (Gauss–Seidel in vertex order, the thesis' "simultaneous" mode) is offered for Laplace and
//! Taubin only; it is sequential.
//!
//! Parameters carry the thesis' names, and their defaults are the thesis' Table A.2 values
//! (the bilateral σ's converted to mean-edge units, see [`BilateralParams`]).

/// `Params { field: recipe's value, else the default's, ... }` for the named fields, each
/// an `Option` of the same name in the recipe's [`SmoothParamsFile`].
macro_rules! recipe_or_default {
    ($file:expr, $params:ident { $($field:ident),* $(,)? }) => {{
        let d = $params::default();
        $params { $($field: $file.$field.unwrap_or(d.$field)),* }
    }};
}

mod bilateral;
mod graph;
mod hc;
mod laplace;
mod normal_filter;
mod taubin;

use crate::mesh::Mesh;
use glam::DVec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

pub use graph::SmoothGraph;
pub use normal_filter::{NormalFilterParams, NormalVariant};

/// How a new position is stored (thesis §3.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Update {
    /// All vertices from the same snapshot, then replaced (Jacobi; the thesis calls this
    /// "sequential"). Order-independent, parallel, the default.
    #[default]
    Buffered,
    /// Each vertex overwritten at once, in vertex order (Gauss–Seidel; the thesis calls this
    /// "simultaneous"). Depends on vertex order; sequential. Laplace and Taubin only.
    InPlace,
}

/// What happens to vertices on an open border (the thesis' models are closed and it does
/// not say): `fixed`, the default (a scan's border is usually a cut, the crop step or the edge
/// of the scanner's view, whose outline should stay where it is, and the umbrella operator
/// would otherwise pull every border inward), or `curve` (recorded as `free`: border
/// vertices average their neighbours along border edges only, as MeshLab/VCG does, so the
/// border curve is denoised without being pulled into the surface; the bilateral filter
/// moves them along their normal like every other vertex). See [`Border`].
pub use crate::ops::border::Border;

/// Edge weights of the discrete Laplacian (Eq. 3.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Weights {
    /// w_ij = 1/|adj(i)|, the "umbrella" operator every filter of the thesis uses (§2.4.2).
    #[default]
    Uniform,
    /// w_ij ∝ (cot α_ij + cot β_ij)/2, recomputed from the current positions before each
    /// pass, negative values clamped to 0 and the row normalised to sum 1 (so that λ keeps
    /// its meaning as a step fraction). Rows on a free border stay uniform.
    Cotangent,
}

/// Which position the Laplace step blends with (Eq. 3.3 vs Eq. 3.5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum LaplaceAnchor {
    /// Eq. (3.3): p = (1−λ) q + λ·avg(q). With λ = 1 this is Eq. (3.4), plain neighbour
    /// averaging (same code path, so the two give identical results).
    #[default]
    Current,
    /// Eq. (3.5), after Vollmer et al.: p = (1−λ) o + λ·avg(q), pulled towards the original
    /// (noisy input) positions o, fixed for the whole run.
    Original,
}

/// What one Taubin `iteration` is (thesis §3.4, §5.3; tools disagree).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum TaubinCount {
    /// One iteration = one λ pass followed by one μ pass (Taubin 1995, MeshLab/VCG). The
    /// default, as the issue asks: `iterations = 13` is 26 passes.
    #[default]
    Pairs,
    /// One iteration = one single pass, alternating λ, μ, λ, … and starting with λ: the
    /// thesis' accounting (§5.3), under which its "13 iterations" are 7 λ and 6 μ passes.
    Passes,
}

/// Lengths of the bilateral filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum LengthUnits {
    /// Multiples of the mesh's mean edge length, measured when the step starts. The default:
    /// the thesis' σ's are absolute lengths in its models' units (Table A.2), which do not
    /// transfer to a scan in millimetres.
    #[default]
    MeanEdge,
    /// Model units, as the thesis' Table A.2 gives them.
    Absolute,
}

/// Laplace (§3.2). Table A.2: λ = 0.08, 22 iterations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaplaceParams {
    pub lambda: f64,
    pub anchor: LaplaceAnchor,
    pub weights: Weights,
}

/// Laplace-HC (§3.3, Eq. 3.6). Table A.2: λ = 1.0, α = 0.001, β = 0.5, 8 iterations.
/// (§5.2 says α = 0.0; Table A.2, the "presented results", says 0.001: the defaults take the table.)
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HcParams {
    pub lambda: f64,
    pub alpha: f64,
    pub beta: f64,
    pub weights: Weights,
}

/// Taubin λ|μ (§3.4, Eq. 3.3 and 3.7). Table A.2: λ = 0.53, μ = −0.54, 13 iterations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaubinParams {
    pub lambda: f64,
    pub mu: f64,
    pub count: TaubinCount,
    pub weights: Weights,
}

/// Bilateral mesh denoising (§3.5; the update is Fleishman et al. 2003's "DenoisePoint").
///
/// Table A.2 gives σ_c = 0.02, σ_s = 0.01 and 3 iterations for the bunny (the Stanford
/// model closest to a lab scan). Those are absolute lengths in the thesis' bunny, which was
/// scaled to a volume of 2.5482 (thesis Table A.1), derived here:: the same zipper bunny
/// (`bun_zipper.ply`, 35,947 vertices as in Table A.1; mean edge 0.001 471, volume
/// 0.000 770 with its base holes) scaled by 14.90 has a mean edge of 0.0219, so
/// σ_c = 0.91 and σ_s = 0.46 mean edges (and the thesis' noise, 0.2 mean edges, is 0.0044,
/// below σ_s as it should be). Our defaults are σ_c = 0.9, σ_s = 0.45 with
/// `units = "mean-edge"`; `units = "absolute"` takes the Table A.2 numbers literally.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BilateralParams {
    /// Spatial (closeness) Gaussian width σ_c.
    pub sigma_c: f64,
    /// Signal (offset from the tangent plane) Gaussian width σ_s.
    pub sigma_s: f64,
    /// Neighbourhood radius ρ; `None` = 2 σ_c as in Fleishman et al.
    pub radius: Option<f64>,
    /// Order of the mesh neighbourhood (thesis §2.4.2) the ρ-ball is taken from; see
    /// the bilateral module for why 3.
    pub rings: u32,
    pub units: LengthUnits,
}

/// The method and its own parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SmoothMethod {
    Laplace(LaplaceParams),
    Hc(HcParams),
    Taubin(TaubinParams),
    Bilateral(BilateralParams),
    NormalFilter(NormalFilterParams),
}

impl SmoothMethod {
    pub fn method_name(&self) -> MethodName {
        match self {
            SmoothMethod::Laplace(_) => MethodName::Laplace,
            SmoothMethod::Hc(_) => MethodName::Hc,
            SmoothMethod::Taubin(_) => MethodName::Taubin,
            SmoothMethod::Bilateral(_) => MethodName::Bilateral,
            SmoothMethod::NormalFilter(_) => MethodName::NormalFilter,
        }
    }

    /// The name in a recipe, from serde.
    pub fn name(&self) -> String {
        self.method_name().name()
    }
}

/// Parameters of the `smooth` step, resolved (every default filled in) and validated.
/// In a recipe they are one flat table: `method` plus that method's parameters, and
/// `iterations`, `update`, `boundary`; a parameter of another method is an error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "SmoothParamsFile", into = "SmoothParamsFile")]
pub struct SmoothParams {
    pub method: SmoothMethod,
    pub iterations: u32,
    pub update: Update,
    pub boundary: Border,
}

/// The method names a recipe may use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MethodName {
    Laplace,
    Hc,
    Taubin,
    Bilateral,
    NormalFilter,
}

impl MethodName {
    /// The name in a recipe, from serde.
    pub fn name(self) -> String {
        crate::text::serde_name(&self)
    }
}

/// The recipe form of [`SmoothParams`]: flat, every parameter optional.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SmoothParamsFile {
    pub method: Option<MethodName>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub iterations: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub update: Option<Update>,
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        with = "crate::ops::border::smooth_option"
    )]
    pub boundary: Option<Border>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lambda: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mu: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub alpha: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub beta: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_c: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rings: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub units: Option<LengthUnits>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub weights: Option<Weights>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub anchor: Option<LaplaceAnchor>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub count: Option<TaubinCount>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub variant: Option<NormalVariant>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub strength: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_r: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub normal_passes: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vertex_passes: Option<u32>,
}

/// Upper bound on `iterations`: far beyond any useful smoothing, low enough that a typo
/// cannot keep the daemon busy for days.
pub const MAX_ITERATIONS: u32 = 10_000;

/// Upper bound on the bilateral neighbourhood order. An order-k neighbourhood of a regular
/// mesh holds about 3k(k+1) vertices (4 bytes each, kept for the whole step): 36 for the
/// default k = 3, 468 for k = 12 — enough for the thesis' solids (ρ = 0.4 on a mesh with
/// mean edge 0.064 needs about 10 rings).
pub const MAX_RINGS: u32 = 12;

/// The keys every method takes besides its own parameters.
const COMMON_KEYS: [&str; 4] = ["method", "iterations", "update", "boundary"];

impl SmoothParamsFile {
    /// Names of the method parameters that are set, from serde (unset ones are not
    /// serialised).
    fn set_names(&self) -> Vec<String> {
        let Ok(serde_json::Value::Object(map)) = serde_json::to_value(self) else {
            unreachable!("a struct serialises as a map")
        };
        map.into_iter()
            .filter(|(key, value)| !value.is_null() && !COMMON_KEYS.contains(&key.as_str()))
            .map(|(key, _)| key)
            .collect()
    }
}

fn own_parameters(method: MethodName) -> &'static [&'static str] {
    match method {
        MethodName::Laplace => &["lambda", "anchor", "weights"],
        MethodName::Hc => &["lambda", "alpha", "beta", "weights"],
        MethodName::Taubin => &["lambda", "mu", "count", "weights"],
        MethodName::Bilateral => &["sigma_c", "sigma_s", "radius", "rings", "units"],
        MethodName::NormalFilter => normal_filter::PARAMETERS,
    }
}

fn check(ok: bool, message: impl FnOnce() -> String) -> Result<(), String> {
    if ok { Ok(()) } else { Err(message()) }
}

/// Table A.2's Laplace: λ = 0.08 (22 iterations).
impl Default for LaplaceParams {
    fn default() -> Self {
        LaplaceParams {
            lambda: 0.08,
            anchor: LaplaceAnchor::Current,
            weights: Weights::Uniform,
        }
    }
}

/// Table A.2's Laplace-HC: λ = 1.0, α = 0.001, β = 0.5 (8 iterations).
impl Default for HcParams {
    fn default() -> Self {
        HcParams {
            lambda: 1.0,
            alpha: 0.001,
            beta: 0.5,
            weights: Weights::Uniform,
        }
    }
}

/// Table A.2's Taubin: λ = 0.53, μ = −0.54 (13 iterations).
impl Default for TaubinParams {
    fn default() -> Self {
        TaubinParams {
            lambda: 0.53,
            mu: -0.54,
            count: TaubinCount::Pairs,
            weights: Weights::Uniform,
        }
    }
}

impl BilateralParams {
    /// Table A.2's bunny values (3 iterations) in `units`: σ_c = 0.02, σ_s = 0.01 as
    /// absolute lengths, σ_c = 0.9, σ_s = 0.45 in mean edges (see the type's note).
    pub fn defaults_in(units: LengthUnits) -> BilateralParams {
        let (sigma_c, sigma_s) = match units {
            LengthUnits::MeanEdge => (0.9, 0.45),
            LengthUnits::Absolute => (0.02, 0.01),
        };
        BilateralParams {
            sigma_c,
            sigma_s,
            radius: None,
            rings: 3,
            units,
        }
    }
}

fn positive(name: &str, v: f64) -> Result<(), String> {
    check(v.is_finite() && v > 0.0, || {
        format!("`{name}` must be a positive length, got {v}")
    })
}

/// `v` in (0, 1] (`open_low`) or [0, 1].
fn unit_interval(name: &str, v: f64, open_low: bool) -> Result<(), String> {
    let ok = v.is_finite() && v <= 1.0 && if open_low { v > 0.0 } else { v >= 0.0 };
    check(ok, || {
        let range = if open_low { "(0, 1]" } else { "[0, 1]" };
        format!("`{name}` must be in {range}, got {v}")
    })
}

/// The method's parameters from the recipe, defaults filled in and checked, with the
/// method's default iteration count: Table A.2's for the thesis' methods; normal-filter's
/// follows its `strength`.
fn resolve_method(method: MethodName, f: &SmoothParamsFile) -> Result<(SmoothMethod, u32), String> {
    Ok(match method {
        MethodName::Laplace => {
            let p = recipe_or_default! { f, LaplaceParams { lambda, anchor, weights } };
            // §3.2 states λ ∈ (0,1) but uses λ = 1 itself (Eq. 3.4, HC): accept (0,1].
            unit_interval("lambda", p.lambda, true)?;
            (SmoothMethod::Laplace(p), 22)
        }
        MethodName::Hc => {
            let p = recipe_or_default! { f, HcParams { lambda, alpha, beta, weights } };
            unit_interval("lambda", p.lambda, true)?;
            unit_interval("alpha", p.alpha, false)?;
            unit_interval("beta", p.beta, false)?;
            (SmoothMethod::Hc(p), 8)
        }
        MethodName::Taubin => {
            let p = recipe_or_default! { f, TaubinParams { lambda, mu, count, weights } };
            // §3.4: 0 < λ < −μ. λ ≤ 1 keeps the shrinking pass a convex blend.
            unit_interval("lambda", p.lambda, true)?;
            check(p.mu.is_finite() && p.mu < -p.lambda, || {
                format!(
                    "`mu` must be negative with |mu| > lambda (0 < lambda < -mu), got lambda = {}, mu = {}",
                    p.lambda, p.mu
                )
            })?;
            (SmoothMethod::Taubin(p), 13)
        }
        MethodName::Bilateral => {
            let d = BilateralParams::defaults_in(f.units.unwrap_or_default());
            let p = BilateralParams {
                sigma_c: f.sigma_c.unwrap_or(d.sigma_c),
                sigma_s: f.sigma_s.unwrap_or(d.sigma_s),
                radius: f.radius.or(d.radius),
                rings: f.rings.unwrap_or(d.rings),
                units: d.units,
            };
            check((1..=MAX_RINGS).contains(&p.rings), || {
                format!("`rings` must be in 1..={MAX_RINGS}, got {}", p.rings)
            })?;
            positive("sigma_c", p.sigma_c)?;
            positive("sigma_s", p.sigma_s)?;
            if let Some(r) = p.radius {
                positive("radius", r)?;
            }
            (SmoothMethod::Bilateral(p), 3)
        }
        MethodName::NormalFilter => {
            let (p, rounds) = normal_filter::resolve(f)?;
            (SmoothMethod::NormalFilter(p), rounds)
        }
    })
}

/// Refuses `update = "in-place"` for the methods that need every vertex computed from one
/// snapshot.
fn check_update(method: MethodName, update: Update) -> Result<(), String> {
    if update != Update::InPlace {
        return Ok(());
    }
    match method {
        // Pitfall 1: HC needs b of all neighbours, so its three steps must each finish for
        // every vertex before the next starts.
        MethodName::Hc => Err("method = \"hc\" needs update = \"buffered\" (its three steps each read the previous step's results for all neighbours)".into()),
        // Fleishman et al. 2003 compute every vertex from one snapshot ("DenoisePoint").
        MethodName::Bilateral | MethodName::NormalFilter => Err("method = \"bilateral\" needs update = \"buffered\" (Fleishman et al. denoise every vertex from one snapshot, with normals of that snapshot)".into()),
        MethodName::Laplace | MethodName::Taubin => Ok(()),
    }
}

impl TryFrom<SmoothParamsFile> for SmoothParams {
    type Error = String;

    fn try_from(f: SmoothParamsFile) -> Result<Self, String> {
        let method = f.method.ok_or_else(|| {
            "missing `method`; expected one of `laplace`, `hc`, `taubin`, `bilateral`, `normal-filter`".to_string()
        })?;
        let own = own_parameters(method);
        if let Some(stray) = f
            .set_names()
            .into_iter()
            .find(|n| !own.contains(&n.as_str()))
        {
            return Err(format!(
                "`{stray}` does not apply to method = \"{}\" (its parameters: {}, iterations, update, boundary)",
                method.name(),
                own.join(", ")
            ));
        }
        let (smooth_method, default_iterations) = resolve_method(method, &f)?;
        let iterations = f.iterations.unwrap_or(default_iterations);
        check((1..=MAX_ITERATIONS).contains(&iterations), || {
            format!("`iterations` must be in 1..={MAX_ITERATIONS}, got {iterations}")
        })?;
        let update = f.update.unwrap_or_default();
        check_update(method, update)?;
        Ok(SmoothParams {
            method: smooth_method,
            iterations,
            update,
            boundary: f.boundary.unwrap_or(Border::Fixed),
        })
    }
}

/// The other way: sets the recipe's `Option` of each named field to the parameters' value.
macro_rules! set_in_recipe {
    ($file:expr, $params:expr, $($field:ident),* $(,)?) => {
        $($file.$field = Some($params.$field);)*
    };
}

impl From<SmoothParams> for SmoothParamsFile {
    fn from(p: SmoothParams) -> Self {
        let mut f = SmoothParamsFile {
            iterations: Some(p.iterations),
            update: Some(p.update),
            boundary: Some(p.boundary),
            ..Default::default()
        };
        match p.method {
            SmoothMethod::Laplace(l) => {
                f.method = Some(MethodName::Laplace);
                set_in_recipe! { f, l, lambda, anchor, weights }
            }
            SmoothMethod::Hc(h) => {
                f.method = Some(MethodName::Hc);
                set_in_recipe! { f, h, lambda, alpha, beta, weights }
            }
            SmoothMethod::Taubin(t) => {
                f.method = Some(MethodName::Taubin);
                set_in_recipe! { f, t, lambda, mu, count, weights }
            }
            SmoothMethod::Bilateral(b) => {
                f.method = Some(MethodName::Bilateral);
                set_in_recipe! { f, b, sigma_c, sigma_s, rings, units }
                f.radius = b.radius;
            }
            SmoothMethod::NormalFilter(n) => {
                f.method = Some(MethodName::NormalFilter);
                normal_filter::write_back(&n, &mut f);
            }
        }
        f
    }
}

impl SmoothParams {
    /// The method with the Table A.2 defaults.
    pub fn defaults(method: MethodName) -> SmoothParams {
        SmoothParams::try_from(SmoothParamsFile {
            method: Some(method),
            ..Default::default()
        })
        .expect("the defaults are valid")
    }

    /// Parameters are validated when parsed; kept for the recipe's `Step::validate`.
    pub fn validate(&self) -> Result<(), String> {
        SmoothParams::try_from(SmoothParamsFile::from(self.clone())).map(|_| ())
    }
}

/// What the step did (the step's figures in the report).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SmoothReport {
    pub method: String,
    pub iterations: u32,
    /// Vertex passes applied (Taubin pairs count two, HC's correction is part of its pass).
    pub passes: u32,
    /// Vertices the filter may move.
    pub smoothed_vertices: usize,
    /// Border vertices held in place (`boundary = "fixed"`).
    pub fixed_boundary_vertices: usize,
    /// Vertices used by no triangle (never moved).
    pub isolated_vertices: usize,
    /// Bilateral only: vertex updates skipped because the neighbourhood was empty or every
    /// weight underflowed (as Fleishman et al.'s "DenoisePoint": the vertex stays where it is).
    pub empty_neighbourhoods: u64,
    /// Normal filter only: vertex updates undone because a triangle would have flipped
    /// against the input.
    pub undone_updates: u64,
    /// Bilateral only: mean number of neighbours inside the ρ-ball per update.
    pub mean_neighbourhood: f64,
    /// Bilateral only: the share of those neighbours that came from the outermost ring
    /// searched. On igea at the defaults it is 6 % (and the ring beyond would add only
    /// 0.005 %); above 15 % (with `rings` ≥ 2) the ball probably reaches past the rings,
    /// and a warning asks for more rings or a smaller radius.
    pub outer_ring_share: f64,
    /// Mean and largest distance a vertex moved, in model units and relative to the
    /// bounding-box diagonal.
    pub mean_displacement: f64,
    pub max_displacement: f64,
    pub mean_displacement_relative: f64,
    pub max_displacement_relative: f64,
    /// Wall time of the passes alone (without building the adjacency), milliseconds.
    pub smoothing_ms: f64,
    /// Vertex updates per second over the passes (smoothed vertices × passes / time).
    pub vertex_updates_per_second: f64,
}

/// Chunk of vertices one rayon task handles: large enough that scheduling is negligible,
/// small enough that two cores share the work evenly.
pub(crate) const CHUNK: usize = 4096;

/// Calls `f(i, &mut out[i])` for every `i`, in parallel chunks of [`CHUNK`]. Each call sees
/// only its own element, so a pass written this way gives the same result for any thread
/// count.
pub(crate) fn par_for_each_indexed<T: Send>(out: &mut [T], f: impl Fn(usize, &mut T) + Sync) {
    out.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(chunk, out)| {
            let first = chunk * CHUNK;
            for (k, slot) in out.iter_mut().enumerate() {
                f(first + k, slot);
            }
        });
}

/// A prepared smoothing step: the adjacency (built once per step, CSR) and the parameters
/// resolved against the mesh (the bilateral length unit). [`smooth`] is `new` + `run`;
/// benchmarks use the two halves to time the passes alone.
pub struct Smoother {
    graph: SmoothGraph,
    /// The bilateral filter's candidate neighbourhoods and normal plan (empty for the other
    /// methods).
    bilateral: bilateral::Prepared,
    /// The normal filter's face rings (empty for the other methods).
    normal_filter: normal_filter::Prepared,
    params: SmoothParams,
    /// Model units per parameter unit for the bilateral lengths.
    length_unit: f64,
}

/// What [`Smoother::run`] did; a method that does not count something leaves it 0.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PassCounts {
    pub passes: u32,
    pub empty_neighbourhoods: u64,
    pub neighbours: u64,
    pub outer_ring_neighbours: u64,
    pub undone_updates: u64,
}

impl PassCounts {
    /// A method that counts nothing but its passes.
    fn plain(passes: u32) -> PassCounts {
        PassCounts {
            passes,
            ..PassCounts::default()
        }
    }
}

impl From<bilateral::BilateralOutcome> for PassCounts {
    fn from(o: bilateral::BilateralOutcome) -> PassCounts {
        PassCounts {
            passes: o.passes,
            empty_neighbourhoods: o.empty_neighbourhoods,
            neighbours: o.neighbours,
            outer_ring_neighbours: o.outer_ring_neighbours,
            undone_updates: 0,
        }
    }
}

impl From<normal_filter::Outcome> for PassCounts {
    fn from(o: normal_filter::Outcome) -> PassCounts {
        PassCounts {
            undone_updates: o.undone,
            ..PassCounts::plain(o.passes)
        }
    }
}

impl Smoother {
    pub fn new(mesh: &Mesh, params: &SmoothParams) -> Smoother {
        let topology = mesh.topology();
        let graph = SmoothGraph::new(&topology, params.boundary, uses_cotangent(params));
        let length_unit = match params.method {
            SmoothMethod::Bilateral(BilateralParams {
                units: LengthUnits::MeanEdge,
                ..
            }) => mesh.mean_edge_length(),
            SmoothMethod::NormalFilter(_) => mesh.mean_edge_length(),
            _ => 1.0,
        };
        let bilateral = match params.method {
            SmoothMethod::Bilateral(p) => bilateral::Prepared::new(
                &topology,
                p.rings,
                &mesh.positions,
                bilateral::ball_radius(&p, length_unit),
            ),
            _ => bilateral::Prepared::default(),
        };
        let normal_filter = match params.method {
            SmoothMethod::NormalFilter(_) => normal_filter::Prepared::new(&topology),
            _ => normal_filter::Prepared::default(),
        };
        Smoother {
            graph,
            bilateral,
            normal_filter,
            params: params.clone(),
            length_unit,
        }
    }

    pub fn graph(&self) -> &SmoothGraph {
        &self.graph
    }

    /// Runs all iterations on `positions` (those of the mesh given to [`Smoother::new`]).
    pub fn run(&self, positions: &mut Vec<DVec3>) -> PassCounts {
        assert_eq!(
            positions.len(),
            self.graph.vertex_count(),
            "positions of another mesh"
        );
        let (graph, iterations, update) = (&self.graph, self.params.iterations, self.params.update);
        let unit = self.length_unit;
        match self.params.method {
            SmoothMethod::Laplace(p) => {
                PassCounts::plain(laplace::run(graph, positions, &p, iterations, update))
            }
            SmoothMethod::Hc(p) => PassCounts::plain(hc::run(graph, positions, &p, iterations)),
            SmoothMethod::Taubin(p) => {
                PassCounts::plain(taubin::run(graph, positions, &p, iterations, update))
            }
            SmoothMethod::Bilateral(p) => {
                bilateral::run(&self.bilateral, graph, positions, &p, unit, iterations).into()
            }
            SmoothMethod::NormalFilter(p) => {
                normal_filter::run(&self.normal_filter, graph, positions, &p, unit, iterations)
                    .into()
            }
        }
    }
}

/// Smooths `mesh` in place. Only `mesh.positions` change.
pub fn smooth(mesh: &mut Mesh, params: &SmoothParams) -> SmoothReport {
    let start = std::time::Instant::now();
    let smoother = Smoother::new(mesh, params);
    let built = start.elapsed();
    let before = mesh.positions.clone();
    let start = std::time::Instant::now();
    let counts = smoother.run(&mut mesh.positions);
    let elapsed = start.elapsed().as_secs_f64();
    let graph = smoother.graph();
    let (mean, max) = displacement(&before, &mesh.positions);
    let diagonal = mesh.bounding_box_diagonal();
    let relative = |d: f64| if diagonal > 0.0 { d / diagonal } else { 0.0 };
    let updates = graph.smoothed_vertices() as f64 * f64::from(counts.passes);
    let outer_ring_share = if counts.neighbours > 0 {
        counts.outer_ring_neighbours as f64 / counts.neighbours as f64
    } else {
        0.0
    };
    // With `rings = 1` every neighbour is in the outermost ring: the 1-ring was asked for.
    let rings = match params.method {
        SmoothMethod::Bilateral(p) => p.rings,
        _ => 0,
    };
    if rings > 1 && outer_ring_share > 0.15 {
        tracing::warn!(
            outer_ring_share,
            "bilateral: the ρ-ball reaches beyond the searched rings; raise `rings` or lower `radius`"
        );
    }
    tracing::debug!(
        method = params.method.name(),
        build_ms = built.as_secs_f64() * 1e3,
        smoothing_ms = elapsed * 1e3,
        "smooth done"
    );
    SmoothReport {
        method: params.method.name(),
        iterations: params.iterations,
        passes: counts.passes,
        smoothed_vertices: graph.smoothed_vertices(),
        fixed_boundary_vertices: graph.fixed_boundary_vertices(),
        isolated_vertices: graph.isolated_vertices(),
        empty_neighbourhoods: counts.empty_neighbourhoods,
        undone_updates: counts.undone_updates,
        mean_neighbourhood: if updates > 0.0 {
            counts.neighbours as f64 / updates
        } else {
            0.0
        },
        outer_ring_share,
        mean_displacement: mean,
        max_displacement: max,
        mean_displacement_relative: relative(mean),
        max_displacement_relative: relative(max),
        smoothing_ms: elapsed * 1e3,
        vertex_updates_per_second: if elapsed > 0.0 {
            updates / elapsed
        } else {
            0.0
        },
    }
}

fn uses_cotangent(params: &SmoothParams) -> bool {
    let w = match params.method {
        SmoothMethod::Laplace(p) => p.weights,
        SmoothMethod::Hc(p) => p.weights,
        SmoothMethod::Taubin(p) => p.weights,
        SmoothMethod::Bilateral(_) | SmoothMethod::NormalFilter(_) => Weights::Uniform,
    };
    w == Weights::Cotangent
}

fn displacement(before: &[DVec3], after: &[DVec3]) -> (f64, f64) {
    if before.is_empty() {
        return (0.0, 0.0);
    }
    let (sum, max) = before
        .iter()
        .zip(after)
        .map(|(a, b)| a.distance(*b))
        .fold((0.0, 0.0f64), |(s, m), d| (s + d, m.max(d)));
    (sum / before.len() as f64, max)
}

#[cfg(test)]
mod tests;
