//! The daemon's configuration (`config/scanmill.toml`, docs/service.md "Configuration keys").
//!
//! Relative paths are taken relative to the working directory the daemon starts in (the
//! repository root for `cargo run`, `/` under systemd, where the shipped unit uses absolute
//! paths). Unknown keys are errors. [`DaemonConfig::validate`] collects every problem at
//! once, so that `scanmill validate-config` can list them all.

use crate::mesh::InputLimits;
use crate::recipe::{Recipe, RecipeError};
use serde::{Deserialize, Serialize};
use std::path::{Component, Path, PathBuf};

/// Where the configuration came from, for the log line that says so.
#[derive(Debug, Clone, PartialEq)]
pub enum ConfigSource {
    File(PathBuf),
    BuiltIn,
}

impl std::fmt::Display for ConfigSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ConfigSource::File(p) => write!(f, "{}", crate::text::escape_path(p)),
            ConfigSource::BuiltIn => write!(f, "built-in default"),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("{origin}: {}", problems.join("; "))]
    Invalid {
        origin: ConfigSource,
        problems: Vec<String>,
    },
}

/// Longest time any `*_secs` key may be: a week. Larger values are typos, and would
/// overflow the clock arithmetic.
const MAX_SECS: f64 = 7.0 * 24.0 * 3600.0;

/// The worker's memory floor when `job_memory_mb` is automatic: the recipe's fixed costs
/// (metric samples, preview, thread stacks) on the smallest scan.
const AUTO_MEMORY_FLOOR: u64 = 1 << 30;
/// Bytes of worker memory allowed per byte of input when automatic. Measured peaks are
/// 4-6 bytes per byte of OBJ text (docs/service.md); decoded textures are 3-4 bytes per
/// pixel, often 10-20 per byte of JPEG. The margin is for the scans nobody measured.
const AUTO_MEMORY_PER_INPUT_BYTE: u64 = 40;
/// Compressed members are assumed to unpack to this many times their size.
const AUTO_GZIP_RATIO: u64 = 8;
fn default_quiet() -> f64 {
    30.0
}
fn default_recipe() -> PathBuf {
    PathBuf::from("config/recipes/face-scan.toml")
}

/// One watched folder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WatchConfig {
    /// A scanner's export folder, watched recursively.
    pub path: PathBuf,
    /// Where finished scans go; never inside a watched folder.
    pub output: PathBuf,
    /// The recipe for every scan found here.
    #[serde(default = "default_recipe")]
    pub recipe: PathBuf,
    /// A scan set unchanged (size, mtime, inode of every member) this long is complete.
    /// Fractions allowed.
    #[serde(default = "default_quiet")]
    pub quiet_period_secs: f64,
    /// `> 0`: do not use file events for this folder, walk it every `poll_secs` instead
    /// (network shares send no events for remote writes).
    #[serde(default)]
    pub poll_secs: f64,
    /// Glob patterns on the path relative to the watched folder (`*` within a name, `**`
    /// across folders, `?` one character). Empty = everything. A pattern without `/`
    /// matches the file name alone.
    #[serde(default)]
    pub include: Vec<String>,
    /// Glob patterns to leave alone (in addition to the built-in temporary-file patterns).
    #[serde(default)]
    pub exclude: Vec<String>,
    /// Optional marker file, e.g. `"{stem}.done"`: when it exists next to the scan (and
    /// every member exists) the scan is ready at once, without waiting for the quiet period.
    #[serde(default)]
    pub marker: Option<String>,
    /// Follow symbolic links inside the folder. Off (the default): a scan or a file it
    /// names that is a link, or lies behind one, is refused and recorded as waiting with
    /// the reason. On: a link is followed only when its target is inside this folder too.
    /// Linked folders are never entered by the walk either way.
    #[serde(default)]
    pub follow_symlinks: bool,
}

