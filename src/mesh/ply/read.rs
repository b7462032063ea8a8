//! Reading a PLY file into a [`MeshBuilder`].
//!
//! What is understood (everything else is skipped and listed in `LoadReport::skipped`):
//! - `vertex`: `x y z` (any scalar type), `nx ny nz`, `red green blue [alpha]` (integers as
//!   0..255, floats as 0..1), and per-vertex texture coordinates under `s t`, `u v`,
//!   `texture_u texture_v` or `texture_s texture_t`;
//! - `face`: `vertex_indices` / `vertex_index` (any integer types; polygons are
//!   fan-triangulated), `texcoord` (MeshLab / OpenMVS: two values per corner) and `texnumber`;
//! - `tristrips` (`vertex_indices` with -1 restarts, alternating winding);
//! - Artec's `multi_texture_vertex` (`tx u v`) and `multi_texture_face`
//!   (`tx tn texture_vertex_indices`): record `tn` names the face, its indices give that face's
//!   corners' texture vertices and `tx` its texture;
//! - `comment TextureFile NAME`: one material per line, in order.
//!
//! The header's counts are the truth: a body that ends early is an error naming the element
//! that is cut off. Data after the last element cannot belong to any element the header
//! declares; it is ignored with a warning and noted in `skipped` (MeshLab and rply do the same),
//! so a file whose header declares fewer faces than it holds loads the declared ones.

use super::header::{self, Element, Format, Header, PropertyKind, Scalar};
use super::source::{Ascii, Binary, Fault, Source, Step};
use crate::mesh::build::{Corner, LoadOptions, LoadReport, MeshBuilder};
use crate::mesh::error::{Location, MeshError, Result};
use crate::mesh::limits::Limit;
use crate::mesh::model::{Index, Material, Mesh, Texture};
use crate::mesh::texture::{self, Referenced};
use glam::{DVec2, DVec3};
use std::path::Path;

/// Marks, in `Material::other_statements`, a texture the PLY header names but that is not on
/// disk (`# missing texture: NAME`). It keeps the name for the PLY writer (which writes the
/// `comment TextureFile` line again) and reads as a comment in an MTL.
pub const MISSING_TEXTURE_PREFIX: &str = "# missing texture: ";

const NONE: u32 = u32::MAX;

/// Everything the body holds that the mesh needs, in flat arrays (no per-element allocation).
#[derive(Default)]
struct Raw {
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    colors: Vec<[u8; 4]>,
    /// Per-vertex texture coordinates (one per vertex, or empty).
    vertex_uvs: Vec<DVec2>,
    /// Face polygons: corner vertex indices, flat, with `face_start[f]..face_start[f + 1]`.
    face_vertices: Vec<Index>,
    face_start: Vec<usize>,
    /// Per-corner texture coordinates, parallel to `face_vertices` (`NONE` = none), indices
    /// into `corner_uv_values`; empty when no face has any.
    corner_uvs: Vec<u32>,
    corner_uv_values: Vec<DVec2>,
    /// Texture number per face (`texnumber` or Artec `tx`); empty when the file has none.
    face_textures: Vec<u32>,
    strip_triangles: Vec<[Index; 3]>,
    /// `(index in strip_triangles, further copies)` of strip triangles that repeat an earlier
    /// one (same three vertices, either orientation); the copies are not stored.
    strip_repeats: Vec<(Index, u32)>,
    /// Triangles the strips produced, repeats included.
    strip_triangle_count: usize,
    /// Artec multi-texture vertices and faces.
    multi_uvs: Vec<DVec2>,
    multi_face_texture: Vec<u32>,
    multi_face_target: Vec<u64>,
    multi_face_indices: Vec<u32>,
    multi_face_start: Vec<usize>,
    skipped: Vec<String>,
}

/// Reads a PLY file whose (already decompressed) content is `bytes`.
pub fn read(path: &Path, bytes: &[u8], options: &LoadOptions) -> Result<(Mesh, LoadReport)> {
    let header = header::parse(path, bytes)?;
    if header.element("face").is_none() && header.element("tristrips").is_none() {
        let elements: Vec<String> = header
            .elements
            .iter()
            .map(|e| format!("{} {}", e.name, e.count))
            .collect();
        return Err(MeshError::NoTriangles {
            path: path.to_path_buf(),
            reason: format!(
                "the file has no face element (it has: {}); a point cloud or range image is not a mesh",
                elements.join(", ")
            ),
        });
    }
    let body = &bytes[header.body_start..];
    let mut raw = Raw {
        face_start: vec![0],
        multi_face_start: vec![0],
        ..Raw::default()
    };
    match header.format {
        Format::Ascii => read_body(path, &header, &mut Ascii::new(body, header.lines), &mut raw)?,
        Format::BinaryLittleEndian => {
            read_body(path, &header, &mut Binary::new(body, false), &mut raw)?
        }
        Format::BinaryBigEndian => {
            read_body(path, &header, &mut Binary::new(body, true), &mut raw)?
        }
    }
    assemble(path, &header, raw, options)
}

