//! The whole face-scan run (issue #8): `scanmill process` with config/recipes/face-scan.toml
//! on a 400,000-triangle textured face scan, load to written output, timed as a user sees
//! it (the release binary in a child process) and with its peak resident memory.
//!
//! The scan is made from ../shared/data/textured/facefuns_di3d_face: subdivided with the
//! seam-keeping `ops::subdivide`, the 400,000 triangles nearest its centre kept (one patch),
//! and scanner-like noise added along the normals (σ = 0.1 × mean edge length, seed 1),
//! written as OBJ + MTL + PNG into a temporary folder.
//!
//! cargo bench --bench face_scan
//! Targets: at most 3 s wall on the lab's 2-core machine, at most 400 bytes per input
//! triangle. Prints medians of wall and CPU time and the peak RSS; criterion's own figures
//! follow.

mod common;
#[path = "common/reference.rs"]
mod reference;

use common::{FACE, FACES, face400k};
use criterion::{Criterion, criterion_group};
use scanmill::mesh::{SaveOptions, save};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

const RECIPE: &str = "config/recipes/face-scan.toml";

fn make_scan(dir: &Path) -> Option<PathBuf> {
    let mesh = face400k()?;
    let path = dir.join("face400k.obj");
    save(&mesh, &path, &SaveOptions::default()).ok()?;
    Some(path)
}

/// Children's user + system CPU seconds and their largest peak RSS in bytes so far.
fn children_usage() -> (f64, u64) {
    // SAFETY: getrusage only writes into the struct we pass.
    let usage = unsafe {
        let mut usage: libc::rusage = std::mem::zeroed();
        libc::getrusage(libc::RUSAGE_CHILDREN, &mut usage);
        usage
    };
    let seconds = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    (
        seconds(usage.ru_utime) + seconds(usage.ru_stime),
        usage.ru_maxrss as u64 * 1024,
    )
}

/// Jiffies the hypervisor took from this machine so far (the `steal` column of /proc/stat),
/// and all jiffies; 0 where the kernel does not say.
fn steal_jiffies() -> (u64, u64) {
    let stat = std::fs::read_to_string("/proc/stat").unwrap_or_default();
    let Some(cpu) = stat.lines().next().filter(|line| line.starts_with("cpu ")) else {
        return (0, 0);
    };
    let fields: Vec<u64> = cpu
        .split_whitespace()
        .skip(1)
        .filter_map(|field| field.parse().ok())
        .collect();
    (
        fields.get(7).copied().unwrap_or(0),
        fields.iter().take(8).sum(),
    )
}

/// One run into an emptied output folder (as the daemon's fresh job folders are).
fn run(input: &Path, out: &Path) {
    let _ = std::fs::remove_dir_all(out);
    let output = Command::new(env!("CARGO_BIN_EXE_scanmill"))
        .arg("process")
        .arg(input)
        .args(["--recipe", RECIPE, "--out"])
        .arg(out)
        .output()
        .expect("cannot start scanmill");
    assert!(
        output.status.success(),
        "scanmill process failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
}

fn bench(c: &mut Criterion) {
    let dir = std::env::temp_dir().join(format!("scanmill-face-scan-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temporary folder");
    let Some(input) = make_scan(&dir) else {
        panic!(
            "face_scan bench: {FACE} not found (the benches read ../shared/data beside the checkout)"
        );
    };
    let out = dir.join("out");

    // Medians of wall and CPU time, and the peak memory, over a few runs of the binary.
    let runs = 5;
    let reference_ms = reference::reference_workload_ms();
    let (steal_before, jiffies_before) = steal_jiffies();
    let mut walls = Vec::new();
    let mut cpus = Vec::new();
    for _ in 0..runs {
        let (cpu_before, _) = children_usage();
        let start = Instant::now();
        run(&input, &out);
        walls.push(start.elapsed().as_secs_f64());
        cpus.push(children_usage().0 - cpu_before);
    }
    walls.sort_by(f64::total_cmp);
    cpus.sort_by(f64::total_cmp);
    let peak = children_usage().1;
    let (steal_after, jiffies_after) = steal_jiffies();
    let steal_percent = 100.0 * (steal_after - steal_before) as f64
        / (jiffies_after - jiffies_before).max(1) as f64;
    eprintln!(
        "face-scan recipe, {FACES} triangles, load to written output: median wall {:.2} s \
         (min {:.2}, max {:.2}), median CPU {:.2} s, peak RSS {:.0} MB = {:.0} bytes per input \
         triangle (loadavg {}; machine speed: reference sort {:.0} ms, CPU steal {:.1} %)",
        walls[runs / 2],
        walls[0],
        walls[runs - 1],
        cpus[runs / 2],
        peak as f64 / 1e6,
        peak as f64 / FACES as f64,
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim(),
        reference_ms,
        steal_percent,
    );

    let mut group = c.benchmark_group("face-scan recipe");
    group.sample_size(10);
    group.bench_function("400k-triangle textured face, load to written output", |b| {
        b.iter(|| run(&input, &out))
    });
    group.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench);
scanmill::criterion_main_on_pool!(benches);
