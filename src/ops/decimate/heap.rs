//! An indexed d-ary min-heap of triangle keys: each triangle has at most one entry, whose
//! key can be changed or removed in place (decrease/increase-key). The collapse loop
//! re-keys the triangles around each collapse at once instead of pushing stale copies,
//! so the heap never holds more than one entry per triangle and a pop is always current.
//!
//! Order: smallest `(key, triangle)`, so ties go to the lower triangle index and the
//! order is fully determined by the keys.

const ABSENT: u32 = u32::MAX;
/// Arity: 4 halves the depth of a binary heap, and the four children of a node fill one
/// cache line (16-byte entries, blocks aligned to 64 bytes), which is what a pop mostly
/// waits for.
const D: usize = 4;
/// Empty slots before the root: with the root in slot `D − 1`, the children of node `i`
/// (nodes `D·i + 1 ..= D·i + D`) are exactly block `i + 1`, one cache line, instead of
/// straddling two.
const PAD: usize = D - 1;

type Entry = (u64, u32);

/// One cache line of entries.
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct Block([Entry; D]);

const EMPTY: Block = Block([(u64::MAX, ABSENT); D]);

pub struct IndexedHeap {
    blocks: Vec<Block>,
    len: usize,
    pos: Vec<u32>,
}

impl IndexedHeap {
    /// A heap over items `0..n`, built in O(n) from the entries `fill` writes: `fill`
    /// gets `n` slots, writes `(key, item)` into each (each item at most once), and a key
    /// of `u64::MAX` leaves the slot out. The entries are written in place, so building
    /// needs no second array of them (peak memory).
    pub fn build(n: usize, fill: impl FnOnce(&mut [Entry])) -> Self {
        let mut heap = IndexedHeap {
            blocks: vec![EMPTY; (n + PAD).div_ceil(D).max(1)],
            len: 0,
            pos: vec![ABSENT; n],
        };
        {
            let slots = heap.slots_mut();
            let slots = &mut slots[PAD..PAD + n];
            fill(slots);
            // Keep the present entries, in order, at the front.
            let mut len = 0;
            for i in 0..n {
                if slots[i].0 != u64::MAX {
                    slots[len] = slots[i];
                    len += 1;
                }
            }
            heap.len = len;
        }
        for i in 0..heap.len {
            let t = heap.at(i).1;
            heap.pos[t as usize] = i as u32;
        }
        let len = heap.len;
        if len > 1 {
            for i in (0..=(len - 2) / D).rev() {
                heap.down(i);
            }
        }
        heap
    }

    /// All slots (the pad, the entries, spare room) as one slice.
    fn slots_mut(&mut self) -> &mut [Entry] {
        let n = self.blocks.len() * D;
        // SAFETY: `Block` is `repr(C)` over `[Entry; D]` and exactly `D` entries long
        // (16 · 4 = 64 bytes, its alignment), so the blocks are `n` contiguous entries.
        unsafe { std::slice::from_raw_parts_mut(self.blocks.as_mut_ptr().cast::<Entry>(), n) }
    }

    #[inline]
    fn at(&self, i: usize) -> Entry {
        let p = i + PAD;
        self.blocks[p / D].0[p % D]
    }

    /// Stores `e` in node `i` and records its position.
    #[inline]
    fn put(&mut self, i: usize, e: Entry) {
        let p = i + PAD;
        self.blocks[p / D].0[p % D] = e;
        self.pos[e.1 as usize] = i as u32;
    }

    #[cfg(test)]
    fn len(&self) -> usize {
        self.len
    }

    /// The key of `t`, if it is in the heap.
    #[inline]
    pub fn key(&self, t: u32) -> Option<u64> {
        let i = self.pos[t as usize];
        (i != ABSENT).then(|| self.at(i as usize).0)
    }

    /// Asks the memory for where `t` is in the heap ([`super::prefetch`]).
    #[inline]
    pub fn prefetch(&self, t: u32) {
        super::prefetch::prefetch(&self.pos, t as usize);
    }

    /// Asks the memory for `t`'s entry (its key); reads where it is, so best called once
    /// [`IndexedHeap::prefetch`] has brought that in.
    #[inline]
    pub fn prefetch_entry(&self, t: u32) {
        let i = self.pos[t as usize];
        if i != ABSENT {
            super::prefetch::prefetch(&self.blocks, (i as usize + PAD) / D);
        }
    }

    /// The smallest entry's item, left in place.
    #[inline]
    pub fn peek(&self) -> Option<u32> {
        (self.len > 0).then(|| self.at(0).1)
    }

    /// Removes and returns the smallest entry as `(key, item)`.
    pub fn pop(&mut self) -> Option<(u64, u32)> {
        if self.len == 0 {
            return None;
        }
        let top = self.at(0);
        self.remove_at(0);
        Some(top)
    }

    /// Inserts `t` with `key`, or changes its key.
    pub fn set(&mut self, t: u32, key: u64) {
        let i = self.pos[t as usize];
        if i == ABSENT {
            let i = self.len;
            if (i + PAD) / D >= self.blocks.len() {
                self.blocks.push(EMPTY);
            }
            self.len += 1;
            self.put(i, (key, t));
            self.up(i);
        } else {
            let i = i as usize;
            let old = self.at(i).0;
            self.put(i, (key, t));
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
        let last = self.len - 1;
        let t = self.at(i).1;
        self.pos[t as usize] = ABSENT;
        self.len -= 1;
        if i == last {
            return;
        }
        let moved = self.at(last);
        self.put(i, moved);
        if i > 0 && moved < self.at((i - 1) / D) {
            self.up(i);
        } else {
            self.down(i);
        }
    }

    fn up(&mut self, mut i: usize) {
        let e = self.at(i);
        while i > 0 {
            let p = (i - 1) / D;
            let pe = self.at(p);
            if e < pe {
                self.put(i, pe);
                i = p;
            } else {
                break;
            }
        }
        self.put(i, e);
    }

    fn down(&mut self, mut i: usize) {
        let e = self.at(i);
        let len = self.len;
        loop {
            let first = i * D + 1;
            if first >= len {
                break;
            }
            // The children of node `i` are block `i + 1`.
            let kids = &self.blocks[i + 1].0;
            let n = (len - first).min(D);
            let mut best = 0;
            for c in 1..n {
                if kids[c] < kids[best] {
                    best = c;
                }
            }
            let be = kids[best];
            if be < e {
                self.put(i, be);
                i = first + best;
            } else {
                break;
            }
        }
        self.put(i, e);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pops_in_key_then_index_order_with_updates_and_removals() {
        // A small deterministic pseudo-random workload checked against a sorted model.
        let n = 200u32;
        let mut lcg = crate::testing::Lcg(12345);
        let mut rnd = move || lcg.next_u64() >> 33;
        let entries: Vec<(u64, u32)> = (0..n)
            .filter(|t| t % 3 != 0)
            .map(|t| (rnd() % 50, t))
            .collect();
        let mut model: Vec<Option<u64>> = vec![None; n as usize];
        for &(k, t) in &entries {
            model[t as usize] = Some(k);
        }
        let mut heap = IndexedHeap::build(n as usize, |slots| {
            slots.fill((u64::MAX, u32::MAX));
            for &(k, t) in &entries {
                slots[t as usize] = (k, t);
            }
        });
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
