//! The accumulator that adds a bar's readings, in any order, into the bins of a grid, page by
//! page, and hands back the finished bins ([`BinAccumulator`]).
//!
//! Separate because it is the streaming part of binning: memory layout (spans, pages), locating
//! a reading's bin, and merging accumulators of file batches.

use super::bar_bins::BarBins;
use super::grid::{BinGrid, BinKey, Region};
use super::moments::BinMoments;
use super::reorder::{
    time_range, BlockScratch, Divide, MAX_SORT_BLOCKS, MAX_SPLIT_SPANS, MIN_BLOCK_SORT_ROWS,
};
use super::{
    counts_ok, reading_time_ok, reading_times_ok, BinError, MAX_ABS_COUNTS, MAX_BAR_READINGS,
};
use crate::campaign::TimeNs;

/// Bins per page of a [`BinAccumulator`] (a power of two).
const PAGE_BINS: usize = 64;
const PAGE_SHIFT: u32 = PAGE_BINS.trailing_zeros();
/// Longest dense page table of one span; pages beyond it (bins of microseconds over days, or
/// readings far outside every mount) are kept in a map.
const DENSE_PAGES: i64 = 1 << 16;
const NO_PAGE: u32 = u32::MAX;

/// One stretch of a bar's time line that no bin crosses (a zero segment, or handling time), its
/// bins anchored at `anchor`, and where its bins' moments are stored.
#[derive(Debug, Clone)]
pub(super) struct Span {
    /// `[from, to)`; `TimeNs::MIN` / `TimeNs::MAX` for the handling time before the first and
    /// after the last mount.
    pub(super) from: TimeNs,
    pub(super) to: TimeNs,
    /// Bin `k` of the span starts at `anchor + k bin_ns` (0 before the first mount: bins on the
    /// epoch's grid there).
    anchor: TimeNs,
    region: Region,
    /// Page number of `slots[0]`.
    base: i64,
    /// Page number - `base` -> index into `BinAccumulator::pages` (`NO_PAGE`: no reading yet).
    slots: Vec<u32>,
    /// Pages outside the dense table.
    far: std::collections::HashMap<i64, u32>,
}

/// How [`BinAccumulator::add_by_bin`] numbers the bins of a batch's rows for one counting sort:
/// span `first_span + g` has its bins from `keys[g].0` on, bin `k` of it at key
/// `k + keys[g].1` (wrapping: the offset is the keys before the span less its first bin);
/// `bins` keys in all.
struct BinLayout {
    first_span: usize,
    keys: Vec<(u64, u64)>,
    bins: u64,
}

/// The bin readings are being added to: its time range, and where its moments live.
#[derive(Debug, Clone, Copy)]
struct Current {
    start: TimeNs,
    end: TimeNs,
    page: u32,
    index: u32,
}

/// Accumulates one bar's readings, in any order, into bins: every bin's moments have a fixed
/// place (pages of `PAGE_BINS` bins, looked up by the bin's number in its span), so a reading
/// costs the same whether the rows come sorted, interleaved with other bars or shuffled, and
/// memory grows with the bins, not with the rows.
#[derive(Debug, Clone)]
pub struct BinAccumulator {
    bin_ns: TimeNs,
    /// In time order, covering the whole time line.
    spans: Vec<Span>,
    pages: Vec<Box<[BinMoments]>>,
    current: Option<Current>,
    /// The span of the last located reading (readings come in runs).
    last_span: usize,
    /// Division by `bin_ns` (a reading out of time order needs one).
    divide: Divide,
    /// Reused buffers of [`BinAccumulator::add_by_block`] and
    /// [`BinAccumulator::add_by_bin`].
    scratch: BlockScratch,
    /// Readings added so far (at most [`MAX_BAR_READINGS`]).
    readings: u64,
}

