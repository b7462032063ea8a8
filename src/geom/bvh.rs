//! A compact bounding-volume hierarchy over a mesh's triangles for exact closest-point
//! queries: the index behind every two-mesh metric.
//!
//! Why not parry3d's `TriMesh`: on a 400k-triangle scan it holds about 100 MB at its peak
//! (64-byte f64 nodes, one leaf per triangle, a refit buffer of the same size, a copy of the
//! vertices and indices), which alone broke the whole run's memory budget (issue #8: 400 bytes
//! per input triangle). This tree has leaves of up to [`LEAF_SIZE`] triangles and 32-byte
//! nodes with `f32` boxes rounded outwards, so the boxes stay conservative for the `f64`
//! queries: about 8 MB for the same scan, positions read from the mesh itself.
//!
//! Queries are exact (the closest point of each candidate triangle is computed in `f64`,
//! [`closest_on_triangle`]) and deterministic: the tree does not depend on the thread count,
//! and the traversal order (nearer child first) only depends on the tree and the query.

use crate::geom::closest::Plane;
use crate::geom::closest_on_triangle;
use crate::mesh::Mesh;
use glam::DVec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// Triangles per leaf. Four keeps the tree small (a quarter of the nodes of one per leaf)
/// while a leaf's triangles are still cheap to test one after another.
pub const LEAF_SIZE: usize = 4;

/// Nodes a search may visit per level of the tree ([`TriangleBvh::budget`]). A search
/// for a point near a scan's surface visits a few nodes per level; this is far above what
/// any query of the metrics, the preview, `seam_fix` or texture follow needs on the scans
/// of ../shared/data (their largest is counted in tests/quadratic_corners.rs), and keeps
/// the worst case, overlapping triangles, at O(log n) per query.
pub const BUDGET_PER_LEVEL: u32 = 32;

/// Deepest tree the searches' fixed stack can walk: median splits halve the triangles at
/// every level, so a tree over `u32` triangle indices is at most 31 levels deep.
const MAX_DEPTH: usize = 64;

/// What one search cost.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct QueryCost {
    /// Nodes visited, inner and leaf.
    pub nodes: u32,
    /// Triangles whose closest point was computed (not those their plane ruled out,
    /// [`TriangleBvh::with_planes`]).
    pub triangles: u32,
}

/// The outcome of [`TriangleBvh::search`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Search {
    /// The nearest triangle found (`None` only for an empty index).
    pub hit: Option<TriangleHit>,
    /// Whether every node that could hold something nearer was visited, so that `hit` is
    /// the nearest; `false` when the search stopped at its budget.
    pub complete: bool,
    pub cost: QueryCost,
}

/// Triangles near a region, with their boxes ([`TriangleBvh::neighbourhood`]).
#[derive(Debug, Default)]
pub struct Neighbourhood {
    items: Vec<Near>,
}

impl Neighbourhood {
    pub fn len(&self) -> usize {
        self.items.len()
    }

    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }
}

/// The answer of [`TriangleBvh::closest_among`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Among {
    Nearest(TriangleHit),
    /// Two triangles are exactly as near.
    Tied,
    /// No triangle (an empty neighbourhood and no start).
    Empty,
}

#[derive(Debug, Clone, Copy)]
struct Near {
    /// Index into the tree's leaf order.
    leaf: u32,
    min: DVec3,
    max: DVec3,
}

/// A node: a box, and either two children (`count == 0`, at `first` and `first + 1`) or a
/// run of `count` triangles starting at `first` in [`DetachedTree::order`].
#[derive(Debug, Clone, Copy)]
struct Node {
    min: [f32; 3],
    max: [f32; 3],
    first: u32,
    count: u32,
}

impl Node {
    const EMPTY: Node = Node {
        min: [0.0; 3],
        max: [0.0; 3],
        first: 0,
        count: 0,
    };
}

/// The closest point of a triangle to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleHit {
    /// The mesh's triangle index.
    pub triangle: u32,
    pub point: DVec3,
    /// Weights of the triangle's corners 0, 1, 2.
    pub bary: DVec3,
    pub distance_squared: f64,
}

/// A [`TriangleBvh`] without its mesh ([`TriangleBvh::detach`]): everything the tree holds.
#[derive(Default)]
pub struct DetachedTree {
    /// The indexed mesh's counts, checked when the tree is put back ([`TriangleBvh::over`]).
    vertices: usize,
    triangles: usize,
    nodes: Vec<Node>,
    /// Mesh triangle indices in leaf order.
    order: Vec<u32>,
    /// The triangles' vertex indices in leaf order (one indirection less per test).
    corners: Vec<[u32; 3]>,
    /// The triangles' planes in leaf order, when asked for ([`TriangleBvh::with_planes`]);
    /// empty otherwise.
    planes: Vec<Plane>,
    /// Each node's cone of normals, when asked for ([`TriangleBvh::with_normal_cones`]);
    /// empty otherwise.
    cones: Vec<NormalCone>,
    /// Nodes one search may visit.
    budget: u32,
    /// Distances within this of each other are equal ([`TriangleBvh::facing`]).
    tie: f64,
}

pub struct TriangleBvh<'a> {
    mesh: &'a Mesh,
    tree: DetachedTree,
    /// Searches that stopped at the budget.
    cut_short: AtomicU64,
}

/// Two distances to the surface closer than this fraction of the indexed surface's
/// bounding-box diagonal are the same distance: the closest point on an edge shared by two
/// triangles, computed from each, differs by rounding only (around 1e-16 of the diagonal).
pub const TIE_FRACTION: f64 = 1e-9;

/// The largest `f32` not above `x`, and the smallest not below it.
fn f32_down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x { f.next_down() } else { f }
}

fn f32_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x { f.next_up() } else { f }
}

