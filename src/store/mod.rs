//! The job queue and audit log in SQLite.
//!
//! Rules (docs/service.md, "Audit and operations"): WAL, `synchronous=FULL` (an audit record that was committed
//! survives a power cut), `busy_timeout`, and every transaction that writes is `BEGIN
//! IMMEDIATE`, so that a reader turned writer can never fail on a stale snapshot. The
//! daemon owns one connection; the command line opens its own, short-lived ones.

mod attempt;
pub mod backend;
mod failure;
pub mod pg;
pub mod query;
pub mod relpath;
pub mod schema;

pub use attempt::backoff_ms;
pub use backend::{Queue, StoreConfig};
pub use failure::FailureKind;
pub use relpath::RelPath;

use attempt::{AttemptEnd, AttemptRecord, AttemptWriter, FailurePlan, record_end};
use rusqlite::{Connection, OpenFlags, OptionalExtension, TransactionBehavior, params};
use std::path::{Path, PathBuf};
use std::time::Duration;

pub use rusqlite;

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("{path}: {source}")]
    Sqlite {
        path: PathBuf,
        #[source]
        source: rusqlite::Error,
    },
    #[error(
        "{path}: database schema version {found} is newer than this scanmill knows ({known}); \
         refusing to run an older binary on it"
    )]
    TooNew {
        path: PathBuf,
        found: u32,
        known: u32,
    },
    #[error("{path}: no database here (has the daemon run with this configuration?)")]
    Missing { path: PathBuf },
    #[error("{path}: integrity check failed: {message}")]
    Integrity { path: PathBuf, message: String },
    #[error("{target}: {}", pg::detail(source))]
    Postgres {
        target: String,
        #[source]
        source: postgres::Error,
    },
    #[error("{target}: {message}")]
    Data { target: String, message: String },
    #[error(transparent)]
    Conn(#[from] pg::ConnInfoError),
    #[error("job {0} not found")]
    NoSuchJob(i64),
    #[error("job {id} is {state}; {message}")]
    WrongState {
        id: i64,
        state: String,
        message: String,
    },
}

pub type Result<T> = std::result::Result<T, StoreError>;

impl StoreError {
    /// Another connection holds the database's write lock (past `busy_timeout`), or the
    /// PostgreSQL server cannot be reached right now (restarting, network): the operation
    /// can be tried again later, nothing is wrong with the database.
    pub fn is_busy(&self) -> bool {
        if let StoreError::Postgres { source, .. } = self {
            return pg::is_retryable(source);
        }
        matches!(
            self,
            StoreError::Sqlite {
                source: rusqlite::Error::SqliteFailure(e, _),
                ..
            } if matches!(
                e.code,
                rusqlite::ErrorCode::DatabaseBusy | rusqlite::ErrorCode::DatabaseLocked
            )
        )
    }
}

/// Whether job `id`, found in `state` (`None`: no such job), may be put back in the queue
/// by hand, on either backend: any state but running, whose attempt still holds the job.
/// Gives the state the job leaves, for the caller to report.
fn requeueable(id: i64, state: Option<String>) -> Result<String> {
    let state = state.ok_or(StoreError::NoSuchJob(id))?;
    if state == "running" {
        return Err(StoreError::WrongState {
            id,
            state,
            message: "wait for it to finish".into(),
        });
    }
    Ok(state)
}

/// Unix time in milliseconds.
pub fn now_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_millis() as i64)
        .unwrap_or(0)
}

/// What a file is to its scan set (stored as the documented names in `job_input.role`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum InputRole {
    /// The mesh file the set is named after (OBJ, PLY, STL, glTF, GLB).
    Mesh,
    /// A material library an OBJ names.
    Mtl,
    /// An image an MTL or a `.gltf` names.
    Texture,
    /// A `.gltf`'s external buffer (vertex and index data).
    Buffer,
}

impl InputRole {
    pub const ALL: [InputRole; 4] = [
        InputRole::Mesh,
        InputRole::Mtl,
        InputRole::Texture,
        InputRole::Buffer,
    ];

