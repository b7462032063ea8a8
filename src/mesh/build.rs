//! Turning what a reader parsed into a valid [`Mesh`]: welding, wedge construction and the
//! repair rules. Every reader (OBJ, PLY) fills a [`MeshBuilder`] and calls
//! [`MeshBuilder::finish`], so the rules are the same whatever the format.
//!
//! Repair rules (issue #2, item 6):
//! - faces with fewer than 3 distinct vertices (after welding) are dropped and counted;
//! - zero-area faces (height below 1e-12 of the longest edge) are dropped and counted;
//! - exact duplicate faces (same three vertices, either orientation) are dropped and counted;
//! - unreferenced vertices are dropped and counted;
//! - non-manifold edges are kept (topology reports them).
//!
//! Non-finite coordinates and out-of-range indices are errors; readers check them with the
//! line or element where they occur, and `finish` checks indices again as a safety net.

use super::error::{Location, MeshError, Result};
use super::limits::InputLimits;
use super::model::{Index, Material, Mesh, Wedge};
use super::wedges::WedgeInterner;
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use rustc_hash::FxHashMap as HashMap;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// One face corner as a file states it: indices into the position, texture-coordinate and
/// normal arrays (0-based, already resolved from negative or 1-based form).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Corner {
    pub vertex: Index,
    pub texcoord: Option<Index>,
    pub normal: Option<Index>,
}

/// Options that govern loading.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoadOptions {
    /// Weld vertices closer than this fraction of the bounding-box diagonal.
    /// 0 (the default) welds only bit-identical positions.
    pub weld_tolerance: f64,
    /// Decode every texture image to check it and learn its size.
    pub check_textures: bool,
    /// A texture image to use when the file names none (an OBJ without `mtllib`/`usemtl`
    /// exported beside its image, e.g. `example.obj` + `example.png`). Readers that find no
    /// materials create one material, `scanmill_texture`, with this diffuse texture; when the
    /// file does declare materials the override is ignored (with a warning).
    pub texture_override: Option<PathBuf>,
    /// How much the scan may make the readers read, decompress and decode (every reader
    /// sees these; `process` and `inspect` use the defaults, the daemon its `[limits]`).
    pub limits: InputLimits,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            weld_tolerance: 0.0,
            check_textures: true,
            texture_override: None,
            limits: InputLimits::default(),
        }
    }
}

/// What loading found and repaired. Shown by `inspect` and kept in reports.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LoadReport {
    pub format: String,
    /// Counts as stored in the file.
    pub file_vertices: usize,
    pub file_faces: usize,
    pub file_texcoords: usize,
    pub file_normals: usize,
    /// Polygons with more than 3 corners, fan-triangulated.
    pub triangulated_polygons: usize,
    /// Triangles produced from triangle strips.
    pub strip_triangles: usize,
    /// Vertices merged into another at the same position.
    pub welded_vertices: usize,
    /// Texture coordinates / normals merged with a bit-identical copy.
    pub merged_texcoords: usize,
    pub merged_normals: usize,
    pub dropped_degenerate_faces: usize,
    pub dropped_zero_area_faces: usize,
    pub dropped_duplicate_faces: usize,
    pub dropped_unreferenced_vertices: usize,
    /// Elements and properties skipped because scanmill does not use them.
    pub skipped: Vec<String>,
    /// Texture images decoded to check them: one per distinct file, however many
    /// materials name it.
    pub decoded_textures: usize,
}

/// What the repair rules decided for one face.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FaceStatus {
    Kept = 0,
    Degenerate = 1,
    ZeroArea = 2,
    Duplicate = 3,
}

/// Raw arrays as a reader parsed them, before validation and repair.
#[derive(Debug, Default)]
pub struct MeshBuilder {
    pub path: PathBuf,
    pub positions: Vec<DVec3>,
    pub texcoords: Vec<DVec2>,
    pub normals: Vec<DVec3>,
    /// Empty, or one per position.
    pub colors: Vec<[u8; 4]>,
    pub faces: Vec<[Corner; 3]>,
    /// Empty, or one per face.
    pub face_materials: Vec<Index>,
    pub materials: Vec<Material>,
    /// `(face, further copies)`: copies of a face that a reader counted instead of storing
    /// (see the PLY strip reader). Each copy shares its face's fate in the repair rules: a
    /// copy of a kept face is a dropped duplicate, a copy of a dropped face is dropped for
    /// the same reason.
    pub face_repeats: Vec<(Index, u32)>,
    pub report: LoadReport,
}

