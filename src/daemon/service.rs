//! The service loop: one tokio task (current-thread runtime) that owns the database
//! connection and the tracker, and reacts to signals, file-event hints, job results and
//! its own timers. Each job is supervised from its own OS thread ([`super::worker`]) and
//! runs in its own worker process ([`super::supervise`]).
//!
//! Start-up: lock the state dir, migrate, requeue jobs left running (not counted), delete
//! stale temporaries, set the watches, walk every root once, then READY=1.
//! Events are hints: any event in a root schedules a full walk of it (after 100 ms, to
//! gather a burst); each root is also walked every `rescan_secs` (or `poll_secs`), after a
//! watcher error or queue overflow, and when the root itself was replaced or remounted.
//! SIGTERM/SIGINT: STOPPING=1, stop claiming, give running jobs `drain_timeout_secs`,
//! then put the rest back in the queue (not counted), checkpoint the WAL and return.

use super::glob::Filter;
use super::scanset::{Content, Done, Event, Known, Limits, RootSpec, Tracker, job_key};
use super::supervise::WorkerLimits;
use super::systemd::{Notifier, StateLock, free_bytes};
use super::worker::{self, JobResult, JobSpec, PublishGate};
use crate::config::{ConfigSource, DaemonConfig, absolute, load_recipe};
use crate::recipe::Recipe;
use crate::store::pg::Fence;
use crate::store::{
    ClaimedJob, Enqueued, FailureKind, FinalState, Finish, JobOrder, NewJob, Owner, Queue,
    RetryPolicy, StoreError, now_ms,
};
use std::collections::HashMap;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

#[derive(Debug, thiserror::Error)]
pub enum ServiceError {
    #[error("invalid configuration ({origin}):\n  {}", problems.join("\n  "))]
    Config {
        origin: ConfigSource,
        problems: Vec<String>,
    },
    #[error("{0}")]
    Locked(std::io::Error),
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error("{context}: {source}")]
    Io {
        context: String,
        #[source]
        source: std::io::Error,
    },
}

struct RootRuntime {
    path: PathBuf,
    output: PathBuf,
    recipe: Arc<Recipe>,
    recipe_path: PathBuf,
    recipe_hash: String,
    poll: Option<Duration>,
    watcher: Option<notify::RecommendedWatcher>,
    identity: Option<(u64, u64)>,
    walk_due: Instant,
    overflow: Arc<AtomicBool>,
}

struct Running {
    job: ClaimedJob,
    gate: Arc<PublishGate>,
    deadline: Instant,
}

/// The running service's state (everything the loop touches).
struct Service {
    config: DaemonConfig,
    config_hash: String,
    store: Queue,
    /// The shared queue's fence (PostgreSQL): job threads publish through it.
    fence: Option<Arc<Fence>>,
    /// When the shared queue's leases are renewed next, and expired ones looked for.
    next_heartbeat: Instant,
    next_rescue: Instant,
    tracker: Tracker,
    roots: Vec<RootRuntime>,
    owner: Owner,
    notifier: Notifier,
    running: HashMap<i64, Running>,
    results_tx: mpsc::UnboundedSender<(i64, JobResult)>,
    hints_tx: mpsc::Sender<usize>,
    last_status: String,
    paused: Option<String>,
    stopping: bool,
    /// Something may be claimable: set by our own writes; other connections' writes are
    /// seen through `data_version`. Lets an idle daemon skip the queue queries.
    work_maybe: bool,
    data_version: i64,
    next_run_after: Option<i64>,
    counts: (i64, i64),
    /// Finished jobs whose end could not be recorded yet (database busy).
    unrecorded: Vec<(i64, JobResult)>,
    /// The current pause after a busy database; reset once a turn of the loop succeeds.
    busy_pause: Duration,
    /// What the web dashboard shows of the loop's state.
    live: crate::web::Live,
}

const DEBOUNCE: Duration = Duration::from_millis(100);
const CLAIM_POLL: Duration = Duration::from_secs(1);
/// Pauses while another process holds the database's write lock (each on top of SQLite's
/// own 10 s busy timeout).
const BUSY_PAUSE_MIN: Duration = Duration::from_millis(500);
const BUSY_PAUSE_MAX: Duration = Duration::from_secs(10);
/// A job's supervisor kills its worker at `job_timeout_secs`; the service gives up on the
/// supervisor itself (stuck publishing on a hung file system) only this much later.
const SUPERVISOR_GRACE: Duration = Duration::from_secs(120);

