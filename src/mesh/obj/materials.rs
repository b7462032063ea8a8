//! An OBJ's materials: the MTL files its `mtllib` statements name, the material of every
//! face from its `usemtl` statements, the texture given on the command line for a file that
//! names none, and the check that every texture decodes.

use super::{DEFAULT_MATERIAL, OVERRIDE_MATERIAL};
use crate::mesh::error::{MeshError, Result};
use crate::mesh::limits::{InputLimits, Limit};
use crate::mesh::model::{Index, Material, Texture};
use crate::mesh::texture::Referenced;
use crate::mesh::{mtl, texture};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The statements of an OBJ that materials are resolved from.
pub(super) struct MaterialStatements<'g> {
    /// `(line, argument)` for every `mtllib` statement (normalised), in file order.
    pub mtllibs: &'g [(u64, String)],
    /// `(first face, material name)` for every `usemtl`, in file order.
    pub usemtl: &'g [(usize, String)],
    /// The file's face count.
    pub faces: usize,
}

/// Materials, the file that named each one's texture (for errors), and the material of
/// every face.
pub(super) struct Assigned {
    pub materials: Vec<Material>,
    pub referrers: Vec<PathBuf>,
    pub face_materials: Vec<Index>,
}

/// The materials of the MTL libraries, each defined once (the first definition wins),
/// with the library that defined it, and the index of each name.
#[derive(Default)]
struct Libraries {
    materials: Vec<Material>,
    referrers: Vec<PathBuf>,
    by_name: HashMap<String, Index>,
}

/// Loads the MTLs and gives every face its material index (see the reader's rules).
pub(super) fn assign_materials(
    path: &Path,
    g: &MaterialStatements<'_>,
    options: &crate::mesh::LoadOptions,
) -> Result<Assigned> {
    let libraries = load_libraries(path, g.mtllibs, &options.limits)?;
    if g.usemtl.is_empty() && libraries.materials.is_empty() {
        return match &options.texture_override {
            Some(texture_path) => override_material(path, texture_path, g.faces),
            None => Ok(Assigned {
                materials: Vec::new(),
                referrers: Vec::new(),
                face_materials: Vec::new(),
            }),
        };
    }
    if let Some(t) = &options.texture_override {
        tracing::warn!(
            "{}: the file declares materials; texture {} not used",
            path.display(),
            t.display()
        );
    }
    Ok(face_materials(path, g, libraries))
}

/// Every material of the libraries the `mtllib` statements name, each library once.
fn load_libraries(
    path: &Path,
    mtllibs: &[(u64, String)],
    limits: &InputLimits,
) -> Result<Libraries> {
    let scan_dir = texture::scan_folder(path);
    let obj_dir = texture::folder_of(path);
    let mut libraries = Libraries::default();
    let mut seen_libraries: Vec<PathBuf> = Vec::new();
    let cap = (limits.max_mtl_bytes, Limit::MtlBytes);
    for (line, argument) in mtllibs {
        for name in mtllib_names(&obj_dir, argument) {
            let resolved = texture::resolve_in_scan(
                &scan_dir,
                &obj_dir,
                (&name, Referenced::MaterialLibrary),
                path,
                cap,
            )
            .map_err(|e| mtl_missing(path, *line, &obj_dir.join(&name), e))?;
            if seen_libraries.contains(&resolved.path) {
                continue;
            }
            for m in mtl::load(&resolved.path, &scan_dir, limits)? {
                if libraries.by_name.contains_key(&m.name) {
                    tracing::warn!(
                        "{}: material {:?} defined again; the first definition is used",
                        resolved.path.display(),
                        m.name
                    );
                    continue;
                }
                let index = libraries.materials.len() as Index;
                libraries.by_name.insert(m.name.clone(), index);
                libraries.materials.push(m);
                libraries.referrers.push(resolved.path.clone());
            }
            seen_libraries.push(resolved.path);
        }
    }
    Ok(libraries)
}

