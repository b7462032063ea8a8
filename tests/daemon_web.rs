//! The web dashboard and /metrics against the running daemon (the real binary), with a real
//! HTTP client: status codes, content, filters, pagination, escaping of hostile file names,
//! /metrics through a Prometheus text-format parser, 404s, traversal attempts, the token.
//! Every wait is a poll with a generous deadline; nothing asserts on durations.

mod common;
mod daemon_support;

use daemon_support::*;
use std::io::{Read, Write};
use std::os::unix::ffi::OsStrExt;
use std::path::Path;

/// The dashboard's base URL, from the daemon's log line.
fn base_url(lab: &Lab) -> String {
    let logs = lab.logs();
    let at = logs
        .find("web dashboard on http://")
        .unwrap_or_else(|| panic!("no dashboard address logged:\n{logs}"));
    let rest = &logs[at + "web dashboard on ".len()..];
    rest.split_whitespace().next().unwrap().to_string()
}

fn agent() -> ureq::Agent {
    ureq::Agent::config_builder()
        .http_status_as_error(false)
        .build()
        .into()
}

/// GET: (status, content type, body as text).
fn get(url: &str) -> (u16, String, String) {
    get_with(url, None)
}

fn get_with(url: &str, auth: Option<&str>) -> (u16, String, String) {
    let mut req = agent().get(url);
    if let Some(a) = auth {
        req = req.header("Authorization", a);
    }
    let mut r = req.call().unwrap_or_else(|e| panic!("{url}: {e}"));
    let kind = r
        .headers()
        .get("content-type")
        .map(|v| v.to_str().unwrap().to_string())
        .unwrap_or_default();
    let body = r.body_mut().read_to_vec().unwrap();
    (
        r.status().as_u16(),
        kind,
        String::from_utf8_lossy(&body).into_owned(),
    )
}

/// A request written byte for byte (no client normalises its path): status and body.
fn raw_get(base: &str, path: &str) -> (u16, String) {
    let addr = base.trim_start_matches("http://").trim_end_matches('/');
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut out = String::new();
    s.read_to_string(&mut out).unwrap();
    let status = out
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    (status, out)
}

/// The job ids of a list page, in the order shown.
fn ids(page: &str) -> Vec<i64> {
    page.split("<td class=\"n\"><a href=\"/jobs/")
        .skip(1)
        .map(|s| s[..s.find('"').unwrap()].parse().unwrap())
        .collect()
}

/// The href of the link with `rel`, `&amp;` undone.
fn link(page: &str, rel: &str) -> Option<String> {
    let at = page.find(&format!("rel=\"{rel}\" href=\""))?;
    let rest = &page[at + rel.len() + 13..];
    Some(rest[..rest.find('"').unwrap()].replace("&amp;", "&"))
}

fn web_lab(extra: &str) -> Lab {
    Lab::new(
        0.3,
        &format!("[web]\nenabled = true\nlisten = \"127.0.0.1:0\"\n{extra}"),
    )
}

/// Strict check of the text format: every line is a comment, or `name{labels} value` with
/// a valid metric name, well-formed quoted label values and a number.
fn strict_exposition(text: &str) {
    for line in text.lines() {
        if line.starts_with("# HELP ") || line.starts_with("# TYPE ") {
            continue;
        }
        let (series, value) = line.rsplit_once(' ').unwrap_or_else(|| panic!("{line}"));
        assert!(
            value.parse::<f64>().is_ok() || value == "+Inf",
            "value: {line}"
        );
        let (name, labels) = match series.find('{') {
            Some(i) => (&series[..i], Some(&series[i..])),
            None => (series, None),
        };
        assert!(
            !name.is_empty()
                && name
                    .bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b':')
                && !name.as_bytes()[0].is_ascii_digit(),
            "name: {line}"
        );
        if let Some(l) = labels {
            let inner = l
                .strip_prefix('{')
                .and_then(|l| l.strip_suffix('}'))
                .unwrap_or_else(|| panic!("{line}"));
            let mut rest = inner;
            while !rest.is_empty() {
                let eq = rest.find("=\"").unwrap_or_else(|| panic!("{line}"));
                let mut i = eq + 2;
                let b = rest.as_bytes();
                while b[i] != b'"' {
                    i += if b[i] == b'\\' { 2 } else { 1 };
                }
                rest = rest[i + 1..].strip_prefix(',').unwrap_or(&rest[i + 1..]);
            }
        }
    }
}

