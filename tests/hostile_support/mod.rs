//! Shared helpers for the hostile-input tests: the real binary run under a kill timer with its
//! peak memory measured, scan folders, small images.
//!
//! Peak memory: `wait4` gives the child's peak resident set. Linux counts in it the memory
//! of the process that spawned it as it was at the spawn (the child starts as a copy of the
//! test process, or shares it until `exec`), so a bound on it only says something when the
//! test process itself stayed small: [`assert_peak_below`] checks that first, and the tests
//! that measure memory live in a test binary of their own that allocates little.

#![allow(dead_code)]

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

pub const RECIPE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/config/recipes/normals-only.toml"
);

/// A child that does not finish in this long is killed and the test fails. It only guards
/// against hangs (a FIFO waited on); nothing asserts how long a run takes.
pub const HANG_GUARD: Duration = Duration::from_secs(120);

pub struct Run {
    pub code: Option<i32>,
    pub stdout: String,
    pub stderr: String,
    /// Peak resident set of the child, in bytes.
    pub peak_rss: u64,
}

/// Runs `scanmill ARGS`, killing it if it is still running after [`HANG_GUARD`].
pub fn run(args: &[&str]) -> Run {
    let mut child = Command::new(env!("CARGO_BIN_EXE_scanmill"))
        .args(args)
        .env("SCANMILL_LOG", "error")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let pid = child.id() as libc::pid_t;
    let done = Arc::new(AtomicBool::new(false));
    let killed = Arc::new(AtomicBool::new(false));
    let guard = {
        let (done, killed) = (done.clone(), killed.clone());
        std::thread::spawn(move || {
            let step = Duration::from_millis(50);
            let mut waited = Duration::ZERO;
            while !done.load(Ordering::SeqCst) {
                if waited >= HANG_GUARD {
                    killed.store(true, Ordering::SeqCst);
                    // SAFETY: the child is not reaped before `done` is set, so the pid is ours.
                    unsafe { libc::kill(pid, libc::SIGKILL) };
                    return;
                }
                std::thread::sleep(step);
                waited += step;
            }
        })
    };
    let mut stdout = String::new();
    let mut stderr = String::new();
    let mut out_pipe = child.stdout.take().unwrap();
    let err_reader = {
        let mut err_pipe = child.stderr.take().unwrap();
        std::thread::spawn(move || {
            let mut s = String::new();
            err_pipe.read_to_string(&mut s).ok();
            s
        })
    };
    out_pipe.read_to_string(&mut stdout).ok();
    stderr.push_str(&err_reader.join().unwrap());
    let mut status = 0;
    // SAFETY: plain FFI call with valid pointers; `rusage` is plain data.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let reaped = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    done.store(true, Ordering::SeqCst);
    guard.join().unwrap();
    assert_eq!(reaped, pid, "wait4 failed");
    assert!(
        !killed.load(Ordering::SeqCst),
        "scanmill {args:?} was still running after {HANG_GUARD:?} and was killed; stderr: {stderr}"
    );
    // Already reaped: keep `Child` from trying again.
    std::mem::forget(child);
    Run {
        code: libc::WIFEXITED(status).then(|| libc::WEXITSTATUS(status)),
        stdout,
        stderr,
        peak_rss: usage.ru_maxrss as u64 * 1024,
    }
}

pub fn process(input: &Path, out: &Path) -> Run {
    run(&[
        "process",
        input.to_str().unwrap(),
        "--recipe",
        RECIPE,
        "--out",
        out.to_str().unwrap(),
    ])
}

pub fn inspect(input: &Path) -> Run {
    run(&["inspect", input.to_str().unwrap()])
}

/// Every file below `dir`, relative names.
pub fn tree(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(rd) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in rd {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p.clone());
            }
            out.push(p.strip_prefix(dir).unwrap().display().to_string());
        }
    }
    out.sort();
    out
}

/// Asserts a failed run: exit 65, one line of error containing every needle, nothing in out.
pub fn assert_refused(r: &Run, out: &Path, needles: &[&str]) {
    assert_eq!(r.code, Some(65), "stderr: {}", r.stderr);
    assert_eq!(r.stderr.trim_end().lines().count(), 1, "{}", r.stderr);
    for n in needles {
        assert!(r.stderr.contains(n), "{n:?} not in {}", r.stderr);
    }
    assert_eq!(tree(out), Vec::<String>::new(), "{}", r.stderr);
}

pub const TRI: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n";

pub fn png(w: u32, h: u32, rgb: [u8; 3]) -> Vec<u8> {
    let img = image::RgbImage::from_pixel(w, h, image::Rgb(rgb));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// A scan folder `<tmp>/a/b/scan` (deep enough for `../../../etc/passwd` to reach /etc)
/// holding `files`; returns the temp dir, the scan folder and an `out` folder beside it.
pub fn scan_dir(files: &[(&str, &[u8])]) -> (tempfile::TempDir, PathBuf, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("a/b/scan");
    std::fs::create_dir_all(&dir).unwrap();
    for (name, content) in files {
        std::fs::write(dir.join(name), content).unwrap();
    }
    let out = tmp.path().join("out");
    (tmp, dir, out)
}

pub fn obj_with_mtl(mtl: &str) -> Vec<(&'static str, Vec<u8>)> {
    vec![
        (
            "scan.obj",
            format!("mtllib scan.mtl\n{TRI}usemtl m\nf 1/1 2/2 3/3\n").into_bytes(),
        ),
        ("scan.mtl", mtl.as_bytes().to_vec()),
    ]
}

pub fn write_all(dir: &Path, files: &[(&str, Vec<u8>)]) {
    for (name, content) in files {
        std::fs::write(dir.join(name), content).unwrap();
    }
}

pub fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
}

/// The peak RSS of this (the test) process so far, in bytes.
pub fn own_peak_rss() -> u64 {
    // SAFETY: plain FFI call with a valid pointer; `rusage` is plain data.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    assert_eq!(unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) }, 0);
    usage.ru_maxrss as u64 * 1024
}

/// Asserts that the child of `r` peaked below `bound` bytes, after checking that the test
/// process itself stayed well below it (else the child's figure would be ours: see the
/// module comment).
pub fn assert_peak_below(r: &Run, bound: u64) {
    let own = own_peak_rss();
    assert!(
        own < bound / 2,
        "the test process peaked at {} MB: too close to the {} MB bound to measure the child",
        own >> 20,
        bound >> 20
    );
    assert!(
        r.peak_rss < bound,
        "peak RSS {} MB, bound {} MB",
        r.peak_rss >> 20,
        bound >> 20
    );
}
