//! Writing an OBJ: the mesh in the shortest exact number form, its MTL, and copies of the
//! texture and map files under names chosen here.

use crate::mesh::error::{MeshError, Result};
use crate::mesh::files;
use crate::mesh::model::{Index, MapFile, Mesh, Wedge};
use crate::mesh::{mtl, texture};
use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Writes `mesh` as an OBJ at `obj_path`: [`write_reserving`] with nothing reserved.
pub fn write(mesh: &Mesh, obj_path: &Path) -> Result<Vec<PathBuf>> {
    write_reserving(mesh, obj_path, &[])
}

/// Writes `mesh` as an OBJ at `obj_path`, with `<stem>.mtl` beside it when the mesh has
/// materials, and copies of the texture and map files. The copies' names are chosen here
/// ([`texture::OutputNames`]): the scan's names, sanitised, kept apart from the OBJ, the MTL
/// and every name in `reserved` (files the caller writes beside, such as a preview).
/// Returns every file written, the OBJ first.
///
/// Positions, texture coordinates and normals are written in the shortest form that reads
/// back to the same `f64` (ryu), so a write/read round trip is bit-exact. Face order is
/// kept; `usemtl` is written where the material changes.
pub fn write_reserving(mesh: &Mesh, obj_path: &Path, reserved: &[String]) -> Result<Vec<PathBuf>> {
    let out_dir = texture::folder_of(obj_path);
    let stem = obj_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "mesh".to_string());
    let obj_name = obj_path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mtl_name = format!("{stem}.mtl");
    let has_materials = !mesh.materials.is_empty();

    let mut written = vec![obj_path.to_path_buf()];
    let plan = if has_materials {
        let mut names = texture::OutputNames::default();
        for name in [&obj_name, &mtl_name].into_iter().chain(reserved) {
            names.reserve(name);
        }
        Some(plan_material_files(mesh, names))
    } else {
        None
    };
    write_obj_file(mesh, obj_path, has_materials.then_some(mtl_name.as_str()))?;
    if let Some(plan) = plan {
        let mtl_path = out_dir.join(&mtl_name);
        std::fs::write(&mtl_path, plan.mtl_text.as_bytes())
            .map_err(|e| MeshError::write(&mtl_path, e))?;
        written.push(mtl_path);
        for (source, name) in plan.copies {
            let target = out_dir.join(&name);
            copy_source(mesh, &source, &target)?;
            written.push(target);
        }
    }
    Ok(written)
}

struct MaterialFiles {
    mtl_text: String,
    /// `(source, output name)` of every file to copy, each once, in first-use order.
    copies: Vec<(PathBuf, String)>,
}

/// The output MTL and the files to copy. Map statements name the file the loader resolved
/// (`Material::map_files`), never a file found again from the statement's text.
fn plan_material_files(mesh: &Mesh, mut names: texture::OutputNames) -> MaterialFiles {
    let mut copies: Vec<(PathBuf, String)> = Vec::new();
    let mut add_copy = |source: &Path, wanted: &str, copies: &mut Vec<(PathBuf, String)>| {
        let name = names.name_for(wanted, source);
        if !copies.iter().any(|(_, n)| *n == name) {
            copies.push((source.to_path_buf(), name.clone()));
        }
        name
    };
    let mut text = String::from("# written by scanmill\n");
    for m in &mesh.materials {
        text.push_str("\nnewmtl ");
        text.push_str(&m.name);
        text.push('\n');
        // Looked up by statement once per material: a search per statement is quadratic, and
        // an MTL of 90k map lines kept the writer busy for minutes (found by fuzzing).
        let map_files: HashMap<usize, &MapFile> =
            m.map_files.iter().map(|f| (f.statement, f)).collect();
        for (i, statement) in m.other_statements.iter().enumerate() {
            let Some((keyword, options, file)) = mtl::map_file_of(statement) else {
                text.push_str(statement);
                text.push('\n');
                continue;
            };
            let Some(source) = map_files.get(&i) else {
                tracing::warn!(
                    "material {:?}: {keyword} {file:?} was not loaded from a file; written as is, not copied",
                    m.name
                );
                text.push_str(statement);
                text.push('\n');
                continue;
            };
            let name = add_copy(&source.path, file, &mut copies);
            text.push_str(keyword);
            text.push(' ');
            if !options.is_empty() {
                text.push_str(options);
                text.push(' ');
            }
            text.push_str(&name);
            text.push('\n');
        }
        if let Some(t) = &m.diffuse_texture {
            let name = add_copy(&t.path, &t.name, &mut copies);
            text.push_str("map_Kd ");
            text.push_str(&name);
            text.push('\n');
        }
    }
    MaterialFiles {
        mtl_text: text,
        copies,
    }
}

