//! Rows that several encoder files hold: found from the files' time ranges per bar, re-read only
//! there, one copy kept (module doc of `read`, "How it works").

use super::*;

/// What re-reading the rows of one bar that may repeat gave: flags, and the copies removed
/// from the bins (counted in `duplicate_rows`).
#[derive(Debug, Default)]
pub(super) struct Overlap {
    pub(super) flags: Vec<Flag>,
    pub(super) removed: u64,
}

/// Readings of one bar that repeat: held by several files, or twice by one. They are found in
/// windows of the bar's time line, and the bar's rows inside them are read again from the files
/// whose time range meets them (filtered in the scan by bar and time, so memory is those rows):
/// - windows where the time ranges of two files overlap for the bar (recorded while streaming,
///   [`FileRange`]), on both reading paths;
/// - with bins, the windows of the bar's [`RepeatSketch`]: where two rows fell in one slot
///   (at full rate the sorted rows show repeats directly, `quality::check_log`).
///
/// There:
/// - a reading (time and counts) held more than once is counted once, as at full rate
///   (`quality::dedup_sorted`): with bins the extra copies are taken out of the bins (exact:
///   integer sums) and flagged `duplicate_rows`; held by several files, also
///   `overlapping_files` (at full rate only that flag is added here);
/// - readings of one time with different counts are `conflicting_readings`, all kept (at full
///   rate `quality::check_log` finds them, so only the binned path flags here).
pub(super) fn resolve_repeats(
    files: &[PathBuf],
    bar_ids: &BTreeSet<&str>,
    ranges: &BTreeMap<(u32, u32), FileRange>,
    bars: &mut [BarRows],
) -> Result<BTreeMap<String, Overlap>, IngestError> {
    let mut found = BTreeMap::new();
    for (index, id) in bar_ids.iter().enumerate() {
        let (binned, repeats) = match bars.get_mut(index) {
            Some(BarRows::Binned { repeats, .. }) => (true, repeats.take()),
            Some(BarRows::Kept { .. }) => (false, None),
            _ => continue,
        };
        let mine: Vec<(u32, FileRange)> = ranges
            .range((index as u32, 0)..=(index as u32, u32::MAX))
            .filter(|((_, file), _)| (*file as usize) < files.len())
            .map(|(&(_, file), &r)| (file, r))
            .collect();
        let mut windows = overlap_windows(&mine);
        match repeats.map_or(RepeatWindows::None, RepeatSketch::windows) {
            RepeatWindows::None => {}
            RepeatWindows::Windows(w) => windows.extend(w),
            RepeatWindows::Everything(from, to) => windows.push((from, to)),
        }
        let windows = merged(windows);
        if windows.is_empty() {
            continue;
        }
        let mut rows: Vec<(i64, i64, u32)> = Vec::new();
        for &(file, r) in &mine {
            let meets: Vec<(i64, i64)> = windows
                .iter()
                .copied()
                .filter(|&(from, to)| r.first_ns <= to && r.last_ns >= from)
                .collect();
            if !meets.is_empty() {
                let path = &files[file as usize];
                let read = guarded(path, || rows_in_windows(path, id, &meets))?;
                rows.extend(read.into_iter().map(|(t, c)| (t, c, file)));
            }
        }
        rows.sort_unstable();
        let copies = compare_copies(&rows);
        let report: &mut Overlap = found.entry(id.to_string()).or_default();
        report_copies(files, id, binned, &copies, report);
        if let Some(BarRows::Binned { bins, .. }) = bars.get_mut(index) {
            bins.remove_all(&copies.removed.0, &copies.removed.1)
                .map_err(|e| IngestError::Parquet {
                    context: "encoders".into(),
                    message: format!("bar {id}: {e}"),
                })?;
            report.removed += copies.removed.0.len() as u64;
        }
    }
    found.retain(|_, o| !o.flags.is_empty() || o.removed > 0);
    Ok(found)
}