impl<'a> TriangleBvh<'a> {
    /// Indexes the given triangles of `mesh` (the caller leaves out those it does not want,
    /// e.g. zero-area ones). Positions must be finite.
    pub fn new(mesh: &'a Mesh, triangles: Vec<u32>) -> TriangleBvh<'a> {
        let mut items: Vec<Item> = triangles
            .par_iter()
            .map(|&t| {
                let [a, b, c] = mesh.triangle_positions(t as usize);
                let centroid = (a + b + c) / 3.0;
                (t, centroid.as_vec3().to_array())
            })
            .collect();
        let sizes = SubtreeSizes::new(items.len());
        let mut nodes = vec![Node::EMPTY; 1 + sizes.descendants(items.len())];
        let (root, descendants) = nodes.split_first_mut().expect("the root is always there");
        *root = split(&sizes, &mut items, 0, descendants, 1);
        let order: Vec<u32> = items.iter().map(|&(t, _)| t).collect();
        drop(items);
        let corners: Vec<[u32; 3]> = order
            .par_iter()
            .map(|&t| mesh.triangle_vertices(t as usize))
            .collect();
        fit_boxes(mesh, &mut nodes, &corners);
        let levels = depth(order.len()) + 1;
        let root = nodes[0];
        let diagonal = (DVec3::from_array(root.max.map(f64::from))
            - DVec3::from_array(root.min.map(f64::from)))
        .length();
        TriangleBvh {
            mesh,
            tree: DetachedTree {
                vertices: mesh.positions.len(),
                triangles: mesh.triangles.len(),
                nodes,
                order,
                corners,
                planes: Vec::new(),
                cones: Vec::new(),
                budget: BUDGET_PER_LEVEL * levels,
                tie: TIE_FRACTION * diagonal,
            },
            cut_short: AtomicU64::new(0),
        }
    }

    /// The tree without the mesh it indexes, to be kept apart from the borrow it was built
    /// under (the decimation step builds `seam_fix`'s tree over its input beside its
    /// collapse loop and hands it on) and put back over that mesh by [`TriangleBvh::over`].
    pub fn detach(mut self) -> DetachedTree {
        std::mem::take(&mut self.tree)
    }

    /// A detached tree over `mesh` again: the same tree, answering as it did.
    ///
    /// # Panics
    /// If `mesh` does not have the vertex and triangle counts of the mesh the tree was built
    /// over (a tree over another mesh would read out of its place).
    pub fn over(mesh: &'a Mesh, tree: DetachedTree) -> TriangleBvh<'a> {
        assert!(
            mesh.positions.len() == tree.vertices && mesh.triangles.len() == tree.triangles,
            "a detached tree is put back over the mesh it was built over"
        );
        TriangleBvh {
            mesh,
            tree,
            cut_short: AtomicU64::new(0),
        }
    }

    /// [`TriangleBvh::new`], with each triangle's plane kept beside it (32 bytes per
    /// triangle): a search then computes the closest point only of the leaf triangles
    /// whose plane is nearer than the best so far ([`Plane::farther_than`]), with the same
    /// answers. For a tree that answers many queries near its surface with a close first
    /// guess (the remesher's: on james a search tests 7 triangles, and the guess is the
    /// answer for 97 % of them); the metrics' and the fairing's trees, over 400,000-triangle
    /// scans, keep their memory instead (the whole face-scan run measured no faster).
    pub fn with_planes(mesh: &'a Mesh, triangles: Vec<u32>) -> TriangleBvh<'a> {
        let mut index = TriangleBvh::new(mesh, triangles);
        index.tree.planes = index
            .tree
            .corners
            .par_iter()
            .map(|t| Plane::of(t.map(|v| mesh.positions[v as usize])))
            .collect();
        index
    }

    /// The tree with each node's cone of normals (16 bytes per node), for
    /// [`TriangleBvh::all_facing_within`].
    pub fn with_normal_cones(mut self) -> TriangleBvh<'a> {
        self.tree.cones = normal_cones(self.mesh, &self.tree.nodes, &self.tree.corners);
        self
    }

    pub fn is_empty(&self) -> bool {
        self.tree.order.is_empty()
    }

    /// Triangles indexed.
    pub fn len(&self) -> usize {
        self.tree.order.len()
    }

    /// Bytes held by the index (not counting the mesh).
    pub fn heap_bytes(&self) -> usize {
        self.tree.nodes.capacity() * std::mem::size_of::<Node>()
            + self.tree.order.capacity() * 4
            + self.tree.corners.capacity() * 12
            + self.tree.planes.capacity() * std::mem::size_of::<Plane>()
            + self.tree.cones.capacity() * std::mem::size_of::<NormalCone>()
    }

    /// The closest point of the indexed surface to `p`. `start`, if given, is a candidate
    /// already known (e.g. from a nearby triangle): it bounds the search from the start, which
    /// prunes most of the tree. `None` only for an empty index.
    ///
    /// A search visits at most [`TriangleBvh::budget`] nodes; one that stops there returns
    /// the nearest triangle it has met, which is then an upper bound on the distance rather
    /// than proven nearest ([`TriangleBvh::search`] says which; the index counts them and
    /// logs their number when it is dropped).
    pub fn closest(&self, p: DVec3, start: Option<TriangleHit>) -> Option<TriangleHit> {
        self.search(p, start).hit
    }

    /// [`TriangleBvh::closest`], with whether the answer is proven and what it cost.
    ///
    /// The traversal is depth first, nearer child first, pruned by box distance against the
    /// best distance so far. That bound fails where boxes cannot separate the triangles:
    /// in a soup of large triangles crossing each other, or a fan of thin triangles around
    /// one vertex, nearly every box contains a query point on the surface, so an exact
    /// search would test nearly every triangle, and the metrics' hundreds of thousands of
    /// queries would cost time quadratic in the mesh. No search visits more than the budget
    /// of nodes, O(log n); on scans the searches end far below it (see [`BUDGET_PER_LEVEL`]).
    /// An early stop for a point on a triangle to rounding would spare most of that work on
    /// an unchanged soup, but it changes which of two triangles within rounding of a shared
    /// vertex answers (a texture seam), so outputs of scans would change: not done.
    pub fn search(&self, p: DVec3, start: Option<TriangleHit>) -> Search {
        // One traversal, compiled twice: a tree without planes runs the code it ran before
        // they existed. One function with both kinds of leaf loop (a test of the planes'
        // presence per triangle, or per leaf) made the fairing's step on face400k, a
        // million searches, 14 ms slower.
        if self.tree.planes.is_empty() {
            self.traverse::<false>(p, start)
        } else {
            self.traverse::<true>(p, start)
        }
    }

    /// [`TriangleBvh::search`], with the leaf triangles' planes read when `PLANES`.
    fn traverse<const PLANES: bool>(&self, p: DVec3, start: Option<TriangleHit>) -> Search {
        let mut cost = QueryCost::default();
        if self.tree.order.is_empty() {
            return Search {
                hit: None,
                complete: true,
                cost,
            };
        }
        let mut best = start;
        let mut best_d2 = best.map_or(f64::INFINITY, |h| h.distance_squared);
        // The tree is at most `depth` levels deep (median splits), so the stack of pending
        // far children never holds more than `depth` nodes.
        let mut stack = [0u32; MAX_DEPTH];
        let mut top = 0;
        let mut node = 0u32;
        loop {
            if cost.nodes >= self.tree.budget {
                self.cut_short.fetch_add(1, Ordering::Relaxed);
                return Search {
                    hit: best,
                    complete: false,
                    cost,
                };
            }
            cost.nodes += 1;
            let n = &self.tree.nodes[node as usize];
            if n.count > 0 {
                let first = n.first as usize;
                for i in first..first + n.count as usize {
                    if PLANES && self.tree.planes[i].farther_than(p, best_d2) {
                        continue;
                    }
                    cost.triangles += 1;
                    let hit = self.leaf_hit(i, p);
                    if hit.distance_squared < best_d2 {
                        best_d2 = hit.distance_squared;
                        best = Some(hit);
                    }
                }
            } else {
                let (l, r) = (n.first, n.first + 1);
                let dl = box_distance_squared(&self.tree.nodes[l as usize], p);
                let dr = box_distance_squared(&self.tree.nodes[r as usize], p);
                let (near, d_near, far, d_far) = if dl <= dr {
                    (l, dl, r, dr)
                } else {
                    (r, dr, l, dl)
                };
                if d_far < best_d2 {
                    stack[top] = far;
                    top += 1;
                }
                if d_near < best_d2 {
                    node = near;
                    continue;
                }
            }
            // Next pending node that can still hold something closer.
            loop {
                if top == 0 {
                    return Search {
                        hit: best,
                        complete: true,
                        cost,
                    };
                }
                top -= 1;
                node = stack[top];
                if box_distance_squared(&self.tree.nodes[node as usize], p) < best_d2 {
                    break;
                }
            }
        }
    }

    /// The indexed triangles whose boxes meet the box `lo..hi`, into `out` (cleared first),
    /// or `false` as soon as there are more than `limit`. For many queries of points inside a
    /// small region: [`TriangleBvh::closest_among`] then tests only these.
    pub fn neighbourhood(
        &self,
        lo: DVec3,
        hi: DVec3,
        limit: usize,
        out: &mut Neighbourhood,
    ) -> bool {
        out.items.clear();
        self.each_in_box(lo, hi, u32::MAX, |i| {
            let [a, b, c] = self.tree.corners[i].map(|v| self.mesh.positions[v as usize]);
            let (min, max) = (a.min(b).min(c), a.max(b).max(c));
            if !meets(min, max, lo, hi) {
                return true;
            }
            if out.items.len() == limit {
                return false;
            }
            out.items.push(Near {
                leaf: i as u32,
                min,
                max,
            });
            true
        })
    }

    /// Calls `visit` with the leaf-order index of every triangle in a leaf whose box meets
    /// `lo..hi`, in tree order, until `visit` answers `false` or `max_nodes` nodes have been
    /// visited; `false` when it stopped early either way.
    fn each_in_box(
        &self,
        lo: DVec3,
        hi: DVec3,
        max_nodes: u32,
        visit: impl FnMut(usize) -> bool,
    ) -> bool {
        let enter = |n: usize| {
            let n = &self.tree.nodes[n];
            let min = DVec3::from_array(n.min.map(f64::from));
            let max = DVec3::from_array(n.max.map(f64::from));
            meets(min, max, lo, hi)
        };
        self.each_entered(max_nodes, enter, visit)
    }

    /// Calls `visit` with the leaf-order index of every triangle in a leaf reached through
    /// nodes that `enter` (given a node's index) lets in, in tree order, until `visit`
    /// answers `false` or `max_nodes` nodes have been visited; `false` when it stopped early
    /// either way.
    fn each_entered(
        &self,
        max_nodes: u32,
        mut enter: impl FnMut(usize) -> bool,
        mut visit: impl FnMut(usize) -> bool,
    ) -> bool {
        if self.tree.order.is_empty() {
            return true;
        }
        let mut stack = [0u32; MAX_DEPTH];
        let mut top = 1;
        let mut visited = 0;
        while top > 0 {
            if visited == max_nodes {
                return false;
            }
            visited += 1;
            top -= 1;
            let node = stack[top] as usize;
            if !enter(node) {
                continue;
            }
            let n = &self.tree.nodes[node];
            if n.count == 0 {
                stack[top] = n.first;
                stack[top + 1] = n.first + 1;
                top += 2;
                continue;
            }
            let first = n.first as usize;
            if !(first..first + n.count as usize).all(&mut visit) {
                return false;
            }
        }
        true
    }

    /// The closest point to `p` of the triangles of `near`, `start` (if given) taken first.
    /// It is the closest of the whole index when `near` was gathered over a box that holds
    /// the ball around `p` whose radius is `p`'s distance to the surface (the caller's
    /// bound). Where another triangle is exactly as near, which one [`TriangleBvh::search`]
    /// would answer depends on its traversal, so the answer is `Tied` and the caller
    /// searches the tree to get the same one.
    pub fn closest_among(
        &self,
        p: DVec3,
        near: &Neighbourhood,
        start: Option<TriangleHit>,
    ) -> Among {
        let mut best = start;
        let mut best_d2 = best.map_or(f64::INFINITY, |h| h.distance_squared);
        let mut tied = false;
        for n in &near.items {
            let gap = (n.min - p).max(p - n.max).max(DVec3::ZERO);
            if gap.length_squared() > best_d2 {
                continue;
            }
            let hit = self.leaf_hit(n.leaf as usize, p);
            if hit.distance_squared < best_d2 {
                best_d2 = hit.distance_squared;
                tied = false;
                best = Some(hit);
            } else if hit.distance_squared == best_d2
                && best.is_some_and(|h| h.triangle != hit.triangle)
            {
                tied = true;
            }
        }
        match best {
            Some(hit) if !tied => Among::Nearest(hit),
            Some(_) => Among::Tied,
            None => Among::Empty,
        }
    }

    /// Nodes one search may visit: [`BUDGET_PER_LEVEL`] per level of this tree.
    pub fn budget(&self) -> u32 {
        self.tree.budget
    }

    /// Searches so far that stopped at the budget (their answers are upper bounds).
    pub fn cut_short(&self) -> u64 {
        self.cut_short.load(Ordering::Relaxed)
    }

    /// The closest point to `p` of the triangle at `i` in leaf order.
    #[inline]
    fn leaf_hit(&self, i: usize, p: DVec3) -> TriangleHit {
        let [a, b, c] = self.tree.corners[i].map(|v| self.mesh.positions[v as usize]);
        let (point, bary) = closest_on_triangle(p, a, b, c);
        TriangleHit {
            triangle: self.tree.order[i],
            point,
            bary,
            distance_squared: point.distance_squared(p),
        }
    }

    /// Of the indexed triangles as near to `p` as `hit` (its closest point), the one whose
    /// normal is nearest to `normal` (by the angle between them).
    ///
    /// Where the closest point lies on an edge or a corner of `hit`'s triangle, the
    /// triangles around that edge or corner are all as near, and at a crease or a fold they
    /// face different ways: which one a search answers depends on its traversal, so a test
    /// of a face's orientation against "the surface's normal at its closest point" must
    /// look at all of them (the normal of a surface at a crease is not one direction but
    /// the range of its faces' normals). Inside a triangle the answer is `hit`'s own
    /// triangle, without a search. Zero-area triangles have no normal and are not chosen
    /// over one that has. The search visits at most [`TriangleBvh::budget`] nodes; past it
    /// the best so far is the answer (overlapping triangles only).
    pub fn facing(&self, p: DVec3, hit: &TriangleHit, normal: DVec3) -> u32 {
        if hit.bary.min_element() > 0.0 {
            return hit.triangle;
        }
        let reach = hit.distance_squared.sqrt() + self.tree.tie;
        let score = |t: u32| {
            self.mesh
                .triangle_cross(t as usize)
                .normalize_or_zero()
                .dot(normal)
        };
        let mut best = (score(hit.triangle), hit.triangle);
        self.each_in_box(
            p - DVec3::splat(reach),
            p + DVec3::splat(reach),
            self.tree.budget,
            |i| {
                let near = self.leaf_hit(i, p);
                if near.triangle != hit.triangle && near.distance_squared.sqrt() <= reach {
                    let s = score(near.triangle);
                    // The lower index on equal scores: the answer does not depend on the tree.
                    if s > best.0 || (s == best.0 && near.triangle < best.1) {
                        best = (s, near.triangle);
                    }
                }
                true
            },
        );
        best.1
    }

    /// Whether every indexed triangle whose closest point to `p` is within `√d2` (and
    /// [`DetachedTree::tie`]) faces the way of `normal` (`normal · m > 0`, `m` its
    /// unnormalised normal) or has no area. Then whichever of them is closest to `p` faces
    /// that way, without finding it: a node is passed over when its box is farther or its
    /// cone of normals lies within 90° of `normal`, and only a triangle turned the other
    /// way needs its closest point. `false` when one such triangle is near enough, when the
    /// search passes its budget, or without cones ([`TriangleBvh::with_normal_cones`]).
    pub fn all_facing_within(&self, p: DVec3, d2: f64, normal: DVec3) -> bool {
        let unit = normal.normalize_or_zero();
        if self.tree.cones.is_empty() || unit == DVec3::ZERO || self.tree.order.is_empty() {
            return false;
        }
        let reach = d2.sqrt() + self.tree.tie;
        let reach2 = reach * reach;
        let enter = |node: usize| {
            box_distance_squared(&self.tree.nodes[node], p) <= reach2
                && !self.tree.cones[node].faces(unit)
        };
        // A triangle turned the other way and near enough stops the walk.
        self.each_entered(self.tree.budget, enter, |i| {
            let [a, b, c] = self.tree.corners[i].map(|v| self.mesh.positions[v as usize]);
            let m = (b - a).cross(c - a);
            m == DVec3::ZERO || normal.dot(m) > 0.0 || self.leaf_hit(i, p).distance_squared > reach2
        })
    }

    /// The closest point of triangle `t` of the mesh (indexed or not) to `p`.
    pub fn hit_on(&self, p: DVec3, t: u32) -> TriangleHit {
        let [a, b, c] = self.mesh.triangle_positions(t as usize);
        let (point, bary) = closest_on_triangle(p, a, b, c);
        TriangleHit {
            triangle: t,
            point,
            bary,
            distance_squared: point.distance_squared(p),
        }
    }
}

/// The directions of the normals under a node: every unit normal of a triangle with area
/// below it is within the half-angle `h` of `axis`, stored as `sin h` (`h` under 90°).
/// A node with no such triangle has [`NormalCone::NONE`]; one whose normals are not within
/// less than 90° of one direction has [`NormalCone::ALL`].
#[derive(Debug, Clone, Copy, PartialEq)]
struct NormalCone {
    axis: [f32; 3],
    sin_half: f32,
}

/// Rounding allowance of a cone's test: the axis is stored in `f32` (about 1e-7 off the
/// `f64` axis the cone was made around, and off unit length), and a merge's cosines carry
/// rounding of about 1e-8 in angle; a normal this close to the cone's edge is not vouched
/// for.
const CONE_MARGIN: f64 = 1e-5;

/// What a cone's half-angle cosine is lowered by at each merge, above its rounding.
const CONE_WIDENING: f64 = 1e-7;

impl NormalCone {
    const NONE: NormalCone = NormalCone {
        axis: [0.0; 3],
        sin_half: -2.0,
    };
    const ALL: NormalCone = NormalCone {
        axis: [0.0; 3],
        sin_half: 2.0,
    };

    /// Every normal in the cone is within 90° of the unit vector `unit`, with a margin:
    /// the angle from the axis plus the half-angle is under 90°.
    #[inline]
    fn faces(&self, unit: DVec3) -> bool {
        let axis = DVec3::new(
            self.axis[0] as f64,
            self.axis[1] as f64,
            self.axis[2] as f64,
        );
        unit.dot(axis) > f64::from(self.sin_half) + CONE_MARGIN
    }
}

/// A cone of normals while the cones are made, in `f64`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Cone {
    /// No triangle with area below.
    None,
    /// Normals around the unit `axis` within the half-angle whose cosine and sine these
    /// are (the angle under 90°).
    Around { axis: DVec3, cos: f64, sin: f64 },
    /// Normals not within less than 90° of one direction.
    All,
}

impl Cone {
    /// The cone around unit `axis` with half-angle cosine `cos` (widened; [`Cone::All`]
    /// when that is 90° or more).
    fn around(axis: DVec3, cos: f64) -> Cone {
        let cos = cos.min(1.0) - CONE_WIDENING;
        if cos <= 0.0 || !axis.is_finite() {
            return Cone::All;
        }
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        Cone::Around { axis, cos, sin }
    }

