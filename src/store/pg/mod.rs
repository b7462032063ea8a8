//! The job queue and audit log on PostgreSQL, shared by several hosts (docs/scale-out.md).
//!
//! The same tables and the same meaning as the SQLite store (`pg::schema`), and the same
//! operations, plus what several hosts on one queue need:
//! - claiming takes the first runnable job `FOR UPDATE SKIP LOCKED`, so hosts never wait on
//!   each other's claims and never take the same job;
//! - a claimed job carries a lease (`lease_until`, in the server's clock, so that hosts'
//!   clocks do not matter) that the daemon's heartbeat renews while the worker runs;
//! - every host rescues jobs whose lease passed: the attempt is recorded `lost` (counted,
//!   like a daemon that died) and the job is queued again, or quarantined when it has used
//!   its attempts;
//! - fencing: the attempt's id is its token (`job.attempt_token`); finishing, and publishing
//!   ([`Fence`]), lock the job row only where the token still matches, in one transaction,
//!   so an attempt that lost its lease can neither mark the job done nor make its output
//!   visible; it is recorded `superseded`.
//!
//! A lost connection (server restart, network) drops the client; the next call connects
//! again, and the service loop waits between tries as it does for a busy SQLite database.

pub mod conninfo;
pub mod copy;
pub mod dashboard;
mod finish;
pub mod query;
pub mod schema;

pub use conninfo::{ConnInfo, ConnInfoError};
pub use finish::{Fence, Fenced};

use super::{
    ClaimedJob, Enqueued, FailureKind, FinalState, Finish, InputMember, InputRole, JobOrder,
    KnownSet, NewJob, Owner, RelPath, Result, RetryPolicy, StoreError, now_ms, requeueable,
};
use postgres::{Client, GenericClient, NoTls};
use std::time::{Duration, Instant};

type DbResult<T> = std::result::Result<T, DbError>;

/// Runs `f` where the synchronous client may block: on this thread, or, inside an async
/// runtime (the daemon's loop), on a scoped thread of its own, since the client drives its
/// own runtime and tokio forbids starting one inside another.
pub(crate) fn off_runtime<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    if tokio::runtime::Handle::try_current().is_err() {
        return f();
    }
    std::thread::scope(|s| {
        s.spawn(f)
            .join()
            .unwrap_or_else(|p| std::panic::resume_unwind(p))
    })
}

impl Drop for PgStore {
    /// Closing the client blocks too.
    fn drop(&mut self) {
        let client = self.client.take();
        off_runtime(move || drop(client));
    }
}

/// The server's clock in Unix ms: leases are set and compared in it alone.
pub(crate) const SERVER_MS: &str = "(extract(epoch from clock_timestamp()) * 1000)::bigint";

pub struct PgStore {
    info: ConnInfo,
    client: Option<Client>,
    lease: Duration,
    /// When the current connection was made: a host rescues nothing during its first
    /// lease after connecting, so that after a server outage the hosts that stayed up
    /// renew their leases before anyone takes their jobs away.
    connected_at: Instant,
    /// Bumped at every call of [`PgStore::data_version`]: other hosts' writes cannot be
    /// seen cheaply, so the loop looks at the queue on every turn (about once a second).
    version: i64,
}

impl PgStore {
    /// Connects and migrates: the daemon's store. A server that cannot be reached is
    /// retried for `patience` (logged), then given up (the unit's restart policy goes on).
    pub fn open(info: ConnInfo, lease: Duration, patience: Duration) -> Result<PgStore> {
        let deadline = Instant::now() + patience;
        let mut pause = Duration::from_millis(500);
        let client = loop {
            match info.config.connect(NoTls) {
                Ok(c) => break c,
                Err(e) if is_retryable(&e) && Instant::now() + pause < deadline => {
                    tracing::warn!(
                        "{}: {e}; trying again in {:.1} s",
                        info.shown,
                        pause.as_secs_f64()
                    );
                    std::thread::sleep(pause);
                    pause = (pause * 2).min(Duration::from_secs(10));
                }
                Err(e) => return Err(pg_err(&info, e)),
            }
        };
        let mut store = PgStore {
            info,
            client: Some(client),
            lease,
            connected_at: Instant::now(),
            version: 0,
        };
        store.migrate()?;
        Ok(store)
    }

