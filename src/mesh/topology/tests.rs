use super::*;
use crate::mesh::model::{Mesh, Wedge};
use glam::{DVec2, DVec3};
use proptest::prelude::*;
use std::collections::{BTreeMap, BTreeSet};

/// A mesh with one wedge per (vertex, texcoord, normal) as given per corner.
fn mesh_with_attributes(
    positions: &[[f64; 3]],
    triangles: &[[u32; 3]],
    texcoords: Option<&[[u32; 3]]>,
    normals: Option<&[[u32; 3]]>,
) -> Mesh {
    let mut wedge_ids: BTreeMap<Wedge, u32> = BTreeMap::new();
    let mut wedges = Vec::new();
    let mut max_uv = 0;
    let mut max_n = 0;
    let tris = triangles
        .iter()
        .enumerate()
        .map(|(t, tri)| {
            std::array::from_fn(|k| {
                let w = Wedge {
                    vertex: tri[k],
                    texcoord: texcoords.map(|uv| uv[t][k]),
                    normal: normals.map(|n| n[t][k]),
                };
                max_uv = max_uv.max(w.texcoord.map_or(0, |x| x + 1));
                max_n = max_n.max(w.normal.map_or(0, |x| x + 1));
                *wedge_ids.entry(w).or_insert_with(|| {
                    wedges.push(w);
                    (wedges.len() - 1) as u32
                })
            })
        })
        .collect();
    let mesh = Mesh {
        positions: positions.iter().map(|&p| DVec3::from(p)).collect(),
        texcoords: (0..max_uv).map(|i| DVec2::new(i as f64, 0.0)).collect(),
        normals: (0..max_n).map(|_| DVec3::Z).collect(),
        wedges,
        triangles: tris,
        ..Default::default()
    };
    mesh.check_invariants().unwrap();
    mesh
}

