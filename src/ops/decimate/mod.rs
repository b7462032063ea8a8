//! Decimation (docs/decimation.md, which names the thesis; § below are the thesis' sections and
//! "reading Rn" the choices listed there where it is wrong or silent): wedge-aware quadric face collapse (algorithm f, §3.2),
//! edge collapse over the same quadrics, and octree vertex clustering (algorithms v and
//! vo, §3.1.1–3.1.2). Every method records in `triangle_origins` the input triangle each
//! output triangle descends from, so that `seam_fix` (§3.3) can run after any of them.
//!
//! Positions are normalised into a unit box (largest side 1) for the whole run (reading
//! R16); errors are reported relative to the bounding-box diagonal.

// Small fixed-size linear algebra reads best with index loops, and `!(x > 0.0)` is the
// intended NaN-rejecting test throughout.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

pub mod audit;
pub mod cluster;
pub mod collapse_loop;
pub mod edge_collapse;
pub mod guards;
pub mod halves;
mod heap;
mod prefetch;
pub mod quadric;
pub mod work;

use crate::mesh::Mesh;
use crate::ops::border::{self, Border};
use collapse_loop::{CollapseOperator, FaceCollapse};
use edge_collapse::EdgeCollapse;
use quadric::Weights;
use serde::{Deserialize, Serialize};
use work::{Config, Work};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Algorithm f (§3.2): face collapse with the wedge-aware quadric.
    FaceCollapse,
    /// Full-edge collapse over the same quadrics and guards. The default: on all six
    /// textured test scans it has a lower mean and RMS distance than face collapse (e.g.
    /// facefuns → 26k: mean 0.0042 % vs 0.0047 % of the diagonal; USNM coral: 0.059 % vs
    /// 0.089 %), and it reaches the target where face collapse runs out of collapses that
    /// keep every seam (pizza → 5k: 14.3k vs 25.2k faces).
    #[default]
    EdgeCollapse,
    /// Algorithm v (§3.1.2): octree clustering with the attribute-extended quadric.
    Cluster,
    /// Algorithm vo (§3.1.1): octree clustering keeping original vertices.
    ClusterKeep,
}

impl Method {
    /// The name in a recipe, from serde.
    pub fn name(self) -> String {
        crate::text::serde_name(&self)
    }
}

/// Whether edge collapse first decimates the two halves of the mesh on two cores
/// ([`halves`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Halves {
    /// For meshes of at least [`halves::AUTO_MIN_FACES`] triangles, when the step allows it
    /// (edge collapse, `boundary = "fixed"`, a `target_faces` and no `max_error`).
    #[default]
    Auto,
    /// Whenever the step allows it (as above, and more than 3 × the target triangles).
    On,
    /// Always one pass over the whole mesh.
    Off,
}

/// Order of the collapse heap.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Priority {
    /// The collapse's quadric error (the thesis' §6.4 reading; reading R11).
    #[default]
    Quadric,
    /// The thesis' cheap size estimate (§3.2 "Cost estimate"; reading R11).
    Estimate,
}

/// How ill-conditioning is detected (§2.3.4, readings R6–R7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Conditioning {
    /// Condition number of the reduced 3×3 (Schur) matrix — the fix of reading R7.
    #[default]
    Reduced,
    /// Condition number of the full (3 + k·m) matrix, as printed; with the recommended
    /// weights it flags every quadric (reading R7). For comparison only.
    ThesisLiteral,
}

/// What an ill-conditioned quadric falls back to (§2.3.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Fallback {
    /// The mean of the merged vertices along the directions the quadric does not
    /// determine, the optimum along the others (never worse than the mean).
    #[default]
    Regularised,
    /// The plain mean of the merged vertices (thesis §3.1.2).
    Mean,
}

