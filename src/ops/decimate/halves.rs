//! Edge collapse in two halves on two cores, then over the whole (`halves` in
//! [`super::DecimateParams`]). The collapse loop is sequential and is most of the step's
//! time, so on a scanner-sized scan the second core would mostly wait.
//!
//! 1. The triangles are split at the median centroid along the bounding box's longest axis.
//!    The vertices used by both halves are the *cut*.
//! 2. Each half is decimated as a mesh of its own (in parallel, `rayon::join`) to its half
//!    of [`STAGE_FACTOR`] × the target; while its loop runs, a half keeps only what its
//!    output reads back from the whole mesh (`Part`). The cut is a border of each half, and
//!    `boundary = "fixed"` holds border vertices still, so the cut stays exactly as it was
//!    (positions, wedges and their attributes).
//! 3. The two results are stitched back together at the cut: its vertices are found by
//!    their bit-identical positions, and their wedges by their identical attributes.
//!    Neither half changed either.
//! 4. The stitched mesh is decimated to the target with [`super::decimate_with_origin`].
//!    The flip guard then holds each triangle against its triangle in this step's input,
//!    as one pass would.
//!
//! Measured in docs/decimation.md ("Two halves in parallel"):
//! - the audit of every guarantee is clean on all six textured scans;
//! - mean and RMS distance and colour deviation are lower than the single pass's on all
//!   six;
//! - the 400k coral takes 1.70 × meshoptimizer's time (criterion), against 2.72 × in one
//!   pass; the 400k face 1.95 × against 3.8 ×.
//!
//! The result does not depend on the thread count: the split and each half's decimation are
//! deterministic, and with one thread the halves simply run one after the other.

use super::{
    CollapseInput, DecimateParams, DecimateReport, Halves, decimate_input,
    decimate_with_origin_beside,
};
use crate::mesh::Mesh;
use crate::mesh::model::{Index, Wedge};
use rustc_hash::FxHashMap;

/// The halves decimate to this many times the target (together); the whole goes from there.
/// Of 1.5 and 2, 1.5 gave the lower distance (docs/decimation.md).
pub const STAGE_FACTOR: f64 = 1.5;

/// `halves = "auto"` splits meshes of at least this many triangles (and more than
/// 2 × [`STAGE_FACTOR`] × the target). Below it the split and the second set-up cost about
/// what the second core saves. From about 80,000 triangles the halves would cost no more CPU
/// than one pass, but on the USNM coral (100k) the face-scan recipe's maximum distance rose
/// by half (one point) and its RMS by 0.45 %, and quality may not drop for speed, so the
/// limit stays here (docs/decimation.md, "Issue #27").
pub const AUTO_MIN_FACES: usize = 150_000;

/// Whether `params` ask for (or allow) the halves on `mesh`, and the target they need.
pub fn wanted(mesh: &Mesh, params: &DecimateParams) -> Option<usize> {
    let target = params.target_faces?;
    let applicable = params.method == super::Method::EdgeCollapse
        && params.boundary == crate::ops::border::Border::Fixed
        && params.max_error.is_none();
    let big_enough = mesh.triangles.len() as f64 > 2.0 * STAGE_FACTOR * target as f64;
    match params.halves {
        Halves::Off => None,
        Halves::On => (applicable && big_enough).then_some(target),
        Halves::Auto => {
            (applicable && big_enough && mesh.triangles.len() >= AUTO_MIN_FACES).then_some(target)
        }
    }
}

const NONE: Index = Index::MAX;

/// One half as a mesh of its own, and where its vertices, texture coordinates and normals
/// come from in the whole mesh. Both halves' working meshes are alive at once, at the step's
/// memory peak, and each has its own copies of what its collapse loop reads; so while the
/// loop runs the half keeps only its wedges and triangle origins, and the values its output
/// needs are read back from the whole mesh ([`CollapseInput`]).
struct Part<'w> {
    whole: &'w Mesh,
    mesh: Mesh,
    /// The whole mesh's index of each vertex, texture coordinate and normal of the half.
    vertices: Vec<Index>,
    texcoords: Vec<Index>,
    normals: Vec<Index>,
}

