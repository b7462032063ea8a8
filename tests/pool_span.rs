//! A job runs on a thread of rayon's pool (`process::on_pool`); its log lines must still
//! carry the caller's span, where the daemon's worker process names its job. A test binary
//! of its own: it installs the process's global subscriber.

use std::io::Write;
use std::sync::{Arc, Mutex};

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

#[test]
fn a_job_on_the_pool_logs_under_the_callers_span() {
    let captured = Captured::default();
    let writer = captured.clone();
    tracing_subscriber::fmt()
        .with_writer(move || writer.clone())
        .with_ansi(false)
        .with_target(false)
        .init();
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
    let text = String::from_utf8(captured.0.lock().unwrap().clone()).unwrap();
    assert!(
        text.contains("worker{job_id=7}: inside the job"),
        "log lines: {text}"
    );
}
