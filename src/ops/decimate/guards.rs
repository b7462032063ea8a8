//! What the thesis leaves out and a lab needs (thesis §3.2, reading R12 in
//! docs/decimation.md; as meshoptimizer and pmp-library do): vertex classes for seams and borders, the link condition, and the
//! triangle checks (normal flip, texture flip, degeneracy).

use super::quadric::{cross, dot, sub};

/// What a vertex may do. Ordered: merging vertices gives the largest class.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(u8)]
pub enum VClass {
    /// Manifold, one wedge, no seam or border edge: moves freely.
    Interior = 0,
    /// On one mesh border (exactly two border edges, no seam edge).
    Border = 1,
    /// On one texture seam (exactly two seam edges and two wedges, no border edge): only
    /// slides along its seam, and both sides of the seam move together.
    Seam = 2,
    /// Never moves: non-manifold, seam junctions and ends, seams meeting a border, borders
    /// under `boundary = "fixed"`.
    Fixed = 3,
}

/// Shape of a vertex link (the edges opposite the vertex in its triangles).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkShape {
    /// One simple cycle of at least 3 edges: an interior manifold vertex.
    Cycle,
    /// One simple path: a manifold border vertex.
    Path,
}

/// Scratch for [`link_shape`], reused so that the hot loop does not allocate.
#[derive(Debug, Default)]
pub struct LinkScratch {
    /// Small links: each vertex with its link-edge count, in the order met.
    counted: Vec<(u32, u32)>,
    /// Small links: the edges the walk has taken.
    used: Vec<bool>,
    /// Large links: the vertices, sorted and distinct; per vertex its link-edge count and its
    /// component's root.
    verts: Vec<u32>,
    degree: Vec<u32>,
    parent: Vec<u32>,
}

/// Up to this many link edges (around a vertex of valence 6 a merge has about 10), the link
/// is checked by a walk, O(k²) but with nothing to sort or index; larger links by
/// union–find, O(k log k), so that a vertex of valence 50,000 does not cost 50,000² steps.
const WALK_EDGES: usize = 32;

/// The link condition in its general form: after merging, the triangles around the new
/// vertex must form one disk (cycle) or one half-disk (path). Every vertex of the link
/// then has at most two link edges (so every edge at the new vertex has one or two
/// triangles: no non-manifold edge), the link is connected (one fan: no non-manifold
/// vertex), and a repeated link edge (a duplicate triangle) is refused. This subsumes the
/// usual `Lk(a) ∩ Lk(b) = Lk(ab)` test for edge collapse and extends it to face collapse.
/// Orientation is ignored, so inconsistently oriented input does not trip it.
pub fn link_shape(edges: &[(u32, u32)], sc: &mut LinkScratch) -> Option<LinkShape> {
    if edges.is_empty() || edges.iter().any(|&(x, y)| x == y) {
        return None;
    }
    if edges.len() <= WALK_EDGES {
        link_shape_by_walk(edges, sc)
    } else {
        link_shape_by_union(edges, sc)
    }
}

/// The shape that link-edge counts allow: `ones` vertices with one link edge, the others
/// with two, `nv` vertices and `ne` edges. Connectivity is for the caller to check.
fn shape_by_counts(ones: usize, nv: usize, ne: usize) -> Option<LinkShape> {
    match ones {
        0 if ne == nv && ne >= 3 => Some(LinkShape::Cycle),
        2 if ne + 1 == nv => Some(LinkShape::Path),
        _ => None,
    }
}

/// [`link_shape`] for a small link: count by scanning, then walk from one end (a path) or
/// anywhere (a cycle) and check the walk takes every edge.
fn link_shape_by_walk(edges: &[(u32, u32)], sc: &mut LinkScratch) -> Option<LinkShape> {
    sc.counted.clear();
    for v in edges.iter().flat_map(|&(x, y)| [x, y]) {
        match sc.counted.iter_mut().find(|e| e.0 == v) {
            Some(e) if e.1 == 2 => return None,
            Some(e) => e.1 += 1,
            None => sc.counted.push((v, 1)),
        }
    }
    let ones = sc.counted.iter().filter(|e| e.1 == 1).count();
    let shape = shape_by_counts(ones, sc.counted.len(), edges.len())?;
    let mut at = match shape {
        LinkShape::Path => sc.counted.iter().find(|e| e.1 == 1)?.0,
        LinkShape::Cycle => edges[0].0,
    };
    sc.used.clear();
    sc.used.resize(edges.len(), false);
    let mut walked = 0;
    while let Some(i) =
        (0..edges.len()).find(|&i| !sc.used[i] && (edges[i].0 == at || edges[i].1 == at))
    {
        sc.used[i] = true;
        walked += 1;
        at = if edges[i].0 == at {
            edges[i].1
        } else {
            edges[i].0
        };
    }
    (walked == edges.len()).then_some(shape)
}

