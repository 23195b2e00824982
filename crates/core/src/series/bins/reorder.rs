//! Grouping rows that arrive out of time order before they are accumulated: a stable counting
//! sort by a small key (time block, bin or span) and an exact division by the bin length.
//!
//! Separate because it is a pure reordering tool with its own thresholds; the accumulator only
//! decides when to use it.

use crate::campaign::TimeNs;

/// Rows at least this many out of time order are grouped by time block before they are added.
pub(super) const MIN_BLOCK_SORT_ROWS: usize = 256;
/// Most time blocks of one grouping.
pub(super) const MAX_SORT_BLOCKS: u64 = 1 << 16;
/// Most spans (zero segments and handling times) rows out of order are split over before they
/// are sorted by bin: a batch of a day file crosses a few; more go by blocks.
pub(super) const MAX_SPLIT_SPANS: usize = 64;

/// The first and last of `time_ns` (one pass); `None` when empty.
pub(super) fn time_range(time_ns: &[TimeNs]) -> Option<(TimeNs, TimeNs)> {
    let (&head, rest) = time_ns.split_first()?;
    Some(
        rest.iter()
            .fold((head, head), |(a, b), &t| (a.min(t), b.max(t))),
    )
}

/// Reused buffers of a counting sort of rows by a small key (time block, bin or span).
#[derive(Debug, Clone, Default)]
pub(super) struct BlockScratch {
    /// Each row's key.
    pub(super) block: Vec<u32>,
    /// `start[g]..start[g + 1]`: the sorted rows of key `g`.
    pub(super) start: Vec<usize>,
    next: Vec<usize>,
    pub(super) time: Vec<TimeNs>,
    pub(super) counts: Vec<i64>,
}

impl BlockScratch {
    /// Stable counting sort of the rows `time_ns`/`counts` by their keys in `block` (each below
    /// `groups`) into `time`/`counts`. The positions are counted with wrapping additions: they
    /// are below the rows' number, and ingest sorts every shuffled row through here, where the
    /// overflow checks our crates build with would be a branch per row and counter.
    pub(super) fn sort_by_block(&mut self, groups: usize, time_ns: &[TimeNs], counts: &[i64]) {
        let Self {
            block,
            start,
            next,
            time,
            counts: sorted_counts,
        } = self;
        start.clear();
        start.resize(groups + 1, 0);
        for &b in block.iter() {
            let slot = &mut start[b as usize + 1];
            *slot = slot.wrapping_add(1);
        }
        for g in 0..groups {
            start[g + 1] = start[g + 1].wrapping_add(start[g]);
        }
        next.clear();
        next.extend_from_slice(&start[..groups]);
        let n = block.len().min(time_ns.len()).min(counts.len());
        time.resize(n, 0);
        sorted_counts.resize(n, 0);
        let (time, sorted_counts) = (&mut time[..n], &mut sorted_counts[..n]);
        for ((&b, &t), &c) in block.iter().zip(time_ns).zip(counts) {
            let at = &mut next[b as usize];
            time[*at] = t;
            sorted_counts[*at] = c;
            *at = at.wrapping_add(1);
        }
    }
}

/// Exact unsigned division by a fixed divisor with a multiplication: `m = ⌊(2⁶⁴ − 1) / d⌋`
/// gives `⌊n m / 2⁶⁴⌋` at most 2 below `⌊n / d⌋`, corrected by comparing the remainder with `d`
/// (a 64-bit `div` takes several times longer, once per shuffled row).
#[derive(Debug, Clone, Copy)]
pub(super) struct Divide {
    d: u64,
    m: u64,
}

impl Divide {
    pub(super) fn new(d: u64) -> Divide {
        let d = d.max(1);
        Divide { d, m: u64::MAX / d }
    }

    #[inline]
    pub(super) fn quotient(&self, n: u64) -> u64 {
        // q ≤ n / d, so q d ≤ n and nothing below can wrap (wrapping: no overflow check paid
        // on every shuffled row).
        let mut q = ((n as u128 * self.m as u128) >> 64) as u64;
        let mut r = n.wrapping_sub(q.wrapping_mul(self.d));
        while r >= self.d {
            q = q.wrapping_add(1);
            r = r.wrapping_sub(self.d);
        }
        q
    }
}
