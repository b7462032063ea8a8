//! The web dashboard and `/metrics` (docs/service.md "Web dashboard and metrics"): served by
//! the daemon on its own tokio runtime, read-only.
//!
//! Rules:
//! - the service loop and the store writer are never waited on: every query runs on
//!   tokio's blocking pool, on connections of the dashboard's own (SQLite: read-only WAL
//!   readers; PostgreSQL: connections that only read), at most [`MAX_CONCURRENT_QUERIES`] at
//!   a time;
//! - pages are HTML rendered here, without script; the Content-Security-Policy forbids
//!   script altogether, and every scanner-provided string is escaped ([`html::esc`]);
//! - files are served by job id only: a preview is the path the store recorded for that
//!   job, resolved, inside one of the configured output folders, a regular file, a PNG or
//!   JPEG, at most [`MAX_PREVIEW_BYTES`]. Nothing in a request names a path.

mod config;
pub mod html;
mod pages;
pub mod params;
mod prometheus;
pub mod reader;
mod thumbs;
mod trends;

pub use config::WebConfig;

use crate::store::{StoreError, now_ms};
use axum::Router;
use axum::extract::{Path as UrlPath, Query, Request, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use reader::{DashboardReader, SqliteReader};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use tokio::sync::Semaphore;

/// Queries running at the same time (each holds a read connection and a blocking thread).
pub const MAX_CONCURRENT_QUERIES: usize = 4;
/// Largest preview file served.
pub const MAX_PREVIEW_BYTES: u64 = 64 << 20;

/// What the daemon is doing, as the service loop last saw it.
#[derive(Debug, Clone, PartialEq)]
pub enum DaemonState {
    Starting,
    Idle,
    Working,
    /// Claiming paused, with the reason (low disk).
    Paused(String),
    Draining,
}

impl DaemonState {
    pub fn label(&self) -> &str {
        match self {
            DaemonState::Starting => "starting",
            DaemonState::Idle => "idle",
            DaemonState::Working => "working",
            DaemonState::Paused(reason) => reason,
            DaemonState::Draining => "draining",
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct LiveStatus {
    pub state: DaemonState,
    pub running: i64,
    pub workers: usize,
    pub started_ms: i64,
}

/// The service loop's status, shared with the dashboard (a lock held for a copy only).
#[derive(Debug, Clone)]
pub struct Live(Arc<Mutex<LiveStatus>>);

impl Live {
    pub fn new(workers: usize) -> Live {
        Live(Arc::new(Mutex::new(LiveStatus {
            state: DaemonState::Starting,
            running: 0,
            workers,
            started_ms: now_ms(),
        })))
    }

    pub fn set(&self, state: DaemonState, running: i64) {
        let mut s = self.0.lock().unwrap_or_else(|p| p.into_inner());
        s.state = state;
        s.running = running;
    }

    pub fn get(&self) -> LiveStatus {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }
}

/// A watched folder as the Health page lists it: (folder, output, recipe), printable.
pub type RootLine = (String, String, String);

/// Everything the handlers share.
struct Shared {
    store: StoreSource,
    pool: Mutex<Vec<Box<dyn DashboardReader>>>,
    permits: Semaphore,
    live: Live,
    roots: Vec<RootLine>,
    /// The configured output folders, every link resolved.
    outputs: Vec<PathBuf>,
    token: Option<String>,
    thumbs: thumbs::Thumbs,
}

/// The store the dashboard reads.
#[derive(Clone)]
pub enum StoreSource {
    Sqlite(PathBuf),
    Postgres(Box<crate::store::pg::conninfo::ConnInfo>),
}

impl StoreSource {
    /// A new reader on it (the pool keeps it for the next request).
    fn open(&self) -> Result<Box<dyn DashboardReader>, StoreError> {
        Ok(match self {
            StoreSource::Sqlite(path) => Box::new(SqliteReader::open(path)?),
            StoreSource::Postgres(info) => Box::new(crate::store::pg::dashboard::PgReader::new(
                crate::store::pg::PgStore::open_existing((**info).clone())?,
            )),
        })
    }
}

/// What the daemon hands the dashboard.
pub struct Setup {
    pub config: WebConfig,
    pub store: StoreSource,
    pub live: Live,
    pub roots: Vec<RootLine>,
    pub outputs: Vec<PathBuf>,
}

/// Binds the listening socket (so that a port in use stops the daemon before it is
/// ready) and starts serving on `runtime`. Returns the address bound.
pub fn start(
    runtime: &tokio::runtime::Runtime,
    setup: Setup,
) -> std::io::Result<std::net::SocketAddr> {
    let addr = setup.config.address().ok_or_else(|| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "web.listen is not an address",
        )
    })?;
    let listener = std::net::TcpListener::bind(addr)?;
    listener.set_nonblocking(true)?;
    let bound = listener.local_addr()?;
    let shared = Arc::new(Shared {
        store: setup.store,
        pool: Mutex::new(Vec::new()),
        permits: Semaphore::new(MAX_CONCURRENT_QUERIES),
        live: setup.live,
        roots: setup.roots,
        outputs: setup
            .outputs
            .iter()
            .map(|o| crate::config::resolved(o))
            .collect(),
        token: setup.config.token.clone(),
        thumbs: thumbs::Thumbs::default(),
    });
    let app = router(shared);
    runtime.spawn(async move {
        let listener = match tokio::net::TcpListener::from_std(listener) {
            Ok(l) => l,
            Err(e) => {
                tracing::error!("web dashboard: {e}");
                return;
            }
        };
        if let Err(e) = axum::serve(listener, app).await {
            tracing::error!("web dashboard stopped: {e}");
        }
    });
    Ok(bound)
}

fn router(shared: Arc<Shared>) -> Router {
    Router::new()
        .route("/", get(jobs))
        .route("/jobs/{id}", get(job))
        .route("/jobs/{id}/preview", get(preview))
        .route("/jobs/{id}/thumb", get(thumb))
        .route("/trends", get(trends_handler))
        .route("/health", get(health))
        .route("/metrics", get(metrics))
        .route("/static/style.css", get(style))
        .fallback(not_found)
        .layer(middleware::from_fn_with_state(shared.clone(), guard))
        .with_state(shared)
}

/// Why a request got no page.
#[derive(Debug)]
enum WebError {
    NotFound(String),
    BadRequest(String),
    Unavailable(String),
}

impl From<StoreError> for WebError {
    fn from(e: StoreError) -> WebError {
        tracing::warn!("web dashboard: {e}");
        WebError::Unavailable(e.to_string())
    }
}

impl IntoResponse for WebError {
    fn into_response(self) -> Response {
        let (code, title, message) = match self {
            WebError::NotFound(m) => (StatusCode::NOT_FOUND, "Not found", m),
            WebError::BadRequest(m) => (StatusCode::BAD_REQUEST, "Bad request", m),
            WebError::Unavailable(m) => (StatusCode::SERVICE_UNAVAILABLE, "Store unavailable", m),
        };
        (code, html_page(pages::message_page(title, &message))).into_response()
    }
}

fn html_page(body: String) -> impl IntoResponse {
    ([(header::CONTENT_TYPE, "text/html; charset=utf-8")], body)
}

/// Runs `f` on a read connection, on the blocking pool.
async fn read<T: Send + 'static>(
    shared: &Arc<Shared>,
    f: impl FnOnce(&dyn DashboardReader) -> Result<T, StoreError> + Send + 'static,
) -> Result<T, WebError> {
    let _permit = shared
        .permits
        .acquire()
        .await
        .map_err(|e| WebError::Unavailable(e.to_string()))?;
    let shared = shared.clone();
    let joined = tokio::task::spawn_blocking(move || {
        let pooled = shared.pool.lock().unwrap_or_else(|p| p.into_inner()).pop();
        let reader: Box<dyn DashboardReader> = match pooled {
            Some(r) => r,
            None => shared.store.open()?,
        };
        let result = f(reader.as_ref());
        if result.is_ok() {
            shared
                .pool
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .push(reader);
        }
        result
    })
    .await;
    match joined {
        Ok(r) => Ok(r?),
        Err(e) => Err(WebError::Unavailable(format!("query stopped: {e}"))),
    }
}

async fn jobs(
    State(shared): State<Arc<Shared>>,
    Query(params): Query<HashMap<String, String>>,
) -> Result<impl IntoResponse, WebError> {
    let q = params::job_query(&params).map_err(WebError::BadRequest)?;
    let (from, to) = (params::echo(&params, "from"), params::echo(&params, "to"));
    let query = q.clone();
    let (page, roots) = read(&shared, move |r| Ok((r.jobs(&query)?, r.roots()?))).await?;
    Ok(html_page(pages::jobs_page(&page, &q, &roots, &from, &to)))
}

fn job_id(text: &str) -> Result<i64, WebError> {
    text.parse::<i64>()
        .ok()
        .filter(|id| *id > 0 && text.bytes().all(|b| b.is_ascii_digit()))
        .ok_or_else(|| WebError::NotFound(format!("no job {text}")))
}

async fn job(
    State(shared): State<Arc<Shared>>,
    UrlPath(id): UrlPath<String>,
) -> Result<impl IntoResponse, WebError> {
    let id = job_id(&id)?;
    let shown = read(&shared, move |r| r.job(id)).await?;
    let shown = shown.ok_or_else(|| WebError::NotFound(format!("no job {id}")))?;
    Ok(html_page(pages::job_page(id, &shown)))
}

async fn preview(
    State(shared): State<Arc<Shared>>,
    UrlPath(id): UrlPath<String>,
) -> Result<impl IntoResponse, WebError> {
    let id = job_id(&id)?;
    let outputs = shared.outputs.clone();
    let found = read(&shared, move |r| {
        Ok(r.preview(id)?
            .and_then(|(file, root)| load_preview(&file, &root, &outputs)))
    })
    .await?;
    let (bytes, kind) =
        found.ok_or_else(|| WebError::NotFound(format!("job {id} has no preview")))?;
    Ok(([(header::CONTENT_TYPE, kind)], bytes))
}

/// The preview scaled down for the job list (PNG).
async fn thumb(
    State(shared): State<Arc<Shared>>,
    UrlPath(id): UrlPath<String>,
) -> Result<impl IntoResponse, WebError> {
    let id = job_id(&id)?;
    let worker = shared.clone();
    let found = read(&shared, move |r| {
        Ok(r.preview(id)?
            .and_then(|(file, root)| load_preview(&file, &root, &worker.outputs))
            .and_then(|(bytes, _)| worker.thumbs.get(id, &bytes)))
    })
    .await?;
    let png = found.ok_or_else(|| WebError::NotFound(format!("job {id} has no preview")))?;
    Ok(([(header::CONTENT_TYPE, "image/png")], png.as_ref().clone()))
}

/// The recorded preview of a job, if it is a PNG or JPEG regular file that lies, every
/// link resolved, inside its job's output root and that inside a configured output folder.
fn load_preview(file: &Path, root: &Path, outputs: &[PathBuf]) -> Option<(Vec<u8>, &'static str)> {
    let real = file.canonicalize().ok()?;
    let real_root = root.canonicalize().ok()?;
    if !real.starts_with(&real_root) || !outputs.iter().any(|o| real_root.starts_with(o)) {
        tracing::warn!(file = %crate::text::escape_path(file), "preview outside the output folders: not served");
        return None;
    }
    let bytes = crate::mesh::files::read_whole(
        &real,
        MAX_PREVIEW_BYTES,
        crate::mesh::limits::Limit::FileBytes,
    )
    .ok()?;
    let kind = if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        "image/png"
    } else if bytes.starts_with(&[0xff, 0xd8, 0xff]) {
        "image/jpeg"
    } else {
        return None;
    };
    Some((bytes, kind))
}

