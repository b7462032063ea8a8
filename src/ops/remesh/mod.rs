//! Remeshing (issue #24, docs/remeshing.md): the recipe step `remesh`.
//!
//! `method = "isotropic"` ([`isotropic`], Botsch & Kobbelt 2004) replaces the triangles by
//! nearly equilateral ones of a target edge length while keeping borders, texture seams,
//! material changes and (optionally) sharp edges as lines, and carrying the texture: every
//! corner's texture coordinate comes from the input, within its own chart ([`export`]).
//! `method = "patches"` ([`patches`]) is the thesis' Bézier-patch remesher for closed
//! manifold meshes; it drops texture coordinates.

pub mod build;
pub mod corners;
pub mod export;
pub mod fit;
pub mod isotropic;
pub mod lines;
pub mod ops;
pub mod patches;
pub mod quality;
pub mod repair;
pub mod sizing;
pub mod slivers;
#[cfg(test)]
mod tests;
pub mod walk;

use crate::geom::bvh::TriangleBvh;
use crate::mesh::Mesh;
use crate::mesh::topology::Topology;
use crate::metrics::TextureCache;
use lines::{LineKind, Lines};
use quality::AngleQuality;
use serde::{Deserialize, Serialize};
use sizing::{Adaptive, Sizing, SizingReport};
use std::time::Instant;
use walk::Planes;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Split, collapse, flip, relax, project (Botsch & Kobbelt 2004).
    #[default]
    Isotropic,
    /// The thesis' Bézier-patch pipeline ([`patches`]): closed manifold meshes only.
    Patches,
}

/// Parameters of the `remesh` step. Exactly one of `edge_length`, `edge_fraction` and
/// `target_faces` sets the target edge length L; with `adaptive`, L is the longest edge
/// (where the surface is flat) and the curvature shortens it elsewhere.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RemeshParams {
    pub method: Method,
    /// L in the mesh's units.
    pub edge_length: Option<f64>,
    /// L as a fraction of the bounding-box diagonal.
    pub edge_fraction: Option<f64>,
    /// L such that equilateral triangles of side L cover the input's area this many times.
    pub target_faces: Option<usize>,
    /// Split–collapse–flip–relax–project rounds.
    pub iterations: usize,
    /// Edges whose two faces' normals differ by more than this (degrees) are kept as lines;
    /// none when absent (scans are noisy: a small angle turns noise into lines).
    pub feature_angle: Option<f64>,
    /// `patches` only: seed spacing as a fraction of the bounding-box diagonal (thesis §4.2).
    /// Left out of the resolved recipe when absent, so isotropic recipes keep their hash.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub f: Option<f64>,
    /// `patches` only: the n of the n×n tessellation of every Bézier patch (thesis §4.7).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub patch_resolution: Option<usize>,
    /// `isotropic` only: a curvature-adaptive size (Dunyach et al. 2013, [`sizing`]). The
    /// adaptive keys are left out of the resolved recipe when absent, so that recipes
    /// written before them keep their hash.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub adaptive: bool,
    /// The approximation tolerance ε of the adaptive size, in the mesh's units ...
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// ... or as a fraction of the bounding-box diagonal (default: L/100).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tolerance_fraction: Option<f64>,
    /// The shortest edge of the adaptive size, in the mesh's units ...
    #[serde(skip_serializing_if = "Option::is_none")]
    pub min_edge_length: Option<f64>,
    /// ... or as a fraction of the bounding-box diagonal (default: L/5).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub min_edge_fraction: Option<f64>,
    /// `isotropic` only: leave every vertex on the input surface, as projection put it,
    /// instead of fitting the free vertices to the input in the least-squares sense
    /// ([`fit`]; the default: 22–34 % closer to the input on the scans of docs/remeshing.md).
    /// Left out of the resolved recipe when false.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub on_surface: bool,
    /// `isotropic` only: the edge length along the input's open borders, as a fraction of
    /// L (default [`DEFAULT_BORDER_EDGE_RATIO`]; 1 for none), growing back to L away from
    /// the border ([`sizing::border_sizes`]). Left out of the resolved recipe when absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub border_edge_ratio: Option<f64>,
    /// `isotropic` only: write a new texture image for the result ([`crate::ops::bake`]), in
    /// which every point shows the colour the input shows at its nearest point, instead of
    /// keeping the input's image (whose photo then lands slightly off between the new
    /// corners). Costs time and a PNG of the input image's size per material. Left out of
    /// the resolved recipe when false.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub bake_texture: bool,
}