/// Parameters of the `decimate` step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DecimateParams {
    pub method: Method,
    /// Stop at this many faces (face collapse lands within 4 of it,
    /// §3.2: it stops as soon as the count is at or below the target).
    pub target_faces: Option<usize>,
    /// Largest error a collapse may have, as a fraction of the bounding-box diagonal (RMS
    /// distance of the merged vertex from the planes it summarises).
    pub max_error: Option<f64>,
    /// `fixed` (recorded as `keep`), `weighted` or `like-interior` (recorded as `free`):
    /// see [`Border`].
    #[serde(with = "border::decimate")]
    pub boundary: Border,
    /// Weight of the border planes with `boundary = "weighted"`.
    pub boundary_weight: f64,
    /// Weight of the planes that hold texture seams in place (through each seam edge,
    /// perpendicular to its triangles, as the border planes): a seam vertex slides along
    /// its seam only where the seam is nearly straight. 0 = no planes. Default: 1 for edge
    /// collapse, 0 for face collapse (measured in docs/decimation.md: the planes lower edge
    /// collapse's texture deviation on every scan with seams, but make face collapse, which
    /// merges three vertices at once, stop short of the target on pizza).
    pub seam_weight: Option<f64>,
    /// λ_geom, λ_tex, λ_normal of §2.3.2. Table 5.1 recommends 1, 1e-17, 1e-17; our default
    /// λ_tex is 0.05 (w = 0.0025 on texture coordinates in \[0,1\] against a unit-box
    /// geometry): it lowers the colour deviation on a textured face for a distance still
    /// below MeshLab's (figures in docs/decimation.md, "Measurements behind rules in the
    /// code"). Set 1e-17 for the thesis' values.
    pub geometry_weight: f64,
    pub texture_weight: f64,
    pub normal_weight: f64,
    /// Use w = λ² (Hoppe's form, §2.3.2 default) rather than w = λ (reading R5).
    pub squared_weights: bool,
    pub priority: Priority,
    /// Research only: set from the recipe's `[experimental.decimate]` table
    /// ([`Experimental`]), never from the step's own table; recorded in the step's resolved
    /// form as it always was, so that recipes keep their hash.
    #[serde(skip_deserializing)]
    pub conditioning: Conditioning,
    /// Condition-number threshold (reading R6: 1e8 from the class text; the GUI said ≥ 1e10).
    pub max_condition: f64,
    pub fallback: Fallback,
    /// Largest change (degrees) of a surviving triangle's normal in one collapse.
    pub max_normal_change: f64,
    /// Link condition, flip, texture-flip and degeneracy guards (not in the thesis, §3.2);
    /// off is the thesis-literal behaviour and loses the guarantees. Research only, as
    /// `conditioning`.
    #[serde(skip_deserializing)]
    pub guards: bool,
    /// Edge collapse of a large scan: the two halves first, each on its own core, then the
    /// whole ([`halves`]; measured in docs/decimation.md: faster and at least as good).
    pub halves: Halves,
}

impl Default for DecimateParams {
    fn default() -> Self {
        DecimateParams {
            method: Method::EdgeCollapse,
            target_faces: None,
            max_error: None,
            boundary: Border::Fixed,
            boundary_weight: 1.0,
            seam_weight: None,
            geometry_weight: 1.0,
            texture_weight: 0.05,
            normal_weight: 1e-17,
            squared_weights: true,
            priority: Priority::Quadric,
            conditioning: Conditioning::Reduced,
            max_condition: 1e8,
            fallback: Fallback::Regularised,
            max_normal_change: 60.0,
            guards: true,
            halves: Halves::Auto,
        }
    }
}

/// The `[experimental.decimate]` table of a recipe: switches that reproduce the thesis as
/// printed, for research; they lose guarantees the product relies on, so they are kept out
/// of the step's own table. They apply to every `decimate` step of the recipe.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Experimental {
    /// `thesis-literal`: the condition number of the full matrix, as printed (reading R7).
    pub conditioning: Conditioning,
    /// `false`: no link, flip, texture-flip or degeneracy guards.
    pub guards: bool,
}

