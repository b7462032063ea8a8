//! The fuzz oracle: what one input is run through and what counts as a finding.
//!
//! Runs inside a worker process (the fuzzer, or the regression test binary, re-executed with
//! `FUZZ_WORKER` set in the environment). The worker reads inputs from stdin, one at a time
//! (a little-endian `u32` length, then the bytes), runs each through the library's public
//! entry points for its target and answers one line per input on stdout:
//!
//! ```text
//! @@fuzz <TAB> verdict <TAB> peak heap bytes <TAB> message (escaped, one line)
//! ```
//!
//! A panic is caught and answered (`panic`); an abort, a signal or going over the memory limit
//! ends the worker, and the parent sees that from the exit status (see `worker.rs`).
//!
//! Memory is counted by [`Counting`], the global allocator of every binary that includes this
//! module: live heap bytes and their peak per input. Over the limit the worker writes one line
//! to stderr and exits with [`OVER_MEMORY_EXIT`], without unwinding (the allocator cannot).
//!
//! Besides "no panic, no abort, no hang, no memory blow-up", the oracle checks what the issue
//! promises of every accepted or refused input:
//! - a refusal is a clear one-line error ([`MESSAGE_MAX`] bytes at most, no line feed);
//! - nothing outside the scan's folder is read into the model or copied on output (a secret file
//!   sits beside the scan folder, a symlink and a literal `..\secret.png` inside it);
//! - a daemon configuration that validates can be used (every duration fits the clock).

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use scanmill::config::DaemonConfig;
use scanmill::mesh::{self, LoadOptions, Mesh};
use scanmill::recipe::Recipe;

/// The worker's exit status when an allocation would go over the memory limit.
pub const OVER_MEMORY_EXIT: i32 = 86;

/// The environment variables that turn a process into a worker.
pub const ENV_TARGET: &str = "FUZZ_WORKER";
pub const ENV_SCRATCH: &str = "FUZZ_SCRATCH";
pub const ENV_MEMORY: &str = "FUZZ_MEMORY_LIMIT";

/// Longest error message accepted as "one clear line": long enough for two paths and a reason,
/// short enough that a log line stays a line (the issue saw a 2 GiB one).
pub const MESSAGE_MAX: usize = 2048;

/// The loaded mesh is also written out (to check what the writers copy) when it has at most
/// this many triangles; bigger ones cost time and copy the same way.
const SAVE_MAX_TRIANGLES: usize = 20_000;

/// What is fuzzed: one file format or configuration file each.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Target {
    Obj,
    Mtl,
    PlyAscii,
    PlyBinary,
    Gzip,
    Recipe,
    Config,
    /// STL, ASCII or binary (issue #28).
    Stl,
    /// glTF as JSON, buffers and images in `data:` URIs or files of the scan folder.
    Gltf,
    /// Binary glTF.
    Glb,
    /// Inputs that misbehave on purpose (`panic`, `abort`, `hang`, `oom`, `escape`): the tests
    /// check with it that the oracle sees each kind of finding. Not part of `all`.
    SelfTest,
}

impl Target {
    pub const ALL: [Target; 10] = [
        Target::Obj,
        Target::Mtl,
        Target::PlyAscii,
        Target::PlyBinary,
        Target::Gzip,
        Target::Recipe,
        Target::Config,
        Target::Stl,
        Target::Gltf,
        Target::Glb,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Target::Obj => "obj",
            Target::Mtl => "mtl",
            Target::PlyAscii => "ply-ascii",
            Target::PlyBinary => "ply-binary",
            Target::Gzip => "gzip",
            Target::Recipe => "recipe",
            Target::Config => "config",
            Target::Stl => "stl",
            Target::Gltf => "gltf",
            Target::Glb => "glb",
            Target::SelfTest => "self-test",
        }
    }

    pub fn parse(name: &str) -> Option<Target> {
        Target::ALL
            .into_iter()
            .chain([Target::SelfTest])
            .find(|t| t.name() == name)
    }

    /// The extension of a saved input.
    pub fn extension(self) -> &'static str {
        match self {
            Target::Obj => "obj",
            Target::Mtl => "mtl",
            Target::PlyAscii | Target::PlyBinary => "ply",
            Target::Gzip => "gz",
            Target::Recipe | Target::Config => "toml",
            Target::Stl => "stl",
            Target::Gltf => "gltf",
            Target::Glb => "glb",
            Target::SelfTest => "txt",
        }
    }
}