/// The first time or counts value of the rows that the bin sums cannot hold exactly.
fn check_readings(time_ns: &[TimeNs], counts: &[i64]) -> Result<(), BinError> {
    // Branch-free pass first (the common, clean case); the search only on failure.
    if reading_times_ok(time_ns) && counts_ok(counts) {
        return Ok(());
    }
    if let Some(&t) = time_ns.iter().find(|&&t| !reading_time_ok(t)) {
        return Err(BinError::TimeOutOfRange { time_ns: t });
    }
    let c = counts
        .iter()
        .copied()
        .find(|c| c.unsigned_abs() > MAX_ABS_COUNTS as u64)
        .unwrap_or_default();
    Err(BinError::CountsOutOfRange { counts: c })
}

impl BinAccumulator {
    /// An empty accumulator on `grid`.
    pub fn new(grid: BinGrid) -> BinAccumulator {
        BinAccumulator {
            bin_ns: grid.bin_ns,
            spans: grid.spans(),
            pages: Vec::new(),
            current: None,
            last_span: 0,
            divide: Divide::new(grid.bin_ns as u64),
            scratch: BlockScratch::default(),
            readings: 0,
        }
    }

    /// Add readings given as two columns, in any order (ingest streams tens of millions of rows
    /// through here). Rows in time order go run by run, each run of one bin in a tight loop;
    /// rows out of order are first grouped by time block (`BinAccumulator::add_by_block`).
    ///
    /// Every row is checked first (times within `EARLIEST_READING_NS`(super::EARLIEST_READING_NS) ..
    /// `LATEST_READING_NS`(super::LATEST_READING_NS), |counts| ≤ [`MAX_ABS_COUNTS`], at most `MAX_BAR_READINGS` in
    /// all): out of those bounds the bin arithmetic could wrap, so nothing of the call is added
    /// and the first offending value is returned.
    pub fn add_all(&mut self, time_ns: &[TimeNs], counts: &[i64]) -> Result<(), BinError> {
        self.add_all_then(time_ns, counts, |_| {})
    }

    /// [`BinAccumulator::add_all`], then `then` called with the same rows' times in the order
    /// they were added: grouped by bin (or time block) when they came out of time order and
    /// were sorted, else as given. A caller that looks at every row's time once more (ingest's
    /// repeat sketch) then walks the bar's time line in order instead of jumping about it.
    /// Not called when the rows are refused.
    pub fn add_all_then(
        &mut self,
        time_ns: &[TimeNs],
        counts: &[i64],
        then: impl FnOnce(&[TimeNs]),
    ) -> Result<(), BinError> {
        let n = time_ns.len().min(counts.len());
        let (time_ns, counts) = (&time_ns[..n], &counts[..n]);
        check_readings(time_ns, counts)?;
        self.readings = self
            .readings
            .checked_add(n as u64)
            .filter(|&r| r <= MAX_BAR_READINGS)
            .ok_or(BinError::TooManyReadings)?;
        let sorted = if n >= MIN_BLOCK_SORT_ROWS && !time_ns.is_sorted() {
            self.add_by_bin(time_ns, counts)
        } else {
            self.add_in_order(time_ns, counts);
            false
        };
        match self.scratch.time.get(..n) {
            Some(rows) if sorted => then(rows),
            _ => then(time_ns),
        }
        Ok(())
    }

    /// Take back readings added before (exact copies of readings that stay, e.g. the rows two
    /// overlapping files both hold): each row's bin loses that reading's integer moments, so
    /// the bins equal those of the readings without the removed rows. A row whose bin holds
    /// nothing is refused ([`BinError::NotAdded`]); the rows before it stay removed.
    pub fn remove_all(&mut self, time_ns: &[TimeNs], counts: &[i64]) -> Result<(), BinError> {
        let n = time_ns.len().min(counts.len());
        check_readings(&time_ns[..n], &counts[..n])?;
        for (&t, &c) in time_ns.iter().zip(counts) {
            let bin = self.locate(t);
            self.current = Some(bin);
            let moments = &mut self.pages[bin.page as usize][bin.index as usize];
            if !moments.remove_one(bin.start, t, c) {
                return Err(BinError::NotAdded { time_ns: t });
            }
            self.readings -= 1;
        }
        Ok(())
    }

