//! The daemon side of a job's worker process: start it with its resource limits, read its
//! events, kill it at the wall-clock deadline or when the job is abandoned, and turn how it
//! ended into the job's outcome.
//!
//! Limits are set in the child between `fork` and `exec`, so they bind the worker from its
//! first instruction:
//! - memory: `RLIMIT_DATA` (heap and private writable mappings; unlike `RLIMIT_AS` it does
//!   not count the address space that allocators and thread stacks only reserve), so an
//!   allocation past the limit fails and the worker aborts;
//! - CPU time: `RLIMIT_CPU` (SIGXCPU at the limit, SIGKILL a little later);
//! - no core dumps; its own process group (a terminal's Ctrl-C reaches the daemon only, which
//!   drains); `PR_SET_PDEATHSIG` so that a worker never outlives the thread supervising it.
//!
//! The supervising thread owns the child until it has reaped it, so the PID it kills can
//! never belong to another process.

use super::protocol::{self, Event, Line};
use super::worker::PublishGate;
use crate::mesh::InputLimits;
use crate::report::Report;
use crate::store::FailureKind;
use std::collections::VecDeque;
use std::ffi::OsString;
use std::io::{BufRead, BufReader, Read, Write};
use std::os::unix::process::CommandExt;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// One job's worker: what to run and within which limits.
#[derive(Debug, Clone)]
pub struct WorkerRequest {
    pub job_id: i64,
    pub input: PathBuf,
    pub recipe: PathBuf,
    pub recipe_hash: String,
    /// The staging folder the worker writes into.
    pub out: PathBuf,
    pub limits: WorkerLimits,
    /// The input limits the worker loads the scan under (the daemon's `[limits]`).
    pub input_limits: InputLimits,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorkerLimits {
    /// `RLIMIT_DATA` of the worker, in bytes.
    pub memory_bytes: u64,
    /// `RLIMIT_CPU` of the worker, in seconds of CPU time (all threads together).
    pub cpu_secs: u64,
    /// Wall-clock time after which the worker is killed.
    pub wall: Duration,
}

/// Why a job failed, and whether trying again could help.
#[derive(Debug, Clone, PartialEq)]
pub struct ProcessFailure {
    pub kind: FailureKind,
    pub message: String,
    pub transient: bool,
}

impl ProcessFailure {
    fn worker(kind: FailureKind, message: String) -> ProcessFailure {
        // A worker that dies is retried: a second attempt may find more memory or a quieter
        // machine, and a file that kills it every time is quarantined after max_attempts.
        ProcessFailure {
            kind,
            message,
            transient: true,
        }
    }
}

/// How a worker ended.
#[derive(Debug)]
pub enum WorkerOutcome {
    Done {
        report: Box<Report>,
        /// What isolation cost: the wall time from starting the worker to its report, less
        /// the time the worker itself spent on the job.
        isolation_ms: f64,
    },
    Failed(ProcessFailure),
    /// Killed because the job was abandoned (daemon stopping); nothing to record as failed.
    Abandoned,
}

/// What the worker said last and how it ended, before interpretation.
struct Ended {
    /// The wait status; `None` when the worker gave its final word and its exit was left
    /// to a reaper in the background.
    status: Option<libc::c_int>,
    rusage: libc::rusage,
    wall: Duration,
    final_event: Option<Event>,
    protocol_error: Option<String>,
    killed: Option<KillReason>,
    stderr_tail: Vec<String>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum KillReason {
    Deadline,
    Abandoned,
    Protocol,
}

/// How often the supervisor looks at the publish gate while the worker is quiet.
const GATE_POLL: Duration = Duration::from_millis(100);
/// Lines of the worker's standard error kept to explain a crash.
const STDERR_TAIL_LINES: usize = 8;

/// Runs one worker to its end. `on_stage` sees every stage as the worker starts it.
pub fn run(
    request: &WorkerRequest,
    gate: &PublishGate,
    on_stage: &mut dyn FnMut(usize, usize, &str),
) -> WorkerOutcome {
    let ended = match spawn_and_wait(request, gate, on_stage) {
        Ok(e) => e,
        Err(e) => {
            return WorkerOutcome::Failed(ProcessFailure::worker(
                FailureKind::Spawn,
                format!("cannot start the worker process: {e}"),
            ));
        }
    };
    interpret(ended, &request.limits)
}

fn command(request: &WorkerRequest) -> Command {
    // The running binary itself, even if the file was replaced by an upgrade since.
    let mut cmd = Command::new("/proc/self/exe");
    cmd.arg0("scanmill")
        .arg("worker")
        .arg("--protocol")
        .arg(protocol::VERSION.to_string())
        .arg("--job-id")
        .arg(request.job_id.to_string())
        .arg("--recipe-hash")
        .arg(&request.recipe_hash)
        .arg("--limits")
        .arg(serde_json::to_string(&request.input_limits).expect("limits serialise"))
        .args([OsString::from("--input"), request.input.clone().into()])
        .args([OsString::from("--recipe"), request.recipe.clone().into()])
        .args([OsString::from("--out"), request.out.clone().into()])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let limits = request.limits;
    // SAFETY: between fork and exec only async-signal-safe calls are made (setpgid, prctl,
    // setrlimit), on values computed before the fork.
    unsafe {
        cmd.pre_exec(move || {
            if libc::setpgid(0, 0) != 0
                || libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL as libc::c_ulong) != 0
            {
                return Err(std::io::Error::last_os_error());
            }
            let set = |resource, soft: u64, hard: u64| {
                let lim = libc::rlimit {
                    rlim_cur: soft as libc::rlim_t,
                    rlim_max: hard as libc::rlim_t,
                };
                if libc::setrlimit(resource, &lim) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            };
            set(libc::RLIMIT_CORE, 0, 0)?;
            set(libc::RLIMIT_DATA, limits.memory_bytes, limits.memory_bytes)?;
            set(libc::RLIMIT_CPU, limits.cpu_secs, limits.cpu_secs + 5)?;
            Ok(())
        });
    }
    cmd
}

enum Piped {
    Line(Vec<u8>),
    TooLong,
}

fn spawn_and_wait(
    request: &WorkerRequest,
    gate: &PublishGate,
    on_stage: &mut dyn FnMut(usize, usize, &str),
) -> std::io::Result<Ended> {
    let start = Instant::now();
    let mut child = command(request).spawn()?;
    let pid = child.id() as libc::pid_t;
    let stdout = child.stdout.take().expect("piped");
    let stderr = child.stderr.take().expect("piped");
    let (tx, rx) = mpsc::channel();
    let reader = std::thread::Builder::new()
        .name(format!("scanmill-job-{}-out", request.job_id))
        .spawn(move || read_lines(stdout, tx))?;
    let tail = Arc::new(Mutex::new(VecDeque::new()));
    let forwarder = {
        let tail = tail.clone();
        std::thread::Builder::new()
            .name(format!("scanmill-job-{}-err", request.job_id))
            .spawn(move || forward_stderr(stderr, &tail))?
    };
    let watch = Watch {
        pid,
        gate,
        deadline: start + request.limits.wall,
    };
    let Heard {
        final_event,
        protocol_error,
        mut killed,
    } = watch.listen(&rx, on_stage);
    if final_event.is_some() && protocol_error.is_none() && killed.is_none() {
        // The worker has said all it will say. Its exit (freeing a large scan's memory takes
        // tens of milliseconds) is not waited for: a reaper does that in the background.
        let wall = start.elapsed();
        let stderr_tail = tail_of(&tail);
        reap_later(pid, request.job_id, reader, forwarder);
        std::mem::forget(child);
        return Ok(Ended {
            status: None,
            // SAFETY: all-zero is a valid rusage.
            rusage: unsafe { std::mem::zeroed() },
            wall,
            final_event,
            protocol_error,
            killed,
            stderr_tail,
        });
    }
    let (status, rusage) = watch.reap(&mut killed);
    let wall = start.elapsed();
    let _ = reader.join();
    let _ = forwarder.join();
    // The child was reaped by wait4; std's handle must not wait for it again.
    std::mem::forget(child);
    Ok(Ended {
        status: Some(status),
        rusage,
        wall,
        final_event,
        protocol_error,
        killed,
        stderr_tail: tail_of(&tail),
    })
}

/// The last lines of the worker's standard error.
fn tail_of(tail: &Mutex<VecDeque<String>>) -> Vec<String> {
    tail.lock()
        .map(|t| t.iter().cloned().collect())
        .unwrap_or_default()
}

/// A running worker, watched against its deadline and the publish gate.
struct Watch<'g> {
    pid: libc::pid_t,
    gate: &'g PublishGate,
    deadline: Instant,
}

