//! The texture fix after decimation (decimation thesis §3.3; docs/decimation.md): output
//! triangles whose texture coordinates moved far more than their positions get them
//! recomputed by projecting their corners onto the input triangle they descend from
//! (`Mesh::triangle_origins`) and interpolating that triangle's texture coordinates
//! (eqs. 3.7–3.8). Within one input triangle all texture coordinates come from one chart,
//! so a repaired triangle never straddles a seam.
//!
//! A repaired corner: the thesis gives the repaired triangle its own texture coordinates
//! and wedges (our reading: the thesis leaves it implicit), leaving its neighbours' alone. Done always, that cuts new texture
//! seams into continuous charts: the seamless facefuns face decimated to 26k came out with
//! 12,763 seam edges, each a possible visible crack in the texture. So where every triangle
//! around the corner's wedge descends from one input chart, the wedge itself is corrected,
//! for all its triangles, with the texture coordinates of the closest input point in that
//! chart (continuous, so no seam); the thesis' per-triangle split is kept where the
//! triangles around the corner come from different charts (a real chart boundary) or the
//! closest point lies in another chart.
//!
//! Detection (§3.3, reading R14 in docs/decimation.md): the thesis flags corner i when `10⁻²·‖p̂′ᵢ − p̂ᵢ‖ < ‖t′ᵢ − tᵢ‖`, with
//! positions normalised into [−1, 1]³. Read literally that flags nearly every corner that
//! moved at all (a texture coordinate moves in proportion to its position, with the chart's
//! scale, usually far above 10⁻²), which is the opposite of the stated intent ("a corner whose
//! texture coordinate moved much more than its position"). `detection = "thesis"` keeps the
//! printed rule; the default `"jump"` flags a corner whose texture coordinate is farther from
//! the projection's than `factor` times the move the input triangle's own texture scale
//! predicts for its position change (plus `tolerance`), i.e. texture that moved
//! inconsistently with geometry — which is what a jump across charts looks like.

use super::texture_follow::{WedgeTriangles, charts, uv_at};
use crate::geom::bvh::{DetachedTree, TriangleBvh};
use crate::mesh::{Index, Mesh, Wedge};
use glam::{DVec2, DVec3};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Detection {
    /// Texture moved inconsistently with the position (default; see the module comment).
    #[default]
    Jump,
    /// The thesis' printed rule, `factor·‖Δp̂‖ < ‖Δt‖` (factor 10⁻² there).
    Thesis,
    /// Repair every triangle.
    All,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SeamFixParams {
    pub detection: Detection,
    /// The detection factor: 10⁻² for `thesis`; for `jump`, how many times the expected
    /// texture move the inconsistency may reach (default 1).
    pub factor: Option<f64>,
    /// Texture-space slack of the `jump` rule (about 4 texels of a 4096² image).
    pub tolerance: f64,
}

impl Default for SeamFixParams {
    fn default() -> Self {
        SeamFixParams {
            detection: Detection::Jump,
            factor: None,
            tolerance: 1e-3,
        }
    }
}

impl SeamFixParams {
    pub fn validate(&self) -> Result<(), String> {
        if let Some(f) = self.factor
            && !(f.is_finite() && f >= 0.0)
        {
            return Err(format!("factor must be a finite number ≥ 0, got {f}"));
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return Err(format!("tolerance must be ≥ 0, got {}", self.tolerance));
        }
        Ok(())
    }

    fn factor(&self) -> f64 {
        self.factor.unwrap_or(match self.detection {
            Detection::Thesis => 1e-2,
            _ => 1.0,
        })
    }
}

/// What the step did.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SeamFixReport {
    pub triangles: usize,
    /// Triangles with a corner flagged by the detection rule.
    pub flagged: usize,
    /// Flagged triangles whose texture coordinates were recomputed.
    pub repaired: usize,
    /// Flagged triangles left alone: no texture coordinates, or a degenerate or unknown
    /// input triangle.
    pub skipped: usize,
    /// Repaired corners whose wedge was corrected in place, for all its triangles.
    pub corners_shared: usize,
    /// Repaired corners given a wedge of their own (the thesis' rule; a seam where there may
    /// have been none).
    pub corners_split: usize,
}

/// The projection of (3.7)–(3.8): the barycentric coordinates of `p` projected onto the
/// plane of `tri` (σ_u, σ_v by the dual basis of the edge vectors, the same solution as the
/// 3×3 system with columns u, v, n). `None` if the triangle is degenerate.
fn project(tri: [DVec3; 3], p: DVec3) -> Option<(f64, f64)> {
    let (u, v) = (tri[1] - tri[0], tri[2] - tri[0]);
    let n = u.cross(v);
    let nn = n.length_squared();
    if nn.is_nan() || nn <= 0.0 {
        return None;
    }
    let b1 = v.cross(n) / nn;
    let b2 = n.cross(u) / nn;
    let d = p - tri[0];
    Some((d.dot(b1), d.dot(b2)))
}