    /// The stored and shown name; part of a set's content hash, so never renamed.
    pub fn as_str(self) -> &'static str {
        match self {
            InputRole::Mesh => "mesh",
            InputRole::Mtl => "mtl",
            InputRole::Texture => "texture",
            InputRole::Buffer => "buffer",
        }
    }

    pub fn from_name(name: &str) -> Option<InputRole> {
        InputRole::ALL.into_iter().find(|r| r.as_str() == name)
    }
}

/// One file of a job's input set.
#[derive(Debug, Clone, PartialEq)]
pub struct InputMember {
    /// Relative to the job's root.
    pub rel_path: RelPath,
    pub role: InputRole,
    pub size: u64,
    pub mtime_ns: i64,
    pub ino: u64,
    pub sha256: String,
}

/// What a job is asked to do, the same when it is queued and when it is claimed: the scan
/// (its input set's hash, its watched folder and path there), the recipe, where the result
/// goes, and the key these make.
#[derive(Debug, Clone)]
pub struct JobOrder {
    pub job_key: String,
    pub set_hash: String,
    pub root: String,
    pub rel_path: RelPath,
    pub output_root: String,
    pub recipe_path: String,
    pub recipe_hash: String,
}

/// What the reconciler hands the store for a ready scan.
#[derive(Debug, Clone)]
pub struct NewJob {
    pub order: JobOrder,
    pub recipe_json: String,
    pub config_hash: String,
    pub max_attempts: u32,
    pub inputs: Vec<InputMember>,
}

#[derive(Debug, Clone, PartialEq)]
pub enum Enqueued {
    /// A new job.
    New(i64),
    /// The same content and recipe already has a job (in this state).
    Existing { id: i64, state: String },
    /// An existing job that had failed because its input vanished or changed was queued
    /// again, since the input is back.
    Revived(i64),
}

/// A job claimed for running.
#[derive(Debug, Clone)]
pub struct ClaimedJob {
    pub id: i64,
    pub order: JobOrder,
    pub generation: i64,
    /// Counted attempt number, from 1.
    pub attempt: u32,
    pub max_attempts: u32,
    pub attempt_id: i64,
    pub inputs: Vec<InputMember>,
}

/// How an attempt ended, as the worker reports it.
#[derive(Debug, Clone)]
pub enum Finish {
    Done(JobDone),
    /// Failed; retried later if `transient` and attempts remain.
    Failed {
        kind: FailureKind,
        message: String,
        transient: bool,
    },
    /// The run was stopped (shutdown, crash): back to queued, not counted as an attempt.
    Interrupted {
        reason: String,
    },
}

/// A job done: what its row, its published files and its step timings record.
#[derive(Debug, Clone)]
pub struct JobDone {
    pub output_dir: String,
    /// The preview picture, if one was drawn.
    pub preview: Option<String>,
    pub outputs: Vec<OutputFile>,
    pub report_json: String,
    pub counts: MeshSizes,
    pub process_ms: f64,
    pub steps: Vec<StepRow>,
}

/// A published output file, as `job_output` records it.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputFile {
    pub path: String,
    pub bytes: u64,
    pub sha256: String,
}

/// The mesh's size before and after processing, as the job row records it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MeshSizes {
    pub in_vertices: i64,
    pub in_faces: i64,
    pub out_vertices: i64,
    pub out_faces: i64,
}

/// How long a job that failed transiently waits before its next attempt: `base_secs`
/// doubled after each attempt, at most `max_secs`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RetryPolicy {
    pub base_secs: f64,
    pub max_secs: f64,
}

#[derive(Debug, Clone)]
pub struct StepRow {
    pub kind: String,
    pub wall_ms: f64,
    pub vertices_before: i64,
    pub vertices_after: i64,
    pub faces_before: i64,
    pub faces_after: i64,
    pub figures_json: String,
}

/// The state a job ends in after [`Store::finish`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FinalState {
    Done,
    RetryLater,
    Failed,
    Quarantined,
    Requeued,
    /// Shared queue: the attempt had lost its job to another; recorded `superseded`.
    Superseded,
}

/// Identity of this daemon run, stamped on every attempt.
#[derive(Debug, Clone)]
pub struct Owner {
    pub id: String,
    pub host: String,
    pub app_version: String,
}

