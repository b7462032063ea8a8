//! Reading a Wavefront OBJ.
//!
//! The reader is a hand-written line parser over the file's bytes (no `String` per line,
//! no allocation per face). It keeps the file's separate position / texture-coordinate /
//! normal index streams exactly as written: the global vertex identity of the file is what
//! welding and seams are built on (tobj re-indexes per group, which shows up as spurious
//! welds, so it is only a test oracle here). Large files are split at line boundaries and
//! parsed in parallel; the result and every error are the same as a sequential parse.
//!
//! Rules:
//! - `v x y z [w]` or `v x y z r g b`: colours are kept only if *every* `v` has them.
//! - `vt u [v [w]]`, `vn x y z`; `f` corners `v`, `v/vt`, `v//vn`, `v/vt/vn`, forms may mix
//!   within a face; negative indices are relative to the elements read so far; positive
//!   indices may point forward (checked against the file's final counts).
//! - Polygons are fan-triangulated `(0, i, i+1)`.
//! - `usemtl` sets the material of the faces that follow. Materials are those of the MTL
//!   files in `mtllib` order; a name found in no MTL becomes a material without texture.
//!   Faces before the first `usemtl`, when the file has materials, get the material
//!   `default` (no texture; reused if an MTL defines it): that is what viewers show for
//!   them, and it survives a write/read round trip (`usemtl default`).
//! - `o`, `g`, `s` are ignored; `l`, `p` and other known but unused statements are skipped
//!   and counted in the report. A statement that is not a word is malformed (binary data).
//! - `\` at the end of a line continues it; `#` starts a comment; CRLF is fine.
//! - A file cut in the middle of a line is an error when that leaves the line incomplete
//!   (`v 1.0 2.` has two coordinates, `f 1/` has no texture index); a cut that happens to
//!   leave a valid line cannot be told apart from a complete file.

use super::materials::{Assigned, MaterialStatements, assign_materials, check_textures};
use crate::mesh::build::{Corner, LoadOptions, LoadReport, MeshBuilder};
use crate::mesh::error::{Location, MeshError, Result};
use crate::mesh::limits::InputLimits;
use crate::mesh::model::{Index, Material, Mesh};
use crate::mesh::texture;
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Files above this size are parsed in parallel chunks of at least this size.
const PARALLEL_CHUNK_BYTES: usize = 1 << 20;

/// Reads an OBJ (its bytes already in memory; `path` names it in errors and locates the
/// MTL and textures) into a mesh.
pub fn read(path: &Path, bytes: &[u8], options: &LoadOptions) -> Result<(Mesh, LoadReport)> {
    let (builder, textures) = parse_unchecked(path, bytes, options)?;
    finish(builder, textures, options)
}

/// Parses an OBJ and its materials into a [`MeshBuilder`], before welding and repair, and
/// checks its textures (`options.check_textures`). Faces are in file order,
/// fan-triangulated; indices are exactly the file's.
pub fn parse(path: &Path, bytes: &[u8], options: &LoadOptions) -> Result<MeshBuilder> {
    let (mut builder, textures) = parse_unchecked(path, bytes, options)?;
    if let Some(textures) = textures {
        builder.report.decoded_textures = textures.run(&mut builder.materials)?;
    }
    Ok(builder)
}

/// The check of an OBJ's textures, still to be made ([`parse_unchecked`]): each distinct
/// image decoded once within the limits ([`check_textures`]).
pub(crate) struct TextureCheck {
    /// The MTL that names each material (for the errors).
    referrers: Vec<PathBuf>,
    limits: InputLimits,
}

impl TextureCheck {
    /// Checks the textures of `materials` (the parsed ones, in their order: the first
    /// failure in that order is the error) and stores each image's size; returns how many
    /// images were decoded.
    fn run(&self, materials: &mut [Material]) -> Result<usize> {
        check_textures(materials, &self.referrers, &self.limits)
    }
}

/// Welds and repairs a parsed OBJ ([`MeshBuilder::finish`]) beside the check of its
/// textures, when there is one. Decoding the images is sequential (a 2,048² JPEG takes
/// ~20 ms) and the weld leaves a core idle part of the time. A texture that fails is the
/// error even when the geometry fails too, as when textures were checked first.
pub(crate) fn finish(
    builder: MeshBuilder,
    textures: Option<TextureCheck>,
    options: &LoadOptions,
) -> Result<(Mesh, LoadReport)> {
    let Some(textures) = textures else {
        return builder.finish(options);
    };
    // The check works on a copy of the materials, and the sizes it finds are given to the
    // materials the repaired mesh keeps, by image path (what a size depends on).
    let mut checked = builder.materials.clone();
    let (decoded, finished) =
        rayon::join(|| textures.run(&mut checked), || builder.finish(options));
    let decoded = decoded?;
    let (mut mesh, mut report) = finished?;
    report.decoded_textures = decoded;
    let sizes: BTreeMap<&Path, (u32, u32)> = checked
        .iter()
        .filter_map(|m| m.diffuse_texture.as_ref())
        .filter_map(|t| Some((t.path.as_path(), t.size?)))
        .collect();
    for material in &mut mesh.materials {
        if let Some(t) = &mut material.diffuse_texture {
            t.size = sizes.get(t.path.as_path()).copied();
        }
    }
    Ok((mesh, report))
}