fn secs(s: f64) -> Duration {
    Duration::from_secs_f64(s.max(0.0))
}

fn root_identity(path: &Path) -> Option<(u64, u64)> {
    std::fs::metadata(path)
        .ok()
        .filter(|m| m.is_dir())
        .map(|m| (m.dev(), m.ino()))
}

/// Runs the daemon until SIGTERM/SIGINT. `config` must come from [`DaemonConfig::locate`].
pub fn run(config: DaemonConfig, origin: ConfigSource) -> Result<(), ServiceError> {
    tracing::info!(config = %origin, version = env!("CARGO_PKG_VERSION"), "scanmill daemon starting");
    // Make the folders first when asked, so that validation sees them.
    if config.create_missing_dirs {
        create_missing_dirs(&config)?;
    }
    let problems = config.validate();
    if !problems.is_empty() {
        return Err(ServiceError::Config { origin, problems });
    }
    let lock = StateLock::acquire(&config.state_dir).map_err(ServiceError::Locked)?;
    let (store, known) = open_store(&config)?;
    let (roots, specs) = watched_roots(&config, &origin)?;
    // File contents are read and hashed on their own thread; results come back to the
    // loop as messages, so no input can hold the loop (or the watchdog ping) up.
    let (content_tx, content_rx) = mpsc::unbounded_channel::<Done>();
    let content = Content::spawn(move |done| {
        let _ = content_tx.send(done);
    })
    .map_err(|source| ServiceError::Io {
        context: "content thread".into(),
        source,
    })?;
    let limits = Limits {
        incomplete_after: secs(config.incomplete_report_secs),
        unreadable_retry: secs(config.rescan_secs),
        max_input_bytes: config.max_input_bytes,
    };
    let tracker = Tracker::new(specs, known, limits, content);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|source| ServiceError::Io {
            context: "tokio runtime".into(),
            source,
        })?;
    let live = crate::web::Live::new(config.workers);
    if config.web.enabled {
        start_web(&runtime, &config, &roots, live.clone())?;
    }
    let (results_tx, results_rx) = mpsc::unbounded_channel();
    let (hints_tx, hints_rx) = mpsc::channel(256);
    let service = Service {
        config_hash: config.hash(),
        fence: store.fence().map(Arc::new),
        next_heartbeat: Instant::now(),
        next_rescue: Instant::now(),
        config,
        store,
        tracker,
        roots,
        owner: Owner::current(),
        notifier: Notifier::from_env(),
        running: HashMap::new(),
        results_tx,
        hints_tx,
        last_status: String::new(),
        paused: None,
        stopping: false,
        work_maybe: true,
        data_version: 0,
        next_run_after: None,
        counts: (0, 0),
        unrecorded: Vec::new(),
        busy_pause: Duration::ZERO,
        live,
    };
    let result = runtime.block_on(service.main_loop(results_rx, hints_rx, content_rx));
    drop(lock);
    result
}

/// Creates the state folder and every watched and output folder that does not exist.
fn create_missing_dirs(config: &DaemonConfig) -> Result<(), ServiceError> {
    let dirs = std::iter::once(&config.state_dir)
        .chain(config.watch.iter().flat_map(|w| [&w.path, &w.output]));
    for d in dirs {
        if !d.exists() {
            std::fs::create_dir_all(d).map_err(|source| ServiceError::Io {
                context: format!("create {}", d.display()),
                source,
            })?;
            tracing::info!("created {}", d.display());
        }
    }
    Ok(())
}

/// Opens the job store, queues again the jobs a previous process left running, and reads
/// the input sets it has recorded.
fn open_store(config: &DaemonConfig) -> Result<(Queue, Known), ServiceError> {
    let mut store = Queue::open(&config.store, &config.database_path())?;
    tracing::info!(store = %store.describe(), "job store open");
    let requeued = store.recover_running()?;
    if requeued > 0 {
        tracing::warn!(
            requeued,
            "jobs left running by a previous process are queued again"
        );
    }
    let mut known = Known::new();
    for (root, rel, members) in store.known_inputs()? {
        known.insert((root, rel), members);
    }
    Ok((store, known))
}

