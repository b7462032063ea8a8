//! Pseudo-Voronoi cells (remeshing thesis §4.2): seeds at a minimum
//! spacing, then every vertex joins the cell of its nearest seed along mesh edges.

use glam::DVec3;
use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};

/// The surface as a vertex graph: positions and, per vertex, its neighbours (ascending).
pub struct Graph<'a> {
    pub positions: &'a [DVec3],
    pub neighbours: Vec<Vec<u32>>,
    /// Vertices that some triangle uses.
    pub used: Vec<bool>,
}

/// The cells: a label per vertex (`u32::MAX` for unused vertices), the seeds, and each
/// vertex's edge-path distance to its seed.
pub struct Cells {
    pub seeds: Vec<u32>,
    pub label: Vec<u32>,
    pub distance: Vec<f64>,
}

/// Thesis §4.2 step 2a: scan the vertices in order and make a vertex a seed when it is
/// farther than `spacing` (Euclidean) from every seed chosen so far. A hash grid of cell
/// size `spacing` keeps this linear.
pub fn spaced_seeds(graph: &Graph<'_>, spacing: f64) -> Vec<u32> {
    let key = |p: DVec3| -> (i64, i64, i64) {
        let q = (p / spacing).floor();
        (q.x as i64, q.y as i64, q.z as i64)
    };
    let mut grid: HashMap<(i64, i64, i64), Vec<u32>> = HashMap::new();
    let mut seeds = Vec::new();
    let s2 = spacing * spacing;
    for (v, &p) in graph.positions.iter().enumerate() {
        if !graph.used[v] {
            continue;
        }
        let (x, y, z) = key(p);
        let mut near = false;
        'scan: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(list) = grid.get(&(x + dx, y + dy, z + dz))
                        && list
                            .iter()
                            .any(|&s| graph.positions[s as usize].distance_squared(p) <= s2)
                    {
                        near = true;
                        break 'scan;
                    }
                }
            }
        }
        if !near {
            grid.entry((x, y, z)).or_default().push(v as u32);
            seeds.push(v as u32);
        }
    }
    seeds
}

#[derive(PartialEq)]
struct Item(f64, u32, u32);
impl Eq for Item {}
impl Ord for Item {
    fn cmp(&self, o: &Self) -> Ordering {
        // Smallest distance first (reading P1: keep the smaller distance), then the lower
        // label, then the lower vertex: ties are broken the same way on every run.
        o.0.total_cmp(&self.0)
            .then(o.1.cmp(&self.1))
            .then(o.2.cmp(&self.2))
    }
}
impl PartialOrd for Item {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

/// Thesis §4.2 step 2b: multi-source Dijkstra over the mesh edges; a vertex's cell is the
/// seed it is reached from first. Each cell is connected (its shortest-path tree).
pub fn grow(graph: &Graph<'_>, seeds: Vec<u32>) -> Cells {
    let n = graph.positions.len();
    let mut label = vec![u32::MAX; n];
    let mut distance = vec![f64::INFINITY; n];
    let mut heap = BinaryHeap::new();
    for (i, &s) in seeds.iter().enumerate() {
        distance[s as usize] = 0.0;
        heap.push(Item(0.0, i as u32, s));
    }
    let mut done = vec![false; n];
    while let Some(Item(d, l, v)) = heap.pop() {
        let vi = v as usize;
        if done[vi] {
            continue;
        }
        done[vi] = true;
        label[vi] = l;
        for &w in &graph.neighbours[vi] {
            let wi = w as usize;
            if done[wi] {
                continue;
            }
            let nd = d + graph.positions[vi].distance(graph.positions[wi]);
            if nd < distance[wi] {
                distance[wi] = nd;
                heap.push(Item(nd, l, w));
            } else if nd == distance[wi] {
                heap.push(Item(nd, l, w));
            }
        }
    }
    Cells {
        seeds,
        label,
        distance,
    }
}