    /// Connects for the command line: never creates or migrates the schema.
    pub fn open_existing(info: ConnInfo) -> Result<PgStore> {
        let client = info.config.connect(NoTls).map_err(|e| pg_err(&info, e))?;
        let mut store = PgStore {
            info,
            client: Some(client),
            lease: Duration::from_secs(30),
            connected_at: Instant::now(),
            version: 0,
        };
        let version = store.schema_version()?;
        if version == 0 {
            return Err(StoreError::Missing {
                path: store.info.shown.clone().into(),
            });
        }
        if version > schema::LATEST {
            return Err(StoreError::TooNew {
                path: store.info.shown.clone().into(),
                found: version,
                known: schema::LATEST,
            });
        }
        Ok(store)
    }

    pub fn shown(&self) -> &str {
        &self.info.shown
    }

    pub fn conn_info(&self) -> &ConnInfo {
        &self.info
    }

    pub fn lease(&self) -> Duration {
        self.lease
    }

    /// The client, connected again if the last one was lost (the command line's copy).
    fn client(&mut self) -> Result<&mut Client> {
        if self.client.as_ref().is_none_or(|c| c.is_closed()) {
            self.client = None;
            let c = self
                .info
                .config
                .connect(NoTls)
                .map_err(|e| pg_err(&self.info, e))?;
            self.client = Some(c);
        }
        Ok(self.client.as_mut().expect("connected"))
    }

    /// Runs `f` on the client (connected again first if the last one was lost; dropped
    /// after an error that says the connection is gone), off any async runtime.
    fn run<T: Send>(&mut self, f: impl FnOnce(&mut Client) -> DbResult<T> + Send) -> Result<T> {
        let (info, slot) = (&self.info, &mut self.client);
        let (result, reconnected) = off_runtime(move || {
            let mut reconnected = false;
            if slot.as_ref().is_none_or(|c| c.is_closed()) {
                *slot = None;
                match info.config.connect(NoTls) {
                    Ok(c) => {
                        *slot = Some(c);
                        reconnected = true;
                    }
                    Err(e) => return (Err(DbError::Pg(e)), false),
                }
            }
            let result = f(slot.as_mut().expect("connected"));
            if let Err(DbError::Pg(e)) = &result
                && is_retryable(e)
            {
                *slot = None;
            }
            (result, reconnected)
        });
        if reconnected {
            tracing::info!("{}: connected again", self.info.shown);
            self.connected_at = Instant::now();
        }
        result.map_err(|e| self.fail(e))
    }

