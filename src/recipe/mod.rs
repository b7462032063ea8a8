//! The recipe: which steps run on a scan, in which order, with which parameters (TOML; the
//! README's recipe reference and docs/architecture.md "Parameters"). Unknown keys and kinds
//! are errors that name the file, the line and the valid choices (serde + toml give us that
//! for free).

pub mod runner;
pub mod step;

use crate::metrics::MetricsOptions;
use crate::ops::crop::CropParams;
use crate::ops::decimate::DecimateParams;
use crate::ops::fair::{FairParams, RelaxParams};
use crate::ops::normals::NormalsParams;
use crate::ops::remesh::RemeshParams;
use crate::ops::seam_fix::SeamFixParams;
use crate::ops::smooth::SmoothParams;
use crate::preview::PreviewOptions;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// Paths are shown escaped (a newline in a file name must not split the one-line error).
#[derive(Debug, thiserror::Error)]
pub enum RecipeError {
    #[error("{}: {source}", crate::text::escape_path(path))]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}: {message}", crate::text::escape_path(path))]
    Parse { path: PathBuf, message: String },
    #[error(
        "{}: line {line}: step `{kind}`: {message}",
        crate::text::escape_path(path)
    )]
    Invalid {
        path: PathBuf,
        line: usize,
        kind: String,
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
    /// Binary glTF with its textures inside (for web viewers).
    Glb,
}

impl OutputFormat {
    pub const ALL: [OutputFormat; 3] = [OutputFormat::Obj, OutputFormat::Ply, OutputFormat::Glb];

    /// The name in a recipe, which is also the output file's extension.
    pub fn name(self) -> &'static str {
        match self {
            OutputFormat::Obj => "obj",
            OutputFormat::Ply => "ply",
            OutputFormat::Glb => "glb",
        }
    }

    fn from_name(name: &str) -> Result<OutputFormat, String> {
        Self::ALL
            .into_iter()
            .find(|f| f.name() == name)
            .ok_or_else(|| {
                format!("unknown output format {name:?}, expected one of \"obj\", \"ply\", \"glb\"")
            })
    }
}

/// The formats a job writes, in order, each once: `format = "obj"` or
/// `format = ["obj", "glb"]`. A single format is serialised as a plain string, so that the
/// resolved form and hash of a recipe written before lists were allowed stay the same.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OutputFormats(Vec<OutputFormat>);

impl OutputFormats {
    /// The formats; never empty, no repeats.
    pub fn list(&self) -> &[OutputFormat] {
        &self.0
    }

    /// Checks and wraps a list (non-empty, no format twice).
    pub fn new(formats: Vec<OutputFormat>) -> Result<OutputFormats, String> {
        if formats.is_empty() {
            return Err("format lists no output format".into());
        }
        for (i, f) in formats.iter().enumerate() {
            if formats[..i].contains(f) {
                return Err(format!("format lists {:?} twice", f.name()));
            }
        }
        Ok(OutputFormats(formats))
    }
}

impl Default for OutputFormats {
    fn default() -> Self {
        OutputFormats(vec![OutputFormat::Obj])
    }
}

impl From<OutputFormat> for OutputFormats {
    fn from(f: OutputFormat) -> Self {
        OutputFormats(vec![f])
    }
}

impl Serialize for OutputFormats {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self.0.as_slice() {
            [one] => one.serialize(s),
            many => many.serialize(s),
        }
    }
}

impl<'de> Deserialize<'de> for OutputFormats {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = OutputFormats;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a format name or a list of them, e.g. [\"obj\", \"glb\"]")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Self::Value, E> {
                OutputFormat::from_name(v)
                    .map(OutputFormats::from)
                    .map_err(E::custom)
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<Self::Value, A::Error> {
                let mut formats = Vec::new();
                // Bounded by the three formats there are: a longer list repeats one.
                while let Some(name) = seq.next_element::<String>()? {
                    formats.push(OutputFormat::from_name(&name).map_err(serde::de::Error::custom)?);
                    if formats.len() > OutputFormat::ALL.len() {
                        break;
                    }
                }
                OutputFormats::new(formats).map_err(serde::de::Error::custom)
            }
        }
        d.deserialize_any(Visitor)
    }
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
    pub format: OutputFormats,
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

