//! The one interface the daemon and the command line use for the job queue and audit log:
//! [`Queue`], an enum of the two backends (docs/architecture.md, "The store"). An enum
//! rather than a trait object: there are exactly two, the daemon matches on the few things
//! only the shared queue has (leases, the fence), and every call stays a plain method call.

use super::pg::{ConnInfo, Fence, PgStore};
use super::{
    ClaimedJob, Enqueued, FinalState, Finish, KnownSet, NewJob, Owner, RelPath, Result,
    RetryPolicy, Store,
};
use crate::store::query::{HistoryFilter, HistoryRow};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// `[store]` in the daemon configuration: absent (or no `url`), SQLite in `state_dir`;
/// `url = "postgres://…"`, the queue shared with other hosts (docs/scale-out.md). A missing
/// key takes its value from [`StoreConfig::default`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StoreConfig {
    /// `postgres://user@host:port/database` (a Unix socket: `postgres://user@%2Frun%2Fpostgresql/db`
    /// or `?host=/run/postgresql`). No password here in production: see `password_file`.
    pub url: Option<String>,
    /// A file whose first line is the password (else `$PGPASSWORD`, else `~/.pgpass`).
    pub password_file: Option<PathBuf>,
    /// A claimed job's lease; the daemon renews it every third of this while the job runs.
    /// Another host takes the job over once it passed without renewal.
    pub lease_secs: f64,
    /// How often each host looks for jobs whose lease passed.
    pub rescue_secs: f64,
    /// At start-up, how long an unreachable server is retried before the daemon gives up
    /// (exit 69; systemd starts it again).
    pub connect_patience_secs: f64,
}

impl Default for StoreConfig {
    fn default() -> StoreConfig {
        StoreConfig {
            url: None,
            password_file: None,
            lease_secs: 30.0,
            rescue_secs: 10.0,
            connect_patience_secs: 60.0,
        }
    }
}

impl StoreConfig {
    pub fn is_shared(&self) -> bool {
        self.url.is_some()
    }

    /// The connection settings, if a URL is set (a bad URL or password file is an error).
    pub fn conn_info(&self) -> Result<Option<ConnInfo>> {
        match &self.url {
            None => Ok(None),
            Some(url) => Ok(Some(ConnInfo::new(url, self.password_file.as_deref())?)),
        }
    }

    pub fn validate(&self) -> Vec<String> {
        let mut problems = Vec::new();
        let ok = |v: f64| v.is_finite() && v > 0.0;
        if !ok(self.lease_secs) || self.lease_secs < 1.0 {
            problems.push(format!(
                "[store] lease_secs = {}: at least 1",
                self.lease_secs
            ));
        }
        if !ok(self.rescue_secs) {
            problems.push(format!(
                "[store] rescue_secs = {}: must be > 0",
                self.rescue_secs
            ));
        }
        if !ok(self.connect_patience_secs) {
            problems.push(format!(
                "[store] connect_patience_secs = {}: must be > 0",
                self.connect_patience_secs
            ));
        }
        if let Err(e) = self.conn_info() {
            problems.push(e.to_string());
        }
        problems
    }

    pub fn lease(&self) -> Duration {
        Duration::from_secs_f64(self.lease_secs.max(1.0))
    }
}

/// The job queue and audit log, on one of its backends.
pub enum Queue {
    Sqlite(Store),
    /// Boxed: the client is large, and the queue is made once.
    Postgres(Box<PgStore>),
}

/// Methods both backends have, with the same name and signature: each passes its
/// arguments on to the backend at hand.
macro_rules! on_either_backend {
    ($(pub fn $name:ident(&mut self $(, $arg:ident: $ty:ty)* $(,)?) -> $ret:ty;)*) => {
        impl Queue {
            $(
                pub fn $name(&mut self $(, $arg: $ty)*) -> $ret {
                    match self {
                        Queue::Sqlite(s) => s.$name($($arg),*),
                        Queue::Postgres(p) => p.$name($($arg),*),
                    }
                }
            )*
        }
    };
}

