//! Texture files: resolving the names an MTL gives, refusing paths that leave the scan's
//! folder, checking that images decode, and choosing safe names for copies on output.
//!
//! Checking an image (when `LoadOptions::check_textures`): the header gives the size, then
//! the whole image is decoded. A full decode costs 4–160 ms per image on the lab's data
//! (1024² PNG 4 ms, 4096² PNG 86 ms, 4096² JPEG 160 ms, release, one core) and catches
//! corrupt compressed data, which a header read does not. The JPEG decoder is lenient: it
//! decodes a JPEG cut in half without complaint (grey bottom half), so a JPEG must also
//! end its scan data with an EOI marker; a PNG cut short fails to decode.

use super::error::{MeshError, Result};
use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};

/// A file name found in an MTL, resolved against the scan's folder.
#[derive(Debug, Clone)]
pub struct ResolvedFile {
    /// The file to read (inside the scan's folder, lexically normalised, not canonical).
    pub path: PathBuf,
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

/// Resolves `name` (as written in `referrer`, an MTL or OBJ) against `base_dir` (the
/// referrer's folder), and checks that the result stays inside `scan_dir` (canonical):
/// `..` that climbs out, an absolute path elsewhere, or a symlink that resolves outside are
/// [`MeshError::PathEscapes`]. A file that does not exist is [`MeshError::Texture`].
pub fn resolve_in_scan(
    scan_dir: &Path,
    base_dir: &Path,
    name: &str,
    referrer: &Path,
) -> Result<ResolvedFile> {
    let escapes = || MeshError::PathEscapes {
        path: referrer.to_path_buf(),
        texture: name.to_string(),
    };
    let missing = |looked: &Path| MeshError::Texture {
        path: referrer.to_path_buf(),
        texture: name.to_string(),
        message: format!("file not found (looked for {})", looked.display()),
    };
    // Names written on Windows use `\`; a literal backslash in a Unix file name is far
    // rarer than a Windows-exported MTL, so `\` is a separator unless the literal exists.
    let literal = base_dir.join(name);
    let name_path = if name.contains('\\') && !literal.exists() {
        PathBuf::from(name.replace('\\', "/"))
    } else {
        PathBuf::from(name)
    };
    let candidate = if name_path.is_absolute() {
        let lexical = normalise(&name_path).ok_or_else(escapes)?;
        // Lexical check first, so that a path elsewhere is refused whether or not it exists.
        let real = lexical.canonicalize().unwrap_or_else(|_| lexical.clone());
        if !real.starts_with(scan_dir) {
            return Err(escapes());
        }
        lexical
    } else {
        // Work relative to the scan folder, so that `..` is judged lexically, whether or
        // not the file exists, and however the folder itself was named (symlinks, `./`).
        let base_real = base_dir.canonicalize().map_err(|_| missing(&literal))?;
        let base_rel = base_real.strip_prefix(scan_dir).map_err(|_| escapes())?;
        let rel = normalise(&base_rel.join(&name_path)).ok_or_else(escapes)?;
        scan_dir.join(rel)
    };
    if !candidate.is_file() {
        return Err(missing(&candidate));
    }
    // Symlinks: the real file must be inside the real scan folder.
    let real = candidate.canonicalize().map_err(|_| missing(&candidate))?;
    if !real.starts_with(scan_dir) {
        return Err(escapes());
    }
    Ok(ResolvedFile { path: candidate })
}

/// Lexical normalisation: drops `.`, applies `..`. `None` if `..` climbs above the start
/// (the root of an absolute path, the beginning of a relative one).
fn normalise(path: &Path) -> Option<PathBuf> {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::Prefix(_) | Component::RootDir => out.push(c.as_os_str()),
            Component::CurDir => {}
            Component::ParentDir => {
                if !matches!(out.components().next_back(), Some(Component::Normal(_))) || !out.pop()
                {
                    return None;
                }
            }
            Component::Normal(n) => out.push(n),
        }
    }
    Some(out)
}

