//! The Jobs, Job and Health pages, rendered to HTML strings (no templates, no script).
//! Every value from the store or the file system passes through [`html::esc`] or
//! [`html::shown`].

use super::html::{self, count, duration_ms, esc, figure, query, shown};
use super::reader::{Cursor, Figures, JobPage, JobQuery, JobRow, JobState};
use super::{DaemonState, LiveStatus};
use crate::store::query::iso_time;
use serde_json::Value;
use std::fmt::Write;

/// `2026-12-03 14:05:09` (UTC) from Unix ms.
pub fn when(ms: i64) -> String {
    let t = iso_time(ms);
    format!("{} {}", &t[..10], &t[11..19])
}

/// The filters of the list as they appear in its links (without the cursor).
pub fn filter_pairs(q: &JobQuery, from: &str, to: &str) -> Vec<(&'static str, String)> {
    vec![
        (
            "state",
            q.state.map(|s| s.as_str().to_string()).unwrap_or_default(),
        ),
        ("root", q.root.clone().unwrap_or_default()),
        ("from", from.to_string()),
        ("to", to.to_string()),
        ("q", q.text.clone().unwrap_or_default()),
        (
            "n",
            if q.limit == super::params::PAGE_SIZE {
                String::new()
            } else {
                q.limit.to_string()
            },
        ),
    ]
}

fn filter_form(q: &JobQuery, roots: &[String], from: &str, to: &str) -> String {
    let mut s = String::from("<form class=\"filters\" method=\"get\" action=\"/\">");
    s.push_str("<label>State <select name=\"state\"><option value=\"\">any</option>");
    for st in JobState::ALL {
        let sel = if q.state == Some(st) { " selected" } else { "" };
        let _ = write!(s, "<option{sel}>{}</option>", st.as_str());
    }
    s.push_str(
        "</select></label><label>Folder <select name=\"root\"><option value=\"\">any</option>",
    );
    for r in roots {
        let sel = if q.root.as_deref() == Some(r) {
            " selected"
        } else {
            ""
        };
        let _ = write!(s, "<option value=\"{}\"{sel}>{}</option>", esc(r), shown(r));
    }
    let _ = write!(
        s,
        "</select></label><label>From <input type=\"date\" name=\"from\" value=\"{}\"></label>\
         <label>To <input type=\"date\" name=\"to\" value=\"{}\"></label>\
         <label>Name contains <input type=\"search\" name=\"q\" value=\"{}\"></label>\
         <button type=\"submit\">Show</button> <a href=\"/\">clear</a></form>",
        esc(from),
        esc(to),
        esc(q.text.as_deref().unwrap_or(""))
    );
    s
}

fn job_list_row(r: &JobRow) -> String {
    let thumb = if r.has_preview {
        format!(
            "<a href=\"/jobs/{0}\"><img class=\"thumb\" src=\"/jobs/{0}/thumb\" alt=\"preview of job {0}\" loading=\"lazy\"></a>",
            r.id
        )
    } else {
        String::new()
    };
    let input = r.rel_path.to_string();
    let detail = match (&r.error_kind, &r.error) {
        (Some(k), Some(e)) => format!("<span class=\"err\">{}: {}</span>", shown(k), shown(e)),
        (Some(k), None) => format!("<span class=\"err\">{}</span>", shown(k)),
        _ => String::new(),
    };
    format!(
        "<tr><td>{thumb}</td><td class=\"n\"><a href=\"/jobs/{id}\">{id}</a></td>\
         <td class=\"state-{state}\">{state}</td><td><a href=\"/jobs/{id}\"><code>{input}</code></a>\
         <br><small>{root}</small> {detail}</td><td class=\"n\">{fin} → {fout}</td>\
         <td class=\"n\">{rms}</td><td class=\"n\">{time}</td><td class=\"t\">{created}</td></tr>\n",
        id = r.id,
        state = esc(&r.state),
        input = shown(&input),
        root = shown(&r.root),
        fin = count(r.in_faces),
        fout = count(r.out_faces),
        rms = figure(r.distance_rms),
        time = duration_ms(r.process_ms),
        created = when(r.created_ms),
    )
}

