//! Deterministic work sharing over fixed row blocks with `std::thread::scope`.
//!
//! The rows `0..n` are cut into blocks of a fixed size that does not depend on the number of
//! threads; each block's result depends only on its rows, and results come back in block
//! order. So the output is the same bit for bit on one core or many.

use std::ops::Range;

/// Below this much work (rows × cost per row) everything runs on the calling thread.
pub(crate) const PARALLEL_MIN_WORK: usize = 1 << 18;

/// The row ranges `[0, block), [block, 2·block), …` covering `0..n`.
pub(crate) fn block_ranges(n: usize, block: usize) -> Vec<Range<usize>> {
    let block = block.max(1);
    (0..n.div_ceil(block))
        .map(|b| b * block..((b + 1) * block).min(n))
        .collect()
}

/// Applies `f` to every block of `block` rows of `0..n` and returns the results in block
/// order, using up to the available cores when `n · cost_per_row` is large enough.
pub(crate) fn map_blocks<T, F>(n: usize, block: usize, cost_per_row: usize, f: F) -> Vec<T>
where
    T: Send,
    F: Fn(Range<usize>) -> T + Sync,
{
    let ranges = block_ranges(n, block);
    let threads = if n.saturating_mul(cost_per_row) < PARALLEL_MIN_WORK {
        1
    } else {
        std::thread::available_parallelism()
            .map_or(1, |c| c.get())
            .min(ranges.len())
    };
    if threads <= 1 {
        return ranges.into_iter().map(&f).collect();
    }
    let per_thread = ranges.len().div_ceil(threads);
    let f = &f;
    std::thread::scope(|scope| {
        let handles: Vec<_> = ranges
            .chunks(per_thread)
            .map(|chunk| scope.spawn(move || chunk.iter().cloned().map(f).collect::<Vec<T>>()))
            .collect();
        handles
            .into_iter()
            .flat_map(|h| match h.join() {
                Ok(part) => part,
                Err(panic) => std::panic::resume_unwind(panic),
            })
            .collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_cover_the_rows_in_order() {
        assert_eq!(block_ranges(7, 3), vec![0..3, 3..6, 6..7]);
        assert_eq!(block_ranges(6, 3), vec![0..3, 3..6]);
        assert!(block_ranges(0, 3).is_empty());
    }

    #[test]
    fn parallel_and_serial_results_agree() {
        let f = |r: Range<usize>| r.map(|i| (i as f64).sqrt()).sum::<f64>();
        let serial = map_blocks(10_000, 64, 1, f);
        let parallel = map_blocks(10_000, 64, PARALLEL_MIN_WORK, f);
        assert_eq!(serial.len(), 157);
        assert_eq!(serial, parallel);
    }
}