/// Each watched folder as the loop runs it and as the tracker sees it, its recipe loaded
/// and stale temporaries removed from its output folder.
fn watched_roots(
    config: &DaemonConfig,
    origin: &ConfigSource,
) -> Result<(Vec<RootRuntime>, Vec<RootSpec>), ServiceError> {
    let mut roots = Vec::new();
    let mut specs = Vec::new();
    let now = Instant::now();
    for w in &config.watch {
        let recipe = load_recipe(&w.recipe).map_err(|e| ServiceError::Config {
            origin: origin.clone(),
            problems: vec![e.to_string()],
        })?;
        let path = absolute(&w.path);
        let output = absolute(&w.output);
        // A shared output folder holds other hosts' staging too: only what no attempt can
        // still be writing is removed.
        let removed = if config.store.is_shared() {
            let age = secs(config.job_timeout_secs) + SUPERVISOR_GRACE;
            super::publish::clean_staging_older(&output, age)
        } else {
            super::publish::clean_staging(&output)
        };
        if removed > 0 {
            tracing::info!(removed, output = %output.display(), "removed stale temporaries");
        }
        specs.push(RootSpec {
            path: path.clone(),
            filter: Filter {
                include: w.include.clone(),
                exclude: w.exclude.clone(),
            },
            quiet: secs(w.quiet_period_secs),
            marker: w.marker.clone(),
            follow_symlinks: w.follow_symlinks,
        });
        roots.push(RootRuntime {
            identity: None,
            path,
            output,
            recipe_hash: recipe.hash(),
            recipe: Arc::new(recipe),
            recipe_path: w.recipe.clone(),
            poll: (w.poll_secs > 0.0).then(|| secs(w.poll_secs)),
            watcher: None,
            walk_due: now,
            overflow: Arc::new(AtomicBool::new(false)),
        });
    }
    Ok((roots, specs))
}

/// Starts the web dashboard on the service's runtime (docs/service.md "Web dashboard and
/// metrics"); a listen address that cannot be bound stops the daemon before it is ready.
fn start_web(
    runtime: &tokio::runtime::Runtime,
    config: &DaemonConfig,
    roots: &[RootRuntime],
    live: crate::web::Live,
) -> Result<(), ServiceError> {
    use crate::text::escape_path;
    let store = match config.store.conn_info() {
        Ok(Some(info)) => crate::web::StoreSource::Postgres(Box::new(info)),
        Ok(None) => crate::web::StoreSource::Sqlite(config.database_path()),
        Err(e) => return Err(ServiceError::Store(e)),
    };
    let setup = crate::web::Setup {
        config: config.web.clone(),
        store,
        live,
        roots: roots
            .iter()
            .map(|r| {
                let (p, o, rc) = (&r.path, &r.output, &r.recipe_path);
                (escape_path(p), escape_path(o), escape_path(rc))
            })
            .collect(),
        outputs: roots.iter().map(|r| r.output.clone()).collect(),
    };
    let addr = crate::web::start(runtime, setup).map_err(|source| ServiceError::Io {
        context: format!("web.listen {}", crate::text::escape_str(&config.web.listen)),
        source,
    })?;
    tracing::info!("web dashboard on http://{addr}/");
    Ok(())
}

/// A stream of the signal `kind`.
fn signal_stream(
    kind: tokio::signal::unix::SignalKind,
) -> Result<tokio::signal::unix::Signal, ServiceError> {
    tokio::signal::unix::signal(kind).map_err(|source| ServiceError::Io {
        context: "signal handler".into(),
        source,
    })
}

impl Service {
    async fn main_loop(
        mut self,
        mut results_rx: mpsc::UnboundedReceiver<(i64, JobResult)>,
        mut hints_rx: mpsc::Receiver<usize>,
        mut content_rx: mpsc::UnboundedReceiver<Done>,
    ) -> Result<(), ServiceError> {
        use tokio::signal::unix::SignalKind;
        let mut sigterm = signal_stream(SignalKind::terminate())?;
        let mut sigint = signal_stream(SignalKind::interrupt())?;
        let mut sighup = signal_stream(SignalKind::hangup())?;
        self.reconcile_and_ready()?;
        let watchdog = self.notifier.watchdog().map(|w| w / 2);

        loop {
            if let Err(e) = self.tend_queue() {
                self.survive(e).await?;
                continue;
            }
            self.busy_pause = Duration::ZERO;
            self.notifier.watchdog_ping();

            let next = self.next_wake(Instant::now(), watchdog);
            tokio::select! {
                _ = sigterm.recv() => { tracing::info!("SIGTERM: stopping"); break; }
                _ = sigint.recv() => { tracing::info!("SIGINT: stopping"); break; }
                _ = sighup.recv() => {
                    tracing::warn!("SIGHUP: live reload is not supported; restart the service to apply a new configuration");
                }
                Some(first) = hints_rx.recv() => self.gather_hints(first, &mut hints_rx),
                Some((id, result)) = results_rx.recv() => {
                    if let Err(e) = self.job_finished(id, result) {
                        self.survive(e).await?;
                    }
                }
                Some(done) = content_rx.recv() => {
                    let events = self.tracker.content_done(done, Instant::now());
                    if let Err(e) = self.handle_events(events) {
                        self.survive(e).await?;
                    }
                }
                _ = tokio::time::sleep_until(next.into()) => {}
            }
            if let Err(e) = self.tend_roots() {
                self.survive(e).await?;
            }
        }
        self.shutdown(&mut results_rx, &mut sigterm, &mut sigint)
            .await
    }