/// The running daemon with its jobs processed: a real scan, three hostile names and a
/// broken file.
struct Site {
    base: String,
    james: i64,
    broken: i64,
    /// The watched folder, resolved.
    root: std::path::PathBuf,
    /// The first job's queued day, `YYYY-MM-DD`.
    today: String,
}

fn hostile_lab() -> (Lab, KillOnDrop, Site) {
    let lab = web_lab("");
    let daemon = KillOnDrop(lab.start(&[]));
    let base = base_url(&lab);
    let inbox = lab.inbox();
    copy_james(&inbox.join("session1"));
    // Hostile names: markup and quotes, a newline, bytes that are not UTF-8; and a broken
    // file whose error text carries its markup-laden name.
    std::fs::write(inbox.join("<script>alert('x')\".ply"), bunny_variant("a")).unwrap();
    std::fs::write(inbox.join("evil\nname.ply"), bunny_variant("b")).unwrap();
    let raw = std::ffi::OsStr::from_bytes(b"bad\xff\xfe.ply");
    std::fs::write(inbox.join(raw), bunny_variant("c")).unwrap();
    std::fs::write(
        inbox.join("<img src=x onerror=alert(1)>.ply"),
        b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n",
    )
    .unwrap();
    assert!(
        wait_for(120, || lab.count_state("done") == 4
            && lab.count_state("failed") + lab.count_state("quarantined")
                == 1),
        "{:#?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    let jobs = lab.jobs();
    let james = jobs
        .iter()
        .find(|j| j["input"].as_str().unwrap().ends_with("james.obj"))
        .unwrap()["id"]
        .as_i64()
        .unwrap();
    let broken = jobs.iter().find(|j| j["state"] != "done").unwrap()["id"]
        .as_i64()
        .unwrap();

    let site = Site {
        root: lab.inbox().canonicalize().unwrap(),
        today: serde_json::to_string(&jobs[0]["created"]).unwrap()[1..11].to_string(),
        base,
        james,
        broken,
    };
    (lab, daemon, site)
}

fn check_list(site: &Site) -> Vec<i64> {
    let (base, james) = (site.base.as_str(), site.james);
    // The list: every job, newest first, names escaped.
    let (code, kind, page) = get(base);
    assert_eq!(code, 200);
    assert!(kind.starts_with("text/html"), "{kind}");
    let all = ids(&page);
    assert_eq!(all.len(), 5, "{page}");
    assert!(all.windows(2).all(|w| w[0] > w[1]), "newest first: {all:?}");
    assert!(page.contains("session1/james.obj"), "{page}");
    assert!(page.contains("&lt;script&gt;alert(&#39;x&#39;)&quot;.ply"));
    assert!(page.contains("evil\\nname.ply"), "newline shown escaped");
    assert!(
        page.contains("bad\\xff\\xfe.ply"),
        "non-UTF-8 bytes shown escaped"
    );
    assert!(page.contains("&lt;img src=x onerror=alert(1)&gt;"));
    let lower = page.to_lowercase();
    assert!(!lower.contains("<script"), "markup injected");
    assert!(!lower.contains("<img src=x"), "markup injected");
    assert!(!page.contains("evil\nname"), "raw newline");
    assert!(page.contains(&format!("/jobs/{james}/thumb")));
    all
}

fn check_filters(site: &Site) {
    let (base, james, broken) = (site.base.as_str(), site.james, site.broken);
    // Filters.
    let (_, _, failed) = get(&format!("{base}?state=failed"));
    let (_, _, quarantined) = get(&format!("{base}?state=quarantined"));
    assert_eq!(
        [ids(&failed), ids(&quarantined)].concat(),
        vec![broken],
        "state filter"
    );
    assert_eq!(
        ids(&get(&format!("{base}?q=JAMES")).2),
        vec![james],
        "name search"
    );
    assert_eq!(ids(&get(&format!("{base}?q=%3Cscript")).2).len(), 1);
    let root = &site.root;
    let root_q: String = root
        .to_string_lossy()
        .bytes()
        .map(|b| format!("%{b:02X}"))
        .collect();
    assert_eq!(ids(&get(&format!("{base}?root={root_q}")).2).len(), 5);
    assert!(ids(&get(&format!("{base}?root=%2Fnowhere")).2).is_empty());
    assert!(ids(&get(&format!("{base}?from=2000-01-01&to=2000-01-31")).2).is_empty());
    let today = &site.today;
    assert_eq!(
        ids(&get(&format!("{base}?from={today}&to={today}")).2).len(),
        5
    );
    for bad in ["?state=exploded", "?before=x", "?from=2026-02-30", "?n=0"] {
        assert_eq!(get(&format!("{base}{bad}")).0, 400, "{bad}");
    }
}

fn check_pagination(site: &Site, all: &[i64]) {
    let base = site.base.as_str();
    // Keyset pagination, two at a time: older pages reach every job once, newer comes back.
    let mut seen = Vec::new();
    let mut url = format!("{base}?n=2");
    let mut pages = Vec::new();
    loop {
        let (code, _, page) = get(&url);
        assert_eq!(code, 200);
        seen.extend(ids(&page));
        pages.push(page.clone());
        match link(&page, "next") {
            Some(href) => url = format!("{}{}", base.trim_end_matches('/'), href),
            None => break,
        }
    }
    assert_eq!(seen, all, "pages cover the list in order, once");
    assert_eq!(pages.len(), 3);
    let back = link(&pages[1], "prev").expect("newer link on page 2");
    assert_eq!(
        ids(&get(&format!("{}{}", base.trim_end_matches('/'), back)).2),
        ids(&pages[0])
    );
}

fn check_job_page(site: &Site, shown: &serde_json::Value) {
    let (base, james, broken) = (site.base.as_str(), site.james, site.broken);
    // The job page: what `show` gives.
    let (code, _, page) = get(&format!("{base}jobs/{james}"));
    assert_eq!(code, 200);
    for output in shown["outputs"].as_array().unwrap() {
        assert!(page.contains(output["sha256"].as_str().unwrap()), "hash");
    }
    assert!(page.contains("id=\"preview\""), "preview shown");
    assert!(page.contains("<h2>Metrics</h2>") && page.contains("distance.rms"));
    assert!(page.contains("&quot;normals&quot;"), "resolved recipe");
    assert!(page.contains("<td>ok</td>"), "attempt outcome");
    let (code, _, page) = get(&format!("{base}jobs/{broken}"));
    assert_eq!(code, 200);
    assert!(page.contains("&lt;img src=x onerror=alert(1)&gt;"));
    assert!(!page.to_lowercase().contains("<img src=x"));
    assert!(
        page.contains("<h2>Metrics</h2><p>none recorded</p>"),
        "{page}"
    );
}

fn check_images(site: &Site) {
    let (base, james, broken) = (site.base.as_str(), site.james, site.broken);
    // The preview, by job id only.
    let mut r = agent()
        .get(format!("{base}jobs/{james}/preview"))
        .call()
        .unwrap();
    assert_eq!(r.status().as_u16(), 200);
    assert_eq!(r.headers()["content-type"], "image/png");
    let png = r.body_mut().read_to_vec().unwrap();
    let img = image::load_from_memory(&png).unwrap();
    assert!(img.width() > 0 && img.height() > 0);
    let mut r = agent()
        .get(format!("{base}jobs/{james}/thumb"))
        .call()
        .unwrap();
    assert_eq!(r.headers()["content-type"], "image/png");
    let thumb = image::load_from_memory(&r.body_mut().read_to_vec().unwrap()).unwrap();
    assert!(
        thumb.width() <= 288 && thumb.width() < img.width(),
        "scaled down"
    );
    assert_eq!(
        get(&format!("{base}jobs/{broken}/thumb")).0,
        404,
        "no preview"
    );
}

fn check_refusals(site: &Site) {
    let base = site.base.as_str();
    // Unknown jobs and pages, traversal attempts.
    for path in [
        "jobs/999999",
        "jobs/abc",
        "jobs/999999/preview",
        "jobs/0",
        "nothing-here",
    ] {
        assert_eq!(get(&format!("{base}{path}")).0, 404, "{path}");
    }
    for path in [
        "/jobs/..%2F..%2F..%2Fetc%2Fpasswd/preview",
        "/jobs/1/../../../../etc/passwd",
        "/../../../../etc/passwd",
        "/static/..%2f..%2f..%2fetc%2fpasswd",
        "/static/../../Cargo.toml",
        "/jobs/%2e%2e/preview",
    ] {
        let (code, text) = raw_get(base, path);
        assert!(code == 404 || code == 400, "{path}: {code}");
        assert!(!text.contains("root:x:0"), "{path}");
    }
    // Read-only: no other method.
    let code = agent().post(base).send_empty().unwrap().status().as_u16();
    assert_eq!(code, 405);

    // Security headers on every page.
    let r = agent().get(base).call().unwrap();
    let csp = r.headers()["content-security-policy"].to_str().unwrap();
    assert!(csp.contains("default-src 'none'"), "{csp}");
}

fn check_trends_and_health(site: &Site) {
    let (base, broken) = (site.base.as_str(), site.broken);
    // Trends and Health.
    let (code, _, page) = get(&format!("{base}trends"));
    assert_eq!(code, 200);
    assert!(page.contains("<svg") && page.contains("<circle"), "{page}");
    assert!(page.contains(&site.root.to_string_lossy().to_string()));
    assert_eq!(get(&format!("{base}trends?days=0")).0, 400);
    let (code, _, page) = get(&format!("{base}health"));
    assert_eq!(code, 200);
    assert!(page.contains("idle") || page.contains("working"), "{page}");
    assert!(page.contains("queue depth"));
    assert!(
        page.contains(&format!("job {broken}")),
        "last error: {page}"
    );
}

fn check_metrics(site: &Site) {
    let base = site.base.as_str();
    // /metrics through a Prometheus parser, and a strict line check.
    let (code, kind, text) = get(&format!("{base}metrics"));
    assert_eq!(code, 200);
    assert!(kind.starts_with("text/plain; version=0.0.4"), "{kind}");
    strict_exposition(&text);
    let scrape = prometheus_parse::Scrape::parse(text.lines().map(|l| Ok(l.to_string()))).unwrap();
    let value = |s: &prometheus_parse::Sample| match s.value {
        prometheus_parse::Value::Gauge(v)
        | prometheus_parse::Value::Counter(v)
        | prometheus_parse::Value::Untyped(v) => v,
        _ => f64::NAN,
    };
    let sum = |metric: &str, label: Option<(&str, &str)>| -> f64 {
        scrape
            .samples
            .iter()
            .filter(|s| s.metric == metric)
            .filter(|s| label.is_none_or(|(k, v)| s.labels.get(k) == Some(v)))
            .map(value)
            .sum()
    };
    assert_eq!(sum("scanmill_jobs", Some(("state", "done"))), 4.0, "{text}");
    assert_eq!(sum("scanmill_jobs", None), 5.0);
    assert_eq!(sum("scanmill_queue_depth", None), 0.0);
    assert_eq!(sum("scanmill_workers", None), 1.0);
    assert!(
        sum("scanmill_attempt_failures_total", None) >= 1.0,
        "{text}"
    );
    let last = sum("scanmill_last_success_timestamp_seconds", None);
    assert!(last > 1.7e9, "{last}");
    let histogram = scrape
        .samples
        .iter()
        .find(|s| s.metric == "scanmill_job_processing_seconds")
        .expect("histogram");
    let prometheus_parse::Value::Histogram(buckets) = &histogram.value else {
        panic!("{histogram:?}")
    };
    assert_eq!(buckets.last().unwrap().count, 4.0, "+Inf bucket");
    assert!(buckets.windows(2).all(|w| w[0].count <= w[1].count));
    assert_eq!(sum("scanmill_job_processing_seconds_count", None), 4.0);
}

#[test]
fn dashboard_lists_filters_pages_escapes_and_exports_metrics() {
    let (lab, _daemon, site) = hostile_lab();
    let all = check_list(&site);
    check_filters(&site);
    check_pagination(&site, &all);
    check_job_page(&site, &lab.show(site.james));
    check_images(&site);
    check_refusals(&site);
    check_trends_and_health(&site);
    check_metrics(&site);
}

#[test]
fn token_is_required_when_configured() {
    let lab = web_lab("token = \"0123456789abcdef-lab\"\n");
    let _d = KillOnDrop(lab.start(&[]));
    let base = base_url(&lab);
    let (code, _, _) = get(&base);
    assert_eq!(code, 401);
    let r = agent().get(&base).call().unwrap();
    assert!(r.headers().contains_key("www-authenticate"));
    assert_eq!(
        get_with(&base, Some("Bearer wrong-token-of-some-length")).0,
        401
    );
    assert_eq!(get_with(&base, Some("Bearer 0123456789abcdef-lab")).0, 200);
    assert_eq!(
        get_with(
            &format!("{base}metrics"),
            Some("Bearer 0123456789abcdef-lab")
        )
        .0,
        200
    );
    // HTTP Basic, as a browser sends it: "lab:0123456789abcdef-lab".
    assert_eq!(
        get_with(&base, Some("Basic bGFiOjAxMjM0NTY3ODlhYmNkZWYtbGFi")).0,
        200
    );
}

#[test]
fn exposed_address_without_token_or_proxy_is_refused_with_exit_78() {
    let lab = Lab::new(0.3, "[web]\nenabled = true\nlisten = \"0.0.0.0:8640\"\n");
    let (code, _, err) = lab.cli(&["validate-config"]);
    assert_eq!(code, 78, "{err}");
    assert!(err.contains("not a loopback address"), "{err}");
    let out = std::process::Command::new(BIN)
        .args(["daemon", "--config"])
        .arg(&lab.config)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(78));
    assert!(!Path::new(&lab.dir.path().join("state/scanmill.sqlite")).exists());
    let lab = Lab::new(0.3, "[web]\nenabled = true\nlisten = \"localhost\"\n");
    let (code, _, err) = lab.cli(&["validate-config"]);
    assert_eq!(code, 78, "{err}");
    assert!(err.contains("web.listen"), "{err}");
}