/// Positions are compared bit-exactly; -0.0 and +0.0 are the same position.
fn position_key(p: DVec3) -> [u64; 3] {
    [
        (p.x + 0.0).to_bits(),
        (p.y + 0.0).to_bits(),
        (p.z + 0.0).to_bits(),
    ]
}

impl MeshBuilder {
    pub fn new(path: &Path, format: &str) -> Self {
        MeshBuilder {
            path: path.to_path_buf(),
            report: LoadReport {
                format: format.to_string(),
                ..Default::default()
            },
            ..Default::default()
        }
    }

    /// Validates, welds, builds wedges, applies the repair rules and compacts.
    pub fn finish(mut self, options: &LoadOptions) -> Result<(Mesh, LoadReport)> {
        self.check_indices()?;
        let (weld, (texcoords, texcoord_map), (normals, normal_map)) =
            self.merge_maps(options.weld_tolerance);
        self.report.merged_texcoords = self.texcoords.len() - texcoords.len();
        self.report.merged_normals = self.normals.len() - normals.len();

        let (kept, dropped) = self.classify_faces(&weld);
        self.report.dropped_degenerate_faces = dropped[FaceStatus::Degenerate as usize];
        self.report.dropped_zero_area_faces = dropped[FaceStatus::ZeroArea as usize];
        self.report.dropped_duplicate_faces = dropped[FaceStatus::Duplicate as usize];

        let maps = CornerMaps {
            weld: &weld,
            texcoords: &texcoord_map,
            normals: &normal_map,
        };
        let (interner, triangles, triangle_materials) = self.wedge_triangles(&kept, &maps);
        if triangles.is_empty() {
            return Err(self.no_triangles());
        }
        self.report.welded_vertices = self.positions.len() - representatives(&weld);

        let mut mesh = Mesh {
            positions: self.positions,
            texcoords,
            normals,
            colors: self.colors,
            wedges: interner.into_wedges(),
            triangles,
            triangle_materials,
            materials: self.materials,
            triangle_origins: Vec::new(),
        };
        let removed = mesh.compact();
        self.report.dropped_unreferenced_vertices = removed.vertices - self.report.welded_vertices;
        debug_assert!(mesh.check_invariants().is_ok());
        Ok((mesh, self.report))
    }

    /// The weld map of the positions and the distinct texture coordinates and normals with
    /// their maps: three independent hash passes (~35-55 ms each on a 400k-triangle scan),
    /// side by side.
    fn merge_maps(&self, weld_tolerance: f64) -> (Vec<Index>, Deduped<DVec2>, Deduped<DVec3>) {
        let (weld, (texcoords, normals)) = rayon::join(
            || self.weld_map(weld_tolerance),
            || {
                rayon::join(
                    || {
                        dedupe_by_bits(&self.texcoords, |t| {
                            [(t.x + 0.0).to_bits(), (t.y + 0.0).to_bits(), 0]
                        })
                    },
                    || dedupe_by_bits(&self.normals, position_key),
                )
            },
        );
        (weld, texcoords, normals)
    }

    /// The kept faces as triangles of wedges (one per distinct vertex, texcoord and normal,
    /// numbered in order of first use), with their materials where the faces have them.
    fn wedge_triangles(
        &self,
        kept: &[Index],
        maps: &CornerMaps<'_>,
    ) -> (WedgeInterner, Vec<[Index; 3]>, Vec<Index>) {
        let mut interner = WedgeInterner::new(self.positions.len());
        let mut triangles: Vec<[Index; 3]> = Vec::with_capacity(kept.len());
        let mut triangle_materials: Vec<Index> = Vec::new();
        let has_materials = !self.face_materials.is_empty();
        for &f in kept {
            let face = &self.faces[f as usize];
            let mut tri = [0; 3];
            for (k, corner) in face.iter().enumerate() {
                let wedge = Wedge {
                    vertex: maps.weld[corner.vertex as usize],
                    texcoord: corner.texcoord.map(|t| maps.texcoords[t as usize]),
                    normal: corner.normal.map(|n| maps.normals[n as usize]),
                };
                tri[k] = interner.intern(wedge);
            }
            triangles.push(tri);
            if has_materials {
                triangle_materials.push(self.face_materials[f as usize]);
            }
        }
        (interner, triangles, triangle_materials)
    }

