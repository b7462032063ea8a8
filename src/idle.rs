//! Work for a core that the job's sequential parts leave idle.
//!
//! Much of a job is parallel, but parts are not: the end of the load, building the
//! topology before `relax`, a border faired as a curve, the last pass of the decimation.
//! Work that needs nothing of the steps (the preview's input panel) is done on a thread
//! of the lowest priority beside them: the scheduler gives it a core when one is idle, and
//! almost nothing while both are busy, so it does not slow the steps it runs beside.

/// Runs `work` on a thread of its own at the lowest scheduling priority (nice 19), with
/// rayon inside it confined to that thread. Blocks until `work` is done; call it from a
/// thread that has nothing else to do (a scoped thread).
pub fn run_when_idle<T: Send>(work: impl FnOnce() -> T + Send) -> T {
    match rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .thread_name(|_| "scanmill-idle".into())
        .start_handler(|_| lower_own_priority())
        .build()
    {
        Ok(pool) => pool.install(work),
        // No thread to be had: do it here, now.
        Err(_) => work(),
    }
}

/// Lowers the calling thread's priority to the least (nice 19). Under Linux the nice value
/// is a thread's own (NPTL), so this leaves the rest of the process as it was.
fn lower_own_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: setpriority takes no pointers; `who = 0` is the calling thread. Raising one's
    // own nice value is always permitted. A failure leaves the priority as it was, which
    // is harmless.
    unsafe {
        libc::setpriority(libc::PRIO_PROCESS, 0, 19);
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn work_runs_and_returns_its_value_at_low_priority() {
        let (value, nice) = super::run_when_idle(|| {
            // SAFETY: getpriority takes no pointers.
            let nice = unsafe { libc::getpriority(libc::PRIO_PROCESS, 0) };
            (rayon::current_num_threads(), nice)
        });
        assert_eq!(value, 1);
        #[cfg(target_os = "linux")]
        assert_eq!(nice, 19);
        let _ = nice;
    }
}
