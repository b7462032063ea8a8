//! Texture files: resolving the names a scan gives, refusing paths that leave the scan's
//! folder, checking that images decode within the job's pixel budget, and choosing safe
//! names for copies on output.
//!
//! Names: every file name a scan writes (OBJ `mtllib`, MTL `map_*`/`bump`/`disp`/...,
//! PLY `comment TextureFile`) goes through [`normalise_name`] once, where it is parsed, and
//! through [`resolve_in_scan`] once, when it is loaded; the model keeps the resolved path and
//! writers copy exactly that file.
//!
//! Checking an image (when `LoadOptions::check_textures`): the header gives the size, which
//! is checked against the job's pixel budget before anything is decoded; then the whole image
//! is decoded, once per distinct file however many materials name it. A full decode costs
//! 4–160 ms per image on the lab's data and catches corrupt compressed data, which a header
//! read does not. The JPEG decoder is lenient: it decodes a JPEG cut in half without
//! complaint (grey bottom half), so a JPEG must also end its scan data with an EOI marker; a
//! PNG cut short fails to decode.

use super::error::{MeshError, Result};
use super::files;
use super::limits::{InputLimits, Limit};
use super::model::Texture;
use rayon::prelude::*;
use std::borrow::Cow;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Component, Path, PathBuf};

/// A file name found in a scan, resolved inside the scan's folder.
#[derive(Debug, Clone)]
pub struct ResolvedFile {
    /// The file to read: canonical (symlinks resolved), inside the scan's folder, a regular
    /// file within its size cap when it was checked.
    pub path: PathBuf,
}

/// The one rule for file names written in a scan's files, applied where they are parsed:
/// `\` is a folder separator. Scans exported on Windows write `tex\a.png`; a Unix file name
/// with a literal backslash is far rarer, and deciding the meaning of `\` once is what keeps
/// the name that is checked and the file that is later copied the same.
pub fn normalise_name(raw: &str) -> String {
    raw.replace('\\', "/")
}

/// Canonical form of the scan's folder (the folder of the OBJ). Falls back to the folder as
/// given if it cannot be canonicalised (then any later check fails safe: nothing is inside).
pub fn scan_folder(obj_path: &Path) -> PathBuf {
    let dir = folder_of(obj_path);
    dir.canonicalize().unwrap_or(dir)
}

/// The folder a file lives in; `.` for a bare file name.
pub fn folder_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// What a scan's file names another file as: said when such a name leads outside the scan's
/// folder or to no file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Referenced {
    /// An image (`map_Kd`, PLY `TextureFile`, a glTF image).
    Texture,
    /// An OBJ's `mtllib`.
    MaterialLibrary,
    /// A glTF buffer.
    Buffer,
}

impl std::fmt::Display for Referenced {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Referenced::Texture => "texture",
            Referenced::MaterialLibrary => "material library",
            Referenced::Buffer => "buffer",
        })
    }
}

