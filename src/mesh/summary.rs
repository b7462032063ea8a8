//! What `scanmill inspect` prints: topology counts, geometry, materials and what loading
//! repaired, as a serialisable struct and as aligned text for a terminal.

use super::build::{LoadReport, is_zero_area};
use super::model::Mesh;
use super::topology::{Topology, TopologyCounts};
use glam::DVec3;
use serde::Serialize;
use std::fmt;

/// Axis-aligned bounding box of the positions.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BoundingBox {
    pub min: DVec3,
    pub max: DVec3,
    pub diagonal: f64,
}

/// One material as `inspect` shows it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MaterialSummary {
    pub name: String,
    /// The diffuse texture's name as the MTL wrote it.
    pub texture: Option<String>,
    /// Width and height in pixels, when the image was decoded.
    pub texture_size: Option<(u32, u32)>,
    /// Triangles that use this material.
    pub triangles: usize,
}

/// A summary of one mesh. The topology counts are flattened into the JSON object.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MeshSummary {
    #[serde(flatten)]
    pub topology: TopologyCounts,
    /// `None` for a mesh without vertices.
    pub bounding_box: Option<BoundingBox>,
    /// Mean length of the undirected edges, each edge counted once.
    pub mean_edge_length: f64,
    /// Triangles in the mesh as it is that repeat a vertex or have zero area (by the
    /// loader's rule: height at most 1e-12 of the longest edge). 0 after a normal load,
    /// which drops them (see `load`).
    pub degenerate_triangles: usize,
    /// Triangles in the mesh as it is with the same three vertices as an earlier one
    /// (either orientation).
    pub duplicate_triangles: usize,
    pub materials: Vec<MaterialSummary>,
    /// What loading found and repaired, if the mesh came from a file.
    pub load: Option<LoadReport>,
}

impl MeshSummary {
    pub fn new(mesh: &Mesh, load: Option<&LoadReport>) -> Self {
        Self::with_topology(mesh, &Topology::new(mesh), load)
    }

    /// As [`MeshSummary::new`], reusing a topology already computed for `mesh`.
    pub fn with_topology(mesh: &Mesh, topology: &Topology, load: Option<&LoadReport>) -> Self {
        let bounding_box = mesh.bounding_box().map(|(min, max)| BoundingBox {
            min,
            max,
            diagonal: (max - min).length(),
        });
        let edges = topology.edges();
        let mean_edge_length = if edges.is_empty() {
            0.0
        } else {
            edges
                .iter()
                .map(|&[a, b]| mesh.positions[a as usize].distance(mesh.positions[b as usize]))
                .sum::<f64>()
                / edges.len() as f64
        };
        let mut material_triangles = vec![0usize; mesh.materials.len()];
        for t in 0..mesh.triangles.len() {
            if let Some(n) = material_triangles.get_mut(mesh.triangle_material(t) as usize) {
                *n += 1;
            }
        }
        let materials = mesh
            .materials
            .iter()
            .zip(material_triangles)
            .map(|(m, triangles)| MaterialSummary {
                name: m.name.clone(),
                texture: m.diffuse_texture.as_ref().map(|t| t.name.clone()),
                texture_size: m.diffuse_texture.as_ref().and_then(|t| t.size),
                triangles,
            })
            .collect();
        MeshSummary {
            topology: topology.counts(),
            bounding_box,
            mean_edge_length,
            degenerate_triangles: count_degenerate(mesh),
            duplicate_triangles: count_duplicates(mesh),
            materials,
            load: load.cloned(),
        }
    }
}

/// Triangles that repeat a vertex or have zero area.
pub fn count_degenerate(mesh: &Mesh) -> usize {
    (0..mesh.triangles.len())
        .filter(|&t| {
            let [a, b, c] = mesh.triangle_vertices(t);
            let [pa, pb, pc] = mesh.triangle_positions(t);
            a == b || b == c || a == c || is_zero_area(pa, pb, pc)
        })
        .count()
}

fn count_duplicates(mesh: &Mesh) -> usize {
    let mut keys: Vec<[u32; 3]> = (0..mesh.triangles.len())
        .map(|t| {
            let mut v = mesh.triangle_vertices(t);
            v.sort_unstable();
            v
        })
        .collect();
    keys.sort_unstable();
    keys.windows(2).filter(|w| w[0] == w[1]).count()
}

/// `1234567` → `"1,234,567"`.
pub fn thousands(n: usize) -> String {
    let digits = n.to_string();
    let mut out = String::with_capacity(digits.len() + digits.len() / 3);
    for (i, ch) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(ch);
    }
    out
}

