//! One scan through one recipe: load, run the steps, write the result into an output
//! folder without ever leaving a half-written file there, and build the report.
//! `scanmill process` and the daemon's worker both call [`process_scan_with_options`].

use crate::daemon::publish::SIDECAR_SUFFIX;
use crate::mesh::files::open_regular;
use crate::mesh::ply::PlyEncoding;
use crate::mesh::{
    InputLimits, LoadOptions, LoadReport, Mesh, MeshError, SaveOptions, load, save_reserving,
};
use crate::ops::remesh::Method;
use crate::preview::Preview;
use crate::recipe::runner::{Progress, RunOutcome, StepError, run_recipe};
use crate::recipe::{OutputFormat, PlyEncodingSpec, Recipe, Step};
use crate::report::{
    FileHash, InputReport, MeshCounts, OutputReport, PreviewReport, RecipeReport, Report,
    combined_hash,
};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Debug, thiserror::Error)]
pub enum ProcessError {
    /// The input could not be read, is not a valid mesh or is above a limit. (A
    /// [`MeshError::Write`] is never an input error: see [`ProcessError::from_save`].)
    #[error(transparent)]
    Input(#[from] MeshError),
    /// A step failed.
    #[error("{input}: {source}")]
    Step {
        input: PathBuf,
        #[source]
        source: StepError,
    },
    /// Writing the result failed (a full disk, a quota, permissions): transient, exit 74.
    #[error("{path}: cannot write output: {message}")]
    Output { path: PathBuf, message: String },
}

impl ProcessError {
    /// The error of a writer: failing to write a file is an output error, failing to read a
    /// file to copy (a texture that vanished) an input error.
    fn from_save(e: MeshError) -> ProcessError {
        match e {
            MeshError::Write { path, source } => ProcessError::Output {
                path,
                message: source.to_string(),
            },
            other => ProcessError::Input(other),
        }
    }
}

/// How `process` treats its input, beyond the recipe.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ProcessOptions {
    /// The texture image of an OBJ that names no material library (facefuns, some scanner
    /// exports): it becomes the OBJ's diffuse texture. Ignored, with a warning, when the OBJ
    /// declares materials of its own.
    pub texture: Option<PathBuf>,
    /// Input limits: `scanmill process` uses the defaults, the daemon its `[limits]` table.
    pub limits: InputLimits,
}

impl ProcessError {
    /// Whether trying again could help (I/O trouble), as opposed to bad input or a step
    /// that will fail the same way every time.
    pub fn is_transient(&self) -> bool {
        match self {
            ProcessError::Input(MeshError::Io { .. }) | ProcessError::Output { .. } => true,
            ProcessError::Input(_) | ProcessError::Step { .. } => false,
        }
    }
}

/// The output base name: the input's name without `.gz` and its mesh extension, escaped
/// (control characters and bytes that are not UTF-8 written out, see
/// [`crate::text::escape_os`]), so that no output name carries a control character. The CLI
/// names its files with it and the daemon its staging folder.
pub fn output_stem(input: &Path) -> String {
    let name = input
        .file_name()
        .map(crate::text::escape_os)
        .unwrap_or_else(|| "scan".into());
    let name = name.strip_suffix(".gz").unwrap_or(&name);
    match name.rsplit_once('.') {
        Some((stem, _)) if !stem.is_empty() => stem.to_string(),
        _ => name.to_string(),
    }
}

