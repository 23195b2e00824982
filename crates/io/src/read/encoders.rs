//! The encoder table, streamed: each batch binned (or kept at full rate) per bar as it is read,
//! with the file and time range of every (file, bar).

use super::*;

// ---------------------------------------------------------------- encoders, streamed

/// The rows of a batch that are kept: bar indices, times (ns) and counts, same length.
pub(super) type KeptRows = (Vec<u32>, Vec<i64>, Vec<i64>);

/// Rows of one bar gathered from every file and batch: kept (in arrival order), or added to the
/// bar's compressed bins as they arrive (`series::BinAccumulator`: order-free integer sums).
pub(super) enum BarRows {
    Kept {
        time_ns: Vec<i64>,
        counts: Vec<i64>,
    },
    /// Added to the bar's bins as they arrive; `repeats` marks where its times may repeat
    /// (`None`: a bar without mounts).
    /// (`Box`: the accumulator is ~300 bytes, the other variants 48 or none.)
    Binned {
        bins: Box<BinAccumulator>,
        repeats: Option<RepeatSketch>,
    },
}

/// Time range and rows of one bar id in one file.
#[derive(Debug, Clone, Copy)]
pub(super) struct FileRange {
    pub(super) first_ns: i64,
    pub(super) last_ns: i64,
    pub(super) rows: u64,
}

impl FileRange {
    /// The range of the times `time_ns` (`None` when empty).
    pub(super) fn of(time_ns: &[i64]) -> Option<FileRange> {
        Some(FileRange {
            first_ns: *time_ns.iter().min()?,
            last_ns: *time_ns.iter().max()?,
            rows: time_ns.len() as u64,
        })
    }

    /// Widens the range kept under `key` by `more` (rows added).
    pub(super) fn add_to<K: Ord>(ranges: &mut BTreeMap<K, FileRange>, key: K, more: FileRange) {
        let range = ranges.entry(key).or_insert(FileRange { rows: 0, ..more });
        range.first_ns = range.first_ns.min(more.first_ns);
        range.last_ns = range.last_ns.max(more.last_ns);
        range.rows += more.rows;
    }
}

/// Ids of a batch as small indices: each distinct value of the batch's dictionary is looked up
/// once, then every row's key is mapped (no string is compared per row).
pub(super) struct IdIndex {
    /// Id -> index (declared bars first, then undeclared ids as they appear).
    pub(super) by_name: BTreeMap<String, u32>,
    pub(super) names: Vec<String>,
    /// Scratch: the index of each dictionary value of the batch.
    of_value: Vec<u32>,
}

impl IdIndex {
    pub(super) fn new<'a>(declared: impl Iterator<Item = &'a str>) -> IdIndex {
        let names: Vec<String> = declared.map(str::to_string).collect();
        IdIndex {
            by_name: names
                .iter()
                .enumerate()
                .map(|(i, n)| (n.clone(), i as u32))
                .collect(),
            names,
            of_value: Vec::new(),
        }
    }

    /// Index of every row's id into `out` (a null row gets the index of the empty id: callers
    /// drop or mark null rows themselves).
    pub(super) fn indices(&mut self, ids: Ids<'_>, out: &mut Vec<u32>) {
        out.clear();
        out.reserve(ids.len());
        let mut of_value = std::mem::take(&mut self.of_value);
        of_value.clear();
        for v in 0..ids.values.len() {
            let id = if ids.values.is_valid(v) {
                ids.values.value(v)
            } else {
                ""
            };
            of_value.push(self.by_string(id));
        }
        let keys = ids.keys();
        // Every key in range (a null row's key too, the usual batch): a plain look-up per row.
        // A negative key is a large u32 and takes the checked path.
        let largest = keys.iter().fold(0u32, |m, &k| m.max(k as u32));
        if (largest as usize) < of_value.len() {
            out.extend(keys.iter().map(|&k| of_value[k as u32 as usize]));
            self.of_value = of_value;
            return;
        }
        let mut empty = None;
        for &key in keys {
            let index = match usize::try_from(key).ok().and_then(|k| of_value.get(k)) {
                Some(&index) => index,
                None => *empty.get_or_insert_with(|| self.by_string("")),
            };
            out.push(index);
        }
        self.of_value = of_value;
    }

    pub(super) fn by_string(&mut self, id: &str) -> u32 {
        if let Some(&index) = self.by_name.get(id) {
            return index;
        }
        let index = self.names.len() as u32;
        self.names.push(id.to_string());
        self.by_name.insert(id.to_string(), index);
        index
    }
}

