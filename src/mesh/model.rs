//! The wedge mesh model (the decimation thesis' `WedgeScene`, §6.4, after Hoppe 1999).
//!
//! A *vertex* is a position. A *wedge* is a (vertex, texture coordinate, normal)
//! combination. A triangle's three corners are wedges. A texture seam is then simply a
//! vertex with more than one wedge: every step that moves positions moves the vertex, so
//! seams stay closed by construction.

use super::wedges::WedgeInterner;
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Sentinel-free optional index: wedges without a texture coordinate or normal use `None`.
pub type Index = u32;

/// One (vertex, texture coordinate, normal) combination used by triangle corners.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Wedge {
    pub vertex: Index,
    pub texcoord: Option<Index>,
    pub normal: Option<Index>,
}

/// A texture image referenced by a material.
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    /// The name as the scan wrote it (normalised, relative to the MTL's folder): the wish
    /// for the copy's name on output, never used to find the file again.
    pub name: String,
    /// The file on disk: for a loaded scan, resolved (symlinks included) and checked to be
    /// inside the scan's folder when it was loaded. Writers copy exactly this file.
    pub path: PathBuf,
    /// Pixel size, known after the image decoded (`None` if not checked).
    pub size: Option<(u32, u32)>,
    /// The image's bytes when it came inside the scan's own file (a GLB's buffer, a `data:`
    /// URI) rather than as a file beside it. `path` is then a name for it that is never
    /// opened (`<scan file>#image<N>`); readers decode these bytes and writers copy them.
    pub embedded: Option<EmbeddedImage>,
}

/// Image bytes (PNG or JPEG) kept exactly as they came, shared between copies of a mesh.
#[derive(Clone, PartialEq)]
pub struct EmbeddedImage(pub Arc<[u8]>);

impl std::fmt::Debug for EmbeddedImage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "EmbeddedImage({} bytes)", self.0.len())
    }
}

/// A file named by one of a material's `other_statements` (`map_Bump`, `bump`, `disp`, ...),
/// resolved and checked when the MTL was loaded.
#[derive(Debug, Clone, PartialEq)]
pub struct MapFile {
    /// Index of the statement in `Material::other_statements`.
    pub statement: usize,
    /// The file (resolved, inside the scan's folder). Writers copy exactly this file.
    pub path: PathBuf,
}

/// A material: its name, its diffuse texture if any, and the MTL statements we do not
/// interpret, kept in order so that they are written back unchanged.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Material {
    pub name: String,
    pub diffuse_texture: Option<Texture>,
    /// Every other statement of the `newmtl` block, verbatim except that file names are
    /// normalised (e.g. `Kd 1 1 1`, `map_Bump n.png`).
    pub other_statements: Vec<String>,
    /// The files the map statements among `other_statements` name. A map statement without
    /// an entry here (a material a program made up) is written as it is and nothing is
    /// copied for it.
    pub map_files: Vec<MapFile>,
}

/// The mesh. Positions, texture coordinates and normals are separate arrays, as in an OBJ;
/// wedges tie them together; triangles are triples of wedge indices.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<DVec3>,
    pub texcoords: Vec<DVec2>,
    pub normals: Vec<DVec3>,
    /// Optional per-vertex colour (RGBA), either empty or one per position.
    pub colors: Vec<[u8; 4]>,
    pub wedges: Vec<Wedge>,
    /// Each triangle is three wedge indices, counter-clockwise seen from outside.
    pub triangles: Vec<[Index; 3]>,
    /// Material index per triangle (into `materials`); empty when the mesh has no materials.
    pub triangle_materials: Vec<Index>,
    pub materials: Vec<Material>,
    /// For every triangle, the index of the input triangle it descends from. Empty means
    /// "identity" (a freshly loaded mesh). Steps that create or collapse triangles fill it,
    /// so that `seam_fix` can project back onto the originating input triangle.
    pub triangle_origins: Vec<Index>,
}