/// Repairs `mesh`, a decimation of `input`. `mesh.triangle_origins` index the mesh as
/// loaded; so do `input.triangle_origins` when `input` is itself derived from it (cropped:
/// then each origin is looked up among `input`'s triangles, any piece of a clipped triangle
/// serving, since all lie in its plane with its texture mapping), else `input` is the
/// loaded mesh and origins index it directly.
pub fn seam_fix(mesh: &mut Mesh, input: &Mesh, params: &SeamFixParams) -> SeamFixReport {
    seam_fix_with(mesh, input, params, None)
}

/// Whether [`seam_fix`] against `input` reads a closest-point tree over it
/// ([`reference_tree`]): it corrects wedges in place only on a textured reference with
/// finite positions.
pub fn reads_tree_over(input: &Mesh) -> bool {
    input.has_texcoords() && input.positions.iter().all(|p| p.is_finite())
}

/// The closest-point tree over every triangle of `input` that [`seam_fix`] reads, for
/// [`seam_fix_with`] (the decimation step builds it beside its collapse loop). Positions
/// must be finite ([`reads_tree_over`]).
pub fn reference_tree(input: &Mesh) -> TriangleBvh<'_> {
    TriangleBvh::new(input, (0..input.triangles.len() as u32).collect())
}

/// [`seam_fix`] with [`reference_tree`] over `input` built already, when `tree` is given
/// (detached; it must have been built over `input`).
pub fn seam_fix_with(
    mesh: &mut Mesh,
    input: &Mesh,
    params: &SeamFixParams,
    tree: Option<DetachedTree>,
) -> SeamFixReport {
    let mut report = SeamFixReport {
        triangles: mesh.triangles.len(),
        ..Default::default()
    };
    if !mesh.has_texcoords() || !input.has_texcoords() {
        return report;
    }
    let origins = Origins::new(input);
    let shared = SharedFix::new(mesh, input, &origins, tree);
    let detect = Detect::new(input, params);
    let mut decisions = vec![Decision::Undecided; mesh.wedges.len()];
    let mut splits: Vec<(usize, usize, DVec2)> = Vec::new();
    for t in 0..mesh.triangles.len() {
        let Some(flag) = detect.flag(mesh, t, origins.in_input(mesh, t)) else {
            continue;
        };
        report.flagged += 1;
        let Some(projected) = flag else {
            report.skipped += 1;
            continue;
        };
        for (k, &uv) in projected.iter().enumerate() {
            let w = mesh.triangles[t][k];
            if matches!(decisions[w as usize], Decision::Undecided) {
                decisions[w as usize] = shared.uv(w).map_or(Decision::Split, Decision::Shared);
            }
            match decisions[w as usize] {
                Decision::Shared(_) => report.corners_shared += 1,
                _ => {
                    splits.push((t, k, uv));
                    report.corners_split += 1;
                }
            }
        }
        report.repaired += 1;
    }
    drop(shared);
    apply(mesh, decisions, splits);
    report
}

/// What becomes of one wedge of the result.
#[derive(Clone, Copy)]
enum Decision {
    Undecided,
    /// Corrected in place, for all its triangles.
    Shared(DVec2),
    /// Each repaired corner gets a wedge of its own.
    Split,
}

/// Applies the decisions and the split corners' texture coordinates, once every decision
/// is taken, each on the decimated mesh as it was.
fn apply(mesh: &mut Mesh, decisions: Vec<Decision>, splits: Vec<(usize, usize, DVec2)>) {
    for (w, decision) in decisions.into_iter().enumerate() {
        if let Decision::Shared(uv) = decision {
            mesh.texcoords.push(uv);
            mesh.wedges[w].texcoord = Some((mesh.texcoords.len() - 1) as Index);
        }
    }
    for (t, k, uv) in splits {
        let old = mesh.wedges[mesh.triangles[t][k] as usize];
        mesh.texcoords.push(uv);
        mesh.wedges.push(Wedge {
            vertex: old.vertex,
            texcoord: Some((mesh.texcoords.len() - 1) as Index),
            normal: old.normal,
        });
        mesh.triangles[t][k] = (mesh.wedges.len() - 1) as Index;
    }
    mesh.compact();
}

/// Where the result's triangle origins are among the input's triangles: the same index
/// when the input is the loaded mesh, else looked up through the input's own origins.
struct Origins {
    by_origin: Option<Vec<u32>>,
}

