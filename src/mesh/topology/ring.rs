//! The ordered 1-ring of a manifold vertex: its neighbours in turning order, as fairing
//! and smoothing need them (cotangent weights, curvature).

use super::{Topology, next_corner, prev_corner};

/// The neighbours of a manifold vertex `v` in order around it, with the triangles between
/// them: triangle `triangles[i]` has corners `v`, `vertices[i]`, `vertices[i + 1]`
/// (indices wrapping around when `closed`).
///
/// When the fan is consistently oriented the order is counter-clockwise, i.e.
/// `triangles[i]` runs `v → vertices[i] → vertices[i + 1]`. An interior vertex has a
/// closed fan (`vertices.len() == triangles.len()`, starting at its lowest triangle); a
/// boundary vertex has an open fan (`vertices.len() == triangles.len() + 1`) whose first
/// and last vertices are its two boundary neighbours.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OrderedRing {
    pub vertices: Vec<u32>,
    pub triangles: Vec<u32>,
    pub closed: bool,
}

/// Reusable buffers for [`Topology::ordered_ring_into`]: building every vertex's ring with
/// one set of these allocates nothing per vertex.
#[derive(Debug, Default)]
pub struct RingBuffers {
    ahead: Vec<u32>,
    behind: Vec<u32>,
    spokes: Vec<(u32, u32)>,
    /// The ring's vertices and triangles after a successful call (see [`OrderedRing`]).
    pub vertices: Vec<u32>,
    pub triangles: Vec<u32>,
}

impl Topology {
    /// The ordered 1-ring of `v`, or `None` if `v` is non-manifold (see the module
    /// documentation), used by no triangle, or on a triangle that repeats a vertex.
    pub fn ordered_ring(&self, v: u32) -> Option<OrderedRing> {
        let mut buffers = RingBuffers::default();
        let closed = self.ordered_ring_into(v, &mut buffers)?;
        Some(OrderedRing {
            vertices: buffers.vertices,
            triangles: buffers.triangles,
            closed,
        })
    }

    /// [`Topology::ordered_ring`] into `buffers.vertices` and `buffers.triangles`;
    /// returns whether the fan is closed, `None` where `ordered_ring` gives `None` (the
    /// buffers' contents are then unspecified).
    pub fn ordered_ring_into(&self, v: u32, buffers: &mut RingBuffers) -> Option<bool> {
        self.ring_into(v, buffers, true)
    }

    /// [`Topology::ordered_ring_into`], with the closed fans' scan (`closed_scan`) or
    /// through the sorted spokes for every fan (the tests compare the two).
    pub(super) fn ring_into(
        &self,
        v: u32,
        buffers: &mut RingBuffers,
        closed_scan: bool,
    ) -> Option<bool> {
        let RingBuffers {
            ahead,
            behind,
            spokes,
            vertices,
            triangles,
        } = buffers;
        ahead.clear();
        behind.clear();
        spokes.clear();
        vertices.clear();
        triangles.clear();
        let corners = self.vertex_corners(v);
        if corners.is_empty() || self.is_non_manifold_vertex(v) {
            return None;
        }
        self.fan_sides(v, corners, ahead, behind)?;
        if closed_scan && every_spoke_shared(ahead, behind) {
            // A closed fan (every spoke on two triangles or more; most vertices of a
            // scan): the walk from triangle 0 that the sorted path makes, each next
            // triangle found by scanning the slots in order, which finds the first slot of
            // the sorted spoke's run. The same ring without the sort and the searches
            // (ordering every ring of a 400k-triangle scan took 27 ms of CPU with them).
            let scan = |s: u32, slot: u32| {
                (0..ahead.len() as u32)
                    .find(|&j| j != slot && (ahead[j as usize] == s || behind[j as usize] == s))
            };
            return walk(
                corners,
                ahead,
                behind,
                (ahead[0], 0),
                scan,
                vertices,
                triangles,
            );
        }
        // (spoke vertex, triangle slot), sorted: the triangles on edge (v, spoke) are adjacent.
        spokes.extend(
            (0..corners.len() as u32)
                .flat_map(|i| [(ahead[i as usize], i), (behind[i as usize], i)]),
        );
        spokes.sort_unstable();
        let start = fan_start(spokes, ahead)?;
        // The triangle slots on edge (v, s): a run of the sorted spokes.
        let on_spoke = |s: u32, slot: u32| {
            let from = spokes.partition_point(|&(x, _)| x < s);
            spokes[from..]
                .iter()
                .take_while(|&&(x, _)| x == s)
                .map(|&(_, j)| j)
                .find(|&j| j != slot)
        };
        walk(corners, ahead, behind, start, on_spoke, vertices, triangles)
    }

