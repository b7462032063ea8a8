//! Shared helpers for the daemon integration tests: a temporary lab (inbox, outbox, state,
//! a normals-only recipe), the real binary started on it, and polling with generous
//! deadlines (never fixed sleeps, never assertions on durations).

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

// Every test crate that has `mod daemon_support;` has `mod common;` too.
pub use crate::common::DATA;
pub const BIN: &str = env!("CARGO_BIN_EXE_scanmill");

pub fn james_dir() -> PathBuf {
    Path::new(DATA).join("textured/james_face_stereo_capture")
}

pub fn bunny() -> Vec<u8> {
    std::fs::read(Path::new(DATA).join("untextured/stanford_bunny/bun_zipper_res4.ply")).unwrap()
}

/// The bunny with one more header comment, so that every copy has its own content hash.
/// `scanmill daemon --config CONFIG` logging at info to `log`, outside systemd, with `envs`
/// set.
pub fn daemon_command(config: &Path, log: std::fs::File, envs: &[(&str, &str)]) -> Command {
    let mut cmd = Command::new(BIN);
    cmd.args(["daemon", "--config"])
        .arg(config)
        .env("SCANMILL_LOG", "info")
        .env_remove("NOTIFY_SOCKET")
        .env_remove("JOURNAL_STREAM")
        .env_remove("SCANMILL_TEST_STEP_DELAY_MS")
        .stdout(Stdio::null())
        .stderr(log);
    for (k, v) in envs {
        cmd.env(k, v);
    }
    cmd
}

pub fn bunny_variant(tag: &str) -> Vec<u8> {
    let b = bunny();
    let at = b.windows(11).position(|w| w == b"comment zip").unwrap();
    let mut out = b[..at].to_vec();
    out.extend_from_slice(format!("comment {tag}\n").as_bytes());
    out.extend_from_slice(&b[at..]);
    out
}

pub struct Lab {
    pub dir: tempfile::TempDir,
    pub config: PathBuf,
}

impl Lab {
    /// `extra` is appended to the top-level keys of the config.
    pub fn new(quiet_secs: f64, extra: &str) -> Lab {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        for sub in ["in", "out", "state"] {
            std::fs::create_dir(d.join(sub)).unwrap();
        }
        std::fs::write(
            d.join("recipe.toml"),
            "[output]\nformat = \"obj\"\n\n[[step]]\nkind = \"normals\"\n",
        )
        .unwrap();
        let config = d.join("scanmill.toml");
        std::fs::write(
            &config,
            format!(
                "state_dir = {:?}\nrescan_secs = 30\nmin_free_disk_mb = 1\nretry_base_secs = 0.5\n{extra}\n\
                 [[watch]]\npath = {:?}\noutput = {:?}\nrecipe = {:?}\nquiet_period_secs = {quiet_secs}\n",
                d.join("state"),
                d.join("in"),
                d.join("out"),
                d.join("recipe.toml"),
            ),
        )
        .unwrap();
        Lab { dir, config }
    }

    pub fn inbox(&self) -> PathBuf {
        self.dir.path().join("in")
    }
    pub fn outbox(&self) -> PathBuf {
        self.dir.path().join("out")
    }