fn mesh(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> Mesh {
    mesh_with_attributes(positions, triangles, None, None)
}

const TETRA_POSITIONS: [[f64; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
];
/// Outward-facing (counter-clockwise seen from outside).
const TETRA: [[u32; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];

fn quad_positions() -> [[f64; 3]; 4] {
    [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ]
}

/// The unit square as triangles (0, 1, 2) and (0, 2, 3), with these texture coordinate
/// (and normal) indices per corner.
fn quad(texcoords: [[u32; 3]; 2], normals: Option<&[[u32; 3]]>) -> Mesh {
    mesh_with_attributes(
        &quad_positions(),
        &[[0, 1, 2], [0, 2, 3]],
        Some(&texcoords),
        normals,
    )
}

/// `n × n` vertices on the unit square, two triangles per cell, optionally leaving out
/// the cells for which `skip(i, j)` holds.
fn grid(n: u32, skip: impl Fn(u32, u32) -> bool) -> Mesh {
    let mut positions = Vec::new();
    for j in 0..n {
        for i in 0..n {
            positions.push([i as f64, j as f64, 0.0]);
        }
    }
    let mut tris = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            if skip(i, j) {
                continue;
            }
            let v = j * n + i;
            tris.push([v, v + 1, v + n + 1]);
            tris.push([v, v + n + 1, v + n]);
        }
    }
    let mut m = mesh(&positions, &tris);
    m.compact();
    m
}

/// Border edges, border loops and connected components.
fn border_and_parts(c: &TopologyCounts) -> (usize, usize, usize) {
    (c.boundary_edges, c.boundary_loops, c.components)
}

#[test]
fn single_triangle() {
    let m = mesh(&quad_positions()[..3], &[[0, 1, 2]]);
    let topo = m.topology();
    let c = topo.counts();
    assert_eq!((c.vertices, c.triangles, c.wedges, c.edges), (3, 1, 3, 3));
    assert_eq!(border_and_parts(&c), (3, 1, 1));
    assert_eq!(c.euler_characteristic, 1);
    assert_eq!(c.non_manifold_vertices + c.non_manifold_edges, 0);
    let l = &topo.boundary_chains()[0];
    assert!(l.closed);
    assert_eq!(l.vertices, vec![0, 1, 2]);
    assert_eq!(l.edges.len(), 3);
    assert_eq!(topo.edge_vertices(l.edges[2]), [0, 2]);
    let ring = topo.ordered_ring(0).unwrap();
    assert_eq!(ring.vertices, vec![1, 2]);
    assert_eq!(ring.triangles, vec![0]);
    assert!(!ring.closed);
    assert!(topo.is_boundary_vertex(0));
    assert_eq!(topo.vertex_neighbours(1), &[0, 2]);
    assert_eq!(topo.find_edge(2, 1), Some(2));
    assert_eq!(topo.find_edge(0, 0), None);
    assert_eq!(topo.opposite_side(0), None);
}

#[test]
fn two_triangles_without_seam() {
    let m = quad([[0, 1, 2], [0, 2, 3]], None);
    let topo = m.topology();
    let c = topo.counts();
    assert_eq!((c.edges, c.boundary_edges, c.boundary_loops), (5, 4, 1));
    assert_eq!(
        (c.seam_edges, c.texture_seam_edges, c.inconsistent_edges),
        (0, 0, 0)
    );
    let diagonal = topo.find_edge(0, 2).unwrap();
    assert_eq!(topo.edge_kind(diagonal), EdgeKind::Manifold);
    assert_eq!(
        topo.edge_triangles(diagonal).collect::<Vec<_>>(),
        vec![0, 1]
    );
    // Side 2 of triangle 0 runs 2 → 0; its opposite is side 0 of triangle 1 (0 → 2).
    assert_eq!(topo.opposite_side(2), Some(3));
    assert_eq!(topo.boundary_chains()[0].vertices, vec![0, 1, 2, 3]);
    let ring = topo.ordered_ring(0).unwrap();
    assert_eq!((ring.vertices, ring.triangles), (vec![1, 2, 3], vec![0, 1]));
    let ring = topo.ordered_ring(2).unwrap();
    assert_eq!((ring.vertices, ring.triangles), (vec![3, 0, 1], vec![1, 0]));
    assert_eq!(topo.euler_characteristic(), 1);
}

#[test]
fn two_triangles_with_texture_seam() {
    // Triangle 1 uses its own texture coordinates at vertices 0 and 2.
    let m = quad([[0, 1, 2], [4, 5, 3]], None);
    let topo = m.topology();
    let c = topo.counts();
    assert_eq!((c.seam_edges, c.texture_seam_edges), (1, 1));
    assert_eq!((c.wedges, c.texcoords), (6, 6));
    assert!(topo.is_texture_seam_edge(topo.find_edge(0, 2).unwrap()));

    // Differing at one end only is still a seam.
    let m = quad([[0, 1, 2], [0, 4, 3]], None);
    assert_eq!(m.topology().counts().texture_seam_edges, 1);
}

#[test]
fn normal_split_is_a_seam_but_not_a_texture_seam() {
    let m = quad([[0, 1, 2], [0, 2, 3]], Some(&[[0, 0, 0], [1, 1, 1]]));
    let c = m.topology().counts();
    assert_eq!((c.seam_edges, c.texture_seam_edges), (1, 0));
}

#[test]
fn closed_tetrahedron() {
    let m = mesh(&TETRA_POSITIONS, &TETRA);
    let topo = m.topology();
    let c = topo.counts();
    assert_eq!((c.vertices, c.edges, c.triangles), (4, 6, 4));
    assert_eq!(border_and_parts(&c), (0, 0, 1));
    assert_eq!((c.inconsistent_edges, c.non_manifold_vertices), (0, 0));
    assert_eq!(c.euler_characteristic, 2);
    for v in 0..4 {
        let ring = topo.ordered_ring(v).unwrap();
        assert!(ring.closed);
        assert_eq!(ring.vertices.len(), 3);
        assert_eq!(topo.vertex_fan_count(v), 1);
        // Counter-clockwise: each triangle runs v → ring[i] → ring[i + 1].
        for i in 0..3 {
            let tri = topo.triangle_vertices(ring.triangles[i]);
            let k = tri.iter().position(|&x| x == v).unwrap();
            assert_eq!(tri[(k + 1) % 3], ring.vertices[i]);
            assert_eq!(tri[(k + 2) % 3], ring.vertices[(i + 1) % 3]);
        }
    }
    assert_eq!(topo.ordered_ring(0).unwrap().triangles[0], 0);
}

#[test]
fn flipped_triangle_in_closed_mesh() {
    let mut tris = TETRA;
    tris[3] = [1, 3, 2];
    let m = mesh(&TETRA_POSITIONS, &tris);
    let topo = m.topology();
    let c = topo.counts();
    assert_eq!(c.inconsistent_edges, 3);
    assert_eq!((c.boundary_edges, c.non_manifold_vertices), (0, 0));
    assert!(topo.is_inconsistent_edge(topo.find_edge(1, 2).unwrap()));
    assert!(!topo.is_inconsistent_edge(topo.find_edge(0, 1).unwrap()));
    // Rings still exist: they follow connectivity, not orientation.
    assert!(topo.ordered_ring(1).unwrap().closed);
}

#[test]
fn bowtie_is_a_non_manifold_vertex_with_two_chains_in_one_loop() {
    let positions = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [-1.0, 0.0, 0.0],
        [-1.0, -1.0, 0.0],
    ];
    let m = mesh(&positions, &[[0, 1, 2], [0, 3, 4]]);
    let topo = m.topology();
    let c = topo.counts();
    assert_eq!((c.non_manifold_vertices, c.non_manifold_edges), (1, 0));
    assert_eq!(topo.non_manifold_vertices(), &[0]);
    assert_eq!(topo.vertex_fan_count(0), 2);
    assert_eq!(border_and_parts(&c), (6, 1, 1));
    assert_eq!((c.boundary_chains, c.open_boundary_chains), (2, 0));
    let loops: Vec<_> = topo.boundary_chains().iter().map(|l| &l.vertices).collect();
    assert_eq!(loops, vec![&vec![0, 1, 2], &vec![0, 3, 4]]);
    assert!(
        topo.boundary_chains()
            .iter()
            .all(|l| l.closed && l.boundary_loop == 0)
    );
    assert_eq!(topo.ordered_ring(0), None);
    assert!(topo.ordered_ring(1).is_some());
    assert_eq!(c.euler_characteristic, 1);
}

