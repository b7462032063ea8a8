//! The region layout: the dual of the cell adjacency (remeshing thesis §4.3, and its
//! failures, §5.5). Every input triangle whose three vertices lie in three different cells
//! is a cell corner ("Voronoi vertex"); the three cell centres around it span one triangular
//! region. Each region thus has exactly three corners by construction, and the layout is
//! checked to be a closed manifold triangulation of the input's topology before any
//! geometry is built on it: the thesis' failure (regions with the wrong corner count,
//! §5.5) cannot reach the later stages.

use super::cells::Cells;
use std::collections::HashMap;

/// Triangular regions as triples of cell labels, counter-clockwise seen from outside (the
/// order of the input triangle's vertices), and the input triangle each comes from.
pub struct Layout {
    pub cells: usize,
    pub regions: Vec<[u32; 3]>,
    pub corner_triangle: Vec<u32>,
}

/// Why a layout is not a valid closed triangulation: the cells to split (the seed retry
/// adds a seed in each).
pub struct Invalid {
    pub bad_cells: Vec<u32>,
    pub reason: String,
}

/// Builds the dual of the cells over `triangles` (vertex triples) and checks it: every
/// directed region edge once and its reverse once (every edge in exactly two regions,
/// consistently oriented), every cell's link one cycle, every cell present, and
/// V − E + F equal to `euler`, the input's.
pub fn dual(cells: &Cells, triangles: &[[u32; 3]], euler: i64) -> Result<Layout, Invalid> {
    let ncells = cells.seeds.len();
    let (regions, corner_triangle) = cell_corners(cells, triangles);
    let mut bad = vec![false; ncells];
    let mut reasons = Vec::new();
    let edges = count_paired_edges(&regions, &mut bad);
    if bad.iter().any(|&b| b) {
        reasons.push("a pair of cells shares more or less than one border".to_string());
    }
    if !links_are_rings(&regions, &mut bad) {
        reasons.push("a cell is not a disk with its neighbours in one ring".to_string());
    }
    let bad_cells: Vec<u32> = (0..ncells as u32).filter(|&c| bad[c as usize]).collect();
    if !bad_cells.is_empty() {
        return Err(Invalid {
            bad_cells,
            reason: reasons.join("; "),
        });
    }
    let chi = ncells as i64 - edges as i64 + regions.len() as i64;
    if chi != euler {
        // Every local check passed, so a cell carries a handle the layout does not see:
        // split the largest cells.
        return Err(Invalid {
            bad_cells: largest_cells(cells, (ncells / 8).max(1)),
            reason: format!("the layout's Euler characteristic is {chi}, the input's {euler}"),
        });
    }
    Ok(Layout {
        cells: ncells,
        regions,
        corner_triangle,
    })
}

/// The regions: one per input triangle whose three vertices lie in three different cells,
/// as its cells' labels in its own vertex order; and that triangle.
fn cell_corners(cells: &Cells, triangles: &[[u32; 3]]) -> (Vec<[u32; 3]>, Vec<u32>) {
    let mut regions = Vec::new();
    let mut corner_triangle = Vec::new();
    for (t, tri) in triangles.iter().enumerate() {
        let l = tri.map(|v| cells.label[v as usize]);
        if l[0] != l[1] && l[1] != l[2] && l[0] != l[2] {
            regions.push(l);
            corner_triangle.push(t as u32);
        }
    }
    (regions, corner_triangle)
}

/// Counts the region edges used once in each direction; marks the cells of any other edge.
fn count_paired_edges(regions: &[[u32; 3]], bad: &mut [bool]) -> usize {
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    for r in regions {
        for k in 0..3 {
            *directed.entry((r[k], r[(k + 1) % 3])).or_default() += 1;
        }
    }
    let mut edges = 0usize;
    for (&(a, b), &n) in &directed {
        if n != 1 || directed.get(&(b, a)) != Some(&1) {
            bad[a as usize] = true;
            bad[b as usize] = true;
        } else if a < b {
            edges += 1;
        }
    }
    edges
}

/// Whether every cell's link (the directed edges b → c of the regions around it) is one
/// cycle; marks the cells whose link is not.
fn links_are_rings(regions: &[[u32; 3]], bad: &mut [bool]) -> bool {
    let mut link: Vec<Vec<(u32, u32)>> = vec![Vec::new(); bad.len()];
    for r in regions {
        for k in 0..3 {
            link[r[k] as usize].push((r[(k + 1) % 3], r[(k + 2) % 3]));
        }
    }
    let mut all = true;
    for (c, l) in link.iter_mut().enumerate() {
        if !is_one_cycle(l) {
            bad[c] = true;
            all = false;
        }
    }
    all
}

/// Whether the directed edges `l` (sorted here) form one cycle through all of them.
fn is_one_cycle(l: &mut [(u32, u32)]) -> bool {
    if l.len() < 3 {
        return false;
    }
    l.sort_unstable();
    let next = |x: u32| -> Option<u32> {
        let i = l.partition_point(|e| e.0 < x);
        (i < l.len() && l[i].0 == x && (i + 1 == l.len() || l[i + 1].0 != x)).then(|| l[i].1)
    };
    let start = l[0].0;
    let mut x = start;
    let mut steps = 0;
    loop {
        match next(x) {
            Some(y) => {
                steps += 1;
                x = y;
                if x == start {
                    return steps == l.len();
                }
                if steps > l.len() {
                    return false;
                }
            }
            None => return false,
        }
    }
}

/// The `count` cells with the most vertices (ties by label).
fn largest_cells(cells: &Cells, count: usize) -> Vec<u32> {
    let ncells = cells.seeds.len();
    let mut size = vec![0usize; ncells];
    for &l in &cells.label {
        if l != u32::MAX {
            size[l as usize] += 1;
        }
    }
    let mut order: Vec<u32> = (0..ncells as u32).collect();
    order.sort_by_key(|&c| (std::cmp::Reverse(size[c as usize]), c));
    order.truncate(count);
    order
}