impl Default for Experimental {
    fn default() -> Self {
        Experimental {
            conditioning: Conditioning::Reduced,
            guards: true,
        }
    }
}

impl Experimental {
    /// The keys of this table, from serde; in a `decimate` step's own table they are an
    /// error that says where they moved.
    pub fn keys() -> Vec<String> {
        match serde_json::to_value(Experimental::default()) {
            Ok(serde_json::Value::Object(map)) => map.into_iter().map(|(k, _)| k).collect(),
            _ => unreachable!("a struct serialises as a map"),
        }
    }
}

impl DecimateParams {
    /// The research switches of the recipe's `[experimental.decimate]` table.
    pub fn with_experimental(self, e: Experimental) -> DecimateParams {
        DecimateParams {
            conditioning: e.conditioning,
            guards: e.guards,
            ..self
        }
    }

    pub fn validate(&self) -> Result<(), String> {
        border::DECIMATE.check(self.boundary)?;
        if self.target_faces.is_none() && self.max_error.is_none() {
            return Err("give target_faces, max_error or both".into());
        }
        if let Some(e) = self.max_error
            && !(e >= 0.0 && e.is_finite())
        {
            return Err(format!("max_error must be a finite number ≥ 0, got {e}"));
        }
        for (name, v) in [
            ("boundary_weight", self.boundary_weight),
            ("seam_weight", self.seam_weight.unwrap_or(0.0)),
            ("geometry_weight", self.geometry_weight),
            ("texture_weight", self.texture_weight),
            ("normal_weight", self.normal_weight),
        ] {
            if !(v >= 0.0 && v.is_finite()) {
                return Err(format!("{name} must be a finite number ≥ 0, got {v}"));
            }
        }
        if !(self.geometry_weight > 0.0) {
            return Err("geometry_weight must be > 0".into());
        }
        if !(self.max_condition >= 1.0) {
            return Err(format!(
                "max_condition must be ≥ 1, got {}",
                self.max_condition
            ));
        }
        if self.halves == Halves::On
            && (self.method != Method::EdgeCollapse
                || self.boundary != Border::Fixed
                || self.target_faces.is_none()
                || self.max_error.is_some())
        {
            return Err(
                "halves = \"on\" needs method = \"edge-collapse\", boundary = \"fixed\", a target_faces and no max_error"
                    .into(),
            );
        }
        if !(self.max_normal_change > 0.0 && self.max_normal_change <= 180.0) {
            return Err(format!(
                "max_normal_change must be in (0, 180] degrees, got {}",
                self.max_normal_change
            ));
        }
        Ok(())
    }

    pub(crate) fn weight(&self, lambda: f64) -> f64 {
        if self.squared_weights {
            lambda * lambda
        } else {
            lambda
        }
    }
}

/// Why a collapse was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// Link condition: the merge would create a non-manifold edge or vertex, a duplicate
    /// triangle, close a hole or open a crack.
    Link,
    /// A surviving triangle's normal would turn too far (or against its input triangle).
    Flip,
    /// A surviving triangle's texture triangle would fold over.
    TextureFlip,
    /// A surviving triangle would become degenerate (zero area) or a worse sliver.
    Degenerate,
    /// A seam would close, or a seam vertex would leave its seam.
    Seam,
    /// A border vertex would leave its border.
    Boundary,
    /// Two fixed vertices (non-manifold, seam junctions, kept borders) would merge.
    Locked,
    /// The collapse's error exceeds `max_error`.
    MaxError,
    /// The merged vertices have more corners together than [`work::MAX_STAR`] (a vertex
    /// of very high valence, e.g. the centre of a large fan): checking it would cost too much.
    Valence,
}