impl Mesh {
    /// Forgets the normals: every wedge loses its normal, and wedges that differed only in
    /// their normal become the first of them. The others keep their order, so a mesh
    /// whose normals split no wedge keeps its numbering (and whatever depends on it). For
    /// a recipe that writes fresh normals, whose earlier steps would only carry the scan's
    /// own along.
    pub fn drop_normals(&mut self) {
        // A wedge's normal indexes `normals` (`check_invariants`): none to drop.
        if self.normals.is_empty() {
            return;
        }
        let mut interner = WedgeInterner::new(self.positions.len());
        let renumbered: Vec<Index> = self
            .wedges
            .iter()
            .map(|&w| interner.intern(Wedge { normal: None, ..w }))
            .collect();
        for triangle in &mut self.triangles {
            for w in triangle.iter_mut() {
                *w = renumbered[*w as usize];
            }
        }
        self.wedges = interner.into_wedges();
        self.normals = Vec::new();
    }

    /// The same vertices, wedges and materials, without triangles: the start of a mesh
    /// that re-triangulates this one.
    pub fn without_triangles(&self) -> Mesh {
        Mesh {
            positions: self.positions.clone(),
            texcoords: self.texcoords.clone(),
            normals: self.normals.clone(),
            colors: self.colors.clone(),
            wedges: self.wedges.clone(),
            materials: self.materials.clone(),
            ..Default::default()
        }
    }

    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    pub fn has_texcoords(&self) -> bool {
        !self.texcoords.is_empty()
    }

    /// The vertex index of each corner of triangle `t`.
    #[inline]
    pub fn triangle_vertices(&self, t: usize) -> [Index; 3] {
        let [a, b, c] = self.triangles[t];
        [
            self.wedges[a as usize].vertex,
            self.wedges[b as usize].vertex,
            self.wedges[c as usize].vertex,
        ]
    }

    /// The three corner positions of triangle `t`.
    #[inline]
    pub fn triangle_positions(&self, t: usize) -> [DVec3; 3] {
        self.triangle_vertices(t)
            .map(|v| self.positions[v as usize])
    }

    /// Unnormalised face normal (cross product; its length is twice the area).
    #[inline]
    pub fn triangle_cross(&self, t: usize) -> DVec3 {
        let [a, b, c] = self.triangle_positions(t);
        (b - a).cross(c - a)
    }

    pub fn triangle_area(&self, t: usize) -> f64 {
        0.5 * self.triangle_cross(t).length()
    }

    /// Texture coordinate of a wedge, if it has one.
    #[inline]
    pub fn wedge_texcoord(&self, w: Index) -> Option<DVec2> {
        self.wedges[w as usize]
            .texcoord
            .map(|i| self.texcoords[i as usize])
    }

    /// Material of triangle `t` (0 when the mesh has no per-triangle materials).
    #[inline]
    pub fn triangle_material(&self, t: usize) -> Index {
        self.triangle_materials.get(t).copied().unwrap_or(0)
    }

    /// The input triangle that triangle `t` descends from.
    #[inline]
    pub fn triangle_origin(&self, t: usize) -> Index {
        self.triangle_origins.get(t).copied().unwrap_or(t as Index)
    }

    /// The embedded bytes of the texture known by `path`, if it is one (see
    /// [`Texture::embedded`]).
    pub fn embedded_image(&self, path: &Path) -> Option<&EmbeddedImage> {
        self.materials
            .iter()
            .filter_map(|m| m.diffuse_texture.as_ref())
            .find(|t| t.path == path)
            .and_then(|t| t.embedded.as_ref())
    }

    /// Axis-aligned bounding box of the positions, `None` for an empty mesh.
    pub fn bounding_box(&self) -> Option<(DVec3, DVec3)> {
        bounding_box_of(&self.positions)
    }

    /// Length of the bounding-box diagonal (0 for an empty mesh).
    pub fn bounding_box_diagonal(&self) -> f64 {
        self.bounding_box()
            .map(|(lo, hi)| (hi - lo).length())
            .unwrap_or(0.0)
    }