    /// The cone of a leaf's triangles (`corners`).
    fn of_leaf(mesh: &Mesh, corners: &[[u32; 3]]) -> Cone {
        let mut units = [DVec3::ZERO; LEAF_SIZE];
        let mut k = 0;
        for t in corners {
            let [a, b, c] = t.map(|v| mesh.positions[v as usize]);
            let m = (b - a).cross(c - a);
            match m.try_normalize() {
                Some(unit) => {
                    units[k] = unit;
                    k += 1;
                }
                // A normal too small to normalise still has a way: no cone vouches.
                None if m != DVec3::ZERO => return Cone::All,
                None => {}
            }
        }
        let units = &units[..k];
        if units.is_empty() {
            return Cone::None;
        }
        let Some(axis) = units.iter().sum::<DVec3>().try_normalize() else {
            return Cone::All;
        };
        Cone::around(axis, units.iter().map(|m| m.dot(axis)).fold(1.0, f64::min))
    }

    /// The cone holding `l` and `r`.
    fn merge(l: Cone, r: Cone) -> Cone {
        match (l, r) {
            (Cone::None, c) | (c, Cone::None) => c,
            (Cone::All, _) | (_, Cone::All) => Cone::All,
            (
                Cone::Around {
                    axis: al,
                    cos: cl,
                    sin: sl,
                },
                Cone::Around {
                    axis: ar,
                    cos: cr,
                    sin: sr,
                },
            ) => {
                let Some(axis) = (al + ar).try_normalize() else {
                    return Cone::All;
                };
                // cos(θ + h) of each child: θ the angle from the new axis to the child's,
                // h the child's half-angle; both under 90°, so the sum is under 90° when
                // this is positive.
                let reach = |a: DVec3, cos_h: f64, sin_h: f64| {
                    let cos_t = axis.dot(a);
                    if cos_t <= 0.0 {
                        return -1.0;
                    }
                    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
                    cos_t * cos_h - sin_t * sin_h
                };
                Cone::around(axis, reach(al, cl, sl).min(reach(ar, cr, sr)))
            }
        }
    }