impl Owner {
    pub fn current() -> Owner {
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .map(|s| s.trim().to_string())
            .ok()
            .filter(|s| !s.is_empty())
            .or_else(|| std::env::var("HOSTNAME").ok())
            .unwrap_or_else(|| "unknown".into());
        // systemd gives every start its own INVOCATION_ID; otherwise pid + start time.
        let id = std::env::var("INVOCATION_ID")
            .ok()
            .filter(|s| !s.is_empty())
            .unwrap_or_else(|| format!("pid{}-{}", std::process::id(), now_ms()));
        Owner {
            id,
            host,
            app_version: env!("CARGO_PKG_VERSION").to_string(),
        }
    }
}

/// Longest failure message recorded: reasons are one line; an input that makes one longer
/// (a file name, a worker's last words) must not fill the database.
pub(crate) const MAX_ERROR_BYTES: usize = 4096;

/// `text` cut to at most `max` bytes at a character boundary, marked `…` when cut.
pub(crate) fn cut(text: &str, max: usize) -> std::borrow::Cow<'_, str> {
    if text.len() <= max {
        return text.into();
    }
    let mut end = max;
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}…", &text[..end]).into()
}

pub struct Store {
    conn: Connection,
    path: PathBuf,
}

/// Turns a SQLite error into one that names the database file `path`.
fn sqlite_error(path: &Path) -> impl Fn(rusqlite::Error) -> StoreError + Copy + '_ {
    move |source| StoreError::Sqlite {
        path: path.to_path_buf(),
        source,
    }
}

impl Store {
    fn err(&self, source: rusqlite::Error) -> StoreError {
        sqlite_error(&self.path)(source)
    }

    /// Opens (creating if needed) and migrates the database: the daemon's connection.
    pub fn open(path: &Path) -> Result<Store> {
        let sq = sqlite_error(path);
        let conn = Connection::open(path).map_err(sq)?;
        // journal_mode persists in the file; set outside any migration.
        conn.pragma_update(None, "journal_mode", "WAL")
            .map_err(sq)?;
        let mut store = Store::configure(conn, path)?;
        store.migrate()?;
        Ok(store)
    }

    /// Opens an existing database for the command line (never creates one). `write`
    /// allows `requeue`; otherwise the connection is query-only.
    pub fn open_existing(path: &Path, write: bool) -> Result<Store> {
        if !path.is_file() {
            return Err(StoreError::Missing {
                path: path.to_path_buf(),
            });
        }
        let flags = if write {
            OpenFlags::SQLITE_OPEN_READ_WRITE
        } else {
            OpenFlags::SQLITE_OPEN_READ_ONLY
        } | OpenFlags::SQLITE_OPEN_NO_MUTEX
            | OpenFlags::SQLITE_OPEN_URI;
        let conn =
            Connection::open_with_flags(path, flags).map_err(|source| StoreError::Sqlite {
                path: path.to_path_buf(),
                source,
            })?;
        let store = Store::configure(conn, path)?;
        if !write {
            store
                .conn
                .pragma_update(None, "query_only", "ON")
                .map_err(|e| store.err(e))?;
        }
        let version = store.user_version()?;
        if version > schema::LATEST {
            return Err(StoreError::TooNew {
                path: path.to_path_buf(),
                found: version,
                known: schema::LATEST,
            });
        }
        Ok(store)
    }

