//! The parent's side of a worker process: start it, hand it one input at a time, and turn
//! its answer, its death or its silence into an [`Outcome`].

use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::oracle::{OVER_MEMORY_EXIT, Violation};

/// What running one input showed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    Accepted,
    /// A clear one-line error (the message).
    Refused(String),
    Finding(Finding),
}

/// A kind of finding: anything the service must never do with an input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum FindingKind {
    Panic,
    /// Killed by a signal (abort, segfault, stack overflow) or an unexpected exit.
    Crash,
    /// Over the worker's memory limit.
    OverMemory,
    /// No answer within the per-input wall limit.
    Hang,
    Violation(ViolationKind),
}

/// [`Violation`] with an order, for the summary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ViolationKind {
    MessyError,
    Escape,
    Unusable,
}

impl From<Violation> for ViolationKind {
    fn from(v: Violation) -> Self {
        match v {
            Violation::MessyError => ViolationKind::MessyError,
            Violation::Escape => ViolationKind::Escape,
            Violation::Unusable => ViolationKind::Unusable,
        }
    }
}

impl FindingKind {
    pub fn name(self) -> &'static str {
        match self {
            FindingKind::Panic => "panic",
            FindingKind::Crash => "crash",
            FindingKind::OverMemory => "over-memory",
            FindingKind::Hang => "hang",
            FindingKind::Violation(ViolationKind::MessyError) => "messy-error",
            FindingKind::Violation(ViolationKind::Escape) => "escape",
            FindingKind::Violation(ViolationKind::Unusable) => "unusable-config",
        }
    }
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Finding {
    pub kind: FindingKind,
    /// One line: the panic message, the signal and the end of stderr, ...
    pub detail: String,
}

/// One input's result.
#[derive(Debug, Clone)]
pub struct Run {
    pub outcome: Outcome,
    /// Peak live heap bytes while the input ran (0 when the worker died).
    pub peak_bytes: u64,
    pub elapsed: Duration,
}

/// A worker process serving one target.
pub struct Worker {
    child: Child,
    stdin: Option<ChildStdin>,
    replies: Receiver<String>,
    stderr_tail: Arc<Mutex<Vec<u8>>>,
    stderr_thread: Option<JoinHandle<()>>,
}

/// How much of a dead worker's stderr is kept for the finding's detail.
const STDERR_TAIL: usize = 2048;

