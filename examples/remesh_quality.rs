//! One remesh result measured against its input with scanmill's own metrics, as one JSON
//! line: the figures of issue #24's comparison with MeshLab (scripts/vs_meshlab_remesh.py
//! runs it on both sides' outputs, so that both are measured by the same code).
//!
//! ```text
//! cargo run --release --example remesh_quality -- INPUT RESULT
//! ```
//!
//! - `faces`: the result's triangles as loaded (`file_faces` as stored; the loader drops
//!   degenerate, zero-area and duplicate faces, counted in `dropped_faces`);
//! - `angles`: `ops::remesh::quality::AngleQuality` (share of triangles with smallest angle
//!   ≥ 30°, its 1st percentile, the smallest), the remesh step's own `quality_after`;
//! - `distance_mean_pct` / `distance_max_pct`: `metrics::compare`'s surface distance, both
//!   directions pooled (`distance.mean_relative`, `max_relative`, in % of the input's
//!   bounding-box diagonal); `result_to_input_mean_pct` / `_max_pct`: one-sided, samples on
//!   the result (MeshLab's Hausdorff filter's figure); `input_to_result_max_pct`: samples on
//!   the input (large where the result lost part of the surface);
//! - `flipped_faces`: `metrics::compare`'s `normals.flipped_faces` (result faces more than
//!   90° from the input's normal at their closest point), of `normal_faces` measured;
//! - `mean_edge` and `mean_edge_pct`: the result's mean undirected edge length
//!   (`MeshSummary`, as `scanmill inspect` prints it), absolute and in % of the input's
//!   diagonal, to check both sides remeshed to the same length.
//!
//! Textures are not loaded: the texture metrics are not among these figures.

use scanmill::mesh::LoadOptions;
use scanmill::mesh::io::load;
use scanmill::mesh::summary::MeshSummary;
use scanmill::metrics::{MetricsOptions, compare};
use scanmill::ops::remesh::quality::AngleQuality;
use std::path::PathBuf;

fn main() {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let [input_path, result_path] = args.as_slice() else {
        eprintln!("usage: remesh_quality INPUT RESULT");
        std::process::exit(2);
    };
    let options = LoadOptions {
        check_textures: false,
        ..LoadOptions::default()
    };
    let (input, _) = load(input_path, &options).unwrap_or_else(|e| {
        eprintln!("{}: {e}", input_path.display());
        std::process::exit(65)
    });
    let (result, report) = load(result_path, &options).unwrap_or_else(|e| {
        eprintln!("{}: {e}", result_path.display());
        std::process::exit(65)
    });
    let metrics = compare(&result, &input, &MetricsOptions::default()).unwrap_or_else(|e| {
        eprintln!("metrics: {e}");
        std::process::exit(1)
    });
    let angles = AngleQuality::of(&result);
    let diagonal = metrics.distance.bbox_diagonal;
    let mean_edge = MeshSummary::new(&result, None).mean_edge_length;
    let line = serde_json::json!({
        "input": input_path,
        "result": result_path,
        "faces": result.triangles.len(),
        "file_faces": report.file_faces,
        "dropped_faces": report.dropped_degenerate_faces
            + report.dropped_zero_area_faces
            + report.dropped_duplicate_faces,
        "angles": angles,
        "distance_mean_pct": 100.0 * metrics.distance.mean_relative,
        "distance_max_pct": 100.0 * metrics.distance.max_relative,
        "result_to_input_mean_pct": 100.0 * metrics.distance.result_to_reference.mean / diagonal,
        "result_to_input_max_pct": 100.0 * metrics.distance.result_to_reference.max / diagonal,
        "input_to_result_max_pct": 100.0 * metrics.distance.reference_to_result.max / diagonal,
        "flipped_faces": metrics.normals.flipped_faces,
        "normal_faces": metrics.normals.faces,
        "input_diagonal": diagonal,
        "mean_edge": mean_edge,
        "mean_edge_pct": 100.0 * mean_edge / diagonal,
    });
    println!("{line}");
}