    /// As stored: the axis in `f32`, the sine rounded up.
    fn stored(self) -> NormalCone {
        match self {
            Cone::None => NormalCone::NONE,
            Cone::All => NormalCone::ALL,
            Cone::Around { axis, sin, .. } => NormalCone {
                axis: axis.as_vec3().to_array(),
                sin_half: f32_up(sin),
            },
        }
    }
}

/// Each node's [`NormalCone`]: leaves from their triangles, inner nodes from their
/// children's cones, a level of the tree at a time from the deepest (each level in
/// parallel; children come after their parent in `nodes`).
fn normal_cones(mesh: &Mesh, nodes: &[Node], corners: &[[u32; 3]]) -> Vec<NormalCone> {
    if corners.is_empty() {
        // The root of an empty index, a leaf of nothing.
        return vec![NormalCone::NONE; nodes.len()];
    }
    let mut cones: Vec<Cone> = nodes
        .par_iter()
        .map(|n| {
            let first = n.first as usize;
            if n.count > 0 {
                Cone::of_leaf(mesh, &corners[first..first + n.count as usize])
            } else {
                Cone::None
            }
        })
        .collect();
    let mut depth = vec![0u32; nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        if n.count == 0 {
            let d = depth[i] + 1;
            depth[n.first as usize] = d;
            depth[n.first as usize + 1] = d;
        }
    }
    let deepest = depth.iter().copied().max().unwrap_or(0);
    let mut inner_at: Vec<Vec<u32>> = vec![Vec::new(); deepest as usize + 1];
    for (i, n) in nodes.iter().enumerate() {
        if n.count == 0 {
            inner_at[depth[i] as usize].push(i as u32);
        }
    }
    for level in inner_at.iter().rev() {
        let merged: Vec<Cone> = level
            .par_iter()
            .map(|&i| {
                let c = nodes[i as usize].first as usize;
                Cone::merge(cones[c], cones[c + 1])
            })
            .collect();
        for (&i, cone) in level.iter().zip(merged) {
            cones[i as usize] = cone;
        }
    }
    cones.into_par_iter().map(Cone::stored).collect()
}

/// The box `min..max` meets the box `lo..hi` (touching counts).
#[inline]
fn meets(min: DVec3, max: DVec3, lo: DVec3, hi: DVec3) -> bool {
    min.cmple(hi).all() && max.cmpge(lo).all()
}

/// Levels below the root of the tree over `len` triangles (median splits, leaves of up to
/// [`LEAF_SIZE`]).
fn depth(len: usize) -> u32 {
    let mut d = 0;
    let mut len = len;
    while len > LEAF_SIZE {
        len = len.div_ceil(2);
        d += 1;
    }
    debug_assert!((d as usize) < MAX_DEPTH);
    d
}

impl Drop for TriangleBvh<'_> {
    /// The searches cut short are said once per index, when it goes: the answers they gave
    /// are upper bounds, and the log is where an operator looks for why a figure is.
    fn drop(&mut self) {
        let cut_short = self.cut_short();
        if cut_short > 0 {
            tracing::warn!(
                searches = cut_short,
                triangles = self.tree.order.len(),
                budget_nodes = self.tree.budget,
                "closest-point searches stopped at their budget: the triangles overlap so that \
                 no box separates them; those answers are the nearest triangle found, an upper \
                 bound on the distance"
            );
        }
    }
}

