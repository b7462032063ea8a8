//! A stable, seeded, deterministic mutation fuzzer for scanmill's inputs (issue #22, item 9).
//! See docs/fuzzing.md for how to run a campaign, repeat one, and turn a finding into a
//! regression file.
//!
//! ```text
//! cargo run --profile test --example fuzz -- --target all --seconds 60 --jobs 2 --seed 1
//! ```
//!
//! Each input runs in a worker process (this binary again, `FUZZ_WORKER` set) that serves
//! many inputs; a panic, an abort or signal, no answer within `--timeout-secs`, or more than
//! `--memory-mb` of heap is a finding. Findings are saved under `--out`, minimised a little.

mod mutate;
mod oracle;
mod seeds;
mod worker;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use clap::Parser;
use sha2::{Digest, Sha256};

use mutate::{Entry, Generator};
use oracle::Target;
use worker::{Finding, FindingKind, Outcome, Run, Worker};

#[global_allocator]
static ALLOC: oracle::Counting = oracle::Counting;

#[derive(Parser)]
#[command(about = "Seeded mutation fuzzer for scanmill's parsers and configuration files")]
struct Args {
    /// obj, mtl, ply-ascii, ply-binary, gzip, recipe, config, or all (one after the other).
    #[arg(long, default_value = "all")]
    target: String,
    /// Run each target this long (wall seconds).
    #[arg(long)]
    seconds: Option<f64>,
    /// Run each target's inputs 0..N (default 1000 when --seconds is not given).
    #[arg(long)]
    iterations: Option<u64>,
    /// Campaign seed: with the same corpus, the same seed gives the same inputs.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Worker processes run side by side.
    #[arg(long, default_value_t = 1)]
    jobs: usize,
    /// Folder of corpus files (default: ../shared/data beside the checkout), used with the
    /// hand-made seeds.
    #[arg(long)]
    corpus: Option<PathBuf>,
    /// Leave out the hand-made seeds.
    #[arg(long)]
    no_hand_made: bool,
    /// Where findings are saved (<out>/<target>/<hash>.<ext> with a .txt beside).
    #[arg(long, default_value = "fuzz-findings")]
    out: PathBuf,
    /// Per-input wall limit; a worker silent this long is a hang. The slowest regular inputs
    /// (a 2 MB MTL of 100k map lines, a gzip bomb refused at its limit) take about 3 s on an
    /// idle core; the margin is for a machine shared with compilers.
    #[arg(long, default_value_t = 30.0)]
    timeout_secs: f64,
    /// Per-worker heap limit.
    #[arg(long, default_value_t = 1024)]
    memory_mb: u64,
    /// Write input N of the (single) target to <out>/<target>/input-N.<ext> and stop.
    #[arg(long)]
    dump: Option<u64>,
    /// Run these files through the (single) target's oracle, print each outcome, and stop.
    #[arg(long, num_args = 1..)]
    replay: Vec<PathBuf>,
    /// Do not minimise findings.
    #[arg(long)]
    no_minimise: bool,
}

