//! Helpers shared by the unit tests of several modules.

/// `f` run in a rayon pool of its own with `threads` threads, for tests that a result does
/// not depend on the thread count.
pub fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}