    /// Runs `f` in one transaction.
    fn with_tx<T: Send>(
        &mut self,
        f: impl FnOnce(&mut postgres::Transaction<'_>) -> DbResult<T> + Send,
    ) -> Result<T> {
        self.run(|client| {
            let mut tx = client.transaction()?;
            let value = f(&mut tx)?;
            tx.commit()?;
            Ok(value)
        })
    }

    /// Runs a read outside any explicit transaction.
    pub(crate) fn read<T: Send>(
        &mut self,
        f: impl FnOnce(&mut Client) -> DbResult<T> + Send,
    ) -> Result<T> {
        self.run(f)
    }

    fn fail(&self, e: DbError) -> StoreError {
        match e {
            DbError::Pg(e) => pg_err(&self.info, e),
            DbError::Data(message) => StoreError::Data {
                target: self.info.shown.clone(),
                message,
            },
        }
    }

    fn schema_version(&mut self) -> Result<u32> {
        self.read(|c| {
            let exists: bool = c
                .query_one("SELECT to_regclass('schema_migrations') IS NOT NULL", &[])?
                .get(0);
            if !exists {
                return Ok(0);
            }
            let v: Option<i64> = c
                .query_one("SELECT max(version) FROM schema_migrations", &[])?
                .get(0);
            Ok(v.unwrap_or(0) as u32)
        })
    }

    /// Applies every migration newer than the database's, under an advisory lock, each
    /// in its own transaction. Refuses a database newer than this binary.
    pub fn migrate(&mut self) -> Result<u32> {
        let shown = self.info.shown.clone();
        let applied = self.with_tx(|tx| {
            tx.execute("SELECT pg_advisory_xact_lock($1)", &[&schema::MIGRATION_LOCK])?;
            let exists: bool = tx
                .query_one("SELECT to_regclass('schema_migrations') IS NOT NULL", &[])?
                .get(0);
            let current = if exists {
                let v: Option<i64> = tx
                    .query_one("SELECT max(version) FROM schema_migrations", &[])?
                    .get(0);
                v.unwrap_or(0) as u32
            } else {
                0
            };
            if current > schema::LATEST {
                return Ok(Err(current));
            }
            for version in current + 1..=schema::LATEST {
                tx.batch_execute(schema::MIGRATIONS[version as usize - 1])?;
                tx.execute(
                    "INSERT INTO schema_migrations(version, applied_at, app_version) VALUES ($1, $2, $3)",
                    &[&(version as i64), &now_ms(), &env!("CARGO_PKG_VERSION")],
                )?;
                tracing::info!(version, "database schema migrated (PostgreSQL)");
            }
            Ok(Ok(schema::LATEST))
        })?;
        applied.map_err(|found| StoreError::TooNew {
            path: shown.into(),
            found,
            known: schema::LATEST,
        })
    }

    /// Records a ready scan; one scan is one job whichever host saw it first (the job key
    /// is UNIQUE and the insert does nothing on a conflict).
    pub fn enqueue(&mut self, job: &NewJob) -> Result<Enqueued> {
        let now = now_ms();
        let rel = job.order.rel_path.to_stored();
        self.with_tx(|tx| {
            let inserted = tx.query_opt(
                "INSERT INTO job(job_key, set_hash, root, rel_path, output_root, recipe_path,
                    recipe_hash, recipe_json, config_hash, state, max_attempts, run_after,
                    created_at, updated_at)
                 VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, 'queued', $10, $11, $11, $11)
                 ON CONFLICT (job_key) DO NOTHING RETURNING id",
                &[
                    &job.order.job_key,
                    &job.order.set_hash,
                    &job.order.root,
                    &rel,
                    &job.order.output_root,
                    &job.order.recipe_path,
                    &job.order.recipe_hash,
                    &job.recipe_json,
                    &job.config_hash,
                    &(job.max_attempts as i64),
                    &now,
                ],
            )?;
            let result = match inserted {
                Some(row) => {
                    let id: i64 = row.get(0);
                    insert_inputs(tx, id, &job.inputs)?;
                    Enqueued::New(id)
                }
                None => enqueue_existing(tx, job, &rel, now)?,
            };
            let id = match &result {
                Enqueued::New(id) | Enqueued::Revived(id) | Enqueued::Existing { id, .. } => *id,
            };
            tx.execute(
                "INSERT INTO sighting(job_id, root, rel_path, seen_at) VALUES ($1, $2, $3, $4)
                 ON CONFLICT DO NOTHING",
                &[&id, &job.order.root, &rel, &now],
            )?;
            tx.execute(
                "DELETE FROM waiting WHERE root=$1 AND rel_path=$2",
                &[&job.order.root, &rel],
            )?;
            Ok(result)
        })
    }

    /// Claims the next runnable job with a fresh lease and its attempt (whose id is the
    /// fencing token).
    pub fn claim(&mut self, owner: &Owner) -> Result<Option<ClaimedJob>> {
        let now = now_ms();
        let lease_ms = self.lease.as_millis() as i64;
        self.with_tx(|tx| {
            let sql = format!(
                "WITH next AS (
                    SELECT id FROM job
                    WHERE (state='queued' OR (state='failed' AND retryable=1)) AND run_after<=$1
                    ORDER BY run_after, id LIMIT 1 FOR UPDATE SKIP LOCKED)
                 UPDATE job j SET state='running', attempts=j.attempts+1, started_at=$1,
                    updated_at=$1, lease_owner=$2, host=$3, app_version=$4,
                    lease_until={SERVER_MS} + $5
                 FROM next WHERE j.id = next.id
                 RETURNING j.id, j.job_key, j.set_hash, j.root, j.rel_path, j.output_root,
                    j.recipe_path, j.recipe_hash, j.generation, j.attempts, j.max_attempts"
            );
            let Some(r) = tx.query_opt(
                &sql,
                &[&now, &owner.id, &owner.host, &owner.app_version, &lease_ms],
            )?
            else {
                return Ok(None);
            };
            let mut job = ClaimedJob {
                id: r.get(0),
                order: JobOrder {
                    job_key: r.get(1),
                    set_hash: r.get(2),
                    root: r.get(3),
                    rel_path: stored_rel(r.get(4))?,
                    output_root: r.get(5),
                    recipe_path: r.get(6),
                    recipe_hash: r.get(7),
                },
                generation: r.get(8),
                attempt: r.get::<_, i64>(9) as u32,
                max_attempts: r.get::<_, i64>(10) as u32,
                attempt_id: 0,
                inputs: Vec::new(),
            };
            job.attempt_id = tx
                .query_one(
                    "INSERT INTO attempt(job_id, n, owner, host, app_version, started_at)
                     VALUES ($1, $2, $3, $4, $5, $6) RETURNING id",
                    &[
                        &job.id,
                        &(job.attempt as i64),
                        &owner.id,
                        &owner.host,
                        &owner.app_version,
                        &now,
                    ],
                )?
                .get(0);
            tx.execute(
                "UPDATE job SET attempt_token=$2 WHERE id=$1",
                &[&job.id, &job.attempt_id],
            )?;
            job.inputs = load_inputs(tx, job.id)?;
            Ok(Some(job))
        })
    }

    /// Renews the leases of the attempts this daemon runs; returns the tokens that still
    /// hold their job (an attempt missing from it lost its lease and is fenced out).
    pub fn heartbeat(&mut self, tokens: &[i64]) -> Result<Vec<i64>> {
        if tokens.is_empty() {
            return Ok(Vec::new());
        }
        let lease_ms = self.lease.as_millis() as i64;
        let sql = format!(
            "UPDATE job SET lease_until = {SERVER_MS} + $2
             WHERE state='running' AND attempt_token = ANY($1) RETURNING attempt_token"
        );
        let tokens = tokens.to_vec();
        self.with_tx(|tx| {
            let rows = tx.query(&sql, &[&tokens, &lease_ms])?;
            Ok(rows.iter().map(|r| r.get::<_, i64>(0)).collect())
        })
    }

    /// Requeues (or quarantines, attempts used up) every job whose lease passed; their
    /// attempt is recorded `lost`. Does nothing during the first lease after connecting.
    pub fn rescue(&mut self) -> Result<usize> {
        if self.client.is_some() && self.connected_at.elapsed() < self.lease {
            return Ok(0);
        }
        let now = now_ms();
        let sql = format!(
            "SELECT id, attempt_token, attempts, max_attempts FROM job
             WHERE state='running' AND lease_until < {SERVER_MS} FOR UPDATE SKIP LOCKED"
        );
        let kind = FailureKind::LeaseExpired.as_str();
        let n = self.with_tx(|tx| {
            let rows = tx.query(&sql, &[])?;
            for r in &rows {
                let (id, token, attempts, max): (i64, Option<i64>, i64, i64) =
                    (r.get(0), r.get(1), r.get(2), r.get(3));
                tx.execute(
                    "UPDATE attempt SET finished_at=$2, outcome='lost', error_kind=$3,
                        error='its lease expired: the daemon running it stopped, hung or lost the database (counted as an attempt)'
                     WHERE id=$1 AND outcome IS NULL",
                    &[&token, &now, &kind],
                )?;
                if attempts >= max {
                    tx.execute(
                        "UPDATE job SET state='quarantined', retryable=0, finished_at=$2,
                            updated_at=$2, lease_owner=NULL, lease_until=NULL, attempt_token=NULL,
                            error_kind=$3, error='its lease expired on each of its ' || attempts || ' attempts'
                         WHERE id=$1",
                        &[&id, &now, &kind],
                    )?;
                } else {
                    tx.execute(
                        "UPDATE job SET state='queued', run_after=$2, updated_at=$2,
                            lease_owner=NULL, lease_until=NULL, attempt_token=NULL WHERE id=$1",
                        &[&id, &now],
                    )?;
                }
            }
            Ok(rows.len())
        })?;
        if n > 0 {
            tracing::warn!(rescued = n, "jobs whose lease expired are queued again");
        }
        Ok(n)
    }

    /// Records how an attempt ended, if it still holds its job; an attempt that lost its
    /// job is recorded `superseded` and changes nothing else.
    pub fn finish(
        &mut self,
        job: &ClaimedJob,
        outcome: &Finish,
        retry: RetryPolicy,
        wall_ms: f64,
    ) -> Result<FinalState> {
        self.with_tx(|tx| finish::finish_in(tx, job, outcome, retry, wall_ms))
    }

    /// Puts a job back in the queue by hand (any state but running).
    pub fn requeue(&mut self, id: i64) -> Result<String> {
        let now = now_ms();
        self.with_tx(|tx| {
            let state = tx
                .query_opt("SELECT state FROM job WHERE id=$1 FOR UPDATE", &[&id])?
                .map(|row| row.get(0));
            let checked = requeueable(id, state);
            if checked.is_ok() {
                tx.execute(
                    "UPDATE job SET state='queued', retryable=0, attempts=0, generation=generation+1,
                        run_after=$2, updated_at=$2, error_kind=NULL, error=NULL WHERE id=$1",
                    &[&id, &now],
                )?;
            }
            Ok(checked)
        })?
    }

    pub fn set_waiting(
        &mut self,
        root: &str,
        rel_path: &RelPath,
        reason: &str,
        first_seen: i64,
    ) -> Result<()> {
        let (now, rel) = (now_ms(), rel_path.to_stored());
        self.with_tx(|tx| {
            tx.execute(
                "INSERT INTO waiting(root, rel_path, reason, first_seen, updated_at) VALUES ($1, $2, $3, $4, $5)
                 ON CONFLICT (root, rel_path) DO UPDATE SET reason=excluded.reason, updated_at=excluded.updated_at",
                &[&root, &rel, &reason, &first_seen, &now],
            )?;
            Ok(())
        })
    }

    pub fn clear_waiting(&mut self, root: &str, rel_path: &RelPath) -> Result<()> {
        let rel = rel_path.to_stored();
        self.with_tx(|tx| {
            tx.execute(
                "DELETE FROM waiting WHERE root=$1 AND rel_path=$2",
                &[&root, &rel],
            )?;
            Ok(())
        })
    }

    /// Queue depth and running count (all hosts).
    pub fn counts(&mut self) -> Result<(i64, i64)> {
        self.read(|c| {
            let r = c.query_one(
                "SELECT count(*) FILTER (WHERE state='queued' OR (state='failed' AND retryable=1)),
                        count(*) FILTER (WHERE state='running') FROM job",
                &[],
            )?;
            Ok((r.get(0), r.get(1)))
        })
    }

    pub fn next_run_after(&mut self) -> Result<Option<i64>> {
        self.read(|c| {
            Ok(c.query_one(
                "SELECT min(run_after) FROM job WHERE state='queued' OR (state='failed' AND retryable=1)",
                &[],
            )?
            .get(0))
        })
    }

    pub fn data_version(&mut self) -> i64 {
        self.version += 1;
        self.version
    }

    /// Every job's input signatures (see `Store::known_inputs`).
    pub fn known_inputs(&mut self) -> Result<Vec<KnownSet>> {
        let rows = self.read(|c| {
            Ok(c.query(
                "SELECT j.id, j.root, j.rel_path, i.rel_path, i.size, i.mtime_ns, i.ino
                 FROM job j JOIN job_input i ON i.job_id = j.id ORDER BY j.id, i.seq",
                &[],
            )?)
        })?;
        let mut out: Vec<KnownSet> = Vec::new();
        let mut last_id = None;
        for r in rows {
            let id: i64 = r.get(0);
            let member = (
                stored_rel(r.get(3)).map_err(|e| self.fail(e))?,
                r.get::<_, i64>(4) as u64,
                r.get::<_, i64>(5),
                r.get::<_, i64>(6) as u64,
            );
            if last_id != Some(id) {
                let rel = stored_rel(r.get(2)).map_err(|e| self.fail(e))?;
                out.push((r.get(1), rel, Vec::new()));
                last_id = Some(id);
            }
            out.last_mut().expect("pushed").2.push(member);
        }
        Ok(out)
    }

    /// The fence the job threads publish through (their own connection).
    pub fn fence(&self) -> Fence {
        Fence::new(self.info.clone())
    }

    /// Direct access for the SQLite → PostgreSQL copy and the tests.
    pub fn client_mut(&mut self) -> Result<&mut Client> {
        self.client()
    }
}