/// A report of the shape the worker records (steps, metrics, outputs), about 3 KB.
fn synthetic_report(n: i64) -> String {
    let f = |k: i64| ((n * 7919 + k * 104_729) % 1000) as f64 / 1000.0;
    let steps: Vec<_> = ["relax", "fair", "decimate", "seam_fix", "normals"]
        .iter()
        .map(|kind| {
            serde_json::json!({"kind": kind, "wall_ms": 800.0 * f(1), "vertices_before": 210_000,
                "vertices_after": 13_500, "faces_before": 400_000, "faces_after": 26_000,
                "figures": {"iterations": 20, "moved_rms": f(2), "flips": 3}})
        })
        .collect();
    serde_json::json!({
        "scanmill_version": "0.1.0",
        "input": {"path": format!("study/subject{n}/scan.obj"), "content_hash": "ab".repeat(32),
            "counts": {"vertices": 210_000, "faces": 400_000, "wedges": 0, "texcoords": 220_000, "normals": 0}},
        "steps": steps,
        "metrics": {
            "distance": {"mean": 0.02 * f(3), "rms": 0.03 + 0.01 * f(4), "max": 0.4 * f(5),
                "mean_relative": 1e-4, "rms_relative": 2e-4, "max_relative": 1e-3, "bbox_diagonal": 250.0,
                "result_to_reference": {"samples": 100_000, "mean": 0.02, "rms": 0.03, "max": 0.3, "inexact": 0},
                "reference_to_result": {"samples": 100_000, "mean": 0.02, "rms": 0.03, "max": 0.3, "inexact": 0},
                "seed": 1},
            "volume": {"reference": 1.2e6, "result": 1.19e6, "relative_change": -0.008},
            "normals": {"mean_deg": 4.1, "rms_deg": 6.0, "p99_deg": 25.0, "max_deg": 80.0},
            "texture": {"status": "measured", "samples": 100_000, "mean": 2.0 + f(6), "rms": 3.0 + f(7), "p99": 12.0, "max": 60.0},
            "topology": {"holes_before": 3, "holes_after": 3, "cracks": 0, "flips": 2},
            "wall_ms": 900.0
        },
        "output": {"counts": {"vertices": 13_500, "faces": 26_000, "wedges": 0, "texcoords": 15_000, "normals": 13_500}},
        "load_ms": 500.0, "write_ms": 120.0, "total_ms": 9000.0 + 4000.0 * f(8)
    })
    .to_string()
}