fn output_error(path: &Path, e: impl std::fmt::Display) -> ProcessError {
    ProcessError::Output {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// The names that scanmill itself writes beside the result `<stem>.<ext>` besides the mesh
/// files: the preview and the daemon's sidecar. Copied textures never take these names,
/// whatever the scan calls its textures.
pub fn reserved_output_names(stem: &str) -> Vec<String> {
    vec![preview_file_name(stem), format!("{stem}{SIDECAR_SUFFIX}")]
}

/// What [`write_mesh`] wrote: supporting files (MTL, texture copies), then the mesh files,
/// one per format in the recipe's order.
#[derive(Debug, Default)]
pub struct Written {
    pub supporting: Vec<PathBuf>,
    pub meshes: Vec<PathBuf>,
}

/// Writes `mesh` into `dir` in each of the recipe's formats, as `<stem>.<format>`. Copied
/// textures never take one of [`reserved_output_names`] nor any format's mesh or MTL name,
/// so that the writers, which choose copy names the same way, agree on them: a texture that
/// two formats copy is written once.
pub fn write_mesh(
    mesh: &Mesh,
    recipe: &Recipe,
    dir: &Path,
    stem: &str,
) -> Result<Written, ProcessError> {
    let ply_encoding = match recipe.output.ply_encoding {
        PlyEncodingSpec::Ascii => PlyEncoding::Ascii,
        PlyEncodingSpec::BinaryLittleEndian => PlyEncoding::BinaryLittleEndian,
        PlyEncodingSpec::BinaryBigEndian => PlyEncoding::BinaryBigEndian,
    };
    let mut reserved = reserved_output_names(stem);
    reserved.push(format!("{stem}.mtl"));
    reserved.extend(OutputFormat::ALL.map(|f| format!("{stem}.{}", f.name())));
    let mut written = Written::default();
    for format in recipe.output.format.list() {
        let main_file = dir.join(format!("{stem}.{}", format.name()));
        let files = save_reserving(mesh, &main_file, &SaveOptions { ply_encoding }, &reserved)
            .map_err(ProcessError::from_save)?;
        for file in files {
            if file != main_file && !written.supporting.contains(&file) {
                written.supporting.push(file);
            }
        }
        written.meshes.push(main_file);
    }
    Ok(written)
}

/// Moves every file of `staging` into `out_dir` by rename (same filesystem), in the order of
/// `files` (supporting files first, the mesh files last), then syncs the folder, so a reader
/// never sees a mesh whose MTL or textures are not there yet.
fn publish(
    staging: &Path,
    files: &[PathBuf],
    out_dir: &Path,
) -> Result<Vec<PathBuf>, ProcessError> {
    let mut published = Vec::with_capacity(files.len());
    for file in files {
        let relative = file
            .strip_prefix(staging)
            .map_err(|e| output_error(file, e))?;
        let target = out_dir.join(relative);
        if let Some(parent) = target.parent() {
            std::fs::create_dir_all(parent).map_err(|e| output_error(parent, e))?;
        }
        std::fs::File::open(file)
            .and_then(|f| f.sync_all())
            .map_err(|e| output_error(file, e))?;
        if target.exists() {
            tracing::warn!(path = %target.display(), "replacing existing output file");
        }
        std::fs::rename(file, &target).map_err(|e| output_error(&target, e))?;
        published.push(target);
    }
    std::fs::File::open(out_dir)
        .and_then(|d| d.sync_all())
        .map_err(|e| output_error(out_dir, e))?;
    Ok(published)
}

/// A staging folder inside the output folder (so that the final rename is atomic), removed
/// again when dropped, whatever happened.
struct Staging(PathBuf);

impl Staging {
    fn new(out_dir: &Path) -> Result<Staging, ProcessError> {
        std::fs::create_dir_all(out_dir).map_err(|e| output_error(out_dir, e))?;
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or(0);
        let dir = out_dir.join(format!(".scanmill-tmp-{}-{nanos}", std::process::id()));
        std::fs::create_dir(&dir).map_err(|e| output_error(&dir, e))?;
        Ok(Staging(dir))
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The preview picture's file name beside the result `<stem>.<ext>`: named after the scan,
/// so that several scans processed into one folder do not overwrite each other's.
pub fn preview_file_name(stem: &str) -> String {
    format!("{stem}.preview.png")
}

/// Whether the recipe's output is numbered afresh whatever the input's order (it decimates
/// or remeshes isotropically), so that the input may be renumbered for speed
/// ([`Mesh::reorder_for_locality`]; for the remesh, docs/remeshing.md, "The input in
/// Morton order"). Other recipes keep the file's numbering, so that their output
/// corresponds vertex for vertex to the input. The `patches` remesh keeps it too: its layout
/// follows the vertex order, and in the new order it left more faces against the input on
/// one scan of its checks, for a time that is not where the numbering matters.
/// `scanmill compare` follows the same rule, so that its rows are what `process` makes.
pub(crate) fn renumbers_anyway(recipe: &Recipe) -> bool {
    recipe.steps.iter().any(|s| match s {
        Step::Decimate(_) => true,
        Step::Remesh(p) => p.method == Method::Isotropic,
        _ => false,
    })
}

/// The hash of an input file, read only if it is a regular file (a FIFO or device is refused
/// at once, never waited on).
fn hash_input(path: &Path) -> Result<FileHash, MeshError> {
    let (file, _) = open_regular(path)?;
    FileHash::of_reader(path, file).map_err(|e| MeshError::io(path, e))
}

/// Runs `job` on a thread of rayon's pool and waits for it (runs it in place when called on
/// one).
///
/// A parallel loop started from a thread outside the pool hands its work to the pool's
/// threads, which may be asleep, and waits to be woken when they are done; started on a
/// thread of the pool, it begins on that thread at once and needs only the other threads to
/// wake. The remesher runs dozens of short parallel loops between sequential passes: on the
/// two-core workstation its step on james took 68 ms from outside the pool and 55 ms on it
/// (docs/remeshing.md, "The job on a thread of the pool"). Jobs, `scanmill compare` and the
/// benches ([`criterion_main_on_pool`](crate::criterion_main_on_pool)) run on it.
///
/// The caller's tracing span is entered on the pool's thread too, so that the job's log
/// lines still name it (the daemon's worker process names its job there).
pub fn on_pool<R: Send>(job: impl FnOnce() -> R + Send) -> R {
    let span = tracing::Span::current();
    rayon::scope(|_| span.in_scope(job))
}

/// `criterion_main!` for the benches, with the benchmark groups run on a thread of rayon's
/// pool as a job runs ([`on_pool`]), so that their times are a job's. Expands to the bench's
/// `main`; the bench crate provides `criterion`.
#[macro_export]
macro_rules! criterion_main_on_pool {
    ($($group:path),+ $(,)?) => {
        fn main() {
            $crate::process::on_pool(|| {
                $($group();)+
            });
            criterion::Criterion::default()
                .configure_from_args()
                .final_summary();
        }
    };
}

/// Processes one scan: the one entry point the CLI and the daemon share. The result lands in
/// `out_dir` only if everything succeeded. Runs [`on_pool`].
pub fn process_scan_with_options(
    input: &Path,
    process_options: &ProcessOptions,
    recipe: &Recipe,
    recipe_path: Option<&Path>,
    out_dir: &Path,
    progress: &dyn Progress,
) -> Result<Report, ProcessError> {
    on_pool(|| {
        let total_start = Instant::now();
        let total_stages = recipe.steps.len() + 2 + usize::from(recipe.preview.enabled);

        progress.stage(0, total_stages, "load");
        let load_start = Instant::now();
        let Loaded {
            mut mesh,
            report: load_report,
            files: input_files,
        } = load_input(input, process_options, recipe)?;
        let load_ms = load_start.elapsed().as_secs_f64() * 1e3;
        let input_counts = MeshCounts::of(&mesh);
        tracing::info!(input = %crate::text::escape_path(input), faces = input_counts.faces, load_ms, "loaded");

        // The steps, then the final metrics against the input and the preview (a clone of the
        // input is kept while the steps run, unless the recipe wants neither).
        let RunOutcome {
            steps,
            metrics,
            preview,
        } = run_recipe(
            recipe,
            &mut mesh,
            &process_options.limits,
            progress,
            1,
            total_stages,
        )
        .map_err(|source| ProcessError::Step {
            input: input.to_path_buf(),
            source,
        })?;

        progress.stage(total_stages - 1, total_stages, "write");
        let write_start = Instant::now();
        let (output_files, preview) = write_outputs(&mesh, recipe, input, out_dir, preview)?;
        let write_ms = write_start.elapsed().as_secs_f64() * 1e3;

        Ok(Report {
            scanmill_version: env!("CARGO_PKG_VERSION").to_string(),
            input: InputReport {
                path: input.to_path_buf(),
                content_hash: combined_hash(&input_files),
                files: input_files,
                counts: input_counts,
                load: load_report,
            },
            recipe: RecipeReport {
                path: recipe_path.map(Path::to_path_buf),
                hash: recipe.hash(),
                resolved: recipe.resolved_json(),
            },
            steps,
            metrics,
            output: OutputReport {
                files: output_files,
                counts: MeshCounts::of(&mesh),
            },
            preview,
            load_ms,
            write_ms,
            total_ms: total_start.elapsed().as_secs_f64() * 1e3,
        })
    })
}

/// A scan as loaded, with the hashes of its files (the mesh file first, then each texture
/// file once).
struct Loaded {
    mesh: Mesh,
    report: LoadReport,
    files: Vec<FileHash>,
}

/// Loads the scan under the recipe's input settings and the limits, hashes its files and,
/// when the recipe renumbers anyway, numbers the mesh for locality.
fn load_input(
    input: &Path,
    process_options: &ProcessOptions,
    recipe: &Recipe,
) -> Result<Loaded, ProcessError> {
    let options = LoadOptions {
        weld_tolerance: recipe.input.weld_tolerance,
        texture_override: process_options.texture.clone(),
        limits: process_options.limits.clone(),
        ..LoadOptions::default()
    };
    // The input's hash is read on a thread of its own beside the load (a second read of
    // the file, from the page cache, while much of the load is sequential).
    let (loaded, input_hash) = std::thread::scope(|scope| {
        let hash = scope.spawn(|| hash_input(input));
        let loaded = load(input, &options);
        let hash = hash
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (loaded, hash)
    });
    let (mut mesh, report) = loaded?;
    // The file's text and the parser's arrays are gone: give their memory back before the
    // steps allocate theirs (see `memory`).
    crate::memory::release_freed();
    let mut files = vec![input_hash?];
    for material in &mesh.materials {
        // Each distinct file once, however many materials name it; an embedded image is
        // part of the scan's file, already hashed.
        if let Some(texture) = &material.diffuse_texture
            && texture.embedded.is_none()
            && !files.iter().any(|f| f.path == texture.path)
        {
            files.push(hash_input(&texture.path)?);
        }
    }
    if renumbers_anyway(recipe) {
        // The output's numbering is new anyway: number the mesh for locality first, which
        // makes every step faster where the file's order is unrelated to space.
        let start = Instant::now();
        mesh.reorder_for_locality();
        let ms = start.elapsed().as_secs_f64() * 1e3;
        tracing::debug!(ms, "vertices and triangles renumbered for locality");
    }
    Ok(Loaded {
        mesh,
        report,
        files,
    })
}

/// Writes the result, its supporting files and the preview into a staging folder and
/// publishes them into `out_dir` (supporting files and the preview first, the mesh files
/// last); returns the published files' hashes and the preview's report.
fn write_outputs(
    mesh: &Mesh,
    recipe: &Recipe,
    input: &Path,
    out_dir: &Path,
    preview: Option<Preview>,
) -> Result<(Vec<FileHash>, Option<PreviewReport>), ProcessError> {
    let stem = output_stem(input);
    let staging = Staging::new(out_dir)?;
    // The mesh's text and the preview's PNG are each written on one core: side by side.
    let (written, preview) = rayon::join(
        || write_mesh(mesh, recipe, &staging.0, &stem),
        || {
            preview.and_then(|preview| {
                let path = staging.0.join(preview_file_name(&stem));
                match crate::preview::write_png(&preview.image, &path) {
                    Ok(()) => Some((path, preview.figures)),
                    Err(e) => {
                        tracing::warn!(error = %e, "no preview");
                        None
                    }
                }
            })
        },
    );
    let Written { supporting, meshes } = written?;
    let mut files = supporting;
    files.extend(preview.iter().map(|(path, _)| path.clone()));
    files.extend(meshes);
    let mut published = publish(&staging.0, &files, out_dir)?;
    drop(staging);
    let preview = match preview {
        Some((staged, figures)) => {
            let index = files.iter().position(|f| *f == staged).unwrap_or_default();
            let path = published.remove(index);
            Some(PreviewReport {
                file: FileHash::of(&path).map_err(|e| output_error(&path, e))?,
                figures,
            })
        }
        None => None,
    };
    let output_files = published
        .par_iter()
        .map(|p| FileHash::of(p).map_err(|e| output_error(p, e)))
        .collect::<Result<Vec<_>, _>>()?;
    Ok((output_files, preview))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn recipe(steps: &str) -> Recipe {
        Recipe::from_toml(steps, Path::new("test.toml")).unwrap()
    }

    #[test]
    fn renumbered_before_a_decimation_or_an_isotropic_remesh_only() {
        let decimate = "[[step]]\nkind = \"decimate\"\ntarget_faces = 1000\n";
        let isotropic = "[[step]]\nkind = \"remesh\"\nedge_fraction = 0.01\n";
        let patches = "[[step]]\nkind = \"remesh\"\nmethod = \"patches\"\nf = 0.05\n";
        let normals = "[[step]]\nkind = \"normals\"\n";
        assert!(renumbers_anyway(&recipe(decimate)));
        assert!(renumbers_anyway(&recipe(isotropic)));
        assert!(!renumbers_anyway(&recipe(patches)));
        assert!(!renumbers_anyway(&recipe(normals)));
        assert!(renumbers_anyway(&recipe(&format!("{normals}{isotropic}"))));
    }
}