/// Resolves `name`, a file of the given role as written in `referrer` (an MTL, OBJ, PLY or
/// glTF; already passed through [`normalise_name`]), against `base_dir` (the referrer's
/// folder), and checks that the result stays inside `scan_dir` (canonical): `..` that climbs
/// out, an absolute path elsewhere, or a symlink that resolves outside are
/// [`MeshError::PathEscapes`]; a FIFO, device or folder is [`MeshError::SpecialFile`]
/// (refused without opening it); a file above `cap` (the value of `limit`) is
/// [`MeshError::TooLarge`]; a file that does not exist is [`MeshError::MissingFile`]. The
/// errors name the role ("material library path … resolves outside the scan's folder").
pub fn resolve_in_scan(
    scan_dir: &Path,
    base_dir: &Path,
    (name, role): (&str, Referenced),
    referrer: &Path,
    (cap, limit): (u64, Limit),
) -> Result<ResolvedFile> {
    let escapes = |resolved: PathBuf| MeshError::PathEscapes {
        path: referrer.to_path_buf(),
        role,
        name: name.to_string(),
        resolved,
    };
    let missing = |looked: &Path| MeshError::MissingFile {
        path: referrer.to_path_buf(),
        role,
        name: name.to_string(),
        looked: looked.to_path_buf(),
    };
    let name_path = Path::new(name);
    // Where the name leads before symlinks, for the lexical check and for messages.
    let base_real = base_dir
        .canonicalize()
        .map_err(|_| missing(&base_dir.join(name_path)))?;
    let joined = base_real.join(name_path);
    let lexical = normalise(&joined).ok_or_else(|| escapes(joined.clone()))?;
    // Lexical check first, so that a path elsewhere is refused whether or not it exists.
    if !lexical.starts_with(scan_dir) {
        return Err(escapes(lexical));
    }
    // Symlinks: the real file must be inside the real scan folder.
    let real = lexical.canonicalize().map_err(|_| missing(&lexical))?;
    if !real.starts_with(scan_dir) {
        return Err(escapes(real));
    }
    let meta = std::fs::metadata(&real).map_err(|_| missing(&real))?;
    if let Some(kind) = files::special_kind(&meta) {
        return Err(MeshError::SpecialFile { path: real, kind });
    }
    if meta.len() > cap {
        return Err(files::too_large(
            &real,
            format!("file size {} bytes", meta.len()),
            limit,
            cap,
        ));
    }
    Ok(ResolvedFile { path: real })
}

/// Lexical normalisation: drops `.`, applies `..` (which stays at the root of an absolute
/// path, as the file system does). `None` if `..` climbs above the beginning of a relative
/// path.
fn normalise(path: &Path) -> Option<PathBuf> {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::Prefix(_) | Component::RootDir => out.push(c.as_os_str()),
            Component::CurDir => {}
            Component::ParentDir => match out.components().next_back() {
                Some(Component::Normal(_)) => {
                    out.pop();
                }
                Some(Component::RootDir) => {}
                _ => return None,
            },
            Component::Normal(n) => out.push(n),
        }
    }
    Some(out)
}

/// One image a load wants checked: the resolved file, the name as the scan wrote it and the
/// file that named it (for errors).
#[derive(Debug, Clone, Copy)]
pub struct ImageRef<'a> {
    pub path: &'a Path,
    pub name: &'a str,
    pub referrer: &'a Path,
    /// The image's bytes when it is embedded in the scan's file (then `path` is only its
    /// name; see [`Texture::embedded`]).
    pub embedded: Option<&'a [u8]>,
}

impl<'a> ImageRef<'a> {
    /// The image of texture `t`, named in `referrer`.
    pub fn of(t: &'a Texture, referrer: &'a Path) -> Self {
        ImageRef {
            path: &t.path,
            name: &t.name,
            referrer,
            embedded: t.embedded.as_ref().map(|e| &*e.0),
        }
    }
}

/// What [`check_images`] learnt: the size of every distinct image, by resolved path.
#[derive(Debug, Default)]
pub struct CheckedImages {
    pub sizes: HashMap<PathBuf, (u32, u32)>,
    /// How many images were decoded (one per distinct file).
    pub decoded: usize,
}

/// Checks the images of one load: each distinct file (by resolved path) is read once (within
/// `limits.max_file_bytes`), its header's pixel count added to the job's total, which must
/// stay within `limits.max_texture_pixels` before anything is decoded; then every distinct
/// image is decoded once, in parallel. The first failure in `images` order is the error.
pub fn check_images(images: &[ImageRef], limits: &InputLimits) -> Result<CheckedImages> {
    let mut distinct: Vec<ImageRef> = Vec::new();
    for image in images {
        if !distinct.iter().any(|d| d.path == image.path) {
            distinct.push(*image);
        }
    }
    let headers: Vec<Result<Header>> = distinct
        .par_iter()
        .map(|image| read_header(image, limits))
        .collect();
    let mut read = Vec::with_capacity(distinct.len());
    let mut pixels = 0u64;
    for (image, header) in distinct.iter().zip(headers) {
        let (bytes, (w, h)) = header?;
        pixels = pixels.saturating_add(u64::from(w) * u64::from(h));
        if pixels > limits.max_texture_pixels {
            return Err(files::too_large(
                image.path,
                format!(
                    "texture {:?} ({w}×{h}) brings the job's decoded pixels to {pixels}, which",
                    image.name
                ),
                Limit::TexturePixels,
                limits.max_texture_pixels,
            ));
        }
        read.push((image, bytes, (w, h)));
    }
    let decoded: Vec<Result<()>> = read
        .par_iter()
        .map(|(image, bytes, size)| {
            decode_bounded(bytes, *size)
                .map(drop)
                .map_err(|message| image_error(image, message))
        })
        .collect();
    let mut out = CheckedImages::default();
    for ((image, _, size), result) in read.iter().zip(decoded) {
        result?;
        out.sizes.insert(image.path.to_path_buf(), *size);
        out.decoded += 1;
    }
    Ok(out)
}