/// What the streamed encoder batches leave behind: per-bar rows of declared bars, and what the
/// checks need (nulls per column and file, undeclared ids per file).
pub(super) struct EncoderSink {
    /// Index of the file being streamed, and its rows streamed before this batch.
    pub(super) file: u32,
    pub(super) row_offset: u64,
    /// How the batch's times are stored (a scan's files share one schema).
    pub(super) time: TimeColumn,
    pub(super) ids: IdIndex,
    /// Rows of the declared bars, by index in `ids`.
    pub(super) bars: Vec<BarRows>,
    /// (file, id) -> rows of an undeclared bar.
    pub(super) unknown: BTreeMap<(u32, String), FileRange>,
    /// (file, column, problem) -> rows that cannot be read (times out of range, counts that are
    /// not whole numbers or beyond ±2^48): the run is refused on them.
    pub(super) bad: BTreeMap<(u32, &'static str, RowProblem), BadRange>,
    /// Per id index: rows read, and missing counts (null, NaN, ±inf) dropped.
    pub(super) read: Vec<(u64, Missing)>,
    /// A bin accumulator's refusal (cannot happen after `push`'s checks; reported if it does).
    pub(super) bin_error: Option<String>,
    /// (declared bar index, file) -> time range and rows: where two files overlap for one bar
    /// ([`resolve_repeats`]).
    pub(super) ranges: BTreeMap<(u32, u32), FileRange>,
    /// Scratch: each row's id index, and the batch's rows grouped by bar.
    pub(super) row_ids: Vec<u32>,
    pub(super) grouped_time: Vec<i64>,
    pub(super) grouped_counts: Vec<i64>,
    pub(super) group_start: Vec<usize>,
}

impl EncoderSink {
    /// An empty sink with rows `rows(id)` for every declared bar.
    pub(super) fn new(
        bar_ids: &BTreeSet<&str>,
        rows: &(dyn Fn(&str) -> BarRows + Sync),
    ) -> EncoderSink {
        EncoderSink {
            file: 0,
            row_offset: 0,
            time: TimeColumn::of(None),
            bad: BTreeMap::new(),
            read: Vec::new(),
            bin_error: None,
            ranges: BTreeMap::new(),
            ids: IdIndex::new(bar_ids.iter().copied()),
            bars: bar_ids.iter().map(|id| rows(id)).collect(),
            unknown: BTreeMap::new(),
            row_ids: Vec::new(),
            grouped_time: Vec::new(),
            grouped_counts: Vec::new(),
            group_start: Vec::new(),
        }
    }

    /// Split one batch per bar and add each bar's rows to its log or bins. The cost per row does
    /// not depend on the order of the rows: ids are indexed on their string views; a batch of
    /// few runs of one bar (a file sorted or grouped by bar) goes run by run, any other (bars
    /// interleaved, or shuffled) is first grouped by bar with a counting sort (stable: each bar's
    /// rows keep their order), so every bar gets its rows as one slice.
    pub(super) fn push(&mut self, batch: &Canonical) -> Result<(), ArrowError> {
        let offset = self.row_offset;
        self.row_offset += batch.rows as u64;
        let time = batch.i64("time")?;
        let bar = batch.text("bar")?;
        if time.null_count() > 0 || bar.null_count() > 0 {
            // Rows without a time or a bar cannot be used: dropped, named by file and rows; the
            // others go on.
            let (mut null_time, mut null_bar) = (None, None);
            let keep: BooleanArray = (0..batch.rows)
                .map(|i| {
                    let row = offset + i as u64;
                    let (t, b) = (time.is_valid(i), bar.is_valid(i));
                    if !t {
                        BadRange::add(&mut null_time, row, || "null".into());
                    }
                    if !b {
                        BadRange::add(&mut null_bar, row, || "null".into());
                    }
                    Some(t && b)
                })
                .collect();
            if let Some(b) = null_time {
                self.merge_bad("time", RowProblem::Null, b);
            }
            if let Some(b) = null_bar {
                self.merge_bad("bar", RowProblem::Null, b);
            }
            let rows: Vec<u64> = (0..batch.rows)
                .filter(|&i| keep.value(i))
                .map(|i| offset + i as u64)
                .collect();
            let kept = batch.filter(&keep)?;
            return self.push_rows(&kept, &|i| rows.get(i).copied().unwrap_or(offset));
        }
        self.push_rows(batch, &|i| offset + i as u64)
    }

