//! MTL material libraries: `newmtl` blocks, their `map_Kd` texture, and every other
//! statement kept verbatim (file names normalised) so that it is written back unchanged.

use super::error::{Location, MeshError, Result};
use super::files;
use super::limits::{InputLimits, Limit};
use super::model::{MapFile, Material, Texture};
use super::texture::{self, Referenced, is_map_statement, normalise_name, split_map_arguments};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A material as the MTL states it, before its files are resolved.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MtlMaterial {
    pub name: String,
    /// The `map_Kd` file name (options stripped, normalised) and the line it is on.
    pub diffuse: Option<(String, u64)>,
    /// Every other statement, trimmed, in order; comments and blank lines are dropped. The
    /// file name of a map statement is normalised ([`normalise_name`]).
    pub other_statements: Vec<String>,
    /// Line of `newmtl`.
    pub line: u64,
}

/// Parses MTL text. Statements before the first `newmtl` are ignored (with a warning);
/// a `newmtl` without a name is malformed.
pub fn parse(mtl_path: &Path, bytes: &[u8]) -> Result<Vec<MtlMaterial>> {
    let text = String::from_utf8_lossy(bytes);
    let mut materials: Vec<MtlMaterial> = Vec::new();
    let mut pending = String::new();
    let mut pending_line = 0;
    for (i, raw) in text.split('\n').enumerate() {
        let line_no = i as u64 + 1;
        let raw = raw.trim_end();
        // `\` at the end of a line continues the statement on the next one.
        if pending.is_empty() {
            pending_line = line_no;
        }
        if let Some(head) = raw.strip_suffix('\\') {
            pending.push_str(head);
            pending.push(' ');
            continue;
        }
        pending.push_str(raw);
        let statement = std::mem::take(&mut pending);
        let statement = statement.trim();
        if statement.is_empty() || statement.starts_with('#') {
            continue;
        }
        let (keyword, args) = match statement.find(char::is_whitespace) {
            Some(k) => (&statement[..k], statement[k..].trim()),
            None => (statement, ""),
        };
        if keyword == "newmtl" {
            if args.is_empty() {
                return Err(MeshError::malformed(
                    mtl_path,
                    Location::Line(pending_line),
                    "newmtl without a material name",
                ));
            }
            materials.push(MtlMaterial {
                name: args.to_string(),
                line: pending_line,
                ..Default::default()
            });
            continue;
        }
        let Some(current) = materials.last_mut() else {
            tracing::warn!(
                "{}: line {pending_line}: `{keyword}` before any newmtl, ignored",
                mtl_path.display()
            );
            continue;
        };
        if keyword.eq_ignore_ascii_case("map_Kd") {
            diffuse_map(mtl_path, pending_line, current, args)?;
        } else {
            current
                .other_statements
                .push(normalised_statement(keyword, args, statement));
        }
    }
    Ok(materials)
}

/// A `map_Kd` statement of `current`: its file (options are not kept), the last one winning.
fn diffuse_map(mtl_path: &Path, line: u64, current: &mut MtlMaterial, args: &str) -> Result<()> {
    let (options, file) = split_map_arguments(args);
    if file.is_empty() {
        return Err(MeshError::malformed(
            mtl_path,
            Location::Line(line),
            "map_Kd without a file name",
        ));
    }
    if !options.is_empty() {
        // The model keeps only the file; options such as `-s` are rare in scans.
        tracing::warn!(
            "{}: line {line}: map_Kd options {options:?} are not kept",
            mtl_path.display()
        );
    }
    if current.diffuse.is_some() {
        tracing::warn!(
            "{}: line {line}: second map_Kd in material {:?}; the last one wins",
            mtl_path.display(),
            current.name
        );
    }
    current.diffuse = Some((normalise_name(file), line));
    Ok(())
}

/// A statement as kept: a map statement with its file name normalised, anything else as
/// written.
fn normalised_statement(keyword: &str, args: &str, statement: &str) -> String {
    if !is_map_statement(keyword) {
        return statement.to_string();
    }
    let (options, file) = split_map_arguments(args);
    if file.is_empty() || !file.contains('\\') {
        return statement.to_string();
    }
    let options = if options.is_empty() {
        String::new()
    } else {
        format!("{options} ")
    };
    format!("{keyword} {options}{}", normalise_name(file))
}