    /// Starts the daemon; its log goes to `log-N.txt` in the lab.
    pub fn start(&self, envs: &[(&str, &str)]) -> Child {
        let n = std::fs::read_dir(self.dir.path())
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .file_name()
                    .to_string_lossy()
                    .starts_with("log-")
            })
            .count();
        let log = std::fs::File::create(self.dir.path().join(format!("log-{n}.txt"))).unwrap();
        let child = daemon_command(&self.config, log, envs).spawn().unwrap();
        // Ready once the database exists and the first walk is done ("ready" logged).
        let path = self.dir.path().join(format!("log-{n}.txt"));
        assert!(
            wait_for(30, || std::fs::read_to_string(&path)
                .unwrap_or_default()
                .contains(" ready ")),
            "daemon did not become ready:\n{}",
            self.logs()
        );
        child
    }

    pub fn logs(&self) -> String {
        let mut all = String::new();
        let mut names: Vec<_> = std::fs::read_dir(self.dir.path())
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.file_name().unwrap().to_string_lossy().starts_with("log-"))
            .collect();
        names.sort();
        for p in names {
            all.push_str(&format!(
                "--- {}\n{}",
                p.display(),
                std::fs::read_to_string(&p).unwrap_or_default()
            ));
        }
        all
    }

    /// Runs a CLI subcommand with this lab's config; returns (exit code, stdout, stderr).
    pub fn cli(&self, args: &[&str]) -> (i32, String, String) {
        let out = Command::new(BIN)
            .args(args)
            .arg("--config")
            .arg(&self.config)
            .output()
            .unwrap();
        (
            out.status.code().unwrap_or(-1),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    }

    /// `history --json` as parsed rows.
    pub fn jobs(&self) -> Vec<serde_json::Value> {
        self.jobs_with(&[])
    }

    pub fn jobs_with(&self, extra: &[&str]) -> Vec<serde_json::Value> {
        let mut args = vec!["history", "--json"];
        args.extend_from_slice(extra);
        let (code, out, err) = self.cli(&args);
        if code != 0 {
            return Vec::new(); // database not there yet
        }
        serde_json::from_str::<Vec<serde_json::Value>>(&out)
            .unwrap_or_else(|e| panic!("{e}: {out} {err}"))
    }

    pub fn count_state(&self, state: &str) -> usize {
        self.jobs().iter().filter(|j| j["state"] == state).count()
    }

    pub fn show(&self, id: i64) -> serde_json::Value {
        let (code, out, err) = self.cli(&["show", &id.to_string()]);
        assert_eq!(code, 0, "{err}");
        serde_json::from_str(&out).unwrap()
    }

    /// Visible (non-hidden) entries of the output tree, relative, sorted.
    /// PIDs of `scanmill worker` processes working for this lab (their staging folder is
    /// under this lab's outbox).
    pub fn worker_pids(&self) -> Vec<u32> {
        let needle = self.outbox().to_string_lossy().into_owned();
        let mut pids = Vec::new();
        for entry in std::fs::read_dir("/proc").unwrap().flatten() {
            let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
                continue;
            };
            let Ok(cmdline) = std::fs::read(entry.path().join("cmdline")) else {
                continue;
            };
            let args: Vec<String> = cmdline
                .split(|&b| b == 0)
                .map(|a| String::from_utf8_lossy(a).into_owned())
                .collect();
            if args.iter().any(|a| a == "worker") && args.iter().any(|a| a.contains(&needle)) {
                pids.push(pid);
            }
        }
        pids
    }

    pub fn visible_outputs(&self) -> Vec<String> {
        let mut out = Vec::new();
        let mut stack = vec![self.outbox()];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).unwrap().flatten() {
                let name = e.file_name().to_string_lossy().into_owned();
                if name.starts_with('.') {
                    continue;
                }
                let p = e.path();
                out.push(
                    p.strip_prefix(self.outbox())
                        .unwrap()
                        .to_string_lossy()
                        .into_owned(),
                );
                if p.is_dir() {
                    stack.push(p);
                }
            }
        }
        out.sort();
        out
    }
}

/// Polls `cond` every 50 ms until it holds or `secs` pass.
pub fn wait_for(secs: u64, mut cond: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + Duration::from_secs(secs);
    while Instant::now() < deadline {
        if cond() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    cond()
}

pub fn signal(child: &Child, sig: i32) {
    // SAFETY: sending a signal to our own child process.
    unsafe {
        libc::kill(child.id() as i32, sig);
    }
}

/// Waits for the child to exit; returns its exit code.
pub fn wait_exit(child: &mut Child, secs: u64) -> Option<i32> {
    let mut status = None;
    wait_for(secs, || {
        status = child.try_wait().unwrap();
        status.is_some()
    });
    status.map(|s| s.code().unwrap_or(-1))
}

/// Writes `bytes` in `pieces` chunks with `pause` between them (a slow writer).
pub fn write_slowly(path: &Path, bytes: &[u8], pieces: usize, pause: Duration) {
    use std::io::Write;
    let mut f = std::fs::File::create(path).unwrap();
    let step = bytes.len().div_ceil(pieces);
    for chunk in bytes.chunks(step) {
        f.write_all(chunk).unwrap();
        f.flush().unwrap();
        std::thread::sleep(pause);
    }
}

pub fn copy_james(to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for f in ["james.obj", "james.obj.mtl", "james.jpg"] {
        std::fs::write(to.join(f), std::fs::read(james_dir().join(f)).unwrap()).unwrap();
    }
}

/// Kills a child if the test fails midway, so that no daemon outlives its test.
pub struct KillOnDrop(pub Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}