fn image_error(image: &ImageRef, message: String) -> MeshError {
    MeshError::Texture {
        path: image.referrer.to_path_buf(),
        texture: image.name.to_string(),
        message,
    }
}

/// An image file's bytes and the size its header declares.
type Header = (Vec<u8>, (u32, u32));

/// Reads an image file (within `limits.max_file_bytes`; an embedded image is copied) and
/// its size from its header.
fn read_header(image: &ImageRef, limits: &InputLimits) -> Result<Header> {
    let bytes = match image.embedded {
        Some(bytes) => bytes.to_vec(),
        None => files::read_whole(image.path, limits.max_file_bytes, Limit::FileBytes)?,
    };
    let size = image_size(&bytes).map_err(|message| image_error(image, message))?;
    Ok((bytes, size))
}

/// An image's size from its header, without decoding it. The decoder's own allocation
/// limit is lifted for this header read, so that a huge declared size is reported as such
/// and judged against the pixel budget (the decode itself is bounded in [`decode_bounded`]).
pub fn image_size(bytes: &[u8]) -> std::result::Result<(u32, u32), String> {
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| e.to_string())?;
    reader.no_limits();
    reader
        .into_dimensions()
        .map_err(|e| format!("not a readable image: {e}"))
}

/// Decodes an image whose header said `size`, allowing the decoder no more than that size
/// (a header that lies about the size cannot make it allocate more). A JPEG must end with
/// its end-of-image marker (see the module comment).
pub fn decode_bounded(
    bytes: &[u8],
    (w, h): (u32, u32),
) -> std::result::Result<image::DynamicImage, String> {
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| e.to_string())?;
    if reader.format() == Some(image::ImageFormat::Jpeg) && !jpeg_has_end(bytes) {
        return Err("JPEG ends before its end-of-image marker (file truncated?)".into());
    }
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(w);
    limits.max_image_height = Some(h);
    // 16-bit RGBA is the widest layout PNG and JPEG decode to; the decoders need a little
    // working memory beside the image.
    limits.max_alloc = Some(u64::from(w) * u64::from(h) * 8 + (64 << 20));
    reader.limits(limits);
    reader
        .decode()
        .map_err(|e| format!("image does not decode: {e}"))
}

/// Reads and decodes one image file within a pixel allowance (for users of textures after
/// loading, such as the texture metric): the file within `limits.max_file_bytes`, its
/// header's pixel count within `pixels_left`, which is reduced by it.
pub fn load_image(
    path: &Path,
    limits: &InputLimits,
    pixels_left: &mut u64,
) -> Result<image::DynamicImage> {
    let name = path.display().to_string();
    let image = ImageRef {
        path,
        name: &name,
        referrer: path,
        embedded: None,
    };
    load_bounded(&image, limits, pixels_left)
}

/// [`load_image`] for a texture, whether it is a file or embedded in the scan's file.
pub fn load_texture(
    t: &Texture,
    limits: &InputLimits,
    pixels_left: &mut u64,
) -> Result<image::DynamicImage> {
    load_bounded(&ImageRef::of(t, &t.path), limits, pixels_left)
}

