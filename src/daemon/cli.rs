//! The service's subcommands, as a clap `Subcommand` that `main.rs` flattens into its own:
//! `daemon`, `history`, `show`, `requeue`, `validate-config`, `db backup`.
//! Each returns an exit code (sysexits, see docs/service.md "Exit codes").

use super::service::{self, ServiceError};
use super::worker_process::{self, WorkerArgs};
use crate::config::{ConfigError, DaemonConfig};
use crate::store::query::{HistoryFilter, HistoryRow, STATES};
use crate::store::{Queue, StoreError, now_ms};
use clap::Subcommand;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Exit codes (sysexits.h).
pub mod exit {
    pub const OK: u8 = 0;
    pub const FAILURE: u8 = 1;
    pub const USAGE: u8 = 64;
    pub const UNAVAILABLE: u8 = 69;
    pub const CANT_CREATE: u8 = 73;
    pub const TEMP_FAIL: u8 = 75;
    pub const CONFIG: u8 = 78;
}

#[derive(Debug, Clone, Subcommand)]
pub enum ServiceCommand {
    /// Run the service: watch folders, process new scans, record every job.
    Daemon {
        /// Daemon configuration (default: $SCANMILL_CONFIG, else config/scanmill.toml, else built-in).
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// List jobs from the audit log.
    History {
        /// The daemon's configuration, which names its database (default: $SCANMILL_CONFIG,
        /// else config/scanmill.toml, else built-in).
        #[arg(long)]
        config: Option<PathBuf>,
        /// A PostgreSQL store to read instead of the configuration's (`postgres://…`).
        #[arg(long, value_name = "URL")]
        store: Option<String>,
        /// Only jobs queued since: a duration back from now (90s, 30m, 12h, 7d) or a UTC date/time.
        #[arg(long)]
        since: Option<String>,
        /// Only jobs in this state: queued, running, done, failed, quarantined, or waiting
        /// (scans not yet jobs: a member missing or unreadable).
        #[arg(long)]
        status: Option<String>,
        /// Only inputs whose path matches this glob (SQLite's GLOB on root/relative path, on either store).
        #[arg(long)]
        input: Option<String>,
        /// Print JSON (one array).
        #[arg(long, conflicts_with = "csv")]
        json: bool,
        /// Print CSV with a header line.
        #[arg(long)]
        csv: bool,
        /// At most this many rows.
        #[arg(long)]
        limit: Option<usize>,
    },
    /// Show everything recorded about one job (inputs, recipe, attempts, step timings, metrics, outputs), as JSON.
    Show {
        job: i64,
        /// The daemon's configuration, which names its database (default: $SCANMILL_CONFIG,
        /// else config/scanmill.toml, else built-in).
        #[arg(long)]
        config: Option<PathBuf>,
        /// A PostgreSQL store to read instead of the configuration's (`postgres://…`).
        #[arg(long, value_name = "URL")]
        store: Option<String>,
    },
    /// Put a job back in the queue (a fresh attempt count; its output is published again, with a suffix if needed).
    Requeue {
        job: i64,
        /// The daemon's configuration, which names its database (default: $SCANMILL_CONFIG,
        /// else config/scanmill.toml, else built-in).
        #[arg(long)]
        config: Option<PathBuf>,
        /// A PostgreSQL store to read instead of the configuration's (`postgres://…`).
        #[arg(long, value_name = "URL")]
        store: Option<String>,
    },
    /// Check the daemon configuration; exit 78 if it is not valid.
    ValidateConfig {
        /// The configuration to check (default: $SCANMILL_CONFIG, else config/scanmill.toml,
        /// else built-in).
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// Database maintenance.
    Db {
        #[command(subcommand)]
        command: DbCommand,
    },
    /// Internal: one daemon job in its own process (started by the daemon, not by hand).
    #[command(hide = true)]
    Worker {
        /// The pipe protocol version the daemon speaks.
        #[arg(long)]
        protocol: u32,
        #[arg(long)]
        job_id: i64,
        #[arg(long)]
        input: PathBuf,
        #[arg(long)]
        recipe: PathBuf,
        #[arg(long)]
        recipe_hash: String,
        /// The daemon's `[limits]`, as JSON.
        #[arg(long)]
        limits: String,
        #[arg(long)]
        out: PathBuf,
    },
}

#[derive(Debug, Clone, Subcommand)]
pub enum DbCommand {
    /// Copy the database with SQLite's online backup (safe while the daemon runs), then check the copy.
    Backup {
        file: PathBuf,
        /// The daemon's configuration, which names its database (default: $SCANMILL_CONFIG,
        /// else config/scanmill.toml, else built-in).
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// Copy this host's SQLite history (jobs, inputs, outputs, attempts, step timings, waiting
    /// scans) into a PostgreSQL store; refuses a store that already holds jobs.
    Migrate {
        /// The PostgreSQL store (`postgres://…`); created and migrated if empty.
        #[arg(long, value_name = "URL")]
        to: String,
        /// The daemon's configuration, which names its database (default: $SCANMILL_CONFIG,
        /// else config/scanmill.toml, else built-in).
        #[arg(long)]
        config: Option<PathBuf>,
    },
}

impl ServiceCommand {
    /// Whether this command sets up its own logging (the daemon logs at info, to journald
    /// under systemd); `main` should not install a subscriber first.
    pub fn owns_logging(&self) -> bool {
        matches!(
            self,
            ServiceCommand::Daemon { .. } | ServiceCommand::Worker { .. }
        )
    }

    /// Runs the command; returns the process exit code.
    pub fn run(&self) -> u8 {
        // Unlocked handles: a held stderr lock would block every log line from other
        // threads (the daemon's jobs) for the whole run.
        let mut out = std::io::stdout();
        let mut err = std::io::stderr();
        match self {
            ServiceCommand::Daemon { config } => run_daemon(config.as_deref(), &mut err),
            ServiceCommand::Worker {
                protocol,
                job_id,
                input,
                recipe,
                recipe_hash,
                limits,
                out,
            } => {
                super::systemd::init_logging();
                let limits = match worker_limits(*protocol, limits, &mut err) {
                    Ok(limits) => limits,
                    Err(code) => return code,
                };
                worker_process::run(WorkerArgs {
                    job_id: *job_id,
                    input: input.clone(),
                    recipe: recipe.clone(),
                    recipe_hash: recipe_hash.clone(),
                    limits,
                    out: out.clone(),
                })
            }
            ServiceCommand::ValidateConfig { config } => {
                validate_config(config.as_deref(), &mut out, &mut err)
            }
            ServiceCommand::History {
                config,
                store,
                since,
                status,
                input,
                json,
                csv,
                limit,
            } => {
                let args = HistoryArgs {
                    since: since.clone(),
                    status: status.clone(),
                    input: input.clone(),
                    limit: *limit,
                    format: Format::chosen(*json, *csv),
                };
                let at = StoreAt::new(config, store);
                report(history(&at, &args, &mut out), &mut err)
            }
            ServiceCommand::Show { job, config, store } => {
                report(show(&StoreAt::new(config, store), *job, &mut out), &mut err)
            }
            ServiceCommand::Requeue { job, config, store } => report(
                requeue(&StoreAt::new(config, store), *job, &mut out),
                &mut err,
            ),
            ServiceCommand::Db {
                command: DbCommand::Backup { file, config },
            } => report(db_backup(config.as_deref(), file, &mut out), &mut err),
            ServiceCommand::Db {
                command: DbCommand::Migrate { to, config },
            } => report(db_migrate(config.as_deref(), to, &mut out), &mut err),
        }
    }
}

/// The worker's `--limits`, once its `--protocol` is checked; the usage exit code otherwise.
fn worker_limits(
    protocol: u32,
    limits: &str,
    err: &mut impl Write,
) -> Result<crate::mesh::InputLimits, u8> {
    let limits = match serde_json::from_str(limits) {
        Ok(l) => l,
        Err(e) => {
            let _ = writeln!(err, "scanmill: error: --limits: {e}");
            return Err(exit::USAGE);
        }
    };
    if protocol != super::protocol::VERSION {
        let _ = writeln!(
            err,
            "scanmill: error: the daemon speaks worker protocol {protocol}, this binary {}",
            super::protocol::VERSION
        );
        return Err(exit::USAGE);
    }
    Ok(limits)
}

/// A command's failure: its exit code and one line for stderr.
#[derive(Debug)]
pub struct CliError {
    pub code: u8,
    pub message: String,
}

impl From<StoreError> for CliError {
    fn from(e: StoreError) -> CliError {
        let code = match &e {
            StoreError::Missing { .. } => exit::UNAVAILABLE,
            StoreError::TooNew { .. } => exit::CONFIG,
            StoreError::NoSuchJob(_) => exit::USAGE,
            StoreError::WrongState { .. } => exit::TEMP_FAIL,
            StoreError::Conn(_) => exit::CONFIG,
            StoreError::Postgres { .. } if e.is_busy() => exit::UNAVAILABLE,
            StoreError::Sqlite { source, .. }
                if matches!(
                    source.sqlite_error_code(),
                    Some(rusqlite::ErrorCode::DatabaseBusy)
                ) =>
            {
                exit::TEMP_FAIL
            }
            _ => exit::FAILURE,
        };
        CliError {
            code,
            message: e.to_string(),
        }
    }
}

impl From<ConfigError> for CliError {
    fn from(e: ConfigError) -> CliError {
        CliError {
            code: exit::CONFIG,
            message: e.to_string(),
        }
    }
}

impl From<std::io::Error> for CliError {
    /// A write to a reader that stopped reading (`scanmill history | head`) ends the command
    /// with success and no message: the rest was not wanted, as with `cat`.
    fn from(e: std::io::Error) -> CliError {
        let code = match e.kind() {
            std::io::ErrorKind::BrokenPipe => exit::OK,
            _ => exit::FAILURE,
        };
        CliError {
            code,
            message: e.to_string(),
        }
    }
}

fn report(result: Result<(), CliError>, err: &mut dyn Write) -> u8 {
    match result {
        Ok(()) => exit::OK,
        Err(e) if e.code == exit::OK => exit::OK,
        Err(e) => {
            let _ = writeln!(err, "scanmill: error: {}", e.message);
            e.code
        }
    }
}

/// `scanmill daemon`: runs until SIGTERM/SIGINT. Exit 0 after a clean stop, 78 for a bad
/// configuration, 75 when another daemon holds the state directory, 69 when the database
/// cannot be opened.
pub fn run_daemon(config: Option<&Path>, err: &mut dyn Write) -> u8 {
    super::systemd::init_logging();
    let (cfg, origin) = match DaemonConfig::locate(config) {
        Ok(x) => x,
        Err(e) => {
            let _ = writeln!(err, "scanmill: error: {e}");
            return exit::CONFIG;
        }
    };
    match service::run(cfg, origin) {
        Ok(()) => exit::OK,
        Err(e) => {
            tracing::error!("{e}");
            let _ = writeln!(err, "scanmill: error: {e}");
            match e {
                ServiceError::Config { .. } => exit::CONFIG,
                ServiceError::Locked(_) => exit::TEMP_FAIL,
                ServiceError::Store(StoreError::TooNew { .. } | StoreError::Conn(_)) => {
                    exit::CONFIG
                }
                ServiceError::Store(_) => exit::UNAVAILABLE,
                ServiceError::Io { .. } => exit::CANT_CREATE,
            }
        }
    }
}

/// `scanmill validate-config`: prints "ok" or every problem; exit 78 on a bad config.
pub fn validate_config(config: Option<&Path>, out: &mut dyn Write, err: &mut dyn Write) -> u8 {
    let (cfg, origin) = match DaemonConfig::locate(config) {
        Ok(x) => x,
        Err(e) => {
            let _ = writeln!(err, "scanmill: error: {e}");
            return exit::CONFIG;
        }
    };
    let problems = cfg.validate();
    if problems.is_empty() {
        let _ = writeln!(out, "{origin}: ok ({} watched folder(s))", cfg.watch.len());
        exit::OK
    } else {
        let _ = writeln!(err, "{origin}: invalid configuration:");
        for p in problems {
            let _ = writeln!(err, "  {p}");
        }
        exit::CONFIG
    }
}

/// Which store a command reads: the configuration's, or `--store URL`.
pub struct StoreAt<'a> {
    pub config: Option<&'a Path>,
    pub url: Option<&'a str>,
}

impl<'a> StoreAt<'a> {
    fn new(config: &'a Option<PathBuf>, url: &'a Option<String>) -> StoreAt<'a> {
        StoreAt {
            config: config.as_deref(),
            url: url.as_deref(),
        }
    }
}

fn open_store(at: &StoreAt<'_>, write: bool) -> Result<Queue, CliError> {
    let (cfg, _) = DaemonConfig::locate(at.config)?;
    Ok(Queue::open_existing(
        &cfg.store,
        at.url,
        &cfg.database_path(),
        write,
    )?)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Text,
    Json,
    Csv,
}

impl Format {
    /// The format `--json` / `--csv` ask for; text when neither.
    fn chosen(json: bool, csv: bool) -> Format {
        if json {
            Format::Json
        } else if csv {
            Format::Csv
        } else {
            Format::Text
        }
    }
}

#[derive(Debug, Clone)]
pub struct HistoryArgs {
    pub since: Option<String>,
    pub status: Option<String>,
    pub input: Option<String>,
    pub limit: Option<usize>,
    pub format: Format,
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// `scanmill history`.
pub fn history(at: &StoreAt<'_>, args: &HistoryArgs, out: &mut dyn Write) -> Result<(), CliError> {
    if let Some(s) = &args.status
        && !STATES.contains(&s.as_str())
    {
        return Err(CliError {
            code: exit::USAGE,
            message: format!("--status {s}: expected one of {}", STATES.join(", ")),
        });
    }
    let mut store = open_store(at, false)?;
    let since_ms = match &args.since {
        Some(s) => Some(store.parse_since(s, now_ms()).ok_or_else(|| CliError {
            code: exit::USAGE,
            message: format!("--since {s}: expected e.g. 7d, 12h, 30m or 2026-11-01[T08:00:00]"),
        })?),
        None => None,
    };
    let filter = HistoryFilter {
        since_ms,
        status: args.status.clone(),
        input_glob: args.input.clone(),
        limit: args.limit,
    };
    let rows = store.history(&filter)?;
    match args.format {
        Format::Json => {
            serde_json::to_writer_pretty(&mut *out, &rows).map_err(std::io::Error::other)?;
            writeln!(out)?;
        }
        Format::Csv => {
            writeln!(
                out,
                "id,state,created,finished,input,recipe,attempts,in_faces,out_faces,process_ms,output,error_kind,error"
            )?;
            for r in &rows {
                let opt = |v: Option<String>| v.unwrap_or_default();
                let fields = [
                    opt(r.id.map(|v| v.to_string())),
                    r.state.clone(),
                    r.created.clone(),
                    opt(r.finished.clone()),
                    r.input.clone(),
                    r.recipe.clone(),
                    r.attempts.to_string(),
                    opt(r.in_faces.map(|v| v.to_string())),
                    opt(r.out_faces.map(|v| v.to_string())),
                    opt(r.process_ms.map(|v| format!("{v:.1}"))),
                    opt(r.output.clone()),
                    opt(r.error_kind.clone()),
                    opt(r.error.clone()),
                ];
                let line: Vec<String> = fields.iter().map(|f| csv_field(f)).collect();
                writeln!(out, "{}", line.join(","))?;
            }
        }
        Format::Text => {
            write_history_text(&rows, out)?;
            let not_jobs = scans_not_jobs(&mut store, &filter)?;
            if not_jobs > 0 {
                writeln!(
                    out,
                    "{not_jobs} scan(s) found but not jobs: a file missing, or refused \
                     (a link, a file outside the folder, too large); see \
                     `scanmill history --status waiting`"
                )?;
            }
        }
    }
    Ok(())
}

/// How many scans the filter's job rows leave out because they never became jobs (waiting
/// for a member, or refused before they were queued): a lab looking for what failed would
/// otherwise not see them. Zero when the filter asks for those scans, or for a job state
/// other than `failed`.
fn scans_not_jobs(store: &mut Queue, filter: &HistoryFilter) -> Result<usize, CliError> {
    if !matches!(filter.status.as_deref(), None | Some("failed")) {
        return Ok(0);
    }
    let waiting = HistoryFilter {
        status: Some("waiting".into()),
        limit: None,
        ..filter.clone()
    };
    Ok(store.history(&waiting)?.len())
}

/// `scanmill db migrate --to URL`: copies this host's SQLite history into PostgreSQL.
pub fn db_migrate(config: Option<&Path>, to: &str, out: &mut dyn Write) -> Result<(), CliError> {
    let (cfg, _) = DaemonConfig::locate(config)?;
    let source = crate::store::Store::open_existing(&cfg.database_path(), false)?;
    let info = crate::store::pg::ConnInfo::new(to, cfg.store.password_file.as_deref())
        .map_err(StoreError::from)?;
    let shown = info.shown.clone();
    let mut target = crate::store::pg::PgStore::open(
        info,
        cfg.store.lease(),
        std::time::Duration::from_secs(5),
    )?;
    let copied = crate::store::pg::copy::from_sqlite(&source, &mut target).map_err(|e| {
        let code = match &e {
            crate::store::pg::copy::CopyError::NotEmpty { .. } => exit::CANT_CREATE,
            crate::store::pg::copy::CopyError::Store(_) => exit::FAILURE,
        };
        CliError {
            code,
            message: e.to_string(),
        }
    })?;
    writeln!(out, "{} -> {shown}: {copied}", source.path().display())?;
    Ok(())
}

fn write_history_text(rows: &[HistoryRow], out: &mut dyn Write) -> std::io::Result<()> {
    writeln!(
        out,
        "{:>6}  {:<11}  {:<24}  {:>9}  {:>9}  {:>9}  input / output or error",
        "id", "state", "created", "faces in", "faces out", "ms"
    )?;
    for r in rows {
        let detail = match (&r.output, &r.error) {
            (_, Some(e)) => format!("{}  ! {}", r.input, e),
            (Some(o), None) if !r.outputs.is_empty() => {
                format!("{}  -> {} ({})", r.input, o, r.outputs.join(", "))
            }
            (Some(o), None) => format!("{}  -> {}", r.input, o),
            (None, None) => r.input.clone(),
        };
        let num = |v: Option<i64>| v.map(|v| v.to_string()).unwrap_or_else(|| "-".into());
        writeln!(
            out,
            "{:>6}  {:<11}  {:<24}  {:>9}  {:>9}  {:>9}  {}",
            r.id.map(|v| v.to_string()).unwrap_or_else(|| "-".into()),
            r.state,
            r.created,
            num(r.in_faces),
            num(r.out_faces),
            r.process_ms
                .map(|v| format!("{v:.0}"))
                .unwrap_or_else(|| "-".into()),
            detail
        )?;
    }
    writeln!(out, "{} row(s)", rows.len())
}

/// `scanmill show JOB`: everything recorded, as pretty JSON.
pub fn show(at: &StoreAt<'_>, job: i64, out: &mut dyn Write) -> Result<(), CliError> {
    let mut store = open_store(at, false)?;
    let value = store.show(job)?;
    serde_json::to_writer_pretty(&mut *out, &value).map_err(std::io::Error::other)?;
    writeln!(out)?;
    Ok(())
}

/// `scanmill requeue JOB`.
pub fn requeue(at: &StoreAt<'_>, job: i64, out: &mut dyn Write) -> Result<(), CliError> {
    let mut store = open_store(at, true)?;
    let was = store.requeue(job)?;
    writeln!(out, "job {job}: {was} -> queued")?;
    Ok(())
}

/// `scanmill db backup FILE`: online backup, then `PRAGMA integrity_check` on the copy.
pub fn db_backup(config: Option<&Path>, file: &Path, out: &mut dyn Write) -> Result<(), CliError> {
    if file.exists() {
        return Err(CliError {
            code: exit::CANT_CREATE,
            message: format!("{}: exists; not overwriting", file.display()),
        });
    }
    let (cfg, _) = DaemonConfig::locate(config)?;
    if cfg.store.is_shared() {
        return Err(CliError {
            code: exit::USAGE,
            message: "the store is PostgreSQL: back it up with pg_dump (docs/scale-out.md)".into(),
        });
    }
    let store = crate::store::Store::open_existing(&cfg.database_path(), false)?;
    store.backup(file)?;
    writeln!(
        out,
        "{} -> {} (integrity ok)",
        store.path().display(),
        file.display()
    )?;
    Ok(())
}