    /// [`Self::push`] of rows without nulls in `time` or `bar`; `row_of(i)`: the file's row of
    /// the batch's row `i` (rows with a problem are named by it).
    pub(super) fn push_rows(
        &mut self,
        batch: &Canonical,
        row_of: &dyn Fn(usize) -> u64,
    ) -> Result<(), ArrowError> {
        let raw: &[i64] = batch.i64("time")?.values();
        let bar = batch.text("bar")?;
        let converted;
        let time: &[i64] = if self.time.ns_per_unit == 1 && reading_times_ok(raw) {
            raw
        } else {
            let (ns, bad_rows) = self.times_ns(raw, row_of);
            if bad_rows {
                // Rows with a time out of range are dropped (named by file and rows).
                let keep: BooleanArray = raw
                    .iter()
                    .map(|&t| Some(self.time.to_ns(t).is_some()))
                    .collect();
                let rows: Vec<u64> = (0..raw.len())
                    .filter(|&i| self.time.to_ns(raw[i]).is_some())
                    .map(row_of)
                    .collect();
                let kept = batch.filter(&keep)?;
                if kept.rows == 0 {
                    return Ok(());
                }
                return self.push_rows(&kept, &|i| rows.get(i).copied().unwrap_or(0));
            }
            converted = ns;
            &converted
        };
        let mut ids = std::mem::take(&mut self.row_ids);
        self.ids.indices(bar, &mut ids);
        if self.read.len() < self.ids.names.len() {
            self.read
                .resize(self.ids.names.len(), (0, Missing::default()));
        }
        for &id in &ids {
            let read = &mut self.read[id as usize].0;
            *read = read.wrapping_add(1); // at most the rows of the campaign
        }
        let counts = batch.get("counts")?;
        let clean = counts
            .as_primitive_opt::<Int64Type>()
            .filter(|c| c.null_count() == 0)
            .map(|c| c.values().as_ref())
            .filter(|v| counts_ok(v));
        match clean {
            Some(counts) => self.add_rows(&ids, time, counts),
            None => {
                let (ids_kept, time_kept, counts_kept) =
                    self.checked_counts(&ids, time, counts, row_of)?;
                self.add_rows(&ids_kept, &time_kept, &counts_kept);
            }
        }
        self.row_ids = ids;
        Ok(())
    }

