//! What the thesis leaves out and a lab needs (spec/decimation.md §5.6 [D], §10.14;
//! peers.md §2.4): vertex classes for seams and borders, the link condition, and the
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
    /// under `boundary = "keep"`.
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
    verts: Vec<(u32, u32)>,
    used: Vec<bool>,
}

/// The link condition in its general form: after merging, the triangles around the new
/// vertex must form one disk (cycle) or one half-disk (path). Every vertex of the link
/// then has at most two link edges (so every edge at the new vertex has one or two
/// triangles: no non-manifold edge), the link is connected (one fan: no non-manifold
/// vertex), and a repeated link edge (a duplicate triangle) is refused. This subsumes the
/// usual `Lk(a) ∩ Lk(b) = Lk(ab)` test for edge collapse and extends it to face collapse.
/// Orientation is ignored, so inconsistently oriented input does not trip it.
pub fn link_shape(edges: &[(u32, u32)], sc: &mut LinkScratch) -> Option<LinkShape> {
    if edges.is_empty() {
        return None;
    }
    sc.verts.clear();
    for &(x, y) in edges {
        if x == y {
            return None;
        }
        for v in [x, y] {
            match sc.verts.iter_mut().find(|e| e.0 == v) {
                Some(e) => {
                    e.1 += 1;
                    if e.1 > 2 {
                        return None;
                    }
                }
                None => sc.verts.push((v, 1)),
            }
        }
    }
    let ones = sc.verts.iter().filter(|e| e.1 == 1).count();
    let (nv, ne) = (sc.verts.len(), edges.len());
    let shape = match ones {
        0 if ne == nv && ne >= 3 => LinkShape::Cycle,
        2 if ne + 1 == nv => LinkShape::Path,
        _ => return None,
    };
    // Connectivity: walk from an end (path) or anywhere (cycle) and count the edges met.
    let start = match shape {
        LinkShape::Path => sc.verts.iter().find(|e| e.1 == 1).map(|e| e.0)?,
        LinkShape::Cycle => edges[0].0,
    };
    sc.used.clear();
    sc.used.resize(ne, false);
    let mut cur = start;
    let mut walked = 0;
    loop {
        let next = edges
            .iter()
            .enumerate()
            .find(|&(i, &(x, y))| !sc.used[i] && (x == cur || y == cur));
        match next {
            Some((i, &(x, y))) => {
                sc.used[i] = true;
                walked += 1;
                cur = if x == cur { y } else { x };
            }
            None => break,
        }
    }
    (walked == ne).then_some(shape)
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
    fn quality_and_uv_area() {
        let q = quality([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.75f64.sqrt(), 0.0]);
        assert!((q - 1.0).abs() < 1e-12);
        assert_eq!(quality([0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]), 0.0);
        assert!(uv_area([0.0, 0.0], [1.0, 0.0], [0.0, 1.0]) > 0.0);
    }
}
