//! Writing a [`Mesh`] as PLY.
//!
//! Layout (MeshLab-compatible):
//! - `comment scanmill`, then `comment TextureFile NAME` per material when any material has a
//!   texture (a material without one is written under its own name, which reads back as a
//!   missing texture, so that `texnumber` keeps indexing the right line);
//! - `vertex`: `x y z` as **double**, so positions round-trip bit-exactly (scanmill computes in
//!   f64; float would move every vertex by up to 6e-8 of its magnitude); `nx ny nz` as float
//!   only when every wedge of each vertex carries the same normal (PLY normals are per vertex);
//!   `red green blue [alpha]` as uchar when the mesh has colours (alpha only if not all 255);
//! - `face`: `list uchar int vertex_indices`, in triangle order; when the mesh has texture
//!   coordinates, `list uchar float texcoord` with 6 values per triangle (per corner, so seams
//!   are kept; float because MeshLab reads that layout: texture coordinates round-trip exactly
//!   to f32); a triangle with a corner that has no texture coordinate gets an empty list;
//!   `int texnumber` when there are several materials.
//!
//! Texture images that exist are copied next to the PLY under their names.

use super::PlyEncoding;
use super::read::MISSING_TEXTURE_PREFIX;
use crate::mesh::error::{MeshError, Result};
use crate::mesh::model::Mesh;
use crate::mesh::obj::copy_source;
use crate::mesh::texture::{OutputNames, sanitise_output_name};
use glam::DVec3;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Values in one of the three encodings.
trait Sink {
    fn f64(&mut self, v: f64);
    fn f32(&mut self, v: f32);
    fn u8(&mut self, v: u8);
    fn i32(&mut self, v: i32);
    /// Ends an element (ASCII: the line).
    fn end(&mut self);
}

struct BinarySink {
    out: Vec<u8>,
    big_endian: bool,
}

macro_rules! put {
    ($self:ident, $v:expr) => {
        if $self.big_endian {
            $self.out.extend_from_slice(&$v.to_be_bytes())
        } else {
            $self.out.extend_from_slice(&$v.to_le_bytes())
        }
    };
}

impl Sink for BinarySink {
    fn f64(&mut self, v: f64) {
        put!(self, v)
    }
    fn f32(&mut self, v: f32) {
        put!(self, v)
    }
    fn u8(&mut self, v: u8) {
        self.out.push(v)
    }
    fn i32(&mut self, v: i32) {
        put!(self, v)
    }
    fn end(&mut self) {}
}

/// ASCII values use Rust's shortest round-trip formatting, so parsing them back gives the same
/// bits (doubles as doubles, floats as floats).
struct AsciiSink {
    out: String,
    line_start: bool,
}

impl AsciiSink {
    fn sep(&mut self) {
        if !self.line_start {
            self.out.push(' ');
        }
        self.line_start = false;
    }
}

impl AsciiSink {
    /// One value after its separator: floats in their shortest round-trip form (`{:?}`),
    /// integers as they are.
    fn value(&mut self, v: std::fmt::Arguments) {
        self.sep();
        let _ = self.out.write_fmt(v);
    }
}

impl Sink for AsciiSink {
    fn f64(&mut self, v: f64) {
        self.value(format_args!("{v:?}"));
    }
    fn f32(&mut self, v: f32) {
        self.value(format_args!("{v:?}"));
    }
    fn u8(&mut self, v: u8) {
        self.value(format_args!("{v}"));
    }
    fn i32(&mut self, v: i32) {
        self.value(format_args!("{v}"));
    }
    fn end(&mut self) {
        self.out.push('\n');
        self.line_start = true;
    }
}

/// One normal per vertex, if the mesh's normals can be expressed that way.
fn vertex_normals(mesh: &Mesh) -> Option<Vec<DVec3>> {
    if mesh.normals.is_empty() {
        return None;
    }
    let mut normals: Vec<Option<DVec3>> = vec![None; mesh.positions.len()];
    for wedge in &mesh.wedges {
        let n = mesh.normals[wedge.normal? as usize];
        let slot = &mut normals[wedge.vertex as usize];
        match slot {
            None => *slot = Some(n),
            Some(prev) if prev.to_array().map(f64::to_bits) != n.to_array().map(f64::to_bits) => {
                tracing::debug!(
                    "vertex {} has several normals; PLY output drops normals",
                    wedge.vertex
                );
                return None;
            }
            Some(_) => {}
        }
    }
    Some(
        normals
            .into_iter()
            .map(|n| n.unwrap_or(DVec3::ZERO))
            .collect(),
    )
}

/// The `TextureFile` name of each material (an empty list when no material has a texture)
/// and the texture files to copy under those names. Names are chosen by [`OutputNames`]:
/// the scan's names, sanitised, never one of the reserved names.
fn texture_names(mesh: &Mesh, names: &mut OutputNames) -> (Vec<String>, Vec<(PathBuf, String)>) {
    let mut copies: Vec<(PathBuf, String)> = Vec::new();
    let chosen: Vec<Option<String>> = mesh
        .materials
        .iter()
        .map(|m| match &m.diffuse_texture {
            Some(t) => {
                let name = names.name_for(&t.name, &t.path);
                if !copies.iter().any(|(_, n)| *n == name) {
                    copies.push((t.path.clone(), name.clone()));
                }
                Some(name)
            }
            // A texture that was missing on input: its name only, no file.
            None => m
                .other_statements
                .iter()
                .find_map(|s| s.strip_prefix(MISSING_TEXTURE_PREFIX))
                .and_then(sanitise_output_name),
        })
        .collect();
    if chosen.iter().all(Option::is_none) {
        return (Vec::new(), Vec::new());
    }
    let list = chosen
        .into_iter()
        .zip(&mesh.materials)
        .map(|(name, m)| name.unwrap_or_else(|| m.name.clone()))
        .collect();
    (list, copies)
}

