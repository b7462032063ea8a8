//! What the dashboard reads, behind one small read-only trait ([`DashboardReader`]), and its
//! SQLite implementation, on a read-only connection of its own (WAL lets it read while the
//! daemon writes; it never takes the write lock). The PostgreSQL one is
//! `store::pg::dashboard::PgReader`: the same queries in PostgreSQL's dialect.

use crate::store::{RelPath, Store, StoreError};
use rusqlite::types::ToSql;
use rusqlite::{OptionalExtension, params};
use serde_json::Value;
use std::path::{Path, PathBuf};

type Result<T> = std::result::Result<T, StoreError>;

/// A job's state as the `job` table records it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JobState {
    Queued,
    Running,
    Done,
    Failed,
    Quarantined,
}

impl JobState {
    pub const ALL: [JobState; 5] = [
        JobState::Queued,
        JobState::Running,
        JobState::Done,
        JobState::Failed,
        JobState::Quarantined,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Done => "done",
            JobState::Failed => "failed",
            JobState::Quarantined => "quarantined",
        }
    }

    pub fn parse(text: &str) -> Option<JobState> {
        JobState::ALL.into_iter().find(|s| s.as_str() == text)
    }
}

/// Where a page of the job list starts (keyset pagination on the job id, newest first).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cursor {
    Newest,
    /// The page of jobs older than this id.
    Before(i64),
    /// The page of jobs newer than this id.
    After(i64),
}

impl Cursor {
    /// The id order a page is fetched in: newest first, except the page before a given
    /// one, which is fetched oldest first from its id and turned round ([`page_of`]).
    pub fn sql_order(self) -> &'static str {
        if matches!(self, Cursor::After(_)) {
            "ASC"
        } else {
            "DESC"
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct JobQuery {
    pub state: Option<JobState>,
    /// A watched folder exactly as recorded.
    pub root: Option<String>,
    /// Created at or after (Unix ms).
    pub from_ms: Option<i64>,
    /// Created before (Unix ms).
    pub to_ms: Option<i64>,
    /// Part of the input's path relative to its root (ASCII case ignored).
    pub text: Option<String>,
    pub cursor: Cursor,
    pub limit: usize,
}

#[derive(Debug, Clone, PartialEq)]
pub struct JobRow {
    pub id: i64,
    pub state: String,
    pub root: String,
    pub rel_path: RelPath,
    pub created_ms: i64,
    pub finished_ms: Option<i64>,
    pub in_faces: Option<i64>,
    pub out_faces: Option<i64>,
    pub distance_rms: Option<f64>,
    pub process_ms: Option<f64>,
    pub has_preview: bool,
    pub error_kind: Option<String>,
    pub error: Option<String>,
}

/// One page of the list, newest first, with the cursors of its neighbours.
#[derive(Debug, Clone, PartialEq)]
pub struct JobPage {
    pub rows: Vec<JobRow>,
    /// `Cursor::After(id)` shows the page before this one.
    pub newer: Option<i64>,
    /// `Cursor::Before(id)` shows the page after this one.
    pub older: Option<i64>,
}

/// One watched folder's figures on one UTC day.
#[derive(Debug, Clone, PartialEq)]
pub struct TrendDay {
    pub root: String,
    /// Days since 1970-01-01 (UTC).
    pub day: i64,
    pub done: i64,
    pub failed: i64,
    /// Means over the day's finished jobs that have the figure.
    pub distance_rms: Option<f64>,
    pub texture_rms: Option<f64>,
    pub process_ms: Option<f64>,
}

/// Processing times of one watched folder's finished jobs, as a histogram.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeHistogram {
    pub root: String,
    /// Cumulative counts, one per bucket bound given to [`DashboardReader::figures`].
    pub le: Vec<i64>,
    pub count: i64,
    pub sum_ms: f64,
}

/// The most recent failed attempt.
#[derive(Debug, Clone, PartialEq)]
pub struct LastError {
    pub job_id: i64,
    pub at_ms: Option<i64>,
    pub kind: String,
    pub message: String,
}

/// The figures of `/health` and `/metrics`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Figures {
    /// (state, root, jobs).
    pub jobs: Vec<(String, String, i64)>,
    pub queue_depth: i64,
    pub running: i64,
    pub waiting: i64,
    pub last_success_ms: Option<i64>,
    /// (error kind, failed attempts).
    pub failures: Vec<(String, i64)>,
    pub times: Vec<TimeHistogram>,
    pub last_error: Option<LastError>,
}