#[test]
fn pinched_boundary_follows_fans() {
    // Two fans meet at vertex 3. The walk from vertex 0 arrives at 3 through fan B, and
    // the lowest edge leaving 3 (3 → 4) belongs to fan A: the fan rule must take 3 → 6.
    let positions = [[0.0; 3]; 7];
    // Fan B: (3,6,5),(3,5,0); fan A: (3,4,1),(3,1,2).
    let m = mesh(&positions, &[[3, 6, 5], [3, 5, 0], [3, 4, 1], [3, 1, 2]]);
    let topo = m.topology();
    assert_eq!(topo.non_manifold_vertices(), &[3]);
    let loops: Vec<_> = topo
        .boundary_chains()
        .iter()
        .map(|l| (l.vertices.clone(), l.closed))
        .collect();
    assert_eq!(
        loops,
        vec![(vec![0, 3, 6, 5], true), (vec![1, 2, 3, 4], true)]
    );
    assert_eq!(topo.boundary_loop_count(), 1);
}

#[test]
fn three_triangles_on_one_edge() {
    let positions = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.5, 1.0, 0.0],
        [0.5, -1.0, 0.0],
        [0.5, 0.0, 1.0],
    ];
    let m = mesh(&positions, &[[0, 1, 2], [1, 0, 3], [0, 1, 4]]);
    let topo = m.topology();
    let c = topo.counts();
    let e = topo.find_edge(0, 1).unwrap();
    assert_eq!(topo.edge_kind(e), EdgeKind::NonManifold);
    assert_eq!(topo.non_manifold_edges().collect::<Vec<_>>(), vec![e]);
    assert_eq!((c.non_manifold_edges, c.non_manifold_vertices), (1, 2));
    assert_eq!(topo.non_manifold_vertices(), &[0, 1]);
    // Triangles 0 and 2 both run 0 → 1.
    assert_eq!(c.inconsistent_edges, 1);
    assert!(topo.is_inconsistent_edge(e));
    assert_eq!(c.boundary_edges, 6);
    let walked: usize = topo.boundary_chains().iter().map(|l| l.edges.len()).sum();
    assert_eq!(walked, 6);
    assert_eq!(
        (c.boundary_loops, c.boundary_chains, c.open_boundary_chains),
        (1, 2, 1)
    );
    assert_eq!(topo.ordered_ring(0), None);
    assert!(topo.ordered_ring(2).is_some());
}