fn signed_thousands(n: i64) -> String {
    let sign = if n < 0 { "-" } else { "" };
    format!("{sign}{}", thousands(n.unsigned_abs() as usize))
}

/// About six significant digits, in plain notation where that stays readable.
fn real(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 {
        "0".into()
    } else if (1e-3..1e7).contains(&a) {
        let decimals = (5 - a.log10().floor() as i32).clamp(0, 8) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.5e}")
    }
}

fn point(p: DVec3) -> String {
    format!("({}, {}, {})", real(p.x), real(p.y), real(p.z))
}

const LABEL: usize = 24;
const NUMBER: usize = 12;

fn count_line(f: &mut fmt::Formatter<'_>, label: &str, n: usize, note: &str) -> fmt::Result {
    writeln!(f, "{label:<LABEL$}{:>NUMBER$}{note}", thousands(n))
}

impl fmt::Display for MeshSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let c = &self.topology;
        count_line(f, "Vertices", c.vertices, "")?;
        count_line(f, "Triangles", c.triangles, "")?;
        count_line(f, "Wedges", c.wedges, "")?;
        count_line(f, "Texture coordinates", c.texcoords, "")?;
        count_line(f, "Edges", c.edges, "")?;
        let mut loops = format!("  in {} loops", thousands(c.boundary_loops));
        if c.boundary_chains != c.boundary_loops || c.open_boundary_chains > 0 {
            loops += &format!(
                " ({} chains split at pinch vertices, {} open)",
                thousands(c.boundary_chains),
                thousands(c.open_boundary_chains)
            );
        }
        count_line(f, "Boundary edges", c.boundary_edges, &loops)?;
        count_line(f, "Components", c.components, "")?;
        count_line(f, "Non-manifold edges", c.non_manifold_edges, "")?;
        count_line(f, "Non-manifold vertices", c.non_manifold_vertices, "")?;
        count_line(f, "Inconsistent edges", c.inconsistent_edges, "")?;
        count_line(
            f,
            "Seam edges",
            c.seam_edges,
            "  (texture coordinate or normal)",
        )?;
        count_line(f, "Texture seam edges", c.texture_seam_edges, "")?;
        writeln!(
            f,
            "{:<LABEL$}{:>NUMBER$}",
            "Euler characteristic",
            signed_thousands(c.euler_characteristic)
        )?;
        count_line(f, "Degenerate triangles", self.degenerate_triangles, "")?;
        count_line(f, "Duplicate triangles", self.duplicate_triangles, "")?;
        match &self.bounding_box {
            Some(b) => {
                writeln!(f, "{:<LABEL$}min {}", "Bounding box", point(b.min))?;
                writeln!(f, "{:<LABEL$}max {}", "", point(b.max))?;
                writeln!(f, "{:<LABEL$}{}", "Diagonal", real(b.diagonal))?;
            }
            None => writeln!(f, "{:<LABEL$}none (no vertices)", "Bounding box")?,
        }
        writeln!(
            f,
            "{:<LABEL$}{}",
            "Mean edge length",
            real(self.mean_edge_length)
        )?;

        count_line(f, "Materials", self.materials.len(), "")?;
        for m in &self.materials {
            let texture = match (&m.texture, m.texture_size) {
                (Some(name), Some((w, h))) => format!("{name} ({w}×{h})"),
                (Some(name), None) => format!("{name} (size not checked)"),
                (None, _) => "no texture".into(),
            };
            writeln!(
                f,
                "  {}: {texture}, {} triangles",
                m.name,
                thousands(m.triangles)
            )?;
        }
        if let Some(load) = &self.load {
            write_load_report(f, load)?;
        }
        Ok(())
    }
}