impl Worker {
    /// Starts `command` (which must run `oracle::worker_main` with the worker's environment)
    /// with piped stdio.
    pub fn spawn(mut command: Command) -> std::io::Result<Worker> {
        let mut child = command
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()?;
        let stdin = child.stdin.take();
        let stdout = child.stdout.take().expect("piped stdout");
        let mut stderr = child.stderr.take().expect("piped stderr");
        let (send, replies) = channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                // Anywhere in the line: the test harness starts a line ("test x ... ") that
                // its test, the worker, ends.
                if let Some(at) = line.find("@@fuzz\t")
                    && send
                        .send(line[at + "@@fuzz\t".len()..].to_string())
                        .is_err()
                {
                    break;
                }
            }
        });
        let stderr_tail = Arc::new(Mutex::new(Vec::new()));
        let tail = Arc::clone(&stderr_tail);
        let stderr_thread = std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = stderr.read(&mut buf) {
                if n == 0 {
                    break;
                }
                let mut tail = tail.lock().expect("stderr tail");
                tail.extend_from_slice(&buf[..n]);
                let excess = tail.len().saturating_sub(STDERR_TAIL);
                tail.drain(..excess);
            }
        });
        Ok(Worker {
            child,
            stdin,
            replies,
            stderr_tail,
            stderr_thread: Some(stderr_thread),
        })
    }

    /// Runs one input. After a finding that ended the worker (crash, over-memory, hang) the
    /// worker is dead: [`Worker::is_alive`] is false and the caller starts a new one.
    pub fn run(&mut self, input: &[u8], timeout: Duration) -> Run {
        let start = Instant::now();
        let sent = self.stdin.as_mut().is_some_and(|stdin| {
            stdin
                .write_all(&(input.len() as u32).to_le_bytes())
                .and_then(|()| stdin.write_all(input))
                .and_then(|()| stdin.flush())
                .is_ok()
        });
        let reply = if sent {
            self.replies.recv_timeout(timeout)
        } else {
            Err(RecvTimeoutError::Disconnected)
        };
        let elapsed = start.elapsed();
        match reply {
            Ok(line) => Run {
                peak_bytes: line
                    .split('\t')
                    .nth(1)
                    .and_then(|p| p.parse().ok())
                    .unwrap_or(0),
                outcome: parse_reply(&line),
                elapsed,
            },
            Err(RecvTimeoutError::Timeout) => {
                let _ = self.child.kill();
                self.reap();
                Run {
                    outcome: Outcome::Finding(Finding {
                        kind: FindingKind::Hang,
                        detail: format!("no answer within {:.1} s; killed", timeout.as_secs_f64()),
                    }),
                    peak_bytes: 0,
                    elapsed,
                }
            }
            Err(RecvTimeoutError::Disconnected) => Run {
                outcome: Outcome::Finding(self.death()),
                peak_bytes: 0,
                elapsed,
            },
        }
    }

    pub fn is_alive(&self) -> bool {
        self.stdin.is_some()
    }

    /// Waits for the worker to end and drains its stderr.
    fn reap(&mut self) -> Option<std::process::ExitStatus> {
        self.stdin = None;
        let status = self.child.wait().ok();
        if let Some(t) = self.stderr_thread.take() {
            let _ = t.join();
        }
        status
    }

    /// The finding a worker that stopped answering stands for.
    fn death(&mut self) -> Finding {
        let status = self.reap();
        let tail = self
            .stderr_tail
            .lock()
            .map(|t| t.clone())
            .unwrap_or_default();
        let tail = String::from_utf8_lossy(&tail);
        let tail = super::oracle::one_line(tail.trim(), 400);
        use std::os::unix::process::ExitStatusExt;
        let (kind, what) = match status {
            Some(s) if s.code() == Some(OVER_MEMORY_EXIT) => {
                (FindingKind::OverMemory, "over the memory limit".to_string())
            }
            Some(s) => match s.signal() {
                Some(sig) => (
                    FindingKind::Crash,
                    format!("killed by signal {sig} ({})", signal_name(sig)),
                ),
                None => (FindingKind::Crash, format!("exited with {s}")),
            },
            None => (FindingKind::Crash, "vanished".to_string()),
        };
        Finding {
            kind,
            detail: format!("worker {what}; stderr: {tail}"),
        }
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        // Closing stdin ends a healthy worker; one that does not end is killed.
        self.stdin = None;
        if !matches!(self.child.try_wait(), Ok(Some(_))) {
            let deadline = Instant::now() + Duration::from_secs(2);
            while Instant::now() < deadline {
                if matches!(self.child.try_wait(), Ok(Some(_))) {
                    return;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

fn signal_name(sig: i32) -> &'static str {
    match sig {
        libc::SIGABRT => "abort",
        libc::SIGSEGV => "segmentation fault",
        libc::SIGBUS => "bus error",
        libc::SIGILL => "illegal instruction",
        libc::SIGFPE => "arithmetic fault",
        libc::SIGKILL => "killed",
        _ => "other",
    }
}

/// `verdict <TAB> peak <TAB> message` as the worker wrote it.
fn parse_reply(line: &str) -> Outcome {
    let mut fields = line.splitn(3, '\t');
    let tag = fields.next().unwrap_or("");
    let _peak = fields.next();
    let message = fields.next().unwrap_or("").to_string();
    match tag {
        "accepted" => Outcome::Accepted,
        "refused" => Outcome::Refused(message),
        "panic" => Outcome::Finding(Finding {
            kind: FindingKind::Panic,
            detail: message,
        }),
        other => match Violation::parse(other) {
            Some(v) => Outcome::Finding(Finding {
                kind: FindingKind::Violation(v.into()),
                detail: message,
            }),
            None => Outcome::Finding(Finding {
                kind: FindingKind::Crash,
                detail: format!("unreadable answer from the worker: {line}"),
            }),
        },
    }
}