/// Collapses refused, by cause.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct RefusedCounts {
    pub link: usize,
    pub flip: usize,
    pub texture_flip: usize,
    pub degenerate: usize,
    pub seam: usize,
    pub boundary: usize,
    pub locked: usize,
    pub max_error: usize,
    /// Not in reports where it is zero (no scan meets it; reports stay as they were).
    #[serde(skip_serializing_if = "is_zero")]
    pub valence: usize,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl RefusedCounts {
    /// The causes with their counts, largest first, with a description of each.
    pub fn ranked(&self) -> Vec<(usize, &'static str)> {
        let mut v = vec![
            (
                self.seam,
                "would close a texture seam or move a seam vertex off its seam",
            ),
            (
                self.locked,
                "would merge two fixed vertices (seam junctions, non-manifold or kept border vertices)",
            ),
            (self.boundary, "would move a border vertex off its border"),
            (
                self.link,
                "would break the link condition (non-manifold, duplicate face, hole closed)",
            ),
            (self.flip, "would turn a triangle over"),
            (self.texture_flip, "would fold the texture over"),
            (self.degenerate, "would make a degenerate triangle"),
            (self.max_error, "exceeds max_error"),
            (
                self.valence,
                "would merge vertices with more triangles around them than a merge may check",
            ),
        ];
        v.retain(|e| e.0 > 0);
        v.sort_by_key(|e| std::cmp::Reverse(e.0));
        v
    }

    pub fn total(&self) -> usize {
        self.link
            + self.flip
            + self.texture_flip
            + self.degenerate
            + self.seam
            + self.boundary
            + self.locked
            + self.max_error
            + self.valence
    }

    /// Adds another loop's counts to these.
    pub fn add(&mut self, o: &RefusedCounts) {
        self.link += o.link;
        self.flip += o.flip;
        self.texture_flip += o.texture_flip;
        self.degenerate += o.degenerate;
        self.seam += o.seam;
        self.boundary += o.boundary;
        self.locked += o.locked;
        self.max_error += o.max_error;
        self.valence += o.valence;
    }

    pub fn count(&mut self, cause: Refusal) {
        match cause {
            Refusal::Link => self.link += 1,
            Refusal::Flip => self.flip += 1,
            Refusal::TextureFlip => self.texture_flip += 1,
            Refusal::Degenerate => self.degenerate += 1,
            Refusal::Seam => self.seam += 1,
            Refusal::Boundary => self.boundary += 1,
            Refusal::Locked => self.locked += 1,
            Refusal::MaxError => self.max_error += 1,
            Refusal::Valence => self.valence += 1,
        }
    }
}

/// Why a decimation stopped (the report's `stopped_by`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum StopReason {
    /// The face target was reached.
    #[default]
    Target,
    /// The next collapse would exceed `max_error`.
    MaxError,
    /// Every collapse left is refused (by a guard, or there is none).
    NoCandidates,
}

/// The step's figures.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DecimateReport {
    pub method: String,
    pub faces_before: usize,
    pub faces_after: usize,
    pub vertices_before: usize,
    pub vertices_after: usize,
    pub target_faces: Option<usize>,
    /// Largest collapse error reached, as a fraction of the bounding-box diagonal.
    pub error_reached: f64,
    pub stopped_by: StopReason,
    pub collapses: usize,
    pub refused: RefusedCounts,
    /// When the target was not reached: every collapse still possible (edges for edge
    /// collapse, triangles for face collapse), by the reason it is refused.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub blocked: Option<RefusedCounts>,
    /// Why the step stopped short of its target, in words (none when it reached it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stop_note: Option<String>,
    /// Candidate evaluations (quadric solves) in the collapse loop.
    pub evaluations: usize,
    /// Applied collapses that used the ill-conditioned fallback (§2.3.4).
    pub ill_conditioned: usize,
    /// Vertices by class at the start: interior, border, seam, fixed.
    pub interior_vertices: usize,
    pub border_vertices: usize,
    pub seam_vertices: usize,
    pub fixed_vertices: usize,
    /// Octree leaves (clustering methods).
    pub clusters: Option<usize>,
    /// When the halves were decimated first: what they did ([`halves`]). The collapses,
    /// refusals and evaluations above include theirs, and the vertex classes are theirs.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub halves: Option<halves::HalvesReport>,
}