/// A texture's bytes as they came: an embedded image's, or the file's (read within
/// `limits.max_file_bytes`). Writers copy these.
pub fn texture_bytes<'t>(t: &'t Texture, limits: &InputLimits) -> Result<Cow<'t, [u8]>> {
    match &t.embedded {
        Some(e) => Ok(Cow::Borrowed(&e.0)),
        None => files::read_whole(&t.path, limits.max_file_bytes, Limit::FileBytes).map(Cow::Owned),
    }
}

fn load_bounded(
    image: &ImageRef,
    limits: &InputLimits,
    pixels_left: &mut u64,
) -> Result<image::DynamicImage> {
    let (bytes, (w, h)) = read_header(image, limits)?;
    let pixels = u64::from(w) * u64::from(h);
    if pixels > *pixels_left {
        return Err(files::too_large(
            image.path,
            format!(
                "texture ({w}×{h}) brings the decoded pixels above what is left ({pixels_left}) of"
            ),
            Limit::TexturePixels,
            limits.max_texture_pixels,
        ));
    }
    *pixels_left -= pixels;
    decode_bounded(&bytes, (w, h)).map_err(|message| image_error(image, message))
}

/// True if a JPEG's first scan is followed, somewhere, by an EOI marker (FF D9).
/// Walks the marker segments up to the first SOS (so an EXIF thumbnail's own EOI does not
/// count), then searches the rest; inside entropy-coded data an FF byte is always followed
/// by 00 or a restart marker, so FF D9 there is the real end.
fn jpeg_has_end(b: &[u8]) -> bool {
    if b.len() < 4 || b[0] != 0xFF || b[1] != 0xD8 {
        return false;
    }
    let mut i = 2;
    loop {
        if i + 1 >= b.len() || b[i] != 0xFF {
            return false;
        }
        let marker = b[i + 1];
        match marker {
            0xFF => i += 1, // fill byte
            0xD9 => return false,
            0x01 | 0xD0..=0xD7 => i += 2,
            _ => {
                if i + 3 >= b.len() {
                    return false;
                }
                let len = u16::from_be_bytes([b[i + 2], b[i + 3]]) as usize;
                i += 2 + len;
                if marker == 0xDA {
                    break;
                }
            }
        }
    }
    let rest = b.get(i..).unwrap_or(&[]);
    memchr::memmem::find(rest, &[0xFF, 0xD9]).is_some()
}

/// MTL statements whose last argument is a file (copied on output, checked on input).
pub fn is_map_statement(keyword: &str) -> bool {
    let k = keyword.to_ascii_lowercase();
    k.starts_with("map_") || matches!(k.as_str(), "bump" | "disp" | "decal" | "refl" | "norm")
}

/// Splits the arguments of a map statement (`-s 1 1 1 -clamp on my texture.png`) into the
/// options and the file name. Options take a known number of arguments (`-o/-s/-t` take up
/// to three numbers); what follows the options, spaces included, is the file name.
/// Returns `(options, file)`; `file` is empty if there is none.
pub fn split_map_arguments(args: &str) -> (&str, &str) {
    let args = args.trim();
    let tokens = token_spans(args);
    let mut i = 0;
    while i < tokens.len() {
        let tok = &args[tokens[i].0..tokens[i].1];
        let fixed = match tok {
            "-blendu" | "-blendv" | "-bm" | "-boost" | "-cc" | "-clamp" | "-imfchan"
            | "-texres" | "-type" => Some(1),
            "-mm" => Some(2),
            "-o" | "-s" | "-t" => None,
            _ => break,
        };
        i += 1;
        match fixed {
            Some(n) => i += n,
            None => {
                // Up to three numbers; the first is required.
                let mut taken = 0;
                while taken < 3
                    && i < tokens.len()
                    && args[tokens[i].0..tokens[i].1].parse::<f64>().is_ok()
                    && (taken == 0 || i + 1 < tokens.len())
                {
                    i += 1;
                    taken += 1;
                }
            }
        }
    }
    if i >= tokens.len() {
        return (args, "");
    }
    let start = tokens[i].0;
    (args[..start].trim_end(), &args[start..])
}