    /// Adds what another consumer's sink gathered from its batches. Every part is a sum, a
    /// count, a range or a set, so the merged sink is the one a single consumer would have
    /// filled (full-rate rows differ only in order, and are sorted afterwards).
    pub(super) fn merge(&mut self, other: EncoderSink) {
        for (key, u) in other.unknown {
            FileRange::add_to(&mut self.unknown, key, u);
        }
        for (key, b) in other.bad {
            BadRange::merge_into(&mut self.bad, key, b);
        }
        for (key, r) in other.ranges {
            FileRange::add_to(&mut self.ranges, key, r);
        }
        // Declared bars have the same indices in every sink (undeclared ids, numbered as they
        // appear, are reported by name through `unknown`).
        let declared = self.bars.len();
        let longest = self.read.len().max(other.read.len()).min(declared);
        if self.read.len() < longest {
            self.read.resize(longest, (0, Missing::default()));
        }
        for (mine, theirs) in self.read.iter_mut().zip(&other.read).take(declared) {
            mine.0 += theirs.0;
            mine.1.merge(&theirs.1);
        }
        self.bin_error = match (self.bin_error.take(), other.bin_error) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        for (mine, theirs) in self.bars.iter_mut().zip(other.bars) {
            match (mine, theirs) {
                (
                    BarRows::Kept { time_ns, counts },
                    BarRows::Kept {
                        time_ns: more_time,
                        counts: more_counts,
                    },
                ) => {
                    time_ns.extend_from_slice(&more_time);
                    counts.extend_from_slice(&more_counts);
                }
                (
                    BarRows::Binned { bins, repeats },
                    BarRows::Binned {
                        bins: more_bins,
                        repeats: more_repeats,
                    },
                ) => {
                    if let Err(e) = bins.merge(*more_bins) {
                        self.bin_error.get_or_insert(e.to_string());
                    }
                    if let (Some(mine), Some(theirs)) = (repeats.as_mut(), more_repeats) {
                        mine.merge(theirs);
                    }
                }
                _ => {}
            }
        }
    }

    /// Times of the batch in ns, and whether some are out of range (those rows recorded in
    /// `bad`, their times 0 here).
    pub(super) fn times_ns(
        &mut self,
        raw: &[i64],
        row_of: &dyn Fn(usize) -> u64,
    ) -> (Vec<i64>, bool) {
        let unit = self.time;
        let mut bad = None;
        let ns: Vec<i64> = raw
            .iter()
            .enumerate()
            .map(|(i, &t)| {
                unit.to_ns(t).unwrap_or_else(|| {
                    BadRange::add(&mut bad, row_of(i), || format!("{t} {}", unit.unit()));
                    0
                })
            })
            .collect();
        match bad {
            None => (ns, false),
            Some(b) => {
                self.merge_bad("time", RowProblem::TimeOutOfBounds, b);
                (ns, true)
            }
        }
    }

    pub(super) fn merge_bad(&mut self, column: &'static str, problem: RowProblem, b: BadRange) {
        BadRange::merge_into(&mut self.bad, (self.file, column, problem), b);
    }

    /// Counts that are not a clean int64 column (nulls, floats, values beyond ±2^48): missing
    /// ones (null, NaN, ±inf) dropped and counted per bar; whole floats converted exactly; a
    /// fraction or a value out of range dropped and named by file and rows (in `bad`).
    pub(super) fn checked_counts(
        &mut self,
        ids: &[u32],
        time: &[i64],
        counts: &ArrayRef,
        row_of: &dyn Fn(usize) -> u64,
    ) -> Result<KeptRows, ArrowError> {
        let (values, ints): (Vec<Option<f64>>, Vec<Option<i64>>) =
            match counts.as_primitive_opt::<Float64Type>() {
                Some(floats) => (floats.iter().collect(), vec![None; floats.len()]),
                None => {
                    let ints = counts.as_primitive_opt::<Int64Type>().ok_or_else(|| {
                        ArrowError::CastError("`counts` is neither int64 nor float64".into())
                    })?;
                    (
                        ints.iter().map(|c| c.map(|c| c as f64)).collect(),
                        ints.iter().collect(),
                    )
                }
            };
        let (mut fraction, mut range) = (None, None);
        let mut kept = (Vec::new(), Vec::new(), Vec::new());
        for (i, (&v, &int)) in values.iter().zip(&ints).enumerate() {
            let row = row_of(i);
            let c = match (int, v) {
                (Some(c), _) => c,
                (None, Some(v)) if v.is_finite() => {
                    if v.fract() != 0.0 {
                        BadRange::add(&mut fraction, row, || v.to_string());
                        continue;
                    }
                    if v.abs() > MAX_ABS_COUNTS as f64 {
                        BadRange::add(&mut range, row, || v.to_string());
                        continue;
                    }
                    v as i64
                }
                (None, v) => {
                    self.read[ids[i] as usize].1.add(time[i], v);
                    continue;
                }
            };
            if c.unsigned_abs() > MAX_ABS_COUNTS as u64 {
                BadRange::add(&mut range, row, || c.to_string());
                continue;
            }
            kept.0.push(ids[i]);
            kept.1.push(time[i]);
            kept.2.push(c);
        }
        if let Some(b) = fraction {
            self.merge_bad("counts", RowProblem::CountsNotWhole, b);
        }
        if let Some(b) = range {
            self.merge_bad("counts", RowProblem::CountsBeyondRange, b);
        }
        Ok(kept)
    }