/// The dashboard's read-only queries.
pub trait DashboardReader: Send {
    fn jobs(&self, query: &JobQuery) -> Result<JobPage>;
    /// Everything `scanmill show` gives (its JSON document), or `None` for no such job.
    fn job(&self, id: i64) -> Result<Option<Value>>;
    /// The recorded preview file and output root of a job.
    fn preview(&self, id: i64) -> Result<Option<(PathBuf, PathBuf)>>;
    fn roots(&self) -> Result<Vec<String>>;
    fn trends(&self, since_ms: i64) -> Result<Vec<TrendDay>>;
    /// `bounds_ms`: the upper bounds of the processing-time buckets.
    fn figures(&self, bounds_ms: &[f64]) -> Result<Figures>;
}

/// [`DashboardReader`] on the SQLite store (a query-only connection).
pub struct SqliteReader {
    store: Store,
}

impl SqliteReader {
    pub fn open(path: &Path) -> Result<SqliteReader> {
        Ok(SqliteReader {
            store: Store::open_existing(path, false)?,
        })
    }

    fn err(&self, source: rusqlite::Error) -> StoreError {
        StoreError::Sqlite {
            path: self.store.path().to_path_buf(),
            source,
        }
    }
}

const JOB_COLUMNS: &str = "id, state, root, rel_path, created_at, finished_at, in_faces, out_faces,
    CASE WHEN json_valid(report_json) THEN json_extract(report_json, '$.metrics.distance.rms') END,
    process_ms, preview IS NOT NULL, error_kind, error";

/// A job's `show` as the dashboard's job page takes it: `None` for an id with no job.
pub(crate) fn found(shown: Result<Value>) -> Result<Option<Value>> {
    match shown {
        Ok(v) => Ok(Some(v)),
        Err(StoreError::NoSuchJob(_)) => Ok(None),
        Err(e) => Err(e),
    }
}

/// The page of `rows`, fetched in the cursor's order (`ORDER BY id DESC`, or `ASC` after
/// `Cursor::After`) with one row more than `q.limit` when there is a further page.
pub(crate) fn page_of(mut rows: Vec<JobRow>, q: &JobQuery) -> JobPage {
    let more = rows.len() > q.limit;
    rows.truncate(q.limit);
    let (newer, older) = match q.cursor {
        Cursor::Newest => (None, more.then(|| rows.last().map(|r| r.id)).flatten()),
        Cursor::Before(_) => (
            rows.first().map(|r| r.id),
            more.then(|| rows.last().map(|r| r.id)).flatten(),
        ),
        Cursor::After(_) => {
            rows.reverse();
            (
                more.then(|| rows.first().map(|r| r.id)).flatten(),
                rows.last().map(|r| r.id),
            )
        }
    };
    JobPage { rows, newer, older }
}

/// `text` as a LIKE pattern that matches it anywhere, its own `%`, `_` and `\` literal.
pub(crate) fn contains_pattern(text: &str) -> String {
    let mut p = String::from("%");
    for c in text.chars() {
        if matches!(c, '%' | '_' | '\\') {
            p.push('\\');
        }
        p.push(c);
    }
    p.push('%');
    p
}

fn job_row(r: &rusqlite::Row<'_>) -> rusqlite::Result<JobRow> {
    Ok(JobRow {
        id: r.get(0)?,
        state: r.get(1)?,
        root: r.get(2)?,
        rel_path: r.get(3)?,
        created_ms: r.get(4)?,
        finished_ms: r.get(5)?,
        in_faces: r.get(6)?,
        out_faces: r.get(7)?,
        distance_rms: r.get::<_, Option<f64>>(8).unwrap_or(None),
        process_ms: r.get(9)?,
        has_preview: r.get(10)?,
        error_kind: r.get(11)?,
        error: r.get(12)?,
    })
}