    fn configure(conn: Connection, path: &Path) -> Result<Store> {
        let store = Store {
            conn,
            path: path.to_path_buf(),
        };
        store
            .conn
            .busy_timeout(Duration::from_secs(10))
            .map_err(|e| store.err(e))?;
        store
            .conn
            .pragma_update(None, "foreign_keys", "ON")
            .map_err(|e| store.err(e))?;
        store
            .conn
            .pragma_update(None, "synchronous", "FULL")
            .map_err(|e| store.err(e))?;
        Ok(store)
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn connection(&self) -> &Connection {
        &self.conn
    }

    fn user_version(&self) -> Result<u32> {
        self.conn
            .query_row("PRAGMA user_version", [], |r| r.get::<_, u32>(0))
            .map_err(|e| self.err(e))
    }

    /// Applies every migration newer than the file's `user_version`, each in its own
    /// IMMEDIATE transaction. Refuses a database newer than this binary.
    pub fn migrate(&mut self) -> Result<u32> {
        let current = self.user_version()?;
        if current > schema::LATEST {
            return Err(StoreError::TooNew {
                path: self.path.clone(),
                found: current,
                known: schema::LATEST,
            });
        }
        for version in current + 1..=schema::LATEST {
            let path = self.path.clone();
            let sq = sqlite_error(&path);
            let tx = self
                .conn
                .transaction_with_behavior(TransactionBehavior::Immediate)
                .map_err(sq)?;
            tx.execute_batch(schema::MIGRATIONS[version as usize - 1])
                .map_err(sq)?;
            tx.execute(
                "INSERT INTO schema_migrations(version, applied_at, app_version) VALUES (?1, ?2, ?3)",
                params![version, now_ms(), env!("CARGO_PKG_VERSION")],
            )
            .map_err(sq)?;
            tx.pragma_update(None, "user_version", version)
                .map_err(sq)?;
            tx.commit().map_err(sq)?;
            tracing::info!(version, "database schema migrated");
        }
        Ok(schema::LATEST)
    }

    fn immediate(&mut self) -> Result<rusqlite::Transaction<'_>> {
        let path = self.path.clone();
        self.conn
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(|source| StoreError::Sqlite { path, source })
    }