impl Default for RemeshParams {
    fn default() -> Self {
        RemeshParams {
            method: Method::Isotropic,
            edge_length: None,
            edge_fraction: None,
            target_faces: None,
            iterations: DEFAULT_ITERATIONS,
            feature_angle: None,
            f: None,
            patch_resolution: None,
            adaptive: false,
            tolerance: None,
            tolerance_fraction: None,
            min_edge_length: None,
            min_edge_fraction: None,
            on_surface: false,
            border_edge_ratio: None,
            bake_texture: false,
        }
    }
}

/// Most items a parallel pass over the working mesh's vertices or faces hands to one thread
/// at a time. The work per item varies along the index order (collapses leave dead vertices
/// and faces where the input was dense; splits add new ones at the end), and rayon's own
/// split of a range into a few large pieces left one thread with most of it: on james,
/// pieces of at most 256 took the projection from 6.0 to 5.0 ms (docs/remeshing.md). The
/// export's passes run over the output, which has no dead items, and do not need it.
const PIECE: usize = 256;

pub const DEFAULT_ITERATIONS: usize = 5;
/// More rounds than this do not change the result measurably and only cost time.
pub const MAX_ITERATIONS: usize = 100;
/// The shortest target length, as a fraction of the diagonal; a floor for `edge_length` and
/// `target_faces`, which do not see the scan's size when the recipe is checked.
pub const MIN_EDGE_FRACTION: f64 = 1e-4;
/// The most triangles a remesh may make (about 4 GB of working mesh). The floor above still
/// allows ~10⁸ triangles on a flat scan, so the expected count is checked before any work:
/// a recipe asking for more fails with the figure instead of running the job out of memory.
pub const MAX_OUTPUT_FACES: f64 = 10_000_000.0;
/// Adaptive defaults, as fractions of the longest edge L: the tolerance ε = L/100 shortens
/// edges where the curvature radius is below about 17·L (L(r) < L for r < L²/(6ε)); the
/// shortest edge L/5 is reached at radii below about 0.7·L, which bounds how many
/// triangles noise or a sharp crease can ask for (at most 25 times the uniform density).
pub const DEFAULT_TOLERANCE_RATIO: f64 = 0.01;
pub const DEFAULT_MIN_EDGE_RATIO: f64 = 0.2;
/// Border edges at half the target length: on the open scans of docs/remeshing.md the mean
/// distance to the input falls by 7–12 % and the largest by half for 3–10 % more triangles,
/// with at least 99.4 % of them at 30° or more. Shorter (0.25 on james) costs the angles.
pub const DEFAULT_BORDER_EDGE_RATIO: f64 = 0.5;
/// The shortest border edge allowed, as a fraction of L.
pub const MIN_BORDER_EDGE_RATIO: f64 = 0.2;

/// Triangles of equilateral side `l` that cover `area` (the relation `target_faces` uses).
fn faces_for(area: f64, l: f64) -> f64 {
    4.0 * area / (3f64.sqrt() * l * l)
}