/// The WHERE clause of a list query (only the filters given, so that SQLite can use the
/// indexes of schema version 3 and `job_created`) and its parameters.
fn job_filter(q: &JobQuery) -> (String, Vec<Box<dyn ToSql>>) {
    let mut clauses: Vec<&str> = Vec::new();
    let mut values: Vec<Box<dyn ToSql>> = Vec::new();
    if let Some(s) = q.state {
        clauses.push("state = ?");
        values.push(Box::new(s.as_str()));
    }
    if let Some(r) = &q.root {
        clauses.push("root = ?");
        values.push(Box::new(r.clone()));
    }
    if let Some(t) = q.from_ms {
        clauses.push("created_at >= ?");
        values.push(Box::new(t));
    }
    if let Some(t) = q.to_ms {
        clauses.push("created_at < ?");
        values.push(Box::new(t));
    }
    if let Some(t) = &q.text {
        // LIKE ignores ASCII case.
        clauses.push("rel_path LIKE ? ESCAPE '\\'");
        values.push(Box::new(contains_pattern(t)));
    }
    match q.cursor {
        Cursor::Newest => {}
        Cursor::Before(id) => {
            clauses.push("id < ?");
            values.push(Box::new(id));
        }
        Cursor::After(id) => {
            clauses.push("id > ?");
            values.push(Box::new(id));
        }
    }
    let sql = if clauses.is_empty() {
        String::new()
    } else {
        format!("WHERE {}", clauses.join(" AND "))
    };
    (sql, values)
}

impl DashboardReader for SqliteReader {
    fn jobs(&self, q: &JobQuery) -> Result<JobPage> {
        let (filter, mut values) = job_filter(q);
        let order = q.cursor.sql_order();
        // The page's ids first, from the indexes alone; then only those (wide) rows.
        let sql = format!(
            "SELECT {JOB_COLUMNS} FROM job WHERE id IN
                (SELECT id FROM job {filter} ORDER BY id {order} LIMIT ?)
             ORDER BY id {order}"
        );
        // One more than asked: tells whether there is a further page.
        values.push(Box::new(q.limit as i64 + 1));
        let conn = self.store.connection();
        let mut stmt = conn.prepare_cached(&sql).map_err(|e| self.err(e))?;
        let rows = stmt
            .query_map(rusqlite::params_from_iter(values.iter()), job_row)
            .map_err(|e| self.err(e))?
            .collect::<rusqlite::Result<Vec<_>>>()
            .map_err(|e| self.err(e))?;
        Ok(page_of(rows, q))
    }

    fn job(&self, id: i64) -> Result<Option<Value>> {
        found(self.store.show(id))
    }

    fn preview(&self, id: i64) -> Result<Option<(PathBuf, PathBuf)>> {
        let row: Option<(Option<String>, String)> = self
            .store
            .connection()
            .query_row(
                "SELECT preview, output_root FROM job WHERE id = ?1",
                [id],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .optional()
            .map_err(|e| self.err(e))?;
        Ok(row.and_then(|(p, root)| p.map(|p| (PathBuf::from(p), PathBuf::from(root)))))
    }

    fn roots(&self) -> Result<Vec<String>> {
        let conn = self.store.connection();
        let mut stmt = conn
            .prepare_cached("SELECT DISTINCT root FROM job ORDER BY root")
            .map_err(|e| self.err(e))?;
        let roots = stmt
            .query_map([], |r| r.get(0))
            .map_err(|e| self.err(e))?
            .collect::<rusqlite::Result<Vec<String>>>()
            .map_err(|e| self.err(e))?;
        Ok(roots)
    }

    fn trends(&self, since_ms: i64) -> Result<Vec<TrendDay>> {
        let conn = self.store.connection();
        let mut stmt = conn
            .prepare_cached(
                "SELECT root, finished_at / 86400000 AS day,
                    count(*) FILTER (WHERE state = 'done'),
                    count(*) FILTER (WHERE state <> 'done'),
                    avg(json_extract(report_json, '$.metrics.distance.rms')) FILTER (WHERE state = 'done'),
                    avg(json_extract(report_json, '$.metrics.texture.rms')) FILTER (WHERE state = 'done'),
                    avg(process_ms) FILTER (WHERE state = 'done')
                 FROM job WHERE state IN ('done', 'failed', 'quarantined') AND finished_at >= ?1
                 GROUP BY root, day ORDER BY root, day",
            )
            .map_err(|e| self.err(e))?;
        let days = stmt
            .query_map([since_ms], |r| {
                Ok(TrendDay {
                    root: r.get(0)?,
                    day: r.get(1)?,
                    done: r.get(2)?,
                    failed: r.get(3)?,
                    distance_rms: r.get(4)?,
                    texture_rms: r.get(5)?,
                    process_ms: r.get(6)?,
                })
            })
            .map_err(|e| self.err(e))?
            .collect::<rusqlite::Result<Vec<_>>>()
            .map_err(|e| self.err(e))?;
        Ok(days)
    }

    fn figures(&self, bounds_ms: &[f64]) -> Result<Figures> {
        let conn = self.store.connection();
        let e = |x| self.err(x);
        // Not `Store::counts`: its filter on `retryable` reads every wide row.
        let (queue_depth, running) = conn
            .query_row(
                "SELECT (SELECT count(*) FROM job WHERE state = 'queued')
                      + (SELECT count(*) FROM job WHERE state = 'failed' AND retryable = 1),
                        (SELECT count(*) FROM job WHERE state = 'running')",
                [],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .map_err(e)?;
        let mut f = Figures {
            queue_depth,
            running,
            ..Figures::default()
        };
        f.jobs = collect(
            conn,
            "SELECT state, root, count(*) FROM job GROUP BY state, root ORDER BY state, root",
            |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)),
        )
        .map_err(e)?;
        f.waiting = conn
            .query_row("SELECT count(*) FROM waiting", [], |r| r.get(0))
            .map_err(e)?;
        f.last_success_ms = conn
            .query_row(
                "SELECT max(finished_at) FROM job WHERE state = 'done'",
                [],
                |r| r.get(0),
            )
            .map_err(e)?;
        f.failures = collect(
            conn,
            "SELECT coalesce(error_kind, 'unknown'), count(*) FROM attempt
             WHERE outcome IN ('retry', 'failed', 'quarantined') GROUP BY 1 ORDER BY 1",
            |r| Ok((r.get(0)?, r.get(1)?)),
        )
        .map_err(e)?;
        f.times = self.histograms(bounds_ms)?;
        f.last_error = conn
            .query_row(
                "SELECT job_id, finished_at, coalesce(error_kind, 'unknown'), coalesce(error, '') FROM attempt
                 WHERE outcome IN ('retry', 'failed', 'quarantined') ORDER BY id DESC LIMIT 1",
                [],
                |r| {
                    Ok(LastError {
                        job_id: r.get(0)?,
                        at_ms: r.get(1)?,
                        kind: r.get(2)?,
                        message: r.get(3)?,
                    })
                },
            )
            .optional()
            .map_err(e)?;
        Ok(f)
    }
}

