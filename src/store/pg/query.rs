//! `history` and `show` on PostgreSQL: the same rows and the same JSON as the SQLite
//! store's (`store::query`), read with `to_jsonb` and shaped by the same rules.

use super::PgStore;
use crate::store::query::{
    HistoryFilter, HistoryRow, input_display, iso_time, output_name, shown_row,
};
use crate::store::{RelPath, Result};
use crate::text::{MAX_SHOWN, bounded, escape_str};
use serde_json::Value;

/// SQLite's GLOB (`*` any run, `?` one character, `[...]` a class, `[^...]` its
/// complement; case-sensitive) as an anchored PostgreSQL regular expression, so that
/// `history --input` means the same on both stores.
pub fn glob_to_regex(glob: &str) -> String {
    let mut out = String::from("^");
    let mut chars = glob.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '*' => out.push_str(".*"),
            '?' => out.push('.'),
            '[' => {
                let mut class = String::from("[");
                if chars.peek() == Some(&'^') {
                    class.push('^');
                    chars.next();
                }
                let mut closed = false;
                let mut first = true;
                for d in chars.by_ref() {
                    if d == ']' && !first {
                        closed = true;
                        break;
                    }
                    first = false;
                    if d == '\\' || d == '[' {
                        class.push('\\');
                    }
                    class.push(d);
                }
                if closed {
                    out.push_str(&class);
                    out.push(']');
                } else {
                    out.push_str("\\[");
                    out.push_str(&regex_escape(&class[1..]));
                }
            }
            _ => out.push_str(&regex_escape(&c.to_string())),
        }
    }
    out.push('$');
    out
}

fn regex_escape(s: &str) -> String {
    let mut out = String::new();
    for c in s.chars() {
        if "\\.+*?()|[]{}^$".contains(c) {
            out.push('\\');
        }
        out.push(c);
    }
    out
}

impl PgStore {
    pub fn history(&mut self, f: &HistoryFilter) -> Result<Vec<HistoryRow>> {
        let since = f.since_ms.unwrap_or(i64::MIN);
        let regex = glob_to_regex(f.input_glob.as_deref().unwrap_or("*"));
        let limit = f.limit.map(|l| l as i64);
        if f.status.as_deref() == Some("waiting") {
            let rows = self.read(|c| {
                Ok(c.query(
                    "SELECT root, rel_path, reason, first_seen FROM waiting
                     WHERE first_seen >= $1 AND (root || '/' || rel_path) ~ $2
                     ORDER BY first_seen LIMIT $3",
                    &[&since, &regex, &limit],
                )?)
            })?;
            return Ok(rows
                .iter()
                .map(|r| {
                    let created = r.get(3);
                    HistoryRow::waiting(
                        shown_input(r.get(0), r.get(1)),
                        created,
                        &r.get::<_, String>(2),
                    )
                })
                .collect());
        }
        let rows = self.read(|c| {
            Ok(c.query(
                "SELECT id, state, created_at, finished_at, root, recipe_path, attempts,
                        in_faces, out_faces, process_ms, output_dir, error_kind, error, rel_path,
                        ARRAY(SELECT path FROM job_output o WHERE o.job_id = job.id ORDER BY path)
                 FROM job
                 WHERE created_at >= $1 AND ($2::text IS NULL OR state = $2)
                   AND (root || '/' || rel_path) ~ $3
                 ORDER BY id LIMIT $4",
                &[&since, &f.status, &regex, &limit],
            )?)
        })?;
        Ok(rows
            .iter()
            .map(|r| HistoryRow {
                id: Some(r.get(0)),
                state: r.get(1),
                created: iso_time(r.get(2)),
                finished: r.get::<_, Option<i64>>(3).map(iso_time),
                input: shown_input(r.get(4), r.get(13)),
                recipe: r.get(5),
                attempts: r.get(6),
                in_faces: r.get(7),
                out_faces: r.get(8),
                process_ms: r.get(9),
                output: r.get::<_, Option<String>>(10).map(|o| escape_str(&o)),
                outputs: r
                    .get::<_, Vec<String>>(14)
                    .iter()
                    .map(|p| output_name(p))
                    .collect(),
                error_kind: r.get(11),
                error: r
                    .get::<_, Option<String>>(12)
                    .map(|e| bounded(&e, MAX_SHOWN)),
            })
            .collect())
    }

    /// Everything recorded about a job, as `Store::show` gives it (plus the lease columns).
    pub fn show(&mut self, id: i64) -> Result<Value> {
        let table = |sql: &str| -> String {
            format!("SELECT coalesce(jsonb_agg(to_jsonb(t)), '[]') FROM ({sql}) t")
        };
        let queries = [
            "SELECT to_jsonb(j) FROM job j WHERE id=$1".to_string(),
            table(
                "SELECT rel_path, role, size, mtime_ns, ino, sha256 FROM job_input WHERE job_id=$1 ORDER BY seq",
            ),
            table("SELECT path, bytes, sha256 FROM job_output WHERE job_id=$1 ORDER BY path"),
            table("SELECT root, rel_path, seen_at FROM sighting WHERE job_id=$1 ORDER BY seen_at"),
            table(
                "SELECT a.id, n, owner, host, app_version, started_at, finished_at, outcome, error_kind, error, a.wall_ms,
                    (SELECT coalesce(jsonb_agg(jsonb_build_object('index', idx, 'kind', kind, 'wall_ms', s.wall_ms,
                        'vertices_before', vertices_before, 'vertices_after', vertices_after,
                        'faces_before', faces_before, 'faces_after', faces_after,
                        'figures', figures_json::jsonb) ORDER BY idx), '[]')
                     FROM step_timing s WHERE s.attempt_id = a.id) AS steps
                 FROM attempt a WHERE job_id=$1 ORDER BY a.id",
            ),
        ];
        let values = self.read(|c| {
            let mut out = Vec::new();
            for q in &queries {
                let row = c.query_opt(q.as_str(), &[&id])?;
                out.push(row.map(|r| r.get::<_, Value>(0)));
            }
            Ok(out)
        })?;
        let mut values = values.into_iter();
        let Some(Some(job)) = values.next() else {
            return Err(crate::store::StoreError::NoSuchJob(id));
        };
        let mut job = shape(job);
        for name in ["inputs", "outputs", "sightings", "attempts_log"] {
            let rows = match values.next().flatten() {
                Some(Value::Array(rows)) => rows,
                _ => Vec::new(),
            };
            job[name] = Value::Array(rows.into_iter().map(shape).collect());
        }
        Ok(job)
    }
}

/// `root/rel_path` as `history` shows it.
fn shown_input(root: String, stored: String) -> String {
    match RelPath::from_stored(&stored) {
        Some(rel) => input_display(&root, &rel),
        None => format!("{}/{}", escape_str(&root), escape_str(&stored)),
    }
}

/// One row as `show` prints it ([`shown_row`], the rule `Store::show` uses too).
fn shape(row: Value) -> Value {
    match row {
        Value::Object(map) => shown_row(map),
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::glob_to_regex;

    #[test]
    fn globs_become_anchored_regexes() {
        assert_eq!(glob_to_regex("*/james*"), "^.*/james.*$");
        assert_eq!(glob_to_regex("a?.p[ly]"), "^a.\\.p[ly]$");
        assert_eq!(glob_to_regex("[^x]y"), "^[^x]y$");
        assert_eq!(glob_to_regex("a(b)+"), "^a\\(b\\)\\+$");
        assert_eq!(glob_to_regex("[abc"), "^\\[abc$");
    }
}
