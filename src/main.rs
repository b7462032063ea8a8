//! The command line. No logic beyond argument handling, progress display and exit codes.

use clap::{Parser, Subcommand};
use scanmill::mesh::summary::MeshSummary;
use scanmill::mesh::{LoadOptions, MeshError, io};
use scanmill::process::{ProcessError, ProcessOptions, process_scan_with_options};
use scanmill::recipe::runner::Progress;
use scanmill::recipe::{Recipe, RecipeError};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Exit codes (sysexits.h), so that scripts and systemd can tell causes apart.
mod exit {
    pub const FAILURE: u8 = 1;
    pub const DATA_ERROR: u8 = 65;
    pub const NO_INPUT: u8 = 66;
    pub const IO_ERROR: u8 = 74;
    pub const CONFIG_ERROR: u8 = 78;
}

#[derive(Parser)]
#[command(
    name = "scanmill",
    version,
    about = "Unattended processing of 3D scans"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run one recipe on one scan, in the foreground.
    Process {
        /// The scan: .obj (with its MTL and textures), .ply, .stl, .gltf or .glb, optionally .gz.
        input: PathBuf,
        /// The recipe file (TOML).
        #[arg(long)]
        recipe: PathBuf,
        /// Folder for the result (created if missing). Files of the same name are replaced.
        #[arg(long)]
        out: PathBuf,
        /// Also write the processing report as JSON to this file.
        #[arg(long)]
        report: Option<PathBuf>,
        /// The texture image of an OBJ that names no material library (OBJ only; ignored
        /// with a warning when the OBJ has materials of its own).
        #[arg(long)]
        texture: Option<PathBuf>,
    },
    /// Load a scan and print what it is.
    Inspect {
        file: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
        /// Weld vertices closer than this fraction of the bounding-box diagonal (0 = bit-exact).
        #[arg(long, default_value_t = 0.0)]
        weld_tolerance: f64,
    },
    /// Run several recipes on the same scan (optionally after adding the smoothing thesis'
    /// noise) and print one table of how far each result is from the clean input
    /// (see docs/smoothing.md).
    Compare {
        /// The scan, clean or raw: .obj or .ply, optionally .gz.
        input: PathBuf,
        /// Recipe files (TOML); each becomes one row, named by its file name.
        #[arg(long, num_args = 1.., required = true)]
        recipes: Vec<PathBuf>,
        /// Add Gaussian noise along the vertex normals first, σ = SIGMA × mean edge length
        /// (the thesis uses 0.2); figures are then against the clean input.
        #[arg(long, value_name = "SIGMA")]
        noise: Option<f64>,
        /// Seed of the noise and of the surface samples.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Surface samples per side for the distances.
        #[arg(long, default_value_t = scanmill::metrics::DEFAULT_SAMPLES)]
        samples: usize,
        /// Print JSON (every metric) instead of a text table.
        #[arg(long, conflicts_with = "csv")]
        json: bool,
        /// Print CSV instead of a text table.
        #[arg(long)]
        csv: bool,
    },
    /// The service and its audit/operations commands (see docs/service.md).
    #[command(flatten)]
    Service(scanmill::daemon::cli::ServiceCommand),
}

/// A progress bar on stderr when it is a terminal; nothing otherwise.
struct TerminalProgress {
    bar: Option<indicatif::ProgressBar>,
}

impl TerminalProgress {
    fn new() -> Self {
        let bar = std::io::stderr().is_terminal().then(|| {
            let bar = indicatif::ProgressBar::new(1);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} {msg}",
                )
                .expect("valid template"),
            );
            bar.enable_steady_tick(std::time::Duration::from_millis(120));
            bar
        });
        TerminalProgress { bar }
    }

    fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

impl Progress for TerminalProgress {
    fn stage(&self, index: usize, total: usize, name: &str) {
        if let Some(bar) = &self.bar {
            bar.set_length(total as u64);
            bar.set_position(index as u64);
            bar.set_message(name.to_string());
        }
    }
}

fn init_logging(default_level: &str) {
    let filter = tracing_subscriber::EnvFilter::try_from_env("SCANMILL_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default_level));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .init();
}

fn mesh_error_code(e: &MeshError) -> u8 {
    match e {
        MeshError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            exit::NO_INPUT
        }
        MeshError::Io { .. } | MeshError::Write { .. } => exit::IO_ERROR,
        _ => exit::DATA_ERROR,
    }
}

/// The recipe at `path`; a missing file exits 66 (no input), any other problem 78 (config).
fn load_recipe(path: &Path) -> Result<Recipe, (u8, anyhow::Error)> {
    Recipe::from_path(path).map_err(|e| {
        let code = match &e {
            RecipeError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
                exit::NO_INPUT
            }
            _ => exit::CONFIG_ERROR,
        };
        (code, e.into())
    })
}