#[derive(Debug, thiserror::Error)]
pub enum DecimateError {
    #[error("invalid decimate parameters: {0}")]
    Params(String),
    #[error("the mesh has no triangles")]
    Empty,
}

/// Decimates `mesh`; the input is left unchanged.
pub fn decimate(
    mesh: &Mesh,
    params: &DecimateParams,
) -> Result<(Mesh, DecimateReport), DecimateError> {
    decimate_beside(mesh, params, &|| ())
}

/// [`decimate`], running `beside` where the decimation leaves a core idle: in a
/// `rayon::join` with a one-pass decimation, or with the final pass after the halves, whose
/// set-up is parallel and whose collapse loop, most of it, is sequential. It has run when
/// this returns, unless the parameters are refused or the mesh is empty. `beside` may run again if a decimation in halves falls back to one pass;
/// what it does must not depend on the decimation.
pub fn decimate_beside(
    mesh: &Mesh,
    params: &DecimateParams,
    beside: &(dyn Fn() + Sync),
) -> Result<(Mesh, DecimateReport), DecimateError> {
    decimate_with_origin_beside(mesh, params, None, beside)
}

/// [`decimate`] of a mesh whose `triangle_origins` index `origin` (an earlier decimation's
/// input): the flip guard of the collapse methods holds every triangle against its origin
/// triangle's normal, as one decimation from `origin` would.
pub fn decimate_with_origin(
    mesh: &Mesh,
    params: &DecimateParams,
    origin: Option<&Mesh>,
) -> Result<(Mesh, DecimateReport), DecimateError> {
    decimate_with_origin_beside(mesh, params, origin, &|| ())
}

/// [`decimate_with_origin`] with work `beside` its collapse loop ([`decimate_beside`]).
pub(crate) fn decimate_with_origin_beside(
    mesh: &Mesh,
    params: &DecimateParams,
    origin: Option<&Mesh>,
    beside: &(dyn Fn() + Sync),
) -> Result<(Mesh, DecimateReport), DecimateError> {
    params.validate().map_err(DecimateError::Params)?;
    if mesh.triangles.is_empty() {
        return Err(DecimateError::Empty);
    }
    let has_uv = !mesh.texcoords.is_empty();
    let has_n = !mesh.normals.is_empty();
    let in_halves = match (origin, halves::wanted(mesh, params)) {
        (None, Some(target)) => {
            let done = halves::run(mesh, params, target, beside);
            if done.is_none() {
                tracing::debug!("the halves' cut could not be matched exactly: one pass instead");
            }
            done
        }
        _ => None,
    };
    let one_pass = || match (has_uv, has_n) {
        (true, true) => run::<5, &Mesh>(mesh, params, origin),
        (true, false) => run::<2, &Mesh>(mesh, params, origin),
        (false, true) => run::<3, &Mesh>(mesh, params, origin),
        (false, false) => run::<0, &Mesh>(mesh, params, origin),
    };
    let (mut out, mut report) = match in_halves {
        Some(done) => done,
        None => rayon::join(one_pass, beside).0,
    };
    if out.triangle_origins.len() != out.triangles.len() {
        out.triangle_origins = (0..out.triangles.len())
            .map(|t| mesh.triangle_origin(t))
            .collect();
    }
    finish(
        params,
        (mesh.triangles.len(), mesh.positions.len()),
        &out,
        &mut report,
    );
    Ok((out, report))
}

