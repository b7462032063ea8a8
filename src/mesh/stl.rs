//! STL input, ASCII and binary. An STL is a triangle soup: every facet states its three
//! corner positions, nothing is shared. The reader hands the soup to [`MeshBuilder`], whose
//! exact-position weld joins the corners into vertices (reported as `vertices welded`, as for
//! a PLY), so that every later step sees a connected surface.
//!
//! Which encoding: a binary STL is an 80-byte header, a little-endian `u32` triangle count
//! and 50 bytes per triangle, so its size is known from its count. A file whose size is
//! exactly that is binary, whatever its header says (several exporters begin a binary header
//! with `solid`); a file that begins with `solid` and is text otherwise is ASCII; anything
//! else is a binary STL whose count and size disagree, an error naming both.
//!
//! Not used, with a note in the load report: facet normals (recomputed by the `normals` step
//! where a recipe wants them; per-facet normals would split every vertex) and the per-facet
//! attribute word, where VisCAM/SolidView and Materialise Magics keep colours.

use super::build::{Corner, LoadOptions, LoadReport, MeshBuilder};
use super::error::{Location, MeshError, Result};
use super::model::{Index, Mesh};
use glam::DVec3;
use std::path::Path;

const HEADER_BYTES: usize = 80;
const FACET_BYTES: usize = 50;

/// Reads an STL file's bytes (see the module rules).
pub fn read(path: &Path, bytes: &[u8], options: &LoadOptions) -> Result<(Mesh, LoadReport)> {
    let builder = parse(path, bytes)?;
    builder.finish(options)
}

/// Parses an STL into a builder (corners unwelded).
pub fn parse(path: &Path, bytes: &[u8]) -> Result<MeshBuilder> {
    match binary_count(bytes) {
        Some(count) => parse_binary(path, bytes, count),
        None if looks_ascii(bytes) => parse_ascii(path, bytes),
        None => Err(count_mismatch(path, bytes)),
    }
}

/// An ASCII STL begins with `solid` and is text: a binary STL whose header happens to begin
/// with `solid` shows binary bytes (its count, its floats) within its first 512 bytes, and a
/// truncated one is then reported as a binary STL whose count and size disagree.
fn looks_ascii(bytes: &[u8]) -> bool {
    bytes.trim_ascii_start().starts_with(b"solid")
        && bytes
            .iter()
            .take(512)
            .all(|&b| b.is_ascii_graphic() || b.is_ascii_whitespace())
}

/// The triangle count of a binary STL whose size agrees with it.
fn binary_count(bytes: &[u8]) -> Option<usize> {
    let count = u32::from_le_bytes(bytes.get(HEADER_BYTES..HEADER_BYTES + 4)?.try_into().ok()?);
    let expected = (HEADER_BYTES as u64 + 4) + u64::from(count) * FACET_BYTES as u64;
    (expected == bytes.len() as u64).then_some(count as usize)
}

fn count_mismatch(path: &Path, bytes: &[u8]) -> MeshError {
    match bytes.get(HEADER_BYTES..HEADER_BYTES + 4) {
        None => MeshError::malformed(
            path,
            Location::Header,
            format!(
                "not an STL file: {} bytes is shorter than a binary STL header (84 bytes) and the file does not begin with \"solid\"",
                bytes.len()
            ),
        ),
        Some(raw) => {
            let count = u32::from_le_bytes(raw.try_into().unwrap_or_default());
            let expected = (HEADER_BYTES as u64 + 4) + u64::from(count) * FACET_BYTES as u64;
            MeshError::malformed(
                path,
                Location::Header,
                format!(
                    "binary STL declares {count} triangles ({expected} bytes) but the file has {} bytes",
                    bytes.len()
                ),
            )
        }
    }
}

fn new_builder(path: &Path, format: &str, facets: usize) -> MeshBuilder {
    let mut b = MeshBuilder::new(path, format);
    b.positions.reserve(facets * 3);
    b.faces.reserve(facets);
    b.report.skipped.push(
        "facet normals (STL normals are per facet; the normals step computes vertex normals)"
            .into(),
    );
    b
}

/// Adds one facet: three fresh positions and a face on them (welded later).
fn push_facet(b: &mut MeshBuilder, corners: [DVec3; 3]) {
    let first = b.positions.len() as Index;
    b.positions.extend_from_slice(&corners);
    b.faces.push([0, 1, 2].map(|k| Corner {
        vertex: first + k,
        texcoord: None,
        normal: None,
    }));
}