/// [`parse`] without the texture check, which it returns to be made later (`None` when
/// `options.check_textures` is off): [`finish`] makes it beside the weld.
pub(crate) fn parse_unchecked(
    path: &Path,
    bytes: &[u8],
    options: &LoadOptions,
) -> Result<(MeshBuilder, Option<TextureCheck>)> {
    let geometry = parse_geometry(path, bytes)?;
    let mut builder = MeshBuilder::new(path, "obj");
    builder.report.file_vertices = geometry.positions.len();
    builder.report.file_texcoords = geometry.texcoords.len();
    builder.report.file_normals = geometry.normals.len();
    builder.report.file_faces = geometry.polygons;
    builder.report.triangulated_polygons = geometry.triangulated;
    builder.report.skipped = geometry
        .skipped
        .iter()
        .map(|(k, n)| format!("{n} `{k}` statement{}", if *n == 1 { "" } else { "s" }))
        .collect();
    if geometry.faces.is_empty() {
        let reason = if bytes.iter().all(u8::is_ascii_whitespace) {
            "the file is empty".to_string()
        } else {
            format!(
                "the file has no `f` statements ({} vertices{})",
                geometry.positions.len(),
                if geometry.skipped.is_empty() {
                    String::new()
                } else {
                    format!(", skipped: {}", builder.report.skipped.join(", "))
                }
            )
        };
        return Err(MeshError::NoTriangles {
            path: path.to_path_buf(),
            reason,
        });
    }
    let statements = MaterialStatements {
        mtllibs: &geometry.mtllibs,
        usemtl: &geometry.usemtl,
        faces: geometry.faces.len(),
    };
    let Assigned {
        materials,
        referrers,
        face_materials,
    } = assign_materials(path, &statements, options)?;
    let textures = options.check_textures.then(|| TextureCheck {
        referrers,
        limits: options.limits.clone(),
    });
    let colors_complete =
        !geometry.positions.is_empty() && geometry.colors.len() == geometry.positions.len();
    if !geometry.colors.is_empty() && !colors_complete {
        tracing::warn!(
            "{}: only {} of {} vertices have colours; colours ignored",
            path.display(),
            geometry.colors.len(),
            geometry.positions.len()
        );
    }
    builder.positions = geometry.positions;
    builder.texcoords = geometry.texcoords;
    builder.normals = geometry.normals;
    builder.colors = if colors_complete {
        geometry.colors
    } else {
        Vec::new()
    };
    builder.faces = geometry.faces;
    builder.face_materials = face_materials;
    builder.materials = materials;
    Ok((builder, textures))
}

// ---------------------------------------------------------------------------------------
// Geometry parsing

/// What the statements of an OBJ say, before materials are resolved.
#[derive(Debug, Default)]
struct Geometry {
    positions: Vec<DVec3>,
    /// Colours of the `v` lines that have them (complete only if as long as `positions`).
    colors: Vec<[u8; 4]>,
    texcoords: Vec<DVec2>,
    normals: Vec<DVec3>,
    faces: Vec<[Corner; 3]>,
    polygons: usize,
    triangulated: usize,
    /// `(first face, material name)` for every `usemtl`, in file order.
    usemtl: Vec<(usize, String)>,
    /// `(line, argument)` for every `mtllib` statement (normalised), in file order.
    mtllibs: Vec<(u64, String)>,
    skipped: BTreeMap<String, usize>,
}

/// How a chunk treats indices whose meaning depends on what came before it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    /// The chunk starts the file: negative indices are resolved, every index is checked
    /// (positive ones against the final counts, at the end), errors carry exact lines.
    Exact,
    /// A chunk of a parallel parse: a negative or zero index stops it (the file is then
    /// parsed sequentially); the largest positive indices are recorded for a final check.
    Parallel,
}

enum ChunkFail {
    Error(MeshError),
    NeedSequential,
}

impl From<MeshError> for ChunkFail {
    fn from(e: MeshError) -> Self {
        ChunkFail::Error(e)
    }
}

type ChunkResult<T> = std::result::Result<T, ChunkFail>;

/// A positive index that was beyond the elements read so far (a forward reference), to be
/// checked against the final count.
#[derive(Debug, Clone, Copy)]
struct Pending {
    line: u64,
    kind: Kind,
    written: i64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Vertex,
    Texcoord,
    Normal,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Vertex => "vertex",
            Kind::Texcoord => "texture coordinate",
            Kind::Normal => "normal",
        }
    }
}

/// Parser state for one chunk of the file.
struct Chunk<'a> {
    path: &'a Path,
    mode: Mode,
    out: Geometry,
    /// Largest 0-based index used per kind (Parallel mode), or `None`.
    max_index: [Option<u32>; 3],
    pending: Vec<Pending>,
    /// Physical lines consumed.
    lines: u64,
    /// Corners of the face being parsed (reused: no allocation per face).
    corners: Vec<Corner>,
}

fn parse_geometry(path: &Path, bytes: &[u8]) -> Result<Geometry> {
    // Some Windows tools start text files with a UTF-8 byte-order mark.
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let threads = rayon::current_num_threads();
    parse_geometry_in(
        path,
        bytes,
        threads.min(bytes.len() / PARALLEL_CHUNK_BYTES).max(1),
    )
}

/// Parses in about `chunks` parallel pieces (1: sequentially).
fn parse_geometry_in(path: &Path, bytes: &[u8], chunks: usize) -> Result<Geometry> {
    let pieces = split_chunks(bytes, chunks);
    if pieces.len() > 1 {
        let results: Vec<ChunkResult<Chunk>> = pieces
            .par_iter()
            .map(|piece| parse_chunk(path, piece, Mode::Parallel))
            .collect();
        match merge_chunks(results)? {
            Some(geometry) => return Ok(geometry),
            None => tracing::debug!("{}: parsing sequentially", path.display()),
        }
    }
    match parse_chunk(path, bytes, Mode::Exact) {
        Ok(chunk) => {
            chunk.check_pending()?;
            Ok(chunk.out)
        }
        Err(ChunkFail::Error(e)) => Err(e),
        Err(ChunkFail::NeedSequential) => unreachable_sequential(path),
    }
}