fn read_body<S: Source>(path: &Path, header: &Header, src: &mut S, raw: &mut Raw) -> Result<()> {
    let vertex_count = header.element("vertex").map_or(0, |e| e.count);
    if vertex_count > Index::MAX as u64 {
        return Err(MeshError::malformed(
            path,
            Location::Header,
            format!(
                "{vertex_count} vertices are more than scanmill handles ({})",
                Index::MAX
            ),
        ));
    }
    let nv = vertex_count as usize;
    for element in &header.elements {
        if element.properties.is_empty() || element.count == 0 {
            continue;
        }
        let at = At { path, element };
        match element.name.as_str() {
            "vertex" => read_vertices(at, src, raw)?,
            "face" => read_faces(at, src, raw, nv)?,
            "tristrips" => read_strips(at, src, raw, nv)?,
            "multi_texture_vertex" => read_multi_vertices(at, src, raw)?,
            "multi_texture_face" => read_multi_faces(at, src, raw)?,
            _ => {
                src.skip_all(element)
                    .map_err(|(i, fault)| to_error(at, src, i, fault))?;
                raw.skipped.push(format!(
                    "element {} ({} elements)",
                    element.name, element.count
                ));
            }
        }
    }
    if let Some(trailing) = src.trailing() {
        tracing::warn!(path = %path.display(), "PLY body has {trailing}; ignored (the header's counts are authoritative)");
        raw.skipped.push(format!("{trailing} (ignored)"));
    }
    Ok(())
}

/// An element being read and the file it is in: what its errors name.
#[derive(Clone, Copy)]
struct At<'a> {
    path: &'a Path,
    element: &'a Element,
}

/// Turns a source fault in element `index` into a located error.
fn to_error<S: Source>(at: At, src: &S, index: u64, fault: Fault) -> MeshError {
    let At { path, element } = at;
    let at = src.location(&element.name, index);
    // Binary locations already say "face 12"; ASCII ones give the line, so name the element.
    let prefix = match at {
        Location::Line(_) => format!("{} {index}: ", element.name),
        _ => String::new(),
    };
    match fault {
        Fault::Truncated(detail) => MeshError::malformed(
            path,
            at,
            format!(
                "truncated: expected {} {} elements, found {index}{detail}",
                element.count, element.name
            ),
        ),
        Fault::Invalid(message) => MeshError::malformed(path, at, format!("{prefix}{message}")),
        Fault::NonFinite(value) => MeshError::NonFinite {
            path: path.to_path_buf(),
            at,
            value: format!("{prefix}{value}"),
        },
        Fault::Index { kind, index, count } => MeshError::IndexOutOfRange {
            path: path.to_path_buf(),
            at,
            kind,
            index,
            count,
        },
    }
}

/// Runs `body` for every element of `element`, between `begin` and `end`, with located errors.
fn for_each<S: Source>(
    at: At,
    src: &mut S,
    mut body: impl FnMut(&mut S, u64) -> Step,
) -> Result<()> {
    for i in 0..at.element.count {
        let step = src
            .begin()
            .and_then(|()| body(src, i))
            .and_then(|()| src.end());
        if let Err(fault) = step {
            return Err(to_error(at, src, i, fault));
        }
    }
    Ok(())
}

/// How many elements to reserve for: the header's count, but never more than the remaining
/// bytes can hold, so a lying header cannot cause a huge allocation. An element takes at
/// least the smallest encoding of each of its values ([`Source::min_value_bytes`]), and a list
/// named in `min_lists` at least that many items (a face has 3 vertex indices).
fn capacity<S: Source>(src: &S, element: &Element, min_lists: &[(&str, usize)]) -> usize {
    let min: usize = element
        .properties
        .iter()
        .map(|p| match p.kind {
            PropertyKind::Scalar(ty) => src.min_value_bytes(ty),
            PropertyKind::List { count, item } => {
                let items = min_lists
                    .iter()
                    .find(|(name, _)| *name == p.name)
                    .map_or(0, |(_, n)| *n);
                src.min_value_bytes(count) + items * src.min_value_bytes(item)
            }
        })
        .sum();
    element.count.min((src.remaining() / min.max(1)) as u64) as usize
}