/// The whole daemon configuration. Every key is optional: a missing one takes its value from
/// [`DaemonConfig::default`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DaemonConfig {
    /// SQLite database, lock file.
    pub state_dir: PathBuf,
    /// Jobs processed at the same time.
    pub workers: usize,
    /// Create missing watch, output and state folders at start-up (handy for a fresh
    /// checkout; leave it off in production so a missing mount is an error).
    pub create_missing_dirs: bool,
    /// Attempts before a job that keeps failing for a transient reason is quarantined.
    pub max_attempts: u32,
    /// Retry delay after the first failed attempt; doubles each attempt, up to the max.
    pub retry_base_secs: f64,
    pub retry_max_secs: f64,
    /// A job running longer than this is abandoned and recorded as failed (timeout).
    pub job_timeout_secs: f64,
    /// On SIGTERM, running jobs get this long to finish before they are put back in the
    /// queue. Keep it below the unit's `TimeoutStopSec`.
    pub drain_timeout_secs: f64,
    /// Full walk of every watched folder this often, whatever the events say.
    pub rescan_secs: f64,
    /// A scan with a member still missing is recorded as waiting (and logged) after this long.
    pub incomplete_report_secs: f64,
    /// Largest input set (all members together) accepted, in bytes.
    pub max_input_bytes: u64,
    /// Claiming pauses while an output folder's file system has less free space than this.
    pub min_free_disk_mb: u64,
    /// Input limits of every job (`[limits]`, see `mesh::limits`); missing keys take their
    /// defaults.
    pub limits: InputLimits,
    /// Memory limit of one job's worker process, in MiB; 0 = automatic (from the input's
    /// size, at most three quarters of the machine's memory shared among `workers`).
    pub job_memory_mb: u64,
    /// CPU-time limit of one job's worker process (all its threads), in seconds; 0 =
    /// automatic (`job_timeout_secs` × the number of CPUs, so that the wall-clock limit
    /// comes first on a machine that is not overloaded).
    pub job_cpu_secs: u64,
    pub watch: Vec<WatchConfig>,
    /// The web dashboard and `/metrics` (`[web]`, off unless `enabled`). Not part of
    /// [`DaemonConfig::hash`]: it does not change what a job produces, and the token is a
    /// secret that has no business in the audit log.
    #[serde(skip_serializing)]
    pub web: crate::web::WebConfig,
    /// The job queue and audit log (`[store]`): absent, SQLite in `state_dir`; a
    /// PostgreSQL URL, a queue shared with other hosts (docs/scale-out.md). Not part of
    /// the hash: where the queue lives does not change what a job produces.
    #[serde(skip_serializing)]
    pub store: crate::store::StoreConfig,
}

/// The value of every key a configuration file leaves out.
impl Default for DaemonConfig {
    fn default() -> Self {
        DaemonConfig {
            state_dir: PathBuf::from("./state"),
            workers: 1,
            create_missing_dirs: false,
            max_attempts: 3,
            retry_base_secs: 30.0,
            retry_max_secs: 3600.0,
            job_timeout_secs: 3600.0,
            drain_timeout_secs: 60.0,
            rescan_secs: 60.0,
            incomplete_report_secs: 600.0,
            max_input_bytes: 4 << 30,
            min_free_disk_mb: 1024,
            limits: InputLimits::default(),
            job_memory_mb: 0,
            job_cpu_secs: 0,
            watch: Vec::new(),
            web: crate::web::WebConfig::default(),
            store: crate::store::StoreConfig::default(),
        }
    }
}

impl DaemonConfig {
    /// The built-in default: watch `./inbox`, write `./outbox`, state in `./state`.
    pub fn built_in() -> DaemonConfig {
        DaemonConfig {
            create_missing_dirs: true,
            watch: vec![WatchConfig {
                path: PathBuf::from("./inbox"),
                output: PathBuf::from("./outbox"),
                recipe: default_recipe(),
                quiet_period_secs: default_quiet(),
                poll_secs: 0.0,
                include: Vec::new(),
                exclude: Vec::new(),
                marker: None,
                follow_symlinks: false,
            }],
            ..DaemonConfig::default()
        }
    }