fn unreachable_sequential<T>(path: &Path) -> Result<T> {
    // Exact mode never asks for a sequential parse; keep a typed error rather than a panic.
    Err(MeshError::malformed(
        path,
        Location::Header,
        "internal error: sequential parse requested twice",
    ))
}

/// Splits at line boundaries (never after a line ending in `\`) into about `n` pieces.
fn split_chunks(bytes: &[u8], n: usize) -> Vec<&[u8]> {
    let mut pieces = Vec::with_capacity(n);
    let mut start = 0;
    for k in 1..n {
        let target = (bytes.len() * k / n).max(start);
        let mut cut = target;
        loop {
            match memchr::memchr(b'\n', &bytes[cut..]) {
                None => {
                    cut = bytes.len();
                    break;
                }
                Some(i) => {
                    cut += i + 1;
                    if !trim_end(&bytes[..cut - 1]).ends_with(b"\\") {
                        break;
                    }
                }
            }
        }
        if cut > start && cut < bytes.len() {
            pieces.push(&bytes[start..cut]);
            start = cut;
        }
    }
    pieces.push(&bytes[start..]);
    pieces
}

/// Joins parallel chunks in order. `Ok(None)`: a chunk needs the sequential parse (a
/// relative or zero index, or an index beyond the final counts — the sequential parse then
/// reports it with its line).
fn merge_chunks(results: Vec<ChunkResult<Chunk>>) -> Result<Option<Geometry>> {
    let mut chunks = Vec::with_capacity(results.len());
    let mut line_offset = 0;
    for r in results {
        match r {
            Ok(c) => {
                let lines = c.lines;
                chunks.push((line_offset, c));
                line_offset += lines;
            }
            Err(ChunkFail::NeedSequential) => return Ok(None),
            Err(ChunkFail::Error(e)) => return Err(shift_line(e, line_offset)),
        }
    }
    let total = |f: fn(&Geometry) -> usize| chunks.iter().map(|(_, c)| f(&c.out)).sum::<usize>();
    let counts = [
        total(|g| g.positions.len()),
        total(|g| g.texcoords.len()),
        total(|g| g.normals.len()),
    ];
    let faces = total(|g| g.faces.len());
    for (_, c) in &chunks {
        let beyond = c.max_index.iter().zip(counts);
        if beyond
            .into_iter()
            .any(|(m, n)| m.is_some_and(|m| m as usize >= n))
        {
            return Ok(None);
        }
    }
    // The first chunk's arrays are kept and the others appended: a large array grows in
    // place (glibc moves the pages of a mapped block, it does not copy them), so only the
    // later chunks' data is copied (the first holds most of the vertices of a file that
    // lists them first).
    let mut chunks = chunks.into_iter();
    let Some((_, first)) = chunks.next() else {
        return Ok(Some(Geometry::default()));
    };
    let mut g = first.out;
    g.positions.reserve_exact(counts[0] - g.positions.len());
    g.texcoords.reserve_exact(counts[1] - g.texcoords.len());
    g.normals.reserve_exact(counts[2] - g.normals.len());
    g.faces.reserve_exact(faces - g.faces.len());
    for (line_offset, c) in chunks {
        let face_offset = g.faces.len();
        let o = c.out;
        g.positions.extend_from_slice(&o.positions);
        g.colors.extend_from_slice(&o.colors);
        g.texcoords.extend_from_slice(&o.texcoords);
        g.normals.extend_from_slice(&o.normals);
        g.faces.extend_from_slice(&o.faces);
        g.polygons += o.polygons;
        g.triangulated += o.triangulated;
        g.usemtl
            .extend(o.usemtl.into_iter().map(|(f, n)| (f + face_offset, n)));
        g.mtllibs
            .extend(o.mtllibs.into_iter().map(|(l, n)| (l + line_offset, n)));
        for (k, n) in o.skipped {
            *g.skipped.entry(k).or_default() += n;
        }
    }
    // No room left over from the first chunk's growth: the arrays live on in the mesh.
    g.positions.shrink_to_fit();
    g.texcoords.shrink_to_fit();
    g.normals.shrink_to_fit();
    g.faces.shrink_to_fit();
    Ok(Some(g))
}

/// Adds `offset` to the line of an error found in a chunk that does not start the file.
fn shift_line(e: MeshError, offset: u64) -> MeshError {
    let shift = |at: Location| match at {
        Location::Line(n) => Location::Line(n + offset),
        other => other,
    };
    match e {
        MeshError::Malformed { path, at, message } => MeshError::Malformed {
            path,
            at: shift(at),
            message,
        },
        MeshError::NonFinite { path, at, value } => MeshError::NonFinite {
            path,
            at: shift(at),
            value,
        },
        MeshError::IndexOutOfRange {
            path,
            at,
            kind,
            index,
            count,
        } => MeshError::IndexOutOfRange {
            path,
            at: shift(at),
            kind,
            index,
            count,
        },
        other => other,
    }
}

fn is_space(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\r' | 0x0b | 0x0c)
}

fn trim_end(mut s: &[u8]) -> &[u8] {
    while let [rest @ .., last] = s {
        if is_space(*last) {
            s = rest;
        } else {
            break;
        }
    }
    s
}