/// Largest `weld_tolerance`: a tenth of the bounding-box diagonal already merges whole
/// features of a scan; more is a typo, not a setting.
pub const MAX_WELD_TOLERANCE: f64 = 0.1;

impl InputSpec {
    pub fn validate(&self) -> Result<(), String> {
        validate_weld_tolerance(self.weld_tolerance)
    }
}

/// `weld_tolerance` must be a finite number in 0..=[`MAX_WELD_TOLERANCE`].
pub fn validate_weld_tolerance(t: f64) -> Result<(), String> {
    if t.is_finite() && (0.0..=MAX_WELD_TOLERANCE).contains(&t) {
        Ok(())
    } else {
        Err(format!(
            "weld_tolerance must be a fraction of the bounding-box diagonal in 0..={MAX_WELD_TOLERANCE}, not {t}"
        ))
    }
}

/// One processing step. The variant name is the recipe's `kind`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Step {
    Crop(CropParams),
    Relax(RelaxParams),
    Fair(FairParams),
    Smooth(SmoothParams),
    Decimate(DecimateParams),
    Remesh(RemeshParams),
    SeamFix(SeamFixParams),
    Normals(NormalsParams),
}

impl Step {
    /// The recipe's `kind` of this step, from serde (the variant's snake_case name).
    pub fn kind(&self) -> String {
        match serde_json::to_value(self) {
            Ok(serde_json::Value::Object(map)) => match map.get("kind") {
                Some(serde_json::Value::String(kind)) => kind.clone(),
                _ => unreachable!("a step serialises with its kind"),
            },
            _ => unreachable!("a step serialises as a table"),
        }
    }

    fn validate(&self) -> Result<(), String> {
        match self {
            Step::Normals(p) => p.validate(),
            Step::Crop(p) => p.validate(),
            Step::Decimate(p) => p.validate(),
            Step::Remesh(p) => p.validate(),
            Step::SeamFix(p) => p.validate(),
            Step::Relax(p) => p.validate(),
            Step::Fair(p) => p.validate(),
            Step::Smooth(p) => p.validate(),
        }
    }
}

/// The `[metrics]` table: quality metrics of the result against the input (and, for steps
/// with `metrics = true`, of the step's result against its own input).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MetricsSpec {
    /// Compute the final metrics: the largest part of the run after the steps on a large scan
    /// (their cost is measured in docs/face-scan.md).
    pub enabled: bool,
    /// Surface samples per direction.
    pub samples: usize,
    pub seed: u64,
    /// Cracks: result boundary edges farther than this many mean input edge lengths from
    /// every input boundary edge.
    pub crack_distance_factor: f64,
}

impl Default for MetricsSpec {
    fn default() -> Self {
        let o = MetricsOptions::default();
        MetricsSpec {
            enabled: true,
            samples: o.samples,
            seed: o.seed,
            crack_distance_factor: o.crack_distance_factor,
        }
    }
}

impl MetricsSpec {
    pub fn options(&self) -> MetricsOptions {
        MetricsOptions {
            samples: self.samples,
            seed: self.seed,
            crack_distance_factor: self.crack_distance_factor,
        }
    }
}

/// The file as written, with the spans of its steps for error messages. Steps are read as
/// tables first so that the `metrics` key, which every step kind accepts, can be taken out
/// before the step's own parameters are checked.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RecipeFile {
    #[serde(default)]
    output: OutputSpec,
    #[serde(default)]
    input: InputSpec,
    #[serde(default)]
    metrics: MetricsSpec,
    #[serde(default)]
    preview: PreviewOptions,
    #[serde(default)]
    experimental: Experimental,
    #[serde(default)]
    step: Vec<toml::Spanned<toml::Table>>,
}

/// The `[experimental]` table: research-only switches, one sub-table per step kind that has
/// any. Not part of the resolved recipe itself: each switch is recorded in the steps it
/// applies to (where it was before it moved here, so that hashes stayed the same).
#[derive(Debug, Clone, Copy, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct Experimental {
    #[serde(default)]
    decimate: crate::ops::decimate::Experimental,
}