    pub fn from_toml(text: &str, path: &Path) -> Result<DaemonConfig, ConfigError> {
        toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: path.to_path_buf(),
            message: crate::recipe::toml_error_message(text, &e),
        })
    }

    pub fn from_path(path: &Path) -> Result<DaemonConfig, ConfigError> {
        let text = crate::recipe::read_settings_file(path).map_err(|source| ConfigError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        DaemonConfig::from_toml(&text, path)
    }

    /// Finds and parses the configuration: `explicit` (from `--config`), else
    /// `$SCANMILL_CONFIG`, else `config/scanmill.toml` if it exists, else the built-in
    /// default. Does not validate.
    pub fn locate(explicit: Option<&Path>) -> Result<(DaemonConfig, ConfigSource), ConfigError> {
        let chosen = match explicit {
            Some(p) => Some(p.to_path_buf()),
            None => match std::env::var_os("SCANMILL_CONFIG") {
                Some(p) if !p.is_empty() => Some(PathBuf::from(p)),
                _ => {
                    let default = PathBuf::from("config/scanmill.toml");
                    default.is_file().then_some(default)
                }
            },
        };
        match chosen {
            Some(path) => Ok((DaemonConfig::from_path(&path)?, ConfigSource::File(path))),
            None => Ok((DaemonConfig::built_in(), ConfigSource::BuiltIn)),
        }
    }

    /// The memory limit of a job whose input set has `input_bytes` (see `job_memory_mb`).
    pub fn job_memory_bytes(&self, input_bytes: u64) -> u64 {
        if self.job_memory_mb > 0 {
            return self.job_memory_mb << 20;
        }
        let share = total_memory_bytes() / 4 * 3 / self.workers.max(1) as u64;
        AUTO_MEMORY_FLOOR
            .saturating_add(input_bytes.saturating_mul(AUTO_MEMORY_PER_INPUT_BYTE))
            .min(share.max(AUTO_MEMORY_FLOOR))
    }

    /// The memory limit for an input set whose members are `(bytes, compressed)`.
    pub fn job_memory_bytes_for(&self, members: impl Iterator<Item = (u64, bool)>) -> u64 {
        let expanded = members
            .map(|(bytes, gz)| {
                if gz {
                    bytes.saturating_mul(AUTO_GZIP_RATIO)
                } else {
                    bytes
                }
            })
            .fold(0u64, u64::saturating_add);
        self.job_memory_bytes(expanded)
    }

    /// The CPU-time limit of one job (see `job_cpu_secs`).
    pub fn job_cpu_secs(&self) -> u64 {
        if self.job_cpu_secs > 0 {
            return self.job_cpu_secs;
        }
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get()) as f64;
        (self.job_timeout_secs * cpus).ceil().max(1.0) as u64
    }

    /// The database file.
    pub fn database_path(&self) -> PathBuf {
        self.state_dir.join("scanmill.sqlite")
    }

    /// Checks everything that can be checked without starting: numbers in range, folders
    /// exist (or will be created), outputs and state outside every watched folder, watched
    /// folders not nested, recipes parse. Returns every problem found.
    pub fn validate(&self) -> Vec<String> {
        let mut problems = Vec::new();
        self.check_numbers(&mut problems);
        problems.extend(self.limits.validate());
        problems.extend(self.web.validate());
        problems.extend(self.store.validate());
        // On a shared queue a host may only work (no watched folders of its own).
        if self.watch.is_empty() && !self.store.is_shared() {
            problems.push("no [[watch]] folder configured".into());
        }
        self.check_dir("state_dir", &self.state_dir, &mut problems);
        for (i, w) in self.watch.iter().enumerate() {
            let name = format!("watch[{i}] ({})", crate::text::escape_path(&w.path));
            check_watch_settings(&name, w, &mut problems);
            self.check_dir(&format!("{name}: path"), &w.path, &mut problems);
            self.check_dir(&format!("{name}: output"), &w.output, &mut problems);
            self.check_watch_placement(i, &name, &mut problems);
            if let Err(e) = load_recipe(&w.recipe) {
                problems.push(format!("{name}: recipe: {e}"));
            }
        }
        problems
    }

    /// The top-level numbers in their ranges.
    fn check_numbers(&self, problems: &mut Vec<String>) {
        let positive = |name: &str, v: f64, problems: &mut Vec<String>| {
            if !(v.is_finite() && v > 0.0 && v <= MAX_SECS) {
                problems.push(format!(
                    "{name} must be a positive number of seconds up to {MAX_SECS} (a week), not {v}"
                ));
            }
        };
        if self.workers == 0 || self.workers > 64 {
            problems.push(format!("workers must be 1..=64, not {}", self.workers));
        }
        if self.max_attempts == 0 || self.max_attempts > 100 {
            problems.push(format!(
                "max_attempts must be 1..=100, not {}",
                self.max_attempts
            ));
        }
        if self.max_input_bytes == 0 {
            problems.push("max_input_bytes must be at least 1".into());
        }
        if self.min_free_disk_mb > 1 << 30 {
            problems.push(format!(
                "min_free_disk_mb must be at most {} (1 PiB), not {}",
                1u64 << 30,
                self.min_free_disk_mb
            ));
        }
        if self.job_memory_mb != 0 && !(64..=1 << 30).contains(&self.job_memory_mb) {
            problems.push(format!(
                "job_memory_mb must be 0 (automatic) or 64..={} MiB, not {}",
                1u64 << 30,
                self.job_memory_mb
            ));
        }
        if self.job_cpu_secs > MAX_SECS as u64 * 1024 {
            problems.push(format!(
                "job_cpu_secs must be 0 (automatic) or at most {}, not {}",
                MAX_SECS as u64 * 1024,
                self.job_cpu_secs
            ));
        }
        positive("retry_base_secs", self.retry_base_secs, problems);
        positive("retry_max_secs", self.retry_max_secs, problems);
        positive("job_timeout_secs", self.job_timeout_secs, problems);
        positive("drain_timeout_secs", self.drain_timeout_secs, problems);
        positive("rescan_secs", self.rescan_secs, problems);
        positive(
            "incomplete_report_secs",
            self.incomplete_report_secs,
            problems,
        );
    }

    /// Watch `i`'s output and the state folder outside its watched folder (lexically, and
    /// again with every link resolved: an output that is a symlink into the watched folder
    /// is inside it), and its watched folder apart from the later ones'.
    fn check_watch_placement(&self, i: usize, name: &str, problems: &mut Vec<String>) {
        let w = &self.watch[i];
        let state = absolute(&self.state_dir);
        let root = absolute(&w.path);
        let out = absolute(&w.output);
        let (real_root, real_out) = (resolved(&root), resolved(&out));
        if out.starts_with(&root)
            || root.starts_with(&out)
            || real_out.starts_with(&real_root)
            || real_root.starts_with(&real_out)
        {
            problems.push(format!(
                "{name}: output {} and the watched folder must not contain one another \
                 (the daemon would process its own output)",
                crate::text::escape_path(&w.output)
            ));
        }
        if state.starts_with(&root) || resolved(&state).starts_with(&real_root) {
            problems.push(format!(
                "{name}: state_dir must not be inside the watched folder"
            ));
        }
        for (j, other) in self.watch.iter().enumerate().skip(i + 1) {
            let o = absolute(&other.path);
            if o.starts_with(&root) || root.starts_with(&o) {
                problems.push(format!(
                    "{name} and watch[{j}] ({}) overlap; watched folders must be disjoint",
                    crate::text::escape_path(&other.path)
                ));
            }
            if absolute(&other.output).starts_with(&root)
                || resolved(&other.output).starts_with(&real_root)
            {
                problems.push(format!(
                    "watch[{j}]: output is inside watched folder {}",
                    crate::text::escape_path(&w.path)
                ));
            }
        }
    }

    fn check_dir(&self, name: &str, path: &Path, problems: &mut Vec<String>) {
        match std::fs::metadata(path) {
            Ok(m) if m.is_dir() => {}
            Ok(_) => problems.push(format!(
                "{name}: {} is not a folder",
                crate::text::escape_path(path)
            )),
            Err(_) if self.create_missing_dirs => {
                // It will be created: its nearest existing ancestor must be a folder.
                let mut ancestor = absolute(path);
                while !ancestor.exists() {
                    if !ancestor.pop() {
                        break;
                    }
                }
                if !ancestor.is_dir() {
                    problems.push(format!(
                        "{name}: cannot create {}",
                        crate::text::escape_path(path)
                    ));
                }
            }
            Err(e) => problems.push(format!("{name}: {}: {e}", crate::text::escape_path(path))),
        }
    }

    /// A stable hash of the resolved configuration (recorded with each job).
    pub fn hash(&self) -> String {
        use sha2::{Digest, Sha256};
        let canonical = serde_json::to_string(self).expect("config serialises");
        hex::encode(Sha256::digest(canonical.as_bytes()))
    }
}