/// What the worker said on its standard output before it closed it or was killed.
struct Heard {
    final_event: Option<Event>,
    protocol_error: Option<String>,
    killed: Option<KillReason>,
}

impl Watch<'_> {
    /// Why the worker must be killed now, if it must: the job was abandoned, or its
    /// deadline has passed.
    fn kill_reason(&self) -> Option<KillReason> {
        if self.gate.is_abandoned() {
            Some(KillReason::Abandoned)
        } else if Instant::now() >= self.deadline {
            Some(KillReason::Deadline)
        } else {
            None
        }
    }

    /// Reads the worker's lines until its final word or until its output closes: stages go
    /// to `on_stage`; a line that breaks the protocol gets the worker killed, as do the
    /// deadline and an abandoned job.
    fn listen(
        &self,
        rx: &mpsc::Receiver<Piped>,
        on_stage: &mut dyn FnMut(usize, usize, &str),
    ) -> Heard {
        let mut heard = Heard {
            final_event: None,
            protocol_error: None,
            killed: None,
        };
        loop {
            if heard.killed.is_none() {
                heard.killed = self.kill_reason();
                if heard.killed.is_some() {
                    kill(self.pid);
                }
            }
            let wait = self
                .deadline
                .saturating_duration_since(Instant::now())
                .clamp(Duration::from_millis(1), GATE_POLL);
            match rx.recv_timeout(wait) {
                Ok(Piped::Line(bytes)) => match Line::decode(&bytes) {
                    Ok(Line {
                        event: Event::Stage { index, total, name },
                        ..
                    }) => on_stage(index, total, &name),
                    Ok(line) => {
                        heard.final_event = Some(line.event);
                        break;
                    }
                    Err(e) => {
                        heard.protocol_error.get_or_insert(e);
                    }
                },
                Ok(Piped::TooLong) => {
                    heard.protocol_error.get_or_insert_with(|| {
                        format!(
                            "a line longer than {} bytes from the worker",
                            protocol::MAX_LINE_BYTES
                        )
                    });
                }
                Err(RecvTimeoutError::Timeout) => continue,
                Err(RecvTimeoutError::Disconnected) => break,
            }
            if heard.protocol_error.is_some() && heard.killed.is_none() {
                heard.killed = Some(KillReason::Protocol);
                kill(self.pid);
            }
        }
        heard
    }

    /// Waits for the worker to exit. Standard output is closed without a final word: the
    /// worker is exiting (or has closed it, which the protocol does not allow: then it is
    /// killed after the deadline like any other).
    fn reap(&self, killed: &mut Option<KillReason>) -> (libc::c_int, libc::rusage) {
        loop {
            match reap(self.pid, Duration::from_millis(50)) {
                Some(r) => return r,
                None if killed.is_none() => {
                    if let Some(reason) = self.kill_reason() {
                        *killed = Some(reason);
                        kill(self.pid);
                    }
                }
                None => {}
            }
        }
    }
}