impl Experimental {
    /// The step with the switches that apply to it.
    fn apply(&self, step: Step) -> Step {
        match step {
            Step::Decimate(p) => Step::Decimate(p.with_experimental(self.decimate)),
            other => other,
        }
    }
}

/// A research-only key written in a step's own table: the line and the message saying
/// where it moved.
fn moved_to_experimental(
    text: &str,
    header_end: usize,
    table: &toml::Table,
) -> Option<(Option<usize>, String)> {
    if table.get("kind").and_then(toml::Value::as_str) != Some("decimate") {
        return None;
    }
    let keys = crate::ops::decimate::Experimental::keys();
    let key = keys.iter().find(|k| table.contains_key(k.as_str()))?;
    let line = line_in_table(text, header_end, |l| {
        l.strip_prefix(key.as_str())
            .is_some_and(|after| after.trim_start().starts_with('='))
    });
    Some((
        line,
        format!("`{key}` is research-only and moved to the recipe's [experimental.decimate] table"),
    ))
}

/// The 1-based line of the first line of the table whose header ends at `header_end` that
/// `matches` (toml spans an array-of-tables element by its `[[step]]` header only, so the
/// table runs to the next header).
fn line_in_table(text: &str, header_end: usize, matches: impl Fn(&str) -> bool) -> Option<usize> {
    let start = header_end.min(text.len());
    let mut offset = start;
    for line in text[start..].split_inclusive('\n') {
        let rest = line.trim_start();
        if rest.starts_with('[') {
            break;
        }
        if matches(rest) {
            return Some(text[..offset].matches('\n').count() + 1);
        }
        offset += line.len();
    }
    None
}

/// The line a step's deserialisation error is about: the unknown key's, or the line
/// holding the unknown variant's value.
fn error_line(text: &str, header_end: usize, message: &str) -> Option<usize> {
    let quoted = |prefix: &str| {
        message
            .strip_prefix(prefix)
            .and_then(|rest| rest.split('`').next())
            .map(str::to_string)
    };
    if let Some(key) = quoted("unknown field `") {
        return line_in_table(text, header_end, |l| {
            l.strip_prefix(key.as_str())
                .is_some_and(|after| after.trim_start().starts_with('='))
        });
    }
    let value = quoted("unknown variant `")?;
    line_in_table(text, header_end, |l| {
        l.contains(&format!("\"{value}\"")) || l.contains(&format!("'{value}'"))
    })
}

/// Largest recipe or configuration file read: they are a few KiB; the cap bounds what a
/// wrong path (`recipe = "/dev/zero"`) can cost.
pub const MAX_SETTINGS_FILE_BYTES: u64 = 1 << 20;

/// Reads a recipe or configuration file as UTF-8 text: a regular file (a FIFO or device is
/// refused before it is opened, and again from the open file, which is opened non-blocking so
/// that a FIFO swapped in between cannot block) of at most [`MAX_SETTINGS_FILE_BYTES`].
pub fn read_settings_file(path: &Path) -> std::io::Result<String> {
    use std::io::{Error, ErrorKind, Read};
    use std::os::unix::fs::OpenOptionsExt;
    let regular = |meta: &std::fs::Metadata| {
        if meta.is_file() {
            Ok(())
        } else {
            Err(Error::new(
                ErrorKind::InvalidInput,
                "not a regular file; refusing to read it",
            ))
        }
    };
    regular(&std::fs::metadata(path)?)?;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK | libc::O_NOCTTY)
        .open(path)?;
    regular(&file.metadata()?)?;
    let mut bytes = Vec::new();
    file.take(MAX_SETTINGS_FILE_BYTES + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > MAX_SETTINGS_FILE_BYTES {
        return Err(Error::new(
            ErrorKind::InvalidData,
            format!("larger than {MAX_SETTINGS_FILE_BYTES} bytes; refusing to read it"),
        ));
    }
    String::from_utf8(bytes)
        .map_err(|_| Error::new(ErrorKind::InvalidData, "stream did not contain valid UTF-8"))
}