impl Origins {
    fn new(input: &Mesh) -> Self {
        let by_origin = (!input.triangle_origins.is_empty()).then(|| {
            let size = input
                .triangle_origins
                .iter()
                .max()
                .map_or(0, |&m| m as usize + 1);
            let mut map = vec![u32::MAX; size];
            for (t, &o) in input.triangle_origins.iter().enumerate() {
                map[o as usize] = t as u32;
            }
            map
        });
        Origins { by_origin }
    }

    /// The input triangle that `mesh`'s triangle `t` descends from (`usize::MAX`: none).
    fn in_input(&self, mesh: &Mesh, t: usize) -> usize {
        let o = mesh.triangle_origin(t) as usize;
        match &self.by_origin {
            Some(map) => map.get(o).map_or(usize::MAX, |&r| r as usize),
            None => o,
        }
    }
}

/// For in-place repairs: the input's charts, a closest-point index over it, and the
/// triangles around each wedge of the result.
struct SharedFix<'a> {
    mesh: &'a Mesh,
    input: &'a Mesh,
    origins: &'a Origins,
    charts: Vec<u32>,
    bvh: Option<TriangleBvh<'a>>,
    around: WedgeTriangles,
}

impl<'a> SharedFix<'a> {
    fn new(
        mesh: &'a Mesh,
        input: &'a Mesh,
        origins: &'a Origins,
        tree: Option<DetachedTree>,
    ) -> Self {
        let (charts, bvh) = match tree {
            Some(tree) => (charts(input), Some(TriangleBvh::over(input, tree))),
            // The charts are sequential; they are made beside the tree, whose build is
            // parallel.
            None => rayon::join(
                || charts(input),
                || reads_tree_over(input).then(|| reference_tree(input)),
            ),
        };
        SharedFix {
            mesh,
            input,
            origins,
            charts,
            bvh,
            around: WedgeTriangles::of(mesh),
        }
    }

    /// Wedge `w`'s texture coordinates corrected in place: those of the closest input point,
    /// when all its triangles descend from one input chart and that point lies in it.
    fn uv(&self, w: Index) -> Option<DVec2> {
        let bvh = self.bvh.as_ref()?;
        let mut origins = self
            .around
            .of_wedge(w)
            .iter()
            .map(|&t| self.origins.in_input(self.mesh, t as usize));
        let first = origins.next()?;
        let chart = *self.charts.get(first)?;
        if !origins.all(|o| self.charts.get(o) == Some(&chart)) {
            return None;
        }
        let p = self.mesh.positions[self.mesh.wedges[w as usize].vertex as usize];
        if !p.is_finite() {
            return None;
        }
        let start = bvh.hit_on(p, first as u32);
        let hit = bvh.closest(p, Some(start))?;
        (self.charts[hit.triangle as usize] == chart)
            .then(|| uv_at(self.input, &hit))
            .flatten()
    }
}

/// The detection rule with its settings resolved.
struct Detect<'a> {
    input: &'a Mesh,
    params: &'a SeamFixParams,
    factor: f64,
    /// Half the input's largest box side: positions are normalised into [−1, 1]³
    /// (footnote 3 of §3.3).
    half: f64,
}

impl<'a> Detect<'a> {
    fn new(input: &'a Mesh, params: &'a SeamFixParams) -> Self {
        let (lo, hi) = input.bounding_box().unwrap_or((DVec3::ZERO, DVec3::ONE));
        Detect {
            input,
            params,
            factor: params.factor(),
            half: ((hi - lo).max_element() * 0.5).max(f64::MIN_POSITIVE),
        }
    }

    /// Whether triangle `t` of `mesh`, descending from input triangle `o`, is flagged:
    /// `None` when it is not (or `o` is unknown or has no texture coordinates), else its
    /// corners projected into `o`'s texture (`None` inside when `o` is degenerate).
    fn flag(&self, mesh: &Mesh, t: usize, o: usize) -> Option<Option<Vec<DVec2>>> {
        let input = self.input;
        if o >= input.triangles.len() {
            return None;
        }
        let orig_p = input.triangle_positions(o);
        let a = input.triangles[o].map(|w| input.wedge_texcoord(w));
        let orig_t = [a[0]?, a[1]?, a[2]?];
        let now_p = mesh.triangle_positions(t);
        let now_t = mesh.triangles[t].map(|w| mesh.wedge_texcoord(w));
        let projected: Option<Vec<DVec2>> = now_p
            .iter()
            .map(|&p| {
                project(orig_p, p).map(|(su, sv)| {
                    orig_t[0] + su * (orig_t[1] - orig_t[0]) + sv * (orig_t[2] - orig_t[0])
                })
            })
            .collect();
        let scale = self.texture_scale(orig_p, orig_t);
        let (factor, half, params) = (self.factor, self.half, self.params);
        let flagged = (0..3).any(|i| {
            let Some(tn) = now_t[i] else { return true };
            let moved = (now_p[i] - orig_p[i]).length() / half;
            match params.detection {
                Detection::All => true,
                Detection::Thesis => factor * moved < (tn - orig_t[i]).length(),
                Detection::Jump => projected.as_ref().is_some_and(|pr| {
                    (tn - pr[i]).length() > factor * scale * moved + params.tolerance
                }),
            }
        });
        flagged.then_some(projected)
    }