impl RemeshParams {
    pub fn validate(&self) -> Result<(), String> {
        if self.method == Method::Patches {
            return self.validate_patches();
        }
        if self.f.is_some() || self.patch_resolution.is_some() {
            return Err("f and patch_resolution belong to method = \"patches\"".into());
        }
        let given = [
            self.edge_length.is_some(),
            self.edge_fraction.is_some(),
            self.target_faces.is_some(),
        ];
        if given.iter().filter(|&&g| g).count() != 1 {
            return Err("give exactly one of edge_length, edge_fraction and target_faces".into());
        }
        if let Some(l) = self.edge_length
            && !(l.is_finite() && l > 0.0)
        {
            return Err(format!("edge_length must be a positive number, not {l}"));
        }
        if let Some(f) = self.edge_fraction
            && !(f.is_finite() && (MIN_EDGE_FRACTION..=1.0).contains(&f))
        {
            return Err(format!(
                "edge_fraction must be in {MIN_EDGE_FRACTION}..=1 (of the bounding-box diagonal), not {f}"
            ));
        }
        if self.target_faces == Some(0) {
            return Err("target_faces must be at least 1".into());
        }
        if !(1..=MAX_ITERATIONS).contains(&self.iterations) {
            return Err(format!(
                "iterations must be in 1..={MAX_ITERATIONS}, not {}",
                self.iterations
            ));
        }
        if let Some(a) = self.feature_angle
            && !(a.is_finite() && (0.0..=180.0).contains(&a))
        {
            return Err(format!("feature_angle must be in 0..=180 degrees, not {a}"));
        }
        if let Some(r) = self.border_edge_ratio
            && !(r.is_finite() && (MIN_BORDER_EDGE_RATIO..=1.0).contains(&r))
        {
            return Err(format!(
                "border_edge_ratio must be in {MIN_BORDER_EDGE_RATIO}..=1 (of the target edge length; 1 for no refinement), not {r}"
            ));
        }
        self.validate_adaptive()
    }

    fn has_adaptive_keys(&self) -> bool {
        self.tolerance.is_some()
            || self.tolerance_fraction.is_some()
            || self.min_edge_length.is_some()
            || self.min_edge_fraction.is_some()
    }

    fn validate_adaptive(&self) -> Result<(), String> {
        if !self.adaptive {
            if self.has_adaptive_keys() {
                return Err("tolerance, tolerance_fraction, min_edge_length and min_edge_fraction belong to adaptive = true".into());
            }
            return Ok(());
        }
        if self.target_faces.is_some() {
            return Err("adaptive = true takes edge_length or edge_fraction (the longest edge, used where the surface is flat), not target_faces: the face count follows the curvature".into());
        }
        if self.tolerance.is_some() && self.tolerance_fraction.is_some() {
            return Err("give tolerance or tolerance_fraction, not both".into());
        }
        if self.min_edge_length.is_some() && self.min_edge_fraction.is_some() {
            return Err("give min_edge_length or min_edge_fraction, not both".into());
        }
        if let Some(t) = self.tolerance
            && !(t.is_finite() && t > 0.0)
        {
            return Err(format!("tolerance must be a positive number, not {t}"));
        }
        if let Some(t) = self.tolerance_fraction
            && !(t.is_finite() && t > 0.0 && t <= 1.0)
        {
            return Err(format!(
                "tolerance_fraction must be in (0, 1] (of the bounding-box diagonal), not {t}"
            ));
        }
        if let Some(m) = self.min_edge_length
            && !(m.is_finite() && m > 0.0)
        {
            return Err(format!(
                "min_edge_length must be a positive number, not {m}"
            ));
        }
        if let Some(m) = self.min_edge_fraction
            && !(m.is_finite() && (MIN_EDGE_FRACTION..=1.0).contains(&m))
        {
            return Err(format!(
                "min_edge_fraction must be in {MIN_EDGE_FRACTION}..=1 (of the bounding-box diagonal), not {m}"
            ));
        }
        // In the same units the bound is checked here; mixed, when the scan is known.
        let pairs = [
            (
                self.min_edge_length,
                self.edge_length,
                "min_edge_length",
                "edge_length",
            ),
            (
                self.min_edge_fraction,
                self.edge_fraction,
                "min_edge_fraction",
                "edge_fraction",
            ),
        ];
        for (min, max, a, b) in pairs {
            if let (Some(min), Some(max)) = (min, max)
                && min > max
            {
                return Err(format!(
                    "{a} ({min}) must not exceed {b} ({max}), the longest edge of adaptive = true"
                ));
            }
        }
        Ok(())
    }