impl Part<'_> {
    /// The half's vertex positions and colours, texture coordinates, normals and triangle
    /// materials, read from the whole mesh.
    fn fill(&mut self) {
        fn gather<T: Copy>(indices: &[Index], values: &[T]) -> Vec<T> {
            indices.iter().map(|&i| values[i as usize]).collect()
        }
        let (w, m) = (self.whole, &mut self.mesh);
        m.positions = gather(&self.vertices, &w.positions);
        if !w.colors.is_empty() {
            m.colors = gather(&self.vertices, &w.colors);
        }
        m.texcoords = gather(&self.texcoords, &w.texcoords);
        m.normals = gather(&self.normals, &w.normals);
        if !w.triangle_materials.is_empty() {
            m.triangle_materials = gather(&m.triangle_origins, &w.triangle_materials);
        }
    }
}

impl CollapseInput for Part<'_> {
    fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    fn thin(&mut self) {
        let m = &mut self.mesh;
        m.positions = Vec::new();
        m.colors = Vec::new();
        m.texcoords = Vec::new();
        m.normals = Vec::new();
        m.triangles = Vec::new();
        m.triangle_materials = Vec::new();
        // What was just dropped, and the set-up's temporaries (the split's order, the maps
        // that built the half), are free chunks amid the arenas, each still resident: without
        // this they kept the peak where dropping them had taken it from (coral400k: 171 MB,
        // 36 MB of it free).
        crate::memory::release_freed();
    }

    fn restore(&mut self) {
        self.fill();
    }
}

/// The triangles of `mesh` with `side[t] == keep`, as a mesh of their own: only what they
/// use is copied, in the order of first use. Each triangle's origin is its index in `mesh`.
fn part<'w>(mesh: &'w Mesh, side: &[bool], keep: bool) -> Part<'w> {
    let faces = side.iter().filter(|&&s| s == keep).count();
    let mut m = Mesh {
        materials: mesh.materials.clone(),
        triangles: Vec::with_capacity(faces),
        triangle_origins: Vec::with_capacity(faces),
        ..Mesh::default()
    };
    let (mut vertices, mut texcoords, mut normals) = (Vec::new(), Vec::new(), Vec::new());
    let mut wedge_map = vec![NONE; mesh.wedges.len()];
    let mut vertex_map = vec![NONE; mesh.positions.len()];
    let mut texcoord_map = vec![NONE; mesh.texcoords.len()];
    let mut normal_map = vec![NONE; mesh.normals.len()];
    // The new index of element `i` (`fresh` if this is its first use).
    let new_index = |map: &mut [Index], i: Index, next: usize| -> (Index, bool) {
        let fresh = map[i as usize] == NONE;
        if fresh {
            map[i as usize] = next as Index;
        }
        (map[i as usize], fresh)
    };
    for t in (0..mesh.triangles.len()).filter(|&t| side[t] == keep) {
        let triangle = mesh.triangles[t].map(|w| {
            let (new_w, fresh) = new_index(&mut wedge_map, w, m.wedges.len());
            if fresh {
                let wedge = mesh.wedges[w as usize];
                let (vertex, new_v) = new_index(&mut vertex_map, wedge.vertex, vertices.len());
                if new_v {
                    vertices.push(wedge.vertex);
                }
                let texcoord = wedge.texcoord.map(|i| {
                    let (x, new_x) = new_index(&mut texcoord_map, i, texcoords.len());
                    if new_x {
                        texcoords.push(i);
                    }
                    x
                });
                let normal = wedge.normal.map(|i| {
                    let (x, new_x) = new_index(&mut normal_map, i, normals.len());
                    if new_x {
                        normals.push(i);
                    }
                    x
                });
                m.wedges.push(Wedge {
                    vertex,
                    texcoord,
                    normal,
                });
            }
            new_w
        });
        m.triangles.push(triangle);
        m.triangle_origins.push(t as Index);
    }
    // The half lives as long as its decimation: no spare room.
    m.wedges.shrink_to_fit();
    vertices.shrink_to_fit();
    texcoords.shrink_to_fit();
    normals.shrink_to_fit();
    let mut part = Part {
        whole: mesh,
        mesh: m,
        vertices,
        texcoords,
        normals,
    };
    part.fill();
    part
}

type PositionKey = [u64; 3];

fn key(p: glam::DVec3) -> PositionKey {
    // `+ 0.0` makes −0 and +0 one key.
    [p.x + 0.0, p.y + 0.0, p.z + 0.0].map(f64::to_bits)
}

/// A wedge's attributes, exactly.
type WedgeKey = (Index, Option<[u64; 2]>, Option<PositionKey>);

