//! `scanmill compare`: run several recipes on the same scan and tabulate how far each result
//! is from the clean input, so a lab can choose its smoothing (or any other) recipe on its
//! own scans. With `noise`, the scan is first degraded with the smoothing thesis' noise
//! protocol (smoothing thesis §4.2.2, docs/smoothing.md: Gaussian, σ = k · mean edge length, along the vertex
//! normals by default, seeded) and every result is measured against the clean scan — which
//! is how the thesis' comparison is reproduced.
//!
//! The command line (`src/main.rs`) only parses arguments and prints one of the renderings
//! of [`CompareTable`].

use crate::mesh::{LoadOptions, Mesh, MeshError};
use crate::metrics::noise::{NoiseOptions, NoiseReport, noisy_copy};
use crate::metrics::{FinalMetrics, MetricsError, MetricsOptions, TextureCache, TextureDeviation};
use crate::recipe::Recipe;
use crate::recipe::runner::{NoProgress, run_steps};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    #[error(transparent)]
    Load(#[from] MeshError),
    #[error("measuring `{row}`: {source}")]
    Metrics {
        row: String,
        #[source]
        source: MetricsError,
    },
}

/// A recipe and the name its row carries (the command line uses the file name).
#[derive(Debug, Clone)]
pub struct NamedRecipe {
    pub name: String,
    pub recipe: Recipe,
}

/// How the comparison runs.
#[derive(Debug, Clone, Default)]
pub struct CompareOptions {
    /// Degrade the input first (the thesis' protocol); `None` compares the recipes'
    /// results with the input as loaded.
    pub noise: Option<NoiseOptions>,
    pub metrics: MetricsOptions,
}

/// One row: a recipe's result against the clean input (or the noisy input itself).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct CompareRow {
    pub name: String,
    /// Wall time of the recipe's steps (loading and measuring excluded), milliseconds.
    pub time_ms: f64,
    pub vertices: usize,
    pub faces: usize,
    /// The recipe failed: the step and its message; no figures.
    pub error: Option<String>,
    /// Surface distance to the clean input, both directions pooled, in model units.
    pub distance_mean: Option<f64>,
    pub distance_rms: Option<f64>,
    pub distance_max: Option<f64>,
    /// The same, in percent of the clean input's bounding-box diagonal.
    pub distance_mean_percent: Option<f64>,
    pub distance_rms_percent: Option<f64>,
    pub distance_max_percent: Option<f64>,
    /// One-sided mean distance from the result's surface to the clean one, in percent of
    /// the diagonal: MeshLab's Hausdorff-filter figure.
    pub to_clean_mean_percent: Option<f64>,
    /// The other direction: from the clean surface to the result's. On a rough (noisy)
    /// surface it is the smaller of the two (the closest point finds the nearest bump);
    /// once smoothed, both agree.
    pub from_clean_mean_percent: Option<f64>,
    /// 100 · (V − V_clean) / V_clean; only when both meshes are closed.
    pub volume_change_percent: Option<f64>,
    /// The thesis' distance deviation (offset along the clean vertex normal), mean of
    /// |d_i| and signed mean; only when the recipe kept the connectivity (smoothing).
    pub vertex_offset_abs_mean: Option<f64>,
    pub vertex_offset_signed_mean: Option<f64>,
    /// Angle between face normals and the clean surface's, radians.
    pub angular_mean: Option<f64>,
    pub angular_rms: Option<f64>,
    /// Colour difference of the texture at corresponding surface points (RMS over R, G, B in
    /// 0–255 levels), when both meshes are textured. Smoothing keeps the texture
    /// coordinates, so a vertex that slides along the surface drags the texture with it:
    /// this column shows that tangential drift.
    pub texture_mean: Option<f64>,
    /// Every figure, as the report carries them (JSON only).
    pub metrics: Option<FinalMetrics>,
}

impl CompareRow {
    fn new(name: &str, mesh: &Mesh, time_ms: f64) -> CompareRow {
        CompareRow {
            name: name.to_string(),
            time_ms,
            vertices: mesh.positions.len(),
            faces: mesh.triangles.len(),
            ..CompareRow::default()
        }
    }