    /// Records a ready scan. The job key is UNIQUE, so the same content with the same
    /// recipe never makes a second job, whatever its path.
    pub fn enqueue(&mut self, job: &NewJob) -> Result<Enqueued> {
        let now = now_ms();
        let path = self.path.clone();
        let sq = sqlite_error(&path);
        let tx = self.immediate()?;
        let existing: Option<(i64, String, Option<String>)> = tx
            .query_row(
                "SELECT id, state, error_kind FROM job WHERE job_key = ?1",
                [&job.order.job_key],
                |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)),
            )
            .optional()
            .map_err(sq)?;
        let result = match existing {
            Some((id, state, kind))
                if state == "failed"
                    && kind
                        .as_deref()
                        .and_then(FailureKind::from_name)
                        .is_some_and(FailureKind::is_input_gone) =>
            {
                // The input is back, complete and quiet: point the job at where it is now.
                tx.execute(
                    "UPDATE job SET state='queued', retryable=0, attempts=0, run_after=?2, updated_at=?2,
                        root=?3, rel_path=?4, error_kind=NULL, error=NULL WHERE id=?1",
                    params![id, now, job.order.root, job.order.rel_path],
                )
                .map_err(sq)?;
                tx.execute("DELETE FROM job_input WHERE job_id=?1", [id])
                    .map_err(sq)?;
                insert_inputs(&tx, id, &job.inputs).map_err(sq)?;
                Enqueued::Revived(id)
            }
            Some((id, state, _)) => Enqueued::Existing { id, state },
            None => {
                tx.execute(
                    "INSERT INTO job(job_key, set_hash, root, rel_path, output_root, recipe_path,
                        recipe_hash, recipe_json, config_hash, state, max_attempts, run_after,
                        created_at, updated_at)
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, 'queued', ?10, ?11, ?11, ?11)",
                    params![
                        job.order.job_key,
                        job.order.set_hash,
                        job.order.root,
                        job.order.rel_path,
                        job.order.output_root,
                        job.order.recipe_path,
                        job.order.recipe_hash,
                        job.recipe_json,
                        job.config_hash,
                        job.max_attempts,
                        now
                    ],
                )
                .map_err(sq)?;
                let id = tx.last_insert_rowid();
                insert_inputs(&tx, id, &job.inputs).map_err(sq)?;
                Enqueued::New(id)
            }
        };
        let id = match &result {
            Enqueued::New(id) | Enqueued::Revived(id) | Enqueued::Existing { id, .. } => *id,
        };
        tx.execute(
            "INSERT OR IGNORE INTO sighting(job_id, root, rel_path, seen_at) VALUES (?1, ?2, ?3, ?4)",
            params![id, job.order.root, job.order.rel_path, now],
        )
        .map_err(sq)?;
        tx.execute(
            "DELETE FROM waiting WHERE root=?1 AND rel_path=?2",
            params![job.order.root, job.order.rel_path],
        )
        .map_err(sq)?;
        tx.commit().map_err(sq)?;
        Ok(result)
    }

    /// Claims the next runnable job: queued, or failed-and-retryable whose backoff has
    /// passed. One statement inside an IMMEDIATE transaction, with its attempt row.
    pub fn claim(&mut self, owner: &Owner) -> Result<Option<ClaimedJob>> {
        let now = now_ms();
        let path = self.path.clone();
        let sq = sqlite_error(&path);
        // A cheap read first, so that an idle daemon takes no write lock every second.
        let any: Option<i64> = self
            .conn
            .query_row(
                "SELECT id FROM job WHERE (state='queued' OR (state='failed' AND retryable=1)) AND run_after<=?1 LIMIT 1",
                [now],
                |r| r.get(0),
            )
            .optional()
            .map_err(sq)?;
        if any.is_none() {
            return Ok(None);
        }
        let tx = self.immediate()?;
        let row = tx
            .query_row(
                "UPDATE job SET state='running', attempts=attempts+1, started_at=?1, updated_at=?1,
                    lease_owner=?2, host=?3, app_version=?4
                 WHERE id = (SELECT id FROM job
                             WHERE (state='queued' OR (state='failed' AND retryable=1)) AND run_after<=?1
                             ORDER BY run_after, id LIMIT 1)
                 RETURNING id, job_key, set_hash, root, rel_path, output_root, recipe_path,
                           recipe_hash, generation, attempts, max_attempts",
                params![now, owner.id, owner.host, owner.app_version],
                |r| {
                    Ok(ClaimedJob {
                        id: r.get(0)?,
                        order: JobOrder {
                            job_key: r.get(1)?,
                            set_hash: r.get(2)?,
                            root: r.get(3)?,
                            rel_path: r.get(4)?,
                            output_root: r.get(5)?,
                            recipe_path: r.get(6)?,
                            recipe_hash: r.get(7)?,
                        },
                        generation: r.get(8)?,
                        attempt: r.get(9)?,
                        max_attempts: r.get(10)?,
                        attempt_id: 0,
                        inputs: Vec::new(),
                    })
                },
            )
            .optional()
            .map_err(sq)?;
        let Some(mut job) = row else {
            return Ok(None);
        };
        tx.execute(
            "INSERT INTO attempt(job_id, n, owner, host, app_version, started_at) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
            params![job.id, job.attempt, owner.id, owner.host, owner.app_version, now],
        )
        .map_err(sq)?;
        job.attempt_id = tx.last_insert_rowid();
        job.inputs = load_inputs(&tx, job.id).map_err(sq)?;
        tx.commit().map_err(sq)?;
        Ok(Some(job))
    }

    /// Records how an attempt ended and moves the job on.
    pub fn finish(
        &mut self,
        job: &ClaimedJob,
        outcome: &Finish,
        retry: RetryPolicy,
        wall_ms: f64,
    ) -> Result<FinalState> {
        let path = self.path.clone();
        let sq = sqlite_error(&path);
        let mut tx = self.immediate()?;
        let end = AttemptEnd {
            job,
            now: now_ms(),
            wall_ms,
        };
        let final_state = record_end(&mut tx, &end, outcome, retry).map_err(sq)?;
        tx.commit().map_err(sq)?;
        Ok(final_state)
    }

    /// At start-up: jobs left `running` by a previous daemon process. Their attempt was
    /// counted when it was claimed and stays counted: whatever took the daemon down while
    /// they ran (a crash, the OOM killer, a power cut) may be the file itself, and a file
    /// that does so every time must end quarantined rather than take the service down at
    /// every start. Jobs with attempts left go back to the queue at once.
    pub fn recover_running(&mut self) -> Result<usize> {
        let now = now_ms();
        let path = self.path.clone();
        let sq = sqlite_error(&path);
        let tx = self.immediate()?;
        tx.execute(
            "UPDATE attempt SET finished_at=?1, outcome='interrupted', error_kind=?2,
                error='the daemon stopped while this attempt ran (counted as an attempt)'
             WHERE outcome IS NULL AND job_id IN (SELECT id FROM job WHERE state='running')",
            params![now, FailureKind::DaemonStopped],
        )
        .map_err(sq)?;
        tx.execute(
            "UPDATE job SET state='quarantined', retryable=0, finished_at=?1, updated_at=?1,
                lease_owner=NULL, error_kind=?2,
                error='the daemon stopped while this job ran, on each of its ' || attempts || ' attempts'
             WHERE state='running' AND attempts >= max_attempts",
            params![now, FailureKind::DaemonStopped],
        )
        .map_err(sq)?;
        let n = tx
            .execute(
                "UPDATE job SET state='queued', run_after=?1, updated_at=?1, lease_owner=NULL
                 WHERE state='running'",
                [now],
            )
            .map_err(sq)?;
        tx.commit().map_err(sq)?;
        Ok(n)
    }

    /// Puts a job back in the queue by hand (any state but running), with a fresh attempt
    /// count and a new generation, so that its output is published again (with a suffix
    /// if the earlier one is still there).
    pub fn requeue(&mut self, id: i64) -> Result<String> {
        let now = now_ms();
        let path = self.path.clone();
        let sq = sqlite_error(&path);
        let tx = self.immediate()?;
        let state = tx
            .query_row("SELECT state FROM job WHERE id=?1", [id], |r| r.get(0))
            .optional()
            .map_err(sq)?;
        let state = requeueable(id, state)?;
        tx.execute(
            "UPDATE job SET state='queued', retryable=0, attempts=0, generation=generation+1,
                run_after=?2, updated_at=?2, error_kind=NULL, error=NULL WHERE id=?1",
            params![id, now],
        )
        .map_err(sq)?;
        tx.commit().map_err(sq)?;
        Ok(state)
    }

    /// Records (or refreshes) a scan that waits too long for a member, with the reason.
    pub fn set_waiting(
        &mut self,
        root: &str,
        rel_path: &RelPath,
        reason: &str,
        first_seen: i64,
    ) -> Result<()> {
        let now = now_ms();
        let path = self.path.clone();
        let tx = self.immediate()?;
        tx.execute(
            "INSERT INTO waiting(root, rel_path, reason, first_seen, updated_at) VALUES (?1, ?2, ?3, ?4, ?5)
             ON CONFLICT(root, rel_path) DO UPDATE SET reason=excluded.reason, updated_at=excluded.updated_at",
            params![root, rel_path, reason, first_seen, now],
        )
        .and_then(|_| tx.commit())
        .map_err(|source| StoreError::Sqlite { path, source })
    }

    /// Forgets a waiting scan (it became a job, or it is gone).
    pub fn clear_waiting(&mut self, root: &str, rel_path: &RelPath) -> Result<()> {
        let path = self.path.clone();
        let tx = self.immediate()?;
        tx.execute(
            "DELETE FROM waiting WHERE root=?1 AND rel_path=?2",
            params![root, rel_path],
        )
        .and_then(|_| tx.commit())
        .map_err(|source| StoreError::Sqlite { path, source })
    }

    /// Queue depth and running count, for STATUS.
    pub fn counts(&self) -> Result<(i64, i64)> {
        self.conn
            .query_row(
                "SELECT count(*) FILTER (WHERE state='queued' OR (state='failed' AND retryable=1)),
                        count(*) FILTER (WHERE state='running') FROM job",
                [],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .map_err(|e| self.err(e))
    }

    /// Online backup into `dest` (the daemon may keep writing meanwhile), then an
    /// integrity check of the copy.
    pub fn backup(&self, dest: &Path) -> Result<()> {
        let sq = sqlite_error(dest);
        self.conn
            .backup(rusqlite::MAIN_DB, dest, None)
            .map_err(sq)?;
        let copy = Connection::open(dest).map_err(sq)?;
        let check: String = copy
            .query_row("PRAGMA integrity_check", [], |r| r.get(0))
            .map_err(sq)?;
        if check != "ok" {
            return Err(StoreError::Integrity {
                path: dest.to_path_buf(),
                message: check,
            });
        }
        Ok(())
    }

    /// Folds the WAL back into the database (at shutdown).
    pub fn checkpoint(&self) {
        if let Err(e) = self.conn.execute_batch("PRAGMA wal_checkpoint(TRUNCATE)") {
            tracing::warn!("wal checkpoint: {e}");
        }
    }
}

