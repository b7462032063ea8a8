//! `scanmill db migrate --to URL`: a workstation's SQLite history copied into a PostgreSQL
//! store, so that a lab that grows keeps its audit trail. Every table, every row, ids kept
//! (a job is still job 17 in `show`), in one transaction; a store that already holds jobs
//! is refused (two histories would collide on ids), so running it twice changes nothing.

use super::PgStore;
use crate::store::{Store, StoreError};
use postgres::types::{ToSql, Type};

/// The tables and their columns, parents first; the order column gives SQLite's
/// insertion order (what `job_input.seq` keeps on PostgreSQL).
const TABLES: &[(&str, &str, &str)] = &[
    (
        "job",
        "id, job_key, set_hash, root, rel_path, output_root, recipe_path, recipe_hash, recipe_json,
         config_hash, state, retryable, attempts, max_attempts, generation, run_after, created_at,
         updated_at, started_at, finished_at, lease_owner, host, app_version, output_dir,
         error_kind, error, in_vertices, in_faces, out_vertices, out_faces, process_ms,
         report_json, preview",
        "id",
    ),
    (
        "job_input",
        "job_id, rel_path, role, size, mtime_ns, ino, sha256",
        "rowid",
    ),
    ("job_output", "job_id, path, bytes, sha256", "rowid"),
    ("sighting", "job_id, root, rel_path, seen_at", "rowid"),
    (
        "attempt",
        "id, job_id, n, owner, host, app_version, started_at, finished_at, outcome, error_kind,
         error, wall_ms",
        "id",
    ),
    (
        "step_timing",
        "attempt_id, idx, kind, wall_ms, vertices_before, vertices_after, faces_before,
         faces_after, figures_json",
        "rowid",
    ),
    (
        "waiting",
        "root, rel_path, reason, first_seen, updated_at",
        "rowid",
    ),
];

#[derive(Debug, thiserror::Error)]
pub enum CopyError {
    #[error(
        "{target} already holds {jobs} job(s); the copy goes into an empty store only (nothing was changed)"
    )]
    NotEmpty { target: String, jobs: i64 },
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// Rows copied, per table, for the report line.
#[derive(Debug, Default, PartialEq)]
pub struct Copied(pub Vec<(&'static str, usize)>);

impl std::fmt::Display for Copied {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let parts: Vec<String> = self.0.iter().map(|(t, n)| format!("{n} {t}")).collect();
        write!(f, "copied {}", parts.join(", "))
    }
}

/// Copies every row of `source` into `target` (migrated, empty).
pub fn from_sqlite(source: &Store, target: &mut PgStore) -> Result<Copied, CopyError> {
    let shown = target.shown().to_string();
    let sq = |e| StoreError::Sqlite {
        path: source.path().to_path_buf(),
        source: e,
    };
    let pg = |e| StoreError::Postgres {
        target: shown.clone(),
        source: e,
    };
    let client = target.client_mut()?;
    let mut tx = client.transaction().map_err(pg)?;
    tx.execute("LOCK TABLE job IN EXCLUSIVE MODE", &[])
        .map_err(pg)?;
    let jobs: i64 = tx
        .query_one("SELECT count(*) FROM job", &[])
        .map_err(pg)?
        .get(0);
    if jobs > 0 {
        return Err(CopyError::NotEmpty {
            target: shown.clone(),
            jobs,
        });
    }
    let mut copied = Copied::default();
    for (table, columns, order) in TABLES {
        let n = copy_table(
            source.connection(),
            &mut tx,
            table,
            columns,
            order,
            &sq,
            &pg,
        )?;
        copied.0.push((table, n));
    }
    for table in ["job", "attempt"] {
        tx.execute(
            &format!(
                "SELECT setval(pg_get_serial_sequence('{table}', 'id'), coalesce(max(id), 0) + 1, false) FROM {table}"
            ),
            &[],
        )
        .map_err(pg)?;
    }
    tx.commit().map_err(pg)?;
    Ok(copied)
}

fn copy_table(
    conn: &rusqlite::Connection,
    tx: &mut postgres::Transaction<'_>,
    table: &str,
    columns: &str,
    order: &str,
    sq: &dyn Fn(rusqlite::Error) -> StoreError,
    pg: &dyn Fn(postgres::Error) -> StoreError,
) -> Result<usize, StoreError> {
    let count = columns.split(',').count();
    let placeholders: Vec<String> = (1..=count).map(|i| format!("${i}")).collect();
    let insert = tx
        .prepare(&format!(
            "INSERT INTO {table} ({columns}) VALUES ({})",
            placeholders.join(", ")
        ))
        .map_err(pg)?;
    let types = insert.params().to_vec();
    let mut select = conn
        .prepare(&format!("SELECT {columns} FROM {table} ORDER BY {order}"))
        .map_err(sq)?;
    let mut rows = select.query([]).map_err(sq)?;
    let mut n = 0;
    while let Some(row) = rows.next().map_err(sq)? {
        let mut values: Vec<Box<dyn ToSql + Sync>> = Vec::with_capacity(count);
        for (i, ty) in types.iter().enumerate() {
            values.push(param(row.get_ref(i).map_err(sq)?, ty));
        }
        let refs: Vec<&(dyn ToSql + Sync)> = values.iter().map(|v| v.as_ref()).collect();
        tx.execute(&insert, &refs).map_err(pg)?;
        n += 1;
    }
    Ok(n)
}

/// A SQLite value as the parameter type PostgreSQL expects for its column.
fn param(v: rusqlite::types::ValueRef<'_>, ty: &Type) -> Box<dyn ToSql + Sync> {
    use rusqlite::types::ValueRef;
    match *ty {
        Type::INT8 => Box::new(match v {
            ValueRef::Integer(i) => Some(i),
            ValueRef::Real(f) => Some(f as i64),
            _ => None,
        }),
        Type::FLOAT8 => Box::new(match v {
            ValueRef::Integer(i) => Some(i as f64),
            ValueRef::Real(f) => Some(f),
            _ => None,
        }),
        _ => Box::new(match v {
            ValueRef::Null => None,
            ValueRef::Integer(i) => Some(i.to_string()),
            ValueRef::Real(f) => Some(f.to_string()),
            ValueRef::Text(t) => Some(String::from_utf8_lossy(t).into_owned()),
            ValueRef::Blob(b) => Some(hex::encode(b)),
        }),
    }
}