async fn trends_handler(
    State(shared): State<Arc<Shared>>,
    Query(params): Query<HashMap<String, String>>,
) -> Result<impl IntoResponse, WebError> {
    let window = params::trend_days(&params).map_err(WebError::BadRequest)?;
    let today = now_ms().div_euclid(86_400_000);
    let first = today - window + 1;
    let days = read(&shared, move |r| r.trends(first * 86_400_000)).await?;
    Ok(html_page(trends::trends_page(&days, first, today, window)))
}

fn bounds_ms() -> Vec<f64> {
    prometheus::TIME_BUCKETS_SECS
        .iter()
        .map(|s| s * 1e3)
        .collect()
}

async fn health(State(shared): State<Arc<Shared>>) -> Result<impl IntoResponse, WebError> {
    let f = read(&shared, |r| r.figures(&bounds_ms())).await?;
    Ok(html_page(pages::health_page(
        &shared.live.get(),
        &shared.roots,
        &f,
    )))
}

async fn metrics(State(shared): State<Arc<Shared>>) -> Result<impl IntoResponse, WebError> {
    let f = read(&shared, |r| r.figures(&bounds_ms())).await?;
    Ok((
        [(
            header::CONTENT_TYPE,
            "text/plain; version=0.0.4; charset=utf-8",
        )],
        prometheus::render(&f, &shared.live.get()),
    ))
}

