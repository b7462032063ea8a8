//! Renumbering a mesh so that what is near in space is near in memory.
//!
//! Every step walks the mesh through its neighbourhoods: a vertex's ring, a triangle's
//! corners, an edge's two fans. Where the file lists vertices in an order unrelated to
//! space (a subdivided scan appends each edge's midpoint at the end, so the two ends of an
//! edge lie 53,000 places apart in the median on the 400k-triangle face), those walks miss
//! the caches at nearly every step. Renumbering once after loading cut the face-scan
//! recipe's `relax` on that scan from 1.47 to 0.90 s, `fair` from 2.39 to 1.86 s and
//! `decimate` from 3.56 to 3.36 s (medians; docs/decimation.md, "Locality").
//!
//! The order: vertices along a Morton (Z-order) curve through their bounding box, wedges by
//! their vertex, texture coordinates and normals by their first use, triangles by their
//! first wedge. Each triangle keeps its corners in their order (and so its orientation);
//! ties keep the file's order, so the result is deterministic.

use super::model::{Index, Mesh, bounding_box_of};
use glam::DVec3;
use rayon::prelude::*;

/// Bits per axis of the Morton code (3 × 21 = 63 bits).
const BITS: u32 = 21;

/// `x`'s low 21 bits spread to every third bit.
fn spread(x: u64) -> u64 {
    let mut x = x & ((1 << BITS) - 1);
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// The Morton code of `p` in the box `lo`..`lo + extent` (cube of side `extent`).
fn morton(p: DVec3, lo: DVec3, extent: f64) -> u64 {
    let scale = ((1u64 << BITS) - 1) as f64 / extent;
    let q = ((p - lo) * scale).clamp(DVec3::ZERO, DVec3::splat(((1u64 << BITS) - 1) as f64));
    spread(q.x as u64) | spread(q.y as u64) << 1 | spread(q.z as u64) << 2
}

/// A renumbering of `n` elements: where each old index goes, and which old index each new
/// one takes (the inverse, for gathering).
struct Renumbering {
    new_of_old: Vec<Index>,
    old_of_new: Vec<Index>,
}

impl Renumbering {
    /// The order that sorts `keys` (ties by index).
    fn sorting(keys: Vec<u64>) -> Renumbering {
        let mut order: Vec<(u64, Index)> = keys
            .into_iter()
            .enumerate()
            .map(|(i, k)| (k, i as Index))
            .collect();
        // Keys are unique with their index, so the unstable sort is deterministic.
        order.par_sort_unstable();
        Renumbering::from_old_of_new(order.into_iter().map(|(_, old)| old).collect())
    }

    /// The order that sorts `keys`, each below `range` (ties by index): a counting sort, two
    /// passes and no comparisons, where the wedges' keys are vertex numbers and the
    /// triangles' wedge numbers.
    fn sorting_small(keys: Vec<Index>, range: usize) -> Renumbering {
        let mut next = vec![0 as Index; range + 1];
        for &k in &keys {
            next[k as usize + 1] += 1;
        }
        for i in 1..next.len() {
            next[i] += next[i - 1];
        }
        let new_of_old = keys
            .iter()
            .map(|&k| {
                let new = next[k as usize];
                next[k as usize] += 1;
                new
            })
            .collect();
        Renumbering::from_new_of_old(new_of_old)
    }

    fn from_old_of_new(old_of_new: Vec<Index>) -> Renumbering {
        Renumbering {
            new_of_old: inverse(&old_of_new),
            old_of_new,
        }
    }

    fn from_new_of_old(new_of_old: Vec<Index>) -> Renumbering {
        Renumbering {
            old_of_new: inverse(&new_of_old),
            new_of_old,
        }
    }

    /// The new index of old element `old`.
    #[inline]
    fn of(&self, old: Index) -> Index {
        self.new_of_old[old as usize]
    }

    /// Moves `values[old]` to `values[new]`: each new element gathered from its old place,
    /// in parallel (an array the length of the renumbering; an empty one stays empty).
    fn permute<T: Copy + Send + Sync>(&self, values: &mut Vec<T>) {
        if values.is_empty() {
            return;
        }
        debug_assert_eq!(values.len(), self.old_of_new.len());
        *values = self
            .old_of_new
            .par_iter()
            .map(|&old| values[old as usize])
            .collect();
    }
}

/// The inverse of the permutation `p` (`q[p[i]] = i`).
fn inverse(p: &[Index]) -> Vec<Index> {
    let mut q = vec![0; p.len()];
    for (i, &j) in p.iter().enumerate() {
        q[j as usize] = i as Index;
    }
    q
}

/// Old → new indices of `count` elements numbered by their first use in `uses` (the
/// unused after them, in their old order).
fn by_first_use(count: usize, uses: impl Iterator<Item = Index>) -> Renumbering {
    const UNSEEN: Index = Index::MAX;
    let mut new = vec![UNSEEN; count];
    let mut next = 0;
    for old in uses {
        if new[old as usize] == UNSEEN {
            new[old as usize] = next;
            next += 1;
        }
    }
    for n in &mut new {
        if *n == UNSEEN {
            *n = next;
            next += 1;
        }
    }
    Renumbering::from_new_of_old(new)
}

impl Mesh {
    /// Renumbers vertices, wedges, texture coordinates, normals and triangles for locality
    /// (see the module's documentation). The mesh stays the same surface with the same
    /// triangles, attributes and materials; only indices change.
    pub fn reorder_for_locality(&mut self) {
        let Some((lo, hi)) = bounding_box_of(&self.positions) else {
            return;
        };
        let extent = (hi - lo).max_element();
        let keys = if extent > 0.0 && extent.is_finite() {
            self.positions
                .par_iter()
                .map(|&p| morton(p, lo, extent))
                .collect()
        } else {
            vec![0; self.positions.len()]
        };
        let vertex = Renumbering::sorting(keys);
        vertex.permute(&mut self.positions);
        vertex.permute(&mut self.colors);

        self.wedges
            .par_iter_mut()
            .for_each(|w| w.vertex = vertex.of(w.vertex));
        let wedge = Renumbering::sorting_small(
            self.wedges.iter().map(|w| w.vertex).collect(),
            self.positions.len(),
        );
        wedge.permute(&mut self.wedges);
        self.triangles
            .par_iter_mut()
            .for_each(|t| *t = t.map(|w| wedge.of(w)));

        let texcoord = by_first_use(
            self.texcoords.len(),
            self.wedges.iter().filter_map(|w| w.texcoord),
        );
        texcoord.permute(&mut self.texcoords);
        let normal = by_first_use(
            self.normals.len(),
            self.wedges.iter().filter_map(|w| w.normal),
        );
        normal.permute(&mut self.normals);
        self.wedges.par_iter_mut().for_each(|w| {
            w.texcoord = w.texcoord.map(|t| texcoord.of(t));
            w.normal = w.normal.map(|n| normal.of(n));
        });

        let triangle = Renumbering::sorting_small(
            self.triangles
                .iter()
                .map(|t| *t.iter().min().expect("three corners"))
                .collect(),
            self.wedges.len(),
        );
        triangle.permute(&mut self.triangles);
        triangle.permute(&mut self.triangle_materials);
        triangle.permute(&mut self.triangle_origins);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::model::Wedge;
    use glam::DVec2;

    /// Each triangle as its three corners' (position, texture coordinate) in its own
    /// corner order, rotated to start at its smallest corner, then all sorted: equal for two
    /// meshes with the same triangles, orientations and attributes, whatever the numbering.
    fn corners(m: &Mesh) -> Vec<[[u64; 5]; 3]> {
        let mut all: Vec<[[u64; 5]; 3]> = m
            .triangles
            .iter()
            .zip(m.triangle_materials.iter().chain(std::iter::repeat(&0)))
            .map(|(t, &mat)| {
                let c = t.map(|w| {
                    let w = m.wedges[w as usize];
                    let p = m.positions[w.vertex as usize];
                    let uv = w.texcoord.map_or(DVec2::NAN, |t| m.texcoords[t as usize]);
                    [p.x, p.y, p.z, uv.x, f64::from(mat) + uv.y].map(f64::to_bits)
                });
                let k = (0..3).min_by_key(|&k| c[k]).expect("three");
                [c[k], c[(k + 1) % 3], c[(k + 2) % 3]]
            })
            .collect();
        all.sort_unstable();
        all
    }

    /// A grid with a texture seam down its middle, vertices and triangles listed in a
    /// scrambled order, two materials.
    fn scrambled_grid() -> Mesh {
        let mut m = crate::mesh::shapes::grid(20, 12);
        let n = m.positions.len();
        let stride = (n / 3..).find(|s| gcd(*s, n) == 1).expect("a stride");
        let old_of_new: Vec<usize> = (0..n).map(|k| k * stride % n).collect();
        let mut new_of_old = vec![0; n];
        for (new, &old) in old_of_new.iter().enumerate() {
            new_of_old[old] = new as Index;
        }
        m.positions = old_of_new.iter().map(|&o| m.positions[o]).collect();
        m.texcoords = m.positions.iter().map(|p| DVec2::new(p.x, p.y)).collect();
        m.wedges = (0..n as Index)
            .map(|v| Wedge {
                vertex: v,
                texcoord: Some(v),
                normal: None,
            })
            .collect();
        for t in &mut m.triangles {
            *t = t.map(|v| new_of_old[v as usize]);
        }
        // The seam: triangles right of x = 10 use a second copy of the texture coordinates.
        for i in 0..m.triangles.len() {
            let t = m.triangles[i];
            if t.iter().all(|&v| m.positions[v as usize].x >= 10.0) {
                m.triangles[i] = t.map(|v| {
                    m.texcoords.push(m.texcoords[v as usize] + DVec2::X * 0.5);
                    m.wedges.push(Wedge {
                        vertex: v,
                        texcoord: Some(m.texcoords.len() as Index - 1),
                        normal: None,
                    });
                    m.wedges.len() as Index - 1
                });
            }
        }
        m.triangles.reverse();
        m.triangle_materials = (0..m.triangles.len() as Index).map(|t| t % 2).collect();
        m
    }

    fn gcd(a: usize, b: usize) -> usize {
        if b == 0 { a } else { gcd(b, a % b) }
    }

    fn mean_edge_gap(m: &Mesh) -> f64 {
        let gaps: Vec<f64> = m
            .triangles
            .iter()
            .flat_map(|t| {
                let v = t.map(|w| m.wedges[w as usize].vertex as f64);
                [
                    (v[0] - v[1]).abs(),
                    (v[1] - v[2]).abs(),
                    (v[2] - v[0]).abs(),
                ]
            })
            .collect();
        gaps.iter().sum::<f64>() / gaps.len() as f64
    }

    #[test]
    fn same_triangles_and_attributes_in_a_local_order() {
        let before = scrambled_grid();
        let mut after = before.clone();
        after.reorder_for_locality();
        assert_eq!(corners(&after), corners(&before));
        assert_eq!(after.positions.len(), before.positions.len());
        assert_eq!(after.wedges.len(), before.wedges.len());
        assert_eq!(after.texcoords.len(), before.texcoords.len());
        // Wedges follow their vertices; triangles their first wedge.
        assert!(after.wedges.is_sorted_by_key(|w| w.vertex));
        assert!(
            after
                .triangles
                .is_sorted_by_key(|t| *t.iter().min().expect("three"))
        );
        let (gap_before, gap_after) = (mean_edge_gap(&before), mean_edge_gap(&after));
        assert!(gap_after < gap_before / 4.0, "{gap_before} → {gap_after}");
        // Deterministic.
        let mut again = before.clone();
        again.reorder_for_locality();
        assert_eq!(again, after);
    }

    #[test]
    fn morton_codes_follow_the_curve() {
        assert_eq!(spread(0b111), 0b1001001);
        assert_eq!(spread((1 << BITS) - 1).count_ones(), BITS);
        let (lo, extent) = (DVec3::ZERO, 1.0);
        assert!(morton(DVec3::ZERO, lo, extent) < morton(DVec3::splat(0.1), lo, extent));
        assert_eq!(morton(DVec3::ONE, lo, extent), (1 << (3 * BITS)) - 1);
    }

    /// The counting sort orders like the comparison sort: by key, ties by index, and each
    /// renumbering's two directions are inverses.
    #[test]
    fn counting_sort_is_the_sort_by_key_then_index() {
        for (n, range) in [(0, 1), (1, 1), (1000, 7), (5000, 1000), (3000, 100_000)] {
            let keys: Vec<Index> = (0..n as u64)
                .map(|i| ((i * 2_654_435_761) % 1_000_003 % range) as Index)
                .collect();
            let counted = Renumbering::sorting_small(keys.clone(), range as usize);
            let sorted = Renumbering::sorting(keys.iter().map(|&k| u64::from(k)).collect());
            assert_eq!(counted.new_of_old, sorted.new_of_old);
            assert_eq!(counted.old_of_new, sorted.old_of_new);
            for (new, &old) in counted.old_of_new.iter().enumerate() {
                assert_eq!(counted.of(old), new as Index);
            }
            let mut values: Vec<Index> = keys.clone();
            counted.permute(&mut values);
            assert!(values.is_sorted());
        }
    }
}
