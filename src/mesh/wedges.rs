//! Numbering distinct wedges as corners are visited. A vertex has only a few wedges (one, or
//! a handful on seams), so a per-vertex list searched linearly is faster and leaner than
//! hashing every corner, and the numbering (order of first use) is deterministic.

use super::model::{Index, Wedge};

const NONE: Index = Index::MAX;

pub struct WedgeInterner {
    first: Vec<Index>,
    next: Vec<Index>,
    wedges: Vec<Wedge>,
}

impl WedgeInterner {
    /// For wedges whose vertices are below `vertex_count`.
    pub fn new(vertex_count: usize) -> Self {
        WedgeInterner {
            first: vec![NONE; vertex_count],
            next: Vec::with_capacity(vertex_count + vertex_count / 4),
            wedges: Vec::with_capacity(vertex_count + vertex_count / 4),
        }
    }

    /// The index of `wedge`, adding it if it is new.
    #[inline]
    pub fn intern(&mut self, wedge: Wedge) -> Index {
        let v = wedge.vertex as usize;
        let mut w = self.first[v];
        while w != NONE {
            if self.wedges[w as usize] == wedge {
                return w;
            }
            w = self.next[w as usize];
        }
        let w = self.wedges.len() as Index;
        self.wedges.push(wedge);
        self.next.push(self.first[v]);
        self.first[v] = w;
        w
    }

    pub fn into_wedges(self) -> Vec<Wedge> {
        self.wedges
    }
}