/// What the oracle concluded about one input (inside the worker).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Verdict {
    /// Loaded (or parsed and validated) without complaint.
    Accepted,
    /// Refused with a clear one-line error: the right answer to a bad input.
    Refused(String),
    /// Something the service must never do; see [`Violation`].
    Violation(Violation, String),
    /// The code under test panicked (caught); the message and its location.
    Panic(String),
}

/// A broken promise that is not a crash.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Violation {
    /// An error message with a line break or longer than [`MESSAGE_MAX`].
    MessyError,
    /// A file outside the scan's folder was resolved into the model or copied on output.
    Escape,
    /// A configuration that validates holds a value the daemon cannot use.
    Unusable,
}

impl Violation {
    pub fn name(self) -> &'static str {
        match self {
            Violation::MessyError => "messy-error",
            Violation::Escape => "escape",
            Violation::Unusable => "unusable-config",
        }
    }

    pub fn parse(name: &str) -> Option<Violation> {
        [
            Violation::MessyError,
            Violation::Escape,
            Violation::Unusable,
        ]
        .into_iter()
        .find(|v| v.name() == name)
    }
}

// ---------------------------------------------------------------------------------------
// Memory accounting

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
static LIMIT: AtomicUsize = AtomicUsize::new(usize::MAX);

/// The system allocator, counting live bytes, their peak, and enforcing [`LIMIT`].
pub struct Counting;

impl Counting {
    fn grow(size: usize) {
        let live = LIVE.fetch_add(size, Ordering::Relaxed) + size;
        if live > LIMIT.load(Ordering::Relaxed) {
            over_limit(size, live - size);
        }
        PEAK.fetch_max(live, Ordering::Relaxed);
    }

    fn shrink(size: usize) {
        LIVE.fetch_sub(size, Ordering::Relaxed);
    }
}