    /// The adaptive size's settings for `mesh` in its units (`None` when not adaptive).
    pub fn adaptive_for(&self, mesh: &Mesh) -> Option<Result<Adaptive, RemeshError>> {
        if !self.adaptive {
            return None;
        }
        let diag = mesh.bounding_box_diagonal();
        let max_edge = self.target_length(mesh);
        let tolerance = match (self.tolerance, self.tolerance_fraction) {
            (Some(t), _) => t,
            (_, Some(f)) => f * diag,
            _ => DEFAULT_TOLERANCE_RATIO * max_edge,
        };
        let min_edge = match (self.min_edge_length, self.min_edge_fraction) {
            (Some(m), _) => m,
            (_, Some(f)) => f * diag,
            _ => DEFAULT_MIN_EDGE_RATIO * max_edge,
        }
        .max(MIN_EDGE_FRACTION * diag);
        if min_edge > max_edge {
            return Some(Err(RemeshError::MinEdgeAboveMax { min_edge, max_edge }));
        }
        Some(Ok(Adaptive {
            tolerance,
            min_edge,
            max_edge,
        }))
    }

    fn validate_patches(&self) -> Result<(), String> {
        if self.edge_length.is_some()
            || self.edge_fraction.is_some()
            || self.feature_angle.is_some()
        {
            return Err("method \"patches\" takes f or target_faces (and patch_resolution), not edge_length, edge_fraction or feature_angle (those are method = \"isotropic\"'s)".into());
        }
        if self.border_edge_ratio.is_some() {
            return Err("method \"patches\" takes closed meshes only and has no border_edge_ratio (that is method = \"isotropic\"'s)".into());
        }
        if self.bake_texture {
            return Err("method \"patches\" drops texture coordinates, so it has no bake_texture (that is method = \"isotropic\"'s)".into());
        }
        if self.on_surface {
            return Err("method \"patches\" has no on_surface: its vertices are on its Bézier patches, not on the input (on_surface is method = \"isotropic\"'s)".into());
        }
        if self.adaptive || self.has_adaptive_keys() {
            return Err("method \"patches\" has no adaptive size: adaptive, tolerance, tolerance_fraction, min_edge_length and min_edge_fraction are method = \"isotropic\"'s".into());
        }
        if self.f.is_some() && self.target_faces.is_some() {
            return Err("give f or target_faces, not both".into());
        }
        if let Some(f) = self.f
            && !(f.is_finite() && (patches::MIN_F..=1.0).contains(&f))
        {
            return Err(format!(
                "f must be in {}..=1 (of the bounding-box diagonal), not {f}",
                patches::MIN_F
            ));
        }
        if self.target_faces == Some(0) {
            return Err("target_faces must be at least 1".into());
        }
        if let Some(n) = self.patch_resolution
            && !(1..=patches::MAX_RESOLUTION).contains(&n)
        {
            return Err(format!(
                "patch_resolution must be in 1..={}, not {n}",
                patches::MAX_RESOLUTION
            ));
        }
        Ok(())
    }

    /// The target edge length L for `mesh`.
    pub fn target_length(&self, mesh: &Mesh) -> f64 {
        let diag = mesh.bounding_box_diagonal();
        if let Some(l) = self.edge_length {
            return l.max(MIN_EDGE_FRACTION * diag);
        }
        if let Some(f) = self.edge_fraction {
            return f * diag;
        }
        let faces = self.target_faces.unwrap_or(1).max(1) as f64;
        (4.0 * surface_area(mesh) / (3f64.sqrt() * faces))
            .sqrt()
            .max(MIN_EDGE_FRACTION * diag)
    }
}