fn skip_space(s: &[u8], mut i: usize) -> usize {
    while i < s.len() && is_space(s[i]) {
        i += 1;
    }
    i
}

fn token_end(s: &[u8], mut i: usize) -> usize {
    while i < s.len() && !is_space(s[i]) {
        i += 1;
    }
    i
}

fn parse_chunk<'a>(path: &'a Path, bytes: &[u8], mode: Mode) -> ChunkResult<Chunk<'a>> {
    let mut chunk = Chunk {
        path,
        mode,
        out: Geometry::default(),
        max_index: [None; 3],
        pending: Vec::new(),
        lines: 0,
        corners: Vec::with_capacity(8),
    };
    // Rough capacity from the byte count (a `v` line is ~30 bytes, faces twice as many).
    let estimate = bytes.len() / 100;
    chunk.out.positions.reserve(estimate);
    chunk.out.faces.reserve(estimate * 2);
    let mut joined: Vec<u8> = Vec::new();
    let mut pos = 0;
    while pos < bytes.len() {
        let end = memchr::memchr(b'\n', &bytes[pos..]).map_or(bytes.len(), |i| pos + i);
        let line = trim_end(&bytes[pos..end]);
        pos = end + 1;
        chunk.lines += 1;
        let line_no = chunk.lines;
        if line.last() == Some(&b'\\') {
            // Continuation: join the physical lines with a space (rare, so it may allocate).
            joined.clear();
            joined.extend_from_slice(&line[..line.len() - 1]);
            while pos < bytes.len() {
                let end = memchr::memchr(b'\n', &bytes[pos..]).map_or(bytes.len(), |i| pos + i);
                let next = trim_end(&bytes[pos..end]);
                pos = end + 1;
                chunk.lines += 1;
                joined.push(b' ');
                match next.strip_suffix(b"\\") {
                    Some(head) => joined.extend_from_slice(head),
                    None => {
                        joined.extend_from_slice(next);
                        break;
                    }
                }
            }
            chunk.statement(&joined, line_no)?;
        } else {
            chunk.statement(line, line_no)?;
        }
    }
    Ok(chunk)
}