on_either_backend! {
    pub fn known_inputs(&mut self) -> Result<Vec<KnownSet>>;
    pub fn counts(&mut self) -> Result<(i64, i64)>;
    pub fn next_run_after(&mut self) -> Result<Option<i64>>;
    pub fn enqueue(&mut self, job: &NewJob) -> Result<Enqueued>;
    pub fn set_waiting(&mut self, root: &str, rel_path: &RelPath, reason: &str, first_seen: i64) -> Result<()>;
    pub fn clear_waiting(&mut self, root: &str, rel_path: &RelPath) -> Result<()>;
    pub fn claim(&mut self, owner: &Owner) -> Result<Option<ClaimedJob>>;
    pub fn finish(&mut self, job: &ClaimedJob, outcome: &Finish, retry: RetryPolicy, wall_ms: f64) -> Result<FinalState>;
    pub fn history(&mut self, f: &HistoryFilter) -> Result<Vec<HistoryRow>>;
    pub fn show(&mut self, id: i64) -> Result<serde_json::Value>;
    pub fn requeue(&mut self, id: i64) -> Result<String>;
}

impl Queue {
    /// The daemon's store: SQLite at `sqlite_path`, or the `[store]` server (connected,
    /// retried for `connect_patience_secs`, migrated).
    pub fn open(store: &StoreConfig, sqlite_path: &Path) -> Result<Queue> {
        match store.conn_info()? {
            None => Ok(Queue::Sqlite(Store::open(sqlite_path)?)),
            Some(info) => {
                let patience = Duration::from_secs_f64(store.connect_patience_secs.max(0.0));
                let pg = PgStore::open(info, store.lease(), patience)?;
                Ok(Queue::Postgres(Box::new(pg)))
            }
        }
    }

    /// The command line's store (never creates one): `url` if given, else the
    /// configuration's.
    pub fn open_existing(
        store: &StoreConfig,
        url: Option<&str>,
        sqlite_path: &Path,
        write: bool,
    ) -> Result<Queue> {
        let info = match url {
            Some(u) => Some(ConnInfo::new(u, store.password_file.as_deref())?),
            None => store.conn_info()?,
        };
        match info {
            None => Ok(Queue::Sqlite(Store::open_existing(sqlite_path, write)?)),
            Some(info) => Ok(Queue::Postgres(Box::new(PgStore::open_existing(info)?))),
        }
    }

    /// Where the store is, for messages (a path, or the URL without its password).
    pub fn describe(&self) -> String {
        match self {
            Queue::Sqlite(s) => s.path().display().to_string(),
            Queue::Postgres(p) => p.shown().to_string(),
        }
    }

    /// At start-up: SQLite requeues what a previous process left running; on the shared
    /// queue that is the rescuer's job (other hosts' jobs are running, not left over).
    pub fn recover_running(&mut self) -> Result<usize> {
        match self {
            Queue::Sqlite(s) => s.recover_running(),
            Queue::Postgres(_) => Ok(0),
        }
    }

    pub fn data_version(&mut self) -> Result<i64> {
        match self {
            Queue::Sqlite(s) => s.data_version(),
            Queue::Postgres(p) => Ok(p.data_version()),
        }
    }

    /// The lease of the shared queue (`None` on SQLite, where the daemon owns its jobs).
    pub fn lease(&self) -> Option<Duration> {
        match self {
            Queue::Sqlite(_) => None,
            Queue::Postgres(p) => Some(p.lease()),
        }
    }

    /// Renews the leases of the running attempts `tokens`; the ones that still hold their
    /// job. Every token on SQLite.
    pub fn heartbeat(&mut self, tokens: &[i64]) -> Result<Vec<i64>> {
        match self {
            Queue::Sqlite(_) => Ok(tokens.to_vec()),
            Queue::Postgres(p) => p.heartbeat(tokens),
        }
    }

    /// Requeues jobs whose lease passed (shared queue only).
    pub fn rescue(&mut self) -> Result<usize> {
        match self {
            Queue::Sqlite(_) => Ok(0),
            Queue::Postgres(p) => p.rescue(),
        }
    }

    /// What the job threads publish through (shared queue only).
    pub fn fence(&self) -> Option<Fence> {
        match self {
            Queue::Sqlite(_) => None,
            Queue::Postgres(p) => Some(p.fence()),
        }
    }

    /// At shutdown: folds SQLite's WAL back; nothing on the server.
    pub fn checkpoint(&self) {
        if let Queue::Sqlite(s) = self {
            s.checkpoint();
        }
    }

    /// `--since` (a duration or a UTC date/time), read by SQLite's date functions on
    /// both backends, so that it means the same everywhere.
    pub fn parse_since(&self, text: &str, now_ms: i64) -> Option<i64> {
        match self {
            Queue::Sqlite(s) => s.parse_since(text, now_ms),
            Queue::Postgres(_) => {
                let conn = rusqlite::Connection::open_in_memory().ok()?;
                let scratch = Store {
                    conn,
                    path: PathBuf::from(":memory:"),
                };
                scratch.parse_since(text, now_ms)
            }
        }
    }
}
