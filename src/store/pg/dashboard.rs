//! The dashboard's queries (`web::reader::DashboardReader`) on a PostgreSQL store: the
//! SQLite reader's queries in PostgreSQL's dialect, on a connection of the dashboard's own.
//! Reads only; each query is one statement, so it sees one snapshot of the shared queue.

use super::{DbError, PgStore};
use crate::store::{RelPath, StoreError};
use crate::web::reader::{
    Cursor, DashboardReader, Figures, JobPage, JobQuery, JobRow, LastError, TimeHistogram,
    TrendDay, contains_pattern, found, page_of,
};
use postgres::types::ToSql;
use serde_json::Value;
use std::path::PathBuf;
use std::sync::Mutex;

type Result<T> = std::result::Result<T, StoreError>;
type Param = Box<dyn ToSql + Sync + Send>;

/// A dashboard connection to a PostgreSQL store (schema version 2 or newer).
pub struct PgReader {
    store: Mutex<PgStore>,
}

impl PgReader {
    pub fn new(store: PgStore) -> PgReader {
        PgReader {
            store: Mutex::new(store),
        }
    }

    fn store(&self) -> std::sync::MutexGuard<'_, PgStore> {
        self.store.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// A number in `report_json` (schema version 2's guarded reader).
fn report_number(path: &str) -> String {
    format!("scanmill_json_number(report_json, '{{{path}}}')")
}

fn job_columns() -> String {
    format!(
        "id, state, root, rel_path, created_at, finished_at, in_faces, out_faces, {}, \
         process_ms, preview IS NOT NULL, error_kind, error",
        report_number("metrics,distance,rms")
    )
}

fn job_row(r: &postgres::Row) -> std::result::Result<JobRow, DbError> {
    let stored: String = r.get(3);
    let rel_path = RelPath::from_stored(&stored)
        .ok_or_else(|| DbError::Data(format!("job {}: unreadable rel_path", r.get::<_, i64>(0))))?;
    Ok(JobRow {
        id: r.get(0),
        state: r.get(1),
        root: r.get(2),
        rel_path,
        created_ms: r.get(4),
        finished_ms: r.get(5),
        in_faces: r.get(6),
        out_faces: r.get(7),
        distance_rms: r.get(8),
        process_ms: r.get(9),
        has_preview: r.get(10),
        error_kind: r.get(11),
        error: r.get(12),
    })
}

/// The WHERE clause of a list query (only the filters given) and its parameters, numbered
/// from $1.
fn job_filter(q: &JobQuery) -> (String, Vec<Param>) {
    let mut clauses: Vec<String> = Vec::new();
    let mut values: Vec<Param> = Vec::new();
    let mut add = |clause: &str, value: Param| {
        values.push(value);
        clauses.push(clause.replace('?', &format!("${}", values.len())));
    };
    if let Some(s) = q.state {
        add("state = ?", Box::new(s.as_str().to_string()));
    }
    if let Some(r) = &q.root {
        add("root = ?", Box::new(r.clone()));
    }
    if let Some(t) = q.from_ms {
        add("created_at >= ?", Box::new(t));
    }
    if let Some(t) = q.to_ms {
        add("created_at < ?", Box::new(t));
    }
    if let Some(t) = &q.text {
        // ILIKE: the SQLite reader's LIKE ignores ASCII case too.
        add(
            "rel_path ILIKE ? ESCAPE '\\'",
            Box::new(contains_pattern(t)),
        );
    }
    match q.cursor {
        Cursor::Newest => {}
        Cursor::Before(id) => add("id < ?", Box::new(id)),
        Cursor::After(id) => add("id > ?", Box::new(id)),
    }
    let sql = if clauses.is_empty() {
        String::new()
    } else {
        format!("WHERE {}", clauses.join(" AND "))
    };
    (sql, values)
}

fn refs(values: &[Param]) -> Vec<&(dyn ToSql + Sync)> {
    values
        .iter()
        .map(|v| v.as_ref() as &(dyn ToSql + Sync))
        .collect()
}

impl DashboardReader for PgReader {
    fn jobs(&self, q: &JobQuery) -> Result<JobPage> {
        let (filter, mut values) = job_filter(q);
        let order = q.cursor.sql_order();
        // One more than asked: tells whether there is a further page.
        values.push(Box::new(q.limit as i64 + 1));
        let sql = format!(
            "SELECT {} FROM job {filter} ORDER BY id {order} LIMIT ${}",
            job_columns(),
            values.len()
        );
        let rows = self.store().read(move |c| {
            c.query(sql.as_str(), &refs(&values))?
                .iter()
                .map(job_row)
                .collect::<std::result::Result<Vec<_>, _>>()
        })?;
        Ok(page_of(rows, q))
    }

    fn job(&self, id: i64) -> Result<Option<Value>> {
        found(self.store().show(id))
    }