    /// The error when no face survives: the file has none, or all were dropped.
    fn no_triangles(self) -> MeshError {
        let r = &self.report;
        let reason = if self.faces.is_empty() {
            "the file has no faces".to_string()
        } else {
            format!(
                "all {} faces were dropped ({} degenerate, {} zero-area, {} duplicate)",
                self.faces.len(),
                r.dropped_degenerate_faces,
                r.dropped_zero_area_faces,
                r.dropped_duplicate_faces
            )
        };
        MeshError::NoTriangles {
            path: self.path,
            reason,
        }
    }

    /// Applies the face repair rules in parallel. Returns the faces kept, in file order, and
    /// how many were dropped for each reason (indexed by [`FaceStatus`]).
    fn classify_faces(&self, weld: &[Index]) -> (Vec<Index>, [usize; 4]) {
        let positions = &self.positions;
        let mut status: Vec<FaceStatus> = self
            .faces
            .par_iter()
            .map(|face| {
                let v = face.map(|c| weld[c.vertex as usize]);
                if v[0] == v[1] || v[1] == v[2] || v[0] == v[2] {
                    FaceStatus::Degenerate
                } else if is_zero_area(
                    positions[v[0] as usize],
                    positions[v[1] as usize],
                    positions[v[2] as usize],
                ) {
                    FaceStatus::ZeroArea
                } else {
                    FaceStatus::Kept
                }
            })
            .collect();
        // A duplicate uses the same three vertices, in either orientation (as MeshLab's
        // "Remove Duplicate Faces" and the counts in data/SOURCES.md define it): a reversed
        // copy is a zero-volume double layer, not surface. The first occurrence is kept.
        let mut keys: Vec<([Index; 3], Index)> = status
            .par_iter()
            .enumerate()
            .filter(|(_, s)| **s == FaceStatus::Kept)
            .map(|(f, _)| {
                let mut key = self.faces[f].map(|c| weld[c.vertex as usize]);
                key.sort_unstable();
                (key, f as Index)
            })
            .collect();
        keys.par_sort_unstable();
        for pair in keys.windows(2) {
            if pair[0].0 == pair[1].0 {
                status[pair[1].1 as usize] = FaceStatus::Duplicate;
            }
        }
        let mut dropped = [0usize; 4];
        for &(f, copies) in &self.face_repeats {
            let fate = match status[f as usize] {
                FaceStatus::Kept => FaceStatus::Duplicate,
                other => other,
            };
            dropped[fate as usize] += copies as usize;
        }
        let mut kept = Vec::with_capacity(self.faces.len());
        for (f, s) in status.iter().enumerate() {
            dropped[*s as usize] += 1;
            if *s == FaceStatus::Kept {
                kept.push(f as Index);
            }
        }
        (kept, dropped)
    }