/// The Jobs page.
pub fn jobs_page(page: &JobPage, q: &JobQuery, roots: &[String], from: &str, to: &str) -> String {
    let mut body = String::from("<h1>Jobs</h1>");
    body.push_str(&filter_form(q, roots, from, to));
    body.push_str(
        "<table class=\"jobs\"><thead><tr><th>preview</th><th>job</th><th>state</th><th>input</th>\
         <th>faces in → out</th><th>distance RMS</th><th>time</th><th>queued (UTC)</th></tr></thead><tbody>\n",
    );
    for r in &page.rows {
        body.push_str(&job_list_row(r));
    }
    body.push_str("</tbody></table>");
    if page.rows.is_empty() {
        body.push_str("<p>No jobs match.</p>");
    }
    let pairs = filter_pairs(q, from, to);
    body.push_str("<p class=\"pager\">");
    if q.cursor != Cursor::Newest {
        let _ = write!(body, "<a href=\"/{}\">newest</a>", query(&pairs));
    }
    if let Some(id) = page.newer {
        let mut p = pairs.clone();
        p.push(("after", id.to_string()));
        let _ = write!(body, "<a rel=\"prev\" href=\"/{}\">← newer</a>", query(&p));
    }
    if let Some(id) = page.older {
        let mut p = pairs.clone();
        p.push(("before", id.to_string()));
        let _ = write!(body, "<a rel=\"next\" href=\"/{}\">older →</a>", query(&p));
    }
    body.push_str("</p>");
    html::page("Jobs", &body)
}

/// A JSON value as table text: strings printable and escaped, numbers as figures.
fn cell(v: &Value) -> String {
    match v {
        Value::Null => "–".into(),
        Value::String(s) => shown(s),
        Value::Number(n) if n.is_i64() => count(n.as_i64()),
        Value::Number(n) => figure(n.as_f64()),
        other => esc(&other.to_string()),
    }
}

/// Rows `path | value` for every scalar inside `v` (nested keys joined with `.`).
fn flatten(prefix: &str, v: &Value, out: &mut Vec<(String, String)>) {
    match v {
        Value::Object(map) => {
            for (k, x) in map {
                let key = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                flatten(&key, x, out);
            }
        }
        Value::Array(items) if items.iter().any(|x| x.is_object() || x.is_array()) => {
            for (i, x) in items.iter().enumerate() {
                flatten(&format!("{prefix}[{i}]"), x, out);
            }
        }
        other => out.push((prefix.to_string(), cell(other))),
    }
}

fn key_value_table(rows: &[(String, String)]) -> String {
    let mut s = String::from("<table class=\"kv\"><tbody>");
    for (k, v) in rows {
        let _ = write!(s, "<tr><th>{}</th><td>{v}</td></tr>", shown(k));
    }
    s.push_str("</tbody></table>");
    s
}

/// A table of an array of objects with the given columns.
fn rows_table(items: &Value, columns: &[&str]) -> String {
    let Some(items) = items.as_array().filter(|a| !a.is_empty()) else {
        return "<p>none</p>".into();
    };
    let mut s = String::from("<table><thead><tr>");
    for c in columns {
        let _ = write!(s, "<th>{}</th>", esc(c));
    }
    s.push_str("</tr></thead><tbody>");
    for item in items {
        s.push_str("<tr>");
        for c in columns {
            let _ = write!(s, "<td>{}</td>", cell(&item[*c]));
        }
        s.push_str("</tr>");
    }
    s.push_str("</tbody></table>");
    s
}

fn pretty(v: &Value) -> String {
    esc(&serde_json::to_string_pretty(v).unwrap_or_default())
}

/// The Job page: everything `scanmill show` gives, laid out for reading.
pub fn job_page(id: i64, job: &Value) -> String {
    let title = format!("Job {id}");
    let mut body = format!(
        "<h1>Job {id}: <code>{}</code></h1><p class=\"state-{1}\">{1}</p>",
        cell(&job["rel_path"]),
        cell(&job["state"])
    );
    if !job["preview"].is_null() {
        let _ = write!(
            body,
            "<h2>Preview</h2><p><img class=\"full\" id=\"preview\" src=\"/jobs/{id}/preview\" alt=\"preview of job {id}\"></p>"
        );
    }
    body.push_str("<h2>Job</h2>");
    body.push_str(&key_value_table(&job_summary(job)));
    job_metrics(&mut body, job);
    let _ = write!(
        body,
        "<h2>Steps</h2>{}<h2>Recipe (as resolved)</h2><pre>{}</pre>",
        rows_table(&job["report"]["steps"], &JOB_STEP_COLUMNS),
        pretty(&job["recipe"])
    );
    for (heading, key, columns) in JOB_TABLES {
        let _ = write!(body, "<h2>{heading}</h2>{}", rows_table(&job[key], columns));
    }
    let _ = write!(
        body,
        "<h2>Everything recorded</h2><details><summary>as <code>scanmill show {id}</code> prints it</summary><pre>{}</pre></details>",
        pretty(job)
    );
    html::page(&title, &body)
}

/// The columns of the job page's step table.
const JOB_STEP_COLUMNS: [&str; 6] = [
    "kind",
    "wall_ms",
    "vertices_before",
    "vertices_after",
    "faces_before",
    "faces_after",
];