fn index_value(value: f64, count: usize, kind: &'static str) -> Step<Index> {
    if value < 0.0 || value >= count as f64 {
        return Err(Fault::Index {
            kind,
            index: value as i64,
            count,
        });
    }
    Ok(value as Index)
}

fn require_integer_list(at: At, name: &str) -> Result<(Scalar, Scalar)> {
    let At { path, element } = at;
    match element.property(name).map(|(_, p)| p.kind) {
        Some(PropertyKind::List { count, item }) if item.is_integer() => Ok((count, item)),
        _ => Err(MeshError::malformed(
            path,
            Location::Header,
            format!(
                "element {}: property {name} must be a list of integers",
                element.name
            ),
        )),
    }
}

// Slots of the vertex value array.
const SKIP: usize = 0;
const X: usize = 1;
const NX: usize = 4;
const RED: usize = 7;
const ALPHA: usize = 10;
const U: usize = 11;
const SLOTS: usize = 13;

fn read_vertices<S: Source>(at: At, src: &mut S, raw: &mut Raw) -> Result<()> {
    let element = at.element;
    check_positions(at)?;
    let layout = VertexLayout::of(element, &mut raw.skipped);
    layout.reserve(raw, capacity(src, element, &[]));
    let VertexLayout {
        normals,
        colors,
        uvs,
        ref slots,
        scalar_types,
    } = layout;
    let mut values = [0.0f64; SLOTS];
    values[ALPHA] = 255.0;

    for_each(at, src, |src, _| {
        for (p, &slot) in element.properties.iter().zip(slots) {
            match p.kind {
                PropertyKind::Scalar(ty) => values[slot] = src.value(ty)?,
                list => src.skip(list)?,
            }
        }
        let position = DVec3::new(values[X], values[X + 1], values[X + 2]);
        if !position.is_finite() {
            return Err(Fault::NonFinite(format!(
                "{} {} {}",
                position.x, position.y, position.z
            )));
        }
        raw.positions.push(position);
        if normals {
            raw.normals
                .push(DVec3::new(values[NX], values[NX + 1], values[NX + 2]));
        }
        if colors {
            raw.colors.push(std::array::from_fn(|c| {
                to_byte(values[RED + c], scalar_types[RED + c])
            }));
        }
        if uvs {
            raw.vertex_uvs.push(finite_uv(values[U], values[U + 1])?);
        }
        Ok(())
    })
}

/// Refuses a vertex element without scalar `x`, `y` and `z`.
fn check_positions(at: At) -> Result<()> {
    let At { path, element } = at;
    for axis in ["x", "y", "z"] {
        match element.property(axis) {
            Some((_, p)) if matches!(p.kind, PropertyKind::Scalar(_)) => {}
            _ => {
                return Err(MeshError::malformed(
                    path,
                    Location::Header,
                    format!("element vertex has no scalar property {axis}"),
                ));
            }
        }
    }
    Ok(())
}

/// Where each property of a vertex element goes: a slot per property (`SKIP` for what is
/// not read) and the scalar type of each slot, with which attributes are present.
struct VertexLayout {
    normals: bool,
    colors: bool,
    uvs: bool,
    slots: Vec<usize>,
    scalar_types: [Scalar; SLOTS],
}

impl VertexLayout {
    /// The layout of `element`; the properties it does not read go to `skipped`.
    fn of(element: &Element, skipped: &mut Vec<String>) -> VertexLayout {
        let has = |name: &str| element.property(name).is_some();
        let normals = ["nx", "ny", "nz"].iter().all(|n| has(n));
        let color_prefix = ["", "diffuse_"].into_iter().find(|prefix| {
            ["red", "green", "blue"]
                .iter()
                .all(|c| has(&format!("{prefix}{c}")))
        });
        let uv_names = [
            ("s", "t"),
            ("u", "v"),
            ("texture_u", "texture_v"),
            ("texture_s", "texture_t"),
        ]
        .into_iter()
        .find(|(u, v)| has(u) && has(v));

        let mut slots = vec![SKIP; element.properties.len()];
        let mut scalar_types = [Scalar::F32; SLOTS];
        for (k, p) in element.properties.iter().enumerate() {
            let name = p.name.as_str();
            let slot = match name {
                "x" => X,
                "y" => X + 1,
                "z" => X + 2,
                "nx" if normals => NX,
                "ny" if normals => NX + 1,
                "nz" if normals => NX + 2,
                _ if uv_names.is_some_and(|(u, _)| u == name) => U,
                _ if uv_names.is_some_and(|(_, v)| v == name) => U + 1,
                _ => match color_prefix.and_then(|prefix| name.strip_prefix(prefix)) {
                    Some("red") => RED,
                    Some("green") => RED + 1,
                    Some("blue") => RED + 2,
                    Some("alpha") => ALPHA,
                    _ => SKIP,
                },
            };
            match (slot, p.kind) {
                (SKIP, _) => skipped.push(format!("vertex.{name}")),
                (_, PropertyKind::Scalar(ty)) => scalar_types[slot] = ty,
                (_, PropertyKind::List { .. }) => {
                    // A list where a scalar is expected: not something we can use.
                    slots[k] = SKIP;
                    skipped.push(format!("vertex.{name} (a list)"));
                    continue;
                }
            }
            slots[k] = slot;
        }
        if !slots.contains(&ALPHA) {
            scalar_types[ALPHA] = Scalar::U8;
        }
        VertexLayout {
            normals,
            colors: color_prefix.is_some(),
            uvs: uv_names.is_some(),
            slots,
            scalar_types,
        }
    }