fn write_load_report(f: &mut fmt::Formatter<'_>, r: &LoadReport) -> fmt::Result {
    writeln!(f, "Loaded as {}", r.format)?;
    writeln!(
        f,
        "  file: {} vertices, {} faces, {} texture coordinates, {} normals",
        thousands(r.file_vertices),
        thousands(r.file_faces),
        thousands(r.file_texcoords),
        thousands(r.file_normals)
    )?;
    let repairs = [
        (r.triangulated_polygons, "polygons fan-triangulated"),
        (r.strip_triangles, "triangles unrolled from strips"),
        (r.welded_vertices, "vertices welded"),
        (r.merged_texcoords, "duplicate texture coordinates merged"),
        (r.merged_normals, "duplicate normals merged"),
        (r.dropped_degenerate_faces, "degenerate faces dropped"),
        (r.dropped_zero_area_faces, "zero-area faces dropped"),
        (r.dropped_duplicate_faces, "duplicate faces dropped"),
        (
            r.dropped_unreferenced_vertices,
            "unreferenced vertices dropped",
        ),
    ];
    let mut any = false;
    for (n, what) in repairs.into_iter().filter(|&(n, _)| n > 0) {
        writeln!(f, "{:<LABEL$}{:>NUMBER$} {what}", "", thousands(n))?;
        any = true;
    }
    if !any {
        writeln!(f, "  nothing welded or repaired")?;
    }
    for skipped in &r.skipped {
        writeln!(f, "  skipped: {skipped}")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::model::{Material, Texture, Wedge};
    use glam::DVec3;

    fn square_with_duplicate() -> Mesh {
        let positions = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.0, 2.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0), // on the diagonal: (0, 2, 4) has zero area
        ];
        let wedges = (0..5)
            .map(|v| Wedge {
                vertex: v,
                texcoord: None,
                normal: None,
            })
            .collect();
        Mesh {
            positions,
            wedges,
            triangles: vec![[0, 1, 2], [0, 2, 3], [2, 1, 0], [0, 2, 4]],
            triangle_materials: vec![0, 0, 1, 1],
            materials: vec![
                Material {
                    name: "skin".into(),
                    diffuse_texture: Some(Texture {
                        name: "skin.jpg".into(),
                        path: "skin.jpg".into(),
                        size: Some((2400, 1600)),
                        embedded: None,
                    }),
                    ..Default::default()
                },
                Material {
                    name: "plain".into(),
                    ..Default::default()
                },
            ],
            ..Default::default()
        }
    }

    #[test]
    fn summary_counts_and_geometry() {
        let mesh = square_with_duplicate();
        let s = MeshSummary::new(&mesh, None);
        assert_eq!(s.topology.triangles, 4);
        assert_eq!(s.degenerate_triangles, 1);
        assert_eq!(s.duplicate_triangles, 1);
        let b = s.bounding_box.unwrap();
        assert_eq!((b.min, b.max), (DVec3::ZERO, DVec3::new(2.0, 2.0, 0.0)));
        assert!((b.diagonal - 8f64.sqrt()).abs() < 1e-12);
        // Edges: 4 sides of length 2, diagonal 0-2 (√8), 0-4 and 2-4 (√2 each).
        let expected = (4.0 * 2.0 + 8f64.sqrt() + 2.0 * 2f64.sqrt()) / 7.0;
        assert!((s.mean_edge_length - expected).abs() < 1e-12);
        assert_eq!(s.materials[0].triangles, 2);
        assert_eq!(s.materials[1].texture, None);
    }

    #[test]
    fn display_is_aligned_and_readable() {
        let mesh = square_with_duplicate();
        let report = LoadReport {
            format: "obj".into(),
            file_vertices: 1_234_567,
            file_faces: 4,
            welded_vertices: 1200,
            ..Default::default()
        };
        let text = MeshSummary::new(&mesh, Some(&report)).to_string();
        assert!(text.contains("1,234,567 vertices"), "{text}");
        assert!(text.contains("1,200 vertices welded"), "{text}");
        assert!(
            text.contains("skin: skin.jpg (2400×1600), 2 triangles"),
            "{text}"
        );
        let number_columns: Vec<usize> = text.lines().take(5).map(|l| l.chars().count()).collect();
        assert!(
            number_columns.iter().all(|&n| n == LABEL + NUMBER),
            "{text}"
        );
        let empty = MeshSummary::new(&Mesh::default(), None).to_string();
        assert!(empty.contains("none (no vertices)"));
    }

    #[test]
    fn summary_serializes_flat() {
        let json = serde_json::to_value(MeshSummary::new(&square_with_duplicate(), None)).unwrap();
        assert_eq!(json["triangles"], 4);
        assert_eq!(json["bounding_box"]["max"][0], 2.0);
        assert!(json["load"].is_null());
    }

    #[test]
    fn number_formatting() {
        assert_eq!(thousands(0), "0");
        assert_eq!(thousands(999), "999");
        assert_eq!(thousands(1000), "1,000");
        assert_eq!(thousands(12_345_678), "12,345,678");
        assert_eq!(signed_thousands(-1234), "-1,234");
        assert_eq!(real(0.0), "0");
        assert_eq!(real(1.5), "1.50000");
        assert_eq!(real(123.456789), "123.457");
        assert_eq!(real(1e-6), "1.00000e-6");
    }
}