/// A job key that exists already: revived if it had failed because its input went away
/// (the input is back), else left as it is.
fn enqueue_existing(
    tx: &mut postgres::Transaction<'_>,
    job: &NewJob,
    rel: &str,
    now: i64,
) -> std::result::Result<Enqueued, DbError> {
    let row = tx.query_one(
        "SELECT id, state, error_kind FROM job WHERE job_key=$1 FOR UPDATE",
        &[&job.order.job_key],
    )?;
    let (id, state, kind): (i64, String, Option<String>) = (row.get(0), row.get(1), row.get(2));
    let input_gone = kind
        .as_deref()
        .and_then(FailureKind::from_name)
        .is_some_and(FailureKind::is_input_gone);
    if state != "failed" || !input_gone {
        return Ok(Enqueued::Existing { id, state });
    }
    tx.execute(
        "UPDATE job SET state='queued', retryable=0, attempts=0, run_after=$2, updated_at=$2,
            root=$3, rel_path=$4, error_kind=NULL, error=NULL WHERE id=$1",
        &[&id, &now, &job.order.root, &rel],
    )?;
    tx.execute("DELETE FROM job_input WHERE job_id=$1", &[&id])?;
    insert_inputs(tx, id, &job.inputs)?;
    Ok(Enqueued::Revived(id))
}

