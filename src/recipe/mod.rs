//! The recipe: which steps run on a scan, in which order, with which parameters
//! (TOML, see DESIGN.md "Recipe file"). Unknown keys and kinds are errors that name the
//! file, the line and the valid choices (serde + toml give us that for free).

pub mod runner;

use crate::ops::normals::NormalsParams;
use crate::ops::smooth::SmoothParams;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum RecipeError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {message}")]
    Parse { path: PathBuf, message: String },
    #[error(
        "{path}: line {line}: step kind `{kind}` is not implemented in this version of scanmill"
    )]
    NotImplemented {
        path: PathBuf,
        line: usize,
        kind: &'static str,
    },
    #[error("{path}: line {line}: step `{kind}`: {message}")]
    Invalid {
        path: PathBuf,
        line: usize,
        kind: &'static str,
        message: String,
    },
}

/// Output file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum OutputFormat {
    #[default]
    Obj,
    Ply,
}

/// PLY encoding on output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum PlyEncodingSpec {
    Ascii,
    #[default]
    BinaryLittleEndian,
    BinaryBigEndian,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    #[serde(default)]
    pub format: OutputFormat,
    #[serde(default)]
    pub ply_encoding: PlyEncodingSpec,
}

/// How the input is loaded.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InputSpec {
    /// Weld vertices closer than this fraction of the bounding-box diagonal (0 = bit-exact).
    pub weld_tolerance: f64,
}

impl Default for InputSpec {
    fn default() -> Self {
        InputSpec {
            weld_tolerance: 0.0,
        }
    }
}

/// Parameters of a step kind that this version does not implement yet. Parsed so that the
/// error can name the step and its line rather than "unknown variant".
pub type PendingParams = toml::Table;

/// One processing step. The variant name is the recipe's `kind`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Step {
    Crop(PendingParams),
    Relax(PendingParams),
    Fair(PendingParams),
    Smooth(SmoothParams),
    Decimate(PendingParams),
    SeamFix(PendingParams),
    Normals(NormalsParams),
}

impl Step {
    pub fn kind(&self) -> &'static str {
        match self {
            Step::Crop(_) => "crop",
            Step::Relax(_) => "relax",
            Step::Fair(_) => "fair",
            Step::Smooth(_) => "smooth",
            Step::Decimate(_) => "decimate",
            Step::SeamFix(_) => "seam_fix",
            Step::Normals(_) => "normals",
        }
    }

    fn is_implemented(&self) -> bool {
        matches!(self, Step::Normals(_) | Step::Smooth(_))
    }

    fn validate(&self) -> Result<(), String> {
        match self {
            Step::Normals(p) => p.validate(),
            Step::Smooth(p) => p.validate(),
            _ => Ok(()),
        }
    }
}

/// The file as written, with the spans of its steps for error messages.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RecipeFile {
    #[serde(default)]
    output: OutputSpec,
    #[serde(default)]
    input: InputSpec,
    #[serde(default)]
    step: Vec<toml::Spanned<Step>>,
}

/// A parsed, validated recipe.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Recipe {
    pub output: OutputSpec,
    pub input: InputSpec,
    pub steps: Vec<Step>,
}

impl Recipe {
    pub fn from_path(path: &Path) -> Result<Recipe, RecipeError> {
        let text = std::fs::read_to_string(path).map_err(|source| RecipeError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Recipe::from_toml(&text, path)
    }

    /// Parses recipe text; `path` is only used in messages.
    pub fn from_toml(text: &str, path: &Path) -> Result<Recipe, RecipeError> {
        let file: RecipeFile = toml::from_str(text).map_err(|e| RecipeError::Parse {
            path: path.to_path_buf(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let line_of = |offset: usize| text[..offset.min(text.len())].matches('\n').count() + 1;
        let mut steps = Vec::with_capacity(file.step.len());
        for spanned in file.step {
            let line = line_of(spanned.span().start);
            let step = spanned.into_inner();
            if !step.is_implemented() {
                return Err(RecipeError::NotImplemented {
                    path: path.to_path_buf(),
                    line,
                    kind: step.kind(),
                });
            }
            step.validate().map_err(|message| RecipeError::Invalid {
                path: path.to_path_buf(),
                line,
                kind: step.kind(),
                message,
            })?;
            steps.push(step);
        }
        Ok(Recipe {
            output: file.output,
            input: file.input,
            steps,
        })
    }

    /// The resolved recipe (defaults filled in) as JSON, the form that is hashed and recorded.
    pub fn resolved_json(&self) -> serde_json::Value {
        serde_json::to_value(self).expect("a recipe always serialises")
    }

    /// SHA-256 of the resolved recipe: the same settings give the same hash whatever the
    /// file's layout, comments or key order.
    pub fn hash(&self) -> String {
        let canonical = serde_json::to_string(&self.resolved_json()).expect("json");
        hex::encode(Sha256::digest(canonical.as_bytes()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Recipe, RecipeError> {
        Recipe::from_toml(text, Path::new("r.toml"))
    }

    #[test]
    fn parses_normals_with_defaults() {
        let r = parse("[output]\nformat = \"ply\"\n[[step]]\nkind = \"normals\"\n").unwrap();
        assert_eq!(r.output.format, OutputFormat::Ply);
        assert_eq!(r.steps.len(), 1);
        assert_eq!(r.steps[0].kind(), "normals");
    }

    #[test]
    fn unknown_kind_names_line_and_choices() {
        let e = parse("[output]\nformat = \"obj\"\n\n[[step]]\nkind = \"sharpen\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 5"), "{e}");
        assert!(
            e.contains("sharpen") && e.contains("normals") && e.contains("decimate"),
            "{e}"
        );
    }

    #[test]
    fn unknown_key_is_an_error() {
        let e = parse("[[step]]\nkind = \"normals\"\ncrease = 30\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("crease") && e.contains("crease_angle"), "{e}");
        let e = parse("[output]\nformat = \"stl\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("stl") && e.contains("obj"), "{e}");
    }

    #[test]
    fn pending_kind_is_a_clear_error() {
        let e = parse(
            "[[step]]\nkind = \"normals\"\n\n[[step]]\nkind = \"decimate\"\ntarget_faces = 26000\n",
        )
        .unwrap_err();
        match e {
            RecipeError::NotImplemented { line, kind, .. } => {
                assert_eq!(kind, "decimate");
                assert_eq!(line, 4);
            }
            other => panic!("unexpected {other}"),
        }
    }

    #[test]
    fn hash_ignores_layout_but_not_values() {
        let a = parse("[[step]]\nkind = \"normals\"\n").unwrap();
        let b =
            parse("# comment\n[[step]]\n  kind = \"normals\"\n  weighting = \"area\"\n").unwrap();
        let c = parse("[[step]]\nkind = \"normals\"\ncrease_angle = 40.0\n").unwrap();
        assert_eq!(a.hash(), b.hash());
        assert_ne!(a.hash(), c.hash());
    }
}