    /// Rows out of time order (a batch of a shuffled file) sorted by bin, each bin's rows then
    /// summed in one run ([`BinMoments::add_run`], in registers) instead of one moments update
    /// in memory per row. One counting sort over every span the rows can fall in (a day file
    /// crosses a mount's end): span `s` owns the keys of its bins between the batch's first
    /// and last time ([`BinLayout`]). Rows a sort would not pay for (over more than
    /// [`MAX_SPLIT_SPANS`] spans, before the first mount, or fewer than two rows a bin) go to
    /// [`BinAccumulator::add_by_block`]. The sums are integers, so the path taken changes no bit.
    /// Returns whether the rows were sorted into `scratch` (else added as given).
    fn add_by_bin(&mut self, time_ns: &[TimeNs], counts: &[i64]) -> bool {
        let n = time_ns.len().min(counts.len());
        let (time_ns, counts) = (&time_ns[..n], &counts[..n]);
        let Some(layout) = self.bin_layout(time_ns) else {
            return self.add_by_block(time_ns, counts);
        };
        let mut scratch = std::mem::take(&mut self.scratch);
        scratch.block.clear();
        let divide = self.divide;
        let spans = &self.spans[layout.first_span..layout.first_span + layout.keys.len()];
        let edges: Vec<TimeNs> = spans[1..].iter().map(|s| s.from).collect();
        scratch.block.extend(time_ns.iter().map(|&t| {
            // The span of `t`: the edges at or before it (few, sorted; no branch per edge).
            let g = edges.iter().map(|&e| usize::from(e <= t)).sum::<usize>();
            let (anchor, to_key) = (spans[g].anchor, layout.keys[g].1);
            // `t` is in span `g`, at or after its anchor, within the batch's bins: no wrap.
            divide
                .quotient(t.wrapping_sub(anchor) as u64)
                .wrapping_add(to_key) as u32
        }));
        scratch.sort_by_block(layout.bins as usize, time_ns, counts);
        for (g, &(k0, to_key)) in layout.keys.iter().enumerate() {
            let s = layout.first_span + g;
            let next = layout
                .keys
                .get(g + 1)
                .map_or(layout.bins, |k| k.0.wrapping_add(k.1));
            for key in k0.wrapping_add(to_key)..next {
                let rows = scratch.start[key as usize]..scratch.start[key as usize + 1];
                if !rows.is_empty() {
                    let k = key.wrapping_sub(to_key) as i64;
                    self.add_bin_run(s, k, &scratch.time[rows.clone()], &scratch.counts[rows]);
                }
            }
        }
        self.scratch = scratch;
        self.current = None;
        true
    }

    /// Where each span's bins go in one counting sort of rows between `time_ns`' first and last
    /// time, or `None` when a sort would not pay or cannot be made: rows over more than
    /// [`MAX_SPLIT_SPANS`] spans, in a span before the first mount (the epoch grid: negative
    /// offsets), or fewer than two rows a bin.
    fn bin_layout(&self, time_ns: &[TimeNs]) -> Option<BinLayout> {
        let (first, last) = time_range(time_ns)?;
        let (s0, s1) = (self.span_index(first), self.span_index(last));
        if s1 - s0 >= MAX_SPLIT_SPANS {
            return None;
        }
        let mut keys = Vec::with_capacity(s1 - s0 + 1);
        let mut bins = 0u64;
        for span in &self.spans[s0..=s1] {
            if span.anchor > span.from {
                return None;
            }
            // The bins of the span the rows can fall in: between the later of the batch's
            // first time and the span's start, and the earlier of its last and the span's end.
            let (from, to) = (first.max(span.from), last.min(span.to - 1));
            let k0 = self.divide.quotient((from - span.anchor) as u64);
            let k1 = self.divide.quotient((to - span.anchor) as u64);
            keys.push((k0, bins.wrapping_sub(k0)));
            bins += k1 - k0 + 1;
        }
        let limit = (time_ns.len() as u64 / 2).min(MAX_SORT_BLOCKS * PAGE_BINS as u64);
        (bins <= limit).then_some(BinLayout {
            first_span: s0,
            keys,
            bins,
        })
    }