fn insert_inputs(
    tx: &rusqlite::Transaction<'_>,
    id: i64,
    inputs: &[InputMember],
) -> rusqlite::Result<()> {
    for m in inputs {
        tx.execute(
            "INSERT INTO job_input(job_id, rel_path, role, size, mtime_ns, ino, sha256) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
            params![id, m.rel_path, m.role.as_str(), m.size as i64, m.mtime_ns, m.ino as i64, m.sha256],
        )?;
    }
    Ok(())
}

fn load_inputs(conn: &Connection, id: i64) -> rusqlite::Result<Vec<InputMember>> {
    let mut stmt = conn.prepare(
        "SELECT rel_path, role, size, mtime_ns, ino, sha256 FROM job_input WHERE job_id=?1 ORDER BY rowid",
    )?;
    let rows = stmt.query_map([id], |r| {
        let role: String = r.get(1)?;
        Ok(InputMember {
            rel_path: r.get(0)?,
            role: InputRole::from_name(&role).ok_or_else(|| {
                rusqlite::Error::FromSqlConversionFailure(
                    1,
                    rusqlite::types::Type::Text,
                    format!("unknown input role {role:?}").into(),
                )
            })?,
            size: r.get::<_, i64>(2)? as u64,
            mtime_ns: r.get(3)?,
            ino: r.get::<_, i64>(4)? as u64,
            sha256: r.get(5)?,
        })
    })?;
    rows.collect()
}