/// The keyword and the file name of a map statement (`None` for other statements and for
/// map statements without a file).
pub fn map_file_of(statement: &str) -> Option<(&str, &str, &str)> {
    let (keyword, args) = match statement.find(char::is_whitespace) {
        Some(k) => (&statement[..k], statement[k..].trim()),
        None => (statement, ""),
    };
    if !is_map_statement(keyword) {
        return None;
    }
    let (options, file) = split_map_arguments(args);
    (!file.is_empty()).then_some((keyword, options, file))
}

/// Reads an MTL file (the resolved path; within `limits.max_mtl_bytes`), resolves its files
/// inside the scan folder (`scan_dir`, canonical) and returns its materials in MTL order,
/// every file they name resolved. Image checks are left to the caller (each distinct image
/// is decoded once, within the job's pixel budget).
pub fn load(mtl_path: &Path, scan_dir: &Path, limits: &InputLimits) -> Result<Vec<Material>> {
    let bytes = files::read_whole(mtl_path, limits.max_mtl_bytes, Limit::MtlBytes)?;
    let base_dir = texture::folder_of(mtl_path);
    let cap = (limits.max_file_bytes, Limit::FileBytes);
    // Each distinct name is resolved once: resolving costs several system calls, and an MTL
    // may repeat one map line a hundred thousand times (found by fuzzing: 16 s for 2 MB).
    let mut resolved: HashMap<String, PathBuf> = HashMap::new();
    let mut resolve = |name: &str| -> Result<PathBuf> {
        if let Some(path) = resolved.get(name) {
            return Ok(path.clone());
        }
        let path = texture::resolve_in_scan(
            scan_dir,
            &base_dir,
            (name, Referenced::Texture),
            mtl_path,
            cap,
        )?
        .path;
        resolved.insert(name.to_string(), path.clone());
        Ok(path)
    };
    let mut out = Vec::new();
    for m in parse(mtl_path, &bytes)? {
        let diffuse_texture = match &m.diffuse {
            Some((name, _line)) => Some(Texture {
                name: name.clone(),
                path: resolve(name)?,
                size: None,
                embedded: None,
            }),
            None => None,
        };
        // Other maps are copied on output, so they must exist and stay inside too.
        let mut map_files = Vec::new();
        for (statement, text) in m.other_statements.iter().enumerate() {
            if let Some((_, _, file)) = map_file_of(text) {
                map_files.push(MapFile {
                    statement,
                    path: resolve(file)?,
                });
            }
        }
        out.push(Material {
            name: m.name,
            diffuse_texture,
            other_statements: m.other_statements,
            map_files,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_blocks_statements_and_textures() {
        let text = b"# comment\r\nnewmtl a\r\nKa 1 1 1\r\nmap_Kd -s 1 1 1 my tex.png\r\n\r\nnewmtl b\nmap_Bump n.png\nillum \\\n 2\n";
        let m = parse(Path::new("x.mtl"), text).unwrap();
        assert_eq!(m.len(), 2);
        assert_eq!(m[0].name, "a");
        assert_eq!(m[0].other_statements, vec!["Ka 1 1 1"]);
        assert_eq!(m[0].diffuse, Some(("my tex.png".to_string(), 4)));
        assert_eq!(m[1].other_statements, vec!["map_Bump n.png", "illum   2"]);
        assert_eq!(m[1].diffuse, None);
    }

    #[test]
    fn backslashes_are_separators_decided_at_parse() {
        let text = b"newmtl a\nmap_Kd tex\\skin.png\nmap_Bump -bm 0.5 ..\\..\\etc\\passwd\n";
        let m = parse(Path::new("x.mtl"), text).unwrap();
        assert_eq!(m[0].diffuse, Some(("tex/skin.png".to_string(), 2)));
        assert_eq!(
            m[0].other_statements,
            vec!["map_Bump -bm 0.5 ../../etc/passwd"]
        );
        assert_eq!(
            map_file_of(&m[0].other_statements[0]),
            Some(("map_Bump", "-bm 0.5", "../../etc/passwd"))
        );
    }

    #[test]
    fn newmtl_without_name_is_malformed() {
        let err = parse(Path::new("x.mtl"), b"newmtl a\nnewmtl\n").unwrap_err();
        assert!(matches!(
            err,
            MeshError::Malformed {
                at: Location::Line(2),
                ..
            }
        ));
    }
}