    /// Adds the rows of bin `k` of span `s` (in any order) as one run.
    fn add_bin_run(&mut self, s: usize, k: i64, time_ns: &[TimeNs], counts: &[i64]) {
        let page = self.page_of(s, k >> PAGE_SHIFT);
        let start = self.spans[s].anchor + k * self.bin_ns;
        let index = (k & (PAGE_BINS as i64 - 1)) as usize;
        self.pages[page as usize][index].add_run(start, time_ns, counts);
    }

    /// Rows out of time order, grouped first by blocks of [`PAGE_BINS`] bins (a stable counting
    /// sort): a bin's moments are then updated while its page is in the cache, not once per
    /// row at a random place among the bar's bins (a shuffled day of 1 440 one-minute bins is
    /// 184 kB a bar, 2.2 MB for twelve, more than a core's L2 cache). The sums are integers,
    /// so the order changes no bit. Returns whether the rows were sorted into `scratch`.
    fn add_by_block(&mut self, time_ns: &[TimeNs], counts: &[i64]) -> bool {
        let n = time_ns.len();
        let Some((first, last)) = time_range(time_ns) else {
            return false;
        };
        let block_ns = (self.bin_ns as u64).saturating_mul(PAGE_BINS as u64);
        let blocks = (last.abs_diff(first) / block_ns).saturating_add(1);
        // Many blocks for few rows gain nothing (and cost their counters).
        if blocks > (n as u64 / 8).min(MAX_SORT_BLOCKS) {
            self.add_in_order(time_ns, counts);
            return false;
        }
        let divide = Divide::new(block_ns);
        let mut scratch = std::mem::take(&mut self.scratch);
        scratch.block.clear();
        scratch.block.extend(
            time_ns
                .iter()
                .map(|&t| divide.quotient(t.abs_diff(first)) as u32),
        );
        scratch.sort_by_block(blocks as usize, time_ns, counts);
        self.add_scattered(&scratch.time, &scratch.counts);
        self.scratch = scratch;
        true
    }

    /// Rows in no particular time order, one at a time: each row's bin by arithmetic within the
    /// span of the row before (the common case); a row in another span or on a page not yet
    /// made goes through [`BinAccumulator::locate`].
    fn add_scattered(&mut self, time_ns: &[TimeNs], counts: &[i64]) {
        let n = time_ns.len().min(counts.len());
        let mut i = 0;
        while i < n {
            let c = self.locate(time_ns[i]);
            self.pages[c.page as usize][c.index as usize].add_one(c.start, time_ns[i], counts[i]);
            i += 1;
            let Self {
                bin_ns,
                spans,
                pages,
                last_span,
                divide,
                ..
            } = self;
            let span = &spans[*last_span];
            let (from, to, anchor) = (span.from, span.to, span.anchor);
            if anchor > from {
                continue; // before the first mount (epoch grid): negative offsets
            }
            while i < n {
                let t = time_ns[i];
                if t < from || t >= to {
                    break;
                }
                let k = divide.quotient((t - anchor) as u64) as i64;
                let offset = ((k >> PAGE_SHIFT) - span.base) as u64;
                let page = match span.slots.get(offset as usize) {
                    Some(&page) if offset < span.slots.len() as u64 && page != NO_PAGE => page,
                    _ => break,
                };
                let start = anchor + k * *bin_ns;
                let index = (k & (PAGE_BINS as i64 - 1)) as usize;
                pages[page as usize][index].add_one(start, t, counts[i]);
                i += 1;
            }
        }
        self.current = None;
    }