fn wedge_key(m: &Mesh, vertex: Index, w: &Wedge) -> WedgeKey {
    (
        vertex,
        w.texcoord
            .map(|t| m.texcoords[t as usize].to_array().map(f64::to_bits)),
        w.normal.map(|n| key(m.normals[n as usize])),
    )
}

/// The cut's vertices of `m` by position; `None` if a cut position is missing or appears
/// twice (which the rules above exclude; the caller then decimates in one pass).
fn cut_vertices(
    m: &Mesh,
    cut: &FxHashMap<PositionKey, ()>,
) -> Option<FxHashMap<PositionKey, Index>> {
    let mut found = FxHashMap::default();
    for (v, p) in m.positions.iter().enumerate() {
        let k = key(*p);
        if cut.contains_key(&k) && found.insert(k, v as Index).is_some() {
            tracing::debug!(vertex = v, "two vertices of a half at one cut position");
            return None;
        }
    }
    if found.len() != cut.len() {
        tracing::debug!(
            found = found.len(),
            cut = cut.len(),
            "cut vertices missing in a half"
        );
        return None;
    }
    Some(found)
}

/// `a` and `b` as one mesh, joined at the cut (positions in `cut`); the result's triangle
/// origins are those of `a` and `b`. `None` if the cut cannot be matched exactly.
fn stitch(a: Mesh, b: &Mesh, cut: &FxHashMap<PositionKey, ()>) -> Option<Mesh> {
    let in_a = cut_vertices(&a, cut)?;
    let in_b = cut_vertices(b, cut)?;
    let mut m = a;
    let shared = m.positions.len() as Index;
    let mut vertex_map = vec![NONE; b.positions.len()];
    for (k, &vb) in &in_b {
        vertex_map[vb as usize] = in_a[k];
    }
    for (v, p) in b.positions.iter().enumerate() {
        if vertex_map[v] == NONE {
            vertex_map[v] = m.positions.len() as Index;
            m.positions.push(*p);
            if !b.colors.is_empty() {
                m.colors.push(b.colors[v]);
            }
        }
    }
    // A wedge of a cut vertex used on both sides is the same in both halves (neither changed
    // it): B's copy becomes A's. Matched by value, so two input wedges of one cut vertex
    // with bit-identical attributes, one used on each side, would become one; the input's
    // loader makes wedges of distinct texture-coordinate indices, so this needs a scan that
    // repeats a texture coordinate at one vertex across a seam.
    let mut a_cut_wedges: FxHashMap<WedgeKey, Index> = FxHashMap::default();
    for (i, w) in m.wedges.iter().enumerate() {
        if w.vertex < shared && in_a.contains_key(&key(m.positions[w.vertex as usize])) {
            a_cut_wedges
                .entry(wedge_key(&m, w.vertex, w))
                .or_insert(i as Index);
        }
    }
    let (t0, n0) = (m.texcoords.len() as Index, m.normals.len() as Index);
    m.texcoords.extend_from_slice(&b.texcoords);
    m.normals.extend_from_slice(&b.normals);
    let mut wedge_map = Vec::with_capacity(b.wedges.len());
    for w in &b.wedges {
        let vertex = vertex_map[w.vertex as usize];
        let matched = (vertex < shared)
            .then(|| a_cut_wedges.get(&wedge_key(b, vertex, w)).copied())
            .flatten();
        wedge_map.push(match matched {
            Some(aw) => aw,
            // New vertices' wedges, and a cut vertex's wedges that only B's triangles use
            // (a texture seam that meets the cut there).
            None => {
                m.wedges.push(Wedge {
                    vertex,
                    texcoord: w.texcoord.map(|t| t + t0),
                    normal: w.normal.map(|n| n + n0),
                });
                (m.wedges.len() - 1) as Index
            }
        });
    }
    m.triangles
        .extend(b.triangles.iter().map(|t| t.map(|w| wedge_map[w as usize])));
    m.triangle_materials
        .extend_from_slice(&b.triangle_materials);
    m.triangle_origins.extend_from_slice(&b.triangle_origins);
    m.compact();
    Some(m)
}

/// What the halves did, for the step's report.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct HalvesReport {
    /// Triangles of each half before, and after its decimation.
    pub faces_before: [usize; 2],
    pub faces_after: [usize; 2],
    /// Vertices shared by the halves (held still until the whole is decimated).
    pub cut_vertices: usize,
    /// Collapses in the halves; the rest of the step's collapses are over the whole.
    pub collapses: [usize; 2],
}