/// A TOML error as one line, "line 5: unknown variant `sharpen`, expected one of …": the
/// toml crate's own rendering spans several lines (a source excerpt with a caret), which would
/// break a log record or a job's error text in two.
pub fn toml_error_message(text: &str, e: &toml::de::Error) -> String {
    let message = e.message().trim().replace(['\n', '\r'], " ");
    match e.span() {
        Some(span) => {
            // Bytes, not `str` slicing: a span need not start on a character boundary.
            let before = &text.as_bytes()[..span.start.min(text.len())];
            let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
            format!("line {line}: {message}")
        }
        None => message,
    }
}

/// A parsed, validated recipe.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Recipe {
    pub output: OutputSpec,
    pub input: InputSpec,
    pub metrics: MetricsSpec,
    /// The `[preview]` table. Left out of the resolved form (and so of the hash) while it
    /// has its defaults, so that recipes written before previews existed keep their hash.
    #[serde(skip_serializing_if = "PreviewOptions::is_default")]
    pub preview: PreviewOptions,
    pub steps: Vec<Step>,
    /// 1-based indices of the steps that asked for their own metrics (`metrics = true`).
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub step_metrics: Vec<usize>,
}

impl Recipe {
    pub fn from_path(path: &Path) -> Result<Recipe, RecipeError> {
        let text = read_settings_file(path).map_err(|source| RecipeError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Recipe::from_toml(&text, path)
    }

    /// Parses recipe text; `path` is only used in messages.
    pub fn from_toml(text: &str, path: &Path) -> Result<Recipe, RecipeError> {
        let line_of = |offset: usize| text[..offset.min(text.len())].matches('\n').count() + 1;
        let file: RecipeFile = toml::from_str(text).map_err(|e| RecipeError::Parse {
            path: path.to_path_buf(),
            message: toml_error_message(text, &e),
        })?;
        let parse_error = |line: usize, message: String| RecipeError::Parse {
            path: path.to_path_buf(),
            message: format!("line {line}: {}", message.trim().replace('\n', " ")),
        };
        file.metrics
            .options()
            .validate()
            .map_err(|message| parse_error(line_of(0), format!("[metrics]: {message}")))?;
        file.preview
            .validate()
            .map_err(|message| parse_error(line_of(0), format!("[preview]: {message}")))?;
        file.input.validate().map_err(|message| {
            let line = text.find("weld_tolerance").map_or(1, line_of);
            parse_error(line, format!("[input]: {message}"))
        })?;
        let mut steps = Vec::with_capacity(file.step.len());
        let mut step_metrics = Vec::new();
        for spanned in file.step {
            let line = line_of(spanned.span().start);
            let spanned_range = spanned.span();
            let mut table = spanned.into_inner();
            match table.remove("metrics") {
                None | Some(toml::Value::Boolean(false)) => {}
                Some(toml::Value::Boolean(true)) => step_metrics.push(steps.len() + 1),
                Some(other) => {
                    return Err(parse_error(
                        line,
                        format!("`metrics` must be true or false, got {other}"),
                    ));
                }
            }
            let step_line = line;
            if let Some((line, message)) = moved_to_experimental(text, spanned_range.end, &table) {
                return Err(parse_error(line.unwrap_or(step_line), message));
            }
            let step = Step::deserialize(toml::Value::Table(table)).map_err(|e| {
                let message = e.message().to_string();
                // Point at the offending key's line where the message names one.
                let line = error_line(text, spanned_range.end, &message).unwrap_or(line);
                parse_error(line, message)
            })?;
            let step = file.experimental.apply(step);
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
            metrics: file.metrics,
            preview: file.preview,
            steps,
            step_metrics,
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

    /// Each recipe text is refused with a message that names every one of its snippets.
    fn assert_refused(cases: &[(&str, &[&str])]) {
        for (text, snippets) in cases {
            let e = parse(text).unwrap_err().to_string();
            assert!(snippets.iter().all(|s| e.contains(s)), "{text:?}: {e}");
        }
    }

    /// A `[[step]]` table of `kind` with the lines `rest`.
    fn step(kind: &str, rest: &str) -> String {
        format!("[[step]]\nkind = \"{kind}\"\n{rest}")
    }

    /// Each recipe text hashes to its hash.
    fn assert_hashes(cases: &[(String, &str)]) {
        for (text, hash) in cases {
            assert_eq!(parse(text).unwrap().hash(), *hash, "{text}");
        }
    }

    #[test]
    fn weld_tolerance_is_range_checked() {
        assert!(parse("[input]\nweld_tolerance = 0.001\n").is_ok());
        assert!(parse("[input]\nweld_tolerance = 0.1\n").is_ok());
        for bad in ["-0.001", "0.5", "nan", "inf", "1e300"] {
            let e = parse(&format!("# c\n[input]\nweld_tolerance = {bad}\n")).unwrap_err();
            let text = e.to_string();
            assert!(matches!(e, RecipeError::Parse { .. }), "{bad}: {text}");
            assert!(
                text.contains("r.toml: line 3: [input]: weld_tolerance must be"),
                "{bad}: {text}"
            );
        }
    }

    #[test]
    fn parses_normals_with_defaults() {
        let r = parse("[output]\nformat = \"ply\"\n[[step]]\nkind = \"normals\"\n").unwrap();
        assert_eq!(r.output.format, OutputFormat::Ply.into());
        assert_eq!(r.steps.len(), 1);
        assert_eq!(r.steps[0].kind(), "normals");
    }

    #[test]
    fn output_format_is_a_name_or_a_list() {
        let one = parse("[output]\nformat = \"obj\"\n").unwrap();
        let list = parse("[output]\nformat = [\"obj\", \"glb\"]\n").unwrap();
        assert_eq!(
            list.output.format.list(),
            [OutputFormat::Obj, OutputFormat::Glb]
        );
        // A single format keeps the resolved form (and hash) it always had.
        assert_eq!(one.resolved_json()["output"]["format"], "obj");
        assert_eq!(one.hash(), parse("").unwrap().hash());
        assert_eq!(
            list.resolved_json()["output"]["format"],
            serde_json::json!(["obj", "glb"])
        );
        for (bad, says) in [
            ("[]", "no output format"),
            ("[\"obj\", \"obj\"]", "\"obj\" twice"),
            ("[\"obj\", \"stl\"]", "unknown output format \"stl\""),
            ("3", "a format name or a list"),
        ] {
            let e = parse(&format!("[output]\nformat = {bad}\n"))
                .unwrap_err()
                .to_string();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }

    #[test]
    fn unknown_kind_names_line_and_choices() {
        assert_refused(&[(
            "[output]\nformat = \"obj\"\n\n[[step]]\nkind = \"sharpen\"\n",
            &["line 5", "sharpen", "normals", "decimate"],
        )]);
    }

    #[test]
    fn unknown_key_is_an_error() {
        assert_refused(&[
            (
                "[[step]]\nkind = \"normals\"\ncrease = 30\n",
                &["crease", "crease_angle"],
            ),
            ("[output]\nformat = \"stl\"\n", &["stl", "obj"]),
        ]);
    }

    #[test]
    fn decimate_and_seam_fix_parse_and_validate() {
        let r = parse(
            "[[step]]\nkind = \"decimate\"\ntarget_faces = 26000\nmethod = \"face-collapse\"\n\n[[step]]\nkind = \"seam_fix\"\n",
        )
        .unwrap();
        assert_eq!(r.steps.len(), 2);
        assert_refused(&[
            (
                "[[step]]\nkind = \"decimate\"\n",
                &["line 1", "target_faces"],
            ),
            (
                "[[step]]\nkind = \"decimate\"\ntarget_faces = 10\nmethod = \"qem\"\n",
                &["face-collapse", "cluster-keep"],
            ),
        ]);
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

    #[test]
    fn crop_metrics_table_and_step_metrics() {
        let r = parse(
            "[metrics]\nsamples = 5000\nseed = 7\n\n[[step]]\nkind = \"crop\"\nabs_max = [100, 120.5, 80]\nmode = \"clip\"\nmetrics = true\n\n[[step]]\nkind = \"normals\"\n",
        )
        .unwrap();
        assert_eq!(r.metrics.samples, 5000);
        assert!(r.metrics.enabled);
        assert_eq!(r.step_metrics, vec![1]);
        match &r.steps[0] {
            Step::Crop(p) => {
                assert_eq!(p.abs_max, Some([100.0, 120.5, 80.0]));
                assert_eq!(p.mode, crate::ops::crop::CropMode::Clip);
            }
            other => panic!("{other:?}"),
        }
        assert_refused(&[
            (
                "[[step]]\nkind = \"crop\"\nmin = [0, 0, 0]\n",
                &["line 1", "min and max"],
            ),
            (
                "\n[[step]]\nkind = \"crop\"\nabs_max = [1, 1, 1]\nmode = \"inside\"\n",
                &["line 5", "any-corner-outside"],
            ),
            ("[[step]]\nkind = \"normals\"\nmetrics = 1\n", &["metrics"]),
            ("[metrics]\nsamples = 0\n", &["samples"]),
            ("[metrics]\nsample = 10\n", &["sample", "enabled"]),
        ]);
        // Hash: the metrics settings count, a step's `metrics = false` is the default.
        let a = parse("[[step]]\nkind = \"normals\"\n").unwrap();
        let b = parse("[[step]]\nkind = \"normals\"\nmetrics = false\n").unwrap();
        let c = parse("[metrics]\nenabled = false\n[[step]]\nkind = \"normals\"\n").unwrap();
        assert_eq!(a.hash(), b.hash());
        assert_ne!(a.hash(), c.hash());
    }

    #[test]
    fn preview_table() {
        let a = parse("[[step]]\nkind = \"normals\"\n").unwrap();
        assert!(a.preview.enabled && a.preview.size == 512);
        let b = parse("[preview]\nenabled = true\n[[step]]\nkind = \"normals\"\n").unwrap();
        assert_eq!(a.hash(), b.hash(), "defaults leave the hash alone");
        let c = parse("[preview]\nsize = 256\nview = \"+y\"\n").unwrap();
        assert_eq!(c.preview.up_axis(), crate::preview::camera::Axis::PosZ);
        assert_ne!(c.hash(), parse("").unwrap().hash());
        assert_refused(&[
            ("[preview]\nview = \"front\"\n", &["-z", "+x"]),
            ("[preview]\nsize = 8\n", &["[preview]", "size"]),
            ("[preview]\nsise = 8\n", &["supersample"]),
        ]);
    }

    /// Every recipe shipped in config/recipes parses and validates, including one added
    /// later without a change here.
    #[test]
    fn every_shipped_recipe_is_valid() {
        let mut names = Vec::new();
        for entry in std::fs::read_dir("config/recipes").unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "toml") {
                let recipe =
                    Recipe::from_path(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                assert!(!recipe.steps.is_empty(), "{}", path.display());
                names.push(path.file_stem().unwrap().to_string_lossy().into_owned());
            }
        }
        for shipped in ["face-scan", "face-scan-denoise", "normals-only", "remesh"] {
            assert!(names.iter().any(|n| n == shipped), "{shipped} not found");
        }
    }

    /// Recipes keep the hash they had before the boundary vocabulary and the
    /// `[experimental]` table (the daemon's job key is built from it): the hashes below were
    /// computed by the code before that change, each for the old spelling; the new spelling
    /// must give the same.
    #[test]
    fn shipped_recipes_keep_their_hash() {
        for (file, hash) in [
            (
                "face-scan",
                "99ed35193967df4b411b86699ea146bfdf6228011aebfe4d522ecf217fe25c6a",
            ),
            (
                "face-scan-denoise",
                "949db8d733e5987c725feafe246b628c033049999a81e53dbed25e6502afffe9",
            ),
            (
                "normals-only",
                "77bef33a73fb8c219cf818cae20e07af5d7dc5f77bb495660a478f5a59d69a6a",
            ),
        ] {
            let path = PathBuf::from(format!("config/recipes/{file}.toml"));
            assert_eq!(Recipe::from_path(&path).unwrap().hash(), hash, "{file}");
        }
    }

    /// The renamed spellings of `smooth` give the hashes the old ones had (computed by the
    /// code before the rename, for the old spelling).
    #[test]
    fn renamed_smooth_spellings_keep_the_hash() {
        let smooth = |rest| step("smooth", rest);
        let curve = "5342e9c737c026fa4bd522a8cff465661b5ac94c78e98ca0080d858f670f7efb";
        assert_hashes(&[
            (smooth("method = \"taubin\"\nboundary = \"free\"\n"), curve),
            (smooth("method = \"taubin\"\nboundary = \"curve\"\n"), curve),
            (
                smooth("method = \"laplace\"\n"),
                "7e43546fbb8c12968d9c60b2e82d0710934e2592e5c9d02c2238a27a860565c5",
            ),
            (
                smooth("method = \"hc\"\n"),
                "0b315dc7d9b4c84c19023535384a407c9b674e4fcad7c799873c601bbbd2e8bf",
            ),
            (
                smooth("method = \"bilateral\"\nboundary = \"fixed\"\nunits = \"absolute\"\n"),
                "d498582e0c2117629be0d73af8cdbf5f84e98027d7042d0af59190c323328a6b",
            ),
            (
                smooth("method = \"normal-filter\"\nboundary = \"curve\"\n"),
                "cde570d86c5a8e7b6ed8f34ce50f0503eb7c76c0627f13c36184bcc682f62f37",
            ),
        ]);
    }

    /// The same for `decimate`, and for its switches moved to `[experimental.decimate]`.
    #[test]
    fn renamed_decimate_spellings_keep_the_hash() {
        let decimate = |rest| step("decimate", &format!("target_faces = 1000\n{rest}"));
        let free = "98d6a664e712fa193b62d49a504ef2e28ee5620e5a1664a13be44d24762b4d57";
        assert_hashes(&[
            (decimate("boundary = \"free\"\n"), free),
            (decimate("boundary = \"like-interior\"\n"), free),
            (
                decimate("boundary = \"weighted\"\n"),
                "f49aff631dc0ba17dec2e5aae18ddafadf39d7282bf7c378faf3fe9e50f14098",
            ),
            (
                "[experimental.decimate]\nconditioning = \"thesis-literal\"\nguards = false\n"
                    .to_string()
                    + &decimate("method = \"face-collapse\"\n"),
                "87262fdcd14afdd7c682e3a2f7d151cdea38be1b1ce4c67a09c31394b53a49b1",
            ),
        ]);
        // The new name means what the old one did.
        let keep = parse(&decimate("boundary = \"keep\"\n")).unwrap();
        let fixed = parse(&decimate("boundary = \"fixed\"\n")).unwrap();
        assert_eq!(keep.hash(), fixed.hash());
    }

    /// The same for `relax` and `fair`, whose `fixed` border is not their `curve` one.
    #[test]
    fn renamed_fairing_spellings_keep_the_hash() {
        let relax_fair = |b| step("relax", b) + &step("fair", b);
        let fixed = "acfe67c37878290113b53d3e255ee23738a925cc011e0a7e6fbb7fd21b626f91";
        assert_hashes(&[(relax_fair("boundary = \"fixed\"\n"), fixed)]);
        assert_ne!(
            parse(&relax_fair("boundary = \"curve\"\n")).unwrap().hash(),
            fixed
        );
    }

    #[test]
    fn research_switches_are_refused_in_the_step_and_say_where_they_moved() {
        for key in ["conditioning = \"thesis-literal\"", "guards = false"] {
            let text = step("decimate", &format!("target_faces = 10\n{key}\n"));
            assert_refused(&[(&text, &["line 4", "[experimental.decimate]"])]);
        }
        let r = parse("[experimental.decimate]\nguards = false\n[[step]]\nkind = \"decimate\"\ntarget_faces = 10\n").unwrap();
        match &r.steps[0] {
            Step::Decimate(p) => assert!(!p.guards),
            other => panic!("{other:?}"),
        }
        assert_refused(&[(
            "[experimental.decimate]\nguard = false\n",
            &["guard", "conditioning"],
        )]);
    }

    #[test]
    fn a_border_mode_of_another_step_is_refused_with_this_steps_choices() {
        assert_refused(&[
            (
                "\n[[step]]\nkind = \"smooth\"\nmethod = \"taubin\"\nboundary = \"weighted\"\n",
                &["line 5", "`curve` (or `free`)"],
            ),
            (
                "[[step]]\nkind = \"fair\"\nboundary = \"keep\"\n",
                &["`curve` (or `fair`)", "`fixed`"],
            ),
        ]);
    }
}
