//! Audit queries: `history` (a filtered list of jobs) and `show` (everything recorded about
//! one job). Both run as short read transactions, so they never hold the WAL back.

use super::{RelPath, Result, Store, StoreError};
use crate::text::{MAX_SHOWN, bounded, escape_str};
use rusqlite::{OptionalExtension, params};
use serde::Serialize;
use serde_json::{Value, json};

/// Filters of `scanmill history`.
#[derive(Debug, Clone, Default)]
pub struct HistoryFilter {
    /// Only jobs created at or after this Unix time (ms).
    pub since_ms: Option<i64>,
    /// Only jobs in this state; `waiting` lists scans that wait for a missing member.
    pub status: Option<String>,
    /// SQLite GLOB on the input's path (`root/rel_path`), e.g. `*/james*`.
    pub input_glob: Option<String>,
    pub limit: Option<usize>,
}

#[derive(Debug, Clone, Default, Serialize)]
pub struct HistoryRow {
    pub id: Option<i64>,
    pub state: String,
    pub created: String,
    pub finished: Option<String>,
    pub input: String,
    pub recipe: String,
    pub attempts: i64,
    pub in_faces: Option<i64>,
    pub out_faces: Option<i64>,
    pub process_ms: Option<f64>,
    pub output: Option<String>,
    /// The names of the files published into `output` (meshes, MTL, textures), sorted.
    pub outputs: Vec<String>,
    pub error_kind: Option<String>,
    pub error: Option<String>,
}

impl HistoryRow {
    /// A scan that has waited since `first_seen_ms` for a missing member, for `reason`.
    pub(crate) fn waiting(input: String, first_seen_ms: i64, reason: &str) -> HistoryRow {
        HistoryRow {
            state: "waiting".into(),
            created: iso_time(first_seen_ms),
            input,
            error_kind: Some("waiting".into()),
            error: Some(bounded(reason, MAX_SHOWN)),
            ..HistoryRow::default()
        }
    }
}

pub const STATES: &[&str] = &[
    "queued",
    "running",
    "done",
    "failed",
    "quarantined",
    "waiting",
];