/// Decimates `mesh` in halves, then as a whole (see the module comment). `None` when the
/// cut could not be stitched exactly; the caller then decimates in one pass. `beside` runs
/// beside the final pass's collapse loop ([`super::decimate_beside`]).
pub fn run(
    mesh: &Mesh,
    params: &DecimateParams,
    target: usize,
    beside: &(dyn Fn() + Sync),
) -> Option<(Mesh, DecimateReport)> {
    let first_half = split(mesh)?;
    let cut = cut_positions(mesh, &first_half)?;
    let stage = (target as f64 * STAGE_FACTOR).round() as usize;
    let half_params = |share: usize| DecimateParams {
        target_faces: Some(share),
        halves: Halves::Off,
        ..params.clone()
    };
    let one_half = |keep: bool, share: usize| {
        let half = part(mesh, &first_half, keep);
        let faces = half.mesh.triangles.len();
        // The half's error is a fraction of its own diagonal; make it one of the whole's.
        let scale =
            half.mesh.bounding_box_diagonal() / mesh.bounding_box_diagonal().max(f64::MIN_POSITIVE);
        let (out, report) = decimate_input(half, &half_params(share)).ok()?;
        Some((out, report, faces, scale))
    };
    // The second half may run on another thread: under the step's span, so that its log
    // lines name the step (and the daemon's job) as the first half's do.
    let span = tracing::Span::current();
    let (a, b) = rayon::join(
        || one_half(true, stage / 2),
        || span.in_scope(|| one_half(false, stage - stage / 2)),
    );
    let ((a, ra, fa, sa), (b, rb, fb, sb)) = (a?, b?);
    let halves = HalvesReport {
        faces_before: [fa, fb],
        faces_after: [a.triangles.len(), b.triangles.len()],
        cut_vertices: cut.len(),
        collapses: [ra.collapses, rb.collapses],
    };
    let stitched = stitch(a, &b, &cut)?;
    drop(b);
    let (mut out, mut report) =
        decimate_with_origin_beside(&stitched, &half_params(target), Some(mesh), beside).ok()?;
    drop(stitched);
    // Origins index `mesh`; the step's output indexes what `mesh`'s own origins do.
    for o in &mut out.triangle_origins {
        *o = mesh.triangle_origin(*o as usize);
    }
    add_halves(&mut report, [(&ra, sa), (&rb, sb)], cut.len());
    report.halves = Some(halves);
    Some((out, report))
}