    fn preview(&self, id: i64) -> Result<Option<(PathBuf, PathBuf)>> {
        let row: Option<(Option<String>, String)> = self.store().read(|c| {
            Ok(
                c.query_opt("SELECT preview, output_root FROM job WHERE id = $1", &[&id])?
                    .map(|r| (r.get(0), r.get(1))),
            )
        })?;
        Ok(row.and_then(|(p, root)| p.map(|p| (PathBuf::from(p), PathBuf::from(root)))))
    }

    fn roots(&self) -> Result<Vec<String>> {
        self.store().read(|c| {
            Ok(c.query("SELECT DISTINCT root FROM job ORDER BY root", &[])?
                .iter()
                .map(|r| r.get(0))
                .collect())
        })
    }

    fn trends(&self, since_ms: i64) -> Result<Vec<TrendDay>> {
        let sql = format!(
            "SELECT root, finished_at / 86400000 AS day,
                count(*) FILTER (WHERE state = 'done'),
                count(*) FILTER (WHERE state <> 'done'),
                avg({}) FILTER (WHERE state = 'done'),
                avg({}) FILTER (WHERE state = 'done'),
                avg(process_ms) FILTER (WHERE state = 'done')
             FROM job WHERE state IN ('done', 'failed', 'quarantined') AND finished_at >= $1
             GROUP BY root, day ORDER BY root, day",
            report_number("metrics,distance,rms"),
            report_number("metrics,texture,rms"),
        );
        self.store().read(move |c| {
            Ok(c.query(sql.as_str(), &[&since_ms])?
                .iter()
                .map(|r| TrendDay {
                    root: r.get(0),
                    day: r.get(1),
                    done: r.get(2),
                    failed: r.get(3),
                    distance_rms: r.get(4),
                    texture_rms: r.get(5),
                    process_ms: r.get(6),
                })
                .collect())
        })
    }

    fn figures(&self, bounds_ms: &[f64]) -> Result<Figures> {
        let times = self.histograms(bounds_ms)?;
        let mut f = self.store().read(|c| {
            let counts = c.query_one(
                "SELECT (SELECT count(*) FROM job WHERE state = 'queued')
                      + (SELECT count(*) FROM job WHERE state = 'failed' AND retryable = 1),
                        (SELECT count(*) FROM job WHERE state = 'running'),
                        (SELECT count(*) FROM waiting),
                        (SELECT max(finished_at) FROM job WHERE state = 'done')",
                &[],
            )?;
            let jobs = c
                .query(
                    "SELECT state, root, count(*) FROM job GROUP BY state, root ORDER BY state, root",
                    &[],
                )?
                .iter()
                .map(|r| (r.get(0), r.get(1), r.get(2)))
                .collect();
            let failures = c
                .query(
                    "SELECT coalesce(error_kind, 'unknown'), count(*) FROM attempt
                     WHERE outcome IN ('retry', 'failed', 'quarantined') GROUP BY 1 ORDER BY 1",
                    &[],
                )?
                .iter()
                .map(|r| (r.get(0), r.get(1)))
                .collect();
            let last_error = c
                .query_opt(
                    "SELECT job_id, finished_at, coalesce(error_kind, 'unknown'), coalesce(error, '')
                     FROM attempt WHERE outcome IN ('retry', 'failed', 'quarantined')
                     ORDER BY id DESC LIMIT 1",
                    &[],
                )?
                .map(|r| LastError {
                    job_id: r.get(0),
                    at_ms: r.get(1),
                    kind: r.get(2),
                    message: r.get(3),
                });
            Ok(Figures {
                jobs,
                queue_depth: counts.get(0),
                running: counts.get(1),
                waiting: counts.get(2),
                last_success_ms: counts.get(3),
                failures,
                times: Vec::new(),
                last_error,
            })
        })?;
        f.times = times;
        Ok(f)
    }
}

impl PgReader {
    /// One pass over the finished jobs: a `count(*) FILTER` per bucket bound.
    fn histograms(&self, bounds_ms: &[f64]) -> Result<Vec<TimeHistogram>> {
        let buckets: String = (1..=bounds_ms.len())
            .map(|i| format!("count(*) FILTER (WHERE process_ms <= ${i}), "))
            .collect();
        let sql = format!(
            "SELECT root, {buckets}count(*), coalesce(sum(process_ms), 0) FROM job
             WHERE state = 'done' AND process_ms IS NOT NULL GROUP BY root ORDER BY root"
        );
        let bounds = bounds_ms.to_vec();
        self.store().read(move |c| {
            let params: Vec<&(dyn ToSql + Sync)> =
                bounds.iter().map(|b| b as &(dyn ToSql + Sync)).collect();
            let n = bounds.len();
            Ok(c.query(sql.as_str(), &params)?
                .iter()
                .map(|r| TimeHistogram {
                    root: r.get(0),
                    le: (1..=n).map(|i| r.get(i)).collect(),
                    count: r.get(n + 1),
                    sum_ms: r.get(n + 2),
                })
                .collect())
        })
    }
}
