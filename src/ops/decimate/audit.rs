//! Checks of the decimation guarantees against the input (used by tests, the example
//! binary and benchmarks): topology counts before and after, flipped and zero-area
//! faces, texture coordinates that left their chart, seam vertices that left their seam,
//! and border edges that are not input border edges.

use crate::geom::segment_distance;
use crate::mesh::Mesh;
use crate::mesh::topology::{Topology, TopologyCounts};
use glam::{DVec2, DVec3};
use serde::Serialize;
use std::collections::HashSet;

#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Audit {
    pub before: TopologyCounts,
    pub after: TopologyCounts,
    /// Output triangles whose normal points against their input triangle's.
    pub flipped_faces: usize,
    /// Output triangles with (near) zero area (height below 1e-9 of the box diagonal).
    pub zero_area_faces: usize,
    /// Output triangles with a corner texture coordinate outside the texture chart of
    /// their input triangle (tolerance `CHART_TOLERANCE` in texture units).
    pub chart_jumps: usize,
    /// Output vertices on a texture seam that do not lie on an input seam edge.
    pub seam_vertices_off_seam: usize,
    /// Output border edges whose end positions are not both on input border edges.
    pub border_edges_off_border: usize,
}

/// Texture-space tolerance of the chart test (about 4 texels of a 4096² image).
pub const CHART_TOLERANCE: f64 = 1e-3;

fn key(p: DVec3) -> [u64; 3] {
    [
        (p.x + 0.0).to_bits(),
        (p.y + 0.0).to_bits(),
        (p.z + 0.0).to_bits(),
    ]
}

/// Charts: triangles joined across manifold edges that are not texture seams (also the
/// remesher's face labels).
pub fn charts(mesh: &Mesh, topo: &Topology) -> Vec<u32> {
    let n = mesh.triangles.len();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            p[x as usize] = p[p[x as usize] as usize];
            x = p[x as usize];
        }
        x
    }
    for e in 0..topo.edge_count() as u32 {
        let sides = topo.edge_sides(e);
        if sides.len() == 2 && !topo.is_texture_seam_edge(e) {
            let (a, b) = (
                find(&mut parent, sides[0] / 3),
                find(&mut parent, sides[1] / 3),
            );
            if a != b {
                parent[a.max(b) as usize] = a.min(b);
            }
        }
    }
    (0..n as u32).map(|t| find(&mut parent, t)).collect()
}

/// A uniform grid over the input's texture triangles for point location.
struct UvGrid {
    lo: DVec2,
    cell: f64,
    nx: usize,
    ny: usize,
    cells: Vec<Vec<u32>>,
}

impl UvGrid {
    fn new(mesh: &Mesh) -> Option<UvGrid> {
        if mesh.texcoords.is_empty() {
            return None;
        }
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for t in &mesh.texcoords {
            lo = lo.min(*t);
            hi = hi.max(*t);
        }
        let n = (mesh.triangles.len() as f64).sqrt().ceil().max(1.0) as usize;
        let size = (hi - lo).max(DVec2::splat(1e-12));
        let cell = (size.x.max(size.y) / n as f64).max(1e-12);
        let nx = ((size.x / cell).ceil() as usize).clamp(1, 4096);
        let ny = ((size.y / cell).ceil() as usize).clamp(1, 4096);
        let mut grid = UvGrid {
            lo,
            cell,
            nx,
            ny,
            cells: vec![Vec::new(); nx * ny],
        };
        for t in 0..mesh.triangles.len() {
            let Some(uv) = uvs(mesh, t) else { continue };
            let a = uv[0].min(uv[1]).min(uv[2]) - DVec2::splat(CHART_TOLERANCE);
            let b = uv[0].max(uv[1]).max(uv[2]) + DVec2::splat(CHART_TOLERANCE);
            let (i0, j0) = grid.index(a);
            let (i1, j1) = grid.index(b);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    grid.cells[j * nx + i].push(t as u32);
                }
            }
        }
        Some(grid)
    }
    fn index(&self, p: DVec2) -> (usize, usize) {
        let q = (p - self.lo) / self.cell;
        (
            (q.x.floor().max(0.0) as usize).min(self.nx - 1),
            (q.y.floor().max(0.0) as usize).min(self.ny - 1),
        )
    }
}

fn uvs(mesh: &Mesh, t: usize) -> Option<[DVec2; 3]> {
    let w = mesh.triangles[t];
    Some([
        mesh.wedge_texcoord(w[0])?,
        mesh.wedge_texcoord(w[1])?,
        mesh.wedge_texcoord(w[2])?,
    ])
}

/// Distance from `p` to the triangle `uv` in texture space (0 inside).
fn uv_distance(p: DVec2, uv: [DVec2; 3]) -> f64 {
    let cross = |a: DVec2, b: DVec2| a.x * b.y - a.y * b.x;
    let area = cross(uv[1] - uv[0], uv[2] - uv[0]);
    let inside = (0..3).all(|k| {
        let (a, b) = (uv[k], uv[(k + 1) % 3]);
        cross(b - a, p - a) * area.signum() >= 0.0
    });
    if inside && area != 0.0 {
        return 0.0;
    }
    (0..3)
        .map(|k| {
            // In the plane z = 0 (the third terms add exact zeros, so the figure is that of
            // a 2-D computation).
            let (a, b) = (uv[k].extend(0.0), uv[(k + 1) % 3].extend(0.0));
            segment_distance(p.extend(0.0), a, b)
        })
        .fold(f64::INFINITY, f64::min)
}