#[test]
fn non_manifold_edges_count_repeated_directions_and_are_never_seams() {
    // Four triangles on edge (0, 1), two each way, each with its own texture coordinates.
    let positions = [[0.0; 3]; 6];
    let tris = [[0, 1, 2], [1, 0, 3], [0, 1, 4], [1, 0, 5]];
    let uvs = [[0, 1, 2], [3, 4, 5], [6, 7, 8], [9, 10, 11]];
    let m = mesh_with_attributes(&positions, &tris, Some(&uvs), None);
    let c = m.topology().counts();
    assert_eq!((c.non_manifold_edges, c.inconsistent_edges), (1, 2));
    assert_eq!((c.seam_edges, c.texture_seam_edges), (0, 0));
}

#[test]
fn square_with_hole() {
    let m = grid(4, |i, j| i == 1 && j == 1);
    let topo = m.topology();
    let c = topo.counts();
    assert_eq!((c.vertices, c.triangles), (16, 16));
    assert_eq!(border_and_parts(&c), (16, 2, 1));
    assert_eq!(c.euler_characteristic, 0);
    let loops = topo.boundary_chains();
    assert!(loops.iter().all(|l| l.closed));
    assert_eq!(loops[0].vertices.len(), 12);
    // Outer loop counter-clockwise (surface on the left), hole clockwise.
    assert_eq!(&loops[0].vertices[..4], &[0, 1, 2, 3]);
    assert_eq!(loops[1].vertices, vec![5, 9, 10, 6]);
    // A corner of the hole is a manifold boundary vertex with an open fan.
    let ring = topo.ordered_ring(5).unwrap();
    assert!(!ring.closed);
    assert_eq!(ring.vertices.first(), Some(&9));
    assert_eq!(ring.vertices.last(), Some(&6));
    // An interior vertex of a full grid has a closed ring.
    let full = grid(3, |_, _| false);
    let ring = full.topology().ordered_ring(4).unwrap();
    assert!(ring.closed);
    assert_eq!(ring.vertices.len(), 6);
}

#[test]
fn two_separate_triangles() {
    let positions = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [5.0, 0.0, 0.0],
        [6.0, 0.0, 0.0],
        [5.0, 1.0, 0.0],
    ];
    let m = mesh(&positions, &[[3, 4, 5], [0, 1, 2]]);
    let topo = m.topology();
    assert_eq!(topo.component_count(), 2);
    assert_eq!(topo.triangle_components(), &[0, 1]);
    assert_eq!(topo.counts().boundary_loops, 2);
    assert_eq!(topo.euler_characteristic(), 2);
}

#[test]
fn empty_mesh_and_unused_vertex() {
    let topo = Mesh::default().topology();
    assert_eq!(topo.counts(), TopologyCounts::default());
    let m = mesh(&TETRA_POSITIONS, &[[0, 1, 2]]);
    let topo = m.topology();
    assert_eq!(topo.ordered_ring(3), None);
    assert_eq!(topo.vertex_fan_count(3), 0);
    assert_eq!(topo.euler_characteristic(), 2);
}