/// The job's published files, replacing any recorded before.
fn insert_outputs(
    tx: &rusqlite::Transaction<'_>,
    job_id: i64,
    outputs: &[OutputFile],
) -> rusqlite::Result<()> {
    tx.execute("DELETE FROM job_output WHERE job_id=?1", [job_id])?;
    for f in outputs {
        tx.execute(
            "INSERT OR REPLACE INTO job_output(job_id, path, bytes, sha256) VALUES (?1, ?2, ?3, ?4)",
            params![job_id, f.path, f.bytes as i64, f.sha256],
        )?;
    }
    Ok(())
}

/// The attempt's step timings, numbered from 1.
fn insert_step_timings(
    tx: &rusqlite::Transaction<'_>,
    attempt_id: i64,
    steps: &[StepRow],
) -> rusqlite::Result<()> {
    for (i, s) in steps.iter().enumerate() {
        tx.execute(
            "INSERT INTO step_timing(attempt_id, idx, kind, wall_ms, vertices_before, vertices_after,
                faces_before, faces_after, figures_json) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)",
            params![
                attempt_id,
                i as i64 + 1,
                s.kind,
                s.wall_ms,
                s.vertices_before,
                s.vertices_after,
                s.faces_before,
                s.faces_after,
                s.figures_json
            ],
        )?;
    }
    Ok(())
}

