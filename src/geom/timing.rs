//! The process's CPU time, for phase timings beside wall time (on a shared machine wall time
//! alone says little).

/// CPU time of the process (all its threads) in seconds; 0 if the clock cannot be read.
pub fn cpu_seconds() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; the call only writes it.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    if rc != 0 {
        return 0.0;
    }
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

#[cfg(test)]
mod tests {
    #[test]
    fn cpu_time_grows_with_work() {
        let before = super::cpu_seconds();
        let mut x = 0u64;
        while super::cpu_seconds() <= before {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
        }
        assert!(super::cpu_seconds() > before, "{x}");
    }
}