    fn fill(&mut self, m: FinalMetrics) {
        let d = &m.distance;
        let diagonal = d.bbox_diagonal;
        let percent = |x: f64| {
            if diagonal > 0.0 {
                100.0 * x / diagonal
            } else {
                0.0
            }
        };
        self.distance_mean = Some(d.mean);
        self.distance_rms = Some(d.rms);
        self.distance_max = Some(d.max);
        self.distance_mean_percent = Some(percent(d.mean));
        self.distance_rms_percent = Some(percent(d.rms));
        self.distance_max_percent = Some(percent(d.max));
        self.to_clean_mean_percent = Some(percent(d.result_to_reference.mean));
        self.from_clean_mean_percent = Some(percent(d.reference_to_result.mean));
        self.volume_change_percent = m.volume.change_percent;
        self.vertex_offset_abs_mean = m.vertex_deviation.map(|v| v.abs_mean);
        self.vertex_offset_signed_mean = m.vertex_deviation.map(|v| v.signed_mean);
        self.angular_mean = Some(m.normals.mean);
        self.angular_rms = Some(m.normals.rms);
        self.texture_mean = match &m.texture {
            TextureDeviation::Measured { mean, .. } => Some(*mean),
            TextureDeviation::Skipped { .. } => None,
        };
        self.metrics = Some(m);
    }
}

/// The comparison: the input, the noise applied, and one row per recipe (after a first row
/// for the noisy input itself when noise was added).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CompareTable {
    pub input: String,
    pub vertices: usize,
    pub faces: usize,
    pub bbox_diagonal: f64,
    pub noise: Option<NoiseReport>,
    pub samples: usize,
    pub rows: Vec<CompareRow>,
}

/// Loads `input` and compares `recipes` on it, on a thread of rayon's pool as a job runs
/// ([`crate::process::on_pool`]), so that the times are a job's.
pub fn run(
    input: &Path,
    recipes: &[NamedRecipe],
    options: &CompareOptions,
) -> Result<CompareTable, CompareError> {
    crate::process::on_pool(|| {
        let load = LoadOptions::default();
        let (clean, _) = crate::mesh::load(input, &load)?;
        run_on_mesh(&clean, &input.display().to_string(), recipes, options)
    })
}

/// Compares `recipes` on an already loaded clean mesh (tests share one load this way).
pub fn run_on_mesh(
    clean: &Mesh,
    input_name: &str,
    recipes: &[NamedRecipe],
    options: &CompareOptions,
) -> Result<CompareTable, CompareError> {
    let mut cache = TextureCache::new();
    let measure = |row: &mut CompareRow, result: &Mesh, cache: &mut TextureCache| {
        let m = crate::metrics::compare_with_cache(result, clean, &options.metrics, cache)
            .map_err(|source| CompareError::Metrics {
                row: row.name.clone(),
                source,
            })?;
        row.fill(m);
        Ok::<(), CompareError>(())
    };
    let mut rows = Vec::with_capacity(recipes.len() + 1);
    let (start_mesh, noise) = match &options.noise {
        Some(noise) => {
            let (noisy, report) = noisy_copy(clean, noise);
            let mut row = CompareRow::new("input + noise", &noisy, 0.0);
            measure(&mut row, &noisy, &mut cache)?;
            rows.push(row);
            (noisy, Some(report))
        }
        None => (clean.clone(), None),
    };
    for named in recipes {
        let mut mesh = start_mesh.clone();
        if crate::process::renumbers_anyway(&named.recipe) {
            // Numbered as `scanmill process` numbers the scan for this recipe, as part of
            // the load (outside the steps' time): the row is what `process` would make.
            mesh.reorder_for_locality();
        }
        let start = Instant::now();
        let outcome = run_steps(
            &named.recipe,
            &mut mesh,
            &NoProgress,
            0,
            named.recipe.steps.len(),
        );
        let time_ms = start.elapsed().as_secs_f64() * 1e3;
        let mut row = CompareRow::new(&named.name, &mesh, time_ms);
        match outcome {
            Ok(_) => measure(&mut row, &mesh, &mut cache)?,
            Err(e) => row.error = Some(e.to_string()),
        }
        tracing::info!(recipe = %named.name, time_ms, "compared");
        rows.push(row);
    }
    Ok(CompareTable {
        input: input_name.to_string(),
        vertices: clean.positions.len(),
        faces: clean.triangles.len(),
        bbox_diagonal: clean.bounding_box_diagonal(),
        noise,
        samples: options.metrics.samples,
        rows,
    })
}

/// Column headings and how each row's cell is printed (text and CSV share them).
type Cell = fn(&CompareRow) -> Option<String>;

fn fixed(x: Option<f64>, digits: usize) -> Option<String> {
    x.map(|v| format!("{v:.digits$}"))
}

fn sci(x: Option<f64>) -> Option<String> {
    x.map(|v| format!("{v:.4e}"))
}

