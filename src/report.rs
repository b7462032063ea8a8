//! The processing report (see README "Recipes" for what it holds): the input, the resolved recipe, one
//! entry per step, the final metrics and the files written. `process --report` writes it
//! as JSON and the daemon stores the same figures in SQLite.

use crate::mesh::{LoadReport, Mesh};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// A file and the SHA-256 of its content.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FileHash {
    #[serde(serialize_with = "crate::text::serialize_path")]
    pub path: PathBuf,
    pub sha256: String,
    pub bytes: u64,
}

impl FileHash {
    pub fn of(path: &Path) -> std::io::Result<FileHash> {
        FileHash::of_reader(path, std::fs::File::open(path)?)
    }

    /// The hash of what `file` (already opened, named `path`) holds.
    pub fn of_reader(path: &Path, mut file: impl std::io::Read) -> std::io::Result<FileHash> {
        let mut hasher = Sha256::new();
        let mut buf = vec![0u8; 1 << 20];
        let mut bytes = 0u64;
        loop {
            let n = file.read(&mut buf)?;
            if n == 0 {
                break;
            }
            bytes += n as u64;
            hasher.update(&buf[..n]);
        }
        Ok(FileHash {
            path: path.to_path_buf(),
            sha256: hex::encode(hasher.finalize()),
            bytes,
        })
    }
}

/// Basic counts of a mesh, cheap to compute.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MeshCounts {
    pub vertices: usize,
    pub faces: usize,
    pub wedges: usize,
    pub texcoords: usize,
    pub normals: usize,
}

impl MeshCounts {
    pub fn of(mesh: &Mesh) -> MeshCounts {
        MeshCounts {
            vertices: mesh.positions.len(),
            faces: mesh.triangles.len(),
            wedges: mesh.wedges.len(),
            texcoords: mesh.texcoords.len(),
            normals: mesh.normals.len(),
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct InputReport {
    #[serde(serialize_with = "crate::text::serialize_path")]
    pub path: PathBuf,
    /// SHA-256 over the mesh file and every texture it references, in a fixed order.
    pub content_hash: String,
    pub files: Vec<FileHash>,
    pub counts: MeshCounts,
    pub load: LoadReport,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RecipeReport {
    pub path: Option<PathBuf>,
    pub hash: String,
    pub resolved: Value,
}

/// One step as it ran.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StepReport {
    pub kind: String,
    pub wall_ms: f64,
    pub vertices_before: usize,
    pub vertices_after: usize,
    pub faces_before: usize,
    pub faces_after: usize,
    /// The step's own figures (iterations, collapses, …), as the step reports them.
    pub figures: Value,
    /// Metrics of the step's result against its input, for steps with `metrics = true`
    /// (a `metrics::FinalMetrics`, or `{"error": …}`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub metrics: Option<Value>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct OutputReport {
    pub files: Vec<FileHash>,
    pub counts: MeshCounts,
}

/// The preview picture (`preview` module): the file written beside the result and what
/// it shows.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PreviewReport {
    pub file: FileHash,
    pub figures: crate::preview::PreviewFigures,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Report {
    pub scanmill_version: String,
    pub input: InputReport,
    pub recipe: RecipeReport,
    pub steps: Vec<StepReport>,
    /// Final quality metrics of the result against the input.
    pub metrics: Value,
    pub output: OutputReport,
    /// The preview, `null` when the recipe turns it off or it could not be drawn (a
    /// preview that fails is logged; it never fails the job).
    pub preview: Option<PreviewReport>,
    pub load_ms: f64,
    pub write_ms: f64,
    pub total_ms: f64,
}

impl Report {
    /// The report with its output and preview paths moved from folder `from` to folder
    /// `to`: the daemon writes into a staging folder and publishes it elsewhere, and the
    /// recorded paths must be where the files are (`to` = "" makes them relative).
    pub fn with_output_folder(&self, from: &Path, to: &Path) -> Report {
        let rebase = |path: &mut PathBuf| {
            if let Ok(rest) = path.strip_prefix(from) {
                *path = to.join(rest);
            }
        };
        let mut report = self.clone();
        for file in &mut report.output.files {
            rebase(&mut file.path);
        }
        if let Some(preview) = &mut report.preview {
            rebase(&mut preview.file.path);
        }
        report
    }
}

/// One hash over several files: each file's name-independent digest, in the given order.
pub fn combined_hash(files: &[FileHash]) -> String {
    let mut hasher = Sha256::new();
    for f in files {
        hasher.update(f.sha256.as_bytes());
        hasher.update(b"\n");
    }
    hex::encode(hasher.finalize())
}