    /// The first reconcile, before READY: whatever arrived while we were down is found now.
    fn reconcile_and_ready(&mut self) -> Result<(), ServiceError> {
        for i in 0..self.roots.len() {
            self.ensure_watch(i);
            self.walk_root(i)?;
        }
        self.counts = self.store.counts()?;
        self.notifier.ready(&self.status_line()?);
        tracing::info!(roots = self.roots.len(), "ready");
        Ok(())
    }

    /// When the loop must wake at the latest: the next claim poll, walk, settling deadline,
    /// job deadline, watchdog ping or delayed retry.
    fn next_wake(&self, now: Instant, watchdog: Option<Duration>) -> Instant {
        let mut next = now + CLAIM_POLL;
        for r in &self.roots {
            next = next.min(r.walk_due);
        }
        if let Some(d) = self.tracker.next_deadline(now) {
            next = next.min(d);
        }
        for r in self.running.values() {
            next = next.min(r.deadline);
        }
        if let Some(w) = watchdog {
            next = next.min(now + w);
        }
        if let Some(t) = self.next_run_after {
            let wait = Duration::from_millis((t - now_ms()).max(0) as u64);
            next = next.min(now + wait);
        }
        next
    }

    /// Gathers a burst of watch hints: one walk per root covers every event in it.
    fn gather_hints(&mut self, first: usize, hints_rx: &mut mpsc::Receiver<usize>) {
        let due = Instant::now() + DEBOUNCE;
        let mut i = first;
        loop {
            if self.roots[i].walk_due > due {
                self.roots[i].walk_due = due;
            }
            match hints_rx.try_recv() {
                Ok(next) => i = next,
                Err(_) => break,
            }
        }
    }

    /// The queue's side of one turn of the loop: record what could not be recorded, claim
    /// what can run, notice timeouts, tell systemd.
    fn tend_queue(&mut self) -> Result<(), ServiceError> {
        self.record_unrecorded()?;
        self.tend_leases()?;
        let version = self.store.data_version()?;
        let due = self.next_run_after.is_some_and(|t| t <= now_ms());
        if self.work_maybe || due || version != self.data_version || self.paused.is_some() {
            self.data_version = version;
            self.work_maybe = false;
            self.claim_jobs()?;
            self.next_run_after = self.store.next_run_after()?;
            self.counts = self.store.counts()?;
        }
        self.check_timeouts()?;
        self.update_status()
    }

    /// The shared queue's leases: renew ours every third of the lease (an attempt that lost
    /// its lease is stopped; the fence keeps it from publishing anyway), and requeue jobs
    /// whose lease passed every `rescue_secs`.
    fn tend_leases(&mut self) -> Result<(), ServiceError> {
        let Some(lease) = self.store.lease() else {
            return Ok(());
        };
        let now = Instant::now();
        if now >= self.next_heartbeat {
            let tokens: Vec<i64> = self.running.values().map(|r| r.job.attempt_id).collect();
            let held = self.store.heartbeat(&tokens)?;
            self.next_heartbeat = now + lease / 3;
            let lost: Vec<i64> = self
                .running
                .iter()
                .filter(|(_, r)| !held.contains(&r.job.attempt_id))
                .map(|(id, _)| *id)
                .collect();
            for id in lost {
                if let Some(state) = self.abandon(id, "lease lost")? {
                    tracing::warn!(job_id = id, state = ?state, "lease lost: another host has the job; stopped and fenced out");
                }
            }
        }
        if now >= self.next_rescue {
            self.next_rescue = now + secs(self.config.store.rescue_secs);
            if self.store.rescue()? > 0 {
                self.work_maybe = true;
            }
        }
        Ok(())
    }