/// Writes a texture or map file of `mesh` to `target`: an image embedded in the scan's file
/// (see [`crate::mesh::Texture::embedded`]) from its bytes, a file by [`copy_file`].
pub fn copy_source(mesh: &Mesh, source: &Path, target: &Path) -> Result<()> {
    let Some(embedded) = mesh.embedded_image(source) else {
        return copy_file(source, target);
    };
    if let Some(parent) = target.parent() {
        std::fs::create_dir_all(parent).map_err(|e| MeshError::write(parent, e))?;
    }
    std::fs::write(target, &embedded.0).map_err(|e| MeshError::write(target, e))
}

/// Copies `source` (a file the loader resolved) to `target`, unless they are the same file
/// (writing over the input's own folder), creating sub-folders as needed. Reading the source
/// fails as an input error, writing the copy as an output error ([`MeshError::Write`]).
pub fn copy_file(source: &Path, target: &Path) -> Result<()> {
    if let (Ok(a), Ok(b)) = (source.canonicalize(), target.canonicalize())
        && a == b
    {
        return Ok(());
    }
    if let Some(parent) = target.parent() {
        std::fs::create_dir_all(parent).map_err(|e| MeshError::write(parent, e))?;
    }
    let (mut from, _) = files::open_regular(source)?;
    let mut to = std::fs::File::create(target).map_err(|e| MeshError::write(target, e))?;
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = match std::io::Read::read(&mut from, &mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(MeshError::io(source, e)),
        };
        to.write_all(&buf[..n])
            .map_err(|e| MeshError::write(target, e))?;
    }
    to.flush().map_err(|e| MeshError::write(target, e))
}

/// Buffered output with hand formatting (ryu, itoa): `write!` per number is several times
/// slower on files of a million lines.
struct Out {
    file: std::fs::File,
    buf: Vec<u8>,
    ryu: ryu::Buffer,
    itoa: itoa::Buffer,
}

const OUT_BUFFER: usize = 1 << 20;

impl Out {
    #[inline]
    fn bytes(&mut self, b: &[u8]) {
        self.buf.extend_from_slice(b);
    }

    #[inline]
    fn float(&mut self, x: f64) {
        // -0.0 would print as "-0.0"; keep it (it reads back bit-exactly).
        let s = self.ryu.format(x);
        self.buf.extend_from_slice(s.as_bytes());
    }

    /// `x y z`.
    #[inline]
    fn xyz(&mut self, p: &glam::DVec3) {
        self.float(p.x);
        self.bytes(b" ");
        self.float(p.y);
        self.bytes(b" ");
        self.float(p.z);
    }

    #[inline]
    fn int(&mut self, x: u64) {
        let s = self.itoa.format(x);
        self.buf.extend_from_slice(s.as_bytes());
    }

    #[inline]
    fn flush_if_full(&mut self) -> std::io::Result<()> {
        if self.buf.len() >= OUT_BUFFER {
            self.file.write_all(&self.buf)?;
            self.buf.clear();
        }
        Ok(())
    }

    fn finish(mut self) -> std::io::Result<()> {
        self.file.write_all(&self.buf)?;
        self.file.flush()
    }
}

