//! A job runs on a thread of rayon's pool (`process::on_pool`); its log lines must still
//! carry the caller's span, where the daemon's worker process names its job. A test binary
//! of its own: it installs the process's global subscriber.
//! The decimation's halves run side by side (`rayon::join`); the second, on another thread,
//! must carry the span too.

use std::io::Write;
use std::sync::{Arc, Mutex, OnceLock};

/// Log output collected in memory.
#[derive(Clone, Default)]
struct Captured(Arc<Mutex<Vec<u8>>>);

impl Write for Captured {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(bytes);
        Ok(bytes.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// The process's one subscriber, writing into memory (installed by the first test).
fn captured() -> &'static Captured {
    static CAPTURED: OnceLock<Captured> = OnceLock::new();
    CAPTURED.get_or_init(|| {
        let captured = Captured::default();
        let writer = captured.clone();
        tracing_subscriber::fmt()
            .with_writer(move || writer.clone())
            .with_ansi(false)
            .with_target(false)
            .init();
        captured
    })
}

/// The lines logged so far that contain `needle`.
fn lines_with(needle: &str) -> Vec<String> {
    let text = String::from_utf8(captured().0.lock().unwrap().clone()).unwrap();
    text.lines()
        .filter(|l| l.contains(needle))
        .map(str::to_string)
        .collect()
}

#[test]
fn a_job_on_the_pool_logs_under_the_callers_span() {
    captured();
    let span = tracing::info_span!("worker", job_id = 7);
    let on_thread = span.in_scope(|| {
        scanmill::process::on_pool(|| {
            tracing::info!("inside the job");
            std::thread::current().id()
        })
    });
    assert_ne!(
        on_thread,
        std::thread::current().id(),
        "the job ran on the pool"
    );
    let lines = lines_with("inside the job");
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(
        lines[0].contains("worker{job_id=7}: inside the job"),
        "{lines:?}"
    );
}

#[test]
fn both_halves_of_a_decimation_log_under_the_step() {
    use scanmill::ops::decimate::{DecimateParams, Halves, decimate};
    captured();
    let mesh = scanmill::mesh::shapes::uv_sphere(1.0, 60, 120);
    let params = DecimateParams {
        target_faces: Some(2_000),
        halves: Halves::On,
        ..DecimateParams::default()
    };
    let span = tracing::info_span!("halves_test");
    let (out, report) = span
        .in_scope(|| scanmill::process::on_pool(|| decimate(&mesh, &params)))
        .unwrap();
    assert!(report.halves.is_some(), "decimated in halves");
    assert!(out.triangles.len() <= 2_000);
    // One line per half, one for the pass over the whole, one for the step: all under the
    // caller's span.
    let lines = lines_with("decimated method=");
    assert_eq!(lines.len(), 4, "{lines:?}");
    assert!(
        lines.iter().all(|l| l.contains("halves_test: decimated")),
        "{lines:?}"
    );
}