    /// The watched folders' side of one turn: walk the roots that are due, then look again
    /// at the scans that were not ready.
    fn tend_roots(&mut self) -> Result<(), ServiceError> {
        let now = Instant::now();
        for i in 0..self.roots.len() {
            if self.roots[i].overflow.swap(false, Ordering::SeqCst) {
                tracing::warn!(root = %self.roots[i].path.display(), "event queue overflow or watcher error: full rescan");
                self.roots[i].walk_due = now;
            }
            if self.roots[i].walk_due <= now {
                self.walk_root(i)?;
            }
        }
        let events = self.tracker.recheck_pending(now, now_ms());
        self.handle_events(events)
    }

    /// Sets up (or re-creates) the file watch of a root that exists; falls back to
    /// polling when the watch cannot be set (e.g. inotify limits).
    fn ensure_watch(&mut self, i: usize) {
        let identity = root_identity(&self.roots[i].path);
        let r = &mut self.roots[i];
        if identity != r.identity {
            if r.identity.is_some() {
                tracing::warn!(root = %r.path.display(), "watched folder replaced, remounted or gone");
                self.tracker.forget_root(i);
            }
            r.watcher = None;
            r.identity = identity;
        }
        if r.identity.is_none() {
            tracing::warn!(root = %r.path.display(), "watched folder is unavailable; will retry");
            return;
        }
        if r.poll.is_some() || r.watcher.is_some() {
            return;
        }
        use notify::Watcher;
        let tx = self.hints_tx.clone();
        let overflow = r.overflow.clone();
        let handler = move |event: notify::Result<notify::Event>| {
            use notify::event::{AccessKind, AccessMode, EventKind};
            let rescan = match &event {
                // Our own reads (walking, hashing) raise open/access/close-nowrite events;
                // they change nothing and must not schedule another walk (a feedback loop).
                Ok(e)
                    if matches!(e.kind, EventKind::Access(a) if a != AccessKind::Close(AccessMode::Write))
                        && !e.need_rescan() =>
                {
                    return;
                }
                Ok(e) => e.need_rescan(),
                Err(_) => true,
            };
            // Every event is only a hint that something in the root changed.
            // A full channel is fine: the hints in it already guarantee a later walk.
            if rescan {
                overflow.store(true, Ordering::SeqCst);
            }
            let _ = tx.try_send(i);
        };
        let created = notify::recommended_watcher(handler).and_then(|mut w| {
            w.watch(&r.path, notify::RecursiveMode::Recursive)?;
            Ok(w)
        });
        match created {
            Ok(w) => r.watcher = Some(w),
            Err(e) => {
                let hint = if matches!(e.kind, notify::ErrorKind::MaxFilesWatch)
                    || e.to_string().contains("No space left")
                {
                    " (inotify limit reached: raise fs.inotify.max_user_watches, see systemd/60-scanmill.conf)"
                } else {
                    ""
                };
                tracing::error!(root = %r.path.display(), "cannot watch: {e}{hint}; polling every 10 s instead");
                r.poll = Some(Duration::from_secs(10));
            }
        }
    }

    fn walk_root(&mut self, i: usize) -> Result<(), ServiceError> {
        self.ensure_watch(i);
        let interval = self.roots[i].poll.unwrap_or(secs(self.config.rescan_secs));
        self.roots[i].walk_due = Instant::now() + interval;
        if self.roots[i].identity.is_none() {
            return Ok(());
        }
        let events = self.tracker.reconcile_root(i, Instant::now(), now_ms());
        self.handle_events(events)
    }

    fn handle_events(&mut self, events: Vec<Event>) -> Result<(), ServiceError> {
        let mut events = events.into_iter();
        while let Some(e) = events.next() {
            if let Err(error) = self.handle_event(e.clone()) {
                // Nothing of a ready set may be lost: it and every set after it are
                // pending again and handed over on a later turn.
                for e in std::iter::once(e).chain(events) {
                    if let Event::Ready(set) = e {
                        self.tracker.hand_back(&set.primary);
                    }
                }
                return Err(error);
            }
        }
        Ok(())
    }