    /// Mean length of the triangle edges (each undirected edge counted once per triangle side).
    pub fn mean_edge_length(&self) -> f64 {
        if self.triangles.is_empty() {
            return 0.0;
        }
        // The perimeters in parallel (three square roots each), then summed on one thread
        // in triangle order: the same sum, bit for bit, as a sequential loop. The fairing
        // computes this at the start of every step, where the other core would wait.
        let perimeters: Vec<f64> = (0..self.triangles.len())
            .into_par_iter()
            .map(|t| {
                let [a, b, c] = self.triangle_positions(t);
                a.distance(b) + b.distance(c) + c.distance(a)
            })
            .collect();
        let sum: f64 = perimeters.iter().sum();
        sum / (3 * self.triangles.len()) as f64
    }

    /// Checks the internal invariants (index ranges, array lengths). Used by tests and
    /// debug assertions after every step; a violation is a bug in scanmill, not bad input.
    pub fn check_invariants(&self) -> Result<(), String> {
        let (nv, nt, nn) = (
            self.positions.len(),
            self.texcoords.len(),
            self.normals.len(),
        );
        if !self.colors.is_empty() && self.colors.len() != nv {
            return Err(format!("{} colours for {} vertices", self.colors.len(), nv));
        }
        for (i, w) in self.wedges.iter().enumerate() {
            if w.vertex as usize >= nv {
                return Err(format!("wedge {i} vertex {} out of range", w.vertex));
            }
            if w.texcoord.is_some_and(|x| x as usize >= nt) {
                return Err(format!("wedge {i} texcoord out of range"));
            }
            if w.normal.is_some_and(|x| x as usize >= nn) {
                return Err(format!("wedge {i} normal out of range"));
            }
        }
        for (t, tri) in self.triangles.iter().enumerate() {
            if tri.iter().any(|&w| w as usize >= self.wedges.len()) {
                return Err(format!("triangle {t} wedge out of range"));
            }
        }
        if !self.triangle_materials.is_empty() {
            if self.triangle_materials.len() != self.triangles.len() {
                return Err("triangle_materials length differs from triangles".into());
            }
            if self
                .triangle_materials
                .iter()
                .any(|&m| m as usize >= self.materials.len())
            {
                return Err("triangle material out of range".into());
            }
        }
        if !self.triangle_origins.is_empty() && self.triangle_origins.len() != self.triangles.len()
        {
            return Err("triangle_origins length differs from triangles".into());
        }
        Ok(())
    }
}

/// Axis-aligned bounding box of `points`, `None` when there are none (for positions that
/// are not, or no longer, a [`Mesh`]'s).
pub fn bounding_box_of(points: &[DVec3]) -> Option<(DVec3, DVec3)> {
    let first = *points.first()?;
    Some(
        points
            .iter()
            .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))),
    )
}

#[cfg(test)]
mod tests {
    use crate::mesh::shapes::{grid, with_a_normal_per_triangle};

    #[test]
    fn dropping_normals_merges_the_wedges_they_split() {
        let plain = grid(3, 2);
        let mut m = with_a_normal_per_triangle(plain.clone());
        m.check_invariants().unwrap();
        assert_eq!(m.wedges.len(), 3 * m.triangles.len());

        m.drop_normals();

        m.check_invariants().unwrap();
        assert!(m.normals.is_empty());
        // One wedge per vertex again (the grid has no texture seam), each corner with its
        // vertex and texture coordinate as before.
        assert_eq!(m.wedges.len(), m.positions.len());
        for (a, b) in m.triangles.iter().zip(&plain.triangles) {
            for (&wa, &wb) in a.iter().zip(b) {
                let (x, y) = (m.wedges[wa as usize], plain.wedges[wb as usize]);
                assert_eq!(
                    (x.vertex, x.texcoord, x.normal),
                    (y.vertex, y.texcoord, None)
                );
            }
        }
    }
}