    /// Reserves room for `cap` vertices in what this layout fills.
    fn reserve(&self, raw: &mut Raw, cap: usize) {
        raw.positions.reserve(cap);
        if self.normals {
            raw.normals.reserve(cap);
        }
        if self.colors {
            raw.colors.reserve(cap);
        }
        if self.uvs {
            raw.vertex_uvs.reserve(cap);
        }
    }
}

/// A colour channel as a byte: floats scale from 0..1, 16-bit values from 0..65535.
fn to_byte(value: f64, ty: Scalar) -> u8 {
    let scaled = match ty {
        Scalar::F32 | Scalar::F64 => value * 255.0,
        Scalar::U16 => value / 257.0,
        _ => value,
    };
    // NaN saturates to 0.
    scaled.round().clamp(0.0, 255.0) as u8
}

fn read_faces<S: Source>(at: At, src: &mut S, raw: &mut Raw, nv: usize) -> Result<()> {
    let element = at.element;
    let index_name = if element.property("vertex_indices").is_some() {
        "vertex_indices"
    } else {
        "vertex_index"
    };
    require_integer_list(at, index_name)?;
    let roles = face_roles(element, index_name, &mut raw.skipped);
    let has_uvs = roles.contains(&FaceRole::Texcoords);
    let has_texnumber = roles.contains(&FaceRole::TexNumber);
    // Every face holds at least 3 indices.
    let cap = capacity(src, element, &[(index_name, 3)]);
    reserve_faces(raw, cap, has_uvs, has_texnumber);
    // Per-face texture coordinates may come before the indices: gather them here (reused).
    let mut uv_scratch: Vec<f64> = Vec::new();

    for_each(at, src, |src, _| {
        let first = raw.face_vertices.len();
        let mut texnumber = 0u32;
        uv_scratch.clear();
        for (p, &role) in element.properties.iter().zip(&roles) {
            match (role, p.kind) {
                (FaceRole::Indices, PropertyKind::List { count, item }) => {
                    let n = src.list_len(count, item)?;
                    if n < 3 {
                        return Err(Fault::Invalid(format!(
                            "a face needs at least 3 vertex indices, this one has {n}"
                        )));
                    }
                    for _ in 0..n {
                        let v = index_value(src.value(item)?, nv, "vertex")?;
                        raw.face_vertices.push(v);
                    }
                }
                (FaceRole::Texcoords, PropertyKind::List { count, item }) => {
                    let n = src.list_len(count, item)?;
                    for _ in 0..n {
                        uv_scratch.push(src.value(item)?);
                    }
                }
                (FaceRole::TexNumber, PropertyKind::Scalar(ty)) => {
                    texnumber = texture_number(src.value(ty)?)?;
                }
                (_, kind) => src.skip(kind)?,
            }
        }
        if has_uvs {
            push_corner_uvs(raw, &uv_scratch, raw.face_vertices.len() - first)?;
        }
        if has_texnumber {
            raw.face_textures.push(texnumber);
        }
        raw.face_start.push(raw.face_vertices.len());
        Ok(())
    })
}

/// What a face element's property is read as.
#[derive(Clone, Copy, PartialEq)]
enum FaceRole {
    Skip,
    Indices,
    Texcoords,
    TexNumber,
}