/// The rows that end an attempt, in SQLite's dialect.
impl AttemptWriter for rusqlite::Transaction<'_> {
    type Error = rusqlite::Error;

    fn job_done(&mut self, end: &AttemptEnd<'_>, done: &JobDone) -> rusqlite::Result<()> {
        self.execute(
            "UPDATE job SET state='done', retryable=0, finished_at=?2, updated_at=?2, lease_owner=NULL,
                output_dir=?3, error_kind=NULL, error=NULL, in_vertices=?4, in_faces=?5,
                out_vertices=?6, out_faces=?7, process_ms=?8, report_json=?9, preview=?10 WHERE id=?1",
            params![
                end.job.id,
                end.now,
                done.output_dir,
                done.counts.in_vertices,
                done.counts.in_faces,
                done.counts.out_vertices,
                done.counts.out_faces,
                done.process_ms,
                done.report_json,
                done.preview
            ],
        )?;
        insert_outputs(self, end.job.id, &done.outputs)?;
        insert_step_timings(self, end.job.attempt_id, &done.steps)
    }

    fn job_failed(
        &mut self,
        end: &AttemptEnd<'_>,
        kind: FailureKind,
        plan: &FailurePlan<'_>,
    ) -> rusqlite::Result<()> {
        self.execute(
            "UPDATE job SET state=?2, retryable=?3, run_after=?4, finished_at=?5, updated_at=?5,
                lease_owner=NULL, error_kind=?6, error=?7 WHERE id=?1",
            params![
                end.job.id,
                plan.state,
                plan.retryable,
                plan.run_after,
                end.now,
                kind,
                plan.message
            ],
        )?;
        Ok(())
    }

    fn job_requeued(&mut self, end: &AttemptEnd<'_>) -> rusqlite::Result<()> {
        self.execute(
            "UPDATE job SET state='queued', attempts=max(attempts-1, 0), run_after=?2, updated_at=?2,
                lease_owner=NULL WHERE id=?1",
            params![end.job.id, end.now],
        )?;
        Ok(())
    }

    fn close_attempt(&mut self, a: &AttemptRecord<'_>) -> rusqlite::Result<()> {
        self.execute(
            "UPDATE attempt SET finished_at=?2, outcome=?3, error_kind=?4, error=?5, wall_ms=?6 WHERE id=?1",
            params![a.attempt_id, a.finished_at, a.outcome, a.kind, a.message, a.wall_ms],
        )?;
        Ok(())
    }
}

#[cfg(test)]
mod tests;

/// A member's recorded signature: (rel_path, size, mtime_ns, ino).
pub type MemberSig = (RelPath, u64, i64, u64);
/// A job's set as recorded: (root, mesh rel_path, members).
pub type KnownSet = (String, RelPath, Vec<MemberSig>);

impl Store {
    /// Every job's input signatures, keyed by (root, mesh rel_path), newest job last, so
    /// that the reconciler need not hash again at start-up what it already recorded.
    pub fn known_inputs(&self) -> Result<Vec<KnownSet>> {
        let err = sqlite_error(&self.path);
        let mut stmt = self
            .conn
            .prepare(
                "SELECT j.id, j.root, j.rel_path, i.rel_path, i.size, i.mtime_ns, i.ino
                 FROM job j JOIN job_input i ON i.job_id = j.id ORDER BY j.id, i.rowid",
            )
            .map_err(err)?;
        let rows = stmt
            .query_map([], |r| {
                Ok((
                    r.get::<_, i64>(0)?,
                    r.get::<_, String>(1)?,
                    r.get::<_, RelPath>(2)?,
                    (
                        r.get::<_, RelPath>(3)?,
                        r.get::<_, i64>(4)? as u64,
                        r.get::<_, i64>(5)?,
                        r.get::<_, i64>(6)? as u64,
                    ),
                ))
            })
            .map_err(err)?;
        let mut out: Vec<KnownSet> = Vec::new();
        let mut last_id = None;
        for row in rows {
            let (id, root, rel, member) = row.map_err(err)?;
            if last_id != Some(id) {
                out.push((root, rel, Vec::new()));
                last_id = Some(id);
            }
            out.last_mut().expect("pushed").2.push(member);
        }
        Ok(out)
    }
}

impl Store {
    /// Changes whenever another connection commits (the CLI's `requeue`); cheap, no I/O.
    pub fn data_version(&self) -> Result<i64> {
        self.conn
            .query_row("PRAGMA data_version", [], |r| r.get(0))
            .map_err(|e| self.err(e))
    }

    /// When the next queued or retryable job becomes runnable (Unix ms), if any.
    pub fn next_run_after(&self) -> Result<Option<i64>> {
        self.conn
            .query_row(
                "SELECT min(run_after) FROM job WHERE state='queued' OR (state='failed' AND retryable=1)",
                [],
                |r| r.get(0),
            )
            .map_err(|e| self.err(e))
    }
}
