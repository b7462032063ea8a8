//! glTF 2.0 input: `.gltf` (JSON, with its buffers and images beside it or in `data:` URIs)
//! and `.glb` (the binary container).
//!
//! The `gltf` crate parses and validates the JSON document (its references between objects);
//! scanmill reads the bytes itself: the GLB container ([`super::glb`]), buffers (external
//! files resolved and confined like an OBJ's textures, within `limits.max_file_bytes`;
//! `data:` URIs decoded only after their size is checked against the same limit) and
//! accessors ([`super::accessor`], every range checked against the bytes present). The
//! crate's own importer is not used: it opens any path a URI names.
//!
//! Read: the default scene's nodes (all meshes when there is no scene), each mesh under its
//! node's world transform; triangle primitives with `POSITION`, `NORMAL`, `TEXCOORD_0` and
//! the material's base-colour texture when it is a file beside the scan. Errors, not guesses:
//! a required extension (Draco, mesh quantization, ...), sparse accessors, primitive modes
//! other than triangles. Skipped with a note: other attributes (tangents, colours, skins,
//! morph targets). An image inside the file (GLB buffer view, `data:` URI) is kept in memory
//! as it came ([`crate::mesh::Texture::embedded`]).

use super::accessor::{self, Buffers};
use super::glb;
use crate::mesh::build::{Corner, LoadOptions, LoadReport, MeshBuilder};
use crate::mesh::error::{Location, MeshError, Result};
use crate::mesh::files;
use crate::mesh::limits::Limit;
use crate::mesh::model::{EmbeddedImage, Index, Material, Mesh, Texture};
use crate::mesh::texture::{self, Referenced};
use base64::Engine;
use glam::{DMat3, DMat4, DVec2, DVec3};
use gltf::mesh::{Mode, Semantic};
use std::path::Path;

/// Reads a `.gltf` or `.glb` file's bytes.
pub fn read(path: &Path, bytes: &[u8], options: &LoadOptions) -> Result<(Mesh, LoadReport)> {
    let (json, bin) = if bytes.starts_with(glb::MAGIC) {
        let chunks = glb::split(path, bytes)?;
        (chunks.json, chunks.bin)
    } else {
        (bytes, None)
    };
    let document = parse_document(path, json)?;
    let format = if bin.is_some() || bytes.starts_with(glb::MAGIC) {
        "glb"
    } else {
        "gltf"
    };
    let mut b = MeshBuilder::new(path, format);
    let buffers = load_buffers(path, &document, bin, options)?;
    let materials = load_materials(path, &document, &buffers, options, &mut b.report)?;
    let has_materials = !materials.is_empty();
    b.materials = materials;
    for (mesh, transform) in placed_meshes(&document) {
        for primitive in mesh.primitives() {
            let at = format!("mesh {} primitive {}", mesh.index(), primitive.index());
            add_primitive(&mut b, &primitive, &buffers, &transform, has_materials)
                .map_err(|message| malformed(path, format!("{at}: {message}")))?;
        }
    }
    b.report.file_vertices = b.positions.len();
    b.report.file_faces = b.faces.len();
    b.report.file_texcoords = b.texcoords.len();
    b.report.file_normals = b.normals.len();
    b.finish(options)
}

fn malformed(path: &Path, message: String) -> MeshError {
    MeshError::malformed(path, Location::Header, message)
}

/// The JSON document, its required extensions refused first (the crate would only call them
/// unsupported), then validated.
fn parse_document(path: &Path, json: &[u8]) -> Result<gltf::Document> {
    let root: gltf::json::Root = gltf::json::deserialize::from_slice(json)
        .map_err(|e| malformed(path, format!("not a glTF 2.0 document: {e}")))?;
    if let Some(ext) = root.extensions_required.first() {
        let what = match ext.as_str() {
            "KHR_draco_mesh_compression" => "Draco-compressed meshes are not supported".to_string(),
            "EXT_meshopt_compression" => "meshopt-compressed buffers are not supported".to_string(),
            other => {
                format!("the file requires extension {other:?}, which scanmill does not support")
            }
        };
        return Err(malformed(path, what));
    }
    check_position_accessors(path, &root)?;
    gltf::Document::from_json(root).map_err(|e| malformed(path, format!("invalid glTF: {e}")))
}

