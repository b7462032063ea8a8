//! The machine's speed at the time of a measurement: the median time of a fixed
//! single-threaded workload (sorting 4 million pseudo-random integers). This machine's speed
//! varies by up to 2× between hours (docs/face-scan.md); printing this beside the medians
//! tells a slow hour from a slower scanmill. One copy, shared by the face_scan bench and the
//! `machine_reference` example (which scripts/vs_meshlab.py runs).

use std::time::Instant;

/// Median milliseconds of five sorts of the same 4 million xorshift64 integers.
pub fn reference_workload_ms() -> f64 {
    let mut times = Vec::new();
    for _ in 0..5 {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut values: Vec<u64> = (0..4_000_000)
            .map(|_| {
                // xorshift64
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state
            })
            .collect();
        let start = Instant::now();
        values.sort_unstable();
        times.push(start.elapsed().as_secs_f64() * 1e3);
        std::hint::black_box(&values);
    }
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}