/// Unix ms → `YYYY-MM-DDTHH:MM:SS.mmmZ` (UTC).
pub fn iso_time(ms: i64) -> String {
    let secs = ms.div_euclid(1000);
    let millis = ms.rem_euclid(1000);
    let days = secs.div_euclid(86_400);
    let rem = secs.rem_euclid(86_400);
    // Howard Hinnant's civil_from_days.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{millis:03}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

impl Store {
    /// Parses `--since`: a duration back from now (`90s`, `30m`, `12h`, `7d`) or a UTC
    /// date/time SQLite understands (`2026-11-01`, `2026-11-01T08:00:00`). Unix ms.
    pub fn parse_since(&self, text: &str, now_ms: i64) -> Option<i64> {
        let t = text.trim();
        let units = [
            ("s", 1_000),
            ("m", 60_000),
            ("h", 3_600_000),
            ("d", 86_400_000),
            ("w", 604_800_000),
        ];
        for (suffix, ms) in units {
            if let Some(n) = t
                .strip_suffix(suffix)
                .and_then(|n| n.trim().parse::<f64>().ok())
                && n.is_finite()
                && n >= 0.0
            {
                return Some(now_ms - (n * ms as f64) as i64);
            }
        }
        self.conn
            .query_row(
                "SELECT CAST(unixepoch(?1, 'subsec') * 1000 AS INTEGER)",
                [t],
                |r| r.get::<_, Option<i64>>(0),
            )
            .ok()
            .flatten()
    }

    pub fn history(&self, f: &HistoryFilter) -> Result<Vec<HistoryRow>> {
        let since = f.since_ms.unwrap_or(i64::MIN);
        let glob = f.input_glob.clone().unwrap_or_else(|| "*".into());
        let limit = f.limit.map(|l| l as i64).unwrap_or(-1);
        if f.status.as_deref() == Some("waiting") {
            return self.waiting_history(since, &glob, limit);
        }
        let mut rows = self.job_history(since, f.status.as_deref(), &glob, limit)?;
        self.fill_output_names(&mut rows)
            .map_err(self.sqlite_err())?;
        Ok(rows)
    }

    /// Maps a rusqlite error to this store's error.
    fn sqlite_err(&self) -> impl Fn(rusqlite::Error) -> StoreError + '_ {
        |source| StoreError::Sqlite {
            path: self.path.clone(),
            source,
        }
    }

    /// The scans that wait for a missing member, as history rows.
    fn waiting_history(&self, since: i64, glob: &str, limit: i64) -> Result<Vec<HistoryRow>> {
        let err = self.sqlite_err();
        let mut stmt = self
            .conn
            .prepare(
                "SELECT root, rel_path, reason, first_seen FROM waiting
                 WHERE first_seen >= ?1 AND (root || '/' || rel_path) GLOB ?2
                 ORDER BY first_seen LIMIT ?3",
            )
            .map_err(&err)?;
        let mapped = stmt
            .query_map(params![since, glob, limit], waiting_row)
            .map_err(&err)?;
        mapped.collect::<rusqlite::Result<Vec<_>>>().map_err(err)
    }

    /// The jobs that pass the filter, without their output names.
    fn job_history(
        &self,
        since: i64,
        status: Option<&str>,
        glob: &str,
        limit: i64,
    ) -> Result<Vec<HistoryRow>> {
        let err = self.sqlite_err();
        let mut stmt = self
            .conn
            .prepare(
                "SELECT id, state, created_at, finished_at, root, recipe_path, attempts,
                        in_faces, out_faces, process_ms, output_dir, error_kind, error, rel_path
                 FROM job
                 WHERE created_at >= ?1 AND (?2 IS NULL OR state = ?2) AND (root || '/' || rel_path) GLOB ?3
                 ORDER BY id LIMIT ?4",
            )
            .map_err(&err)?;
        let mapped = stmt
            .query_map(params![since, status, glob, limit], job_history_row)
            .map_err(&err)?;
        mapped.collect::<rusqlite::Result<Vec<_>>>().map_err(err)
    }

    /// Fills [`HistoryRow::outputs`] from the recorded output files.
    fn fill_output_names(&self, rows: &mut [HistoryRow]) -> rusqlite::Result<()> {
        let mut stmt = self
            .conn
            .prepare_cached("SELECT path FROM job_output WHERE job_id=?1 ORDER BY path")?;
        for row in rows.iter_mut() {
            let Some(id) = row.id else { continue };
            let paths = stmt.query_map([id], |r| r.get::<_, String>(0))?;
            for path in paths {
                row.outputs.push(output_name(&path?));
            }
        }
        Ok(())
    }

    /// Everything recorded about a job, as JSON: the job, its inputs, outputs, every
    /// attempt with its step timings, where else its input was seen, and the report.
    pub fn show(&self, id: i64) -> Result<Value> {
        let mut job = self.job_json(id)?;
        let inputs = self.child_rows(
            "SELECT rel_path, role, size, mtime_ns, ino, sha256 FROM job_input WHERE job_id=?1 ORDER BY rowid",
            id,
        )?;
        let outputs = self.child_rows(
            "SELECT path, bytes, sha256 FROM job_output WHERE job_id=?1 ORDER BY path",
            id,
        )?;
        let sightings = self.child_rows(
            "SELECT root, rel_path, seen_at FROM sighting WHERE job_id=?1 ORDER BY seen_at",
            id,
        )?;
        let mut attempts = self.child_rows(
            "SELECT id, n, owner, host, app_version, started_at, finished_at, outcome, error_kind, error, wall_ms
             FROM attempt WHERE job_id=?1 ORDER BY id",
            id,
        )?;
        for attempt in &mut attempts {
            let attempt_id = attempt["id"].as_i64().unwrap_or(0);
            attempt["steps"] = Value::Array(self.step_timings(attempt_id)?);
        }
        job["inputs"] = Value::Array(inputs);
        job["outputs"] = Value::Array(outputs);
        job["attempts_log"] = Value::Array(attempts);
        job["sightings"] = Value::Array(sightings);
        Ok(job)
    }

    /// The job's own row, every column by name, as [`shown_row`] prints it.
    fn job_json(&self, id: i64) -> Result<Value> {
        self.conn
            .query_row("SELECT * FROM job WHERE id=?1", [id], |r| {
                let stmt = r.as_ref();
                let columns = (0..stmt.column_count())
                    .map(|i| Ok((stmt.column_name(i)?.to_string(), sql_value(r.get_ref(i)?))))
                    .collect::<rusqlite::Result<Vec<_>>>()?;
                Ok(shown_row(columns))
            })
            .optional()
            .map_err(self.sqlite_err())?
            .ok_or(StoreError::NoSuchJob(id))
    }

    /// The rows of `sql` (one `?1`, the job or attempt id) as [`shown_row`] prints them.
    fn child_rows(&self, sql: &str, id: i64) -> Result<Vec<Value>> {
        let err = self.sqlite_err();
        let mut stmt = self.conn.prepare(sql).map_err(&err)?;
        let names: Vec<String> = stmt.column_names().iter().map(|s| s.to_string()).collect();
        let rows = stmt
            .query_map([id], |r| {
                let columns = (names.iter().enumerate())
                    .map(|(i, name)| Ok((name.clone(), sql_value(r.get_ref(i)?))))
                    .collect::<rusqlite::Result<Vec<_>>>()?;
                Ok(shown_row(columns))
            })
            .map_err(&err)?;
        rows.collect::<rusqlite::Result<Vec<_>>>().map_err(err)
    }

    /// An attempt's step timings, in step order.
    fn step_timings(&self, attempt_id: i64) -> Result<Vec<Value>> {
        let err = self.sqlite_err();
        let mut stmt = self
            .conn
            .prepare(
                "SELECT idx, kind, wall_ms, vertices_before, vertices_after, faces_before, faces_after, figures_json
                 FROM step_timing WHERE attempt_id=?1 ORDER BY idx",
            )
            .map_err(&err)?;
        stmt.query_map([attempt_id], |r| {
            Ok(json!({
                "index": r.get::<_, i64>(0)?,
                "kind": r.get::<_, String>(1)?,
                "wall_ms": r.get::<_, f64>(2)?,
                "vertices_before": r.get::<_, i64>(3)?,
                "vertices_after": r.get::<_, i64>(4)?,
                "faces_before": r.get::<_, i64>(5)?,
                "faces_after": r.get::<_, i64>(6)?,
                "figures": serde_json::from_str::<Value>(&r.get::<_, String>(7)?).unwrap_or(Value::Null),
            }))
        })
        .map_err(&err)?
        .collect::<rusqlite::Result<Vec<_>>>()
        .map_err(err)
    }
}