fn insert_inputs(
    tx: &mut impl GenericClient,
    id: i64,
    inputs: &[InputMember],
) -> std::result::Result<(), DbError> {
    for m in inputs {
        tx.execute(
            "INSERT INTO job_input(job_id, rel_path, role, size, mtime_ns, ino, sha256)
             VALUES ($1, $2, $3, $4, $5, $6, $7)",
            &[
                &id,
                &m.rel_path.to_stored(),
                &m.role.as_str(),
                &(m.size as i64),
                &m.mtime_ns,
                &(m.ino as i64),
                &m.sha256,
            ],
        )?;
    }
    Ok(())
}

fn load_inputs(
    tx: &mut impl GenericClient,
    id: i64,
) -> std::result::Result<Vec<InputMember>, DbError> {
    let rows = tx.query(
        "SELECT rel_path, role, size, mtime_ns, ino, sha256 FROM job_input WHERE job_id=$1 ORDER BY seq",
        &[&id],
    )?;
    rows.iter()
        .map(|r| {
            let role: String = r.get(1);
            Ok(InputMember {
                rel_path: stored_rel(r.get(0))?,
                role: InputRole::from_name(&role)
                    .ok_or_else(|| conversion(format!("unknown input role {role:?}")))?,
                size: r.get::<_, i64>(2) as u64,
                mtime_ns: r.get(3),
                ino: r.get::<_, i64>(4) as u64,
                sha256: r.get(5),
            })
        })
        .collect()
}