    /// Texture scale of an input triangle: texture length per unit of normalised length.
    fn texture_scale(&self, p: [DVec3; 3], uv: [DVec2; 3]) -> f64 {
        let geo_area = (p[1] - p[0]).cross(p[2] - p[0]).length() / self.half / self.half;
        let uv_area = {
            let (a, b) = (uv[1] - uv[0], uv[2] - uv[0]);
            (a.x * b.y - a.y * b.x).abs()
        };
        if geo_area > 0.0 {
            (uv_area / geo_area).sqrt()
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::grid;

    #[test]
    fn projection_is_identity_at_the_corners() {
        let tri = [DVec3::ZERO, DVec3::X, DVec3::Y];
        assert_eq!(project(tri, DVec3::X), Some((1.0, 0.0)));
        assert_eq!(project(tri, DVec3::new(0.0, 1.0, 5.0)), Some((0.0, 1.0)));
        assert_eq!(project([DVec3::ZERO; 3], DVec3::X), None);
    }

    #[test]
    fn untouched_mesh_is_not_flagged_and_all_is_identity() {
        let input = grid(4, 4);
        let mut m = input.clone();
        let r = seam_fix(&mut m, &input, &SeamFixParams::default());
        assert_eq!(r.flagged, 0);
        assert_eq!(m, input);
        // Repairing everything with unmoved corners gives the same coordinates.
        let r = seam_fix(
            &mut m,
            &input,
            &SeamFixParams {
                detection: Detection::All,
                ..Default::default()
            },
        );
        assert_eq!(r.repaired, input.triangles.len());
        for t in 0..m.triangles.len() {
            for k in 0..3 {
                let a = m.wedge_texcoord(m.triangles[t][k]).unwrap();
                let b = input.wedge_texcoord(input.triangles[t][k]).unwrap();
                assert!((a - b).length() < 1e-12);
            }
        }
    }

    #[test]
    fn a_jumped_texture_coordinate_is_repaired() {
        let input = grid(4, 4);
        let mut m = input.clone();
        // One wedge's texture coordinate jumps far away (as if taken from another chart).
        let w = m.triangles[5][1] as usize;
        let tc = m.wedges[w].texcoord.unwrap() as usize;
        m.texcoords[tc] += DVec2::new(0.5, 0.0);
        let r = seam_fix(&mut m, &input, &SeamFixParams::default());
        assert!(
            r.repaired >= 1 && r.repaired < input.triangles.len(),
            "{r:?}"
        );
        let fixed = m.wedge_texcoord(m.triangles[5][1]).unwrap();
        let want = input.wedge_texcoord(input.triangles[5][1]).unwrap();
        assert!((fixed - want).length() < 1e-12);
    }

    /// The tree over the reference built before (as the decimation step does, beside its
    /// collapse loop) repairs exactly as the tree `seam_fix` builds itself, wedges
    /// corrected in place through it included.
    #[test]
    fn a_tree_built_before_repairs_the_same() {
        let input = grid(6, 6);
        let mut m = input.clone();
        for (i, p) in m.positions.iter_mut().enumerate() {
            p.z += 0.01 * (i % 3) as f64;
        }
        for t in [5, 17, 30] {
            let tc = m.wedges[m.triangles[t][1] as usize].texcoord.unwrap() as usize;
            m.texcoords[tc] += DVec2::new(0.4, 0.1);
        }
        let mut own = m.clone();
        let own_report = seam_fix(&mut own, &input, &SeamFixParams::default());
        assert!(own_report.corners_shared > 0, "{own_report:?}");
        assert!(reads_tree_over(&input));
        let tree =
            std::thread::scope(|s| s.spawn(|| reference_tree(&input).detach()).join().unwrap());
        let given_report = seam_fix_with(&mut m, &input, &SeamFixParams::default(), Some(tree));
        assert_eq!(given_report, own_report);
        assert_eq!(m, own);
    }
}