/// Input lines by kind (edges of the input).
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct LineCounts {
    pub border: usize,
    pub seam: usize,
    pub material: usize,
    pub feature: usize,
    pub non_manifold: usize,
}

#[derive(Debug, Clone, Serialize)]
pub struct RemeshReport {
    pub method: Method,
    pub edge_length: f64,
    pub iterations: usize,
    pub counts: isotropic::Counts,
    pub lines: LineCounts,
    /// Vertices never touched (non-manifold ones and the ends of non-manifold edges).
    pub locked_vertices: usize,
    pub quality_before: AngleQuality,
    pub quality_after: AngleQuality,
    pub seconds: f64,
    /// `adaptive = true` only: the size field (tolerance, shortest and longest edge, how many
    /// input vertices are clamped); `edge_length` is then the longest edge.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sizing: Option<SizingReport>,
    /// `isotropic` on a mesh with a border: the edge length along it ([`sizing::border_sizes`];
    /// absent when `border_edge_ratio` is 1 or the mesh is closed).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub border_edge: Option<f64>,
    /// `bake_texture = true` only: the images baked and the texels read.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bake: Option<crate::ops::bake::BakeReport>,
    /// `patches` only: seeds, retries, regions, patches; texture coordinates are dropped.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub patches: Option<patches::PatchesReport>,
}

/// Why a mesh cannot be remeshed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RemeshError {
    #[error("the mesh has no triangles")]
    Empty,
    #[error("the mesh's bounding box has no extent")]
    Flat,
    #[error(
        "an edge length of {edge_length:.3e} would make about {expected:.0} triangles, more than \
         the {limit:.0} a remesh may make; choose a longer edge_length or edge_fraction, or fewer target_faces"
    )]
    TooDense {
        edge_length: f64,
        expected: f64,
        limit: f64,
    },
    #[error(
        "the shortest edge of adaptive = true ({min_edge:.3e}) is longer than the longest \
         ({max_edge:.3e}, from edge_length or edge_fraction); lower min_edge_length or min_edge_fraction"
    )]
    MinEdgeAboveMax { min_edge: f64, max_edge: f64 },
    #[error("{0}")]
    Patches(#[from] patches::PatchesError),
}

fn surface_area(mesh: &Mesh) -> f64 {
    (0..mesh.triangles.len())
        .map(|t| mesh.triangle_area(t))
        .sum()
}

/// Remeshes `mesh` (already validated parameters) into a new mesh.
pub fn remesh(mesh: &Mesh, params: &RemeshParams) -> Result<(Mesh, RemeshReport), RemeshError> {
    remesh_with(mesh, params, &mut TextureCache::new())
}