async fn style() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/css; charset=utf-8")],
        html::STYLE,
    )
}

async fn not_found() -> WebError {
    WebError::NotFound("no such page".into())
}

/// Every request: the token when one is configured; every response: headers that keep
/// the pages inert (no script, no framing, no sniffing, not cached).
async fn guard(State(shared): State<Arc<Shared>>, request: Request, next: Next) -> Response {
    if let Some(token) = &shared.token
        && !authorized(request.headers(), token)
    {
        let mut r = (StatusCode::UNAUTHORIZED, "a token is required\n").into_response();
        r.headers_mut().insert(
            header::WWW_AUTHENTICATE,
            HeaderValue::from_static("Basic realm=\"scanmill\", charset=\"UTF-8\""),
        );
        return r;
    }
    let mut response = next.run(request).await;
    let h = response.headers_mut();
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(
            "default-src 'none'; img-src 'self'; style-src 'self'; base-uri 'none'; form-action 'self'; frame-ancestors 'none'",
        ),
    );
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    h.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("no-referrer"),
    );
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    response
}

/// `Authorization: Bearer TOKEN`, or Basic with TOKEN as the password (any user name),
/// compared in constant time.
fn authorized(headers: &HeaderMap, token: &str) -> bool {
    use base64::Engine;
    let Some(value) = headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
    else {
        return false;
    };
    if let Some(given) = value.strip_prefix("Bearer ") {
        return same(given.trim().as_bytes(), token.as_bytes());
    }
    if let Some(encoded) = value.strip_prefix("Basic ")
        && let Ok(decoded) = base64::engine::general_purpose::STANDARD.decode(encoded.trim())
        && let Some(colon) = decoded.iter().position(|&b| b == b':')
    {
        return same(&decoded[colon + 1..], token.as_bytes());
    }
    false
}