fn main() -> ExitCode {
    if let Some(env) = oracle::worker_env() {
        std::process::exit(oracle::worker_main(env));
    }
    let args = Args::parse();
    let targets: Vec<Target> = match args.target.as_str() {
        "all" => Target::ALL.to_vec(),
        name => match Target::parse(name) {
            Some(t) => vec![t],
            None => {
                eprintln!("fuzz: unknown target {name:?}");
                return ExitCode::from(2);
            }
        },
    };
    if args.jobs == 0 {
        eprintln!("fuzz: --jobs must be at least 1");
        return ExitCode::from(2);
    }
    if !args.replay.is_empty() || args.dump.is_some() {
        let [target] = targets[..] else {
            eprintln!("fuzz: --replay and --dump need one --target");
            return ExitCode::from(2);
        };
        return if let Some(n) = args.dump {
            dump(&args, target, n)
        } else {
            replay(&args, target)
        };
    }
    let mut findings = 0;
    let mut total_cpu = 0.0;
    for target in targets {
        let summary = campaign(&args, target);
        findings += summary.findings;
        total_cpu += summary.cpu_seconds;
    }
    println!("fuzz: {total_cpu:.1} CPU-seconds in all, {findings} distinct findings");
    if findings == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

fn load_corpus(args: &Args, target: Target) -> Vec<Entry> {
    let dir = args.corpus.clone().unwrap_or_else(seeds::data_dir);
    let mut corpus: Vec<Entry> = seeds::data_files(target, &dir)
        .into_iter()
        .filter_map(|p| {
            let bytes = std::fs::read(&p).ok()?;
            Some(Entry::new(target, seeds::adapt(target, bytes)))
        })
        .collect();
    if !args.no_hand_made {
        for s in seeds::hand_made(target) {
            corpus.push(Entry::new(target, s.bytes));
        }
    }
    corpus
}

fn worker_command(args: &Args, target: Target, scratch: &Path) -> Command {
    // The running binary itself, even if a build replaced the file since it started.
    let mut cmd = Command::new("/proc/self/exe");
    cmd.env(oracle::ENV_TARGET, target.name())
        .env(oracle::ENV_SCRATCH, scratch)
        .env(oracle::ENV_MEMORY, (args.memory_mb << 20).to_string())
        // One core per worker: --jobs says how many are used.
        .env("RAYON_NUM_THREADS", "1");
    cmd
}

/// What a target's campaign found.
struct Summary {
    findings: usize,
    cpu_seconds: f64,
}

/// Counters shared by a target's jobs.
#[derive(Default)]
struct Stats {
    done: u64,
    accepted: u64,
    refused: u64,
    /// Highest iteration completed + 1 (all below it are done when the jobs stop).
    completed_below: u64,
    peak: (u64, u64),
    slowest: (Duration, u64),
    /// Distinct findings by signature: (kind, first iteration, detail, saved file, count).
    findings: BTreeMap<String, (FindingKind, u64, String, PathBuf, u64)>,
}

fn campaign(args: &Args, target: Target) -> Summary {
    let corpus = load_corpus(args, target);
    if corpus.is_empty() {
        eprintln!("fuzz: {}: empty corpus; skipped", target.name());
        return Summary {
            findings: 0,
            cpu_seconds: 0.0,
        };
    }
    let corpus_len = corpus.len();
    let generator = Arc::new(Generator::new(target, args.seed, corpus));
    let limit = match (args.iterations, args.seconds) {
        (Some(n), _) => n,
        (None, Some(_)) => u64::MAX,
        (None, None) => 1000,
    };
    let deadline = args
        .seconds
        .map(|s| Instant::now() + Duration::from_secs_f64(s));
    let next = Arc::new(AtomicU64::new(0));
    let stats = Arc::new(Mutex::new(Stats::default()));
    let timeout = Duration::from_secs_f64(args.timeout_secs);
    let scratch = tempfile::tempdir().expect("a scratch folder");
    let cpu_before = cpu_seconds();
    let started = Instant::now();
    println!(
        "fuzz: {}: seed {}, {} corpus entries, {} job(s), {}",
        target.name(),
        args.seed,
        corpus_len,
        args.jobs,
        match (args.iterations, args.seconds) {
            (Some(n), _) => format!("inputs 0..{n}"),
            (None, Some(s)) => format!("{s} s"),
            (None, None) => format!("inputs 0..{limit}"),
        }
    );
    std::thread::scope(|scope| {
        for job in 0..args.jobs {
            let (generator, next, stats) = (&generator, &next, &stats);
            let dir = scratch.path().join(format!("job{job}"));
            scope.spawn(move || {
                let spawn =
                    || Worker::spawn(worker_command(args, target, &dir)).expect("start a worker");
                let mut worker = spawn();
                loop {
                    if deadline.is_some_and(|d| Instant::now() >= d) {
                        break;
                    }
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= limit {
                        break;
                    }
                    let input = generator.input(i);
                    let run = worker.run(&input, timeout);
                    if !worker.is_alive() {
                        worker = spawn();
                    }
                    let finding = match &run.outcome {
                        Outcome::Finding(f) => Some(f.clone()),
                        _ => None,
                    };
                    record(stats, i, &run);
                    if let Some(f) = finding {
                        let (file, new) = save_finding(args, target, stats, i, &input, &f);
                        if new && !args.no_minimise && f.kind != FindingKind::Hang {
                            let small = minimise(&mut worker, &input, &f, timeout, &spawn);
                            if small.len() < input.len() {
                                let _ = std::fs::write(&file, &small);
                            }
                        }
                    }
                }
            });
        }
    });
    let wall = started.elapsed().as_secs_f64();
    let cpu = cpu_seconds() - cpu_before;
    let stats = stats.lock().expect("stats");
    println!(
        "fuzz: {}: {} inputs (all of 0..{}) in {wall:.1} s wall, {cpu:.1} CPU-seconds; \
         {} accepted, {} refused; peak heap {:.1} MB (input {}); slowest {:.2} s (input {})",
        target.name(),
        stats.done,
        stats.completed_below,
        stats.accepted,
        stats.refused,
        stats.peak.0 as f64 / 1e6,
        stats.peak.1,
        stats.slowest.0.as_secs_f64(),
        stats.slowest.1,
    );
    for (kind, first, detail, file, count) in stats.findings.values() {
        println!(
            "fuzz: {}: FINDING {} x{count}, first input {first}: {detail}\n      saved as {}",
            target.name(),
            kind.name(),
            file.display()
        );
    }
    Summary {
        findings: stats.findings.len(),
        cpu_seconds: cpu,
    }
}

fn record(stats: &Mutex<Stats>, i: u64, run: &Run) {
    let mut s = stats.lock().expect("stats");
    s.done += 1;
    s.completed_below = s.completed_below.max(i + 1);
    match run.outcome {
        Outcome::Accepted => s.accepted += 1,
        Outcome::Refused(_) => s.refused += 1,
        Outcome::Finding(_) => {}
    }
    if run.peak_bytes > s.peak.0 {
        s.peak = (run.peak_bytes, i);
    }
    if run.elapsed > s.slowest.0 {
        s.slowest = (run.elapsed, i);
    }
}

/// Findings with the same signature count as one (one input saved, the rest counted): a
/// panic by its location, a crash by its signal, any other kind by the kind alone.
fn signature(f: &Finding) -> String {
    let part = match f.kind {
        FindingKind::Panic => f.detail.rsplit(" at ").next().unwrap_or(""),
        FindingKind::Crash => f.detail.split(';').next().unwrap_or(""),
        _ => "",
    };
    format!("{} {part}", f.kind.name())
}

fn short_hash(bytes: &[u8]) -> String {
    hex::encode(&Sha256::digest(bytes)[..8])
}

/// Saves a finding's input (once per signature) with a note; returns its path and whether
/// the signature is new.
fn save_finding(
    args: &Args,
    target: Target,
    stats: &Mutex<Stats>,
    i: u64,
    input: &[u8],
    f: &Finding,
) -> (PathBuf, bool) {
    let sig = signature(f);
    let dir = args.out.join(target.name());
    let file = dir.join(format!("{}.{}", short_hash(input), target.extension()));
    {
        let mut s = stats.lock().expect("stats");
        if let Some(entry) = s.findings.get_mut(&sig) {
            entry.4 += 1;
            return (entry.3.clone(), false);
        }
        s.findings
            .insert(sig, (f.kind, i, f.detail.clone(), file.clone(), 1));
    }
    let _ = std::fs::create_dir_all(&dir);
    let _ = std::fs::write(&file, input);
    let note = format!(
        "{}: {}\ninput {i} of: cargo run --profile test --example fuzz -- --target {} --seed {} \
         --dump {i}{}\n",
        f.kind.name(),
        f.detail,
        target.name(),
        args.seed,
        args.corpus
            .as_ref()
            .map(|c| format!(" --corpus {}", c.display()))
            .unwrap_or_default(),
    );
    let _ = std::fs::write(
        file.with_extension(format!("{}.txt", target.extension())),
        note,
    );
    println!(
        "fuzz: {}: input {i}: {}: {}",
        target.name(),
        f.kind.name(),
        f.detail
    );
    (file, true)
}

/// Shrinks an input while it still gives a finding with the same signature: removes chunks
/// of halving size (a small delta-debugging pass), within a budget of runs and time.
fn minimise(
    worker: &mut Worker,
    input: &[u8],
    finding: &Finding,
    timeout: Duration,
    spawn: &dyn Fn() -> Worker,
) -> Vec<u8> {
    let wanted = signature(finding);
    let started = Instant::now();
    let mut runs = 0;
    let mut current = input.to_vec();
    let mut chunk = current.len() / 2;
    while chunk > 0 && runs < 400 && started.elapsed() < Duration::from_secs(60) {
        let mut at = 0;
        while at < current.len() && runs < 400 && started.elapsed() < Duration::from_secs(60) {
            let end = (at + chunk).min(current.len());
            let candidate = [&current[..at], &current[end..]].concat();
            let run = worker.run(&candidate, timeout);
            runs += 1;
            if !worker.is_alive() {
                *worker = spawn();
            }
            let same = matches!(&run.outcome, Outcome::Finding(f) if signature(f) == wanted);
            if same {
                current = candidate;
            } else {
                at += chunk;
            }
        }
        chunk /= 2;
    }
    current
}

fn dump(args: &Args, target: Target, n: u64) -> ExitCode {
    let generator = Generator::new(target, args.seed, load_corpus(args, target));
    let input = generator.input(n);
    let dir = args.out.join(target.name());
    let file = dir.join(format!("input-{n}.{}", target.extension()));
    match std::fs::create_dir_all(&dir).and_then(|()| std::fs::write(&file, &input)) {
        Ok(()) => {
            println!("{}", file.display());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("fuzz: cannot write {}: {e}", file.display());
            ExitCode::FAILURE
        }
    }
}

fn replay(args: &Args, target: Target) -> ExitCode {
    let scratch = tempfile::tempdir().expect("a scratch folder");
    let spawn =
        || Worker::spawn(worker_command(args, target, scratch.path())).expect("start a worker");
    let mut worker = spawn();
    let timeout = Duration::from_secs_f64(args.timeout_secs);
    let mut bad = 0;
    for path in &args.replay {
        let input = match std::fs::read(path) {
            Ok(b) => b,
            Err(e) => {
                eprintln!("fuzz: {}: {e}", path.display());
                bad += 1;
                continue;
            }
        };
        let run = worker.run(&input, timeout);
        if !worker.is_alive() {
            worker = spawn();
        }
        let shown = match &run.outcome {
            Outcome::Accepted => "accepted".to_string(),
            Outcome::Refused(m) => format!("refused: {m}"),
            Outcome::Finding(f) => {
                bad += 1;
                format!("FINDING {}: {}", f.kind.name(), f.detail)
            }
        };
        println!(
            "{}: {shown} (peak heap {:.1} MB, {:.2} s)",
            path.display(),
            run.peak_bytes as f64 / 1e6,
            run.elapsed.as_secs_f64()
        );
    }
    if bad == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

/// User + system CPU time of this process and its waited-for children.
fn cpu_seconds() -> f64 {
    let of = |who| {
        // SAFETY: getrusage fills the zeroed struct it is given.
        let mut u: libc::rusage = unsafe { std::mem::zeroed() };
        unsafe { libc::getrusage(who, &mut u) };
        let t = |tv: libc::timeval| tv.tv_sec as f64 + tv.tv_usec as f64 / 1e6;
        t(u.ru_utime) + t(u.ru_stime)
    };
    of(libc::RUSAGE_SELF) + of(libc::RUSAGE_CHILDREN)
}