// SAFETY: every call forwards to `System` with the same arguments; the counters are
// bookkeeping only.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        Counting::grow(layout.size());
        // SAFETY: forwarded unchanged.
        let p = unsafe { System.alloc(layout) };
        if p.is_null() {
            Counting::shrink(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        Counting::grow(layout.size());
        // SAFETY: forwarded unchanged.
        let p = unsafe { System.alloc_zeroed(layout) };
        if p.is_null() {
            Counting::shrink(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged.
        unsafe { System.dealloc(ptr, layout) };
        Counting::shrink(layout.size());
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let old = layout.size();
        if new_size > old {
            Counting::grow(new_size - old);
        }
        // SAFETY: forwarded unchanged.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if p.is_null() {
            if new_size > old {
                Counting::shrink(new_size - old);
            }
        } else if new_size < old {
            Counting::shrink(old - new_size);
        }
        p
    }
}

/// Ends the worker: an allocation would go over the limit. Writes without allocating.
fn over_limit(requested: usize, live: usize) -> ! {
    let mut line = [0u8; 160];
    let mut n = 0;
    let mut put = |bytes: &[u8]| {
        for &b in bytes {
            if n < line.len() {
                line[n] = b;
                n += 1;
            }
        }
    };
    put(b"fuzz worker: over the memory limit: ");
    put(decimal(requested as u64).as_slice());
    put(b" bytes requested with ");
    put(decimal(live as u64).as_slice());
    put(b" bytes live\n");
    // SAFETY: writing a stack buffer to fd 2, then exiting without running anything else
    // (we are inside the allocator: no unwinding, no destructors).
    unsafe {
        libc::write(2, line.as_ptr().cast(), n);
        libc::_exit(OVER_MEMORY_EXIT);
    }
}

/// Digits of `v` in a fixed buffer (no allocation), as a small array-backed slice.
fn decimal(mut v: u64) -> DecimalDigits {
    let mut digits = [0u8; 20];
    let mut start = digits.len();
    loop {
        start -= 1;
        digits[start] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    DecimalDigits { digits, start }
}

struct DecimalDigits {
    digits: [u8; 20],
    start: usize,
}

impl DecimalDigits {
    fn as_slice(&self) -> &[u8] {
        &self.digits[self.start..]
    }
}

/// Starts counting a new input's peak from what is live now.
fn reset_peak() -> usize {
    let live = LIVE.load(Ordering::Relaxed);
    PEAK.store(live, Ordering::Relaxed);
    live
}

fn peak() -> usize {
    PEAK.load(Ordering::Relaxed)
}

// ---------------------------------------------------------------------------------------
// The worker

/// The worker's settings, read from the environment its parent set.
pub struct WorkerEnv {
    pub target: Target,
    pub scratch: PathBuf,
    pub memory_limit: usize,
}

/// `Some` when this process was started as a worker.
pub fn worker_env() -> Option<WorkerEnv> {
    let target = std::env::var(ENV_TARGET).ok()?;
    let target = Target::parse(&target).unwrap_or_else(|| {
        eprintln!("fuzz worker: unknown target {target:?}");
        std::process::exit(2)
    });
    let scratch = PathBuf::from(std::env::var_os(ENV_SCRATCH)?);
    let memory_limit = std::env::var(ENV_MEMORY)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(usize::MAX);
    Some(WorkerEnv {
        target,
        scratch,
        memory_limit,
    })
}

/// The panic message of the last panic, with its location (set by the hook, read after
/// `catch_unwind`).
static LAST_PANIC: Mutex<String> = Mutex::new(String::new());

/// Serves inputs until stdin closes. Returns the process exit status.
pub fn worker_main(env: WorkerEnv) -> i32 {
    let scratch = match Scratch::create(&env.scratch) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("fuzz worker: cannot set up {}: {e}", env.scratch.display());
            return 2;
        }
    };
    // Relative paths in a configuration (and the default recipe's) resolve in the scratch.
    if let Err(e) = std::env::set_current_dir(&scratch.root) {
        eprintln!("fuzz worker: cannot enter {}: {e}", scratch.root.display());
        return 2;
    }
    std::panic::set_hook(Box::new(|info| {
        let message = match info.payload().downcast_ref::<&str>() {
            Some(s) => s.to_string(),
            None => match info.payload().downcast_ref::<String>() {
                Some(s) => s.clone(),
                None => "(non-string panic payload)".to_string(),
            },
        };
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        if let Ok(mut last) = LAST_PANIC.lock() {
            *last = format!("{message}{at}");
        }
    }));
    LIMIT.store(env.memory_limit, Ordering::Relaxed);
    let mut stdin = std::io::stdin().lock();
    let mut stdout = std::io::stdout().lock();
    loop {
        let mut len = [0u8; 4];
        if stdin.read_exact(&mut len).is_err() {
            return 0;
        }
        let mut input = vec![0u8; u32::from_le_bytes(len) as usize];
        if stdin.read_exact(&mut input).is_err() {
            return 0;
        }
        reset_peak();
        let verdict = std::panic::catch_unwind(|| run_one(env.target, &scratch, &input))
            .unwrap_or_else(|_| {
                Verdict::Panic(LAST_PANIC.lock().map(|s| s.clone()).unwrap_or_default())
            });
        let peak = peak();
        drop(input);
        let (tag, message) = match &verdict {
            Verdict::Accepted => ("accepted", String::new()),
            Verdict::Refused(m) => ("refused", m.clone()),
            Verdict::Violation(v, m) => (v.name(), m.clone()),
            Verdict::Panic(m) => ("panic", m.clone()),
        };
        let line = format!("@@fuzz\t{tag}\t{peak}\t{}\n", one_line(&message, 600));
        if stdout.write_all(line.as_bytes()).is_err() || stdout.flush().is_err() {
            return 0;
        }
    }
}