/// How long a worker that has given its final word may take to exit before it is killed.
const EXIT_PATIENCE: Duration = Duration::from_secs(30);

/// Waits for a worker that has finished its job to exit, on a thread of its own.
fn reap_later(
    pid: libc::pid_t,
    job_id: i64,
    reader: std::thread::JoinHandle<()>,
    forwarder: std::thread::JoinHandle<()>,
) {
    let reaper = move || {
        if reap(pid, EXIT_PATIENCE).is_none() {
            tracing::warn!(job_id, pid, "worker did not exit after its result; killed");
            kill(pid);
            while reap(pid, Duration::from_secs(1)).is_none() {}
        }
        let _ = reader.join();
        let _ = forwarder.join();
    };
    let spawned = std::thread::Builder::new()
        .name(format!("scanmill-job-{job_id}-reap"))
        .spawn(reaper);
    if let Err(e) = spawned {
        // No thread to spare: kill it now (its result is already in hand) and reap here.
        tracing::warn!(job_id, "cannot start a reaper ({e}); killing the worker");
        kill(pid);
        while reap(pid, Duration::from_secs(1)).is_none() {}
    }
}

/// Kills the worker and anything it started (its own process group).
fn kill(pid: libc::pid_t) {
    // SAFETY: plain syscalls; `pid` is our unreaped child, so the IDs are still ours.
    unsafe {
        libc::kill(-pid, libc::SIGKILL);
        libc::kill(pid, libc::SIGKILL);
    }
}