    /// Rows run by run: each run of rows in one bin summed in a tight loop, a row out of order
    /// on its own.
    fn add_in_order(&mut self, time_ns: &[TimeNs], counts: &[i64]) {
        let n = time_ns.len().min(counts.len());
        let mut i = 0;
        while i < n {
            let t = time_ns[i];
            let bin = match self.current {
                Some(c) if t >= c.start && t < c.end => c,
                _ => {
                    let c = self.locate(t);
                    self.current = Some(c);
                    c
                }
            };
            let moments = &mut self.pages[bin.page as usize][bin.index as usize];
            if time_ns
                .get(i + 1)
                .is_some_and(|&t| t >= bin.start && t < bin.end)
            {
                let run = time_ns[i + 1..n]
                    .iter()
                    .position(|&t| t < bin.start || t >= bin.end)
                    .map_or(n, |k| i + 1 + k);
                moments.add_run(bin.start, &time_ns[i..run], &counts[i..run]);
                i = run;
            } else {
                // Rows not sorted by time (shuffled, or bars interleaved): one at a time.
                moments.add_one(bin.start, t, counts[i]);
                i += 1;
            }
        }
    }

    /// Adds every reading of `other`, an accumulator made on the same grid: ingest's consumers
    /// each fill one while the encoder batches stream, and merge them at the end. A bin's
    /// moments are integer sums, so the result is exactly that of one accumulator given every
    /// reading, in any order ([`BinError::OtherGrid`] for another grid, nothing added).
    pub fn merge(&mut self, other: BinAccumulator) -> Result<(), BinError> {
        let same_grid = other.bin_ns == self.bin_ns
            && other.spans.len() == self.spans.len()
            && other
                .spans
                .iter()
                .zip(&self.spans)
                .all(|(a, b)| (a.from, a.to, a.anchor) == (b.from, b.to, b.anchor));
        if !same_grid {
            return Err(BinError::OtherGrid);
        }
        self.readings = self
            .readings
            .checked_add(other.readings)
            .filter(|&r| r <= MAX_BAR_READINGS)
            .ok_or(BinError::TooManyReadings)?;
        let Self { spans, pages, .. } = self;
        let mut theirs: Vec<Option<Box<[BinMoments]>>> =
            other.pages.into_iter().map(Some).collect();
        for (span, their_span) in spans.iter_mut().zip(&other.spans) {
            for (number, page) in their_span.pages() {
                let Some(moments) = theirs[page as usize].take() else {
                    continue;
                };
                let slot = span.slot(number);
                match *slot {
                    NO_PAGE => {
                        *slot = pages.len() as u32;
                        pages.push(moments);
                    }
                    mine => {
                        let target = &mut pages[mine as usize];
                        target
                            .iter_mut()
                            .zip(moments.iter())
                            .for_each(|(a, b)| a.merge(b));
                    }
                }
            }
        }
        self.current = None;
        Ok(())
    }

    /// The bin holding a reading at `t`, its page created if needed.
    fn locate(&mut self, t: TimeNs) -> Current {
        let s = self.span_index(t);
        self.last_span = s;
        let bin_ns = self.bin_ns;
        let span = &self.spans[s];
        let offset = t - span.anchor;
        let k = if offset >= 0 {
            self.divide.quotient(offset as u64) as i64
        } else {
            offset.div_euclid(bin_ns)
        };
        let start = span.anchor + k * bin_ns;
        let end = start.saturating_add(bin_ns).min(span.to);
        let index = (k & (PAGE_BINS as i64 - 1)) as u32;
        let page = self.page_of(s, k >> PAGE_SHIFT);
        Current {
            start,
            end,
            page,
            index,
        }
    }