/// `text` escaped onto one line and cut to about `max` characters.
pub fn one_line(text: &str, max: usize) -> String {
    let mut out = String::new();
    for c in text.chars() {
        if out.len() >= max {
            out.push('…');
            break;
        }
        match c {
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if c.is_control() => out.push_str(&c.escape_unicode().to_string()),
            c => out.push(c),
        }
    }
    out
}

/// The worker's folder: the scan folder with companion files, a secret outside it, an output
/// folder. Created once per worker; inputs overwrite their own file in it.
pub struct Scratch {
    pub root: PathBuf,
    /// Canonical scan folder (inputs are written here).
    pub scan: PathBuf,
    /// Output folder for the writers (emptied before each save).
    pub out: PathBuf,
    /// Bytes of the files that must never be read into a result or copied: the secret beside
    /// the scan folder, and /etc/passwd when it is readable.
    secrets: Vec<Vec<u8>>,
    /// Names in the scratch root after set-up: a writer that puts anything else there escaped.
    root_names: Vec<std::ffi::OsString>,
}

/// A tiny PNG with a given first pixel (distinct images for distinct roles).
fn png(path: &Path, first: [u8; 3], size: u32) -> std::io::Result<()> {
    let mut img = image::RgbImage::new(size, size);
    img.put_pixel(0, 0, image::Rgb(first));
    img.save(path).map_err(std::io::Error::other)
}

impl Scratch {
    pub fn create(root: &Path) -> std::io::Result<Scratch> {
        std::fs::create_dir_all(root)?;
        let root = root.canonicalize()?;
        let scan = root.join("scan");
        let out = root.join("out");
        std::fs::create_dir_all(scan.join("sub"))?;
        std::fs::create_dir_all(&out)?;
        png(&root.join("secret.png"), [0xde, 0xad, 0xbe], 3)?;
        std::fs::write(
            root.join("outside.mtl"),
            "newmtl m0\nmap_Kd secret.png\nmap_Bump secret.png\n",
        )?;
        png(&scan.join("tex.png"), [1, 2, 3], 2)?;
        png(&scan.join("sub").join("inner.png"), [4, 5, 6], 2)?;
        let mut jpeg = image::RgbImage::new(8, 8);
        jpeg.put_pixel(0, 0, image::Rgb([200, 10, 10]));
        jpeg.save(scan.join("tex.jpg"))
            .map_err(std::io::Error::other)?;
        std::fs::write(scan.join("bad.png"), b"\x89PNG\r\n\x1a\nnot really")?;
        // Companions for the OBJ and PLY targets (overwritten by the MTL target).
        std::fs::write(scan.join("scan.mtl"), COMPANION_MTL)?;
        // Hostile neighbours: a symlink out, a literal backslash name (finding 2 of #22),
        // a FIFO that blocks whoever opens it for reading.
        let _ = std::fs::remove_file(scan.join("link.png"));
        std::os::unix::fs::symlink("../secret.png", scan.join("link.png"))?;
        std::fs::write(scan.join("..\\secret.png"), b"literal backslash name")?;
        let fifo = scan.join("fifo.png");
        if !fifo.exists() {
            let c = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes())
                .map_err(std::io::Error::other)?;
            // SAFETY: a valid NUL-terminated path.
            if unsafe { libc::mkfifo(c.as_ptr(), 0o600) } != 0 {
                return Err(std::io::Error::last_os_error());
            }
        }
        let mut secrets = vec![std::fs::read(root.join("secret.png"))?];
        if let Ok(passwd) = std::fs::read("/etc/passwd") {
            secrets.push(passwd);
        }
        let root_names = names_in(&root)?;
        Ok(Scratch {
            root,
            scan,
            out,
            secrets,
            root_names,
        })
    }
}

fn names_in(dir: &Path) -> std::io::Result<Vec<std::ffi::OsString>> {
    let mut names = std::fs::read_dir(dir)?
        .map(|e| e.map(|e| e.file_name()))
        .collect::<std::io::Result<Vec<_>>>()?;
    names.sort();
    Ok(names)
}

