//! Removing unused vertices, wedges, texture coordinates and normals (the thesis'
//! `RemoveFaces` clean-up, decimation thesis §6.4), keeping the order of what stays.

use super::model::{Index, Mesh};

/// How many elements of each kind [`Mesh::compact`] removed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Compacted {
    pub vertices: usize,
    pub wedges: usize,
    pub texcoords: usize,
    pub normals: usize,
}

const UNUSED: Index = Index::MAX;

/// Old→new index table for the elements marked used, in their original order.
fn remap(used: &[bool]) -> (Vec<Index>, usize) {
    let mut next = 0;
    let table = used
        .iter()
        .map(|&u| {
            if u {
                next += 1;
                next - 1
            } else {
                UNUSED
            }
        })
        .collect();
    (table, next as usize)
}

/// Keeps the elements `table` maps, and gives back the room of the others: a compacted mesh
/// often lives on for the rest of a run (a step's output, the seam reference), and a vector
/// that grew by appending (texture coordinates appended per moved wedge) can hold several
/// times its length.
fn keep<T: Copy>(values: &mut Vec<T>, table: &[Index]) {
    let mut i = 0;
    values.retain(|_| {
        i += 1;
        table[i - 1] != UNUSED
    });
    values.shrink_to_fit();
}

impl Mesh {
    /// Drops every vertex, wedge, texture coordinate and normal no triangle uses.
    pub fn compact(&mut self) -> Compacted {
        let mut wedge_used = vec![false; self.wedges.len()];
        for tri in &self.triangles {
            for &w in tri {
                wedge_used[w as usize] = true;
            }
        }
        let (wedge_table, _) = remap(&wedge_used);
        keep(&mut self.wedges, &wedge_table);
        for tri in &mut self.triangles {
            for w in tri.iter_mut() {
                *w = wedge_table[*w as usize];
            }
        }

        let mut vertex_used = vec![false; self.positions.len()];
        let mut texcoord_used = vec![false; self.texcoords.len()];
        let mut normal_used = vec![false; self.normals.len()];
        for w in &self.wedges {
            vertex_used[w.vertex as usize] = true;
            if let Some(t) = w.texcoord {
                texcoord_used[t as usize] = true;
            }
            if let Some(n) = w.normal {
                normal_used[n as usize] = true;
            }
        }
        let (vertex_table, _) = remap(&vertex_used);
        let (texcoord_table, _) = remap(&texcoord_used);
        let (normal_table, _) = remap(&normal_used);
        let before = (
            self.positions.len(),
            self.texcoords.len(),
            self.normals.len(),
        );
        keep(&mut self.positions, &vertex_table);
        if !self.colors.is_empty() {
            keep(&mut self.colors, &vertex_table);
        }
        keep(&mut self.texcoords, &texcoord_table);
        keep(&mut self.normals, &normal_table);
        for w in &mut self.wedges {
            w.vertex = vertex_table[w.vertex as usize];
            w.texcoord = w.texcoord.map(|t| texcoord_table[t as usize]);
            w.normal = w.normal.map(|n| normal_table[n as usize]);
        }
        Compacted {
            vertices: before.0 - self.positions.len(),
            wedges: wedge_used.len() - self.wedges.len(),
            texcoords: before.1 - self.texcoords.len(),
            normals: before.2 - self.normals.len(),
        }
    }
}