    fn handle_event(&mut self, e: Event) -> Result<(), ServiceError> {
        match e {
            Event::Ready(set) => {
                let r = &self.roots[set.root_index];
                let root = r.path.to_string_lossy().into_owned();
                let job = NewJob {
                    order: JobOrder {
                        job_key: job_key(&set.set_hash, &r.recipe_hash),
                        set_hash: set.set_hash.clone(),
                        root: root.clone(),
                        rel_path: set.rel_path.clone(),
                        output_root: r.output.to_string_lossy().into_owned(),
                        recipe_path: r.recipe_path.to_string_lossy().into_owned(),
                        recipe_hash: r.recipe_hash.clone(),
                    },
                    recipe_json: r.recipe.resolved_json().to_string(),
                    config_hash: self.config_hash.clone(),
                    max_attempts: self.config.max_attempts,
                    inputs: set.inputs.clone(),
                };
                self.work_maybe = true;
                match self.store.enqueue(&job)? {
                    Enqueued::New(id) => {
                        tracing::info!(job_id = id, input = %set.rel_path, "queued")
                    }
                    Enqueued::Revived(id) => {
                        tracing::info!(job_id = id, input = %set.rel_path, "input is back: queued again")
                    }
                    Enqueued::Existing { id, state } => tracing::info!(
                        job_id = id,
                        input = %set.rel_path,
                        state,
                        "same content and recipe as an existing job: not processed again"
                    ),
                }
                let members = set
                    .inputs
                    .iter()
                    .map(|m| (m.rel_path.clone(), m.size, m.mtime_ns, m.ino))
                    .collect();
                self.tracker.remember(&root, &set.rel_path, members);
            }
            Event::Waiting {
                root_index,
                rel_path,
                reason,
                first_seen_ms,
            } => {
                let root = self.roots[root_index].path.to_string_lossy().into_owned();
                self.store
                    .set_waiting(&root, &rel_path, &reason, first_seen_ms)?;
            }
            Event::NotWaiting {
                root_index,
                rel_path,
            } => {
                let root = self.roots[root_index].path.to_string_lossy().into_owned();
                self.store.clear_waiting(&root, &rel_path)?;
            }
        }
        Ok(())
    }

    /// Free-disk floor on every output file system; claiming pauses below it.
    fn disk_ok(&mut self) -> bool {
        let floor = self.config.min_free_disk_mb.saturating_mul(1 << 20);
        let low = self.roots.iter().find_map(|r| {
            free_bytes(&r.output).filter(|&f| f < floor).map(|f| {
                format!(
                    "paused: low disk on {} ({} MiB free)",
                    r.output.display(),
                    f >> 20
                )
            })
        });
        if low != self.paused {
            match &low {
                Some(m) => tracing::error!("{m}"),
                None => tracing::info!("disk space back above the floor: resuming"),
            }
            self.paused = low;
        }
        self.paused.is_none()
    }

    fn claim_jobs(&mut self) -> Result<(), ServiceError> {
        while !self.stopping && self.running.len() < self.config.workers && self.disk_ok() {
            let Some(job) = self.store.claim(&self.owner)? else {
                break;
            };
            let recipe_source = self
                .roots
                .iter()
                .find(|r| r.recipe_path.to_string_lossy() == job.order.recipe_path)
                .map(|r| (r.recipe.clone(), r.recipe_path.clone()));
            let (recipe, recipe_path) = match recipe_source {
                Some(x) => x,
                None => match load_recipe(Path::new(&job.order.recipe_path)) {
                    Ok(r) => (Arc::new(r), PathBuf::from(&job.order.recipe_path)),
                    Err(e) => {
                        self.fail_unstarted(&job, FailureKind::Recipe, e.to_string(), false)?;
                        continue;
                    }
                },
            };
            let gate = Arc::new(PublishGate::default());
            let spec = JobSpec {
                job: job.clone(),
                recipe,
                recipe_path,
                config_hash: self.config_hash.clone(),
                owner: self.owner.clone(),
                max_input_bytes: self.config.max_input_bytes,
                limits: self.worker_limits(&job),
                input_limits: self.config.limits.clone(),
                gate: gate.clone(),
                fence: self.fence.clone(),
            };
            let tx = self.results_tx.clone();
            let id = job.id;
            tracing::info!(job_id = id, input = %job.order.rel_path, attempt = job.attempt, "running");
            let spawned = std::thread::Builder::new()
                .name(format!("scanmill-job-{id}"))
                .spawn(move || {
                    let result = worker::run(spec);
                    let _ = tx.send((id, result));
                });
            if let Err(e) = spawned {
                self.fail_unstarted(&job, FailureKind::Spawn, e.to_string(), true)?;
                break;
            }
            self.running.insert(
                id,
                Running {
                    job,
                    gate,
                    deadline: Instant::now()
                        + secs(self.config.job_timeout_secs)
                        + SUPERVISOR_GRACE,
                },
            );
        }
        Ok(())
    }

