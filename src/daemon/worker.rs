//! One job, supervised from one OS thread of the daemon: check the inputs are still the ones
//! queued, run the recipe in a worker process ([`super::supervise`]) into a staging folder,
//! check again, write the provenance sidecar, publish.
//!
//! Everything that reads the scan runs in the worker process, under its memory, CPU and
//! wall-clock limits: a file that makes it abort, crash or run out of memory ends that
//! process only. The thread here only stats files, writes the sidecar and renames; it runs
//! inside `catch_unwind` all the same. A job that is abandoned (the daemon stopping) has
//! its [`PublishGate`] closed by the service: the supervisor then kills the worker, and the
//! gate is checked again right before the one rename that makes a result visible, so an
//! abandoned job can never publish.

use super::publish::{self, Published, SIDECAR_SUFFIX, STAGING_DIR};
use super::scanset::StatSig;
use super::supervise::{self, WorkerLimits, WorkerOutcome, WorkerRequest};
use crate::process::output_stem;
use crate::recipe::Recipe;
use crate::report::Report;
use crate::store::FailureKind;
use crate::store::{ClaimedJob, Finish, JobDone, MeshSizes, OutputFile, Owner, StepRow, now_ms};
use serde_json::json;
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};
use std::time::Instant;

const RUNNING: u8 = 0;
const PUBLISHING: u8 = 1;
const ABANDONED: u8 = 2;

/// Decides, once, whether a job publishes or is abandoned.
#[derive(Debug, Default)]
pub struct PublishGate(AtomicU8);

impl PublishGate {
    /// The worker asks to publish; false if the job was abandoned.
    pub fn begin_publish(&self) -> bool {
        self.0
            .compare_exchange(RUNNING, PUBLISHING, Ordering::SeqCst, Ordering::SeqCst)
            .is_ok()
    }
    /// The service abandons the job; false if it is already publishing (then wait for it).
    pub fn abandon(&self) -> bool {
        self.0
            .compare_exchange(RUNNING, ABANDONED, Ordering::SeqCst, Ordering::SeqCst)
            .is_ok()
    }
    /// Whether the service has given up on the job (its worker is to be killed).
    pub fn is_abandoned(&self) -> bool {
        self.0.load(Ordering::SeqCst) == ABANDONED
    }
}

/// Everything a job needs, owned, so it can move to its thread.
pub struct JobSpec {
    pub job: ClaimedJob,
    pub recipe: Arc<Recipe>,
    pub recipe_path: PathBuf,
    pub config_hash: String,
    pub owner: Owner,
    pub max_input_bytes: u64,
    pub limits: WorkerLimits,
    pub input_limits: crate::mesh::InputLimits,
    pub gate: Arc<PublishGate>,
    /// The shared queue's fence: publishing happens only while this attempt's token
    /// still holds the job (`None` on SQLite, where the daemon owns its jobs).
    pub fence: Option<Arc<crate::store::pg::Fence>>,
}

/// What a finished thread reports.
#[derive(Debug, Clone)]
pub enum JobResult {
    Finished {
        finish: Finish,
        wall_ms: f64,
    },
    /// The gate was closed (timeout or shutdown); nothing was published.
    Abandoned,
}

fn failure(kind: FailureKind, message: impl Into<String>, transient: bool) -> Finish {
    Finish::Failed {
        kind,
        message: message.into(),
        transient,
    }
}

/// Runs the job to its end. Never panics.
pub fn run(spec: JobSpec) -> JobResult {
    let start = Instant::now();
    let span = tracing::info_span!("job", job_id = spec.job.id, input = %spec.job.order.rel_path, attempt = spec.job.attempt);
    let _guard = span.enter();
    let staging = Path::new(&spec.job.order.output_root)
        .join(STAGING_DIR)
        .join(format!(
            "job{}-g{}-a{}-{}",
            spec.job.id,
            spec.job.generation,
            spec.job.attempt,
            std::process::id()
        ));
    let outcome = std::panic::catch_unwind(AssertUnwindSafe(|| run_inner(&spec, &staging)));
    // Whatever happened, nothing of this attempt stays in staging.
    if staging.exists()
        && let Err(e) = std::fs::remove_dir_all(&staging)
    {
        tracing::warn!("cannot remove {}: {e}", staging.display());
    }
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    match outcome {
        Ok(Some(finish)) => JobResult::Finished { finish, wall_ms },
        Ok(None) => JobResult::Abandoned,
        Err(panic) => {
            let message = panic_message(panic.as_ref());
            tracing::error!("job panicked: {message}");
            JobResult::Finished {
                finish: failure(
                    FailureKind::Panic,
                    format!("internal error (panic): {message}"),
                    false,
                ),
                wall_ms,
            }
        }
    }
}