impl Chunk<'_> {
    fn malformed(&self, line: u64, message: impl Into<String>) -> ChunkFail {
        ChunkFail::Error(MeshError::malformed(
            self.path,
            Location::Line(line),
            message,
        ))
    }

    fn statement(&mut self, line: &[u8], line_no: u64) -> ChunkResult<()> {
        let start = skip_space(line, 0);
        if start == line.len() || line[start] == b'#' {
            return Ok(());
        }
        let kw_end = token_end(line, start);
        let keyword = &line[start..kw_end];
        let rest = &line[kw_end..];
        match keyword {
            b"v" => self.vertex(rest, line_no),
            b"vt" => self.texcoord(rest, line_no),
            b"vn" => self.normal(rest, line_no),
            b"f" => self.face(rest, line_no),
            b"usemtl" => {
                let name = text_argument(rest);
                if name.is_empty() {
                    return Err(self.malformed(line_no, "usemtl without a material name"));
                }
                let face = self.out.faces.len();
                self.out.usemtl.push((face, name));
                Ok(())
            }
            b"mtllib" => {
                let names = text_argument(rest);
                if names.is_empty() {
                    return Err(self.malformed(line_no, "mtllib without a file name"));
                }
                self.out
                    .mtllibs
                    .push((line_no, texture::normalise_name(&names)));
                Ok(())
            }
            b"o" | b"g" | b"s" | b"mg" => Ok(()),
            _ if keyword
                .first()
                .is_some_and(|b| b.is_ascii_alphabetic() || *b == b'_')
                && keyword
                    .iter()
                    .all(|b| b.is_ascii_alphanumeric() || *b == b'_') =>
            {
                // `l`, `p`, free-form geometry (`vp`, `curv`, ...), render attributes:
                // nothing scanmill uses. Counted, so `inspect` can say what was left out.
                let keyword = String::from_utf8_lossy(keyword).into_owned();
                *self.out.skipped.entry(keyword).or_default() += 1;
                Ok(())
            }
            _ => Err(self.malformed(
                line_no,
                format!(
                    "not an OBJ statement: {:?} (is this a text OBJ file?)",
                    String::from_utf8_lossy(&keyword[..keyword.len().min(16)])
                ),
            )),
        }
    }

    /// Parses up to `N` numbers after the keyword; returns how many there were.
    fn numbers<const N: usize>(
        &self,
        rest: &[u8],
        line_no: u64,
        what: &str,
    ) -> ChunkResult<([f64; N], usize)> {
        let mut values = [0.0; N];
        let mut count = 0;
        let mut i = skip_space(rest, 0);
        while i < rest.len() && rest[i] != b'#' {
            let end = token_end(rest, i);
            let token = &rest[i..end];
            if count == N {
                return Err(self.malformed(line_no, format!("{what} has more than {N} numbers")));
            }
            let value = parse_f64(token).ok_or_else(|| {
                self.malformed(
                    line_no,
                    format!("not a number: {:?}", String::from_utf8_lossy(token)),
                )
            })?;
            if !value.is_finite() {
                return Err(ChunkFail::Error(MeshError::NonFinite {
                    path: self.path.to_path_buf(),
                    at: Location::Line(line_no),
                    value: String::from_utf8_lossy(token).into_owned(),
                }));
            }
            values[count] = value;
            count += 1;
            i = skip_space(rest, end);
        }
        Ok((values, count))
    }

    fn vertex(&mut self, rest: &[u8], line_no: u64) -> ChunkResult<()> {
        let (n, count) = self.numbers::<6>(rest, line_no, "vertex")?;
        match count {
            3 | 4 => {}
            6 => {
                let c = |x: f64| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
                self.out.colors.push([c(n[3]), c(n[4]), c(n[5]), 255]);
            }
            _ => {
                return Err(self.malformed(
                    line_no,
                    format!(
                        "vertex has {count} numbers; expected x y z, x y z w or x y z r g b \
                         (file truncated?)"
                    ),
                ));
            }
        }
        self.out.positions.push(DVec3::new(n[0], n[1], n[2]));
        Ok(())
    }

    fn texcoord(&mut self, rest: &[u8], line_no: u64) -> ChunkResult<()> {
        let (n, count) = self.numbers::<3>(rest, line_no, "texture coordinate")?;
        if count == 0 {
            return Err(self.malformed(line_no, "texture coordinate without numbers"));
        }
        self.out.texcoords.push(DVec2::new(n[0], n[1]));
        Ok(())
    }

    fn normal(&mut self, rest: &[u8], line_no: u64) -> ChunkResult<()> {
        let (n, count) = self.numbers::<3>(rest, line_no, "normal")?;
        if count != 3 {
            return Err(self.malformed(
                line_no,
                format!("normal has {count} numbers, expected 3 (file truncated?)"),
            ));
        }
        self.out.normals.push(DVec3::new(n[0], n[1], n[2]));
        Ok(())
    }

    fn face(&mut self, rest: &[u8], line_no: u64) -> ChunkResult<()> {
        self.corners.clear();
        let mut i = skip_space(rest, 0);
        while i < rest.len() && rest[i] != b'#' {
            let corner = self.corner(rest, &mut i, line_no)?;
            self.corners.push(corner);
            i = skip_space(rest, i);
        }
        let n = self.corners.len();
        if n < 3 {
            return Err(self.malformed(
                line_no,
                format!(
                    "face has {n} corner{}, needs at least 3",
                    if n == 1 { "" } else { "s" }
                ),
            ));
        }
        self.out.polygons += 1;
        if n > 3 {
            self.out.triangulated += 1;
        }
        let c = &self.corners;
        for k in 1..n - 1 {
            self.out.faces.push([c[0], c[k], c[k + 1]]);
        }
        Ok(())
    }

    /// One corner: `v`, `v/vt`, `v//vn` or `v/vt/vn`.
    fn corner(&mut self, s: &[u8], i: &mut usize, line_no: u64) -> ChunkResult<Corner> {
        let bad = |this: &Self, i: usize| {
            let end = token_end(s, i);
            this.malformed(
                line_no,
                format!(
                    "bad face corner {:?}; expected v, v/vt, v//vn or v/vt/vn",
                    String::from_utf8_lossy(&s[token_start(s, i)..end])
                ),
            )
        };
        let v = parse_index(s, i).ok_or_else(|| bad(self, *i))?;
        let mut vt = None;
        let mut vn = None;
        if s.get(*i) == Some(&b'/') {
            *i += 1;
            if s.get(*i) == Some(&b'/') {
                *i += 1;
                vn = Some(parse_index(s, i).ok_or_else(|| bad(self, *i))?);
            } else {
                vt = Some(parse_index(s, i).ok_or_else(|| bad(self, *i))?);
                if s.get(*i) == Some(&b'/') {
                    *i += 1;
                    vn = Some(parse_index(s, i).ok_or_else(|| bad(self, *i))?);
                }
            }
        }
        if *i < s.len() && !is_space(s[*i]) && s[*i] != b'#' {
            return Err(bad(self, *i));
        }
        Ok(Corner {
            vertex: self.resolve(v, Kind::Vertex, line_no)?,
            texcoord: vt
                .map(|t| self.resolve(t, Kind::Texcoord, line_no))
                .transpose()?,
            normal: vn
                .map(|n| self.resolve(n, Kind::Normal, line_no))
                .transpose()?,
        })
    }

    /// Turns an index as written (1-based or negative) into a 0-based one.
    fn resolve(&mut self, written: i64, kind: Kind, line_no: u64) -> ChunkResult<Index> {
        let so_far = match kind {
            Kind::Vertex => self.out.positions.len(),
            Kind::Texcoord => self.out.texcoords.len(),
            Kind::Normal => self.out.normals.len(),
        };
        let out_of_range = |count: usize| {
            ChunkFail::Error(MeshError::IndexOutOfRange {
                path: self.path.to_path_buf(),
                at: Location::Line(line_no),
                kind: kind.name(),
                index: written,
                count,
            })
        };
        if written > 0 {
            let index = written - 1;
            if index >= Index::MAX as i64 {
                return Err(out_of_range(so_far));
            }
            let index = index as Index;
            match self.mode {
                Mode::Exact => {
                    if index as usize >= so_far {
                        self.pending.push(Pending {
                            line: line_no,
                            kind,
                            written,
                        });
                    }
                }
                Mode::Parallel => {
                    let slot = &mut self.max_index[kind as usize];
                    *slot = Some(slot.map_or(index, |m| m.max(index)));
                }
            }
            return Ok(index);
        }
        if self.mode == Mode::Parallel {
            // Zero (an error whose message needs the file's counts) or relative (needs the
            // elements before this chunk): let the sequential parse decide.
            return Err(ChunkFail::NeedSequential);
        }
        if written == 0 {
            return Err(out_of_range(so_far));
        }
        let index = so_far as i64 + written;
        if index < 0 {
            return Err(out_of_range(so_far));
        }
        Ok(index as Index)
    }

    /// Forward references must exist once the whole file has been read.
    fn check_pending(&self) -> Result<()> {
        let counts = [
            self.out.positions.len(),
            self.out.texcoords.len(),
            self.out.normals.len(),
        ];
        for p in &self.pending {
            let count = counts[p.kind as usize];
            if p.written as usize > count {
                return Err(MeshError::IndexOutOfRange {
                    path: self.path.to_path_buf(),
                    at: Location::Line(p.line),
                    kind: p.kind.name(),
                    index: p.written,
                    count,
                });
            }
        }
        Ok(())
    }
}