fn header(mesh: &Mesh, encoding: PlyEncoding, layout: &Layout, textures: &[String]) -> String {
    let format = match encoding {
        PlyEncoding::Ascii => "ascii",
        PlyEncoding::BinaryLittleEndian => "binary_little_endian",
        PlyEncoding::BinaryBigEndian => "binary_big_endian",
    };
    let mut h = format!("ply\nformat {format} 1.0\ncomment scanmill\n");
    for name in textures {
        let _ = writeln!(h, "comment TextureFile {name}");
    }
    let _ = writeln!(h, "element vertex {}", mesh.positions.len());
    h.push_str("property double x\nproperty double y\nproperty double z\n");
    if layout.normals.is_some() {
        h.push_str("property float nx\nproperty float ny\nproperty float nz\n");
    }
    if layout.colors {
        h.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
        if layout.alpha {
            h.push_str("property uchar alpha\n");
        }
    }
    let _ = writeln!(h, "element face {}", mesh.triangles.len());
    h.push_str("property list uchar int vertex_indices\n");
    if layout.texcoords {
        h.push_str("property list uchar float texcoord\n");
    }
    if layout.texnumber {
        h.push_str("property int texnumber\n");
    }
    h.push_str("end_header\n");
    h
}

struct Layout {
    normals: Option<Vec<DVec3>>,
    colors: bool,
    alpha: bool,
    texcoords: bool,
    texnumber: bool,
}

fn body(mesh: &Mesh, layout: &Layout, out: &mut impl Sink) {
    for (v, p) in mesh.positions.iter().enumerate() {
        out.f64(p.x);
        out.f64(p.y);
        out.f64(p.z);
        if let Some(normals) = &layout.normals {
            let n = normals[v].as_vec3();
            out.f32(n.x);
            out.f32(n.y);
            out.f32(n.z);
        }
        if layout.colors {
            let c = mesh.colors[v];
            out.u8(c[0]);
            out.u8(c[1]);
            out.u8(c[2]);
            if layout.alpha {
                out.u8(c[3]);
            }
        }
        out.end();
    }
    for (t, tri) in mesh.triangles.iter().enumerate() {
        out.u8(3);
        for &w in tri {
            out.i32(mesh.wedges[w as usize].vertex as i32);
        }
        if layout.texcoords {
            let uvs = tri.map(|w| mesh.wedge_texcoord(w));
            if uvs.iter().all(Option::is_some) {
                out.u8(6);
                for uv in uvs.into_iter().flatten() {
                    out.f32(uv.x as f32);
                    out.f32(uv.y as f32);
                }
            } else {
                out.u8(0);
            }
        }
        if layout.texnumber {
            out.i32(mesh.triangle_material(t) as i32);
        }
        out.end();
    }
}

/// Writes `mesh` to `path`: [`write_reserving`] with nothing reserved.
pub fn write(mesh: &Mesh, path: &Path, encoding: PlyEncoding) -> Result<Vec<PathBuf>> {
    write_reserving(mesh, path, encoding, &[])
}

/// Writes `mesh` to `path` and copies its texture images next to it, under names that are
/// never the PLY's own nor one of `reserved`. Returns the files written, the PLY first.
pub fn write_reserving(
    mesh: &Mesh,
    path: &Path,
    encoding: PlyEncoding,
    reserved: &[String],
) -> Result<Vec<PathBuf>> {
    if mesh.positions.len() > i32::MAX as usize {
        return Err(MeshError::malformed(
            path,
            crate::mesh::Location::Header,
            "too many vertices for PLY int indices",
        ));
    }
    let mut names = OutputNames::default();
    let own_name = path.file_name().map(|n| n.to_string_lossy().into_owned());
    for name in own_name.iter().chain(reserved) {
        names.reserve(name);
    }
    let (textures, copies) = texture_names(mesh, &mut names);
    let layout = Layout {
        normals: vertex_normals(mesh),
        colors: !mesh.colors.is_empty(),
        alpha: mesh.colors.iter().any(|c| c[3] != 255),
        texcoords: mesh.has_texcoords(),
        texnumber: mesh.materials.len() > 1,
    };
    let head = header(mesh, encoding, &layout, &textures);
    let bytes = match encoding {
        PlyEncoding::Ascii => {
            let mut sink = AsciiSink {
                out: head,
                line_start: true,
            };
            body(mesh, &layout, &mut sink);
            sink.out.into_bytes()
        }
        PlyEncoding::BinaryLittleEndian | PlyEncoding::BinaryBigEndian => {
            let per_vertex = 24 + if layout.normals.is_some() { 12 } else { 0 } + 4;
            let per_face = 13 + if layout.texcoords { 25 } else { 0 } + 4;
            let mut out = Vec::with_capacity(
                head.len() + per_vertex * mesh.positions.len() + per_face * mesh.triangles.len(),
            );
            out.extend_from_slice(head.as_bytes());
            let mut sink = BinarySink {
                out,
                big_endian: encoding == PlyEncoding::BinaryBigEndian,
            };
            body(mesh, &layout, &mut sink);
            sink.out
        }
    };
    std::fs::write(path, bytes).map_err(|e| MeshError::write(path, e))?;
    let mut written = vec![path.to_path_buf()];
    let dir = path.parent().unwrap_or(Path::new(""));
    for (source, name) in copies {
        // A texture of a mesh made in memory may have no file: its name is written only.
        if mesh.embedded_image(&source).is_none() && !source.is_file() {
            continue;
        }
        let target = dir.join(&name);
        copy_source(mesh, &source, &target)?;
        written.push(target);
    }
    Ok(written)
}