/// Audits `output` (a decimation of `input`, with `triangle_origins` indexing `input`).
pub fn audit(input: &Mesh, output: &Mesh) -> Audit {
    let tin = Topology::new(input);
    let tout = Topology::new(output);
    let diag = input.bounding_box_diagonal().max(f64::MIN_POSITIVE);
    let mut a = Audit {
        before: tin.counts(),
        after: tout.counts(),
        chart_jumps: chart_jumps(input, &tin, output),
        seam_vertices_off_seam: seam_vertices_off_seam(input, &tin, output, &tout, diag),
        border_edges_off_border: border_edges_off_border(input, &tin, output, &tout),
        ..Default::default()
    };
    count_bad_faces(input, output, diag, &mut a);
    a
}

/// Output triangles turned over against their origin, and of zero area.
fn count_bad_faces(input: &Mesh, output: &Mesh, diag: f64, a: &mut Audit) {
    for t in 0..output.triangles.len() {
        let o = output.triangle_origin(t) as usize;
        let n = output.triangle_cross(t);
        if o < input.triangles.len() && n.dot(input.triangle_cross(o)) < 0.0 {
            a.flipped_faces += 1;
        }
        let p = output.triangle_positions(t);
        let longest = p[0]
            .distance(p[1])
            .max(p[1].distance(p[2]))
            .max(p[2].distance(p[0]));
        if n.length() <= 1e-9 * diag * longest.max(1e-300) {
            a.zero_area_faces += 1;
        }
    }
}

/// Output triangles whose texture corners are not all in their origin's chart.
fn chart_jumps(input: &Mesh, tin: &Topology, output: &Mesh) -> usize {
    let mut jumps = 0;
    if let Some(grid) = UvGrid::new(input) {
        let chart = charts(input, tin);
        for t in 0..output.triangles.len() {
            let o = output.triangle_origin(t) as usize;
            let Some(uv) = uvs(output, t) else { continue };
            if o >= input.triangles.len() {
                continue;
            }
            let want = chart[o];
            let ok = uv.iter().all(|&p| {
                let (i, j) = grid.index(p);
                grid.cells[j * grid.nx + i].iter().any(|&u| {
                    chart[u as usize] == want
                        && uvs(input, u as usize)
                            .is_some_and(|q| uv_distance(p, q) <= CHART_TOLERANCE)
                })
            });
            if !ok {
                jumps += 1;
            }
        }
    }
    jumps
}

/// Output seam vertices that lie on no input seam edge (positions; a grid over the seam
/// segments).
fn seam_vertices_off_seam(
    input: &Mesh,
    tin: &Topology,
    output: &Mesh,
    tout: &Topology,
    diag: f64,
) -> usize {
    let mut off = 0;
    let seam_segments: Vec<(DVec3, DVec3)> = (0..tin.edge_count() as u32)
        .filter(|&e| tin.is_texture_seam_edge(e))
        .map(|e| {
            let [x, y] = tin.edge_vertices(e);
            (input.positions[x as usize], input.positions[y as usize])
        })
        .collect();
    let mut seam_out: Vec<u32> = (0..tout.edge_count() as u32)
        .filter(|&e| tout.is_texture_seam_edge(e))
        .flat_map(|e| tout.edge_vertices(e))
        .collect();
    seam_out.sort_unstable();
    seam_out.dedup();
    if !seam_out.is_empty() {
        let cell = (diag / 200.0).max(1e-12);
        let mut grid: std::collections::HashMap<[i64; 3], Vec<u32>> = Default::default();
        let idx = |p: DVec3| (p / cell).floor().as_i64vec3().to_array();
        for (i, (x, y)) in seam_segments.iter().enumerate() {
            let (lo, hi) = (idx(x.min(*y)), idx(x.max(*y)));
            for i0 in lo[0]..=hi[0] {
                for i1 in lo[1]..=hi[1] {
                    for i2 in lo[2]..=hi[2] {
                        grid.entry([i0, i1, i2]).or_default().push(i as u32);
                    }
                }
            }
        }
        for v in seam_out {
            let p = output.positions[v as usize];
            let on = grid.get(&idx(p)).is_some_and(|list| {
                list.iter().any(|&s| {
                    let (x, y) = seam_segments[s as usize];
                    segment_distance(p, x, y) <= 1e-9 * diag
                })
            });
            if !on {
                off += 1;
            }
        }
    }
    off
}

/// Output border edges whose ends are not both input border vertices (by exact position).
fn border_edges_off_border(input: &Mesh, tin: &Topology, output: &Mesh, tout: &Topology) -> usize {
    let mut off = 0;
    let border_in: HashSet<([u64; 3], [u64; 3])> = tin
        .boundary_edges()
        .map(|e| {
            let [x, y] = tin.edge_vertices(e);
            let (kx, ky) = (
                key(input.positions[x as usize]),
                key(input.positions[y as usize]),
            );
            (kx.min(ky), kx.max(ky))
        })
        .collect();
    let border_vertices_in: HashSet<[u64; 3]> =
        border_in.iter().flat_map(|&(x, y)| [x, y]).collect();
    for e in tout.boundary_edges() {
        let [x, y] = tout.edge_vertices(e);
        let (kx, ky) = (
            key(output.positions[x as usize]),
            key(output.positions[y as usize]),
        );
        if !(border_vertices_in.contains(&kx) && border_vertices_in.contains(&ky)) {
            off += 1;
        }
    }
    off
}