fn token_start(s: &[u8], mut i: usize) -> usize {
    while i > 0 && !is_space(s[i - 1]) {
        i -= 1;
    }
    i
}

/// An optionally signed decimal integer at `s[*i..]`; `None` without digits or on overflow.
#[inline]
fn parse_index(s: &[u8], i: &mut usize) -> Option<i64> {
    let mut j = *i;
    let negative = match s.get(j) {
        Some(b'-') => {
            j += 1;
            true
        }
        Some(b'+') => {
            j += 1;
            false
        }
        _ => false,
    };
    let digits_start = j;
    let mut value: i64 = 0;
    while let Some(&b) = s.get(j) {
        if !b.is_ascii_digit() {
            break;
        }
        value = value.checked_mul(10)?.checked_add((b - b'0') as i64)?;
        j += 1;
    }
    if j == digits_start {
        return None;
    }
    *i = j;
    Some(if negative { -value } else { value })
}

/// A number token as `str::parse` reads it, to the bit. The plain decimals scanners write
/// take [`plain_decimal`]'s shortcut; anything else (exponents, long mantissas, `inf`, bad
/// tokens) the standard parser.
#[inline]
fn parse_f64(token: &[u8]) -> Option<f64> {
    plain_decimal(token).or_else(|| std::str::from_utf8(token).ok()?.parse().ok())
}

/// Powers of ten exactly representable in `f64`.
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// `[+-]digits[.digits]` (or `.digits`) whose digits, read as one integer `m`, are at most
/// 2^53, with at most 22 after the point: then `m` and `10^k` are exact in `f64` and
/// `m / 10^k` is one correctly rounded division, which is the correctly rounded value of
/// the decimal (Clinger's fast path, the one the standard parser takes first as well).
/// `None` for any other token, which the caller hands to the standard parser. Most of a
/// scan's text is such numbers (`-12.345678`), and this skips the UTF-8 check and the
/// general grammar for them.
#[inline]
fn plain_decimal(token: &[u8]) -> Option<f64> {
    let (negative, digits) = match token.split_first()? {
        (b'-', rest) => (true, rest),
        (b'+', rest) => (false, rest),
        _ => (false, token),
    };
    let mut mantissa: u64 = 0;
    let mut count = 0;
    let mut fraction = None;
    for (i, &b) in digits.iter().enumerate() {
        match b {
            b'0'..=b'9' => {
                count += 1;
                if count > 19 {
                    return None;
                }
                mantissa = mantissa * 10 + u64::from(b - b'0');
            }
            b'.' if fraction.is_none() => fraction = Some(i),
            _ => return None,
        }
    }
    let after_point = fraction.map_or(0, |i| digits.len() - i - 1);
    if count == 0 || mantissa > 1 << 53 || after_point >= POW10.len() {
        return None;
    }
    let value = mantissa as f64 / POW10[after_point];
    Some(if negative { -value } else { value })
}

/// The rest of a statement as text, comments stripped, trimmed.
fn text_argument(rest: &[u8]) -> String {
    let rest = match memchr::memchr(b'#', rest) {
        Some(h) => &rest[..h],
        None => rest,
    };
    String::from_utf8_lossy(rest).trim().to_string()
}

#[cfg(test)]
mod tests {
    use super::super::*;
    use super::*;

    fn opts() -> LoadOptions {
        LoadOptions {
            check_textures: false,
            ..Default::default()
        }
    }

    fn geometry(text: &str) -> Result<Geometry> {
        parse_geometry_in(Path::new("t.obj"), text.as_bytes(), 1)
    }

    fn corner(v: u32, t: Option<u32>, n: Option<u32>) -> Corner {
        Corner {
            vertex: v,
            texcoord: t,
            normal: n,
        }
    }

    fn line_of(e: &MeshError) -> Option<u64> {
        match e {
            MeshError::Malformed {
                at: Location::Line(n),
                ..
            }
            | MeshError::NonFinite {
                at: Location::Line(n),
                ..
            }
            | MeshError::IndexOutOfRange {
                at: Location::Line(n),
                ..
            } => Some(*n),
            _ => None,
        }
    }

    const QUAD: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvn 0 0 1\n";

    #[test]
    fn corner_forms_mix_and_negative_indices_resolve() {
        let g = geometry(&format!("{QUAD}f 1 2/1 3//1 4/2/1\nf -4 -3 -2\n")).unwrap();
        assert_eq!(g.polygons, 2);
        assert_eq!(g.triangulated, 1);
        assert_eq!(
            g.faces[0],
            [
                corner(0, None, None),
                corner(1, Some(0), None),
                corner(2, None, Some(0))
            ]
        );
        assert_eq!(g.faces[1][2], corner(3, Some(1), Some(0)));
        assert_eq!(
            g.faces[2],
            [
                corner(0, None, None),
                corner(1, None, None),
                corner(2, None, None)
            ]
        );
    }