/// The MTL beside the OBJ and PLY targets' inputs.
const COMPANION_MTL: &str = "newmtl m0\nKd 1 1 1\nmap_Kd tex.png\n\
newmtl m1\nmap_Kd -s 1 1 1 tex.jpg\nmap_Bump sub/inner.png\n";

/// Runs one input through its target.
pub fn run_one(target: Target, scratch: &Scratch, input: &[u8]) -> Verdict {
    let verdict = match target {
        Target::Obj => load_mesh(scratch, "scan.obj", input),
        Target::PlyAscii | Target::PlyBinary => load_mesh(scratch, "scan.ply", input),
        Target::Gzip => {
            let name = if gzip_body_starts_with(input, b"ply") {
                "scan.ply.gz"
            } else {
                "scan.obj.gz"
            };
            load_mesh(scratch, name, input)
        }
        Target::Stl => load_mesh(scratch, "scan.stl", input),
        Target::Gltf => load_mesh(scratch, "scan.gltf", input),
        Target::Glb => load_mesh(scratch, "scan.glb", input),
        Target::Mtl => load_mtl(scratch, input),
        Target::Recipe => recipe(scratch, input),
        Target::Config => config(scratch, input),
        Target::SelfTest => self_test(scratch, input),
    };
    match verdict {
        Verdict::Refused(message) if !is_one_clear_line(&message) => Verdict::Violation(
            Violation::MessyError,
            format!("{} bytes: {message}", message.len()),
        ),
        v => v,
    }
}

/// Not empty, not longer than [`MESSAGE_MAX`], no line feed. (A carriage return or another
/// control character copied from a file name into a message is the business of whoever
/// shows it: logs and the CLI escape control characters, issue #22 item 4.)
fn is_one_clear_line(message: &str) -> bool {
    !message.is_empty() && message.len() <= MESSAGE_MAX && !message.contains('\n')
}

/// Whether the gzip stream decompresses to something that starts with `prefix`.
fn gzip_body_starts_with(compressed: &[u8], prefix: &[u8]) -> bool {
    let mut head = vec![0u8; prefix.len()];
    flate2::read::MultiGzDecoder::new(compressed)
        .read_exact(&mut head)
        .is_ok()
        && head == prefix
}

fn write_input(path: &Path, input: &[u8]) -> Result<(), Verdict> {
    std::fs::write(path, input)
        .map_err(|e| Verdict::Refused(format!("oracle: cannot write {}: {e}", path.display())))
}

/// Loads `input` saved as `scan/<name>` through `mesh::io::load`, then checks the result.
fn load_mesh(s: &Scratch, name: &str, input: &[u8]) -> Verdict {
    let path = s.scan.join(name);
    if let Err(v) = write_input(&path, input) {
        return v;
    }
    let verdict = match mesh::io::load(&path, &LoadOptions::default()) {
        Ok((mesh, _report)) => check_loaded(s, &mesh, writers_for(name)),
        Err(e) => Verdict::Refused(e.to_string()),
    };
    let _ = std::fs::remove_file(&path);
    verdict
}

/// Loads an MTL: the parser directly, the MTL loader (which resolves files), then an OBJ that
/// uses it.
fn load_mtl(s: &Scratch, input: &[u8]) -> Verdict {
    let mtl_path = s.scan.join("scan.mtl");
    let materials = match mesh::mtl::parse(&mtl_path, input) {
        Ok(m) => m,
        Err(e) => return Verdict::Refused(e.to_string()),
    };
    if let Err(v) = write_input(&mtl_path, input) {
        return v;
    }
    let limits = mesh::limits::InputLimits::default();
    let verdict = match mesh::mtl::load(&mtl_path, &s.scan, &limits) {
        Err(e) => Verdict::Refused(e.to_string()),
        Ok(loaded) => match textures_inside(s, loaded.iter()) {
            Some(escape) => escape,
            None => {
                // Use the MTL's first material, when its name can be written on a line.
                let used = materials
                    .first()
                    .map(|m| m.name.as_str())
                    .filter(|n| !n.is_empty() && !n.contains(['\n', '\r', '#']))
                    .unwrap_or("m0");
                let obj = format!(
                    "mtllib scan.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                     vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl {used}\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"
                );
                load_mesh(s, "scan.obj", obj.as_bytes())
            }
        },
    };
    // Put the companion back for the other targets of the same worker (there are none today,
    // but a worker serves one target only by convention, not by construction).
    let _ = std::fs::write(&mtl_path, COMPANION_MTL);
    verdict
}