#[test]
fn repeated_vertex_does_not_panic() {
    let m = mesh(&TETRA_POSITIONS, &[[0, 0, 1], [0, 1, 2]]);
    let topo = m.topology();
    assert_eq!(topo.triangle_edges(0)[0], NO_EDGE);
    assert_eq!(topo.ordered_ring(0), None);
    let _ = topo.counts();
}

#[test]
fn counts_serialize() {
    let json = serde_json::to_string(&mesh(&TETRA_POSITIONS, &TETRA).topology().counts()).unwrap();
    assert!(json.contains("\"euler_characteristic\":2"));
}

// ----- properties on random meshes -----

fn random_mesh() -> impl Strategy<Value = Mesh> {
    (4u32..14).prop_flat_map(|n| {
        let triangle = (0..n, 0..n, 0..n)
            .prop_filter("distinct corners", |(a, b, c)| a != b && b != c && a != c)
            .prop_map(|(a, b, c)| [a, b, c]);
        (Just(n), proptest::collection::vec(triangle, 0..40)).prop_map(|(n, tris)| {
            let positions: Vec<[f64; 3]> = (0..n).map(|i| [i as f64, 0.0, 0.0]).collect();
            mesh(&positions, &tris)
        })
    })
}

/// A random patch of a grid: manifold, consistently oriented, possibly with holes and
/// pinch vertices.
fn random_grid_patch() -> impl Strategy<Value = Mesh> {
    proptest::collection::vec(any::<bool>(), 36)
        .prop_map(|keep| grid(7, |i, j| !keep[(j * 6 + i) as usize]))
}

/// The invariants every mesh's topology keeps, whatever its shape.
fn check_common(m: &Mesh) -> Result<(), TestCaseError> {
    let topo = m.topology();
    check_edges(m, &topo)?;
    check_boundary_chains(&topo)?;
    check_boundary_loops(&topo)?;
    check_neighbours_and_components(&topo)?;
    check_rings(&topo)
}

/// Every side belongs to one edge; the edges are the triangles' distinct vertex pairs,
/// sorted; the Euler characteristic counts them.
fn check_edges(m: &Mesh, topo: &Topology) -> Result<(), TestCaseError> {
    let c = topo.counts();
    let sides: usize = (0..c.edges as u32).map(|e| topo.edge_sides(e).len()).sum();
    prop_assert_eq!(sides, 3 * c.triangles);

    let unique: BTreeSet<[u32; 2]> = (0..m.triangles.len())
        .flat_map(|t| {
            let v = m.triangle_vertices(t);
            (0..3).map(move |k| {
                let (a, b) = (v[k], v[(k + 1) % 3]);
                [a.min(b), a.max(b)]
            })
        })
        .collect();
    let unique_list: Vec<[u32; 2]> = unique.iter().copied().collect();
    prop_assert_eq!(topo.edges(), unique_list.as_slice());
    prop_assert_eq!(
        c.euler_characteristic,
        c.vertices as i64 - unique.len() as i64 + c.triangles as i64
    );
    Ok(())
}

/// Every boundary edge is walked exactly once, by a chain whose consecutive vertices are
/// its ends.
fn check_boundary_chains(topo: &Topology) -> Result<(), TestCaseError> {
    let mut walked: Vec<u32> = topo
        .boundary_chains()
        .iter()
        .flat_map(|l| l.edges.iter().copied())
        .collect();
    walked.sort_unstable();
    prop_assert_eq!(walked, topo.boundary_edges().collect::<Vec<_>>());
    for l in topo.boundary_chains() {
        prop_assert_eq!(l.vertices.len(), l.edges.len() + usize::from(!l.closed));
        for (i, &e) in l.edges.iter().enumerate() {
            let [a, b] = topo.edge_vertices(e);
            let (p, q) = (l.vertices[i], l.vertices[(i + 1) % l.vertices.len()]);
            prop_assert!([p.min(q), p.max(q)] == [a, b]);
        }
    }
    Ok(())
}