    /// Adds the batch's rows (id index, time ns, counts) to the bars' logs or bins.
    pub(super) fn add_rows(&mut self, ids: &[u32], time: &[i64], counts: &[i64]) {
        let runs = 1 + ids.windows(2).filter(|w| w[0] != w[1]).count();
        if runs * 64 <= ids.len() {
            let mut start = 0;
            for end in 1..=ids.len() {
                if end == ids.len() || ids[end] != ids[start] {
                    self.append(ids[start], &time[start..end], &counts[start..end]);
                    start = end;
                }
            }
        } else {
            self.group_by_bar(ids, time, counts);
            let (grouped_time, grouped_counts) = (
                std::mem::take(&mut self.grouped_time),
                std::mem::take(&mut self.grouped_counts),
            );
            let starts = std::mem::take(&mut self.group_start);
            for (index, w) in starts.windows(2).enumerate() {
                if w[1] > w[0] {
                    let range = w[0]..w[1];
                    let (t, c) = (&grouped_time[range.clone()], &grouped_counts[range]);
                    self.append(index as u32, t, c);
                }
            }
            (self.grouped_time, self.grouped_counts, self.group_start) =
                (grouped_time, grouped_counts, starts);
        }
    }

    /// Counting sort of the batch's rows by id index into the grouped scratch columns;
    /// `group_start[k]..group_start[k + 1]` are the rows of index `k`.
    pub(super) fn group_by_bar(&mut self, ids: &[u32], time: &[i64], counts: &[i64]) {
        let groups = self.ids.names.len();
        let starts = &mut self.group_start;
        starts.clear();
        starts.resize(groups + 1, 0);
        // Positions below the batch's rows: wrapping additions, no overflow check per row.
        for &id in ids {
            let slot = &mut starts[id as usize + 1];
            *slot = slot.wrapping_add(1);
        }
        for k in 0..groups {
            starts[k + 1] = starts[k + 1].wrapping_add(starts[k]);
        }
        let mut next: Vec<usize> = starts[..groups].to_vec();
        let n = ids.len().min(time.len()).min(counts.len());
        self.grouped_time.resize(n, 0);
        self.grouped_counts.resize(n, 0);
        let (grouped_time, grouped_counts) =
            (&mut self.grouped_time[..n], &mut self.grouped_counts[..n]);
        for ((&id, &t), &c) in ids.iter().zip(time).zip(counts) {
            let at = &mut next[id as usize];
            grouped_time[*at] = t;
            grouped_counts[*at] = c;
            *at = at.wrapping_add(1);
        }
    }