    /// Triangle i (the i-th corner at `v`) is (v, `ahead[i]`, `behind[i]`) in its
    /// orientation; `None` where a triangle repeats a vertex.
    fn fan_sides(
        &self,
        v: u32,
        corners: &[u32],
        ahead: &mut Vec<u32>,
        behind: &mut Vec<u32>,
    ) -> Option<()> {
        for &c in corners {
            let (a, b) = (
                self.corner_vertex(next_corner(c)),
                self.corner_vertex(prev_corner(c)),
            );
            if a == v || b == v || a == b {
                return None;
            }
            ahead.push(a);
            behind.push(b);
        }
        Some(())
    }
}

/// Where the walk around a fan starts, as (spoke, triangle slot): an open fan at a spoke
/// with one triangle, preferably one its triangle leaves v along (so the walk is
/// counter-clockwise); a closed fan at triangle 0. `None` where an open fan has only one
/// such spoke.
fn fan_start(spokes: &[(u32, u32)], ahead: &[u32]) -> Option<(u32, u32)> {
    let mut boundary_spokes = spokes
        .chunk_by(|x, y| x.0 == y.0)
        .filter(|run| run.len() == 1)
        .map(|run| run[0]);
    Some(match boundary_spokes.next() {
        None => (ahead[0], 0),
        Some(one) => {
            let other = boundary_spokes.next()?;
            if ahead[one.1 as usize] != one.0 && ahead[other.1 as usize] == other.0 {
                other
            } else {
                one
            }
        }
    })
}

/// Whether every spoke of the fan (each `ahead` and `behind` vertex) is on two triangles
/// or more: no boundary spoke, so [`fan_start`] starts at triangle 0. Counted by pairs
/// (a dozen triangles at most, else `false` and the sorted path decides).
fn every_spoke_shared(ahead: &[u32], behind: &[u32]) -> bool {
    const MOST: usize = 12;
    let n = ahead.len();
    if n > MOST {
        return false;
    }
    let on_another = |s: u32, i: usize| (0..n).any(|j| j != i && (ahead[j] == s || behind[j] == s));
    (0..n).all(|i| on_another(ahead[i], i) && on_another(behind[i], i))
}

/// Walks from `start` (spoke, triangle slot) across each triangle to the next one on the
/// far spoke (`next(spoke, slot)`: the first other slot on that spoke, in slot order),
/// until an open fan's other border spoke or back at the start; returns whether the fan is
/// closed, `None` where the walk missed a triangle (more than one fan).
fn walk(
    corners: &[u32],
    ahead: &[u32],
    behind: &[u32],
    (first_spoke, first_slot): (u32, u32),
    next: impl Fn(u32, u32) -> Option<u32>,
    vertices: &mut Vec<u32>,
    triangles: &mut Vec<u32>,
) -> Option<bool> {
    vertices.push(first_spoke);
    triangles.push(corners[first_slot as usize] / 3);
    let (mut slot, mut spoke) = (first_slot, first_spoke);
    loop {
        let i = slot as usize;
        spoke = if ahead[i] == spoke {
            behind[i]
        } else {
            ahead[i]
        };
        vertices.push(spoke);
        let Some(next_slot) = next(spoke, slot) else {
            break; // open fan: reached the other boundary spoke
        };
        if next_slot == first_slot {
            vertices.pop(); // closed fan: back at the first spoke
            break;
        }
        if triangles.len() == corners.len() {
            return None; // cannot happen for a single fan; never loop
        }
        triangles.push(corners[next_slot as usize] / 3);
        slot = next_slot;
    }
    let closed = vertices.len() == triangles.len();
    (triangles.len() == corners.len()).then_some(closed)
}