/// Fills a fresh store with `n` finished jobs over two watched folders and 60 days, each
/// with its attempt, inputs, outputs, sighting and step timings, in one transaction.
fn fill_store(db: &Path, roots: [&str; 2], n: i64) {
    let store = scanmill::store::Store::open(db).unwrap();
    let c = store.connection();
    c.execute_batch("BEGIN").unwrap();
    let now = scanmill::store::now_ms();
    let day = 86_400_000i64;
    for id in 1..=n {
        let root = roots[(id % 7 == 0) as usize];
        let created = now - 60 * day + id * (60 * day / n);
        insert_job(c, id, root, created);
    }
    c.execute_batch("COMMIT").unwrap();
}

const RECIPE: &str = r#"{"output":{"format":"obj"},"steps":[{"kind":"relax"},{"kind":"fair"},{"kind":"decimate","target_faces":26000},{"kind":"seam_fix"},{"kind":"normals"}]}"#;

/// One job as the daemon records it (attempt id = job id): every 50 jobs, two failed and
/// one quarantined.
fn insert_job(c: &rusqlite::Connection, id: i64, root: &str, created: i64) {
    let dir = format!("study{}/subject{id}", id % 40);
    let rel = format!("{dir}/scan.obj");
    let finished = created + 10_000;
    let (state, kind, error) = match id % 50 {
        0 | 1 => (
            "failed",
            Some("input"),
            Some(format!("{rel}: line 7: expected 3 numbers")),
        ),
        2 => (
            "quarantined",
            Some("timeout"),
            Some("did not finish within job_timeout_secs".into()),
        ),
        _ => ("done", None, None),
    };
    let done = state == "done";
    let key = format!("{id:064x}");
    c.prepare_cached(
        "INSERT INTO job(id, job_key, set_hash, root, rel_path, output_root, recipe_path, recipe_hash,
            recipe_json, config_hash, state, attempts, max_attempts, run_after, created_at, updated_at,
            started_at, finished_at, output_dir, error_kind, error, in_vertices, in_faces, out_vertices,
            out_faces, process_ms, report_json, preview)
         VALUES (?1, ?2, ?2, ?3, ?4, '/srv/out', '/etc/scanmill/face-scan.toml', 'rh', ?5, 'ch', ?6, 1, 3,
            ?7, ?7, ?8, ?7, ?8, ?9, ?10, ?11, 210000, 400000, 13500, 26000, ?12, ?13, ?14)",
    )
    .unwrap()
    .execute(rusqlite::params![
        id, key, root, rel, RECIPE, state, created, finished,
        done.then(|| format!("/srv/out/{dir}/scan")),
        kind, error,
        done.then_some(9000.0 + (id % 13) as f64 * 700.0),
        done.then(|| synthetic_report(id)),
        done.then(|| format!("/srv/out/{dir}/scan/scan.preview.png")),
    ])
    .unwrap();
    let outcome = if done { "ok" } else { state };
    c.prepare_cached(
        "INSERT INTO attempt(id, job_id, n, owner, host, app_version, started_at, finished_at, outcome,
            error_kind, error, wall_ms) VALUES (?1, ?1, 1, 'pid1', 'lab', '0.1.0', ?2, ?3, ?4, ?5, ?6, 9000)",
    )
    .unwrap()
    .execute(rusqlite::params![id, created, finished, outcome, kind, error])
    .unwrap();
    if done {
        insert_results(c, id, &dir, &key);
    }
    for (f, role) in [
        ("scan.obj", "mesh"),
        ("scan.mtl", "mtl"),
        ("scan.jpg", "texture"),
    ] {
        c.prepare_cached(
            "INSERT INTO job_input(job_id, rel_path, role, size, mtime_ns, ino, sha256)
             VALUES (?1, ?2, ?3, 1000000, 0, ?1, ?4)",
        )
        .unwrap()
        .execute(rusqlite::params![id, format!("{dir}/{f}"), role, key])
        .unwrap();
    }
    c.prepare_cached(
        "INSERT INTO sighting(job_id, root, rel_path, seen_at) VALUES (?1, ?2, ?3, ?4)",
    )
    .unwrap()
    .execute(rusqlite::params![id, root, rel, created])
    .unwrap();
}