/// Checks every input member is still the file that was queued.
fn check_inputs(job: &ClaimedJob) -> Result<(), Box<Finish>> {
    let root = Path::new(&job.order.root);
    for m in &job.inputs {
        let path = root.join(&m.rel_path);
        match StatSig::of(&path) {
            Ok(s) if s.size == m.size && s.mtime_ns == m.mtime_ns && s.ino == m.ino => {}
            Ok(_) => {
                return Err(boxed_failure(
                    FailureKind::InputChanged,
                    format!(
                        "{} changed after it was queued; the new version is a new job",
                        crate::text::escape_path(&path)
                    ),
                    false,
                ));
            }
            Err(e) => {
                return Err(boxed_failure(
                    FailureKind::InputVanished,
                    format!("{}: {e}", crate::text::escape_path(&path)),
                    false,
                ));
            }
        }
    }
    Ok(())
}

/// Why a job stopped before its end: a failure to record, or the gate closed.
enum Halt {
    Failed(Box<Finish>),
    Abandoned,
}

impl From<Box<Finish>> for Halt {
    fn from(f: Box<Finish>) -> Halt {
        Halt::Failed(f)
    }
}

fn halt(kind: FailureKind, message: impl Into<String>, transient: bool) -> Halt {
    Halt::Failed(boxed_failure(kind, message, transient))
}

/// The job's phases in order; `None` when it was abandoned.
fn run_inner(spec: &JobSpec, staging: &Path) -> Option<Finish> {
    let started = Instant::now();
    let phases = || -> Result<Finish, Halt> {
        preflight(spec)?;
        let job = &spec.job;
        let primary = Path::new(&job.order.root).join(&job.order.rel_path);
        let stem = output_stem(&primary);
        let scan_dir = staging.join(&stem);
        std::fs::create_dir_all(&scan_dir).map_err(|e| {
            halt(
                FailureKind::Output,
                format!("{}: {e}", scan_dir.display()),
                true,
            )
        })?;
        let started_ms = now_ms();
        let report = process_in_worker(spec, primary, &scan_dir)?;
        check_inputs(job)?;
        write_sidecar(spec, &report, &scan_dir, &stem, started_ms)?;
        let publish_and_record = || {
            let final_dir = publish(spec, &scan_dir, &stem)?;
            tracing::info!(output = %final_dir.display(), ms = report.total_ms, "published");
            Ok(done(
                report.with_output_folder(&scan_dir, &final_dir),
                &final_dir,
            ))
        };
        match &spec.fence {
            None => publish_and_record(),
            Some(fence) => fenced(fence, job, started, publish_and_record),
        }
    };
    match phases() {
        Ok(finish) => Some(finish),
        Err(Halt::Failed(f)) => Some(*f),
        Err(Halt::Abandoned) => None,
    }
}

/// Publishes through the shared queue's fence: only while this attempt holds the job.
fn fenced(
    fence: &crate::store::pg::Fence,
    job: &ClaimedJob,
    started: Instant,
    publish: impl FnOnce() -> Result<Finish, Halt>,
) -> Result<Finish, Halt> {
    use crate::store::pg::Fenced;
    match fence.hold(job, started, publish) {
        Ok(Fenced::Held(result)) => result,
        Ok(Fenced::Superseded) => {
            tracing::warn!("lease lost and the job taken over: fenced out, nothing published");
            Err(halt(
                FailureKind::Superseded,
                "fenced out: another attempt holds the job",
                false,
            ))
        }
        Err(e) => Err(halt(
            FailureKind::Output,
            format!("cannot confirm this attempt still holds the job ({e}); not published"),
            true,
        )),
    }
}

/// What is checked before the worker starts: the recipe and the inputs are still the ones
/// queued, and the input set is within `max_input_bytes`.
fn preflight(spec: &JobSpec) -> Result<(), Halt> {
    let job = &spec.job;
    if spec.recipe.hash() != job.order.recipe_hash {
        return Err(halt(
            FailureKind::RecipeChanged,
            format!(
                "{} changed since this job was queued; the scan is queued again under the new recipe",
                spec.recipe_path.display()
            ),
            false,
        ));
    }
    check_inputs(job)?;
    let total: u64 = job.inputs.iter().map(|m| m.size).sum();
    if total > spec.max_input_bytes {
        return Err(halt(
            FailureKind::TooLarge,
            format!(
                "input set is {total} bytes, above max_input_bytes = {}",
                spec.max_input_bytes
            ),
            false,
        ));
    }
    Ok(())
}

/// Runs the recipe on `primary` in a worker process, into `scan_dir`.
fn process_in_worker(spec: &JobSpec, primary: PathBuf, scan_dir: &Path) -> Result<Report, Halt> {
    let job = &spec.job;
    let request = WorkerRequest {
        job_id: job.id,
        input: primary,
        recipe: spec.recipe_path.clone(),
        recipe_hash: job.order.recipe_hash.clone(),
        out: scan_dir.to_path_buf(),
        limits: spec.limits,
        input_limits: spec.input_limits.clone(),
    };
    let mut on_stage = |index: usize, total: usize, name: &str| {
        tracing::debug!(job_id = job.id, index, total, stage = name, "stage");
    };
    match supervise::run(&request, &spec.gate, &mut on_stage) {
        WorkerOutcome::Done {
            report,
            isolation_ms,
        } => {
            tracing::info!(
                isolation_ms,
                process_ms = report.total_ms,
                "worker finished"
            );
            Ok(*report)
        }
        WorkerOutcome::Abandoned => {
            tracing::warn!("abandoned while running; worker killed");
            Err(Halt::Abandoned)
        }
        WorkerOutcome::Failed(f) => {
            // An input that vanished or changed while being read is not the scan's fault.
            check_inputs(job)?;
            Err(halt(f.kind, f.message, f.transient))
        }
    }
}