/// Waits up to `patience` for the worker to exit; its status and resource use.
fn reap(pid: libc::pid_t, patience: Duration) -> Option<(libc::c_int, libc::rusage)> {
    let until = Instant::now() + patience;
    loop {
        let mut status = 0;
        // SAFETY: zeroed rusage is a valid value; wait4 fills it.
        let mut rusage: libc::rusage = unsafe { std::mem::zeroed() };
        // SAFETY: waiting for our own child.
        let r = unsafe { libc::wait4(pid, &mut status, libc::WNOHANG, &mut rusage) };
        if r == pid {
            return Some((status, rusage));
        }
        if r < 0 {
            let e = std::io::Error::last_os_error();
            if e.raw_os_error() != Some(libc::EINTR) {
                // Not our child any more (cannot happen: we are its only reaper).
                return Some((0, rusage));
            }
        }
        if Instant::now() >= until {
            return None;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn read_lines(stdout: impl Read, tx: mpsc::Sender<Piped>) {
    let mut reader = BufReader::new(stdout);
    loop {
        let mut line = Vec::new();
        let limit = protocol::MAX_LINE_BYTES as u64 + 1;
        match (&mut reader).take(limit).read_until(b'\n', &mut line) {
            Ok(0) | Err(_) => return,
            Ok(_) if line.last() != Some(&b'\n') && line.len() as u64 >= limit => {
                let _ = tx.send(Piped::TooLong);
                return;
            }
            Ok(_) => {
                if line.last() == Some(&b'\n') {
                    line.pop();
                }
                if tx.send(Piped::Line(line)).is_err() {
                    return;
                }
            }
        }
    }
}

/// Passes the worker's log through to ours, keeping the last lines.
fn forward_stderr(stderr: impl Read, tail: &Mutex<VecDeque<String>>) {
    let mut reader = BufReader::new(stderr);
    let mut line = Vec::new();
    loop {
        line.clear();
        match (&mut reader).take(64 << 10).read_until(b'\n', &mut line) {
            Ok(0) | Err(_) => return,
            Ok(_) => {
                let _ = std::io::stderr().write_all(&line);
                if line.last() != Some(&b'\n') {
                    let _ = std::io::stderr().write_all(b"\n");
                }
                let text = String::from_utf8_lossy(&line).trim_end().to_string();
                if let Ok(mut t) = tail.lock() {
                    if t.len() == STDERR_TAIL_LINES {
                        t.pop_front();
                    }
                    t.push_back(text);
                }
            }
        }
    }
}

fn signal_name(sig: libc::c_int) -> &'static str {
    match sig {
        libc::SIGABRT => "SIGABRT",
        libc::SIGSEGV => "SIGSEGV",
        libc::SIGBUS => "SIGBUS",
        libc::SIGILL => "SIGILL",
        libc::SIGFPE => "SIGFPE",
        libc::SIGKILL => "SIGKILL",
        libc::SIGTERM => "SIGTERM",
        libc::SIGXCPU => "SIGXCPU",
        libc::SIGXFSZ => "SIGXFSZ",
        libc::SIGPIPE => "SIGPIPE",
        _ => "signal",
    }
}

/// Bytes as "1.9 GB" / "312 MB".
fn size(bytes: u64) -> String {
    if bytes >= 1 << 30 {
        format!("{:.1} GB", bytes as f64 / (1u64 << 30) as f64)
    } else {
        format!("{} MB", bytes >> 20)
    }
}

fn interpret(ended: Ended, limits: &WorkerLimits) -> WorkerOutcome {
    let cpu_secs = cpu_seconds(&ended.rusage);
    let after = after_text(&ended, cpu_secs);
    let last_words = last_words(&ended.stderr_tail);
    match ended.killed {
        Some(KillReason::Abandoned) => return WorkerOutcome::Abandoned,
        Some(KillReason::Deadline) => {
            return WorkerOutcome::Failed(ProcessFailure::worker(
                FailureKind::Timeout,
                format!(
                    "ran longer than job_timeout_secs = {}: worker killed {after}",
                    limits.wall.as_secs_f64()
                ),
            ));
        }
        Some(KillReason::Protocol) | None => {}
    }
    if let Some(e) = ended.protocol_error {
        return WorkerOutcome::Failed(ProcessFailure::worker(
            FailureKind::WorkerProtocol,
            format!("worker broke the protocol ({e}); killed {after}"),
        ));
    }
    if let Some(status) = ended.status
        && libc::WIFSIGNALED(status)
    {
        let sig = libc::WTERMSIG(status);
        let (kind, why) = signal_cause(sig, &ended.stderr_tail, cpu_secs, limits);
        return WorkerOutcome::Failed(ProcessFailure::worker(
            kind,
            format!(
                "worker killed by signal {sig} ({}){why} {after}{last_words}",
                signal_name(sig)
            ),
        ));
    }
    exit_outcome(ended, &after, &last_words)
}

/// User plus system CPU time, in seconds.
fn cpu_seconds(rusage: &libc::rusage) -> f64 {
    let cpu = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    cpu(rusage.ru_utime) + cpu(rusage.ru_stime)
}

/// "after 2.1 s (CPU 1.9 s), peak 312 MB".
fn after_text(ended: &Ended, cpu_secs: f64) -> String {
    let peak = (ended.rusage.ru_maxrss.max(0) as u64) << 10;
    format!(
        "after {:.1} s (CPU {cpu_secs:.1} s), peak {}",
        ended.wall.as_secs_f64(),
        size(peak)
    )
}

/// The worker's last meaningful stderr line, as a clause to append ("" when none).
fn last_words(stderr_tail: &[String]) -> String {
    // The runtime's own noise after a panic or abort says nothing about the cause.
    let noise = |l: &str| {
        let l = l.trim();
        l.is_empty()
            || l.starts_with("stack backtrace")
            || l.starts_with("skipping backtrace")
            || l.starts_with("note: ")
    };
    stderr_tail
        .iter()
        .rev()
        .find(|l| !noise(l))
        .map(|l| format!("; its last words: \"{}\"", crate::text::bounded(l, 300)))
        .unwrap_or_default()
}

/// Why a worker died of signal `sig`: the failure kind and a clause explaining it.
fn signal_cause(
    sig: libc::c_int,
    stderr_tail: &[String],
    cpu_secs: f64,
    limits: &WorkerLimits,
) -> (FailureKind, String) {
    let out_of_memory = stderr_tail
        .iter()
        .any(|l| l.contains("memory allocation of"));
    if out_of_memory {
        (
            FailureKind::OutOfMemory,
            format!(
                " (out of memory: job_memory_mb = {})",
                limits.memory_bytes >> 20
            ),
        )
    } else if sig == libc::SIGXCPU || (sig == libc::SIGKILL && cpu_secs >= limits.cpu_secs as f64) {
        (
            FailureKind::CpuLimit,
            format!(" (CPU time limit: job_cpu_secs = {})", limits.cpu_secs),
        )
    } else if sig == libc::SIGKILL {
        (
            FailureKind::WorkerKilled,
            " (not by scanmill: the kernel's out-of-memory killer or an operator)".into(),
        )
    } else {
        (FailureKind::WorkerCrashed, String::new())
    }
}

/// The outcome of a worker that exited by itself: its final event, if it sent one.
fn exit_outcome(ended: Ended, after: &str, last_words: &str) -> WorkerOutcome {
    let code = ended.status.map_or(0, |s| libc::WEXITSTATUS(s));
    match ended.final_event {
        Some(Event::Done { report, busy_ms }) if code == 0 => WorkerOutcome::Done {
            report,
            isolation_ms: ended.wall.as_secs_f64() * 1e3 - busy_ms,
        },
        Some(Event::Failed {
            kind,
            message,
            transient,
        }) => WorkerOutcome::Failed(ProcessFailure {
            kind,
            message,
            transient,
        }),
        _ => WorkerOutcome::Failed(ProcessFailure::worker(
            FailureKind::WorkerCrashed,
            format!("worker exited with status {code} without a result {after}{last_words}"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ended(status: libc::c_int, tail: &[&str]) -> Ended {
        Ended {
            status: Some(status),
            // SAFETY: all-zero is a valid rusage.
            rusage: unsafe { std::mem::zeroed() },
            wall: Duration::from_millis(2100),
            final_event: None,
            protocol_error: None,
            killed: None,
            stderr_tail: tail.iter().map(|s| s.to_string()).collect(),
        }
    }

    const LIMITS: WorkerLimits = WorkerLimits {
        memory_bytes: 2 << 30,
        cpu_secs: 100,
        wall: Duration::from_secs(60),
    };

    fn failure(outcome: WorkerOutcome) -> ProcessFailure {
        match outcome {
            WorkerOutcome::Failed(f) => f,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn an_abort_after_a_failed_allocation_is_out_of_memory() {
        // Status of a process killed by SIGABRT: the signal number in the low bits.
        let f = failure(interpret(
            ended(
                libc::SIGABRT,
                &["memory allocation of 1073741824 bytes failed"],
            ),
            &LIMITS,
        ));
        assert_eq!(f.kind, FailureKind::OutOfMemory);
        assert!(f.transient);
        assert!(f.message.contains("signal 6 (SIGABRT)"), "{}", f.message);
        assert!(f.message.contains("job_memory_mb = 2048"), "{}", f.message);
        assert!(f.message.contains("after 2.1 s"), "{}", f.message);
    }

    #[test]
    fn a_segfault_is_a_crash_and_an_exit_without_result_too() {
        let f = failure(interpret(ended(libc::SIGSEGV, &[]), &LIMITS));
        assert_eq!(f.kind, FailureKind::WorkerCrashed);
        assert!(f.message.contains("signal 11 (SIGSEGV)"), "{}", f.message);
        let f = failure(interpret(ended(101 << 8, &["boom\x1b[31m"]), &LIMITS));
        assert_eq!(f.kind, FailureKind::WorkerCrashed);
        assert!(f.message.contains("status 101"), "{}", f.message);
        assert!(!f.message.contains('\x1b'), "escaped: {}", f.message);
    }

    #[test]
    fn a_deadline_kill_is_a_timeout_and_an_abandon_is_not_a_failure() {
        let mut e = ended(libc::SIGKILL, &[]);
        e.killed = Some(KillReason::Deadline);
        assert_eq!(failure(interpret(e, &LIMITS)).kind, FailureKind::Timeout);
        let mut e = ended(libc::SIGKILL, &[]);
        e.killed = Some(KillReason::Abandoned);
        assert!(matches!(interpret(e, &LIMITS), WorkerOutcome::Abandoned));
    }

    #[test]
    fn the_workers_own_failure_is_passed_on_unchanged() {
        let mut e = ended(0, &[]);
        e.final_event = Some(Event::Failed {
            kind: FailureKind::Input,
            message: "line 3: bad".into(),
            transient: false,
        });
        let f = failure(interpret(e, &LIMITS));
        assert_eq!(
            f,
            ProcessFailure {
                kind: FailureKind::Input,
                message: "line 3: bad".into(),
                transient: false
            }
        );
    }
}