/// Loads a watch folder's recipe. The shipped face-scan recipe may be missing on an odd
/// checkout; only for that exact default path the daemon falls back to a minimal
/// normals-only recipe (and says so), so that `scanmill daemon` on a fresh clone works.
pub fn load_recipe(path: &Path) -> Result<Recipe, RecipeError> {
    match Recipe::from_path(path) {
        Err(RecipeError::Io { source, .. })
            if source.kind() == std::io::ErrorKind::NotFound && path == default_recipe() =>
        {
            tracing::warn!(
                "{}: not found; using the built-in minimal recipe (normals only)",
                path.display()
            );
            Recipe::from_toml(BUILT_IN_RECIPE, Path::new("<built-in recipe>"))
        }
        other => other,
    }
}

/// The fallback recipe: recompute normals, write OBJ.
pub const BUILT_IN_RECIPE: &str = "[output]\nformat = \"obj\"\n\n[[step]]\nkind = \"normals\"\n";

/// `path` with every symlink resolved, as far as it exists: the longest existing ancestor
/// is canonicalised and the missing rest appended (it is created later, as a real folder).
pub fn resolved(path: &Path) -> PathBuf {
    let path = absolute(path);
    let mut existing = path.clone();
    let mut rest = Vec::new();
    loop {
        if let Ok(real) = existing.canonicalize() {
            return rest
                .iter()
                .rev()
                .fold(real, |p, c: &std::ffi::OsString| p.join(c));
        }
        match (
            existing.file_name().map(|n| n.to_os_string()),
            existing.parent(),
        ) {
            (Some(name), Some(parent)) => {
                rest.push(name);
                existing = parent.to_path_buf();
            }
            _ => return path,
        }
    }
}