/// The job page's tables after the recipe: heading, key in `show`'s JSON, columns.
const JOB_TABLES: [(&str, &str, &[&str]); 4] = [
    (
        "Attempts",
        "attempts_log",
        &[
            "n",
            "outcome",
            "error_kind",
            "error",
            "started_at",
            "finished_at",
            "wall_ms",
            "host",
            "owner",
            "app_version",
        ],
    ),
    ("Outputs", "outputs", &["path", "bytes", "sha256"]),
    ("Inputs", "inputs", &["rel_path", "role", "size", "sha256"]),
    ("Seen at", "sightings", &["root", "rel_path", "seen_at"]),
];

/// The job's plain fields (not its tables) as key and cell.
fn job_summary(job: &Value) -> Vec<(String, String)> {
    let mut summary = Vec::new();
    if let Value::Object(map) = job {
        for (k, v) in map {
            if !(v.is_object() || v.is_array()) {
                summary.push((k.clone(), cell(v)));
            }
        }
    }
    summary
}

/// The report's metrics, flattened, or "none recorded".
fn job_metrics(body: &mut String, job: &Value) {
    let mut metrics = Vec::new();
    if job["report"]["metrics"].is_object() {
        flatten("", &job["report"]["metrics"], &mut metrics);
    }
    body.push_str("<h2>Metrics</h2>");
    body.push_str(&if metrics.is_empty() {
        "<p>none recorded</p>".into()
    } else {
        key_value_table(&metrics)
    });
}

/// The Health page.
pub fn health_page(live: &LiveStatus, roots: &[(String, String, String)], f: &Figures) -> String {
    let state = match &live.state {
        DaemonState::Paused(reason) => format!("paused: {}", shown(reason)),
        s => s.label().to_string(),
    };
    let mut rows = vec![
        ("daemon".to_string(), state),
        ("since (UTC)".into(), when(live.started_ms)),
        ("queue depth".into(), count(Some(f.queue_depth))),
        (
            "workers busy".into(),
            format!("{} of {}", live.running, live.workers),
        ),
        (
            "scans not jobs: a member missing, or refused".into(),
            count(Some(f.waiting)),
        ),
        (
            "last successful job (UTC)".into(),
            f.last_success_ms
                .map(when)
                .unwrap_or_else(|| "never".into()),
        ),
    ];
    rows.push((
        "last error".into(),
        match &f.last_error {
            Some(e) => format!(
                "<a href=\"/jobs/{0}\">job {0}</a> {1}: <span class=\"err\">{2}: {3}</span>",
                e.job_id,
                e.at_ms.map(when).unwrap_or_default(),
                shown(&e.kind),
                shown(&e.message)
            ),
            None => "none".into(),
        },
    ));
    let mut body = String::from("<h1>Health</h1>");
    body.push_str(&key_value_table(&rows));
    body.push_str("<h2>Watched folders</h2><table><thead><tr><th>folder</th><th>output</th><th>recipe</th></tr></thead><tbody>");
    for (path, out, recipe) in roots {
        let _ = write!(
            body,
            "<tr><td><code>{}</code></td><td><code>{}</code></td><td><code>{}</code></td></tr>",
            shown(path),
            shown(out),
            shown(recipe)
        );
    }
    body.push_str("</tbody></table><h2>Jobs by state</h2><table><thead><tr><th>state</th><th>folder</th><th>jobs</th></tr></thead><tbody>");
    for (state, root, n) in &f.jobs {
        let _ = write!(
            body,
            "<tr><td>{}</td><td><code>{}</code></td><td class=\"n\">{}</td></tr>",
            esc(state),
            shown(root),
            count(Some(*n))
        );
    }
    body.push_str("</tbody></table>");
    html::page("Health", &body)
}

/// A page that says what went wrong (404, 400, 500), in one line.
pub fn message_page(title: &str, message: &str) -> String {
    html::page(
        title,
        &format!("<h1>{}</h1><p>{}</p>", esc(title), shown(message)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn job_page_of_a_failed_job_escapes_and_has_no_metric_rows() {
        let job = serde_json::json!({
            "rel_path": "x<script>.ply", "state": "failed", "preview": null, "report": null,
            "error": "bad \"name\"\n<img src=x>", "recipe": {"steps": [{"kind": "<b>"}]},
            "attempts_log": [], "outputs": [], "inputs": [], "sightings": []
        });
        let page = job_page(3, &job);
        assert!(
            page.contains("<h2>Metrics</h2><p>none recorded</p>"),
            "{page}"
        );
        assert!(page.contains("x&lt;script&gt;.ply"));
        assert!(
            page.contains("bad &quot;name&quot;\\n&lt;img src=x&gt;"),
            "{page}"
        );
        assert!(page.contains("&quot;&lt;b&gt;&quot;"), "recipe escaped");
        assert!(!page.contains("<script") && !page.contains("<img src=x"));
        assert!(
            !page.contains("id=\"preview\""),
            "no preview without a file"
        );
    }
}