/// Where the time ranges of two of a bar's files overlap.
pub(super) fn overlap_windows(mine: &[(u32, FileRange)]) -> Vec<(i64, i64)> {
    let mut windows = Vec::new();
    for (i, (_, a)) in mine.iter().enumerate() {
        for (_, b) in &mine[i + 1..] {
            let (from, to) = (a.first_ns.max(b.first_ns), a.last_ns.min(b.last_ns));
            if from <= to {
                windows.push((from, to));
            }
        }
    }
    windows
}

/// Windows `[from, to]` sorted and merged where they meet or touch.
pub(super) fn merged(mut windows: Vec<(i64, i64)>) -> Vec<(i64, i64)> {
    windows.sort_unstable();
    let mut out: Vec<(i64, i64)> = Vec::with_capacity(windows.len());
    for (from, to) in windows {
        match out.last_mut() {
            Some(last) if from <= last.1.saturating_add(1) => last.1 = last.1.max(to),
            _ => out.push((from, to)),
        }
    }
    out
}

/// The flags of one bar's repeated readings (see [`resolve_repeats`]).
pub(super) fn report_copies(
    files: &[PathBuf],
    id: &str,
    binned: bool,
    copies: &Copies,
    report: &mut Overlap,
) {
    let names = |set: &BTreeSet<u32>| {
        set.iter()
            .map(|&f| file_name(&files[f as usize]))
            .collect::<Vec<_>>()
    };
    if let Some((a, b, n)) = copies.across_files {
        let note = FlagNote::OverlappingFiles {
            bar: id.to_string(),
            files: names(&copies.duplicate_files),
            out_of_bins: binned,
        };
        report.flags.push(Flag::at(note, a, b, n));
    }
    if !binned {
        return;
    }
    if let Some((a, b)) = copies.removed_range {
        let n = copies.removed.0.len() as u64;
        let note = FlagNote::DuplicateRows {
            table: LogTable::Encoders,
            out_of_bins: true,
        };
        report.flags.push(Flag::at(note, a, b, n));
    }
    if let Some((a, b, n)) = copies.conflicts {
        let note = FlagNote::ConflictingInFiles {
            bar: id.to_string(),
            files: names(&copies.conflict_files),
        };
        report.flags.push(Flag::at(note, a, b, n));
    }
}

pub(super) fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// What rows `(time, counts, file)` sorted by all three hold more than once.
#[derive(Debug, Default, PartialEq)]
pub(super) struct Copies {
    /// Copies to take out: every row of a (time, counts) reading but one.
    pub(super) removed: (Vec<i64>, Vec<i64>),
    pub(super) removed_range: Option<(i64, i64)>,
    /// Readings held by more than one file: first, last time, copies among those removed.
    pub(super) across_files: Option<(i64, i64, u64)>,
    pub(super) duplicate_files: BTreeSet<u32>,
    /// Times with more than one counts value: first, last, readings concerned.
    pub(super) conflicts: Option<(i64, i64, u64)>,
    pub(super) conflict_files: BTreeSet<u32>,
}

pub(super) fn widen(range: Option<(i64, i64, u64)>, t: i64, n: u64) -> Option<(i64, i64, u64)> {
    let (a, b, m) = range.unwrap_or((t, t, 0));
    Some((a.min(t), b.max(t), m + n))
}

pub(super) fn compare_copies(rows: &[(i64, i64, u32)]) -> Copies {
    let mut out = Copies::default();
    for group in rows.chunk_by(|a, b| a.0 == b.0) {
        let t = group[0].0;
        let mut values = 0u64;
        for same in group.chunk_by(|a, b| a.1 == b.1) {
            values += 1;
            let extra = same.len() - 1;
            if extra == 0 {
                continue;
            }
            let c = same[0].1;
            out.removed.0.extend(std::iter::repeat_n(t, extra));
            out.removed.1.extend(std::iter::repeat_n(c, extra));
            out.removed_range = Some(out.removed_range.map_or((t, t), |(a, b)| (a, b.max(t))));
            if same.first().map(|r| r.2) != same.last().map(|r| r.2) {
                out.across_files = widen(out.across_files, t, extra as u64);
                out.duplicate_files.extend(same.iter().map(|r| r.2));
            }
        }
        if values > 1 {
            out.conflicts = widen(out.conflicts, t, group.len() as u64);
            out.conflict_files.extend(group.iter().map(|r| r.2));
        }
    }
    out
}

