//! GLB output: one self-contained file a web viewer opens as it is.
//!
//! Layout: one glTF vertex per wedge (a wedge is already a distinct position, texture
//! coordinate and normal, so texture seams become the split vertices glTF requires and
//! nothing is merged or lost), shared by one triangle primitive per material. Every vertex
//! attribute is one tightly packed buffer view; each primitive's indices another; each
//! base-colour image a third kind, its bytes copied from the file as they came (PNG or
//! JPEG, the two formats core glTF allows; never decoded or re-encoded).
//!
//! Conversions the format imposes: positions and normals are 32-bit floats (glTF has no
//! 64-bit attributes); texture coordinates are flipped (`v` → `1 - v`: glTF's origin is the
//! image's top-left corner, OBJ's and PLY's the bottom-left); normals are normalised. Vertex
//! colours become `COLOR_0` (normalised bytes, RGBA).

use super::glb;
use crate::mesh::error::{MeshError, Result};
use crate::mesh::limits::InputLimits;
use crate::mesh::model::{Index, Mesh, Texture};
use crate::mesh::texture;
use serde_json::{Value, json};
use std::io::Write;
use std::path::{Path, PathBuf};

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_BYTE: u32 = 5121;
const UNSIGNED_INT: u32 = 5125;

/// The binary buffer and the JSON arrays that describe it, filled side by side.
#[derive(Default)]
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Builder {
    /// Appends `bytes` as a buffer view (4-byte aligned) and returns its index.
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        self.bin.resize(self.bin.len().div_ceil(4) * 4, 0);
        let mut view = json!({
            "buffer": 0,
            "byteOffset": self.bin.len(),
            "byteLength": bytes.len(),
        });
        if let Some(target) = target {
            view["target"] = json!(target);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(view);
        self.views.len() - 1
    }

    /// Appends a buffer view and an accessor over all of it; returns the accessor's index.
    fn accessor(&mut self, bytes: &[u8], target: u32, mut accessor: Value) -> usize {
        accessor["bufferView"] = json!(self.view(bytes, Some(target)));
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }
}

fn f32_bytes(values: impl Iterator<Item = f32>) -> Vec<u8> {
    values.flat_map(f32::to_le_bytes).collect()
}

/// The vertex attributes (one vertex per wedge); returns the `attributes` object.
fn write_attributes(mesh: &Mesh, b: &mut Builder) -> Value {
    let positions: Vec<[f32; 3]> = mesh
        .wedges
        .iter()
        .map(|w| mesh.positions[w.vertex as usize].as_vec3().to_array())
        .collect();
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in &positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let bytes = f32_bytes(positions.iter().flatten().copied());
    let count = positions.len();
    let mut attributes = json!({
        "POSITION": b.accessor(&bytes, ARRAY_BUFFER, json!({
            "componentType": FLOAT, "count": count, "type": "VEC3", "min": lo, "max": hi,
        })),
    });
    if let Some(normals) = unit_normals(mesh) {
        let bytes = f32_bytes(normals.iter().flatten().copied());
        attributes["NORMAL"] = json!(b.accessor(
            &bytes,
            ARRAY_BUFFER,
            json!({
                "componentType": FLOAT, "count": count, "type": "VEC3",
            })
        ));
    }
    if mesh.has_texcoords() {
        let uvs = mesh.wedges.iter().flat_map(|w| {
            let t = w
                .texcoord
                .map_or(glam::DVec2::ZERO, |t| mesh.texcoords[t as usize]);
            [t.x as f32, (1.0 - t.y) as f32]
        });
        let bytes = f32_bytes(uvs);
        attributes["TEXCOORD_0"] = json!(b.accessor(
            &bytes,
            ARRAY_BUFFER,
            json!({
                "componentType": FLOAT, "count": count, "type": "VEC2",
            })
        ));
    }
    if !mesh.colors.is_empty() {
        let bytes: Vec<u8> = mesh
            .wedges
            .iter()
            .flat_map(|w| mesh.colors[w.vertex as usize])
            .collect();
        attributes["COLOR_0"] =
            json!(b.accessor(&bytes, ARRAY_BUFFER, json!({
            "componentType": UNSIGNED_BYTE, "normalized": true, "count": count, "type": "VEC4",
        })));
    }
    attributes
}

/// Every wedge's normal, normalised; `None` (and no `NORMAL` attribute) unless every wedge
/// has one of non-zero, finite length, as glTF requires unit normals on every vertex.
fn unit_normals(mesh: &Mesh) -> Option<Vec<[f32; 3]>> {
    mesh.wedges
        .iter()
        .map(|w| {
            let n = mesh.normals[w.normal? as usize].as_vec3();
            let unit = n.try_normalize()?;
            Some(unit.to_array())
        })
        .collect()
}

/// The image's MIME type from its first bytes: PNG and JPEG are the formats core glTF
/// allows.
fn mime_type(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some("image/png")
    } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some("image/jpeg")
    } else {
        None
    }
}