/// Loops are the connected pieces of the boundary-edge graph; chains sharing a vertex are
/// in the same loop.
fn check_boundary_loops(topo: &Topology) -> Result<(), TestCaseError> {
    let c = topo.counts();
    let mut piece: Vec<usize> = (0..c.vertices).collect();
    fn root(piece: &mut [usize], mut x: usize) -> usize {
        while piece[x] != x {
            x = piece[x];
        }
        x
    }
    for e in topo.boundary_edges() {
        let [a, b] = topo.edge_vertices(e);
        let (ra, rb) = (root(&mut piece, a as usize), root(&mut piece, b as usize));
        piece[ra] = rb;
    }
    let pieces: BTreeSet<usize> = topo
        .boundary_edges()
        .map(|e| root(&mut piece, topo.edge_vertices(e)[0] as usize))
        .collect();
    prop_assert_eq!(c.boundary_loops, pieces.len());
    let mut loop_of_piece = BTreeMap::new();
    for chain in topo.boundary_chains() {
        for &v in &chain.vertices {
            let r = root(&mut piece, v as usize);
            prop_assert_eq!(
                *loop_of_piece.entry(r).or_insert(chain.boundary_loop),
                chain.boundary_loop
            );
        }
    }
    Ok(())
}

/// Neighbours are symmetric; triangles sharing a vertex share a component.
fn check_neighbours_and_components(topo: &Topology) -> Result<(), TestCaseError> {
    for v in 0..topo.counts().vertices as u32 {
        for &w in topo.vertex_neighbours(v) {
            prop_assert!(topo.vertex_neighbours(w).contains(&v));
        }
        let mut comps = topo.vertex_triangles(v).map(|t| topo.triangle_component(t));
        if let Some(first) = comps.next() {
            prop_assert!(comps.all(|x| x == first));
        }
    }
    Ok(())
}

/// Rings cover their vertex's triangles, consecutive vertices around each triangle.
fn check_rings(topo: &Topology) -> Result<(), TestCaseError> {
    for v in 0..topo.counts().vertices as u32 {
        let Some(ring) = topo.ordered_ring(v) else {
            prop_assert!(topo.is_non_manifold_vertex(v) || topo.vertex_corners(v).is_empty());
            continue;
        };
        let mut tris = ring.triangles.clone();
        tris.sort_unstable();
        prop_assert_eq!(tris, topo.vertex_triangles(v).collect::<Vec<_>>());
        for (i, &t) in ring.triangles.iter().enumerate() {
            let tri = topo.triangle_vertices(t);
            let next = ring.vertices[(i + 1) % ring.vertices.len()];
            prop_assert!(tri.contains(&ring.vertices[i]) && tri.contains(&next));
        }
        prop_assert_eq!(ring.closed, !topo.is_boundary_vertex(v));
    }
    Ok(())
}

proptest! {
    #[test]
    fn random_meshes_are_consistent(m in random_mesh()) {
        check_common(&m)?;
    }

    #[test]
    fn manifold_patches_have_closed_loops(m in random_grid_patch()) {
        check_common(&m)?;
        let topo = m.topology();
        let c = topo.counts();
        prop_assert_eq!(c.non_manifold_edges + c.inconsistent_edges, 0);
        prop_assert_eq!(c.open_boundary_chains, 0);
        let walked: usize = topo.boundary_chains().iter().map(|l| l.edges.len()).sum();
        prop_assert_eq!(walked, c.boundary_edges);
        // Manifold vertices form one fan; a pinch vertex is exactly a vertex with two.
        for v in 0..c.vertices as u32 {
            prop_assert_eq!(topo.is_non_manifold_vertex(v), topo.vertex_fan_count(v) > 1);
        }
    }
}

// ----- the parallel passes against the definitions -----