    pub(super) fn append(&mut self, index: u32, time: &[i64], counts: &[i64]) {
        let Some(range) = FileRange::of(time) else {
            return;
        };
        if matches!(
            self.bars.get(index as usize),
            Some(BarRows::Kept { .. } | BarRows::Binned { .. })
        ) {
            FileRange::add_to(&mut self.ranges, (index, self.file), range);
        }
        match self.bars.get_mut(index as usize) {
            Some(BarRows::Kept {
                time_ns,
                counts: kept,
            }) => {
                time_ns.extend_from_slice(time);
                kept.extend_from_slice(counts);
                return;
            }
            Some(BarRows::Binned { bins, repeats }) => {
                // Every row was checked in `push` (times and counts within the sums' range).
                // The sketch marks the rows in the order the bins took them: grouped by bin when
                // they came shuffled, so its bitmap is walked in order, not at random.
                let added = match repeats {
                    Some(repeats) => bins.add_all_then(time, counts, |rows| repeats.add(rows)),
                    None => bins.add_all(time, counts),
                };
                if let Err(e) = added {
                    self.bin_error.get_or_insert(e.to_string());
                }
                return;
            }
            None => {}
        }
        let id = self.ids.names[index as usize].clone();
        FileRange::add_to(&mut self.unknown, (self.file, id), range);
    }
}

/// Streams every encoder file (projection and type normalisation as each batch is decoded)
/// into per-bar logs sorted by (time, counts), or, for the bars `grids` names, straight into
/// compressed bins (the bar's log then stays empty). Schema errors name their file before any
/// row is read; rows that cannot be used (nulls, undeclared bars, times or counts out of range)
/// are dropped and flagged by file, column and rows. `rows_hint`: the encoder rows the files'
/// footers announce (per-bar logs are reserved from it).
pub(super) fn read_encoders(
    files: &[PathBuf],
    bar_ids: &BTreeSet<&str>,
    grids: &BTreeMap<String, (BinGrid, Option<RepeatSketch>)>,
    rows_hint: usize,
    zones: &mut Vec<(PathBuf, bool)>,
) -> Result<Encoders, IngestError> {
    let keep = |id: &str| match grids.get(id) {
        Some((grid, repeats)) => BarRows::Binned {
            bins: Box::new(BinAccumulator::new(grid.clone())),
            repeats: repeats.clone(),
        },
        None => BarRows::Kept {
            time_ns: Vec::with_capacity(rows_hint / bar_ids.len().max(1)),
            counts: Vec::with_capacity(rows_hint / bar_ids.len().max(1)),
        },
    };
    // Every batch knows its file and row offset, so rows that cannot be used are named by
    // file and rows in this one pass.
    let sink = stream_encoders(files, bar_ids, &keep, zones)?;
    if let Some(message) = sink.bin_error {
        return Err(IngestError::Parquet {
            context: "encoders".into(),
            message,
        });
    }
    // Rows that cannot be used are dropped, counted and flagged by file, column and rows; the
    // night goes on (`docs/guarantees.md`, "Inputs").
    let mut dropped: Vec<Flag> = sink
        .bad
        .into_iter()
        .map(|((file, column, problem), b)| b.flag(&file_path(files, file), column, problem))
        .collect();
    let declared: Vec<String> = bar_ids.iter().map(|b| b.to_string()).collect();
    dropped.extend(sink.unknown.into_iter().map(|((file, id), u)| {
        unknown_id_flag(
            &file_path(files, file),
            "bar",
            &id,
            u.rows,
            u.first_ns,
            u.last_ns,
            &declared,
        )
    }));
    let rows: BTreeMap<String, (u64, Missing)> = bar_ids
        .iter()
        .zip(
            sink.read
                .iter()
                .chain(std::iter::repeat(&(0, Missing::default()))),
        )
        .map(|(id, r)| (id.to_string(), *r))
        .collect();
    let mut bars = sink.bars;
    let clock = std::time::Instant::now();
    let overlaps = resolve_repeats(files, bar_ids, &sink.ranges, &mut bars)?;
    tracing::debug!(elapsed = ?clock.elapsed(), bars = overlaps.len(), "repeated readings resolved");
    // Bars in parallel: an unsorted full-rate log is sorted here (~0.1 s a million rows).
    use rayon::prelude::*;
    let finished: Vec<(String, BarLog, Option<BarBins>)> = bar_ids
        .iter()
        .zip(bars)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|(id, rows)| match rows {
            BarRows::Kept { time_ns, counts } => {
                let (time_ns, counts) = sorted_by_time_then_value(time_ns, counts);
                let log = BarLog {
                    time_ns,
                    counts,
                    celsius: BTreeMap::new(),
                };
                (id.to_string(), log, None)
            }
            BarRows::Binned { bins, .. } => {
                (id.to_string(), BarLog::default(), Some(bins.finish()))
            }
        })
        .collect();
    let mut logs = BTreeMap::new();
    let mut bins = BTreeMap::new();
    for (id, log, binned) in finished {
        if let Some(b) = binned {
            bins.insert(id.clone(), b);
        }
        logs.insert(id, log);
    }
    Ok(Encoders {
        logs,
        bins,
        rows,
        overlaps,
        dropped,
    })
}