    fn check_indices(&self) -> Result<()> {
        let (nv, nt, nn) = (
            self.positions.len(),
            self.texcoords.len(),
            self.normals.len(),
        );
        let out_of_range =
            |f: usize, kind: &'static str, index: Index, count: usize| MeshError::IndexOutOfRange {
                path: self.path.clone(),
                at: Location::Element {
                    element: "face".into(),
                    index: f as u64,
                },
                kind,
                index: index as i64,
                count,
            };
        for (f, face) in self.faces.iter().enumerate() {
            for c in face {
                if c.vertex as usize >= nv {
                    return Err(out_of_range(f, "vertex", c.vertex, nv));
                }
                if let Some(t) = c.texcoord.filter(|&t| t as usize >= nt) {
                    return Err(out_of_range(f, "texture coordinate", t, nt));
                }
                if let Some(n) = c.normal.filter(|&n| n as usize >= nn) {
                    return Err(out_of_range(f, "normal", n, nn));
                }
            }
        }
        for (i, p) in self.positions.iter().enumerate() {
            if !p.is_finite() {
                return Err(MeshError::NonFinite {
                    path: self.path.clone(),
                    at: Location::Element {
                        element: "vertex".into(),
                        index: i as u64,
                    },
                    value: format!("{} {} {}", p.x, p.y, p.z),
                });
            }
        }
        if !self.face_materials.is_empty() && self.face_materials.len() != self.faces.len() {
            return Err(MeshError::malformed(
                &self.path,
                Location::Header,
                "material list does not match faces",
            ));
        }
        Ok(())
    }

    /// For every vertex, the vertex it is welded into (itself if it is kept).
    /// Deterministic: the representative is the lowest index of the group.
    fn weld_map(&self, relative_tolerance: f64) -> Vec<Index> {
        let n = self.positions.len();
        let mut map: Vec<Index> = (0..n as Index).collect();
        if relative_tolerance <= 0.0 {
            let mut first: HashMap<[u64; 3], Index> =
                HashMap::with_capacity_and_hasher(n, Default::default());
            for (i, &p) in self.positions.iter().enumerate() {
                map[i] = *first.entry(position_key(p)).or_insert(i as Index);
            }
            return map;
        }
        let diagonal = bbox_diagonal(&self.positions);
        let tol = relative_tolerance * diagonal;
        if tol <= 0.0 {
            return self.weld_map(0.0);
        }
        // Grid hash with cell = tolerance: a vertex is welded into the first earlier
        // representative within `tol`, searching the 27 neighbouring cells.
        let cell = |p: DVec3| -> [i64; 3] {
            let q = (p / tol).floor();
            [q.x as i64, q.y as i64, q.z as i64]
        };
        let mut grid: HashMap<[i64; 3], Vec<Index>> = HashMap::default();
        for (i, &p) in self.positions.iter().enumerate() {
            let c = cell(p);
            let mut found: Option<Index> = None;
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let Some(reps) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                            continue;
                        };
                        for &r in reps {
                            if self.positions[r as usize].distance(p) <= tol
                                && found.is_none_or(|f| r < f)
                            {
                                found = Some(r);
                            }
                        }
                    }
                }
            }
            match found {
                Some(r) => map[i] = r,
                None => grid.entry(c).or_default().push(i as Index),
            }
        }
        map
    }
}

fn bbox_diagonal(points: &[DVec3]) -> f64 {
    let Some(&first) = points.first() else {
        return 0.0;
    };
    let (lo, hi) = points
        .iter()
        .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    (hi - lo).length()
}

/// A triangle whose height is below 1e-12 of its longest edge has no area worth keeping.
/// Shared with `summary` so that `inspect` counts degenerate triangles by the same rule.
pub(crate) fn is_zero_area(a: DVec3, b: DVec3, c: DVec3) -> bool {
    let cross = (b - a).cross(c - a).length();
    let longest = (b - a)
        .length_squared()
        .max((c - b).length_squared())
        .max((a - c).length_squared());
    // cross = longest_edge * height; height <= 1e-12 * longest_edge
    cross <= 1e-12 * longest
}

/// Merges bit-identical values, keeping first occurrences in order.
/// Distinct values, and where each original value went among them.
type Deduped<T> = (Vec<T>, Vec<Index>);

/// Where a file's corner indices go: its vertex to the welded vertex, its texture
/// coordinate and normal to the distinct ones.
struct CornerMaps<'a> {
    weld: &'a [Index],
    texcoords: &'a [Index],
    normals: &'a [Index],
}

/// Vertices that survive welding (representatives), before dropping unreferenced ones.
fn representatives(weld: &[Index]) -> usize {
    weld.iter()
        .enumerate()
        .filter(|&(i, &r)| r as usize == i)
        .count()
}

fn dedupe_by_bits<T: Copy>(values: &[T], key: impl Fn(T) -> [u64; 3]) -> Deduped<T> {
    let mut first: HashMap<[u64; 3], Index> =
        HashMap::with_capacity_and_hasher(values.len(), Default::default());
    let mut kept = Vec::with_capacity(values.len());
    let map = values
        .iter()
        .map(|&v| {
            *first.entry(key(v)).or_insert_with(|| {
                kept.push(v);
                (kept.len() - 1) as Index
            })
        })
        .collect();
    (kept, map)
}