fn token_spans(s: &str) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut start = None;
    for (i, c) in s.char_indices() {
        if c.is_whitespace() {
            if let Some(st) = start.take() {
                spans.push((st, i));
            }
        } else if start.is_none() {
            start = Some(i);
        }
    }
    if let Some(st) = start {
        spans.push((st, s.len()));
    }
    spans
}

/// A name for a copied file that stays inside the output folder (the name the scan wrote,
/// already normalised, is only a wish): `.` and `..` parts and any root or drive are
/// dropped; an absolute name keeps only its file name; control characters and `\\` become
/// `_` (an output MTL must stay one statement per line); a leading `-` gets a `_` before it
/// (it would read as an option of the map statement). `None` if nothing usable remains.
/// [`OutputNames`] then keeps the result apart from every other generated file.
pub fn sanitise_output_name(name: &str) -> Option<String> {
    let absolute = name.starts_with('/') || name.as_bytes().get(1) == Some(&b':');
    let mut parts: Vec<String> = Vec::new();
    for part in name.split('/') {
        match part {
            "" | "." => {}
            ".." => {
                parts.pop();
            }
            p if p.ends_with(':') => {} // a drive, `C:`
            p => parts.push(
                p.chars()
                    .map(|c| if c.is_control() || c == '\\' { '_' } else { c })
                    .collect(),
            ),
        }
    }
    if absolute {
        parts = parts.split_off(parts.len().saturating_sub(1));
    }
    let joined = parts.join("/");
    match joined.chars().next() {
        None => None,
        Some('-') => Some(format!("_{joined}")),
        Some(_) => Some(joined),
    }
}

/// Chooses output names for copied files, keeping every generated name unique: the same
/// source keeps one name; a different source asking for a taken name gets `stem_2.ext`,
/// `stem_3.ext`, ...; a name whose folder would be a reserved or copied file is placed in the
/// output folder itself. Compared lower-cased, so that case-insensitive file systems are
/// safe too.
#[derive(Debug, Default)]
pub struct OutputNames {
    /// Lower-cased file name → its source (`None` for reserved names).
    taken: BTreeMap<String, Option<PathBuf>>,
    /// Lower-cased folders that copies create.
    folders: BTreeSet<String>,
}

impl OutputNames {
    /// Reserves a name (the mesh and MTL themselves, a sidecar, a preview) that no copy may
    /// use, whatever its source is called.
    pub fn reserve(&mut self, name: &str) {
        self.taken.insert(name.to_lowercase(), None);
    }

    /// The output name for `source`, wanted as `wanted` (the name the scan wrote; it is
    /// sanitised here, see [`sanitise_output_name`]).
    pub fn name_for(&mut self, wanted: &str, source: &Path) -> String {
        let source = source
            .canonicalize()
            .unwrap_or_else(|_| source.to_path_buf());
        let file_name = || {
            source
                .file_name()
                .and_then(|n| sanitise_output_name(&n.to_string_lossy()))
                .unwrap_or_else(|| "texture".into())
        };
        let mut wanted = sanitise_output_name(wanted).unwrap_or_else(file_name);
        if !self.folders_free(&wanted) {
            wanted = wanted
                .rsplit('/')
                .next()
                .map_or_else(file_name, str::to_string);
        }
        let (stem, ext) = match wanted.rfind('.') {
            Some(dot) if dot > wanted.rfind('/').map_or(0, |s| s + 1) => {
                (&wanted[..dot], &wanted[dot..])
            }
            _ => (wanted.as_str(), ""),
        };
        let mut n = 1;
        loop {
            let candidate = if n == 1 {
                wanted.clone()
            } else {
                format!("{stem}_{n}{ext}")
            };
            let key = candidate.to_lowercase();
            match self.taken.get(&key) {
                None if !self.folders.contains(&key) => {
                    for (i, _) in key.match_indices('/') {
                        self.folders.insert(key[..i].to_string());
                    }
                    self.taken.insert(key, Some(source.clone()));
                    return candidate;
                }
                Some(Some(s)) if *s == source => return candidate,
                _ => n += 1,
            }
        }
    }