    /// The shortcut reads every token as the standard parser does, to the bit, and leaves
    /// to it what it cannot read exactly.
    #[test]
    fn plain_decimals_read_as_the_standard_parser_reads_them() {
        let mut tokens: Vec<String> = [
            "0",
            "-0",
            "+0",
            "0.0",
            "-0.0",
            "1.",
            ".5",
            "-.5",
            "+.25",
            "00012.3400",
            "7",
            "9007199254740992",
            "9007199254740993",
            "-9007199254740992.0",
            "1234567890123456789",
            "12345678901234567890",
            "0.1",
            "0.2",
            "0.3",
            "0.0000000000000000000001",
            "0.00000000000000000000001",
            "3.141592653589793",
            "2.718281828459045",
            "1e5",
            "1E-3",
            "-2.5e+10",
            "inf",
            "-inf",
            "NaN",
            ".",
            "-",
            "+",
            "",
            "1.2.3",
            "1-2",
            "--1",
            "1,5",
            "0x10",
            " 1",
            "１",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        for _ in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let digits = (x % 19) as usize + 1;
            let point = (x >> 8) as usize % (digits + 2);
            let mantissa = (x >> 16) % 10u64.pow(digits as u32);
            let mut t = format!("{mantissa:0digits$}");
            if point <= digits {
                t.insert(point, '.');
            }
            if x & 1 == 1 {
                t.insert(0, '-');
            }
            tokens.push(t);
            // And what scanners write: a float printed with 6 or 9 decimals.
            let v = f64::from_bits(x) % 1e4;
            if v.is_finite() {
                tokens.push(format!("{v:.6}"));
                tokens.push(format!("{v:.9}"));
            }
        }
        let mut shortcut = 0;
        for t in &tokens {
            let standard: Option<f64> = t.parse().ok();
            let got = parse_f64(t.as_bytes());
            assert_eq!(got.map(f64::to_bits), standard.map(f64::to_bits), "{t:?}");
            shortcut += usize::from(plain_decimal(t.as_bytes()).is_some());
        }
        // Most tokens take the shortcut (else this would test only the standard parser).
        assert!(
            shortcut > tokens.len() * 9 / 10,
            "{shortcut} of {}",
            tokens.len()
        );
    }

    #[test]
    fn byte_order_mark_is_skipped() {
        let b = parse(
            Path::new("t.obj"),
            b"\xEF\xBB\xBFv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            &opts(),
        )
        .unwrap();
        assert_eq!(b.positions.len(), 3);
    }

