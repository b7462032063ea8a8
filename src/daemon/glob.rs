//! Which files the watcher looks at: small glob patterns (`*`, `**`, `?`) for the
//! configured include/exclude lists, and the built-in temporary-file patterns that are
//! always ignored (docs/service.md, "How a scan is detected": dot-files, `*.tmp`, `*.part`, … anchored at the end
//! of the name, so `x.obj.part` is never taken for an OBJ).

/// Matches `text` against `pattern`: `*` any run of characters except `/`, `**` any run
/// including `/`, `?` one character except `/`. Everything else literally.
pub fn glob_match(pattern: &str, text: &str) -> bool {
    let p: Vec<char> = pattern.chars().collect();
    let t: Vec<char> = text.chars().collect();
    matches(&p, &t)
}

fn matches(p: &[char], t: &[char]) -> bool {
    match p.first() {
        None => t.is_empty(),
        Some('*') if p.get(1) == Some(&'*') => {
            // `**/` may also match nothing at all (`**/a` matches `a`).
            let rest = &p[2..];
            let rest_no_slash = rest.strip_prefix(&['/']).unwrap_or(rest);
            if matches(rest_no_slash, t) {
                return true;
            }
            (0..=t.len()).any(|i| matches(rest, &t[i..]))
        }
        Some('*') => {
            let rest = &p[1..];
            for i in 0..=t.len() {
                if matches(rest, &t[i..]) {
                    return true;
                }
                if i < t.len() && t[i] == '/' {
                    break;
                }
            }
            false
        }
        Some('?') => !t.is_empty() && t[0] != '/' && matches(&p[1..], &t[1..]),
        Some(c) => t.first() == Some(c) && matches(&p[1..], &t[1..]),
    }
}

/// A pattern without `/` applies to the file name alone; with `/`, to the relative path.
pub fn pattern_matches(pattern: &str, rel_path: &str) -> bool {
    if pattern.contains('/') {
        glob_match(pattern, rel_path)
    } else {
        let name = rel_path.rsplit('/').next().unwrap_or(rel_path);
        glob_match(pattern, name)
    }
}

/// Names that are always ignored (files being written by common tools, hidden files,
/// and our own temporaries).
pub fn is_ignored_name(name: &str) -> bool {
    let lower = name.to_ascii_lowercase();
    name.starts_with('.')
        || name.starts_with("~$")
        || name.ends_with('~')
        || [
            ".tmp",
            ".temp",
            ".part",
            ".partial",
            ".crdownload",
            ".swp",
            ".download",
        ]
        .iter()
        .any(|s| lower.ends_with(s))
}

/// The kind of scan a file name starts, if any (anchored at the end: `.obj`, `.ply`,
/// `.stl`, `.gltf`, `.glb`, each optionally `.gz`, any case).
pub fn primary_kind(name: &str) -> Option<PrimaryKind> {
    let lower = name.to_ascii_lowercase();
    let base = lower.strip_suffix(".gz").unwrap_or(&lower);
    if base.ends_with(".obj") && base.len() > 4 {
        Some(PrimaryKind::Obj)
    } else if base.ends_with(".ply") && base.len() > 4 {
        Some(PrimaryKind::Ply)
    } else if base.ends_with(".gltf") && base.len() > 5 {
        Some(PrimaryKind::Gltf)
    } else if (base.ends_with(".stl") || base.ends_with(".glb")) && base.len() > 4 {
        Some(PrimaryKind::SelfContained)
    } else {
        None
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PrimaryKind {
    Obj,
    Ply,
    /// A `.gltf`: the JSON names its buffers and images, which are members beside it.
    Gltf,
    /// STL and GLB: one file holds the whole scan (a GLB its textures too), so the set is the
    /// file alone.
    SelfContained,
}

/// The include/exclude filter of one watched folder.
#[derive(Debug, Clone, Default)]
pub struct Filter {
    pub include: Vec<String>,
    pub exclude: Vec<String>,
}

impl Filter {
    /// Whether a candidate at `rel_path` (relative, `/`-separated) is taken.
    pub fn accepts(&self, rel_path: &str) -> bool {
        if rel_path.split('/').any(is_ignored_name) {
            return false;
        }
        if self.exclude.iter().any(|p| pattern_matches(p, rel_path)) {
            return false;
        }
        self.include.is_empty() || self.include.iter().any(|p| pattern_matches(p, rel_path))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn star_stays_within_a_name() {
        assert!(glob_match("*.obj", "a.obj"));
        assert!(!glob_match("*.obj", "d/a.obj"));
        assert!(glob_match("d/*.obj", "d/a.obj"));
        assert!(!glob_match("*.obj", "a.obj.part"));
    }

    #[test]
    fn double_star_crosses_folders() {
        assert!(glob_match("**/*.ply", "a/b/c.ply"));
        assert!(glob_match("**/*.ply", "c.ply"));
        assert!(glob_match("raw/**", "raw/x/y.obj"));
        assert!(glob_match("a?c", "abc"));
        assert!(!glob_match("a?c", "a/c"));
    }

    #[test]
    fn filter_rules() {
        let f = Filter {
            include: vec![],
            exclude: vec!["preview_*".into(), "old/**".into()],
        };
        assert!(f.accepts("s1/scan.obj"));
        assert!(!f.accepts("s1/preview_scan.obj"));
        assert!(!f.accepts("old/x/scan.obj"));
        assert!(!f.accepts(".hidden/scan.obj"));
        assert!(!f.accepts("scan.obj.part"));
        let only = Filter {
            include: vec!["*.ply".into()],
            exclude: vec![],
        };
        assert!(only.accepts("d/a.ply"));
        assert!(!only.accepts("d/a.obj"));
    }

    #[test]
    fn primary_kinds() {
        assert_eq!(primary_kind("a.OBJ"), Some(PrimaryKind::Obj));
        assert_eq!(primary_kind("a.ply.gz"), Some(PrimaryKind::Ply));
        assert_eq!(primary_kind("a.obj.mtl"), None);
        assert_eq!(primary_kind("a.STL"), Some(PrimaryKind::SelfContained));
        assert_eq!(primary_kind("a.glb"), Some(PrimaryKind::SelfContained));
        assert_eq!(primary_kind("a.gltf"), Some(PrimaryKind::Gltf));
        assert_eq!(primary_kind("a.GLTF.gz"), Some(PrimaryKind::Gltf));
        assert_eq!(primary_kind("a.gltf.bin"), None);
        assert_eq!(primary_kind(".obj"), None);
        assert!(is_ignored_name("x.PART"));
        assert!(is_ignored_name("~$x.obj"));
    }
}