/// Every file a material names (its diffuse texture, its other maps) must resolve inside
/// the scan folder.
fn textures_inside<'a>(
    s: &Scratch,
    materials: impl Iterator<Item = &'a mesh::Material>,
) -> Option<Verdict> {
    for m in materials {
        let files = m
            .diffuse_texture
            .iter()
            .map(|t| &t.path)
            .chain(m.map_files.iter().map(|f| &f.path));
        for path in files {
            let real = path.canonicalize().unwrap_or_else(|_| path.clone());
            if !real.starts_with(&s.scan) {
                return Some(Verdict::Violation(
                    Violation::Escape,
                    format!(
                        "material {:?}: {} resolves to {}, outside the scan folder",
                        m.name,
                        path.display(),
                        real.display()
                    ),
                ));
            }
        }
    }
    None
}

/// The outputs a loaded input is written to: OBJ always, and the input's own format where
/// scanmill writes it.
fn writers_for(input: &str) -> &'static [&'static str] {
    if input.contains(".ply") {
        &["scan.obj", "scan.ply"]
    } else if input.contains(".gl") {
        &["scan.obj", "scan.glb"]
    } else {
        &["scan.obj"]
    }
}

/// After a successful load: textures inside the scan folder; and, for small meshes, the
/// writers copy nothing from outside and write nothing outside the output folder.
fn check_loaded(s: &Scratch, mesh: &Mesh, names: &[&str]) -> Verdict {
    if let Some(escape) = textures_inside(s, mesh.materials.iter()) {
        return escape;
    }
    if mesh.triangles.len() > SAVE_MAX_TRIANGLES {
        return Verdict::Accepted;
    }
    for name in names {
        let _ = std::fs::remove_dir_all(&s.out);
        if let Err(e) = std::fs::create_dir_all(&s.out) {
            return Verdict::Refused(format!("oracle: cannot create {}: {e}", s.out.display()));
        }
        let written = mesh::io::save(mesh, &s.out.join(name), &mesh::SaveOptions::default());
        if let Some(escape) = output_escape(s, written.as_deref().unwrap_or(&[])) {
            return escape;
        }
    }
    Verdict::Accepted
}

/// A written path outside the output folder, a new name in the scratch root, or a secret's
/// bytes in the output folder.
fn output_escape(s: &Scratch, written: &[PathBuf]) -> Option<Verdict> {
    let escape = |m: String| Some(Verdict::Violation(Violation::Escape, m));
    for p in written {
        let parent = p.parent().and_then(|d| d.canonicalize().ok());
        if !parent.is_some_and(|d| d.starts_with(&s.out)) {
            return escape(format!(
                "the writer wrote {} outside the output folder",
                p.display()
            ));
        }
    }
    match names_in(&s.root) {
        Ok(names) if names != s.root_names => {
            return escape(format!(
                "the scratch folder changed: {:?} (expected {:?})",
                names, s.root_names
            ));
        }
        _ => {}
    }
    let mut files = Vec::new();
    files_under(&s.out, &mut files);
    for path in files {
        let Ok(meta) = std::fs::symlink_metadata(&path) else {
            continue;
        };
        if meta.file_type().is_symlink() {
            return escape(format!("the writer made a symlink {}", path.display()));
        }
        if !meta.is_file() || meta.len() > 16 << 20 {
            continue;
        }
        let Ok(bytes) = std::fs::read(&path) else {
            continue;
        };
        if s.secrets.contains(&bytes) {
            return escape(format!(
                "{} is a copy of a file outside the scan folder",
                path.display()
            ));
        }
    }
    None
}

