//! `method = "patches"`: the remeshing thesis' Bézier-patch remesher (its §4), rebuilt to
//! be robust (see docs/remeshing.md for what is built and what differs from the thesis).
//!
//! 1. [`cells`]: seeds at a spacing f·(bounding-box diagonal), pseudo-Voronoi cells by
//!    Dijkstra over the edges (thesis §4.2).
//! 2. [`layout`]: the triangular regions as the dual of the cell adjacency, checked to be a
//!    closed manifold triangulation of the input's Euler characteristic; where it is not,
//!    seeds are added in the offending cells and the cells regrown (bounded retries).
//! 3. [`charts`]: the surface cut along the cell borders and each cell mapped onto a regular
//!    polygon by a harmonic map that cannot fold (thesis §4.2 c, §4.3); a cell that is not a
//!    disc fails the layout like an invalid dual.
//! 4. [`quads`]: each region split into three quads, each refined 4×4, Doo–Sabin points
//!    sampled through the charts (thesis §4.4–§4.5).
//! 5. [`bezier`]: 16 biquadratic Bézier patches per quad (thesis §4.5, b₂₀ erratum fixed).
//! 6. [`tessellate`]: n×n samples per patch, shared along patch sides (thesis §4.7).

pub mod bezier;
pub mod cells;
pub mod charts;
pub mod defects;
pub mod layout;
pub mod quads;
pub mod tessellate;

use super::repair::{self, Repairs};
use crate::mesh::Mesh;
use crate::mesh::topology::Topology;
use cells::Graph;
use defects::Defects;
use serde::Serialize;
use std::collections::HashMap;

pub const DEFAULT_F: f64 = 0.1;
/// The smallest seed spacing fraction a recipe may ask for.
pub const MIN_F: f64 = 1e-3;
pub const DEFAULT_RESOLUTION: usize = 2;
pub const MAX_RESOLUTION: usize = 64;
/// Seed retries when the layout is not a valid closed triangulation.
pub const MAX_RETRIES: usize = 12;
/// The sides of `polygons` (closed vertex loops), each once, by its ends (lower first), in
/// the order they first appear, with each side's index in that order: the deterministic
/// numbering the coarse border vertices and the patch sides are made in.
pub(crate) struct UniqueSides {
    pub index: HashMap<(u32, u32), usize>,
    pub ends: Vec<(u32, u32)>,
}

impl UniqueSides {
    pub fn of<const N: usize>(polygons: &[[u32; N]]) -> UniqueSides {
        let mut index = HashMap::with_capacity(polygons.len() * N / 2);
        let mut ends = Vec::new();
        for poly in polygons {
            for k in 0..N {
                let (a, b) = (poly[k], poly[(k + 1) % N]);
                let key = (a.min(b), a.max(b));
                index.entry(key).or_insert_with(|| {
                    ends.push(key);
                    ends.len() - 1
                });
            }
        }
        UniqueSides { index, ends }
    }

    /// The index of the side between `a` and `b`, either way round.
    pub fn of_ends(&self, a: u32, b: u32) -> usize {
        self.index[&(a.min(b), a.max(b))]
    }
}

/// The two counter-clockwise triangles of the quad `q`, split along its shorter diagonal
/// (the thesis' proposal, §4.7; the first diagonal on a tie); `p` gives the positions.
pub(crate) fn split_quad(q: [u32; 4], p: impl Fn(u32) -> glam::DVec3) -> [[u32; 3]; 2] {
    let [a, b, c, d] = q;
    if p(a).distance_squared(p(c)) <= p(b).distance_squared(p(d)) {
        [[a, b, c], [a, c, d]]
    } else {
        [[a, b, d], [b, c, d]]
    }
}

/// Output triangles per region: 3 quads × 16 patches × 2n².
fn faces_per_region(n: usize) -> f64 {
    96.0 * (n * n) as f64
}