/// A stored `rel_path` read back (see `RelPath`'s storage notes).
fn stored_rel(text: String) -> std::result::Result<RelPath, DbError> {
    RelPath::from_stored(&text).ok_or_else(|| conversion(format!("bad stored path {text:?}")))
}

fn conversion(message: String) -> DbError {
    DbError::Data(message)
}

/// What a transaction's body fails with: the server's error, or a stored value this
/// binary cannot read.
pub(crate) enum DbError {
    Pg(postgres::Error),
    Data(String),
}

impl From<postgres::Error> for DbError {
    fn from(e: postgres::Error) -> DbError {
        DbError::Pg(e)
    }
}

/// Whether `e` may go away by itself: the connection was lost or refused, the server is
/// starting or shutting down, or a transaction lost a race (serialization, deadlock).
pub fn is_retryable(e: &postgres::Error) -> bool {
    use postgres::error::SqlState;
    if e.is_closed() {
        return true;
    }
    match e.code() {
        None => e.as_db_error().is_none(),
        Some(code) => [
            SqlState::ADMIN_SHUTDOWN,
            SqlState::CRASH_SHUTDOWN,
            SqlState::CANNOT_CONNECT_NOW,
            SqlState::T_R_SERIALIZATION_FAILURE,
            SqlState::T_R_DEADLOCK_DETECTED,
            SqlState::CONNECTION_FAILURE,
            SqlState::CONNECTION_EXCEPTION,
            SqlState::TOO_MANY_CONNECTIONS,
        ]
        .contains(code),
    }
}

/// The error with its cause ("error connecting to server: No such file or directory"); the
/// server's own message, detail and hint for a database error.
pub fn detail(e: &postgres::Error) -> String {
    if let Some(db) = e.as_db_error() {
        let mut text = format!("{}: {}", db.severity(), db.message());
        if let Some(d) = db.detail() {
            text.push_str(&format!(" ({d})"));
        }
        return text;
    }
    match std::error::Error::source(e) {
        Some(cause) => format!("{e}: {cause}"),
        None => e.to_string(),
    }
}

fn pg_err(info: &ConnInfo, source: postgres::Error) -> StoreError {
    StoreError::Postgres {
        target: info.shown.clone(),
        source,
    }
}