/// The role of each property of a face element; the ones skipped go to `skipped`.
fn face_roles(element: &Element, index_name: &str, skipped: &mut Vec<String>) -> Vec<FaceRole> {
    element
        .properties
        .iter()
        .map(|p| match (p.name.as_str(), p.kind) {
            (name, PropertyKind::List { .. }) if name == index_name => FaceRole::Indices,
            ("texcoord", PropertyKind::List { .. }) => FaceRole::Texcoords,
            ("texnumber", PropertyKind::Scalar(_)) => FaceRole::TexNumber,
            (name, _) => {
                skipped.push(format!("face.{name}"));
                FaceRole::Skip
            }
        })
        .collect()
}

/// Reserves room for `cap` faces; texture coordinates may be empty lists, so their arrays
/// grow as they are read.
fn reserve_faces(raw: &mut Raw, cap: usize, has_uvs: bool, has_texnumber: bool) {
    raw.face_start.reserve(cap);
    raw.face_vertices.reserve(cap * 3);
    if has_uvs {
        raw.corner_uvs.resize(raw.face_vertices.len(), NONE);
    }
    if has_texnumber {
        raw.face_textures.reserve(cap);
    }
}

/// A `texnumber` value as a texture number.
fn texture_number(t: f64) -> std::result::Result<u32, Fault> {
    if !(0.0..=f64::from(u16::MAX)).contains(&t) || t.fract() != 0.0 {
        return Err(Fault::Invalid(format!(
            "texnumber {t} is not a texture number"
        )));
    }
    Ok(t as u32)
}

/// A face's texture coordinates (`uvs`, two values a corner, or none) for its `corners`.
fn push_corner_uvs(raw: &mut Raw, uvs: &[f64], corners: usize) -> std::result::Result<(), Fault> {
    if uvs.is_empty() {
        raw.corner_uvs.extend(std::iter::repeat_n(NONE, corners));
    } else if uvs.len() == 2 * corners {
        for uv in uvs.chunks_exact(2) {
            let uv = finite_uv(uv[0], uv[1])?;
            raw.corner_uvs.push(raw.corner_uv_values.len() as u32);
            raw.corner_uv_values.push(uv);
        }
    } else {
        return Err(Fault::Invalid(format!(
            "texcoord has {} values for a face with {corners} corners (expected {})",
            uvs.len(),
            2 * corners
        )));
    }
    Ok(())
}

/// A texture coordinate, refused when not finite.
fn finite_uv(u: f64, v: f64) -> std::result::Result<DVec2, Fault> {
    let uv = DVec2::new(u, v);
    if !uv.is_finite() {
        return Err(Fault::NonFinite(format!(
            "texture coordinate {} {}",
            uv.x, uv.y
        )));
    }
    Ok(uv)
}

/// Unrolls triangle strips: triangle j of a strip is (`v[j]`, `v[j+1]`, `v[j+2]`), with the first
/// two swapped for odd j so that all keep the strip's orientation; -1 restarts a strip.
/// Triangles that repeat an index are the zero-area joins strippers insert; they are dropped.
///
/// A strip spends one index per triangle, so a few megabytes of one-byte indices can name
/// tens of millions of triangles; over few vertices nearly all are copies, which the repair
/// rules drop anyway. Copies of a triangle already unrolled are therefore only counted here
/// (`strip_repeats`, charged to the first copy's fate by [`MeshBuilder::finish`]), so that
/// memory follows the distinct triangles, not the bytes.
fn read_strips<S: Source>(at: At, src: &mut S, raw: &mut Raw, nv: usize) -> Result<()> {
    let element = at.element;
    require_integer_list(at, "vertex_indices")?;
    note_unread(raw, element, &["vertex_indices"]);
    // Sorted vertices → (index in strip_triangles, further copies).
    let mut seen: rustc_hash::FxHashMap<[Index; 3], (Index, u32)> = Default::default();
    let first = raw.strip_triangles.len();
    for_each(at, src, |src, _| {
        for p in &element.properties {
            let PropertyKind::List { count, item } = p.kind else {
                src.skip(p.kind)?;
                continue;
            };
            if p.name != "vertex_indices" {
                src.skip(p.kind)?;
                continue;
            }
            let n = src.list_len(count, item)?;
            let (mut a, mut b, mut len) = (0, 0, 0usize);
            for _ in 0..n {
                let value = src.value(item)?;
                if value == -1.0 {
                    len = 0;
                    continue;
                }
                let c = index_value(value, nv, "vertex")?;
                if len >= 2 {
                    let tri = if (len - 2) % 2 == 0 {
                        [a, b, c]
                    } else {
                        [b, a, c]
                    };
                    if a != b && b != c && a != c {
                        raw.strip_triangle_count += 1;
                        let mut key = tri;
                        key.sort_unstable();
                        let next = raw.strip_triangles.len() as Index;
                        let entry = seen.entry(key).or_insert((next, 0));
                        if entry.0 == next {
                            raw.strip_triangles.push(tri);
                        } else {
                            entry.1 += 1;
                        }
                    }
                }
                (a, b) = (b, c);
                len += 1;
            }
        }
        Ok(())
    })?;
    raw.strip_repeats.extend(
        seen.into_values()
            .filter(|(_, copies)| *copies > 0)
            .map(|(t, copies)| (t - first as Index, copies)),
    );
    raw.strip_repeats.sort_unstable();
    Ok(())
}