/// One bar's rows of one encoder file with times in one of `windows` (sorted, disjoint): the
/// scan filters by bar and by the windows' whole span, so only those rows are decoded into
/// memory. Missing counts (null, NaN, ±inf) are left out as in the streamed read; whole float
/// counts converted.
pub(super) fn rows_in_windows(
    path: &Path,
    bar: &str,
    windows: &[(i64, i64)],
) -> Result<Vec<(i64, i64)>, IngestError> {
    let (Some(&(from_ns, _)), Some(&(_, to_ns))) = (windows.first(), windows.last()) else {
        return Ok(Vec::new());
    };
    let inside = |t: i64| {
        let k = windows.partition_point(|w| w.1 < t);
        windows.get(k).is_some_and(|w| w.0 <= t)
    };
    Ok(rows_in_window(path, bar, from_ns, to_ns)?
        .into_iter()
        .filter(|&(t, _)| inside(t))
        .collect())
}

/// One bar's rows of one encoder file with times in `[from_ns, to_ns]`: the scan filters by
/// bar and time, so only those rows are decoded into memory. Missing counts (null, NaN, ±inf)
/// are left out as in the streamed read; whole float counts converted.
pub(super) fn rows_in_window(
    path: &Path,
    bar: &str,
    from_ns: i64,
    to_ns: i64,
) -> Result<Vec<(i64, i64)>, IngestError> {
    let scan = checked_scan(path, &ENCODER_COLUMNS)?;
    let unit = scan.time;
    let per = unit.ns_per_unit;
    let (lo, hi) = (
        from_ns.div_euclid(per) + i64::from(from_ns.rem_euclid(per) != 0),
        to_ns.div_euclid(per),
    );
    // Row groups whose footer statistics put all their times outside the window are skipped.
    let time_index = scan.columns.first().map_or(0, |c| c.index);
    let groups: Vec<usize> = (0..scan.file.row_group_rows().len())
        .filter(|&g| {
            scan.file
                .int64_range(g, time_index)
                .is_none_or(|(min, max)| max >= lo && min <= hi)
        })
        .collect();
    let mut rows = Vec::new();
    for batch in scan.reader(path, Some(groups))? {
        let batch = batch.map_err(|e| not_parquet(path, e))?;
        let batch = scan.canonical(&batch).map_err(|e| not_parquet(path, e))?;
        window_rows(&batch, bar, (lo, hi), unit, &mut rows).map_err(|e| not_parquet(path, e))?;
    }
    rows.retain(|&(t, _)| t >= from_ns && t <= to_ns);
    Ok(rows)
}

/// The rows of `batch` of bar `bar` with stored times in `[lo, hi]` and a count (whole float
/// counts converted, missing ones left out), times in ns, appended to `out`.
fn window_rows(
    batch: &Canonical,
    bar: &str,
    (lo, hi): (i64, i64),
    unit: TimeColumn,
    out: &mut Vec<(i64, i64)>,
) -> Result<(), ArrowError> {
    let time = batch.i64("time")?;
    let bars = batch.text("bar")?;
    let counts = batch.get("counts")?;
    let floats = counts.as_primitive_opt::<Float64Type>();
    let ints = counts.as_primitive_opt::<Int64Type>();
    for i in 0..batch.rows {
        if time.is_null(i) || bars.value(i) != Some(bar) {
            continue;
        }
        let t = time.value(i);
        if t < lo || t > hi {
            continue;
        }
        let count = match (floats, ints) {
            (Some(f), _) => f
                .is_valid(i)
                .then(|| f.value(i))
                .filter(|v| v.is_finite())
                .map(|v| v as i64),
            (None, Some(c)) => c.is_valid(i).then(|| c.value(i)),
            (None, None) => None,
        };
        if let (Some(ns), Some(c)) = (unit.to_ns(t), count) {
            out.push((ns, c));
        }
    }
    Ok(())
}