const COLUMNS: &[(&str, Cell)] = &[
    ("recipe", |r| Some(r.name.clone())),
    ("time_ms", |r| fixed(Some(r.time_ms), 1)),
    ("faces", |r| Some(r.faces.to_string())),
    ("dist_mean_%", |r| fixed(r.distance_mean_percent, 4)),
    ("dist_rms_%", |r| fixed(r.distance_rms_percent, 4)),
    ("dist_max_%", |r| fixed(r.distance_max_percent, 4)),
    ("to_clean_mean_%", |r| fixed(r.to_clean_mean_percent, 4)),
    ("from_clean_mean_%", |r| fixed(r.from_clean_mean_percent, 4)),
    ("volume_%", |r| fixed(r.volume_change_percent, 3)),
    ("offset_abs_mean", |r| sci(r.vertex_offset_abs_mean)),
    ("offset_signed_mean", |r| sci(r.vertex_offset_signed_mean)),
    ("angle_mean_rad", |r| fixed(r.angular_mean, 4)),
    ("angle_rms_rad", |r| fixed(r.angular_rms, 4)),
    ("texture_mean", |r| fixed(r.texture_mean, 4)),
    ("error", |r| r.error.clone()),
];

impl CompareTable {
    /// An aligned plain-text table with a heading that says what was compared.
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{}: {} vertices, {} faces, bounding-box diagonal {:.6}",
            self.input, self.vertices, self.faces, self.bbox_diagonal
        );
        match &self.noise {
            Some(n) => {
                let _ = writeln!(
                    out,
                    "noise: σ = {:.6} ({:.3} × mean edge {:.6}), {:?}, seed {}; figures against the clean input",
                    n.sigma,
                    if n.mean_edge_length > 0.0 {
                        n.sigma / n.mean_edge_length
                    } else {
                        0.0
                    },
                    n.mean_edge_length,
                    n.direction,
                    n.seed
                );
            }
            None => {
                let _ = writeln!(out, "no noise; figures against the input");
            }
        }
        let _ = writeln!(
            out,
            "distances in % of the diagonal ({} samples per side); volume change in %; angles in radians",
            self.samples
        );
        let error_column = self.rows.iter().any(|r| r.error.is_some());
        let columns: Vec<&(&str, Cell)> = COLUMNS
            .iter()
            .filter(|(name, _)| *name != "error" || error_column)
            .collect();
        let cells: Vec<Vec<String>> = self
            .rows
            .iter()
            .map(|r| {
                columns
                    .iter()
                    .map(|(_, cell)| cell(r).unwrap_or_else(|| "–".into()))
                    .collect()
            })
            .collect();
        let widths: Vec<usize> = columns
            .iter()
            .enumerate()
            .map(|(c, (name, _))| {
                cells
                    .iter()
                    .map(|row| row[c].chars().count())
                    .chain([name.len()])
                    .max()
                    .unwrap_or(0)
            })
            .collect();
        let line = |out: &mut String, values: Vec<&str>| {
            let parts: Vec<String> = values
                .iter()
                .enumerate()
                .map(|(c, v)| {
                    let pad = widths[c].saturating_sub(v.chars().count());
                    if c == 0 {
                        format!("{v}{}", " ".repeat(pad))
                    } else {
                        format!("{}{v}", " ".repeat(pad))
                    }
                })
                .collect();
            let _ = writeln!(out, "{}", parts.join("  ").trim_end());
        };
        line(&mut out, columns.iter().map(|(name, _)| *name).collect());
        for row in &cells {
            line(&mut out, row.iter().map(String::as_str).collect());
        }
        out
    }

    /// The whole table with every metric, as JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("the table always serialises")
    }

    /// One header line and one line per row; empty cells for figures that do not apply.
    pub fn to_csv(&self) -> String {
        let quote = |s: String| {
            if s.contains([',', '"', '\n']) {
                format!("\"{}\"", s.replace('"', "\"\""))
            } else {
                s
            }
        };
        let mut out = String::new();
        let header: Vec<&str> = COLUMNS.iter().map(|(name, _)| *name).collect();
        let _ = writeln!(out, "{}", header.join(","));
        for r in &self.rows {
            let cells: Vec<String> = COLUMNS
                .iter()
                .map(|(_, cell)| quote(cell(r).unwrap_or_default()))
                .collect();
            let _ = writeln!(out, "{}", cells.join(","));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::uv_sphere;
    use crate::testing::on_threads;
    use std::path::Path;

    fn recipe(text: &str) -> Recipe {
        Recipe::from_toml(text, Path::new("r.toml")).unwrap()
    }

    fn table() -> CompareTable {
        let clean = uv_sphere(1.0, 30, 60);
        let recipes = [
            NamedRecipe {
                name: "laplace".into(),
                recipe: recipe(
                    "[[step]]\nkind = \"smooth\"\nmethod = \"laplace\"\nlambda = 1.0\niterations = 10\n",
                ),
            },
            NamedRecipe {
                name: "taubin, pairs".into(),
                recipe: recipe("[[step]]\nkind = \"smooth\"\nmethod = \"taubin\"\n"),
            },
        ];
        let options = CompareOptions {
            noise: Some(NoiseOptions::default()),
            metrics: MetricsOptions {
                samples: 5_000,
                ..Default::default()
            },
        };
        run_on_mesh(&clean, "sphere", &recipes, &options).unwrap()
    }

    /// A decimating recipe is run on the scan numbered as `scanmill process` numbers it
    /// (here a sphere whose vertices and triangles are listed in reverse order).
    #[test]
    fn a_decimating_row_is_what_process_makes() {
        let mut scrambled = uv_sphere(1.0, 30, 60);
        scrambled.positions.reverse();
        let n = scrambled.positions.len() as u32;
        for w in &mut scrambled.wedges {
            w.vertex = n - 1 - w.vertex;
        }
        scrambled.triangles.reverse();
        let decimate = recipe("[[step]]\nkind = \"decimate\"\ntarget_faces = 600\n");
        let options = CompareOptions {
            noise: None,
            metrics: MetricsOptions {
                samples: 2_000,
                ..Default::default()
            },
        };
        let named = [NamedRecipe {
            name: "decimate".into(),
            recipe: decimate.clone(),
        }];
        let row = run_on_mesh(&scrambled, "sphere", &named, &options)
            .unwrap()
            .rows
            .remove(0);
        // What `process` makes: the steps on the scan renumbered, measured against the scan.
        let measured = |steps_on: &Mesh| {
            let mut result = steps_on.clone();
            run_steps(&decimate, &mut result, &NoProgress, 0, 1).unwrap();
            let mut expected = CompareRow::new("decimate", &result, 0.0);
            expected.fill(
                crate::metrics::compare_with_cache(
                    &result,
                    &scrambled,
                    &options.metrics,
                    &mut TextureCache::new(),
                )
                .unwrap(),
            );
            expected
        };
        let mut renumbered = scrambled.clone();
        renumbered.reorder_for_locality();
        let process = measured(&renumbered);
        assert_eq!(row.faces, process.faces);
        assert_eq!(row.distance_mean, process.distance_mean);
        // The file's order decimates differently (so the test can tell).
        assert_ne!(measured(&scrambled).distance_mean, process.distance_mean);
    }

    #[test]
    fn table_rows_and_renderings() {
        let t = table();
        assert_eq!(t.rows.len(), 3);
        assert_eq!(t.rows[0].name, "input + noise");
        let noisy = t.rows[0].distance_mean.unwrap();
        let taubin = t.rows[2].distance_mean.unwrap();
        assert!(taubin < noisy, "{taubin} vs {noisy}");
        // Laplace with λ = 1 shrinks; Taubin nearly keeps the volume.
        let (lv, tv) = (
            t.rows[1].volume_change_percent.unwrap(),
            t.rows[2].volume_change_percent.unwrap(),
        );
        assert!(lv < -1.0 && tv.abs() < lv.abs() / 5.0, "{lv} {tv}");
        assert!(t.rows[2].vertex_offset_abs_mean.is_some());

        let text = t.to_text();
        assert!(
            text.contains("taubin, pairs") && text.contains("volume_%"),
            "{text}"
        );
        let csv = t.to_csv();
        assert_eq!(csv.lines().count(), 4);
        assert!(csv.contains("\"taubin, pairs\""), "{csv}");
        let json: serde_json::Value = serde_json::from_str(&t.to_json()).unwrap();
        assert_eq!(json["rows"].as_array().unwrap().len(), 3);
        assert!(json["noise"]["sigma"].as_f64().unwrap() > 0.0);
    }

    #[test]
    fn deterministic_across_thread_counts() {
        let (a, b) = (on_threads(1, table), on_threads(3, table));
        let strip = |t: &CompareTable| {
            t.rows
                .iter()
                .map(|r| (r.distance_mean, r.volume_change_percent, r.angular_mean))
                .collect::<Vec<_>>()
        };
        assert_eq!(strip(&a), strip(&b));
    }
}