/// Every corner's fan and the non-manifold vertices by the definitions: one union-find over
/// all corners, joined edge by edge across the interior manifold edges (the fans are its
/// sets, named by their lowest corner), and the vertices where two fans meet or a
/// non-manifold edge ends.
fn fans_by_definition(topo: &Topology) -> (Vec<u32>, Vec<u32>) {
    let corners = 3 * topo.triangle_count();
    let mut sets = UnionFind::new(corners);
    for e in 0..topo.edge_count() as u32 {
        if let [s1, s2] = *topo.edge_sides(e) {
            let (h1, h2) = (next_corner(s1), next_corner(s2));
            if topo.corner_vertex(s1) == topo.corner_vertex(s2) {
                sets.union(s1, s2);
                sets.union(h1, h2);
            } else {
                sets.union(s1, h2);
                sets.union(h1, s2);
            }
        }
    }
    let fans: Vec<u32> = (0..corners as u32).map(|c| sets.find(c)).collect();
    let on_non_manifold_edge = ends_of_edges_with(topo, |sides| sides > 2);
    let non_manifold = (0..topo.vertex_count() as u32)
        .filter(|&v| {
            let roots: BTreeSet<u32> = topo
                .vertex_corners(v)
                .iter()
                .map(|&c| fans[c as usize])
                .collect();
            roots.len() > 1 || on_non_manifold_edge.contains(&v)
        })
        .collect();
    (fans, non_manifold)
}

/// The vertices at an end of an edge whose number of sides passes `test`.
fn ends_of_edges_with(topo: &Topology, test: impl Fn(usize) -> bool) -> BTreeSet<u32> {
    (0..topo.edge_count() as u32)
        .filter(|&e| test(topo.edge_sides(e).len()))
        .flat_map(|e| topo.edge_vertices(e))
        .collect()
}

fn check_fans(topo: &Topology) -> Result<(), TestCaseError> {
    let (fans, non_manifold) = fans_by_definition(topo);
    let found: Vec<u32> = (0..fans.len() as u32).map(|c| topo.corner_fan(c)).collect();
    prop_assert_eq!(found, fans);
    prop_assert_eq!(topo.non_manifold_vertices(), non_manifold.as_slice());
    let boundary = (0..topo.edge_count() as u32)
        .filter(|&e| topo.edge_sides(e).len() == 1)
        .count();
    prop_assert_eq!(topo.counts().boundary_edges, boundary);
    let on_boundary = ends_of_edges_with(topo, |sides| sides == 1);
    for v in 0..topo.vertex_count() as u32 {
        prop_assert_eq!(topo.is_boundary_vertex(v), on_boundary.contains(&v));
    }
    Ok(())
}

/// Triangles over a few vertices, repeated corners allowed: many edges with three or more
/// sides, sides running the same way, and pinched fans.
fn random_soup() -> impl Strategy<Value = Mesh> {
    (3u32..10).prop_flat_map(|n| {
        let triangle = (0..n, 0..n, 0..n).prop_map(|(a, b, c)| [a, b, c]);
        (Just(n), proptest::collection::vec(triangle, 0..30)).prop_map(|(n, tris)| {
            let positions: Vec<[f64; 3]> = (0..n).map(|i| [i as f64, 0.0, 0.0]).collect();
            mesh(&positions, &tris)
        })
    })
}

/// Every vertex's ring as the closed fans' scan finds it and as the sorted spokes do:
/// the same vertices, triangles and closedness, or `None` from both.
fn check_ring_paths(topo: &Topology) -> Result<(), TestCaseError> {
    let (mut a, mut b) = (RingBuffers::default(), RingBuffers::default());
    for v in 0..topo.vertex_count() as u32 {
        let scanned = topo.ring_into(v, &mut a, true);
        let sorted = topo.ring_into(v, &mut b, false);
        prop_assert_eq!(scanned, sorted, "vertex {}", v);
        if scanned.is_some() {
            prop_assert_eq!(&a.vertices, &b.vertices, "vertex {}", v);
            prop_assert_eq!(&a.triangles, &b.triangles, "vertex {}", v);
        }
    }
    Ok(())
}