#[derive(Debug, Clone, Default, Serialize)]
pub struct PatchesReport {
    pub f: f64,
    pub patch_resolution: usize,
    pub seeds: usize,
    /// Seeds added by the layout check (the thesis' failure, its §6, is caught here).
    pub seeds_added: usize,
    pub retries: usize,
    pub regions: usize,
    pub patches: usize,
    /// Parameter triangles turned over in the cells' harmonic charts: 0 by construction
    /// (positive weights on a convex polygon); counted as a check.
    pub folded_chart_triangles: usize,
    /// The isotropic remesher's last pass, run on the tessellation: triangles turned against
    /// the input triangle closest to their centroid (where a patch bridges a crease narrower
    /// than itself), their repair (`remesh::repair`), and how many are left (0 on smooth
    /// shapes; a few at the narrowest creases of real scans).
    pub turned: Repairs,
    /// Isolated non-manifold defects cut off before the remesh ([`defects`]); all zero on a
    /// manifold input.
    pub defects: Defects,
    pub texcoords_dropped: bool,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PatchesError {
    #[error(
        "method \"patches\" needs a closed mesh; this one has {0} border edges (use method = \"isotropic\", which keeps borders)"
    )]
    Open(usize),
    #[error(
        "method \"patches\" needs a manifold mesh; {edges} non-manifold edges and {vertices} non-manifold vertices remain where the surface touches itself (small parts hanging from such edges are left out, these are not; repair it first, or use method = \"isotropic\")"
    )]
    NonManifold { edges: usize, vertices: usize },
    #[error(
        "method \"patches\" needs consistently oriented triangles; {0} edges are used twice in the same direction (fix the orientation first)"
    )]
    Inconsistent(usize),
    #[error(
        "method \"patches\" found no valid region layout after {retries} retries ({reason}); try a larger f or fewer target_faces"
    )]
    Layout { retries: usize, reason: String },
    #[error(
        "method \"patches\" would make {expected:.0} triangles ({regions} regions), more than the {limit:.0} a remesh may make; choose a larger f, fewer target_faces or a smaller patch_resolution"
    )]
    TooDense {
        regions: usize,
        expected: f64,
        limit: f64,
    },
    #[error("method \"patches\": {0}")]
    Internal(String),
}

/// Remeshes a closed manifold `mesh` with seed spacing fraction `f` (or the `f` that gives
/// about `target_faces`) and n = `resolution`.
pub fn remesh(
    mesh: &Mesh,
    f: Option<f64>,
    target_faces: Option<usize>,
    resolution: usize,
) -> Result<(Mesh, PatchesReport), PatchesError> {
    let texcoords_dropped = mesh.has_texcoords();
    let topo = Topology::new(mesh);
    let cut = defects::without_defects(mesh, &topo);
    let (mesh, topo, defects) = match &cut {
        Some((clean, defects)) => {
            tracing::warn!(
                non_manifold_edges = defects.non_manifold_edges,
                non_manifold_vertices = defects.non_manifold_vertices,
                sheets = defects.sheets_dropped,
                triangles = defects.triangles_dropped,
                "remesh patches: small parts joined to the mesh by non-manifold edges or vertices are left out"
            );
            (clean, Topology::new(clean), *defects)
        }
        None => (mesh, topo, Defects::default()),
    };
    let input = checked_input(mesh, &topo)?;
    let resolution = resolution.max(1);
    let (fraction, seeds) = choose_seeds(&input.graph, mesh, f, target_faces, resolution);
    let initial = seeds.len();
    let (layout, charts, seeds, retries) = valid_layout(&input, seeds)?;
    let expected = layout.regions.len() as f64 * faces_per_region(resolution);
    if expected > super::MAX_OUTPUT_FACES {
        return Err(PatchesError::TooDense {
            regions: layout.regions.len(),
            expected,
            limit: super::MAX_OUTPUT_FACES,
        });
    }
    let fine = quads::build(&layout, &charts);
    let nets = bezier::nets(&fine).map_err(PatchesError::Internal)?;
    let out = tessellate::tessellate(&fine, &nets, resolution);
    let (out, turned) = repair::repair_mesh(mesh, out);
    if turned.left > 0 {
        tracing::warn!(
            triangles = turned.left,
            "remesh patches: output triangles face against the input (creases or thin parts narrower than a patch; a smaller f helps)"
        );
    }
    let report = PatchesReport {
        f: fraction,
        patch_resolution: resolution,
        seeds: seeds.len(),
        seeds_added: seeds.len() - initial,
        retries,
        regions: layout.regions.len(),
        patches: fine.faces.len(),
        folded_chart_triangles: charts.folded,
        turned,
        defects,
        texcoords_dropped,
    };
    Ok((out, report))
}

/// What the layout needs of a checked input: its triangles without degenerate ones, the
/// vertex graph and the Euler characteristic the layout must have.
struct Input<'a> {
    triangles: Vec<[u32; 3]>,
    /// Each of `triangles`' index in the mesh.
    ids: Vec<u32>,
    graph: Graph<'a>,
    euler: i64,
}