fn non_finite(path: &Path, facet: usize, p: DVec3) -> MeshError {
    MeshError::NonFinite {
        path: path.to_path_buf(),
        at: Location::Element {
            element: "facet".into(),
            index: facet as u64,
        },
        value: format!("{} {} {}", p.x, p.y, p.z),
    }
}

fn parse_binary(path: &Path, bytes: &[u8], count: usize) -> Result<MeshBuilder> {
    // The count was checked against the size: the reservation is bounded by the bytes present.
    let mut b = new_builder(path, "stl-binary", count);
    b.report.file_faces = count;
    b.report.file_vertices = count * 3;
    let mut attributes = 0usize;
    let body = &bytes[HEADER_BYTES + 4..];
    for (f, facet) in body.chunks_exact(FACET_BYTES).enumerate() {
        let float = |i: usize| {
            let at = 12 + 4 * i;
            f64::from(f32::from_le_bytes([
                facet[at],
                facet[at + 1],
                facet[at + 2],
                facet[at + 3],
            ]))
        };
        let corners =
            [0, 1, 2].map(|c| DVec3::new(float(3 * c), float(3 * c + 1), float(3 * c + 2)));
        if let Some(p) = corners.iter().find(|p| !p.is_finite()) {
            return Err(non_finite(path, f, *p));
        }
        if facet[48] != 0 || facet[49] != 0 {
            attributes += 1;
        }
        push_facet(&mut b, corners);
    }
    if attributes > 0 {
        b.report.skipped.push(format!(
            "facet attribute words ({attributes} non-zero: colour in the VisCAM or Magics convention, not read)"
        ));
    }
    Ok(b)
}

/// ASCII STL: `solid`, then `facet normal` / `outer loop` / three `vertex x y z` /
/// `endloop` / `endfacet` blocks, then `endsolid`. Several solids in one file are read one
/// after another. Keywords are checked in order, so a missing or extra `vertex` is an error
/// at its line.
fn parse_ascii(path: &Path, bytes: &[u8]) -> Result<MeshBuilder> {
    let mut b = new_builder(path, "stl-ascii", 0);
    let mut corners: Vec<DVec3> = Vec::with_capacity(3);
    let mut in_solid = false;
    for (i, raw_line) in bytes.split(|&c| c == b'\n').enumerate() {
        let line_no = (i + 1) as u64;
        let line = std::str::from_utf8(raw_line)
            .map_err(|_| MeshError::malformed(path, Location::Line(line_no), "not UTF-8 text"))?
            .trim();
        let mut tokens = line.split_ascii_whitespace();
        let Some(keyword) = tokens.next() else {
            continue;
        };
        let bad = |message: String| MeshError::malformed(path, Location::Line(line_no), message);
        match (keyword, in_solid) {
            ("solid", false) => in_solid = true,
            ("endsolid", true) => in_solid = false,
            ("facet", true) | ("outer", true) => {}
            ("vertex", true) => {
                if corners.len() == 3 {
                    return Err(bad("a facet with more than three vertices".into()));
                }
                corners.push(parse_vertex(path, line_no, tokens)?);
            }
            ("endloop", true) => {}
            ("endfacet", true) => {
                let facet: [DVec3; 3] = corners.as_slice().try_into().map_err(|_| {
                    bad(format!(
                        "a facet with {} vertices, not three",
                        corners.len()
                    ))
                })?;
                push_facet(&mut b, facet);
                corners.clear();
            }
            (other, _) => {
                return Err(bad(format!(
                    "unexpected {:?} {} a solid",
                    other,
                    if in_solid { "inside" } else { "outside" }
                )));
            }
        }
    }
    if in_solid || !corners.is_empty() {
        return Err(MeshError::malformed(
            path,
            Location::Line(bytes.split(|&c| c == b'\n').count() as u64),
            "the file ends inside a solid (truncated? no \"endsolid\")",
        ));
    }
    b.report.file_faces = b.faces.len();
    b.report.file_vertices = b.positions.len();
    Ok(b)
}

fn parse_vertex<'a>(
    path: &Path,
    line_no: u64,
    mut tokens: impl Iterator<Item = &'a str>,
) -> Result<DVec3> {
    let mut xyz = [0.0f64; 3];
    for v in &mut xyz {
        let token = tokens.next().ok_or_else(|| {
            MeshError::malformed(path, Location::Line(line_no), "vertex needs three numbers")
        })?;
        *v = token.parse::<f64>().map_err(|_| {
            MeshError::malformed(
                path,
                Location::Line(line_no),
                format!("{token:?} is not a number"),
            )
        })?;
        if !v.is_finite() {
            return Err(MeshError::NonFinite {
                path: path.to_path_buf(),
                at: Location::Line(line_no),
                value: token.to_string(),
            });
        }
    }
    if tokens.next().is_some() {
        return Err(MeshError::malformed(
            path,
            Location::Line(line_no),
            "vertex has more than three numbers",
        ));
    }
    Ok(DVec3::from_array(xyz))
}