/// A finished job's step timings and output files.
fn insert_results(c: &rusqlite::Connection, id: i64, dir: &str, key: &str) {
    for (i, k) in ["relax", "fair", "decimate", "seam_fix", "normals"]
        .iter()
        .enumerate()
    {
        c.prepare_cached(
            "INSERT INTO step_timing(attempt_id, idx, kind, wall_ms, vertices_before, vertices_after,
                faces_before, faces_after, figures_json) VALUES (?1, ?2, ?3, 800, 210000, 13500, 400000, 26000, '{}')",
        )
        .unwrap()
        .execute(rusqlite::params![id, i as i64 + 1, k])
        .unwrap();
    }
    for f in ["scan.obj", "scan.mtl", "scan.jpg", "scan.scanmill.json"] {
        c.prepare_cached(
            "INSERT INTO job_output(job_id, path, bytes, sha256) VALUES (?1, ?2, 1000000, ?3)",
        )
        .unwrap()
        .execute(rusqlite::params![
            id,
            format!("/srv/out/{dir}/scan/{f}"),
            key
        ])
        .unwrap();
    }
}

/// Median, 90th percentile and maximum of `runs` GETs of `url` (ms, client side, over
/// loopback: HTTP included); the body is checked once.
fn time_get(url: &str, runs: usize) -> (f64, f64, f64, String) {
    let a = agent();
    let mut times = Vec::with_capacity(runs);
    let mut body = String::new();
    for _ in 0..runs {
        let start = std::time::Instant::now();
        let mut r = a.get(url).call().unwrap();
        let text = r.body_mut().read_to_string().unwrap();
        times.push(start.elapsed().as_secs_f64() * 1e3);
        assert_eq!(r.status().as_u16(), 200, "{url}");
        body = text;
    }
    times.sort_by(f64::total_cmp);
    (times[runs / 2], times[runs * 9 / 10], times[runs - 1], body)
}