/// A `waiting` row as a history row.
fn waiting_row(r: &rusqlite::Row<'_>) -> rusqlite::Result<HistoryRow> {
    let root: String = r.get(0)?;
    let rel: RelPath = r.get(1)?;
    Ok(HistoryRow::waiting(
        input_display(&root, &rel),
        r.get(3)?,
        &r.get::<_, String>(2)?,
    ))
}

/// A row of `job_history`'s query as a history row.
fn job_history_row(r: &rusqlite::Row<'_>) -> rusqlite::Result<HistoryRow> {
    Ok(HistoryRow {
        id: Some(r.get(0)?),
        state: r.get(1)?,
        created: iso_time(r.get(2)?),
        finished: r.get::<_, Option<i64>>(3)?.map(iso_time),
        input: input_display(&r.get::<_, String>(4)?, &r.get::<_, RelPath>(13)?),
        recipe: r.get(5)?,
        attempts: r.get(6)?,
        in_faces: r.get(7)?,
        out_faces: r.get(8)?,
        process_ms: r.get(9)?,
        output: r.get::<_, Option<String>>(10)?.map(|o| escape_str(&o)),
        outputs: Vec::new(),
        error_kind: r.get(11)?,
        error: r
            .get::<_, Option<String>>(12)?
            .map(|e| bounded(&e, MAX_SHOWN)),
    })
}

/// One row of `show` (the job, or a row of a table about it) as printed, by both backends:
/// `*_at` and `run_after` times as ISO text, `*_json` texts parsed and the suffix dropped,
/// input-derived fields made printable ([`escape_row`]).
pub(crate) fn shown_row(columns: impl IntoIterator<Item = (String, Value)>) -> Value {
    let mut map = serde_json::Map::new();
    for (name, value) in columns {
        let value = match (&value, name.as_str()) {
            (Value::Number(ms), n) if n.ends_with("_at") || n == "run_after" => {
                json!(iso_time(ms.as_i64().unwrap_or(0)))
            }
            (Value::String(s), n) if n.ends_with("_json") => {
                serde_json::from_str(s).unwrap_or(value)
            }
            _ => value,
        };
        map.insert(name.trim_end_matches("_json").to_string(), value);
    }
    let mut row = Value::Object(map);
    escape_row(&mut row);
    row
}

/// An output file as `history` lists it: its name, escaped.
pub(crate) fn output_name(path: &str) -> String {
    escape_str(path.rsplit('/').next().unwrap_or(path))
}

/// `root/rel_path` as shown: escaped, any bytes.
pub(crate) fn input_display(root: &str, rel: &RelPath) -> String {
    format!("{}/{rel}", escape_str(root))
}

/// Makes the input-derived fields of a `show` row printable: `rel_path` decoded from its
/// stored form and escaped, paths escaped, error texts escaped and bounded.
pub(crate) fn escape_row(row: &mut Value) {
    let Value::Object(map) = row else { return };
    for (name, value) in map.iter_mut() {
        let Value::String(text) = value else { continue };
        *text = match name.as_str() {
            "rel_path" => RelPath::from_stored(text)
                .map(|p| p.to_string())
                .unwrap_or_else(|| escape_str(text)),
            "error" => bounded(text, MAX_SHOWN),
            "root" | "output_root" | "output_dir" | "preview" | "path" | "recipe_path" => {
                escape_str(text)
            }
            _ => continue,
        };
    }
}

fn sql_value(v: rusqlite::types::ValueRef<'_>) -> Value {
    use rusqlite::types::ValueRef;
    match v {
        ValueRef::Null => Value::Null,
        ValueRef::Integer(i) => json!(i),
        ValueRef::Real(f) => json!(f),
        ValueRef::Text(t) => json!(String::from_utf8_lossy(t)),
        ValueRef::Blob(b) => json!(hex::encode(b)),
    }
}

#[cfg(test)]
mod tests {
    use super::iso_time;

    #[test]
    fn iso_time_known_values() {
        assert_eq!(iso_time(0), "1970-01-01T00:00:00.000Z");
        assert_eq!(iso_time(1_700_000_000_123), "2023-11-14T22:13:20.123Z");
        assert_eq!(iso_time(951_782_400_000), "2000-02-29T00:00:00.000Z");
    }
}