#[cfg(test)]
mod tests {
    use super::*;

    const TETRA: &str = "solid t\n\
        facet normal 0 0 -1\n outer loop\n  vertex 0 0 0\n  vertex 0 1 0\n  vertex 1 0 0\n endloop\nendfacet\n\
        facet normal 0 -1 0\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 0 0 1\n endloop\nendfacet\n\
        facet normal -1 0 0\n outer loop\n  vertex 0 0 0\n  vertex 0 0 1\n  vertex 0 1 0\n endloop\nendfacet\n\
        facet normal 1 1 1\n outer loop\n  vertex 1 0 0\n  vertex 0 1 0\n  vertex 0 0 1\n endloop\nendfacet\n\
        endsolid t\n";

    fn binary(facets: &[[[f32; 3]; 3]], attribute: u16) -> Vec<u8> {
        let mut out = b"solid binary header that lies".to_vec();
        out.resize(HEADER_BYTES, b' ');
        out.extend_from_slice(&(facets.len() as u32).to_le_bytes());
        for facet in facets {
            out.extend_from_slice(&[0u8; 12]);
            for c in facet.iter().flatten() {
                out.extend_from_slice(&c.to_le_bytes());
            }
            out.extend_from_slice(&attribute.to_le_bytes());
        }
        out
    }

    fn load(bytes: &[u8]) -> Result<(Mesh, LoadReport)> {
        read(Path::new("t.stl"), bytes, &LoadOptions::default())
    }

    #[test]
    fn ascii_tetrahedron_is_welded_into_four_vertices() {
        let (mesh, report) = load(TETRA.as_bytes()).unwrap();
        assert_eq!((mesh.vertex_count(), mesh.triangle_count()), (4, 4));
        assert_eq!(report.welded_vertices, 8);
        assert_eq!(report.format, "stl-ascii");
        assert!(report.skipped[0].starts_with("facet normals"));
    }

    #[test]
    fn binary_beginning_with_solid_is_binary_and_attributes_are_noted() {
        let facets = [
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        ];
        let (mesh, report) = load(&binary(&facets, 0x8000 | 31)).unwrap();
        assert_eq!((mesh.vertex_count(), mesh.triangle_count()), (4, 2));
        assert_eq!(report.format, "stl-binary");
        assert!(
            report.skipped.iter().any(|s| s.contains("2 non-zero")),
            "{report:?}"
        );
    }

    #[test]
    fn lying_count_names_both_numbers() {
        let mut bytes = binary(&[[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]], 0);
        bytes[HEADER_BYTES] = 7;
        bytes[0] = b'x';
        let e = load(&bytes).unwrap_err().to_string();
        assert!(
            e.contains("declares 7 triangles (434 bytes) but the file has 134 bytes"),
            "{e}"
        );
        // Cut short, a binary file whose header begins with `solid` is still read as binary.
        let solid = binary(&[[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]], 0);
        let e = load(&solid[..100]).unwrap_err().to_string();
        assert!(
            e.contains("declares 1 triangles (134 bytes) but the file has 100 bytes"),
            "{e}"
        );
    }

    #[test]
    fn truncated_and_nan_inputs_are_located_errors() {
        let cut = TETRA.strip_suffix("endsolid t\n").unwrap();
        let e = load(cut.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("ends inside a solid"), "{e}");
        let nan = TETRA.replacen("vertex 1 0 0", "vertex nan 0 0", 1);
        let e = load(nan.as_bytes()).unwrap_err().to_string();
        assert!(
            e.contains("line 6: coordinate is not a finite number: nan"),
            "{e}"
        );
        let e = load(&binary(
            &[[[f32::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]],
            0,
        ))
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("facet 0: coordinate is not a finite number"),
            "{e}"
        );
        let four = TETRA.replacen("  vertex 1 0 0\n", "  vertex 1 0 0\n  vertex 2 0 0\n", 1);
        let e = load(four.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("more than three vertices"), "{e}");
        let e = load(b"tiny").unwrap_err().to_string();
        assert!(e.contains("shorter than a binary STL header"), "{e}");
    }
}