/// The input of a collapse decimation ([`collapse`]). A caller that owns its input may
/// drop from it, while the collapse loop runs, what the loop does not read (the working
/// mesh has its own copies), and bring it back for the output: the halves do
/// (`halves.rs`), since both halves' working meshes are alive at once at the step's memory
/// peak.
pub(crate) trait CollapseInput {
    fn mesh(&self) -> &Mesh;
    /// The working mesh has its copies ([`Work::copied`]), its quadrics are not yet made:
    /// what only the output needs may go.
    fn thin(&mut self) {}
    /// The loop is done: bring back what [`Work::into_mesh`] reads (all but the triangles).
    fn restore(&mut self) {}
}

impl CollapseInput for &Mesh {
    fn mesh(&self) -> &Mesh {
        self
    }
}

/// [`decimate`] of an input the caller owns (see [`CollapseInput`]), in one pass (no
/// halves, no origin).
pub(crate) fn decimate_input<I: CollapseInput>(
    input: I,
    params: &DecimateParams,
) -> Result<(Mesh, DecimateReport), DecimateError> {
    params.validate().map_err(DecimateError::Params)?;
    let mesh = input.mesh();
    if mesh.triangles.is_empty() {
        return Err(DecimateError::Empty);
    }
    let before = (mesh.triangles.len(), mesh.positions.len());
    let (has_uv, has_n) = (!mesh.texcoords.is_empty(), !mesh.normals.is_empty());
    let (out, mut report) = match (has_uv, has_n) {
        (true, true) => run::<5, I>(input, params, None),
        (true, false) => run::<2, I>(input, params, None),
        (false, true) => run::<3, I>(input, params, None),
        (false, false) => run::<0, I>(input, params, None),
    };
    finish(params, before, &out, &mut report);
    Ok((out, report))
}

/// One decimation with `M` attribute channels per wedge.
fn run<const M: usize, I: CollapseInput>(
    input: I,
    params: &DecimateParams,
    origin: Option<&Mesh>,
) -> (Mesh, DecimateReport) {
    let w = weights::<M>(input.mesh(), params);
    match params.method {
        Method::Cluster | Method::ClusterKeep => cluster::run::<M>(input.mesh(), params, w),
        Method::FaceCollapse | Method::EdgeCollapse => collapse::<M, I>(input, params, w, origin),
    }
}

/// The report's counts and the log lines of a finished decimation; `before` is the input's
/// (triangles, vertices).
fn finish(
    params: &DecimateParams,
    before: (usize, usize),
    out: &Mesh,
    report: &mut DecimateReport,
) {
    report.method = params.method.name();
    (report.faces_before, report.vertices_before) = before;
    report.faces_after = out.triangles.len();
    report.vertices_after = out.positions.len();
    report.target_faces = params.target_faces;
    debug_assert!(out.check_invariants().is_ok());
    if let Some(note) = &report.stop_note {
        tracing::info!("{note}");
    }
    tracing::info!(
        method = report.method,
        faces = report.faces_after,
        collapses = report.collapses,
        error = report.error_reached,
        "decimated"
    );
}

fn weights<const M: usize>(mesh: &Mesh, params: &DecimateParams) -> Weights<M> {
    let mut attr = [0.0; M];
    let mut k = 0;
    if !mesh.texcoords.is_empty() && M >= 2 {
        attr[0] = params.weight(params.texture_weight);
        attr[1] = attr[0];
        k = 2;
    }
    if !mesh.normals.is_empty() && M >= k + 3 {
        for a in &mut attr[k..k + 3] {
            *a = params.weight(params.normal_weight);
        }
    }
    Weights {
        geom: params.weight(params.geometry_weight),
        attr,
    }
}

/// The collapse methods' settings for [`Work`], from the step's parameters.
fn collapse_config(params: &DecimateParams) -> Config {
    Config {
        boundary: params.boundary,
        boundary_weight: params.boundary_weight,
        seam_weight: params.seam_weight.unwrap_or(match params.method {
            Method::EdgeCollapse => 1.0,
            _ => 0.0,
        }),
        conditioning: params.conditioning,
        max_condition: params.max_condition,
        fallback: params.fallback,
        cos_max_normal_change: params.max_normal_change.to_radians().cos(),
        guards: params.guards,
    }
}