    /// The span holding `t` (the spans cover the whole time line), the last one used first.
    fn span_index(&self, t: TimeNs) -> usize {
        match self.spans.get(self.last_span) {
            Some(span) if span.from <= t && t < span.to => self.last_span,
            _ => self.spans.partition_point(|s| s.from <= t) - 1,
        }
    }

    /// Index into `pages` of page `number` of span `s`, made (empty) if needed.
    fn page_of(&mut self, s: usize, number: i64) -> u32 {
        let slot = self.spans[s].slot(number);
        match *slot {
            NO_PAGE => {
                *slot = self.pages.len() as u32;
                self.pages
                    .push(vec![BinMoments::default(); PAGE_BINS].into_boxed_slice());
                *slot
            }
            page => page,
        }
    }

    /// The bins, in time order.
    pub fn finish(self) -> BarBins {
        let mut bins: Vec<(BinKey, BinMoments)> = Vec::new();
        for span in &self.spans {
            for (number, page) in span.pages() {
                for (index, moments) in self.pages[page as usize].iter().enumerate() {
                    if moments.n == 0 {
                        continue;
                    }
                    let k = (number << PAGE_SHIFT) + index as i64;
                    let key = BinKey {
                        start_ns: span.anchor + k * self.bin_ns,
                        region: span.region,
                    };
                    bins.push((key, *moments));
                }
            }
        }
        BarBins {
            bin_ns: self.bin_ns,
            bins,
        }
    }
}

impl Span {
    pub(super) fn new(
        from: TimeNs,
        to: TimeNs,
        anchor: TimeNs,
        region: Region,
        bin_ns: TimeNs,
    ) -> Span {
        // A bounded span gets its whole page table at once (readings of a span in any order
        // then never move it); an unbounded or very long one grows it as readings come.
        let pages = if from > TimeNs::MIN && to < TimeNs::MAX {
            ((to - anchor - 1).div_euclid(bin_ns) >> PAGE_SHIFT) + 1
        } else {
            0
        };
        let dense = if pages <= DENSE_PAGES { pages } else { 0 };
        Span {
            from,
            to,
            anchor,
            region,
            base: 0,
            slots: vec![NO_PAGE; dense as usize],
            far: std::collections::HashMap::new(),
        }
    }

    /// The pages holding readings: (page number, index into `BinAccumulator::pages`), by
    /// page number.
    fn pages(&self) -> Vec<(i64, u32)> {
        let mut pages: Vec<(i64, u32)> = self
            .slots
            .iter()
            .enumerate()
            .filter(|(_, &p)| p != NO_PAGE)
            .map(|(k, &p)| (self.base + k as i64, p))
            .chain(self.far.iter().map(|(&k, &p)| (k, p)))
            .collect();
        pages.sort_unstable();
        pages
    }

    /// The page table entry of page `number`.
    fn slot(&mut self, number: i64) -> &mut u32 {
        if self.slots.is_empty() && self.far.is_empty() {
            self.base = number;
        }
        let offset = number - self.base;
        if offset < 0 || offset >= self.slots.len() as i64 {
            // Grow the dense table towards the page (at least doubling it) while it stays short.
            let len = self.slots.len() as i64;
            let (low, high) = (self.base.min(number), (self.base + len).max(number + 1));
            if high - low > DENSE_PAGES {
                return self.far.entry(number).or_insert(NO_PAGE);
            }
            let grow = len.max(1);
            let (low, high) = if number < self.base {
                ((self.base - grow).min(low), high)
            } else {
                (low, (self.base + len + grow).max(high))
            };
            let (low, high) = if high - low > DENSE_PAGES {
                (self.base.min(number), (self.base + len).max(number + 1))
            } else {
                (low, high)
            };
            let mut slots = vec![NO_PAGE; (high - low) as usize];
            let at = (self.base - low) as usize;
            slots[at..at + self.slots.len()].copy_from_slice(&self.slots);
            self.slots = slots;
            self.base = low;
        }
        &mut self.slots[(number - self.base) as usize]
    }
}