/// Refuses an open, non-manifold or inconsistently oriented mesh; otherwise its graph.
fn checked_input<'a>(mesh: &'a Mesh, topo: &Topology) -> Result<Input<'a>, PatchesError> {
    let open = topo.boundary_edges().count();
    if open > 0 {
        return Err(PatchesError::Open(open));
    }
    let nm_edges = topo.non_manifold_edges().count();
    let nm_vertices = topo.non_manifold_vertices().len();
    if nm_edges > 0 || nm_vertices > 0 {
        return Err(PatchesError::NonManifold {
            edges: nm_edges,
            vertices: nm_vertices,
        });
    }
    let flipped = (0..topo.edge_count() as u32)
        .filter(|&e| topo.is_inconsistent_edge(e))
        .count();
    if flipped > 0 {
        return Err(PatchesError::Inconsistent(flipped));
    }
    let (ids, triangles): (Vec<u32>, Vec<[u32; 3]>) = (0..topo.triangle_count() as u32)
        .map(|t| (t, topo.triangle_vertices(t)))
        .filter(|(_, t)| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
        .unzip();
    let n = mesh.positions.len();
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut used = vec![false; n];
    let known = topo.vertex_count().min(n);
    for (v, list) in neighbours.iter_mut().enumerate().take(known) {
        *list = topo.vertex_neighbours(v as u32).to_vec();
    }
    for t in &triangles {
        for &v in t {
            used[v as usize] = true;
        }
    }
    let euler = used.iter().filter(|&&u| u).count() as i64 - topo.edge_count() as i64
        + triangles.len() as i64;
    let graph = Graph {
        positions: &mesh.positions,
        neighbours,
        used,
    };
    Ok(Input {
        triangles,
        ids,
        graph,
        euler,
    })
}

/// The seeds at spacing `f`, or at the spacing whose seed count gives about `target_faces`:
/// regions ≈ 2·cells on a closed surface, so the target asks for target / faces_per_region /
/// 2 cells; the seeding is linear, so a few rounds of a square-root correction are cheap.
fn choose_seeds(
    graph: &Graph<'_>,
    mesh: &Mesh,
    f: Option<f64>,
    target_faces: Option<usize>,
    resolution: usize,
) -> (f64, Vec<u32>) {
    let diag = mesh.bounding_box_diagonal();
    let mut fraction = f.unwrap_or(DEFAULT_F);
    let mut seeds = cells::spaced_seeds(graph, fraction * diag);
    let Some(target) = target_faces else {
        return (fraction, seeds);
    };
    let want = (target as f64 / faces_per_region(resolution) / 2.0).max(4.0);
    // Keep the closest seed count seen (the greedy seeding is not monotone in f).
    let miss = |n: usize| (n as f64 / want).ln().abs();
    let mut best = (fraction, seeds.clone());
    for _ in 0..8 {
        let ratio = (seeds.len() as f64 / want).sqrt();
        if (ratio - 1.0).abs() < 0.05 {
            break;
        }
        fraction *= ratio.clamp(0.25, 4.0);
        seeds = cells::spaced_seeds(graph, fraction * diag);
        if miss(seeds.len()) < miss(best.1.len()) {
            best = (fraction, seeds.clone());
        }
    }
    best
}

/// Grows the cells, builds their dual and the cells' charts until the dual is a valid
/// closed triangulation and every cell a disc: each retry adds a seed in every offending
/// cell, at the cell's vertex farthest from its seed (reading P2). The layout, the charts,
/// the final seeds and the retries.
fn valid_layout(
    input: &Input<'_>,
    mut seeds: Vec<u32>,
) -> Result<(layout::Layout, charts::Charts, Vec<u32>, usize), PatchesError> {
    let mut retries = 0;
    loop {
        let grown = cells::grow(&input.graph, seeds);
        let bad = match layout::dual(&grown, &input.triangles, input.euler) {
            Ok(l) => match charts::build(
                input.graph.positions,
                &input.triangles,
                &input.ids,
                &grown.label,
                &l,
            ) {
                Ok(c) => return Ok((l, c, grown.seeds, retries)),
                Err(bad_cells) => layout::Invalid {
                    bad_cells,
                    reason: "a cell is not a disc".to_string(),
                },
            },
            Err(bad) => bad,
        };
        if retries == MAX_RETRIES {
            return Err(PatchesError::Layout {
                retries,
                reason: bad.reason,
            });
        }
        retries += 1;
        let mut far: Vec<(f64, u32)> = vec![(-1.0, u32::MAX); grown.seeds.len()];
        for (v, &l) in grown.label.iter().enumerate() {
            if l != u32::MAX && grown.distance[v] > far[l as usize].0 {
                far[l as usize] = (grown.distance[v], v as u32);
            }
        }
        seeds = grown.seeds;
        for c in bad.bad_cells {
            let (d, v) = far[c as usize];
            if d > 0.0 && v != u32::MAX && !seeds.contains(&v) {
                seeds.push(v);
            }
        }
    }
}
