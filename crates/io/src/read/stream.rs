//! Streaming the encoder files row group by row group on the consumer threads, so that every
//! batch knows its file and its rows' offset in it; undeclared ids per file.

use super::*;

/// The encoder table per bar: full-rate logs (sorted) or bins, and per bar the rows read and
/// the missing counts dropped.
pub(super) struct Encoders {
    pub(super) logs: BTreeMap<String, BarLog>,
    pub(super) bins: BTreeMap<String, BarBins>,
    pub(super) rows: BTreeMap<String, (u64, Missing)>,
    /// Per bar: rows several files hold ([`resolve_repeats`]).
    pub(super) overlaps: BTreeMap<String, Overlap>,
    /// Rows that could not be used, dropped: one `unusable_rows` flag per file, column and
    /// problem.
    pub(super) dropped: Vec<Flag>,
}

/// Threads that each decode whole row groups of the encoder files and split and accumulate
/// their batches into a sink of their own; the sinks are merged at the end (bins and repeat
/// sketches are order-free sums). Each thread decodes and consumes in turn, so two keep both
/// cores of the reference machine busy without a queue between a decoder and its consumers.
pub(super) const BATCH_CONSUMERS: usize = 2;

/// One row group of one encoder file: the unit of work of a consumer.
pub(super) struct RowGroupTask {
    /// Index of the file.
    pub(super) file: u32,
    /// Index of the row group in the file.
    pub(super) group: usize,
    /// The file's rows before this row group (bad rows are named by their row in the file).
    pub(super) row_offset: u64,
}

/// Streams every encoder file into sinks with rows `rows(id)` per declared bar, merged into
/// one: [`BATCH_CONSUMERS`] threads take the files' row groups in file order, decode each in
/// batches (only the three spec columns) and split and accumulate every batch, knowing its file
/// and its rows' offset in that file. Every schema is checked (footers only) before any row is
/// read; a decode that fails names its file (the first such file, in file order).
pub(super) fn stream_encoders(
    files: &[PathBuf],
    bar_ids: &BTreeSet<&str>,
    rows: &(dyn Fn(&str) -> BarRows + Sync),
    zones: &mut Vec<(PathBuf, bool)>,
) -> Result<EncoderSink, IngestError> {
    let mut scans = Vec::with_capacity(files.len());
    for path in files {
        let scan = guarded(path, || checked_scan(path, &ENCODER_COLUMNS))?;
        zones.push((path.clone(), scan.time.zoned));
        scans.push(scan);
    }
    let tasks = row_group_tasks(&scans);
    let next = std::sync::atomic::AtomicUsize::new(0);
    let failed = std::sync::Mutex::new(None::<(usize, IngestError)>);
    let consume = || -> Result<EncoderSink, IngestError> {
        let mut sink = EncoderSink::new(bar_ids, rows);
        loop {
            let at = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let Some(task) = tasks.get(at) else { break };
            if failed.lock().map_or(true, |f| f.is_some()) {
                break;
            }
            if let Err(e) = consume_row_group(files, &scans, task, &mut sink) {
                if let Ok(mut first) = failed.lock() {
                    if first.as_ref().is_none_or(|(k, _)| at < *k) {
                        *first = Some((at, e));
                    }
                }
                break;
            }
        }
        Ok(sink)
    };
    let consumer_failed = || IngestError::Parquet {
        context: "encoders".into(),
        message: "a batch consumer panicked".into(),
    };
    let sinks: Vec<Result<EncoderSink, IngestError>> = std::thread::scope(|scope| {
        let consumers: Vec<_> = (0..BATCH_CONSUMERS).map(|_| scope.spawn(consume)).collect();
        consumers
            .into_iter()
            .map(|c| c.join().unwrap_or_else(|_| Err(consumer_failed())))
            .collect()
    });
    if let Some((_, e)) = failed.into_inner().ok().flatten() {
        return Err(e);
    }
    let mut merged: Option<EncoderSink> = None;
    for sink in sinks {
        let sink = sink?;
        match merged.as_mut() {
            None => merged = Some(sink),
            Some(all) => all.merge(sink),
        }
    }
    merged.ok_or_else(consumer_failed)
}

/// Every non-empty row group of every file, in file order, with its first row in its file.
pub(super) fn row_group_tasks(scans: &[Scan]) -> Vec<RowGroupTask> {
    let mut tasks = Vec::new();
    for (file, scan) in scans.iter().enumerate() {
        let mut row_offset = 0;
        for (group, rows) in scan.file.row_group_rows().into_iter().enumerate() {
            if rows > 0 {
                tasks.push(RowGroupTask {
                    file: u32::try_from(file).unwrap_or(u32::MAX),
                    group,
                    row_offset,
                });
            }
            row_offset += rows;
        }
    }
    tasks
}

/// Decodes one row group (announced to the supervisor, a panic named by its file) and adds
/// every batch to `sink`.
fn consume_row_group(
    files: &[PathBuf],
    scans: &[Scan],
    task: &RowGroupTask,
    sink: &mut EncoderSink,
) -> Result<(), IngestError> {
    let index = task.file as usize;
    let (Some(path), Some(scan)) = (files.get(index), scans.get(index)) else {
        return Ok(());
    };
    guarded(path, || {
        (sink.file, sink.row_offset, sink.time) = (task.file, task.row_offset, scan.time);
        for batch in scan.reader(path, Some(vec![task.group]))? {
            let batch = batch.map_err(|e| not_parquet(path, e))?;
            let rows = scan.canonical(&batch).map_err(|e| not_parquet(path, e))?;
            sink.push(&rows).map_err(|e| not_parquet(path, e))?;
        }
        Ok(())
    })
}

/// Rows sorted by time, ties by value, so that the order never depends on how the rows were
/// split into files and batches. Already sorted rows (a logger's usual output) are only checked.
pub(super) fn sorted_by_time_then_value(
    mut time_ns: Vec<i64>,
    mut counts: Vec<i64>,
) -> (Vec<i64>, Vec<i64>) {
    let sorted = time_ns
        .windows(2)
        .zip(counts.windows(2))
        .all(|(t, c)| (t[0], c[0]) <= (t[1], c[1]));
    if sorted {
        return (time_ns, counts);
    }
    let mut rows: Vec<(i64, i64)> = time_ns
        .iter()
        .copied()
        .zip(counts.iter().copied())
        .collect();
    // Equal (time, counts) pairs are indistinguishable, so an unstable sort is deterministic.
    rows.sort_unstable();
    // Written back into the columns: one pair buffer beside them, not two more columns.
    for ((t, c), (rt, rc)) in time_ns.iter_mut().zip(counts.iter_mut()).zip(rows) {
        (*t, *c) = (rt, rc);
    }
    (time_ns, counts)
}

/// Rows of an id `campaign.toml` does not declare, dropped: an `unusable_rows` flag.
pub(super) fn unknown_id_flag(
    path: &Path,
    column: &str,
    id: &str,
    rows: u64,
    first_ns: i64,
    last_ns: i64,
    declared: &[String],
) -> Flag {
    let note = FlagNote::UndeclaredId {
        file: path.to_path_buf(),
        column: column.to_string(),
        id: id.to_string(),
        first_ns,
        last_ns,
        declared: declared.to_vec(),
    };
    Flag::file(note, rows)
}

pub(super) fn file_path(files: &[PathBuf], index: u32) -> PathBuf {
    files.get(index as usize).cloned().unwrap_or_default()
}

pub(super) struct IdSummary {
    pub(super) file: u32,
    pub(super) id: String,
    pub(super) rows: u64,
    pub(super) first_ns: i64,
    pub(super) last_ns: i64,
}
