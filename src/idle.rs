//! Work for a core that the job's sequential parts leave idle.
//!
//! Much of a job is parallel, but parts are not: the end of the load, building the
//! topology before `relax`, a border faired as a curve, the last pass of the decimation.
//! Work that needs nothing of the steps (the preview's input panel) is done on a thread
//! of the lowest priority beside them: the scheduler gives it a core when one is idle, and
//! none while both are busy, so it does not slow the steps it runs beside.

/// Runs `work` on a thread of its own at the lowest scheduling priority, with
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

/// Lowers the calling thread's priority to the least: the `SCHED_IDLE` policy, under which
/// it runs only when a core would otherwise idle and any other thread waking up takes the
/// core back at once. Where that is refused, nice 19. Under Linux both are a thread's own
/// (NPTL), so the rest of the process keeps its priority. Measured on the face-scan recipe
/// (400k-triangle face, four alternating runs each): with nice 19 the preview's input panel
/// drawn beside `relax` made it 60 ms slower; with `SCHED_IDLE` it did not.
fn lower_own_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: sched_setscheduler reads the parameter through a pointer to a local that
    // outlives the call; setpriority takes no pointers. `0` is the calling thread.
    // Lowering one's own priority is always permitted, and a failure leaves the priority as
    // it was, which is harmless.
    unsafe {
        let param = libc::sched_param { sched_priority: 0 };
        if libc::sched_setscheduler(0, libc::SCHED_IDLE, &param) != 0 {
            libc::setpriority(libc::PRIO_PROCESS, 0, 19);
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn work_runs_and_returns_its_value_at_low_priority() {
        let (threads, lowered) = super::run_when_idle(|| {
            #[cfg(target_os = "linux")]
            // SAFETY: neither call takes a pointer; `0` is the calling thread.
            let lowered = unsafe {
                libc::sched_getscheduler(0) == libc::SCHED_IDLE
                    || libc::getpriority(libc::PRIO_PROCESS, 0) == 19
            };
            #[cfg(not(target_os = "linux"))]
            let lowered = true;
            (rayon::current_num_threads(), lowered)
        });
        assert_eq!(threads, 1);
        assert!(lowered);
        // The calling thread keeps its own priority.
        #[cfg(target_os = "linux")]
        // SAFETY: as above.
        unsafe {
            assert_ne!(libc::sched_getscheduler(0), libc::SCHED_IDLE);
        }
    }
}