/// Node counts of the subtrees `build` makes: they depend only on the number of triangles
/// (every split is at the median), so each subtree's place in the node array is known before
/// it is built, and the halves can be built in parallel into their own parts of the array.
/// At every depth the subtrees have one of two sizes (⌊n/2^d⌋ or one more), so the table is
/// small.
struct SubtreeSizes(rustc_hash::FxHashMap<usize, usize>);

impl SubtreeSizes {
    fn new(len: usize) -> SubtreeSizes {
        fn fill(len: usize, table: &mut rustc_hash::FxHashMap<usize, usize>) -> usize {
            if len <= LEAF_SIZE {
                return 0;
            }
            if let Some(&d) = table.get(&len) {
                return d;
            }
            let mid = len / 2;
            let d = 2 + fill(mid, table) + fill(len - mid, table);
            table.insert(len, d);
            d
        }
        let mut table = rustc_hash::FxHashMap::default();
        fill(len, &mut table);
        SubtreeSizes(table)
    }

    /// Nodes below the root of a subtree over `len` triangles.
    fn descendants(&self, len: usize) -> usize {
        if len <= LEAF_SIZE { 0 } else { self.0[&len] }
    }
}

/// Subtrees at least this large build their halves in parallel.
const PARALLEL_BUILD: usize = 1 << 14;

/// A triangle and its centroid, rounded to `f32`, while the tree is built.
type Item = (u32, [f32; 3]);

/// Splits the subtree over `items` (sorting them into leaf order) and returns its root, box
/// not yet set ([`fit_boxes`]); `items` starts at `first_item` of the whole list, and the
/// subtree's descendants go into `below`, which is the node array from index `offset` on.
/// Layout: a node's two children sit side by side at the start of its part of the array,
/// followed by the left child's descendants and then the right child's.
///
/// The tree does not depend on how the median is selected. Every split is at the median of
/// a total order (centroid along the axis, then triangle index), so each node's triangles are
/// the same set whatever the selection algorithm; and the order within a leaf is that of its
/// parent's selection, which has at most 2 × [`LEAF_SIZE`] + 1 items and so sorts them fully
/// (the standard library's selection sorts slices this short outright). The tree is that of
/// sorting every node's triangles fully (tested below).
fn split(
    sizes: &SubtreeSizes,
    items: &mut [Item],
    first_item: usize,
    below: &mut [Node],
    offset: usize,
) -> Node {
    if items.len() <= LEAF_SIZE {
        return Node {
            first: first_item as u32,
            count: items.len() as u32,
            ..Node::EMPTY
        };
    }
    // Split at the median centroid along the axis where the centroids spread most.
    let mid = items.len() / 2;
    select_median(items, mid, widest_centroid_axis(items));
    let (left_items, right_items) = items.split_at_mut(mid);
    let (pair, rest) = below.split_at_mut(2);
    let (left_below, right_below) = rest.split_at_mut(sizes.descendants(mid));
    let right_offset = offset + 2 + left_below.len();
    let right_first = first_item + mid;
    let parallel = left_items.len() + right_items.len() >= PARALLEL_BUILD;
    let mut left = || split(sizes, left_items, first_item, left_below, offset + 2);
    let mut right = || split(sizes, right_items, right_first, right_below, right_offset);
    let (left, right) = if parallel {
        rayon::join(left, right)
    } else {
        (left(), right())
    };
    pair[0] = left;
    pair[1] = right;
    Node {
        first: offset as u32,
        count: 0,
        ..Node::EMPTY
    }
}

/// An `f32`'s bits, mapped so that their unsigned order is [`f32::total_cmp`]'s.
#[inline(always)]
fn ordered_bits(x: f32) -> u32 {
    let b = x.to_bits();
    if b >> 31 == 1 { !b } else { b | 0x8000_0000 }
}

/// The build's sort key along axis `A`: centroid, then triangle index, as one integer (one
/// comparison instead of a float comparison and a tie-break: the selections are most of the
/// build's time).
#[inline(always)]
fn split_key<const A: usize>(item: &Item) -> u64 {
    (u64::from(ordered_bits(item.1[A])) << 32) | u64::from(item.0)
}

/// Puts the `mid` smallest items by [`split_key`] along `axis` first.
fn select_median(items: &mut [Item], mid: usize, axis: usize) {
    match axis {
        0 => items.select_nth_unstable_by_key(mid, split_key::<0>),
        1 => items.select_nth_unstable_by_key(mid, split_key::<1>),
        _ => items.select_nth_unstable_by_key(mid, split_key::<2>),
    };
}