fn run_process(
    input: &Path,
    recipe_path: &Path,
    out: &Path,
    report: Option<&Path>,
    texture: Option<&Path>,
) -> Result<(), (u8, anyhow::Error)> {
    let recipe = load_recipe(recipe_path)?;
    let progress = TerminalProgress::new();
    let options = ProcessOptions {
        texture: texture.map(Path::to_path_buf),
        ..ProcessOptions::default()
    };
    let result =
        process_scan_with_options(input, &options, &recipe, Some(recipe_path), out, &progress);
    progress.finish();
    let result = result.map_err(|e| {
        let code = match &e {
            ProcessError::Input(m) => mesh_error_code(m),
            ProcessError::Step { .. } => exit::FAILURE,
            ProcessError::Output { .. } => exit::IO_ERROR,
        };
        (code, e.into())
    })?;
    if let Some(path) = report {
        let json = serde_json::to_string_pretty(&result).expect("report serialises");
        std::fs::write(path, json + "\n").map_err(|e| {
            (
                exit::IO_ERROR,
                anyhow::anyhow!("{}: cannot write report: {e}", path.display()),
            )
        })?;
    }
    // The mesh files come last, one per format.
    let files = &result.output.files;
    let meshes = &files[files
        .len()
        .saturating_sub(recipe.output.format.list().len())..];
    let main_file = meshes
        .iter()
        .map(|f| f.path.display().to_string())
        .collect::<Vec<_>>()
        .join(", ");
    eprintln!(
        "{} → {} ({} → {} faces, {:.0} ms)",
        input.display(),
        main_file,
        result.input.counts.faces,
        result.output.counts.faces,
        result.total_ms
    );
    Ok(())
}

fn run_inspect(file: &Path, json: bool, weld_tolerance: f64) -> Result<(), (u8, anyhow::Error)> {
    scanmill::recipe::validate_weld_tolerance(weld_tolerance)
        .map_err(|m| (exit::CONFIG_ERROR, anyhow::anyhow!("--weld-tolerance: {m}")))?;
    // The default input limits; a FIFO or device is refused at once by the loader.
    let options = LoadOptions {
        weld_tolerance,
        ..LoadOptions::default()
    };
    let (mesh, report) = io::load(file, &options).map_err(|e| (mesh_error_code(&e), e.into()))?;
    let summary = MeshSummary::new(&mesh, Some(&report));
    if json {
        let text = serde_json::to_string_pretty(&summary).expect("summary serialises");
        emit(&format!("{text}\n"))
    } else {
        emit(&format!("{}\n{summary}\n", file.display()))
    }
}

/// Writes a command's output to stdout. A reader that stops early (`scanmill inspect … |
/// head`) closes the pipe: that is the reader's choice, not a failure of the command, so
/// the rest is dropped quietly, as `cat` does.
fn emit(text: &str) -> Result<(), (u8, anyhow::Error)> {
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err((exit::FAILURE, e.into())),
        _ => Ok(()),
    }
}

fn run_compare(
    input: &Path,
    recipe_paths: &[PathBuf],
    noise: Option<f64>,
    seed: u64,
    samples: usize,
    json: bool,
    csv: bool,
) -> Result<(), (u8, anyhow::Error)> {
    use scanmill::compare::{CompareError, CompareOptions, NamedRecipe};
    use scanmill::metrics::MetricsOptions;
    use scanmill::metrics::noise::NoiseOptions;
    let bad_argument = |message: String| (exit::CONFIG_ERROR, anyhow::anyhow!(message));
    if let Some(sigma) = noise
        && !(sigma.is_finite() && sigma >= 0.0)
    {
        return Err(bad_argument(format!(
            "--noise must be a non-negative multiple of the mean edge length, got {sigma}"
        )));
    }
    let metrics = MetricsOptions {
        samples,
        seed,
        ..MetricsOptions::default()
    };
    metrics
        .validate()
        .map_err(|m| bad_argument(format!("--samples: {m}")))?;
    let mut recipes = Vec::with_capacity(recipe_paths.len());
    for path in recipe_paths {
        let recipe = load_recipe(path)?;
        let name = path.file_name().map_or_else(
            || path.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        recipes.push(NamedRecipe { name, recipe });
    }
    let options = CompareOptions {
        noise: noise.map(|sigma_factor| NoiseOptions {
            sigma_factor,
            seed,
            ..NoiseOptions::default()
        }),
        metrics,
    };
    let table = scanmill::compare::run(input, &recipes, &options).map_err(|e| match e {
        CompareError::Load(m) => (mesh_error_code(&m), anyhow::Error::from(m)),
        other => (exit::FAILURE, other.into()),
    })?;
    if json {
        emit(&format!("{}\n", table.to_json()))
    } else if csv {
        emit(&table.to_csv())
    } else {
        emit(&table.to_text())
    }
}

fn main() -> ExitCode {
    scanmill::memory::configure();
    let cli = Cli::parse();
    if let Command::Service(service) = &cli.command {
        // The daemon sets up its own logging (journald under systemd, info level).
        if !service.owns_logging() {
            init_logging("warn");
        }
        return ExitCode::from(service.run());
    }
    init_logging("warn");
    let result = match &cli.command {
        Command::Process {
            input,
            recipe,
            out,
            report,
            texture,
        } => run_process(input, recipe, out, report.as_deref(), texture.as_deref()),
        Command::Inspect {
            file,
            json,
            weld_tolerance,
        } => run_inspect(file, *json, *weld_tolerance),
        Command::Compare {
            input,
            recipes,
            noise,
            seed,
            samples,
            json,
            csv,
        } => run_compare(input, recipes, *noise, *seed, *samples, *json, *csv),
        Command::Service(_) => return ExitCode::FAILURE, // handled above
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err((code, error)) => {
            // One line. scanmill's errors already carry their cause in their message.
            eprintln!("scanmill: error: {error}");
            ExitCode::from(code)
        }
    }
}
