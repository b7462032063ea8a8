//! Prefetch hints for the collapse loop. The loop is bound by memory latency, not
//! arithmetic: each collapse starts where the heap's cheapest merge happens to be, and its
//! records (corner lists, vertex quadrics, positions, the heap's own entries) are seldom in
//! cache. Asking for them a little before they are read lets several misses overlap.
//! A prefetch is a hint: nothing computed depends on it, so the output is the same with or
//! without (docs/decimation.md, "Where the collapse loop waits").

/// Bytes in a cache line (x86_64).
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
const LINE: usize = 64;

/// How many cache lines the `bytes` bytes from address `addr` touch.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
fn lines_spanned(addr: usize, bytes: usize) -> usize {
    if bytes == 0 {
        0
    } else {
        ((addr % LINE) + bytes).div_ceil(LINE)
    }
}

/// Asks the memory for the cache lines of `items[first..first + count]`, without waiting
/// for them. Out-of-range indices are harmless (the hint is dropped).
#[inline(always)]
pub(super) fn prefetch_span<T>(items: &[T], first: usize, count: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let start = items.as_ptr().wrapping_add(first).cast::<i8>();
        let bytes = count * size_of::<T>();
        // SAFETY (every call below): a prefetch is only a hint: it reads nothing into the
        // program and never faults, whatever the address (`wrapping_add` makes no in-bounds
        // claim).
        let hint = |at: usize| unsafe { _mm_prefetch::<_MM_HINT_T0>(start.wrapping_add(at)) };
        match bytes {
            0 => {}
            // The lines of the first byte, of the one 64 bytes on and of the last byte are
            // every line of up to 128 bytes (a line asked for twice costs next to nothing);
            // for the records read here (at most 80 bytes) the sizes are mostly constants,
            // so these branches fold away.
            1..=LINE => {
                hint(0);
                hint(bytes - 1);
            }
            65..=128 => {
                hint(0);
                hint(LINE);
                hint(bytes - 1);
            }
            _ => {
                for l in 0..lines_spanned(start as usize, bytes) {
                    hint(l * LINE);
                }
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (items, first, count);
}

/// [`prefetch_span`] of the one item `items[i]`.
#[inline(always)]
pub(super) fn prefetch<T>(items: &[T], i: usize) {
    prefetch_span(items, i, 1);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_span_touches_the_lines_of_its_first_and_last_byte() {
        assert_eq!(lines_spanned(0, 0), 0);
        assert_eq!(lines_spanned(0, 64), 1);
        assert_eq!(lines_spanned(63, 1), 1);
        assert_eq!(lines_spanned(63, 2), 2);
        // An 80-byte reduced quadric at a 16-byte offset: two lines; at 48, still two.
        assert_eq!(lines_spanned(16, 80), 2);
        assert_eq!(lines_spanned(48 + 640, 80), 2);
        assert_eq!(lines_spanned(56, 80), 3);
    }
}