/// Sets every box once the tree's shape and leaf order are known: a leaf's from its
/// triangles' corners (read through `corners`, one indirection less than the mesh's
/// triangles), rounded outwards to `f32`, in parallel; then each inner node's as the union
/// of its children's, which is the same box as rounding the union of the corners (rounding
/// is monotone). Children sit after their parent in the array, so one backward pass does.
fn fit_boxes(mesh: &Mesh, nodes: &mut [Node], corners: &[[u32; 3]]) {
    if corners.is_empty() {
        // The root of an empty index, a leaf of nothing: the empty box.
        nodes[0].min = [f32::INFINITY; 3];
        nodes[0].max = [f32::NEG_INFINITY; 3];
        return;
    }
    nodes.par_iter_mut().filter(|n| n.count > 0).for_each(|n| {
        let mut min = DVec3::INFINITY;
        let mut max = DVec3::NEG_INFINITY;
        let first = n.first as usize;
        for c in &corners[first..first + n.count as usize] {
            for &v in c {
                let p = mesh.positions[v as usize];
                min = min.min(p);
                max = max.max(p);
            }
        }
        n.min = [f32_down(min.x), f32_down(min.y), f32_down(min.z)];
        n.max = [f32_up(max.x), f32_up(max.y), f32_up(max.z)];
    });
    for i in (0..nodes.len()).rev() {
        let n = nodes[i];
        if n.count == 0 {
            let (l, r) = (nodes[n.first as usize], nodes[n.first as usize + 1]);
            nodes[i].min = [0, 1, 2].map(|k| l.min[k].min(r.min[k]));
            nodes[i].max = [0, 1, 2].map(|k| l.max[k].max(r.max[k]));
        }
    }
}

/// The axis along which the centroids spread most. Centroids are never NaN (positions are
/// finite), so plain vector minima and maxima give the same extents as `f32::min`/`max`.
fn widest_centroid_axis(items: &[Item]) -> usize {
    let mut min = glam::Vec3A::INFINITY;
    let mut max = glam::Vec3A::NEG_INFINITY;
    for (_, c) in items {
        let c = glam::Vec3A::from_array(*c);
        min = min.min(c);
        max = max.max(c);
    }
    let extent = max - min;
    if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    }
}