fn write_obj_file(mesh: &Mesh, obj_path: &Path, mtl_name: Option<&str>) -> Result<()> {
    let file = std::fs::File::create(obj_path).map_err(|e| MeshError::write(obj_path, e))?;
    let mut out = Out {
        file,
        buf: Vec::with_capacity(OUT_BUFFER + 4096),
        ryu: ryu::Buffer::new(),
        itoa: itoa::Buffer::new(),
    };
    write_obj_body(mesh, mtl_name, &mut out)
        .and_then(|()| out.finish())
        .map_err(|e| MeshError::write(obj_path, e))
}

fn write_obj_body(mesh: &Mesh, mtl_name: Option<&str>, out: &mut Out) -> std::io::Result<()> {
    out.bytes(b"# written by scanmill\n");
    if let Some(name) = mtl_name {
        out.bytes(b"mtllib ");
        out.bytes(name.as_bytes());
        out.bytes(b"\n");
    }
    write_vertices(mesh, out)?;
    for t in &mesh.texcoords {
        out.bytes(b"vt ");
        out.float(t.x);
        out.bytes(b" ");
        out.float(t.y);
        out.bytes(b"\n");
        out.flush_if_full()?;
    }
    for n in &mesh.normals {
        out.bytes(b"vn ");
        out.xyz(n);
        out.bytes(b"\n");
        out.flush_if_full()?;
    }
    write_faces(mesh, mtl_name.is_some(), out)
}

/// The `v` lines, with the vertex colours where the mesh has them.
fn write_vertices(mesh: &Mesh, out: &mut Out) -> std::io::Result<()> {
    // Colours as c/255 with 4 decimals: enough to read back the same byte.
    let colour_text: Vec<String> = if mesh.colors.is_empty() {
        Vec::new()
    } else {
        (0..=255u32)
            .map(|c| format!("{:.4}", c as f64 / 255.0))
            .collect()
    };
    for (i, p) in mesh.positions.iter().enumerate() {
        out.bytes(b"v ");
        out.xyz(p);
        if let Some(c) = mesh.colors.get(i) {
            for &channel in &c[..3] {
                out.bytes(b" ");
                out.bytes(colour_text[channel as usize].as_bytes());
            }
        }
        out.bytes(b"\n");
        out.flush_if_full()?;
    }
    Ok(())
}

/// The `f` lines, each preceded by `usemtl` where the material changes (with materials).
fn write_faces(mesh: &Mesh, with_materials: bool, out: &mut Out) -> std::io::Result<()> {
    let mut current: Option<Index> = None;
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if with_materials {
            let m = mesh.triangle_material(t);
            if current != Some(m) {
                out.bytes(b"usemtl ");
                let name = mesh
                    .materials
                    .get(m as usize)
                    .map_or("", |m| m.name.as_str());
                out.bytes(name.as_bytes());
                out.bytes(b"\n");
                current = Some(m);
            }
        }
        out.bytes(b"f");
        for &w in tri {
            out.bytes(b" ");
            write_corner(mesh.wedges[w as usize], out);
        }
        out.bytes(b"\n");
        out.flush_if_full()?;
    }
    Ok(())
}

/// A face corner: `v`, `v/vt`, `v//vn` or `v/vt/vn` (1-based).
fn write_corner(wedge: Wedge, out: &mut Out) {
    out.int(wedge.vertex as u64 + 1);
    match (wedge.texcoord, wedge.normal) {
        (None, None) => {}
        (Some(vt), None) => {
            out.bytes(b"/");
            out.int(vt as u64 + 1);
        }
        (None, Some(vn)) => {
            out.bytes(b"//");
            out.int(vn as u64 + 1);
        }
        (Some(vt), Some(vn)) => {
            out.bytes(b"/");
            out.int(vt as u64 + 1);
            out.bytes(b"/");
            out.int(vn as u64 + 1);
        }
    }
}