/// [`remesh`], with the bake (`bake_texture`) reading the input's images from `textures`
/// and leaving the baked ones there (a recipe run shares one cache with its final metrics
/// and preview).
pub fn remesh_with(
    mesh: &Mesh,
    params: &RemeshParams,
    textures: &mut TextureCache,
) -> Result<(Mesh, RemeshReport), RemeshError> {
    let start = Instant::now();
    if mesh.triangles.is_empty() {
        return Err(RemeshError::Empty);
    }
    if mesh.bounding_box_diagonal().partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return Err(RemeshError::Flat);
    }
    if params.method == Method::Patches {
        return remesh_patches(mesh, params, start);
    }
    let l = params.target_length(mesh);
    let adaptive = params.adaptive_for(mesh).transpose()?;
    // The adaptive field's minimum bounds its density; the check below uses the field.
    let shortest = adaptive.map_or(l, |a| a.min_edge);
    let area = surface_area(mesh);
    let expected = faces_for(area, shortest);
    if expected.is_nan() || (adaptive.is_none() && expected > MAX_OUTPUT_FACES) {
        return Err(RemeshError::TooDense {
            edge_length: l,
            expected,
            limit: MAX_OUTPUT_FACES,
        });
    }
    let planes = Planes::for_sizes(mesh.triangles.len(), faces_for(area, l));
    // The search tree and the input's angles read only the input: made beside the rest of
    // the set-up, which is longer.
    let ((bvh, quality_before), setup) = rayon::join(
        || {
            let all = (0..mesh.triangles.len() as u32).collect();
            let bvh = match planes {
                Planes::Kept => TriangleBvh::with_planes(mesh, all),
                Planes::None => TriangleBvh::new(mesh, all),
            }
            .with_normal_cones();
            (bvh, AngleQuality::of(mesh))
        },
        || {
            let topo = Topology::new(mesh);
            let (sheet, rest) = walk::Sheet::new_beside(mesh, topo, planes, |topo| {
                // The size field reads neither the lines nor the corner table.
                let (field, (lines, c)) = rayon::join(
                    || size_field(mesh, topo, params, l, adaptive.as_ref(), area),
                    || {
                        let lines = Lines::new(mesh, topo, params.feature_angle);
                        let c = build::build(mesh, topo, &lines);
                        (lines, c)
                    },
                );
                Ok::<_, RemeshError>((field?, lines, c))
            });
            Ok::<_, RemeshError>((sheet, rest?))
        },
    );
    let (sheet, (field, lines, mut c)) = setup?;
    let mut sizing = field.sizing;
    let chart_of_input = c.chart.clone();
    let input = isotropic::Input {
        mesh,
        sheet: &sheet,
        bvh: &bvh,
        lines: &lines,
    };
    let counts = isotropic::run(
        &mut c,
        &input,
        &mut sizing,
        params.iterations,
        !params.on_surface,
    );
    let mut out = export::export(&c, &lines, &sheet, &chart_of_input, &bvh);
    let bake = params.bake_texture.then(|| {
        let source = crate::ops::bake::Source { mesh, bvh: &bvh };
        crate::ops::bake::bake(&mut out, &source, textures)
    });
    let report = RemeshReport {
        method: params.method,
        edge_length: field.edge_length,
        iterations: params.iterations,
        counts,
        lines: LineCounts {
            border: lines.count(LineKind::Border),
            seam: lines.count(LineKind::Seam),
            material: lines.count(LineKind::Material),
            feature: lines.count(LineKind::Feature),
            non_manifold: lines.count(LineKind::NonManifold),
        },
        locked_vertices: c.locked.iter().filter(|&&l| l).count(),
        quality_before,
        quality_after: AngleQuality::of(&out),
        seconds: start.elapsed().as_secs_f64(),
        sizing: field.report,
        border_edge: field.border_edge,
        bake,
        patches: None,
    };
    Ok((out, report))
}

/// The target length the passes work to, and what the report says of it.
struct SizeField {
    sizing: Sizing,
    /// L as used: the one asked for, or scaled to keep `target_faces` with a refined border.
    edge_length: f64,
    report: Option<SizingReport>,
    /// The edge length along the input's borders, when refined.
    border_edge: Option<f64>,
}