proptest! {
    #[test]
    fn fans_and_flags_as_defined_on_soups(m in random_soup()) {
        check_fans(&m.topology())?;
    }

    #[test]
    fn closed_fans_scanned_as_sorted_on_soups(m in random_soup()) {
        check_ring_paths(&m.topology())?;
    }

    #[test]
    fn closed_fans_scanned_as_sorted_on_random_meshes(m in random_mesh()) {
        check_ring_paths(&m.topology())?;
    }

    #[test]
    fn closed_fans_scanned_as_sorted_on_patches(m in random_grid_patch()) {
        check_ring_paths(&m.topology())?;
    }

    #[test]
    fn fans_and_flags_as_defined_on_random_meshes(m in random_mesh()) {
        check_fans(&m.topology())?;
    }
}

/// The edges as one loop over the sorted buckets builds them: the oracle of
/// [`build_edges`]'s parallel blocks (the bucketing is shared).
fn build_edges_one_by_one(vertex_count: usize, corner_vertices: &[u32]) -> EdgeArrays {
    let side_count = corner_vertices.len();
    let (bucket_offsets, mut keyed) = bucket_sides(vertex_count, corner_vertices);
    let mut edges: Vec<[u32; 2]> = Vec::with_capacity(keyed.len() / 2 + 1);
    let mut edge_offsets: Vec<u32> = Vec::with_capacity(keyed.len() / 2 + 2);
    let mut side_list: Vec<u32> = Vec::with_capacity(keyed.len());
    let mut side_edges = vec![NO_EDGE; side_count];
    for lo in 0..vertex_count {
        let bucket = &mut keyed[bucket_offsets[lo] as usize..bucket_offsets[lo + 1] as usize];
        bucket.sort_unstable();
        let mut previous_high = None;
        for &key in bucket.iter() {
            let (high, side) = ((key >> 32) as u32, key as u32);
            if previous_high != Some(high) {
                previous_high = Some(high);
                edge_offsets.push(side_list.len() as u32);
                edges.push([lo as u32, high]);
            }
            side_edges[side as usize] = (edges.len() - 1) as u32;
            side_list.push(side);
        }
    }
    edge_offsets.push(side_list.len() as u32);
    (edges, edge_offsets, side_list, side_edges)
}

fn check_edge_arrays(m: &Mesh) -> Result<(), TestCaseError> {
    let corners: Vec<u32> = (0..m.triangles.len())
        .flat_map(|t| m.triangle_vertices(t))
        .collect();
    let n = m.positions.len();
    prop_assert_eq!(
        build_edges(n, &corners),
        build_edges_one_by_one(n, &corners)
    );
    Ok(())
}

proptest! {
    #[test]
    fn edges_in_blocks_as_one_by_one_on_soups(m in random_soup()) {
        check_edge_arrays(&m)?;
    }

    #[test]
    fn edges_in_blocks_as_one_by_one_on_random_meshes(m in random_mesh()) {
        check_edge_arrays(&m)?;
    }
}

/// A patch large enough to be split between threads and blocks (over 4,096 vertices), with
/// holes that pinch vertices, one triangle turned and one edge given a third triangle.
#[test]
fn fans_and_flags_as_defined_on_a_large_patch() {
    let mut m = grid(80, |i, j| (i * 7 + j * 13) % 11 == 0);
    m.triangles[100].swap(1, 2);
    let extra = m.triangles[2000];
    m.triangles.push([extra[1], extra[0], extra[2]]);
    let topo = crate::testing::on_threads(2, || m.topology());
    assert!(topo.vertex_count() > 4096 && !topo.non_manifold_vertices().is_empty());
    assert!(topo.counts().non_manifold_edges > 0 && topo.counts().inconsistent_edges > 0);
    check_fans(&topo).unwrap();
    crate::testing::on_threads(2, || check_edge_arrays(&m)).unwrap();
}