/// Every entry under `dir` except folders, recursively (symlinks are not followed).
fn files_under(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        match entry.file_type() {
            Ok(t) if t.is_dir() => files_under(&entry.path(), out),
            _ => out.push(entry.path()),
        }
    }
}

/// The mesh recipes run on: small, textured, quick for every step.
fn recipe_mesh() -> Mesh {
    mesh::shapes::grid(6, 6)
}

/// Parses a recipe from a file, then runs it on a small mesh.
fn recipe(s: &Scratch, input: &[u8]) -> Verdict {
    let path = s.root.join("recipe.toml");
    if let Err(v) = write_input(&path, input) {
        return v;
    }
    let recipe = match Recipe::from_path(&path) {
        Ok(r) => r,
        Err(e) => return Verdict::Refused(e.to_string()),
    };
    let _ = recipe.resolved_json();
    let _ = recipe.hash();
    let mut mesh = recipe_mesh();
    let stages = recipe.steps.len() + 1;
    match scanmill::recipe::runner::run_recipe(
        &recipe,
        &mut mesh,
        &scanmill::mesh::InputLimits::default(),
        &scanmill::recipe::runner::NoProgress,
        0,
        stages,
    ) {
        Ok(_) => Verdict::Accepted,
        Err(e) => Verdict::Refused(e.to_string()),
    }
}

/// Parses and validates a daemon configuration; one that validates must be usable.
fn config(s: &Scratch, input: &[u8]) -> Verdict {
    let path = s.root.join("scanmill.toml");
    if let Err(v) = write_input(&path, input) {
        return v;
    }
    let config = match DaemonConfig::from_path(&path) {
        Ok(c) => c,
        Err(e) => return Verdict::Refused(e.to_string()),
    };
    let problems = config.validate();
    let _ = config.hash();
    if let Some(problem) = problems.iter().find(|p| !is_one_clear_line(p)) {
        return Verdict::Refused(problem.clone());
    }
    if !problems.is_empty() {
        return Verdict::Refused(problems.join("; "));
    }
    match unusable_duration(&config) {
        Some(m) => Verdict::Violation(Violation::Unusable, m),
        None => Verdict::Accepted,
    }
}

/// A seconds value the daemon would turn into a `Duration` past the clock's range.
fn unusable_duration(c: &DaemonConfig) -> Option<String> {
    let mut keys = vec![
        ("retry_base_secs", c.retry_base_secs),
        ("retry_max_secs", c.retry_max_secs),
        ("job_timeout_secs", c.job_timeout_secs),
        ("drain_timeout_secs", c.drain_timeout_secs),
        ("rescan_secs", c.rescan_secs),
        ("incomplete_report_secs", c.incomplete_report_secs),
    ];
    for w in &c.watch {
        keys.push(("quiet_period_secs", w.quiet_period_secs));
        keys.push(("poll_secs", w.poll_secs));
    }
    let now = Instant::now();
    keys.into_iter().find_map(|(key, secs)| {
        let usable = Duration::try_from_secs_f64(secs)
            .ok()
            .and_then(|d| now.checked_add(d))
            .is_some();
        (!usable).then(|| format!("{key} = {secs} validates but is no usable duration"))
    })
}

/// Misbehaves as the input says (see [`Target::SelfTest`]).
fn self_test(s: &Scratch, input: &[u8]) -> Verdict {
    match input {
        b"panic" => panic!("self-test panic"),
        b"abort" => std::process::abort(),
        b"hang" => loop {
            std::thread::sleep(Duration::from_secs(1));
        },
        b"oom" => {
            let mut hog: Vec<Vec<u8>> = Vec::new();
            loop {
                hog.push(vec![1u8; 64 << 20]);
            }
        }
        b"escape" => {
            let _ = std::fs::copy(s.root.join("secret.png"), s.out.join("copy.png"));
            output_escape(s, &[]).unwrap_or(Verdict::Accepted)
        }
        b"messy" => Verdict::Refused("two\nlines".to_string()),
        _ => Verdict::Accepted,
    }
}
