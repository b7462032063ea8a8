//! The worker side of a daemon job: `scanmill worker`, started by the daemon for one job.
//!
//! It loads the recipe (and checks it is the one the job was queued with), runs the same
//! [`crate::process::process_scan_with_options`] as `scanmill process` into the staging folder it is
//! given, and reports on standard output in the [`super::protocol`]. It never publishes and
//! never touches the database: whatever happens in here (a panic, an abort, running out of
//! memory, a signal) ends this process only, and the daemon records it as the job's failure.

use super::protocol::{Event, Line};
use super::worker::panic_message;
use crate::config::load_recipe;
use crate::mesh::InputLimits;
use crate::process::{ProcessError, ProcessOptions, process_scan_with_options};
use crate::recipe::runner::Progress;
use crate::store::FailureKind;
use std::io::Write;
use std::panic::AssertUnwindSafe;
use std::path::PathBuf;
use std::time::Duration;

/// What the daemon passes on the command line.
#[derive(Debug, Clone)]
pub struct WorkerArgs {
    pub job_id: i64,
    pub input: PathBuf,
    pub recipe: PathBuf,
    pub recipe_hash: String,
    /// The input limits of the daemon's `[limits]`.
    pub limits: InputLimits,
    pub out: PathBuf,
}

/// Test-only hooks, read from the environment the daemon passes on.
mod test_hooks {
    use std::path::Path;
    use std::time::Duration;

    /// `SCANMILL_TEST_STEP_DELAY_MS`: sleep this long at every stage, so that tests can
    /// interrupt a job at a known point.
    pub fn stage_delay() -> Option<Duration> {
        std::env::var("SCANMILL_TEST_STEP_DELAY_MS")
            .ok()
            .and_then(|v| v.parse::<u64>().ok())
            .filter(|&ms| ms > 0)
            .map(Duration::from_millis)
    }

    /// `SCANMILL_TEST_WORKER_FAULT=KIND:NAME[,KIND:NAME…]`: misbehave as KIND (`abort`,
    /// `segv`, `oom`, `hang`, `spin`) when the input's file name contains NAME, so that the
    /// tests can show that a worker dying in each way fails only its own job.
    pub fn inject_fault(input: &Path) {
        let Ok(specs) = std::env::var("SCANMILL_TEST_WORKER_FAULT") else {
            return;
        };
        let name = input
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let chosen = specs.split(',').find_map(|spec| {
            let (kind, needle) = spec.split_once(':')?;
            (!needle.is_empty() && name.contains(needle)).then_some(kind)
        });
        let Some(kind) = chosen else {
            return;
        };
        tracing::warn!("test hook: worker fault {kind:?}");
        match kind {
            "abort" => std::process::abort(),
            // SAFETY: none: a write through a null pointer, the segmentation fault wanted.
            "segv" => unsafe {
                std::ptr::null_mut::<u8>().write_volatile(1);
            },
            "oom" => {
                // Touch memory until the worker's memory limit refuses more; capped so
                // that a run without a limit cannot take the machine with it.
                let mut held: Vec<Vec<u8>> = Vec::new();
                for _ in 0..1024 {
                    held.push(vec![1u8; 64 << 20]);
                }
                std::hint::black_box(&held);
            }
            "hang" => loop {
                std::thread::sleep(Duration::from_secs(1));
            },
            "spin" => {
                let mut x = 0u64;
                loop {
                    x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
                }
            }
            _ => {}
        }
    }
}

struct PipeProgress {
    delay: Option<Duration>,
}

impl Progress for PipeProgress {
    fn stage(&self, index: usize, total: usize, name: &str) {
        emit(Event::Stage {
            index,
            total,
            name: name.to_string(),
        });
        if let Some(d) = self.delay {
            std::thread::sleep(d);
        }
    }
}

fn emit(event: Event) {
    let mut out = std::io::stdout().lock();
    // A daemon that stopped reading has killed us or is gone: nothing left to tell.
    let _ = out.write_all(&Line::new(event).encode());
    let _ = out.flush();
}

/// The failure kind and whether another attempt could help, for a processing error.
pub fn failure_of(e: &ProcessError) -> Event {
    let kind = match e {
        ProcessError::Input(_) => FailureKind::Input,
        ProcessError::Step { .. } => FailureKind::Step,
        ProcessError::Output { .. } => FailureKind::Output,
    };
    Event::Failed {
        kind,
        message: e.to_string(),
        transient: e.is_transient(),
    }
}

/// Runs the job and reports; the exit code is 0 whenever a final event was written.
pub fn run(args: WorkerArgs) -> u8 {
    let span = tracing::info_span!("worker", job_id = args.job_id, pid = std::process::id());
    let _guard = span.enter();
    let start = std::time::Instant::now();
    // When memory runs short, the kernel's OOM killer should take a worker, not the daemon
    // that records why it died. Raising one's own score needs no privilege.
    let _ = std::fs::write("/proc/self/oom_score_adj", "500");
    test_hooks::inject_fault(&args.input);
    let event = std::panic::catch_unwind(AssertUnwindSafe(|| run_job(&args, start)))
        .unwrap_or_else(|panic| {
            let message = panic_message(panic.as_ref());
            tracing::error!("job panicked: {message}");
            Event::Failed {
                kind: FailureKind::Panic,
                message: format!("internal error (panic): {message}"),
                transient: false,
            }
        });
    emit(event);
    0
}

fn run_job(args: &WorkerArgs, start: std::time::Instant) -> Event {
    let recipe = match load_recipe(&args.recipe) {
        Ok(r) => r,
        Err(e) => {
            return Event::Failed {
                kind: FailureKind::Recipe,
                message: e.to_string(),
                transient: false,
            };
        }
    };
    if recipe.hash() != args.recipe_hash {
        return Event::Failed {
            kind: FailureKind::RecipeChanged,
            message: format!(
                "{} changed since this job was queued; the scan is queued again under the new recipe",
                args.recipe.display()
            ),
            transient: false,
        };
    }
    let progress = PipeProgress {
        delay: test_hooks::stage_delay(),
    };
    let options = ProcessOptions {
        texture: None,
        limits: args.limits.clone(),
    };
    match process_scan_with_options(
        &args.input,
        &options,
        &recipe,
        Some(&args.recipe),
        &args.out,
        &progress,
    ) {
        Ok(report) => Event::Done {
            report: Box::new(report),
            busy_ms: start.elapsed().as_secs_f64() * 1e3,
        },
        Err(e) => failure_of(&e),
    }
}