/// The materials, textures and images; images are read from the texture files and copied
/// into the buffer. A texture in another format is left out (with a warning): glTF cannot
/// carry it without converting it.
fn write_materials(mesh: &Mesh, b: &mut Builder) -> Result<(Vec<Value>, Vec<Value>, Vec<Value>)> {
    let (mut materials, mut textures, mut images) = (Vec::new(), Vec::new(), Vec::new());
    let mut image_of: Vec<(PathBuf, usize)> = Vec::new();
    for m in &mesh.materials {
        let mut pbr = json!({ "metallicFactor": 0.0, "roughnessFactor": 1.0 });
        if let Some(t) = &m.diffuse_texture
            && let Some(image) = image_index(t, b, &mut images, &mut image_of)?
        {
            textures.push(json!({ "source": image, "sampler": 0 }));
            pbr["baseColorTexture"] = json!({ "index": textures.len() - 1 });
        }
        materials.push(json!({
            "name": m.name,
            "pbrMetallicRoughness": pbr,
            "doubleSided": true,
        }));
    }
    Ok((materials, textures, images))
}

/// The index of the image for texture `t`, adding it on first use (several materials may
/// share one file).
fn image_index(
    t: &Texture,
    b: &mut Builder,
    images: &mut Vec<Value>,
    image_of: &mut Vec<(PathBuf, usize)>,
) -> Result<Option<usize>> {
    if let Some((_, i)) = image_of.iter().find(|(p, _)| *p == t.path) {
        return Ok(Some(*i));
    }
    let bytes = texture::texture_bytes(t, &InputLimits::default())?;
    let Some(mime) = mime_type(&bytes) else {
        tracing::warn!(texture = %t.name, "GLB output: the texture is neither PNG nor JPEG; left out");
        return Ok(None);
    };
    let view = b.view(&bytes, None);
    // The name is the texture's file name, so that a reader can name the file it extracts.
    let name = t.name.rsplit('/').next().unwrap_or(&t.name);
    images.push(json!({ "bufferView": view, "mimeType": mime, "name": name }));
    image_of.push((t.path.clone(), images.len() - 1));
    Ok(Some(images.len() - 1))
}

/// One triangle primitive per material (one in all for a mesh without materials), each with
/// its own index accessor over the shared vertices.
fn write_primitives(mesh: &Mesh, attributes: &Value, b: &mut Builder) -> Vec<Value> {
    let groups = mesh.materials.len().max(1);
    let mut indices: Vec<Vec<u8>> = vec![Vec::new(); groups];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let group = if mesh.materials.is_empty() {
            0
        } else {
            mesh.triangle_material(t) as usize
        };
        indices[group].extend(tri.iter().flat_map(|w: &Index| w.to_le_bytes()));
    }
    let mut primitives = Vec::new();
    for (group, bytes) in indices.iter().enumerate() {
        if bytes.is_empty() {
            continue;
        }
        let accessor = b.accessor(
            bytes,
            ELEMENT_ARRAY_BUFFER,
            json!({
                "componentType": UNSIGNED_INT, "count": bytes.len() / 4, "type": "SCALAR",
            }),
        );
        let mut primitive = json!({ "attributes": attributes, "indices": accessor, "mode": 4 });
        if !mesh.materials.is_empty() {
            primitive["material"] = json!(group);
        }
        primitives.push(primitive);
    }
    primitives
}

/// The whole file: JSON document and binary buffer.
fn encode(mesh: &Mesh, path: &Path) -> Result<(Vec<u8>, Vec<u8>)> {
    if mesh.triangles.is_empty() {
        return Err(MeshError::NoTriangles {
            path: path.to_path_buf(),
            reason: "a GLB needs at least one triangle".into(),
        });
    }
    let mut b = Builder::default();
    let attributes = write_attributes(mesh, &mut b);
    let primitives = write_primitives(mesh, &attributes, &mut b);
    let (materials, textures, images) = write_materials(mesh, &mut b)?;
    b.bin.resize(b.bin.len().div_ceil(4) * 4, 0);
    let mut doc = json!({
        "asset": { "version": "2.0", "generator": concat!("scanmill ", env!("CARGO_PKG_VERSION")) },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": primitives }],
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": [{ "byteLength": b.bin.len() }],
    });
    if !materials.is_empty() {
        doc["materials"] = json!(materials);
    }
    if !images.is_empty() {
        doc["images"] = json!(images);
        doc["textures"] = json!(textures);
        doc["samplers"] = json!([{ "magFilter": 9729, "minFilter": 9987 }]);
    }
    let text =
        serde_json::to_vec(&doc).map_err(|e| MeshError::write(path, std::io::Error::other(e)))?;
    Ok((text, b.bin))
}

/// Writes `mesh` as a GLB file at `path`. Returns the files written (just `path`: the
/// textures are inside it).
pub fn write(mesh: &Mesh, path: &Path) -> Result<Vec<PathBuf>> {
    let (json, bin) = encode(mesh, path)?;
    let file = std::fs::File::create(path).map_err(|e| MeshError::write(path, e))?;
    let mut out = std::io::BufWriter::with_capacity(1 << 20, file);
    glb::write(&mut out, &json, &bin)
        .and_then(|()| out.flush())
        .map_err(|e| MeshError::write(path, e))?;
    Ok(vec![path.to_path_buf()])
}