/// Equality whose time does not depend on where the first difference is.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bearer_and_basic_tokens() {
        let mut h = HeaderMap::new();
        assert!(!authorized(&h, "0123456789abcdef"));
        h.insert(
            header::AUTHORIZATION,
            HeaderValue::from_static("Bearer 0123456789abcdef"),
        );
        assert!(authorized(&h, "0123456789abcdef"));
        assert!(!authorized(&h, "0123456789abcdeF"));
        // "lab:0123456789abcdef"
        h.insert(
            header::AUTHORIZATION,
            HeaderValue::from_static("Basic bGFiOjAxMjM0NTY3ODlhYmNkZWY="),
        );
        assert!(authorized(&h, "0123456789abcdef"));
        assert!(!authorized(&h, "0123456789abcdeg"));
    }

    #[test]
    fn job_ids_are_digits_only() {
        assert_eq!(job_id("12").unwrap(), 12);
        for bad in ["0", "-1", "+1", "..%2F", "1e3", "", "99999999999999999999"] {
            assert!(job_id(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn previews_outside_the_output_folders_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir_all(out.join("job")).unwrap();
        let png = out.join("job/p.png");
        std::fs::write(&png, b"\x89PNG\r\n\x1a\nrest").unwrap();
        let outputs = vec![out.canonicalize().unwrap()];
        assert_eq!(load_preview(&png, &out, &outputs).unwrap().1, "image/png");
        // A recorded path that leaves its root, or a root outside the configured outputs.
        let secret = dir.path().join("secret.png");
        std::fs::write(&secret, b"\x89PNG\r\n\x1a\nsecret").unwrap();
        assert!(load_preview(&out.join("job/../../secret.png"), &out, &outputs).is_none());
        assert!(load_preview(&secret, dir.path(), &outputs).is_none());
        // A link inside the output tree that points out of it.
        std::os::unix::fs::symlink(&secret, out.join("job/link.png")).unwrap();
        assert!(load_preview(&out.join("job/link.png"), &out, &outputs).is_none());
        // Not an image.
        std::fs::write(out.join("job/t.png"), b"<script>").unwrap();
        assert!(load_preview(&out.join("job/t.png"), &out, &outputs).is_none());
    }
}