/// Records the properties of `element` other than `read` as skipped (`element.property`).
fn note_unread(raw: &mut Raw, element: &Element, read: &[&str]) {
    for p in &element.properties {
        if !read.contains(&p.name.as_str()) {
            raw.skipped.push(format!("{}.{}", element.name, p.name));
        }
    }
}

fn read_multi_vertices<S: Source>(at: At, src: &mut S, raw: &mut Raw) -> Result<()> {
    let At { path, element } = at;
    let (Some((iu, _)), Some((iv, _))) = (element.property("u"), element.property("v")) else {
        return Err(MeshError::malformed(
            path,
            Location::Header,
            "element multi_texture_vertex has no u and v properties",
        ));
    };
    note_unread(raw, element, &["u", "v", "tx"]);
    raw.multi_uvs.reserve(capacity(src, element, &[]));
    for_each(at, src, |src, _| {
        let mut uv = DVec2::ZERO;
        for (k, p) in element.properties.iter().enumerate() {
            match p.kind {
                PropertyKind::Scalar(ty) if k == iu => uv.x = src.value(ty)?,
                PropertyKind::Scalar(ty) if k == iv => uv.y = src.value(ty)?,
                kind => src.skip(kind)?,
            }
        }
        if !uv.is_finite() {
            return Err(Fault::NonFinite(format!(
                "texture coordinate {} {}",
                uv.x, uv.y
            )));
        }
        raw.multi_uvs.push(uv);
        Ok(())
    })
}

fn read_multi_faces<S: Source>(at: At, src: &mut S, raw: &mut Raw) -> Result<()> {
    let element = at.element;
    require_integer_list(at, "texture_vertex_indices")?;
    note_unread(raw, element, &["tx", "tn", "texture_vertex_indices"]);
    let texture_vertices = raw.multi_uvs.len();
    for_each(at, src, |src, i| {
        let (mut tx, mut tn) = (0.0, i as f64);
        for p in &element.properties {
            match (p.name.as_str(), p.kind) {
                ("tx", PropertyKind::Scalar(ty)) => tx = src.value(ty)?,
                ("tn", PropertyKind::Scalar(ty)) => tn = src.value(ty)?,
                ("texture_vertex_indices", PropertyKind::List { count, item }) => {
                    let n = src.list_len(count, item)?;
                    for _ in 0..n {
                        let t = index_value(src.value(item)?, texture_vertices, "texture vertex")?;
                        raw.multi_face_indices.push(t);
                    }
                }
                (_, kind) => src.skip(kind)?,
            }
        }
        if !(0.0..=f64::from(u16::MAX)).contains(&tx) || tn < 0.0 {
            return Err(Fault::Invalid(format!(
                "bad texture number tx {tx} or face number tn {tn}"
            )));
        }
        raw.multi_face_texture.push(tx as u32);
        raw.multi_face_target.push(tn as u64);
        raw.multi_face_start.push(raw.multi_face_indices.len());
        Ok(())
    })
}

/// Applies Artec's per-face texture-vertex indices to the faces they name.
fn apply_multi_texture(path: &Path, raw: &mut Raw) -> Result<()> {
    let records = raw.multi_face_target.len();
    if records == 0 {
        return Ok(());
    }
    let faces = raw.face_start.len() - 1;
    let base = raw.corner_uv_values.len() as u32;
    raw.corner_uv_values.extend_from_slice(&raw.multi_uvs);
    raw.corner_uvs.resize(raw.face_vertices.len(), NONE);
    if raw.face_textures.is_empty() {
        raw.face_textures = vec![0; faces];
    }
    for r in 0..records {
        let at = || Location::Element {
            element: "multi_texture_face".into(),
            index: r as u64,
        };
        let f = raw.multi_face_target[r];
        if f >= faces as u64 {
            return Err(MeshError::IndexOutOfRange {
                path: path.to_path_buf(),
                at: at(),
                kind: "face",
                index: f.min(i64::MAX as u64) as i64,
                count: faces,
            });
        }
        let f = f as usize;
        let corners = raw.face_start[f]..raw.face_start[f + 1];
        let uvs = &raw.multi_face_indices[raw.multi_face_start[r]..raw.multi_face_start[r + 1]];
        if uvs.len() != corners.len() {
            return Err(MeshError::malformed(
                path,
                at(),
                format!(
                    "{} texture vertex indices for face {f}, which has {} corners",
                    uvs.len(),
                    corners.len()
                ),
            ));
        }
        for (slot, &t) in raw.corner_uvs[corners].iter_mut().zip(uvs) {
            *slot = base + t;
        }
        raw.face_textures[f] = raw.multi_face_texture[r];
    }
    Ok(())
}