    /// The limits of one job's worker process.
    fn worker_limits(&self, job: &ClaimedJob) -> WorkerLimits {
        let members = job.inputs.iter().map(|m| {
            (
                m.size,
                m.rel_path.as_bytes().to_ascii_lowercase().ends_with(b".gz"),
            )
        });
        WorkerLimits {
            memory_bytes: self.config.job_memory_bytes_for(members),
            cpu_secs: self.config.job_cpu_secs(),
            wall: secs(self.config.job_timeout_secs),
        }
    }

    /// Stops running job `id` and records its attempt as interrupted for `reason`, unless
    /// it is already publishing (then it is let finish): the state the job ends in, or
    /// `None` when it was let finish.
    fn abandon(&mut self, id: i64, reason: &str) -> Result<Option<FinalState>, ServiceError> {
        if !self.running[&id].gate.abandon() {
            return Ok(None);
        }
        let r = self.running.remove(&id).expect("present");
        let f = Finish::Interrupted {
            reason: reason.into(),
        };
        Ok(Some(self.store.finish(&r.job, &f, self.retry(), 0.0)?))
    }

    /// Records that claimed `job` failed before its worker ran.
    fn fail_unstarted(
        &mut self,
        job: &ClaimedJob,
        kind: FailureKind,
        message: String,
        transient: bool,
    ) -> Result<FinalState, ServiceError> {
        let f = Finish::Failed {
            kind,
            message,
            transient,
        };
        Ok(self.store.finish(job, &f, self.retry(), 0.0)?)
    }

    fn retry(&self) -> RetryPolicy {
        RetryPolicy {
            base_secs: self.config.retry_base_secs,
            max_secs: self.config.retry_max_secs,
        }
    }

    /// Records a job's end. While the database is busy (another process holds its write
    /// lock) the result is kept and recorded on a later turn of the loop: never lost.
    fn job_finished(&mut self, id: i64, result: JobResult) -> Result<(), ServiceError> {
        let Some(running) = self.running.get(&id) else {
            // An abandoned job's thread came back: already recorded.
            return Ok(());
        };
        let (finish, wall_ms) = match &result {
            JobResult::Finished { finish, wall_ms } => (finish.clone(), *wall_ms),
            JobResult::Abandoned => (
                Finish::Interrupted {
                    reason: "abandoned".into(),
                },
                0.0,
            ),
        };
        let state = match self
            .store
            .finish(&running.job, &finish, self.retry(), wall_ms)
        {
            Ok(state) => state,
            Err(e) if e.is_busy() => {
                self.unrecorded.push((id, result));
                return Err(e.into());
            }
            Err(e) => return Err(e.into()),
        };
        self.running.remove(&id);
        self.work_maybe = true;
        match (&finish, state) {
            (_, FinalState::Superseded) => {
                tracing::warn!(
                    job_id = id,
                    "fenced out: its lease had expired and another host took the job over; nothing published"
                )
            }
            (Finish::Done(done), _) => {
                tracing::info!(job_id = id, output = %done.output_dir, wall_ms, "done")
            }
            (Finish::Failed { kind, message, .. }, s) => {
                tracing::warn!(job_id = id, kind = %kind, state = ?s, "failed: {}", crate::text::bounded(message, crate::text::MAX_SHOWN))
            }
            (Finish::Interrupted { .. }, _) => {}
        }
        Ok(())
    }

    /// Results that could not be recorded while the database was busy, oldest first.
    fn record_unrecorded(&mut self) -> Result<(), ServiceError> {
        let mut pending = std::mem::take(&mut self.unrecorded).into_iter();
        while let Some((id, result)) = pending.next() {
            if let Err(e) = self.job_finished(id, result) {
                self.unrecorded.extend(pending);
                return Err(e);
            }
        }
        Ok(())
    }

    /// After an error in the loop: a busy database is waited out (with a growing pause,
    /// the watchdog fed meanwhile); anything else ends the service.
    async fn survive(&mut self, error: ServiceError) -> Result<(), ServiceError> {
        if !matches!(&error, ServiceError::Store(e) if e.is_busy()) {
            return Err(error);
        }
        self.busy_pause = (self.busy_pause * 2).clamp(BUSY_PAUSE_MIN, BUSY_PAUSE_MAX);
        let why = match &error {
            ServiceError::Store(StoreError::Postgres { .. }) => {
                "the database server is out of reach"
            }
            _ => "another process holds the database's write lock",
        };
        tracing::warn!(
            "{error}: {why}; trying again in {:.1} s",
            self.busy_pause.as_secs_f64()
        );
        self.notifier.watchdog_ping();
        tokio::time::sleep(self.busy_pause).await;
        self.notifier.watchdog_ping();
        Ok(())
    }