impl SqliteReader {
    /// One pass over the finished jobs: a `count(*) FILTER` per bucket bound.
    fn histograms(&self, bounds_ms: &[f64]) -> Result<Vec<TimeHistogram>> {
        let buckets: Vec<String> = (0..bounds_ms.len())
            .map(|i| format!("count(*) FILTER (WHERE process_ms <= ?{})", i + 1))
            .collect();
        let sql = format!(
            "SELECT root, {}{} count(*), coalesce(sum(process_ms), 0) FROM job
             WHERE state = 'done' AND process_ms IS NOT NULL GROUP BY root ORDER BY root",
            buckets.join(", "),
            if buckets.is_empty() { "" } else { "," }
        );
        let conn = self.store.connection();
        let mut stmt = conn.prepare_cached(&sql).map_err(|e| self.err(e))?;
        let n = bounds_ms.len();
        let rows = stmt
            .query_map(rusqlite::params_from_iter(bounds_ms.iter()), |r| {
                let mut le = Vec::with_capacity(n);
                for i in 0..n {
                    le.push(r.get(i + 1)?);
                }
                Ok(TimeHistogram {
                    root: r.get(0)?,
                    le,
                    count: r.get(n + 1)?,
                    sum_ms: r.get(n + 2)?,
                })
            })
            .map_err(|e| self.err(e))?
            .collect::<rusqlite::Result<Vec<_>>>()
            .map_err(|e| self.err(e))?;
        Ok(rows)
    }
}

fn collect<T>(
    conn: &rusqlite::Connection,
    sql: &str,
    f: impl FnMut(&rusqlite::Row<'_>) -> rusqlite::Result<T>,
) -> rusqlite::Result<Vec<T>> {
    let mut stmt = conn.prepare_cached(sql)?;
    let rows = stmt.query_map(params![], f)?;
    rows.collect()
}

#[cfg(test)]
mod tests {
    use super::contains_pattern;

    #[test]
    fn search_text_is_literal_in_the_like_pattern() {
        assert_eq!(contains_pattern("james"), "%james%");
        assert_eq!(contains_pattern("50%_a\\b"), "%50\\%\\_a\\\\b%");
    }
}
