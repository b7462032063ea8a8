//! Handing freed memory back to the operating system between the big phases of a job.
//!
//! A job allocates and frees buffers of hundreds of megabytes from different rayon threads
//! (the input, each step's working arrays, the metrics' indices). glibc's malloc keeps freed
//! memory in per-thread arenas, where the next phase, running on other threads, may not reuse
//! it: resident memory then grows with every phase instead of staying near the largest one.
//! On a 400k-triangle face scan decimated with metrics on, resident memory peaked at 166 MB
//! without this and 143 MB with it (issue #8's budget is 400 bytes per input triangle,
//! 160 MB). mimalloc as the global allocator was tried instead and peaked higher (181 MB).

/// Returns freed heap memory to the operating system (glibc's `malloc_trim`); elsewhere a
/// no-op. Cheap next to a processing step: call it between phases, not in loops.
pub fn release_freed() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only walks the allocator's own free lists; it takes no pointers
    // from us and is documented as safe to call at any time from any thread.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Threshold from which glibc serves an allocation with its own `mmap` (and unmaps it when
/// it is freed), kept fixed (see [`configure`]). Measured on the face-scan recipe, 400k-triangle
/// face, four runs each: glibc's own (dynamic) threshold peaked at 148–153 MB; fixed at 2 MB,
/// 136–138 MB but about 2 % slower (every array above 2 MB is then fresh pages, faulted in
/// and zeroed again, in every sweep of `relax` and `fair`); fixed at 8 MB, 141–142 MB at the
/// same speed as glibc's.
pub const MMAP_THRESHOLD: usize = 8 << 20;

/// Process-wide allocator settings for the binary (call once, first thing in `main`).
///
/// glibc raises its `mmap` threshold each time a large `mmap`ed block is freed, up to 32
/// MB. After the first big phase of a job, the next phase's arrays of tens of megabytes then
/// come from the per-thread arenas instead. There they stay when freed: in whichever arena
/// the freeing thread used, fragmented, and resident until a trim. With the threshold fixed,
/// every array above it is its own mapping and goes back to the operating system when freed.
/// Issue #8's budget for the 400k-triangle face is 160 MB; the edge collapse in halves on
/// the 400k coral (`examples/decimate`) peaked at 198 MB with glibc's threshold.
pub fn configure() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets an allocator parameter; it is called before any thread is
    // started.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD as libc::c_int);
    }
}