    /// Whether none of the folders of `name` is a file name already given out.
    fn folders_free(&self, name: &str) -> bool {
        let key = name.to_lowercase();
        key.match_indices('/')
            .all(|(i, _)| !self.taken.contains_key(&key[..i]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn map_arguments_split_options_from_names_with_spaces() {
        assert_eq!(split_map_arguments("tex.png"), ("", "tex.png"));
        assert_eq!(
            split_map_arguments("-s 1 1 1 my tex.png"),
            ("-s 1 1 1", "my tex.png")
        );
        assert_eq!(
            split_map_arguments("-clamp on -bm 0.5 n.png"),
            ("-clamp on -bm 0.5", "n.png")
        );
        assert_eq!(split_map_arguments("-o 0.5 1.png"), ("-o 0.5", "1.png"));
        assert_eq!(split_map_arguments("-s 2"), ("-s 2", ""));
        assert_eq!(split_map_arguments("  "), ("", ""));
    }

    #[test]
    fn output_names_stay_inside() {
        assert_eq!(sanitise_output_name("a.png").as_deref(), Some("a.png"));
        assert_eq!(sanitise_output_name("../x.png").as_deref(), Some("x.png"));
        assert_eq!(
            sanitise_output_name("tex\\a\nb.png").as_deref(),
            Some("tex_a_b.png")
        );
        assert_eq!(sanitise_output_name("-o").as_deref(), Some("_-o"));
        assert_eq!(
            sanitise_output_name("/etc/passwd").as_deref(),
            Some("passwd")
        );
        assert_eq!(
            sanitise_output_name(&normalise_name("C:\\scans\\t.jpg")).as_deref(),
            Some("t.jpg")
        );
        assert_eq!(
            sanitise_output_name("./a/../../b.png").as_deref(),
            Some("b.png")
        );
        assert_eq!(sanitise_output_name(".."), None);
    }

    #[test]
    fn output_names_are_unique() {
        let mut names = OutputNames::default();
        names.reserve("scan.obj");
        assert_eq!(names.name_for("t.png", Path::new("/a/t.png")), "t.png");
        assert_eq!(names.name_for("t.png", Path::new("/a/t.png")), "t.png");
        assert_eq!(names.name_for("T.png", Path::new("/b/t.png")), "T_2.png");
        assert_eq!(names.name_for("scan.obj", Path::new("/b/x")), "scan_2.obj");
    }

    #[test]
    fn generated_names_never_collide_with_reserved_ones() {
        let mut names = OutputNames::default();
        for reserved in [
            "scan.obj",
            "scan.mtl",
            "scan.scanmill.json",
            "scan.preview.png",
        ] {
            names.reserve(reserved);
        }
        let a = names.name_for("scan.scanmill.json", Path::new("/a/1"));
        let b = names.name_for("SCAN.preview.png", Path::new("/a/2"));
        let c = names.name_for("scan.preview.png/x.png", Path::new("/a/3"));
        let d = names.name_for("x.png", Path::new("/a/4"));
        let e = names.name_for("sub/y.png", Path::new("/a/5"));
        let f = names.name_for("sub", Path::new("/a/6"));
        assert_eq!(
            [a, b, c, d, e, f],
            [
                "scan.scanmill_2.json",
                "SCAN.preview_2.png",
                "x.png",
                "x_2.png",
                "sub/y.png",
                "sub_2"
            ]
        );
    }

    #[test]
    fn jpeg_end_marker() {
        let ok = [
            0xFF, 0xD8, 0xFF, 0xDA, 0x00, 0x02, 0x12, 0xFF, 0x00, 0xFF, 0xD9,
        ];
        assert!(jpeg_has_end(&ok));
        assert!(!jpeg_has_end(&ok[..9]));
        assert!(!jpeg_has_end(b"not a jpeg"));
    }
}