/// Face or edge collapse: the set-up, the collapse loop, the output; the phases' wall and
/// CPU times go to the debug log.
fn collapse<const M: usize, I: CollapseInput>(
    mut input: I,
    params: &DecimateParams,
    w: Weights<M>,
    origin: Option<&Mesh>,
) -> (Mesh, DecimateReport) {
    let diag = input.mesh().bounding_box_diagonal();
    let (t0, c0) = (std::time::Instant::now(), cpu_seconds());
    let mut work = Work::<M>::copied(input.mesh(), w, collapse_config(params), origin);
    input.thin();
    work.prepare();
    let (t1, c1) = (std::time::Instant::now(), cpu_seconds());
    // Normalised units: the largest box side is 1.
    let to_diag = if diag > 0.0 {
        1.0 / (work.inv_scale * diag)
    } else {
        1.0
    };
    let max_error = params.max_error.map_or(f64::INFINITY, |e| e / to_diag);
    let target = params.target_faces.unwrap_or(0);
    let (stats, what) = if params.method == Method::FaceCollapse {
        let op = FaceCollapse {
            priority: params.priority,
        };
        let stats = collapse_loop::run(&mut work, &op, target, max_error);
        (stats, FaceCollapse::NAME)
    } else {
        let stats = collapse_loop::run(&mut work, &EdgeCollapse, target, max_error);
        (stats, EdgeCollapse::NAME)
    };
    let (t2, c2) = (std::time::Instant::now(), cpu_seconds());
    let report = collapse_report(params, &work, stats, what, to_diag);
    work.release_loop_state();
    input.restore();
    let out = work.into_mesh(input.mesh());
    tracing::debug!(
        work_ms = (t1 - t0).as_secs_f64() * 1e3,
        collapse_ms = (t2 - t1).as_secs_f64() * 1e3,
        output_ms = t2.elapsed().as_secs_f64() * 1e3,
        work_cpu_ms = (c1 - c0) * 1e3,
        collapse_cpu_ms = (c2 - c1) * 1e3,
        output_cpu_ms = (cpu_seconds() - c2) * 1e3,
        "decimate phases"
    );
    (out, report)
}

/// The report of a collapse method: the loop's figures, errors back in the input's units
/// (`to_diag`), and when the loop stopped short, a note of why.
fn collapse_report<const M: usize>(
    params: &DecimateParams,
    work: &Work<M>,
    stats: collapse_loop::LoopStats,
    what: &str,
    to_diag: f64,
) -> DecimateReport {
    let target = params.target_faces.unwrap_or(0);
    let classes = &work.classes;
    DecimateReport {
        error_reached: stats.max_error * to_diag,
        stopped_by: if stats.stopped_by == StopReason::NoCandidates && params.max_error.is_some() {
            StopReason::MaxError
        } else {
            stats.stopped_by
        },
        collapses: stats.collapses,
        refused: stats.refused,
        stop_note: stats.blocked.as_ref().map(|b| {
            let causes: Vec<String> = b
                .ranked()
                .iter()
                .map(|(n, why)| format!("{n} {why}"))
                .collect();
            format!(
                "stopped at {} faces, short of the target {}: all {} {what} left are refused: {}",
                work.live,
                target,
                b.total(),
                causes.join("; ")
            )
        }),
        blocked: stats.blocked,
        evaluations: stats.evaluations,
        ill_conditioned: stats.ill_conditioned,
        interior_vertices: classes.interior,
        border_vertices: classes.border,
        seam_vertices: classes.seam,
        fixed_vertices: classes.fixed,
        ..Default::default()
    }
}

/// The process's CPU time, for the phase timings in the debug log.
pub(crate) use crate::geom::timing::cpu_seconds;

#[cfg(test)]
mod tests;