/// Which triangles are in the first half: those whose centroid is below the median along
/// the longest side of the bounding box (ties by index).
fn split(mesh: &Mesh) -> Option<Vec<bool>> {
    let n = mesh.triangles.len();
    let (lo, hi) = mesh.bounding_box()?;
    let axis = (hi - lo).max_position();
    let centroid = |t: usize| {
        let [a, b, c] = mesh.triangle_positions(t);
        (a[axis] + b[axis] + c[axis]) / 3.0
    };
    let mut order: Vec<(f64, u32)> = (0..n).map(|t| (centroid(t), t as u32)).collect();
    order.select_nth_unstable_by(n / 2, |x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    let mut first_half = vec![false; n];
    for &(_, t) in &order[..n / 2] {
        first_half[t as usize] = true;
    }
    Some(first_half)
}

/// The positions of the vertices both halves use, or `None` when two of them share a
/// position (the stitch could not tell them apart).
fn cut_positions(mesh: &Mesh, first_half: &[bool]) -> Option<FxHashMap<PositionKey, ()>> {
    let mut used_by = vec![0u8; mesh.positions.len()];
    for (t, &first) in first_half.iter().enumerate() {
        let bit = if first { 1 } else { 2 };
        for v in mesh.triangle_vertices(t) {
            used_by[v as usize] |= bit;
        }
    }
    let cut: FxHashMap<PositionKey, ()> = (0..mesh.positions.len())
        .filter(|&v| used_by[v] == 3)
        .map(|v| (key(mesh.positions[v]), ()))
        .collect();
    (cut.len() == used_by.iter().filter(|&&u| u == 3).count()).then_some(cut)
}

/// Adds the halves' counts to the whole's `report`: their collapses, evaluations and
/// refusals, the largest error (each half's scaled to the whole's diagonal), and the vertex
/// classes as the halves saw them (the `cut` vertices counted once, as fixed).
fn add_halves(report: &mut DecimateReport, halves: [(&DecimateReport, f64); 2], cut: usize) {
    let [(ra, sa), (rb, sb)] = halves;
    report.collapses += ra.collapses + rb.collapses;
    report.evaluations += ra.evaluations + rb.evaluations;
    report.ill_conditioned += ra.ill_conditioned + rb.ill_conditioned;
    report.refused.add(&ra.refused);
    report.refused.add(&rb.refused);
    report.error_reached = report
        .error_reached
        .max(ra.error_reached * sa)
        .max(rb.error_reached * sb);
    report.interior_vertices = ra.interior_vertices + rb.interior_vertices;
    report.border_vertices = ra.border_vertices + rb.border_vertices;
    report.seam_vertices = ra.seam_vertices + rb.seam_vertices;
    report.fixed_vertices = (ra.fixed_vertices + rb.fixed_vertices).saturating_sub(cut);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::grid;
    use crate::ops::decimate::Method;
    use glam::DVec3;

    /// A bumpy textured grid with a normal per vertex, colours and two materials in bands,
    /// and the side of each triangle (left or right of the middle).
    fn grid_with_everything(n: usize) -> (Mesh, Vec<bool>) {
        let mut m = grid(n, n);
        for p in &mut m.positions {
            p.z = 0.3 * ((p.x * 0.4).sin() * (p.y * 0.3).cos());
        }
        m.normals = m
            .positions
            .iter()
            .map(|p| (*p + DVec3::Z).normalize())
            .collect();
        for w in &mut m.wedges {
            w.normal = Some(w.vertex);
        }
        m.colors = (0..m.positions.len())
            .map(|v| [v as u8, 1, 2, 255])
            .collect();
        m.materials = vec![Default::default(), Default::default()];
        let nt = m.triangles.len();
        m.triangle_materials = (0..nt).map(|t| (t * 3 / nt % 2) as Index).collect();
        let half = n as f64 / 2.0;
        let side = (0..m.triangles.len())
            .map(|t| m.triangle_positions(t).iter().map(|p| p.x).sum::<f64>() / 3.0 < half)
            .collect();
        (m, side)
    }

    /// While its collapse loop runs a half holds only its wedges and triangle origins; what
    /// it gives back is what it held.
    #[test]
    fn a_thinned_half_holds_only_wedges_and_origins_and_restores_the_rest() {
        let (m, side) = grid_with_everything(12);
        let mut half = part(&m, &side, true);
        let before = half.mesh.clone();
        assert!(!before.normals.is_empty() && !before.colors.is_empty());
        half.thin();
        let thin = &half.mesh;
        assert_eq!(thin.positions.capacity(), 0);
        assert_eq!(thin.texcoords.capacity(), 0);
        assert_eq!(thin.normals.capacity(), 0);
        assert_eq!(thin.colors.capacity(), 0);
        assert_eq!(thin.triangles.capacity(), 0);
        assert_eq!(thin.triangle_materials.capacity(), 0);
        assert_eq!(thin.wedges, before.wedges);
        assert_eq!(thin.triangle_origins, before.triangle_origins);
        half.restore();
        // Everything but the triangles, which the output does not read.
        let restored = Mesh {
            triangles: before.triangles.clone(),
            ..half.mesh.clone()
        };
        assert_eq!(restored, before);
        // No spare room in what stays alive beside the other half.
        assert_eq!(before.wedges.capacity(), before.wedges.len());
        assert_eq!(before.triangles.capacity(), before.triangles.len());
    }

    /// Decimating a half thinned gives exactly what decimating a copy of it does.
    #[test]
    fn a_thinned_half_decimates_as_its_copy_does() {
        let (m, side) = grid_with_everything(16);
        let params = DecimateParams {
            method: Method::EdgeCollapse,
            target_faces: Some(60),
            boundary: crate::ops::border::Border::Fixed,
            halves: Halves::Off,
            ..Default::default()
        };
        for keep in [true, false] {
            let half = part(&m, &side, keep);
            let copy = half.mesh.clone();
            let (expected, expected_report) =
                crate::ops::decimate::decimate_with_origin(&copy, &params, None).unwrap();
            let (out, report) = decimate_input(half, &params).unwrap();
            assert!(report.collapses > 0);
            assert_eq!(out, expected);
            assert_eq!(report, expected_report);
        }
    }
}