/// Writes the provenance sidecar beside the files and syncs the folder.
fn write_sidecar(
    spec: &JobSpec,
    report: &Report,
    scan_dir: &Path,
    stem: &str,
    started_ms: i64,
) -> Result<(), Halt> {
    let job = &spec.job;
    // The sidecar sits beside the files: its paths are relative to its folder.
    let sidecar_report = report.with_output_folder(scan_dir, Path::new(""));
    let sidecar = json!({
        "job_id": job.id,
        "job_key": job.order.job_key,
        "generation": job.generation,
        "attempt": job.attempt,
        "set_hash": job.order.set_hash,
        "inputs": job.inputs.iter().map(|m| json!({
            "path": crate::text::escape_path(&Path::new(&job.order.root).join(&m.rel_path)),
            "role": m.role.as_str(), "bytes": m.size, "mtime_ns": m.mtime_ns, "sha256": m.sha256,
        })).collect::<Vec<_>>(),
        "recipe": { "path": spec.recipe_path, "hash": job.order.recipe_hash, "resolved": spec.recipe.resolved_json() },
        "config_hash": spec.config_hash,
        "scanmill_version": spec.owner.app_version,
        "host": spec.owner.host,
        "daemon": spec.owner.id,
        "started": crate::store::query::iso_time(started_ms),
        "finished": crate::store::query::iso_time(now_ms()),
        "report": serde_json::to_value(&sidecar_report).unwrap_or_default(),
    });
    let sidecar_path = scan_dir.join(format!("{stem}{SIDECAR_SUFFIX}"));
    serde_json::to_vec_pretty(&sidecar)
        .map_err(std::io::Error::other)
        .and_then(|bytes| std::fs::write(&sidecar_path, bytes))
        .and_then(|_| publish::sync_tree(scan_dir))
        .map_err(|e| {
            halt(
                FailureKind::Output,
                format!("{}: {e}", scan_dir.display()),
                true,
            )
        })
}

/// Publishes the staged folder, unless the job was abandoned; the folder it went to.
fn publish(spec: &JobSpec, scan_dir: &Path, stem: &str) -> Result<PathBuf, Halt> {
    let job = &spec.job;
    if !spec.gate.begin_publish() {
        tracing::warn!("abandoned before publishing; result discarded");
        return Err(Halt::Abandoned);
    }
    // The output folder is named from the escaped form: never a control character in it.
    let dest = publish::destination(
        Path::new(&job.order.output_root),
        &job.order.rel_path.to_string(),
        stem,
    );
    match publish::publish_dir(scan_dir, &dest, stem, &job.order.job_key, job.generation) {
        Ok(Published::New(d)) => Ok(d),
        Ok(Published::AlreadyThere(d)) => {
            tracing::info!(
                "{} already holds this job's result (published before a restart)",
                d.display()
            );
            Ok(d)
        }
        Err(e) => Err(halt(
            FailureKind::Output,
            format!("publish to {}: {e}", dest.display()),
            true,
        )),
    }
}

/// What the store records of a published job.
fn done(report: Report, final_dir: &Path) -> Finish {
    let report_value = serde_json::to_value(&report).unwrap_or_default();
    let outputs = report
        .output
        .files
        .iter()
        .map(|f| {
            let name = f.path.file_name().map(PathBuf::from).unwrap_or_default();
            OutputFile {
                path: final_dir.join(name).to_string_lossy().into_owned(),
                bytes: f.bytes,
                sha256: f.sha256.clone(),
            }
        })
        .collect();
    let steps = report
        .steps
        .iter()
        .map(|s| StepRow {
            kind: s.kind.clone(),
            wall_ms: s.wall_ms,
            vertices_before: s.vertices_before as i64,
            vertices_after: s.vertices_after as i64,
            faces_before: s.faces_before as i64,
            faces_after: s.faces_after as i64,
            figures_json: s.figures.to_string(),
        })
        .collect();
    // The preview was published into the same folder as the mesh.
    let preview = report
        .preview
        .as_ref()
        .and_then(|p| p.file.path.file_name())
        .map(|name| final_dir.join(name).to_string_lossy().into_owned());
    Finish::Done(JobDone {
        output_dir: final_dir.to_string_lossy().into_owned(),
        preview,
        outputs,
        report_json: report_value.to_string(),
        counts: MeshSizes {
            in_vertices: report.input.counts.vertices as i64,
            in_faces: report.input.counts.faces as i64,
            out_vertices: report.output.counts.vertices as i64,
            out_faces: report.output.counts.faces as i64,
        },
        process_ms: report.total_ms,
        steps,
    })
}

/// The text a panic carried (`panic!` with a literal or a formatted message).
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

fn boxed_failure(kind: FailureKind, message: impl Into<String>, transient: bool) -> Box<Finish> {
    Box::new(failure(kind, message, transient))
}
