//! The remesher's connectivity: a corner table (three half-edges per face, each with its
//! opposite) that supports the four local operations of isotropic remeshing: edge split,
//! edge collapse, edge flip and the vertex ring. Half-edge `h` of face `h / 3` runs from
//! `vtx[h]` to `vtx[next(h)]`.
//!
//! Vertices whose triangles do not form one consistently oriented fan (non-manifold
//! vertices and the ends of non-manifold or inconsistent edges) are *locked*: the operations
//! never take them as an endpoint, so their partial ring is never relied on.

use glam::DVec3;

pub const NIL: u32 = u32::MAX;

#[inline]
pub fn next(h: u32) -> u32 {
    if h % 3 == 2 { h - 2 } else { h + 1 }
}

#[inline]
pub fn prev(h: u32) -> u32 {
    if h.is_multiple_of(3) { h + 2 } else { h - 1 }
}

/// The working mesh. Face labels (`chart`, `material`) are carried by every operation;
/// `seg` marks a constrained edge with the input polyline segment it lies near (`NIL` for a
/// free edge; a border half-edge is constrained by having no opposite).
#[derive(Debug, Clone, Default)]
pub struct Corners {
    pub vtx: Vec<u32>,
    pub opp: Vec<u32>,
    pub seg: Vec<u32>,
    pub face_dead: Vec<bool>,
    pub chart: Vec<u32>,
    pub material: Vec<u32>,
    pub pos: Vec<DVec3>,
    /// One outgoing half-edge per vertex; the border one when the vertex is on a border,
    /// so that a counter-clockwise walk from it meets the whole fan.
    pub out: Vec<u32>,
    pub locked: Vec<bool>,
    pub vertex_dead: Vec<bool>,
    pub kind: Vec<VKind>,
    /// Line vertices: a segment of their line near them.
    pub vseg: Vec<u32>,
    /// The input triangle the vertex was last projected onto (the search's first guess).
    pub vtri: Vec<u32>,
}

/// What a vertex of the working mesh may do (ordered from the freest).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum VKind {
    /// Moves on the surface; collapses onto any neighbour.
    Free,
    /// On one input line: moves along it, collapses only along it.
    Line,
    /// Never moves and never goes (line ends and junctions, locked vertices).
    Corner,
}

impl Corners {
    pub fn face_count(&self) -> usize {
        self.face_dead.len()
    }

    pub fn live_faces(&self) -> usize {
        self.face_dead.iter().filter(|&&d| !d).count()
    }

    #[inline]
    pub fn dest(&self, h: u32) -> u32 {
        self.vtx[next(h) as usize]
    }

    #[inline]
    pub fn is_border(&self, h: u32) -> bool {
        self.opp[h as usize] == NIL
    }

    /// The edge may not be flipped, and only split or collapsed along its polyline.
    #[inline]
    pub fn is_constrained(&self, h: u32) -> bool {
        self.is_border(h) || self.seg[h as usize] != NIL
    }

    #[inline]
    pub fn link(&mut self, a: u32, b: u32) {
        if a != NIL {
            self.opp[a as usize] = b;
        }
        if b != NIL {
            self.opp[b as usize] = a;
        }
    }

    /// The next outgoing half-edge counter-clockwise around `vtx[h]`, `NIL` at a border.
    #[inline]
    pub fn rotate(&self, h: u32) -> u32 {
        self.opp[prev(h) as usize]
    }

    /// The outgoing half-edges of `v`, counter-clockwise from `out[v]`.
    pub fn fan(&self, v: u32, hs: &mut Vec<u32>) {
        hs.clear();
        hs.extend(self.fan_iter(v));
    }