/// [`link_shape`] for a large link: vertices sorted and found by binary search, components
/// joined by union–find.
fn link_shape_by_union(edges: &[(u32, u32)], sc: &mut LinkScratch) -> Option<LinkShape> {
    sc.verts.clear();
    sc.verts.extend(edges.iter().flat_map(|&(x, y)| [x, y]));
    sc.verts.sort_unstable();
    sc.verts.dedup();
    let nv = sc.verts.len();
    sc.degree.clear();
    sc.degree.resize(nv, 0);
    sc.parent.clear();
    sc.parent.extend(0..nv as u32);
    let mut components = nv;
    for &(x, y) in edges {
        let at = |v: u32| sc.verts.binary_search(&v).unwrap_or(0);
        let (i, j) = (at(x), at(y));
        for k in [i, j] {
            sc.degree[k] += 1;
            if sc.degree[k] > 2 {
                return None;
            }
        }
        let (ri, rj) = (root(&mut sc.parent, i), root(&mut sc.parent, j));
        if ri != rj {
            sc.parent[ri.max(rj)] = ri.min(rj) as u32;
            components -= 1;
        }
    }
    let ones = sc.degree.iter().filter(|&&d| d == 1).count();
    let shape = shape_by_counts(ones, nv, edges.len())?;
    // Every vertex has a link edge, so one component of vertices is one of edges.
    (components == 1).then_some(shape)
}

/// The root of `i`'s component, halving the path on the way.
fn root(parent: &mut [u32], mut i: usize) -> usize {
    while parent[i] as usize != i {
        let p = parent[i] as usize;
        parent[i] = parent[p];
        i = p;
    }
    i
}

/// Triangle shape quality `4√3·A / (l₁² + l₂² + l₃²)`: 1 for equilateral, 0 for degenerate.
#[inline]
pub fn quality(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let n = cross(sub(b, a), sub(c, a));
    let area2 = dot(n, n).sqrt();
    let l = dot(sub(b, a), sub(b, a)) + dot(sub(c, b), sub(c, b)) + dot(sub(a, c), sub(a, c));
    if l > 0.0 {
        2.0 * 3f64.sqrt() * area2 / l
    } else {
        0.0
    }
}

/// Below this quality a triangle counts as degenerate (zero area) and is never produced.
pub const DEGENERATE_QUALITY: f64 = 1e-6;
/// Below this quality a collapse may not make a triangle worse than it was.
pub const SLIVER_QUALITY: f64 = 1e-3;

/// Signed area (doubled) of a texture triangle.
#[inline]
pub fn uv_area(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn link_shapes() {
        let mut sc = LinkScratch::default();
        assert_eq!(
            link_shape(&[(1, 2), (2, 3), (3, 1)], &mut sc),
            Some(LinkShape::Cycle)
        );
        assert_eq!(
            link_shape(&[(1, 2), (3, 4), (2, 3)], &mut sc),
            Some(LinkShape::Path)
        );
        // Two fans (bowtie): two paths.
        assert_eq!(link_shape(&[(1, 2), (3, 4)], &mut sc), None);
        // Cycle plus a path: a vertex of degree 3.
        assert_eq!(link_shape(&[(1, 2), (2, 3), (3, 1), (3, 4)], &mut sc), None);
        // Two disjoint cycles.
        assert_eq!(
            link_shape(&[(1, 2), (2, 3), (3, 1), (4, 5), (5, 6), (6, 4)], &mut sc),
            None
        );
        // Duplicate triangle: a 2-cycle.
        assert_eq!(link_shape(&[(1, 2), (1, 2)], &mut sc), None);
        assert_eq!(link_shape(&[], &mut sc), None);
    }

    #[test]
    fn the_walk_and_union_find_agree_on_random_links() {
        let mut sc = LinkScratch::default();
        let mut lcg = crate::testing::Lcg(7);
        let mut next = |m: u64| (lcg.next_u64() >> 33) % m;
        let (mut cycles, mut paths, mut large) = (0, 0, 0);
        for _ in 0..20_000 {
            // Both strategies on every link, small and large, across the size where
            // `link_shape` goes from the walk to union-find.
            let n = if next(4) == 0 {
                WALK_EDGES as u64 - 4 + next(9)
            } else {
                1 + next(9)
            };
            // Mostly rings and paths over few labels, some shuffled and broken.
            let mut edges: Vec<(u32, u32)> = match next(3) {
                0 => (0..n).map(|i| (i as u32, ((i + 1) % n) as u32)).collect(),
                1 => (0..n).map(|i| (i as u32, i as u32 + 1)).collect(),
                _ => (0..n).map(|_| (next(6) as u32, next(6) as u32)).collect(),
            };
            for _ in 0..next(3) {
                let i = next(edges.len() as u64) as usize;
                edges[i].1 = next(12) as u32;
            }
            for i in (1..edges.len()).rev() {
                edges.swap(i, next(i as u64 + 1) as usize);
            }
            let loops = edges.iter().any(|&(x, y)| x == y);
            let want = (!loops)
                .then(|| link_shape_by_walk(&edges, &mut sc))
                .flatten();
            let union = (!loops)
                .then(|| link_shape_by_union(&edges, &mut sc))
                .flatten();
            assert_eq!(union, want, "{edges:?}");
            assert_eq!(link_shape(&edges, &mut sc), want, "{edges:?}");
            cycles += usize::from(want == Some(LinkShape::Cycle));
            paths += usize::from(want == Some(LinkShape::Path));
            large += usize::from(want.is_some() && edges.len() > WALK_EDGES);
        }
        assert!(
            cycles > 1000 && paths > 1000 && large > 500,
            "{cycles} {paths} {large}"
        );
    }

    #[test]
    fn quality_and_uv_area() {
        let q = quality([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.75f64.sqrt(), 0.0]);
        assert!((q - 1.0).abs() < 1e-12);
        assert_eq!(quality([0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]), 0.0);
        assert!(uv_area([0.0, 0.0], [1.0, 0.0], [0.0, 1.0]) > 0.0);
    }
}