/// The size field of an isotropic remesh at target length `l`: uniform, or per input vertex
/// where `adaptive` or a refined border ([`sizing::border_sizes`]) asks for shorter edges
/// (the shorter of the two). With `target_faces`, a refined border's field is scaled so
/// that the expected count stays the one asked for. Refuses a field that would make more
/// than [`MAX_OUTPUT_FACES`].
fn size_field(
    mesh: &Mesh,
    topo: &Topology,
    params: &RemeshParams,
    l: f64,
    adaptive: Option<&Adaptive>,
    area: f64,
) -> Result<SizeField, RemeshError> {
    let ratio = params
        .border_edge_ratio
        .unwrap_or(DEFAULT_BORDER_EDGE_RATIO);
    let border = sizing::border_sizes(mesh, topo, l, ratio);
    let (mut sizes, report) = match (adaptive, &border) {
        (None, None) => {
            return Ok(SizeField {
                sizing: Sizing::uniform(l),
                edge_length: l,
                report: None,
                border_edge: None,
            });
        }
        (Some(a), _) => {
            let (sizes, report) = sizing::input_sizes(mesh, topo, a);
            (sizes, Some(report))
        }
        (None, Some(_)) => (vec![l; mesh.positions.len()], None),
    };
    let mut edge_length = l;
    let mut border_edge = border.as_ref().map(|_| ratio * l);
    if let Some(border) = &border {
        for (s, &b) in sizes.iter_mut().zip(border) {
            *s = s.min(b);
        }
    }
    let mut expected = adaptive_faces(mesh, &sizes);
    if let (Some(target), None) = (params.target_faces, adaptive) {
        let scale = (expected / target.max(1) as f64).sqrt();
        if scale.is_finite() && scale > 0.0 {
            sizes.iter_mut().for_each(|s| *s *= scale);
            edge_length *= scale;
            border_edge = border_edge.map(|b| b * scale);
            expected = adaptive_faces(mesh, &sizes);
        }
    }
    if expected.is_nan() || expected > MAX_OUTPUT_FACES {
        return Err(RemeshError::TooDense {
            edge_length: sizes.iter().copied().fold(f64::INFINITY, f64::min),
            expected,
            limit: MAX_OUTPUT_FACES,
        });
    }
    if adaptive.is_some()
        && let Some(note) = growth_note(faces_for(area, l), expected)
    {
        tracing::warn!("remesh: {note}");
    }
    Ok(SizeField {
        sizing: Sizing::adaptive(sizes),
        edge_length,
        report,
        border_edge,
    })
}

/// An adaptive remesh that asks for more than this many times the triangles of a uniform
/// one at its longest edge gets a warning before it starts. On the scans in
/// ../shared/data the defaults ask for 3–5 times (docs/remeshing.md); the USNM coral, a
/// crumpled photogrammetry surface, for about 12 times (750k triangles from 100k).
const GROWTH_WARNING: f64 = 8.0;

/// What to tell the user when the adaptive size asks for `expected` triangles where a
/// uniform remesh at the longest edge makes `uniform`.
fn growth_note(uniform: f64, expected: f64) -> Option<String> {
    let factor = expected / uniform.max(1.0);
    (factor > GROWTH_WARNING).then(|| {
        format!(
            "the adaptive size asks for about {expected:.0} triangles, {factor:.1}× the \
             {uniform:.0} of a uniform remesh at the longest edge: the surface bends at the \
             scale of the shortest edge almost everywhere (a crumpled or noisy scan). A larger \
             `tolerance` or `min_edge_length` (or their `_fraction`s) makes fewer"
        )
    })
}

/// The triangles an adaptive field asks for: each input triangle's area at the mean size
/// of its corners.
fn adaptive_faces(mesh: &Mesh, sizes: &[f64]) -> f64 {
    (0..mesh.triangles.len())
        .map(|t| {
            let s = mesh
                .triangle_vertices(t)
                .map(|v| sizes[v as usize])
                .iter()
                .sum::<f64>()
                / 3.0;
            faces_for(mesh.triangle_area(t), s)
        })
        .sum()
}

fn remesh_patches(
    mesh: &Mesh,
    params: &RemeshParams,
    start: Instant,
) -> Result<(Mesh, RemeshReport), RemeshError> {
    let n = params
        .patch_resolution
        .unwrap_or(patches::DEFAULT_RESOLUTION);
    let (out, report) = patches::remesh(mesh, params.f, params.target_faces, n)?;
    let quality_after = AngleQuality::of(&out);
    Ok((
        out,
        RemeshReport {
            method: Method::Patches,
            edge_length: 0.0,
            iterations: 0,
            counts: isotropic::Counts::default(),
            lines: LineCounts::default(),
            locked_vertices: 0,
            quality_before: AngleQuality::of(mesh),
            quality_after,
            seconds: start.elapsed().as_secs_f64(),
            sizing: None,
            border_edge: None,
            bake: None,
            patches: Some(report),
        },
    ))
}