    /// The outgoing half-edges of `v`, counter-clockwise from `out[v]`, walked in place:
    /// for the passes that read a fan once and need no list of it.
    #[inline]
    pub fn fan_iter(&self, v: u32) -> Fan<'_> {
        let start = self.out[v as usize];
        Fan {
            c: self,
            start,
            next: start,
            walked: 0,
            border_end: NIL,
        }
    }

    /// The neighbours of `v` in ring order, walked in place (what [`Corners::ring`] lists).
    #[inline]
    pub fn neighbours(&self, v: u32) -> Neighbours<'_> {
        Neighbours {
            fan: self.fan_iter(v),
            last_done: false,
        }
    }

    /// A half-edge of the edge a–b (a→b, or b→a where a→b is a border's missing side), if
    /// there is that edge.
    pub fn half_edge(&self, a: u32, b: u32, hs: &mut Vec<u32>) -> Option<u32> {
        self.fan(a, hs);
        if let Some(&h) = hs.iter().find(|&&h| self.dest(h) == b) {
            return Some(h);
        }
        self.fan(b, hs);
        hs.iter().copied().find(|&h| self.dest(h) == a)
    }

    /// The neighbours of `v` in ring order (the last one of a border vertex closes no face).
    pub fn ring(&self, v: u32, ring: &mut Vec<u32>) {
        ring.clear();
        ring.extend(self.neighbours(v));
    }

    pub fn is_border_vertex(&self, v: u32) -> bool {
        self.is_border(self.out[v as usize])
    }

    /// Sets `out[v]` from any outgoing half-edge `h`: turns clockwise to the border one if
    /// there is one.
    pub fn fix_out(&mut self, v: u32, h: u32) {
        let mut g = h;
        let mut steps = 0;
        while self.opp[g as usize] != NIL && steps <= MAX_FAN {
            g = next(self.opp[g as usize]);
            steps += 1;
            if g == h {
                break;
            }
        }
        self.out[v as usize] = g;
    }

    /// Appends a vertex and returns its index.
    pub fn add_vertex(&mut self, p: DVec3, kind: VKind, vseg: u32, vtri: u32) -> u32 {
        self.pos.push(p);
        self.out.push(NIL);
        self.locked.push(false);
        self.vertex_dead.push(false);
        self.kind.push(kind);
        self.vseg.push(vseg);
        self.vtri.push(vtri);
        (self.pos.len() - 1) as u32
    }

    /// Appends a face with the labels of face `like`; returns its first half-edge.
    pub fn add_face(&mut self, v: [u32; 3], like: usize) -> u32 {
        let h = self.vtx.len() as u32;
        self.vtx.extend(v);
        self.opp.extend([NIL; 3]);
        self.seg.extend([NIL; 3]);
        self.face_dead.push(false);
        self.chart.push(self.chart[like]);
        self.material.push(self.material[like]);
        h
    }

    pub fn face_positions(&self, f: usize) -> [DVec3; 3] {
        [0, 1, 2].map(|i| self.pos[self.vtx[3 * f + i] as usize])
    }

    pub fn face_cross(&self, f: usize) -> DVec3 {
        let [a, b, c] = self.face_positions(f);
        (b - a).cross(c - a)
    }
}

/// The outgoing half-edges of a vertex ([`Corners::fan_iter`]): from `out[v]`, rotating
/// counter-clockwise until the fan closes, a border ends it, or [`MAX_FAN`] is passed.
pub struct Fan<'a> {
    c: &'a Corners,
    start: u32,
    next: u32,
    walked: usize,
    /// The last half-edge, when a border ended the fan.
    border_end: u32,
}

impl Iterator for Fan<'_> {
    type Item = u32;

    #[inline]
    fn next(&mut self) -> Option<u32> {
        let h = self.next;
        if h == NIL {
            return None;
        }
        self.walked += 1;
        let g = self.c.rotate(h);
        if g == NIL {
            self.border_end = h;
        }
        self.next = if g == self.start || self.walked > MAX_FAN {
            NIL
        } else {
            g
        };
        Some(h)
    }
}

/// The neighbours of a vertex ([`Corners::neighbours`]): the end of each outgoing
/// half-edge, and on a border the vertex the last face's incoming side starts at.
pub struct Neighbours<'a> {
    fan: Fan<'a>,
    last_done: bool,
}

impl Iterator for Neighbours<'_> {
    type Item = u32;

    #[inline]
    fn next(&mut self) -> Option<u32> {
        if let Some(h) = self.fan.next() {
            return Some(self.fan.c.dest(h));
        }
        let h = self.fan.border_end;
        if self.last_done || h == NIL {
            return None;
        }
        self.last_done = true;
        Some(self.fan.c.vtx[prev(h) as usize])
    }
}

/// A fan longer than this is not walked further (a guard against a corrupted table; a
/// real vertex this busy is locked).
pub const MAX_FAN: usize = 4096;

impl Corners {
    /// Checks the table's invariants: opposite half-edges are mutual and run the other
    /// way, every live vertex's `out` leaves it from a live face, constrained marks match
    /// on both sides. Used by tests; a failure is a bug.
    pub fn check(&self) -> Result<(), String> {
        for h in 0..self.vtx.len() as u32 {
            if self.face_dead[(h / 3) as usize] {
                continue;
            }
            let g = self.opp[h as usize];
            if g == NIL {
                continue;
            }
            if self.face_dead[(g / 3) as usize] {
                return Err(format!("half-edge {h}: opposite {g} is in a dead face"));
            }
            if self.opp[g as usize] != h {
                return Err(format!("half-edge {h}: opposite {g} is not mutual"));
            }
            if self.vtx[g as usize] != self.dest(h) || self.dest(g) != self.vtx[h as usize] {
                return Err(format!("half-edge {h}: opposite {g} does not run back"));
            }
            if self.seg[g as usize] != self.seg[h as usize] {
                return Err(format!("half-edge {h}: constraint differs from {g}'s"));
            }
        }
        for v in 0..self.pos.len() {
            if self.vertex_dead[v] {
                continue;
            }
            let h = self.out[v];
            if h == NIL || self.face_dead[(h / 3) as usize] || self.vtx[h as usize] != v as u32 {
                return Err(format!("vertex {v}: out {h} does not leave it"));
            }
        }
        Ok(())
    }
}