/// Every primitive's `POSITION` names an accessor that exists. The crate's validation looks
/// that accessor up without a range check (a panic on a hostile index, found by fuzzing), so
/// this runs first.
fn check_position_accessors(path: &Path, root: &gltf::json::Root) -> Result<()> {
    let position = gltf::json::validation::Checked::Valid(Semantic::Positions);
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(index) = primitive.attributes.get(&position)
                && index.value() >= root.accessors.len()
            {
                return Err(malformed(
                    path,
                    format!(
                        "mesh {m} primitive {p}: POSITION accessor {} does not exist (the file has {})",
                        index.value(),
                        root.accessors.len()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Every buffer's bytes: the GLB's BIN chunk, a `data:` URI or a file beside the scan. The
/// bytes of all buffers together stay within `limits.max_file_bytes`; each must hold at
/// least its declared `byteLength`.
fn load_buffers(
    path: &Path,
    document: &gltf::Document,
    bin: Option<&[u8]>,
    options: &LoadOptions,
) -> Result<Vec<Vec<u8>>> {
    let cap = options.limits.max_file_bytes;
    let mut total = 0u64;
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let at = |m: String| malformed(path, format!("buffer {}: {m}", buffer.index()));
        let bytes = match buffer.source() {
            gltf::buffer::Source::Bin => bin
                .ok_or_else(|| at("refers to the GLB's binary chunk, which the file lacks".into()))?
                .to_vec(),
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                decode_data_uri(uri, total, cap).map_err(at)?
            }
            gltf::buffer::Source::Uri(uri) => read_beside(path, uri, options, Referenced::Buffer)?,
        };
        if (bytes.len() as u64) < buffer.length() as u64 {
            return Err(at(format!(
                "byteLength is {} but the data holds {} bytes",
                buffer.length(),
                bytes.len()
            )));
        }
        total += bytes.len() as u64;
        if total > cap {
            return Err(files::too_large(
                path,
                format!("the buffers' {total} bytes in all"),
                Limit::FileBytes,
                cap,
            ));
        }
        buffers.push(bytes);
    }
    Ok(buffers)
}

/// Decodes a base64 `data:` URI, refusing it before decoding (its decoded size is known from
/// its length) if it would bring the buffers read so far, `before` bytes, above `cap`.
fn decode_data_uri(uri: &str, before: u64, cap: u64) -> std::result::Result<Vec<u8>, String> {
    let (head, payload) = uri.split_once(',').ok_or("data URI without a comma")?;
    if !head.ends_with(";base64") {
        return Err("only base64 data URIs are supported".into());
    }
    let decoded_size = payload.len() as u64 / 4 * 3;
    if before.saturating_add(decoded_size) > cap {
        return Err(format!(
            "a data URI of about {decoded_size} bytes after {before} bytes of buffers exceeds {} = {cap}",
            Limit::FileBytes
        ));
    }
    base64::engine::general_purpose::STANDARD
        .decode(payload)
        .map_err(|e| format!("data URI is not valid base64: {e}"))
}

/// Reads a file a URI names, resolved inside the scan's folder (as an OBJ's textures are).
fn read_beside(path: &Path, uri: &str, options: &LoadOptions, role: Referenced) -> Result<Vec<u8>> {
    let file = resolve_beside(path, uri, options, role)?;
    files::read_whole(&file, options.limits.max_file_bytes, Limit::FileBytes)
}

fn resolve_beside(
    path: &Path,
    uri: &str,
    options: &LoadOptions,
    role: Referenced,
) -> Result<std::path::PathBuf> {
    // glTF calls a texture's file an image.
    let what = match role {
        Referenced::Texture => "image".to_string(),
        other => other.to_string(),
    };
    let name = super::refs::file_name(uri)
        .map_err(|m| malformed(path, format!("{what} URI {uri:?}: {m}")))?;
    let limit = (options.limits.max_file_bytes, Limit::FileBytes);
    let resolved = texture::resolve_in_scan(
        &texture::scan_folder(path),
        &texture::folder_of(path),
        (&name, role),
        path,
        limit,
    )?;
    Ok(resolved.path)
}

/// One material per glTF material, with its base-colour texture when the image is a file
/// beside the scan (checked like an OBJ's textures when `options.check_textures`).
fn load_materials(
    path: &Path,
    document: &gltf::Document,
    buffers: &Buffers,
    options: &LoadOptions,
    report: &mut LoadReport,
) -> Result<Vec<Material>> {
    let mut materials: Vec<Material> = Vec::new();
    for m in document.materials() {
        let name = m
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("material{}", materials.len()));
        let mut material = Material {
            name,
            ..Material::default()
        };
        if let Some(info) = m.pbr_metallic_roughness().base_color_texture() {
            if info.tex_coord() != 0 {
                report.skipped.push(format!(
                    "material {}: texture on TEXCOORD_{}",
                    materials.len(),
                    info.tex_coord()
                ));
            }
            let image = info.texture().source().index();
            let at = |m: String| malformed(path, format!("image {image}: {m}"));
            material.diffuse_texture = match image_source(document, image).map_err(at)? {
                ImageSource::File(uri) => {
                    let file = resolve_beside(path, uri, options, Referenced::Texture)?;
                    Some(Texture {
                        name: super::refs::file_name(uri).unwrap_or_default(),
                        path: file,
                        size: None,
                        embedded: None,
                    })
                }
                source => {
                    let name = document.images().nth(image).and_then(|i| i.name());
                    embedded_texture(path, (image, name), source, buffers, options, report)?
                }
            };
        }
        materials.push(material);
    }
    if document
        .meshes()
        .any(|m| m.primitives().any(|p| p.material().index().is_none()))
        && !materials.is_empty()
    {
        materials.push(Material {
            name: "default".into(),
            ..Material::default()
        });
    }
    if options.check_textures {
        check_textures(&mut materials, path, options, report)?;
    }
    Ok(materials)
}

fn check_textures(
    materials: &mut [Material],
    path: &Path,
    options: &LoadOptions,
    report: &mut LoadReport,
) -> Result<()> {
    let images: Vec<texture::ImageRef> = materials
        .iter()
        .filter_map(|m| m.diffuse_texture.as_ref())
        .map(|t| texture::ImageRef::of(t, path))
        .collect();
    let checked = texture::check_images(&images, &options.limits)?;
    report.decoded_textures = checked.decoded;
    for t in materials
        .iter_mut()
        .filter_map(|m| m.diffuse_texture.as_mut())
    {
        t.size = checked.sizes.get(&t.path).copied();
    }
    Ok(())
}

/// Where an image's bytes are.
enum ImageSource<'a> {
    /// A file beside the scan (a relative URI).
    File(&'a str),
    /// A `data:` URI.
    Data(&'a str),
    View(gltf::buffer::View<'a>),
}

/// Image `index`'s source, read from the JSON: the crate's `Image::source` unwraps a missing
/// `uri`, `bufferView` or `mimeType` (panics on hostile input, found by fuzzing).
fn image_source(
    document: &gltf::Document,
    index: usize,
) -> std::result::Result<ImageSource<'_>, String> {
    let json = document
        .as_json()
        .images
        .get(index)
        .ok_or("does not exist")?;
    match (&json.uri, json.buffer_view) {
        (Some(uri), None) if uri.starts_with("data:") => Ok(ImageSource::Data(uri)),
        (Some(uri), None) => Ok(ImageSource::File(uri)),
        (None, Some(view)) => document
            .views()
            .nth(view.value())
            .map(ImageSource::View)
            .ok_or_else(|| format!("buffer view {} does not exist", view.value())),
        _ => Err("an image needs exactly one of uri and bufferView".into()),
    }
}

/// A texture whose image is inside the file (a buffer view or a `data:` URI): its bytes as
/// they are, named `<file>#image<N>`. An image that is neither PNG nor JPEG is left out with
/// a note.
fn embedded_texture(
    path: &Path,
    (image, name): (usize, Option<&str>),
    source: ImageSource,
    buffers: &Buffers,
    options: &LoadOptions,
    report: &mut LoadReport,
) -> Result<Option<Texture>> {
    let at = |m: String| malformed(path, format!("image {image}: {m}"));
    let bytes: Vec<u8> = match source {
        ImageSource::View(view) => accessor::view_bytes(&view, buffers).map_err(at)?.to_vec(),
        ImageSource::Data(uri) => {
            decode_data_uri(uri, 0, options.limits.max_file_bytes).map_err(at)?
        }
        ImageSource::File(_) => return Ok(None),
    };
    let extension = if bytes.starts_with(b"\x89PNG") {
        "png"
    } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        "jpg"
    } else {
        report
            .skipped
            .push(format!("image {image}: neither PNG nor JPEG"));
        return Ok(None);
    };
    let stem = name
        .map(|n| {
            let lower = n.to_ascii_lowercase();
            let known = [".png", ".jpg", ".jpeg"]
                .iter()
                .find(|e| lower.ends_with(*e));
            n[..n.len() - known.map_or(0, |e| e.len())].to_string()
        })
        .unwrap_or_else(|| format!("image{image}"));
    let mut virtual_path = path.as_os_str().to_owned();
    virtual_path.push(format!("#image{image}"));
    Ok(Some(Texture {
        name: format!("{stem}.{extension}"),
        path: virtual_path.into(),
        size: None,
        embedded: Some(EmbeddedImage(bytes.into())),
    }))
}

/// The meshes to read with their world transforms: the default scene's (or the first
/// scene's) node trees, each node visited once; every mesh untransformed when the file has
/// no scene.
fn placed_meshes(document: &gltf::Document) -> Vec<(gltf::Mesh<'_>, DMat4)> {
    let Some(scene) = document
        .default_scene()
        .or_else(|| document.scenes().next())
    else {
        return document.meshes().map(|m| (m, DMat4::IDENTITY)).collect();
    };
    let mut visited = vec![false; document.nodes().len()];
    let mut out = Vec::new();
    let mut stack: Vec<(gltf::Node, DMat4)> = scene.nodes().map(|n| (n, DMat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        if std::mem::replace(&mut visited[node.index()], true) {
            continue;
        }
        let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
        let world = parent * local;
        if let Some(mesh) = node.mesh() {
            out.push((mesh, world));
        }
        stack.extend(node.children().map(|c| (c, world)));
    }
    out.sort_by_key(|(m, _)| m.index());
    out
}

/// Adds one primitive's vertices (transformed) and triangles to the builder.
fn add_primitive(
    b: &mut MeshBuilder,
    p: &gltf::Primitive,
    buffers: &Buffers,
    transform: &DMat4,
    has_materials: bool,
) -> std::result::Result<(), String> {
    let attributes = Attributes::read(p, buffers)?;
    let first = (b.positions.len(), b.texcoords.len(), b.normals.len());
    attributes.push_vertices(b, transform);
    let material = p
        .material()
        .index()
        .map_or(b.materials.len().saturating_sub(1), |m| m) as Index;
    // A mirroring transform turns the winding over; swap two corners to keep it outward.
    let mirrored = DMat3::from_mat4(*transform).determinant() < 0.0;
    attributes.push_faces(b, first, mirrored, has_materials.then_some(material));
    note_skipped_attributes(b, p);
    Ok(())
}

/// A triangle primitive's attributes and indices, checked against each other.
struct Attributes {
    positions: Vec<[f32; 3]>,
    normals: Option<Vec<[f32; 3]>>,
    uvs: Option<Vec<[f32; 2]>>,
    indices: Vec<u32>,
}

impl Attributes {
    fn read(p: &gltf::Primitive, buffers: &Buffers) -> std::result::Result<Attributes, String> {
        if p.mode() != Mode::Triangles {
            return Err(format!(
                "primitive mode {:?} is not supported (only triangles)",
                p.mode()
            ));
        }
        if p.extension_value("KHR_draco_mesh_compression").is_some() {
            return Err("Draco-compressed primitives are not supported".into());
        }
        let positions = accessor::read_vec3(
            &p.get(&Semantic::Positions).ok_or("no POSITION")?,
            buffers,
            "POSITION",
        )?;
        let n = positions.len();
        let normals = p
            .get(&Semantic::Normals)
            .map(|a| accessor::read_vec3(&a, buffers, "NORMAL"))
            .transpose()?;
        let uvs = p
            .get(&Semantic::TexCoords(0))
            .map(|a| accessor::read_texcoords(&a, buffers))
            .transpose()?;
        if normals.as_ref().is_some_and(|v| v.len() != n)
            || uvs.as_ref().is_some_and(|v| v.len() != n)
        {
            return Err("attributes have different counts".into());
        }
        let indices = match p.indices() {
            Some(a) => accessor::read_indices(&a, buffers)?,
            None => (0..n as u32).collect(),
        };
        if indices.len() % 3 != 0 {
            return Err(format!(
                "{} indices is not a whole number of triangles",
                indices.len()
            ));
        }
        if let Some(&bad) = indices.iter().find(|&&i| i as usize >= n) {
            return Err(format!(
                "index {bad} is out of range (the primitive has {n} vertices)"
            ));
        }
        Ok(Attributes {
            positions,
            normals,
            uvs,
            indices,
        })
    }

    /// Positions and normals transformed; texture coordinates flipped to OBJ's origin
    /// (bottom left).
    fn push_vertices(&self, b: &mut MeshBuilder, transform: &DMat4) {
        let identity = *transform == DMat4::IDENTITY;
        let normal_matrix = DMat3::from_mat4(*transform).inverse().transpose();
        for p in &self.positions {
            let p = DVec3::from_array(p.map(f64::from));
            b.positions.push(if identity {
                p
            } else {
                transform.transform_point3(p)
            });
        }
        if let Some(normals) = &self.normals {
            b.normals.extend(normals.iter().map(|v| {
                let v = DVec3::from_array(v.map(f64::from));
                if identity {
                    v
                } else {
                    (normal_matrix * v).normalize_or_zero()
                }
            }));
        }
        if let Some(uvs) = &self.uvs {
            b.texcoords.extend(
                uvs.iter()
                    .map(|t| DVec2::new(f64::from(t[0]), 1.0 - f64::from(t[1]))),
            );
        }
    }

    /// The triangles, their corners indexing from `first` (positions, texture coordinates,
    /// normals as the builder held before [`Attributes::push_vertices`]).
    fn push_faces(
        &self,
        b: &mut MeshBuilder,
        first: (usize, usize, usize),
        mirrored: bool,
        material: Option<Index>,
    ) {
        let (v0, t0, n0) = first;
        let corner = |i: u32| Corner {
            vertex: (v0 + i as usize) as Index,
            texcoord: self.uvs.as_ref().map(|_| (t0 + i as usize) as Index),
            normal: self.normals.as_ref().map(|_| (n0 + i as usize) as Index),
        };
        for tri in self.indices.chunks_exact(3) {
            let [a, bb, c] = [tri[0], tri[1], tri[2]].map(corner);
            b.faces.push(if mirrored { [a, c, bb] } else { [a, bb, c] });
            if let Some(material) = material {
                b.face_materials.push(material);
            }
        }
    }
}

/// Attributes scanmill does not read are named in the load report, once each.
fn note_skipped_attributes(b: &mut MeshBuilder, p: &gltf::Primitive) {
    for (semantic, _) in p.attributes() {
        if !matches!(
            semantic,
            Semantic::Positions | Semantic::Normals | Semantic::TexCoords(0)
        ) {
            let note = format!("attribute {}", semantic.to_string());
            if !b.report.skipped.contains(&note) {
                b.report.skipped.push(note);
            }
        }
    }
}
