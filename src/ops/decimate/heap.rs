//! An indexed d-ary min-heap of triangle keys: each triangle has at most one entry, whose
//! key can be changed or removed in place (decrease/increase-key). The collapse loop
//! re-keys the triangles around each collapse at once instead of pushing stale copies,
//! so the heap never holds more than one entry per triangle and a pop is always current.
//!
//! Order: smallest `(key, triangle)`, so ties go to the lower triangle index and the
//! order is fully determined by the keys.

const ABSENT: u32 = u32::MAX;
/// Arity: 4 halves the depth of a binary heap, and the four children of a node share a
/// cache line (16-byte entries), which is what a pop mostly waits for.
const D: usize = 4;

pub struct IndexedHeap {
    h: Vec<(u64, u32)>,
    pos: Vec<u32>,
}

impl IndexedHeap {
    /// A heap over items `0..n` holding the given `(item, key)` entries (each item at most
    /// once), built in O(n).
    pub fn from_entries(n: usize, entries: Vec<(u64, u32)>) -> Self {
        let mut heap = IndexedHeap {
            h: entries,
            pos: vec![ABSENT; n],
        };
        for (i, &(_, t)) in heap.h.iter().enumerate() {
            heap.pos[t as usize] = i as u32;
        }
        let len = heap.h.len();
        if len > 1 {
            for i in (0..=(len - 2) / D).rev() {
                heap.down(i);
            }
        }
        heap
    }

    #[cfg(test)]
    fn len(&self) -> usize {
        self.h.len()
    }

    /// The key of `t`, if it is in the heap.
    #[inline]
    pub fn key(&self, t: u32) -> Option<u64> {
        let i = self.pos[t as usize];
        (i != ABSENT).then(|| self.h[i as usize].0)
    }

    /// Removes and returns the smallest entry as `(key, item)`.
    pub fn pop(&mut self) -> Option<(u64, u32)> {
        let top = *self.h.first()?;
        self.remove_at(0);
        Some(top)
    }

    /// Inserts `t` with `key`, or changes its key.
    pub fn set(&mut self, t: u32, key: u64) {
        let i = self.pos[t as usize];
        if i == ABSENT {
            self.h.push((key, t));
            let i = self.h.len() - 1;
            self.pos[t as usize] = i as u32;
            self.up(i);
        } else {
            let i = i as usize;
            let old = self.h[i].0;
            self.h[i].0 = key;
            if key < old {
                self.up(i);
            } else if key > old {
                self.down(i);
            }
        }
    }

    /// Removes `t` if present.
    pub fn remove(&mut self, t: u32) {
        let i = self.pos[t as usize];
        if i != ABSENT {
            self.remove_at(i as usize);
        }
    }

    fn remove_at(&mut self, i: usize) {
        let last = self.h.len() - 1;
        let t = self.h[i].1;
        self.pos[t as usize] = ABSENT;
        if i == last {
            self.h.pop();
            return;
        }
        let moved = self.h[last];
        self.h.pop();
        self.h[i] = moved;
        self.pos[moved.1 as usize] = i as u32;
        if i > 0 && moved < self.h[(i - 1) / D] {
            self.up(i);
        } else {
            self.down(i);
        }
    }

    fn up(&mut self, mut i: usize) {
        let e = self.h[i];
        while i > 0 {
            let p = (i - 1) / D;
            if e < self.h[p] {
                self.h[i] = self.h[p];
                self.pos[self.h[i].1 as usize] = i as u32;
                i = p;
            } else {
                break;
            }
        }
        self.h[i] = e;
        self.pos[e.1 as usize] = i as u32;
    }

    fn down(&mut self, mut i: usize) {
        let e = self.h[i];
        let len = self.h.len();
        loop {
            let first = i * D + 1;
            if first >= len {
                break;
            }
            let end = (first + D).min(len);
            let mut best = first;
            for c in first + 1..end {
                if self.h[c] < self.h[best] {
                    best = c;
                }
            }
            if self.h[best] < e {
                self.h[i] = self.h[best];
                self.pos[self.h[i].1 as usize] = i as u32;
                i = best;
            } else {
                break;
            }
        }
        self.h[i] = e;
        self.pos[e.1 as usize] = i as u32;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pops_in_key_then_index_order_with_updates_and_removals() {
        // A small deterministic pseudo-random workload checked against a sorted model.
        let n = 200u32;
        let mut state = 12345u64;
        let mut rnd = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            state >> 33
        };
        let entries: Vec<(u64, u32)> = (0..n)
            .filter(|t| t % 3 != 0)
            .map(|t| (rnd() % 50, t))
            .collect();
        let mut model: Vec<Option<u64>> = vec![None; n as usize];
        for &(k, t) in &entries {
            model[t as usize] = Some(k);
        }
        let mut heap = IndexedHeap::from_entries(n as usize, entries);
        for step in 0..2000 {
            let t = (rnd() % n as u64) as u32;
            match step % 4 {
                0 | 1 => {
                    let k = rnd() % 50;
                    heap.set(t, k);
                    model[t as usize] = Some(k);
                }
                2 => {
                    heap.remove(t);
                    model[t as usize] = None;
                }
                _ => {
                    let expect = model
                        .iter()
                        .enumerate()
                        .filter_map(|(i, k)| k.map(|k| (k, i as u32)))
                        .min();
                    assert_eq!(heap.pop(), expect);
                    if let Some((_, i)) = expect {
                        model[i as usize] = None;
                    }
                }
            }
            assert_eq!(heap.len(), model.iter().flatten().count());
        }
    }
}