    #[test]
    fn polygons_are_fans() {
        let g = geometry("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv -1 1 0\nf 1 2 3 4 5\n").unwrap();
        let tris: Vec<[u32; 3]> = g.faces.iter().map(|f| f.map(|c| c.vertex)).collect();
        assert_eq!(tris, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
        assert_eq!(g.triangulated, 1);
    }

    #[test]
    fn continuation_crlf_comments_and_skipped_statements() {
        let text = "# c\r\nv 0 0 0 # inline\r\nv 1 \\\r\n 0 0\r\nv 0 1 0\r\no x\r\ng y\r\ns 1\r\n\
                    l 1 2\r\np 1\r\np 2\r\nvp 0.5\r\nf 1 2 \\\r\n3\r\nv 9 9 9";
        let g = geometry(text).unwrap();
        assert_eq!(g.positions.len(), 4);
        assert_eq!(g.positions[1], DVec3::new(1.0, 0.0, 0.0));
        assert_eq!(g.faces.len(), 1);
        assert_eq!(g.skipped.get("l"), Some(&1));
        assert_eq!(g.skipped.get("p"), Some(&2));
        assert_eq!(g.skipped.get("vp"), Some(&1));
    }

    #[test]
    fn continuation_error_names_the_first_line() {
        let e = geometry("v 0 0 0\nf 1 \\\n 2\n").unwrap_err();
        assert_eq!(line_of(&e), Some(2), "{e}");
    }

    #[test]
    fn colours_kept_only_when_every_vertex_has_them() {
        let g = geometry("v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 0.5\nf 1 2 3\n").unwrap();
        assert_eq!(
            g.colors,
            vec![[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 128, 255]]
        );
        let b = parse(
            Path::new("t.obj"),
            b"v 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            &opts(),
        )
        .unwrap();
        assert!(b.colors.is_empty());
    }

    #[test]
    fn forward_references_are_allowed() {
        let g = geometry("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
        assert_eq!(g.faces.len(), 1);
        let e = geometry("f 1 2 4\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap_err();
        assert!(
            matches!(
                e,
                MeshError::IndexOutOfRange {
                    index: 4,
                    count: 3,
                    ..
                }
            ),
            "{e}"
        );
        assert_eq!(line_of(&e), Some(1));
    }

    #[test]
    fn bad_indices_name_the_line_and_value() {
        // (faces, the index refused, of what, how many there are, on which line)
        for (faces, bad, what, there_are, line) in [
            ("f 1 2 3\nf 1 0 3\n", 0, "vertex", 4, 9),
            ("f 1 2 -5\n", -5, "vertex", 4, 8),
            ("f 1/3 2 3\n", 3, "texture coordinate", 2, 8),
        ] {
            let e = geometry(&format!("{QUAD}{faces}")).unwrap_err();
            assert!(
                matches!(
                    e,
                    MeshError::IndexOutOfRange { index, kind, count, .. }
                        if index == bad && kind == what && count == there_are
                ),
                "{faces}: {e}"
            );
            assert_eq!(line_of(&e), Some(line), "{faces}");
        }
        let e = geometry(&format!("{QUAD}f 1 2 99999999999999999999\n")).unwrap_err();
        assert!(matches!(e, MeshError::Malformed { .. }), "{e}");
    }

    #[test]
    fn malformed_lines() {
        for (text, needle) in [
            ("f 1 2\n", "2 corners"),
            ("f 1\n", "1 corner,"),
            ("f 1 2 3/\n", "bad face corner"),
            ("f 1 2 3//\n", "bad face corner"),
            ("f 1 2 x\n", "bad face corner"),
            ("f 1 2 3/1/1/1\n", "bad face corner"),
            ("v 1.0 2.\n", "2 numbers"),
            ("v 1 2 3 4 5\n", "5 numbers"),
            ("v 1 2 x\n", "not a number"),
            ("vn 1 2\n", "2 numbers"),
            ("vt\n", "without numbers"),
            ("usemtl\n", "without a material name"),
            ("\u{1}\u{2}garbage\n", "not an OBJ statement"),
        ] {
            let e = geometry(&format!("{QUAD}{text}")).unwrap_err();
            assert!(matches!(e, MeshError::Malformed { .. }), "{text}: {e}");
            assert!(e.to_string().contains(needle), "{text}: {e}");
            assert!(e.to_string().contains("t.obj: line 8"), "{text}: {e}");
        }
    }

    #[test]
    fn non_finite_coordinates() {
        for v in ["nan", "inf", "-Infinity", "1e999"] {
            let e = geometry(&format!("v 0 {v} 0\n")).unwrap_err();
            assert!(matches!(e, MeshError::NonFinite { .. }), "{v}: {e}");
            assert_eq!(line_of(&e), Some(1));
        }
    }

    #[test]
    fn no_faces_is_no_triangles() {
        for text in ["", "v 0 0 0\nv 1 0 0\n", "# nothing\n"] {
            let e = parse(Path::new("t.obj"), text.as_bytes(), &opts()).unwrap_err();
            assert!(matches!(e, MeshError::NoTriangles { .. }), "{e}");
        }
    }

    #[test]
    fn usemtl_without_library_and_default_material() {
        let text = format!(
            "{QUAD}f 1 2 3\nusemtl skin\nf 1 3 4\nusemtl eye\nf 2 3 4\nusemtl skin\nf 1 2 4\n"
        );
        let b = parse(Path::new("t.obj"), text.as_bytes(), &opts()).unwrap();
        let names: Vec<&str> = b.materials.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, vec![DEFAULT_MATERIAL, "skin", "eye"]);
        assert_eq!(b.face_materials, vec![0, 1, 2, 1]);
        assert!(b.materials.iter().all(|m| m.diffuse_texture.is_none()));
    }

    /// A file big enough to be split, with continuations and usemtl across the pieces.
    fn big_text(faces: usize) -> String {
        let mut s = String::new();
        for i in 0..faces + 2 {
            s.push_str(&format!("v {i} {} 0.25\nvt 0.{i} 0.5\n", i * i % 7));
        }
        for i in 0..faces {
            if i % 1000 == 0 {
                s.push_str(&format!("usemtl m{}\n", i / 3000));
            }
            s.push_str(&format!(
                "f {}/{} {}/{} \\\n {}/{}\n",
                i + 1,
                i + 1,
                i + 2,
                i + 2,
                i + 3,
                i + 3
            ));
        }
        s
    }

    #[test]
    fn parallel_parse_equals_sequential() {
        let text = big_text(20_000);
        let seq = parse_geometry_in(Path::new("t.obj"), text.as_bytes(), 1).unwrap();
        for chunks in [2, 3, 7] {
            let par = parse_geometry_in(Path::new("t.obj"), text.as_bytes(), chunks).unwrap();
            assert_eq!(par.positions, seq.positions);
            assert_eq!(par.texcoords, seq.texcoords);
            assert_eq!(par.faces, seq.faces);
            assert_eq!(par.usemtl, seq.usemtl);
            assert_eq!(par.polygons, seq.polygons);
        }
    }

    #[test]
    fn parallel_parse_errors_match_sequential() {
        let good = big_text(20_000);
        let lines = good.lines().count() as u64;
        for bad in [
            format!("{good}f 1 2 {}\n", 30_000),
            format!("{good}f 1 2 -1\nf 1 2 0\n"),
            format!("{good}v 1 nan 2\n"),
            format!("{good}f 1 2\n"),
        ] {
            let seq = parse_geometry_in(Path::new("t.obj"), bad.as_bytes(), 1).unwrap_err();
            let par = parse_geometry_in(Path::new("t.obj"), bad.as_bytes(), 4).unwrap_err();
            assert_eq!(seq.to_string(), par.to_string());
            assert!(line_of(&par).unwrap() > lines, "{par}");
        }
        // Relative indices in a later piece: the sequential parse takes over.
        let relative = format!("{good}f -1 -2 -3\n");
        let seq = parse_geometry_in(Path::new("t.obj"), relative.as_bytes(), 1).unwrap();
        let par = parse_geometry_in(Path::new("t.obj"), relative.as_bytes(), 4).unwrap();
        assert_eq!(seq.faces, par.faces);
    }

    #[test]
    fn split_never_cuts_after_a_continuation() {
        let text = "v 1 \\\n2 3\n".repeat(100);
        for piece in split_chunks(text.as_bytes(), 9) {
            assert!(piece.starts_with(b"v 1"));
        }
    }
}