/// Opens an image, learns its size and checks that it decodes completely (see the module
/// comment for why a full decode). Errors name the texture and the MTL.
pub fn check_image(path: &Path, name: &str, referrer: &Path) -> Result<(u32, u32)> {
    let fail = |message: String| MeshError::Texture {
        path: referrer.to_path_buf(),
        texture: name.to_string(),
        message,
    };
    let bytes =
        std::fs::read(path).map_err(|e| fail(format!("cannot read {}: {e}", path.display())))?;
    let reader = image::ImageReader::new(std::io::Cursor::new(&bytes[..]))
        .with_guessed_format()
        .map_err(|e| fail(format!("cannot read {}: {e}", path.display())))?;
    let format = reader.format();
    let size = reader
        .into_dimensions()
        .map_err(|e| fail(format!("not a readable image: {e}")))?;
    if format == Some(image::ImageFormat::Jpeg) && !jpeg_has_end(&bytes) {
        return Err(fail(
            "JPEG ends before its end-of-image marker (file truncated?)".into(),
        ));
    }
    image::ImageReader::new(std::io::Cursor::new(&bytes[..]))
        .with_guessed_format()
        .map_err(|e| fail(e.to_string()))?
        .decode()
        .map_err(|e| fail(format!("image does not decode: {e}")))?;
    Ok(size)
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

/// A name for a copied file that stays inside the output folder: `\` becomes `/`, `.` and
/// `..` parts and any root or drive are dropped; an absolute name keeps only its file name.
/// `None` if nothing usable remains.
pub fn sanitise_output_name(name: &str) -> Option<String> {
    let name = name.replace('\\', "/");
    let absolute = name.starts_with('/') || name.as_bytes().get(1) == Some(&b':');
    let mut parts: Vec<&str> = Vec::new();
    for part in name.split('/') {
        match part {
            "" | "." => {}
            ".." => {
                parts.pop();
            }
            p if p.ends_with(':') => {} // a drive, `C:`
            p => parts.push(p),
        }
    }
    if absolute {
        let last = parts.last()?;
        return Some((*last).to_string());
    }
    if parts.is_empty() {
        None
    } else {
        Some(parts.join("/"))
    }
}

/// Chooses output names for copied files, keeping names unique: the same source keeps one
/// name; a different source asking for a taken name gets `stem_2.ext`, `stem_3.ext`, ...
#[derive(Debug, Default)]
pub struct OutputNames {
    /// Lower-cased name → source (so that case-insensitive file systems also stay safe).
    taken: BTreeMap<String, Option<PathBuf>>,
}

impl OutputNames {
    /// Reserves names (the OBJ and MTL themselves) that no copy may use.
    pub fn reserve(&mut self, name: &str) {
        self.taken.insert(name.to_lowercase(), None);
    }

    /// The output name for `source`, wanted as `wanted` (already sanitised).
    pub fn name_for(&mut self, wanted: &str, source: &Path) -> String {
        let source = source
            .canonicalize()
            .unwrap_or_else(|_| source.to_path_buf());
        let (stem, ext) = match wanted.rfind('.') {
            Some(dot) if dot > wanted.rfind('/').map_or(0, |s| s + 1) => {
                (&wanted[..dot], &wanted[dot..])
            }
            _ => (wanted, ""),
        };
        let mut n = 1;
        loop {
            let candidate = if n == 1 {
                wanted.to_string()
            } else {
                format!("{stem}_{n}{ext}")
            };
            match self.taken.get(&candidate.to_lowercase()) {
                None => {
                    self.taken
                        .insert(candidate.to_lowercase(), Some(source.clone()));
                    return candidate;
                }
                Some(Some(s)) if *s == source => return candidate,
                _ => n += 1,
            }
        }
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
            sanitise_output_name("tex\\a.png").as_deref(),
            Some("tex/a.png")
        );
        assert_eq!(
            sanitise_output_name("/etc/passwd").as_deref(),
            Some("passwd")
        );
        assert_eq!(
            sanitise_output_name("C:\\scans\\t.jpg").as_deref(),
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
    fn jpeg_end_marker() {
        let ok = [
            0xFF, 0xD8, 0xFF, 0xDA, 0x00, 0x02, 0x12, 0xFF, 0x00, 0xFF, 0xD9,
        ];
        assert!(jpeg_has_end(&ok));
        assert!(!jpeg_has_end(&ok[..9]));
        assert!(!jpeg_has_end(b"not a jpeg"));
    }
}