    fn check_timeouts(&mut self) -> Result<(), ServiceError> {
        let now = Instant::now();
        let late: Vec<i64> = self
            .running
            .iter()
            .filter(|(_, r)| r.deadline <= now)
            .map(|(id, _)| *id)
            .collect();
        for id in late {
            let r = &self.running[&id];
            if !r.gate.abandon() {
                continue; // publishing right now: its result comes in a moment
            }
            let r = &self.running[&id];
            self.work_maybe = true;
            let f = Finish::Failed {
                kind: FailureKind::Timeout,
                message: format!(
                    "its supervisor did not finish within job_timeout_secs = {} plus {} s (stuck writing or publishing?); abandoned, it cannot publish",
                    self.config.job_timeout_secs,
                    SUPERVISOR_GRACE.as_secs()
                ),
                transient: true,
            };
            let state =
                self.store
                    .finish(&r.job, &f, self.retry(), self.config.job_timeout_secs * 1e3)?;
            self.running.remove(&id);
            tracing::error!(job_id = id, state = ?state, "job timed out");
        }
        Ok(())
    }

    fn daemon_state(&self) -> crate::web::DaemonState {
        use crate::web::DaemonState;
        if self.stopping {
            DaemonState::Draining
        } else if let Some(p) = &self.paused {
            DaemonState::Paused(p.clone())
        } else if self.counts.1 > 0 {
            DaemonState::Working
        } else {
            DaemonState::Idle
        }
    }

    fn status_line(&self) -> Result<String, ServiceError> {
        let (queued, running) = self.counts;
        Ok(format!(
            "{}; queue={queued}; running={running}; waiting={}",
            self.daemon_state().label(),
            self.tracker.pending()
        ))
    }

    fn update_status(&mut self) -> Result<(), ServiceError> {
        let line = self.status_line()?;
        self.live
            .set(self.daemon_state(), self.running.len() as i64);
        if line != self.last_status {
            self.notifier.status(&line);
            tracing::debug!("{line}");
            self.last_status = line;
        }
        Ok(())
    }

    async fn shutdown(
        mut self,
        results_rx: &mut mpsc::UnboundedReceiver<(i64, JobResult)>,
        sigterm: &mut tokio::signal::unix::Signal,
        sigint: &mut tokio::signal::unix::Signal,
    ) -> Result<(), ServiceError> {
        self.stopping = true;
        self.live
            .set(self.daemon_state(), self.running.len() as i64);
        self.notifier.stopping();
        for r in &mut self.roots {
            r.watcher = None;
        }
        let deadline = Instant::now() + secs(self.config.drain_timeout_secs);
        if !self.running.is_empty() {
            tracing::info!(running = self.running.len(), "waiting for running jobs");
        }
        while !self.running.is_empty() {
            tokio::select! {
                Some((id, result)) = results_rx.recv() => self.job_finished(id, result)?,
                _ = tokio::time::sleep_until(deadline.into()) => break,
                _ = sigterm.recv() => { tracing::warn!("second signal: not waiting any longer"); break; }
                _ = sigint.recv() => { tracing::warn!("second signal: not waiting any longer"); break; }
            }
            self.notifier.watchdog_ping();
        }
        // Jobs still running go back to the queue; one that is publishing right now is
        // let finish (a rename and an fsync).
        let ids: Vec<i64> = self.running.keys().copied().collect();
        for id in ids {
            if let Some(state) = self.abandon(id, "daemon stopped before the job finished")? {
                debug_assert_eq!(state, FinalState::Requeued);
                tracing::warn!(
                    job_id = id,
                    "not finished before the stop deadline: queued again"
                );
            }
        }
        let publishing_deadline = Instant::now() + Duration::from_secs(30);
        while !self.running.is_empty() {
            tokio::select! {
                Some((id, result)) = results_rx.recv() => self.job_finished(id, result)?,
                _ = tokio::time::sleep_until(publishing_deadline.into()) => break,
            }
        }
        self.store.checkpoint();
        tracing::info!("stopped");
        Ok(())
    }
}