/// Squared distance from `p` to the node's box (0 inside).
#[inline]
fn box_distance_squared(n: &Node, p: DVec3) -> f64 {
    let lo = DVec3::new(n.min[0] as f64, n.min[1] as f64, n.min[2] as f64);
    let hi = DVec3::new(n.max[0] as f64, n.max[1] as f64, n.max[2] as f64);
    let d = (lo - p).max(p - hi).max(DVec3::ZERO);
    d.length_squared()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::{grid, uv_sphere};
    use crate::metrics::surface::rng;
    use crate::testing::on_threads;
    use rand::RngExt;

    fn brute_force(mesh: &Mesh, p: DVec3) -> f64 {
        (0..mesh.triangles.len())
            .map(|t| {
                let [a, b, c] = mesh.triangle_positions(t);
                closest_on_triangle(p, a, b, c).0.distance_squared(p)
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn triangle_regions() {
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        let cases = [
            (DVec3::new(0.25, 0.25, 1.0), DVec3::new(0.25, 0.25, 0.0)),
            (DVec3::new(-1.0, -1.0, 0.0), a),
            (DVec3::new(2.0, -0.5, 0.0), b),
            (DVec3::new(-0.1, 3.0, 0.0), c),
            (DVec3::new(0.5, -1.0, 0.0), DVec3::new(0.5, 0.0, 0.0)),
            (DVec3::new(-1.0, 0.5, 0.0), DVec3::new(0.0, 0.5, 0.0)),
            (DVec3::new(1.0, 1.0, 0.0), DVec3::new(0.5, 0.5, 0.0)),
        ];
        for (p, want) in cases {
            let (got, bary) = closest_on_triangle(p, a, b, c);
            assert!((got - want).length() < 1e-15, "{p}: {got} vs {want}");
            assert!((bary.element_sum() - 1.0).abs() < 1e-15);
            let back = a * bary.x + b * bary.y + c * bary.z;
            assert!((back - got).length() < 1e-15);
        }
        // Degenerate triangles still give a point on them.
        let (got, _) = closest_on_triangle(DVec3::new(0.5, 1.0, 0.0), a, b, b);
        assert!((got - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-15);
    }

    /// A page folded back over itself along x = 0: a point beside the fold is as near to
    /// both triangles (on their shared edge), and `facing` answers the one that faces the
    /// given way, whichever the search found; a point above the inside of one triangle has
    /// that triangle as its only answer.
    #[test]
    fn facing_at_a_fold() {
        let mesh = Mesh {
            positions: vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(0.8, 0.5, 0.3)],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            wedges: (0..4)
                .map(|vertex| crate::mesh::Wedge {
                    vertex,
                    texcoord: None,
                    normal: None,
                })
                .collect(),
            ..Mesh::default()
        };
        let (up, folded) = (mesh.triangle_cross(0), mesh.triangle_cross(1));
        assert!(up.dot(folded) < 0.0, "the second triangle is folded back");
        let bvh = TriangleBvh::new(&mesh, vec![0, 1]);
        let beside = DVec3::new(-0.5, 0.5, 0.0);
        let hit = bvh.closest(beside, None).unwrap();
        assert!((hit.point - DVec3::new(0.0, 0.5, 0.0)).length() < 1e-12);
        for start in [0, 1] {
            let hit = bvh.hit_on(beside, start);
            assert_eq!(bvh.facing(beside, &hit, up.normalize()), 0);
            assert_eq!(bvh.facing(beside, &hit, folded.normalize()), 1);
        }
        let above = DVec3::new(0.5, 0.1, 0.01);
        let hit = bvh.closest(above, None).unwrap();
        assert_eq!(hit.triangle, 0);
        assert_eq!(bvh.facing(above, &hit, folded.normalize()), 0);
    }

    #[test]
    fn matches_brute_force() {
        for mesh in [uv_sphere(1.0, 12, 20), grid(7, 5)] {
            let all: Vec<u32> = (0..mesh.triangles.len() as u32).collect();
            let bvh = TriangleBvh::new(&mesh, all);
            let mut r = rng(11);
            for _ in 0..2000 {
                let p = DVec3::new(r.random(), r.random(), r.random()) * 8.0 - 2.0;
                let hit = bvh.closest(p, None).unwrap();
                assert_eq!(hit.distance_squared, brute_force(&mesh, p), "{p}");
                // A start candidate never changes the distance found.
                let start = bvh.hit_on(p, (hit.triangle + 7) % mesh.triangles.len() as u32);
                let hinted = bvh.closest(p, Some(start)).unwrap();
                assert_eq!(hinted.distance_squared, hit.distance_squared);
            }
        }
    }

    /// A tree built on another thread, detached and put back over its mesh, answers every
    /// search as the tree did: same triangle, point, distance and cost.
    #[test]
    fn a_detached_tree_put_back_answers_as_before() {
        let mesh = uv_sphere(1.0, 12, 20);
        let all: Vec<u32> = (0..mesh.triangles.len() as u32).collect();
        let tree = TriangleBvh::new(&mesh, all.clone());
        let detached = std::thread::scope(|s| {
            s.spawn(|| TriangleBvh::new(&mesh, all).detach())
                .join()
                .unwrap()
        });
        let again = TriangleBvh::over(&mesh, detached);
        let mut r = rng(3);
        for _ in 0..500 {
            let p = DVec3::new(r.random(), r.random(), r.random()) * 4.0 - 2.0;
            assert_eq!(tree.search(p, None), again.search(p, None), "{p}");
        }
    }

    #[test]
    #[should_panic(expected = "the mesh it was built over")]
    fn a_detached_tree_is_not_put_over_another_mesh() {
        let (mesh, other) = (uv_sphere(1.0, 12, 20), uv_sphere(1.0, 12, 21));
        let tree = TriangleBvh::new(&mesh, (0..mesh.triangles.len() as u32).collect()).detach();
        let _ = TriangleBvh::over(&other, tree);
    }

    /// Points of a small region, tested against the triangles whose boxes meet the region
    /// grown by the points' distance bound: the answer is the tree search's, to the bit,
    /// unless two triangles are exactly as near (then `Tied`, and they are). On the grid,
    /// points straight above its vertices and edges make such ties; at random points there
    /// are none.
    /// The planes change which triangles a search computes, never its answer: the same
    /// triangle, point and distance for points off and on the surface, with and without a
    /// first guess.
    #[test]
    fn planes_change_no_answer() {
        let mut mesh = uv_sphere(1.0, 24, 40);
        let mut r = rng(5);
        for p in mesh.positions.iter_mut() {
            *p *= 1.0 + 0.05 * r.random::<f64>();
        }
        let all: Vec<u32> = (0..mesh.triangles.len() as u32).collect();
        let plain = TriangleBvh::new(&mesh, all.clone());
        let planes = TriangleBvh::with_planes(&mesh, all);
        let (mut tested_plain, mut tested_planes) = (0, 0);
        for i in 0..4000 {
            let t = r.random_range(0..mesh.triangles.len());
            let [a, b, c] = mesh.triangle_positions(t);
            let on = (a + b + c) / 3.0;
            let p = match i % 3 {
                0 => on,
                1 => on * (1.0 + 0.01 * r.random::<f64>()),
                _ => DVec3::new(r.random(), r.random(), r.random()) * 3.0 - 1.5,
            };
            let start = (i % 2 == 0).then(|| plain.hit_on(p, t as u32));
            let (x, y) = (plain.search(p, start), planes.search(p, start));
            assert_eq!(x.hit, y.hit, "{p}");
            tested_plain += x.cost.triangles;
            tested_planes += y.cost.triangles;
        }
        // Many leaf triangles are ruled out by their plane (a third here).
        assert!(
            4 * tested_planes < 3 * tested_plain,
            "{tested_planes} of {tested_plain}"
        );
    }

    /// A sphere with radii jittered by up to `jitter` and every `turn`-th triangle turned
    /// inside out: normals that point every way, as at a scan's folds.
    fn crumpled(jitter: f64, turn: usize) -> Mesh {
        let mut mesh = uv_sphere(1.0, 24, 40);
        let mut r = rng(7);
        for p in mesh.positions.iter_mut() {
            *p *= 1.0 + jitter * r.random::<f64>();
        }
        for t in mesh.triangles.iter_mut().step_by(turn) {
            t.swap(1, 2);
        }
        mesh
    }

    /// The leaf-order range of each node's triangles.
    fn ranges(bvh: &TriangleBvh) -> Vec<std::ops::Range<usize>> {
        let mut out = vec![0..0; bvh.tree.nodes.len()];
        for i in (0..bvh.tree.nodes.len()).rev() {
            let n = bvh.tree.nodes[i];
            let first = n.first as usize;
            out[i] = if n.count > 0 {
                first..first + n.count as usize
            } else {
                out[first].start..out[first + 1].end
            };
        }
        out
    }

    #[test]
    fn normal_cones_hold_their_triangles() {
        let mut r = rng(11);
        for mesh in [crumpled(0.02, 1000), crumpled(0.3, 7), grid(7, 5)] {
            let all: Vec<u32> = (0..mesh.triangles.len() as u32).collect();
            let bvh = TriangleBvh::new(&mesh, all).with_normal_cones();
            let ranges = ranges(&bvh);
            let mut vouched = 0;
            for _ in 0..200 {
                let n = DVec3::new(r.random(), r.random(), r.random()) * 2.0 - 1.0;
                let n = n.normalize();
                for (node, range) in ranges.iter().enumerate() {
                    if !bvh.tree.cones[node].faces(n) {
                        continue;
                    }
                    vouched += 1;
                    for i in range.clone() {
                        let m = mesh.triangle_cross(bvh.tree.order[i] as usize);
                        assert!(n.dot(m) > 0.0, "node {node}: {m} against {n}");
                    }
                }
            }
            assert!(vouched > 1000, "{vouched}");
        }
        // An empty index has cones too, and vouches for nothing.
        let mesh = grid(3, 3);
        let empty = TriangleBvh::new(&mesh, Vec::new()).with_normal_cones();
        assert!(!empty.all_facing_within(DVec3::ZERO, 1.0, DVec3::Z));
    }

    #[test]
    fn all_facing_within_vouches_only_when_every_near_triangle_faces() {
        let mesh = crumpled(0.1, 13);
        let all: Vec<u32> = (0..mesh.triangles.len() as u32).collect();
        let plain = TriangleBvh::new(&mesh, all.clone());
        let bvh = TriangleBvh::new(&mesh, all).with_normal_cones();
        let mut r = rng(3);
        let distance2 = |p: DVec3, u: usize| {
            let [a, b, c] = mesh.triangle_positions(u);
            closest_on_triangle(p, a, b, c).0.distance_squared(p)
        };
        let (mut asked, mut vouched) = (0, 0);
        for i in 0..3000 {
            let t = r.random_range(0..mesh.triangles.len());
            let [a, b, c] = mesh.triangle_positions(t);
            let p = (a + b + c) / 3.0 * (1.0 + 0.01 * (r.random::<f64>() - 0.5));
            let d2 = distance2(p, t) * [1.0, 4.0, 100.0][i % 3];
            let n = if i % 5 == 0 {
                DVec3::new(r.random(), r.random(), r.random()) - 0.5
            } else {
                mesh.triangle_cross(t)
            };
            // Without cones nothing is vouched for.
            assert!(!plain.all_facing_within(p, d2, n));
            asked += 1;
            if !bvh.all_facing_within(p, d2, n) {
                continue;
            }
            vouched += 1;
            for u in 0..mesh.triangles.len() {
                if distance2(p, u) <= d2 {
                    let m = mesh.triangle_cross(u);
                    assert!(n.dot(m) > 0.0, "triangle {u} near {p} turned from {n}");
                }
            }
        }
        // Where the surface is smooth around the query, the answer is yes.
        assert!(2 * vouched > asked, "{vouched} of {asked}");
    }

    #[test]
    fn closest_among_a_neighbourhood_is_the_tree_search() {
        let mesh = grid(9, 9);
        let bvh = TriangleBvh::new(&mesh, (0..mesh.triangles.len() as u32).collect());
        let mut near = Neighbourhood::default();
        let mut r = rng(5);
        let (mut nearest, mut tied) = (0, 0);
        for k in 0..400 {
            // A region of side 0.5 at height up to 0.3 over the grid; every point in it is
            // within 0.3 + the region's diagonal of the surface.
            let corner = DVec3::new(r.random::<f64>() * 8.0, r.random::<f64>() * 8.0, 0.0);
            // Every other region starts at a grid vertex, for the points over its lines.
            let corner = if k % 2 == 0 { corner.floor() } else { corner };
            let reach = 0.3 + 0.5 * 3f64.sqrt();
            let (lo, hi) = (corner, corner + DVec3::new(0.5, 0.5, 0.3));
            assert!(bvh.neighbourhood(lo - reach, hi + reach, 1000, &mut near));
            assert!(near.len() < mesh.triangles.len());
            for i in 0..10 {
                let offset = if k % 2 == 0 {
                    // On a grid line, over a vertex when i is even.
                    DVec3::new(0.0, if i % 2 == 0 { 0.0 } else { 0.25 }, 0.1)
                } else {
                    DVec3::new(r.random(), r.random(), r.random()) * DVec3::new(0.5, 0.5, 0.3)
                };
                let p = corner + offset;
                let tree = bvh.closest(p, None).unwrap();
                match bvh.closest_among(p, &near, None) {
                    Among::Nearest(hit) => {
                        assert_eq!(hit, tree, "{p}");
                        nearest += 1;
                    }
                    Among::Tied => {
                        let ties = (0..mesh.triangles.len())
                            .filter(|&t| {
                                bvh.hit_on(p, t as u32).distance_squared == tree.distance_squared
                            })
                            .count();
                        assert!(ties >= 2, "{p}: tied with {ties} triangle(s)");
                        tied += 1;
                    }
                    Among::Empty => panic!("{p}: no triangle near"),
                }
            }
        }
        assert!(
            nearest > 1000 && tied > 50,
            "{nearest} nearest, {tied} tied"
        );
        // More than `limit` triangles: refused.
        assert!(!bvh.neighbourhood(DVec3::splat(-1.0), DVec3::splat(10.0), 10, &mut near));
    }

    /// The tree over a mesh large enough for the parallel build: every triangle in exactly
    /// one leaf, every box the union of its children's, and the same tree on one thread as
    /// on two.
    #[test]
    fn parallel_build_is_a_valid_tree_whatever_the_threads() {
        let mesh = uv_sphere(1.0, 120, 160);
        let n = mesh.triangles.len();
        assert!(n > 2 * PARALLEL_BUILD);
        let all: Vec<u32> = (0..n as u32).collect();
        let build_on = |threads| {
            on_threads(threads, || {
                let bvh = TriangleBvh::new(&mesh, all.clone());
                let nodes: Vec<_> = bvh
                    .tree
                    .nodes
                    .iter()
                    .map(|n| (n.min, n.max, n.first, n.count))
                    .collect();
                (nodes, bvh.tree.order.clone())
            })
        };
        let (one, two) = (build_on(1), build_on(2));
        assert_eq!(one, two);
        let bvh = TriangleBvh::new(&mesh, all);
        let mut seen = vec![0u32; n];
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let node = bvh.tree.nodes[i];
            if node.count > 0 {
                assert!(node.count as usize <= LEAF_SIZE);
                for j in node.first..node.first + node.count {
                    seen[bvh.tree.order[j as usize] as usize] += 1;
                }
                continue;
            }
            let (l, r) = (
                bvh.tree.nodes[node.first as usize],
                bvh.tree.nodes[node.first as usize + 1],
            );
            for k in 0..3 {
                assert_eq!(node.min[k], l.min[k].min(r.min[k]));
                assert_eq!(node.max[k], l.max[k].max(r.max[k]));
            }
            stack.extend([node.first as usize, node.first as usize + 1]);
        }
        assert!(seen.iter().all(|&s| s == 1), "every triangle in one leaf");
    }

    /// The tree is the one of sorting every node's triangles fully before splitting it (see
    /// `split`): however the median is selected, the same leaves in the same order.
    #[test]
    fn tree_is_that_of_full_sorts() {
        fn sorted(items: &mut [Item]) {
            if items.len() <= LEAF_SIZE {
                return;
            }
            let axis = widest_centroid_axis(items);
            items.sort_by(|a, b| a.1[axis].total_cmp(&b.1[axis]).then(a.0.cmp(&b.0)));
            let (left, right) = items.split_at_mut(items.len() / 2);
            sorted(left);
            sorted(right);
        }
        for mesh in [uv_sphere(1.0, 120, 160), grid(9, 7)] {
            let n = mesh.triangles.len() as u32;
            // Every other triangle, so that indices and positions do not run in step.
            let some: Vec<u32> = (0..n).filter(|t| t % 3 != 1).collect();
            let bvh = TriangleBvh::new(&mesh, some.clone());
            let mut items: Vec<Item> = some
                .iter()
                .map(|&t| {
                    let [a, b, c] = mesh.triangle_positions(t as usize);
                    (t, ((a + b + c) / 3.0).as_vec3().to_array())
                })
                .collect();
            sorted(&mut items);
            let order: Vec<u32> = items.iter().map(|&(t, _)| t).collect();
            assert_eq!(bvh.tree.order, order);
            for node in bvh.tree.nodes.iter().filter(|n| n.count > 0) {
                let (mut min, mut max) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
                for i in node.first..node.first + node.count {
                    for p in mesh.triangle_positions(bvh.tree.order[i as usize] as usize) {
                        (min, max) = (min.min(p), max.max(p));
                    }
                }
                assert_eq!(
                    node.min,
                    [f32_down(min.x), f32_down(min.y), f32_down(min.z)]
                );
                assert_eq!(node.max, [f32_up(max.x), f32_up(max.y), f32_up(max.z)]);
            }
        }
    }

    #[test]
    fn boxes_are_conservative_in_f64() {
        // Coordinates that f32 cannot hold exactly.
        let mut mesh = grid(3, 3);
        for p in &mut mesh.positions {
            *p = *p * 0.1 + DVec3::splat(1e3 + 1.0 / 3.0);
        }
        let all: Vec<u32> = (0..mesh.triangles.len() as u32).collect();
        let bvh = TriangleBvh::new(&mesh, all);
        for n in &bvh.tree.nodes {
            let leaf = n.count > 0;
            if leaf {
                for i in n.first..n.first + n.count {
                    for v in bvh.tree.corners[i as usize] {
                        let p = mesh.positions[v as usize].to_array();
                        for ((lo, hi), x) in n.min.iter().zip(n.max).zip(p) {
                            assert!(*lo as f64 <= x && x <= hi as f64);
                        }
                    }
                }
            }
        }
        assert!(bvh.closest(DVec3::ZERO, None).is_some());
        let empty = TriangleBvh::new(&mesh, Vec::new());
        assert!(empty.is_empty() && empty.closest(DVec3::ZERO, None).is_none());
    }
}