/// The machine's physical memory, from sysinfo(2); 4 GiB if it cannot be read.
pub fn total_memory_bytes() -> u64 {
    // SAFETY: sysinfo fills the zeroed struct it is given.
    let mut info: libc::sysinfo = unsafe { std::mem::zeroed() };
    if unsafe { libc::sysinfo(&mut info) } != 0 {
        return 4 << 30;
    }
    (info.totalram as u64).saturating_mul(info.mem_unit.max(1) as u64)
}

/// `path` made absolute against the working directory and cleaned of `.` and `..`
/// (lexically: the folders may not exist yet).
pub fn absolute(path: &Path) -> PathBuf {
    let joined = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir()
            .unwrap_or_else(|_| PathBuf::from("/"))
            .join(path)
    };
    let mut out = PathBuf::new();
    for c in joined.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other.as_os_str()),
        }
    }
    out
}

/// One watched folder's own settings in their ranges.
fn check_watch_settings(name: &str, w: &WatchConfig, problems: &mut Vec<String>) {
    if !(w.quiet_period_secs.is_finite() && (0.05..=MAX_SECS).contains(&w.quiet_period_secs)) {
        problems.push(format!(
            "{name}: quiet_period_secs must be 0.05..={MAX_SECS}, not {}",
            w.quiet_period_secs
        ));
    }
    if !(w.poll_secs.is_finite() && (0.0..=MAX_SECS).contains(&w.poll_secs)) {
        problems.push(format!(
            "{name}: poll_secs must be 0 (use file events) or up to {MAX_SECS}, not {}",
            w.poll_secs
        ));
    }
    for p in w.include.iter().chain(&w.exclude) {
        if p.is_empty() {
            problems.push(format!("{name}: empty include/exclude pattern"));
        }
    }
    if let Some(m) = &w.marker
        && (m.is_empty() || m.contains('/'))
    {
        problems.push(format!(
            "{name}: marker must be a file name such as \"{{stem}}.done\""
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> DaemonConfig {
        DaemonConfig::from_toml(text, Path::new("t.toml")).unwrap()
    }

    #[test]
    fn design_shape_parses_with_defaults() {
        let c = parse(
            "state_dir = \"./state\"\nworkers = 1\n[[watch]]\npath = \"./inbox\"\noutput = \"./outbox\"\n\
             recipe = \"config/recipes/face-scan.toml\"\nquiet_period_secs = 30\npoll_secs = 0\n",
        );
        assert_eq!(c.workers, 1);
        assert_eq!(c.watch.len(), 1);
        assert_eq!(c.watch[0].quiet_period_secs, 30.0);
        assert_eq!(c.max_attempts, 3);
        assert!(!c.create_missing_dirs);
    }

    #[test]
    fn fractional_quiet_period_accepted() {
        let c = parse("[[watch]]\npath = \"a\"\noutput = \"b\"\nquiet_period_secs = 0.5\n");
        assert_eq!(c.watch[0].quiet_period_secs, 0.5);
    }

    #[test]
    fn unknown_key_is_an_error() {
        let e = DaemonConfig::from_toml("wrokers = 2\n", Path::new("t.toml")).unwrap_err();
        assert!(e.to_string().contains("wrokers"), "{e}");
    }

    #[test]
    fn validate_reports_output_inside_watch_and_missing_dirs() {
        let dir = tempfile::tempdir().unwrap();
        let inbox = dir.path().join("in");
        std::fs::create_dir(&inbox).unwrap();
        let recipe = dir.path().join("r.toml");
        std::fs::write(&recipe, BUILT_IN_RECIPE).unwrap();
        let text = format!(
            "state_dir = {:?}\n[[watch]]\npath = {:?}\noutput = {:?}\nrecipe = {:?}\nquiet_period_secs = 0\n",
            dir.path().join("missing-state"),
            inbox,
            inbox.join("out"),
            recipe
        );
        let problems = parse(&text).validate();
        let all = problems.join("\n");
        assert!(all.contains("must not contain one another"), "{all}");
        assert!(all.contains("quiet_period_secs"), "{all}");
        assert!(all.contains("missing-state"), "{all}");
        assert!(all.contains("output"), "{all}");
    }

    #[test]
    fn validate_accepts_good_config_and_rejects_bad_recipe() {
        let dir = tempfile::tempdir().unwrap();
        for d in ["in", "out", "state"] {
            std::fs::create_dir(dir.path().join(d)).unwrap();
        }
        let recipe = dir.path().join("r.toml");
        std::fs::write(&recipe, BUILT_IN_RECIPE).unwrap();
        let text = format!(
            "state_dir = {:?}\n[[watch]]\npath = {:?}\noutput = {:?}\nrecipe = {:?}\n",
            dir.path().join("state"),
            dir.path().join("in"),
            dir.path().join("out"),
            recipe
        );
        assert_eq!(parse(&text).validate(), Vec::<String>::new());
        std::fs::write(&recipe, "[[step]]\nkind = \"sharpen\"\n").unwrap();
        let problems = parse(&text).validate();
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert!(problems[0].contains("recipe"));
    }

    #[test]
    fn overlapping_watch_roots_rejected() {
        let c = parse(
            "create_missing_dirs = true\n[[watch]]\npath = \"/tmp/x\"\noutput = \"/tmp/o1\"\n\
             [[watch]]\npath = \"/tmp/x/y\"\noutput = \"/tmp/o2\"\n",
        );
        assert!(c.validate().iter().any(|p| p.contains("overlap")));
    }

    #[test]
    fn follow_symlinks_is_off_unless_set() {
        let c = parse("[[watch]]\npath = \"a\"\noutput = \"b\"\n");
        assert!(!c.watch[0].follow_symlinks);
        let c = parse("[[watch]]\npath = \"a\"\noutput = \"b\"\nfollow_symlinks = true\n");
        assert!(c.watch[0].follow_symlinks);
    }

    #[test]
    fn absolute_cleans_dots() {
        assert_eq!(absolute(Path::new("/a/./b/../c")), PathBuf::from("/a/c"));
    }
}