/// A file without materials, given a texture: one material with that texture for every
/// face.
fn override_material(path: &Path, texture_path: &Path, faces: usize) -> Result<Assigned> {
    let name = texture_path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| texture_path.display().to_string());
    let material = Material {
        name: OVERRIDE_MATERIAL.to_string(),
        diffuse_texture: Some(Texture {
            name,
            path: texture_path.to_path_buf(),
            size: None,
            embedded: None,
        }),
        other_statements: Vec::new(),
        map_files: Vec::new(),
    };
    if !texture_path.is_file() {
        return Err(MeshError::Texture {
            path: path.to_path_buf(),
            texture: texture_path.display().to_string(),
            message: "texture given for this scan does not exist".into(),
        });
    }
    Ok(Assigned {
        materials: vec![material],
        referrers: vec![path.to_path_buf()],
        face_materials: vec![0; faces],
    })
}

/// Each face's material from the `usemtl` statements: `default` before the first, and a
/// material without texture for a name that no library defines.
fn face_materials(path: &Path, g: &MaterialStatements<'_>, libraries: Libraries) -> Assigned {
    let Libraries {
        mut materials,
        mut referrers,
        mut by_name,
    } = libraries;
    let mut lookup =
        |name: &str, materials: &mut Vec<Material>, referrers: &mut Vec<PathBuf>| -> Index {
            *by_name.entry(name.to_string()).or_insert_with(|| {
                if name != DEFAULT_MATERIAL {
                    tracing::warn!(
                        "{}: usemtl {name:?} is in no material library; it gets no texture",
                        path.display()
                    );
                }
                materials.push(Material {
                    name: name.to_string(),
                    ..Default::default()
                });
                referrers.push(path.to_path_buf());
                (materials.len() - 1) as Index
            })
        };
    let first_named = g.usemtl.first().map_or(g.faces, |(f, _)| *f);
    let mut face_materials = Vec::with_capacity(g.faces);
    if first_named > 0 {
        let default = lookup(DEFAULT_MATERIAL, &mut materials, &mut referrers);
        face_materials.resize(first_named, default);
    }
    for (k, (start, name)) in g.usemtl.iter().enumerate() {
        let end = g.usemtl.get(k + 1).map_or(g.faces, |(f, _)| *f);
        let m = lookup(name, &mut materials, &mut referrers);
        face_materials.resize(face_materials.len() + (end - start), m);
    }
    Assigned {
        materials,
        referrers,
        face_materials,
    }
}

/// The MTL names of one `mtllib` statement: the whole argument if that file exists (names
/// with spaces), else its whitespace-separated words.
fn mtllib_names(obj_dir: &Path, argument: &str) -> Vec<String> {
    if obj_dir.join(argument).is_file() {
        return vec![argument.to_string()];
    }
    argument.split_whitespace().map(str::to_string).collect()
}

/// A missing or unreadable MTL is an error: the scan is incomplete without it.
fn mtl_missing(obj: &Path, line: u64, looked: &Path, e: MeshError) -> MeshError {
    match e {
        MeshError::MissingFile { name, .. } => MeshError::Io {
            path: looked.to_path_buf(),
            source: std::io::Error::new(
                std::io::ErrorKind::NotFound,
                format!(
                    "material library {name:?} named at {} line {line} does not exist",
                    obj.display()
                ),
            ),
        },
        other => other,
    }
}

/// Decodes every distinct diffuse texture once, within the job's pixel budget, and stores
/// each material's size; the first failure in material order is the error, naming the
/// texture and the MTL (`referrers`). Returns how many images were decoded.
pub(super) fn check_textures(
    materials: &mut [Material],
    referrers: &[PathBuf],
    limits: &InputLimits,
) -> Result<usize> {
    let images: Vec<texture::ImageRef> = materials
        .iter()
        .zip(referrers)
        .filter_map(|(m, referrer)| {
            m.diffuse_texture.as_ref().map(|t| texture::ImageRef {
                path: &t.path,
                name: &t.name,
                referrer,
                embedded: None,
            })
        })
        .collect();
    let checked = texture::check_images(&images, limits)?;
    for m in materials.iter_mut() {
        if let Some(t) = &mut m.diffuse_texture {
            t.size = checked.sizes.get(&t.path).copied();
        }
    }
    Ok(checked.decoded)
}