#[test]
#[ignore = "fills a store with 100,000 jobs (about a minute) and prints page timings; run by hand: \
            cargo test --test daemon_web page_timings -- --ignored --nocapture"]
fn page_timings_on_a_store_of_100k_jobs() {
    let n = std::env::var("SCANMILL_WEB_JOBS").map_or(100_000, |v| v.parse().unwrap());
    let lab = web_lab("");
    let root = lab.inbox().to_string_lossy().into_owned();
    let started = std::time::Instant::now();
    fill_store(
        &lab.dir.path().join("state/scanmill.sqlite"),
        [&root, "/srv/scans/b"],
        n,
    );
    eprintln!(
        "filled {n} jobs in {:.1} s",
        started.elapsed().as_secs_f64()
    );
    let _d = KillOnDrop(lab.start(&[]));
    let base = base_url(&lab);
    let day = |back: i64| {
        scanmill::store::query::iso_time(scanmill::store::now_ms() - back * 86_400_000)[..10]
            .to_string()
    };
    let pages = [
        ("job list, newest", String::new()),
        (
            "job list, a page in the middle",
            format!("?before={}", n / 2),
        ),
        ("job list, state=failed", "?state=failed".into()),
        (
            "job list, the smaller folder",
            "?root=%2Fsrv%2Fscans%2Fb".into(),
        ),
        (
            "job list, 10 days in the middle",
            format!("?from={}&to={}", day(35), day(25)),
        ),
        (
            "job list, name search (11 hits, whole table)",
            "?q=subject9999".into(),
        ),
        ("job page", format!("jobs/{}", n / 2 + 3)),
        ("trends (28 days)", "trends".into()),
        ("health", "health".into()),
        ("metrics", "metrics".into()),
    ];
    eprintln!("{:<46} {:>8} {:>8} {:>8}", "page", "median", "p90", "max");
    for (name, path) in pages {
        let url = format!("{base}{path}");
        let _ = time_get(&url, 2);
        let (median, p90, max, body) = time_get(&url, 21);
        if name.starts_with("job list") && !name.contains("search") {
            assert_eq!(ids(&body).len(), 50, "{name}: a full page");
        }
        eprintln!("{name:<46} {median:>6.1}ms {p90:>6.1}ms {max:>6.1}ms");
    }
}