/// Materials from `comment TextureFile` lines, and how many images were decoded.
///
/// PLY texture files are optional: MeshLab and OpenMVS name them in a comment, and PLYs are
/// routinely passed around without them (see data/ply_texcoords). So a texture that is not on
/// disk does not fail the load, even with `check_textures`: the material is kept with
/// `diffuse_texture: None`, its name is kept in `other_statements` (see
/// [`MISSING_TEXTURE_PREFIX`]) and a warning is logged. A name that resolves outside the scan's
/// folder (`..`, an absolute path, a symlink), names a FIFO or device, or is above the size
/// limit is refused with an error, as for OBJ: it is never read. A texture that is present but
/// does not decode is an error with `check_textures`, as for OBJ: the user clearly meant it to
/// be used.
fn texture_materials(
    path: &Path,
    names: &[String],
    options: &LoadOptions,
) -> Result<(Vec<Material>, usize)> {
    let scan_dir = texture::scan_folder(path);
    let base_dir = texture::folder_of(path);
    let cap = (options.limits.max_file_bytes, Limit::FileBytes);
    let mut materials = Vec::with_capacity(names.len());
    for (i, name) in names.iter().enumerate() {
        let mut material = Material {
            name: format!("texture{i}"),
            ..Material::default()
        };
        match texture::resolve_in_scan(&scan_dir, &base_dir, (name, Referenced::Texture), path, cap)
        {
            Ok(resolved) => {
                material.diffuse_texture = Some(Texture {
                    name: name.clone(),
                    path: resolved.path,
                    size: None,
                    embedded: None,
                });
            }
            Err(MeshError::MissingFile { .. }) => {
                tracing::warn!(path = %path.display(), texture = %name, "PLY texture is missing; material {} has no texture", material.name);
                material
                    .other_statements
                    .push(format!("{MISSING_TEXTURE_PREFIX}{name}"));
            }
            Err(e) => return Err(e),
        }
        materials.push(material);
    }
    if !options.check_textures {
        return Ok((materials, 0));
    }
    let images: Vec<texture::ImageRef> = materials
        .iter()
        .filter_map(|m| m.diffuse_texture.as_ref())
        .map(|t| texture::ImageRef {
            path: &t.path,
            name: &t.name,
            referrer: path,
            embedded: None,
        })
        .collect();
    let checked = texture::check_images(&images, &options.limits)?;
    for t in materials
        .iter_mut()
        .filter_map(|m| m.diffuse_texture.as_mut())
    {
        t.size = checked.sizes.get(&t.path).copied();
    }
    Ok((materials, checked.decoded))
}

fn assemble(
    path: &Path,
    header: &Header,
    mut raw: Raw,
    options: &LoadOptions,
) -> Result<(Mesh, LoadReport)> {
    let faces = raw.face_start.len() - 1;
    apply_multi_texture(path, &mut raw)?;

    let (mut materials, decoded_textures) =
        texture_materials(path, &header.texture_files(), options)?;
    let with_materials = materials_for_faces(path, &mut materials, &raw.face_textures);

    let mut b = MeshBuilder::new(path, &format!("ply {}", header.format.keyword()));
    file_counts(&mut b.report, &mut raw, faces);
    b.report.decoded_textures = decoded_textures;
    warn_bad_normals(path, &raw.normals);
    push_triangles(&mut b, &raw, faces, with_materials);

    b.positions = raw.positions;
    b.normals = raw.normals;
    b.colors = raw.colors;
    b.texcoords = raw.vertex_uvs;
    b.texcoords.extend_from_slice(&raw.corner_uv_values);
    b.materials = materials;
    b.finish(options)
}

/// Whether the faces carry materials; when they do, adds a material without texture for
/// every texture number the header names no file for.
fn materials_for_faces(path: &Path, materials: &mut Vec<Material>, face_textures: &[u32]) -> bool {
    let max_texture = face_textures.iter().copied().max();
    let with_materials = !materials.is_empty() || max_texture.is_some_and(|m| m > 0);
    if let Some(max) = max_texture.filter(|_| with_materials) {
        if max as usize >= materials.len() {
            tracing::warn!(path = %path.display(), "faces use texture {max} but the header names {} texture files; adding materials without texture", materials.len());
        }
        while materials.len() <= max as usize {
            materials.push(Material {
                name: format!("texture{}", materials.len()),
                ..Material::default()
            });
        }
    }
    with_materials
}

/// What the file held, into the load report (the skipped properties are taken from `raw`).
fn file_counts(report: &mut LoadReport, raw: &mut Raw, faces: usize) {
    report.file_vertices = raw.positions.len();
    report.file_faces = faces;
    report.file_normals = raw.normals.len();
    report.file_texcoords = raw.vertex_uvs.len() + raw.corner_uv_values.len();
    report.strip_triangles = raw.strip_triangle_count;
    report.skipped = std::mem::take(&mut raw.skipped);
}

fn warn_bad_normals(path: &Path, normals: &[DVec3]) {
    let bad_normals = normals.iter().filter(|n| !n.is_finite()).count();
    if bad_normals > 0 {
        tracing::warn!(path = %path.display(), "{bad_normals} vertex normals are not finite; those corners get no normal");
    }
}

/// The corner of vertex `v` with corner texture coordinate `uv` (`NONE`: the vertex's own,
/// if the vertices have them); texture coordinates index vertex ones, then corner ones.
fn corner(raw: &Raw, v: Index, uv: u32) -> Corner {
    let vertex_uv_count = raw.vertex_uvs.len();
    Corner {
        vertex: v,
        texcoord: if uv != NONE {
            Some(vertex_uv_count as Index + uv)
        } else if vertex_uv_count > 0 {
            Some(v)
        } else {
            None
        },
        normal: (!raw.normals.is_empty() && raw.normals[v as usize].is_finite()).then_some(v),
    }
}

/// The faces, fan-triangulated, then the strips' triangles, with their materials.
fn push_triangles(b: &mut MeshBuilder, raw: &Raw, faces: usize, with_materials: bool) {
    let triangles = raw.face_vertices.len().saturating_sub(2 * faces) + raw.strip_triangles.len();
    b.faces.reserve(triangles);
    if with_materials {
        b.face_materials.reserve(triangles);
    }
    for f in 0..faces {
        let (start, end) = (raw.face_start[f], raw.face_start[f + 1]);
        if end - start > 3 {
            b.report.triangulated_polygons += 1;
        }
        let c = |k: usize| {
            corner(
                raw,
                raw.face_vertices[k],
                raw.corner_uvs.get(k).copied().unwrap_or(NONE),
            )
        };
        for k in start + 1..end - 1 {
            b.faces.push([c(start), c(k), c(k + 1)]);
            if with_materials {
                b.face_materials
                    .push(raw.face_textures.get(f).copied().unwrap_or(0));
            }
        }
    }
    let first_strip = b.faces.len() as Index;
    b.face_repeats = raw
        .strip_repeats
        .iter()
        .map(|&(t, copies)| (first_strip + t, copies))
        .collect();
    for tri in &raw.strip_triangles {
        b.faces.push(tri.map(|v| corner(raw, v, NONE)));
        if with_materials {
            b.face_materials.push(0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reservations_are_bounded_by_the_bytes_that_remain() {
        let text = "ply\nformat binary_little_endian 1.0\nelement vertex 2147483648\n\
                    property uchar x\nproperty uchar y\nproperty uchar z\n\
                    element face 4294967295\nproperty list uchar uchar vertex_indices\nend_header\n";
        let mut bytes = text.as_bytes().to_vec();
        bytes.extend([0u8; 1200]);
        let header = header::parse(Path::new("x.ply"), &bytes).unwrap();
        let body = &bytes[header.body_start..];
        let (vertex, face) = (
            header.element("vertex").unwrap(),
            header.element("face").unwrap(),
        );
        let faces = [("vertex_indices", 3)];
        // Binary: 3 bytes a vertex; a face at least its count byte and 3 index bytes.
        let binary = Binary::new(body, false);
        assert_eq!(capacity(&binary, vertex, &[]), 400);
        assert_eq!(capacity(&binary, face, &faces), 300);
        // ASCII: at least a digit and a separator per value.
        let ascii = Ascii::new(body, header.lines);
        assert_eq!(capacity(&ascii, vertex, &[]), 200);
        assert_eq!(capacity(&ascii, face, &faces), 150);
    }
}
