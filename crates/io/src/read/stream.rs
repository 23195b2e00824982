//! Streaming the encoder files in batches cut at the files' footer row counts, so that every
//! batch knows its file; nulls and ids per file.

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

/// One decoded batch of rows of one encoder file, as the consumers get it.
pub(super) struct Batch {
    /// Index of the file.
    pub(super) file: u32,
    /// The file's rows before this batch (bad rows are named by their row in the file).
    pub(super) row_offset: u64,
    /// How the file stores its times.
    pub(super) time: TimeColumn,
    pub(super) frame: DataFrame,
}

/// Consumers of the decoded batches: each splits and accumulates whole batches into a sink of
/// its own, and the sinks are merged at the end (bins and repeat sketches are order-free
/// sums). One consumer was the stream's long pole: per row it costs more than polars' decoding.
pub(super) const BATCH_CONSUMERS: usize = 2;

/// Streams every encoder file into sinks with rows `rows(id)` per declared bar, merged into
/// one: polars decodes while [`BATCH_CONSUMERS`] threads split and accumulate the batches it
/// hands over (a bounded queue, so at most a few batches wait). `shared_scans`: files of one
/// schema share a scan (each batch is cut at the files' footer row counts, `footer_rows`).
pub(super) fn stream_encoders(
    files: &[PathBuf],
    footer_rows: &[u64],
    bar_ids: &BTreeSet<&str>,
    rows: &(dyn Fn(&str) -> BarRows + Sync),
    shared_scans: bool,
    zones: &mut Vec<(PathBuf, bool)>,
) -> Result<EncoderSink, IngestError> {
    let new_sink = || EncoderSink {
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
    };
    let (batches, received) = std::sync::mpsc::sync_channel::<Batch>(4);
    // Shared by the consumers only: when every consumer has stopped (an error), the receiver is
    // dropped and polars' next send fails, which ends the scan.
    let received = std::sync::Arc::new(std::sync::Mutex::new(received));
    let consumer_failed = || IngestError::Polars {
        context: "encoders".into(),
        message: "a batch consumer panicked".into(),
    };
    std::thread::scope(|scope| {
        let consumers: Vec<_> = (0..BATCH_CONSUMERS)
            .map(|_| {
                let mut sink = new_sink();
                let received = received.clone();
                scope.spawn(move || -> PolarsResult<EncoderSink> {
                    loop {
                        let next = match received.lock() {
                            Ok(queue) => queue.recv(),
                            Err(_) => break,
                        };
                        let Ok(batch) = next else { break };
                        (sink.file, sink.row_offset, sink.time) =
                            (batch.file, batch.row_offset, batch.time);
                        sink.push(&batch.frame)?;
                    }
                    Ok(sink)
                })
            })
            .collect();
        drop(received);
        let streamed = stream_files(files, footer_rows, batches, shared_scans, zones);
        let mut merged: Option<EncoderSink> = None;
        for consumer in consumers {
            let sink = consumer
                .join()
                .map_err(|_| consumer_failed())?
                .map_err(polars_error("encoders"))?;
            match merged.as_mut() {
                None => merged = Some(sink),
                Some(all) => all.merge(sink),
            }
        }
        streamed?;
        merged.ok_or_else(consumer_failed)
    })
}

/// Streams every encoder file, sending each batch with its file's index and its rows' offset in
/// that file to `batches`. `shared_scans`: consecutive files of one schema are
/// read by one scan; else one scan a file. `footer_rows`: each file's rows, as its footer says.
pub(super) fn stream_files(
    files: &[PathBuf],
    footer_rows: &[u64],
    batches: std::sync::mpsc::SyncSender<Batch>,
    shared_scans: bool,
    zones: &mut Vec<(PathBuf, bool)>,
) -> Result<(), IngestError> {
    // Schemas first (footers only): every schema error is raised before any row is read.
    let mut groups: Vec<(Vec<usize>, LazyFrame, SchemaRef, Vec<Expr>)> = Vec::new();
    for (index, path) in files.iter().enumerate() {
        let (lazy, schema, exprs) = guarded(path, || checked_scan(path, &ENCODER_COLUMNS))?;
        zones.push((path.clone(), TimeColumn::of(schema.get("time")).zoned));
        match groups.last_mut() {
            Some((members, _, shared, _)) if shared_scans && *shared == schema => {
                members.push(index)
            }
            _ => groups.push((vec![index], lazy, schema, exprs)),
        }
    }
    for (members, lazy, schema, exprs) in groups {
        let first = &files[members[0]];
        let time = TimeColumn::of(schema.get("time"));
        let (file, lazy, cursor) = if members.len() == 1 {
            (u32::try_from(members[0]).unwrap_or(u32::MAX), lazy, None)
        } else {
            let paths: Vec<PlRefPath> = members
                .iter()
                .map(|&i| {
                    PlRefPath::try_from_path(&files[i]).map_err(|e| not_parquet(&files[i], e))
                })
                .collect::<Result<_, _>>()?;
            let cursor = FileCursor::new(
                members
                    .iter()
                    .map(|&i| (u32::try_from(i).unwrap_or(u32::MAX), footer_rows[i]))
                    .collect(),
            );
            let shared = LazyFrame::scan_parquet_files(paths.into(), scan_args())
                .map_err(|e| not_parquet(first, e))?;
            (
                u32::MAX,
                shared,
                Some(std::sync::Arc::new(std::sync::Mutex::new(cursor))),
            )
        };
        // A shared scan's batches arrive in file order (`maintain_order`): each is cut at the
        // files' footer row counts and sent with its file's index, so every row's file is
        // known (`FileRange`) without a per-row path column.
        let to_consumer = batches.clone();
        let batch_cursor = cursor.clone();
        // Rows of a scan of one file sent so far: each batch's offset in its file.
        let sent = std::sync::atomic::AtomicU64::new(0);
        let callback = PlanCallback::new(move |batch: DataFrame| {
            let send = |file: u32, row_offset: u64, frame: DataFrame| {
                to_consumer
                    .send(Batch {
                        file,
                        row_offset,
                        time,
                        frame,
                    })
                    .map_err(|_| polars_err!(ComputeError: "the batch consumers stopped"))
            };
            match &batch_cursor {
                None => {
                    let rows = batch.height() as u64;
                    let offset = sent.fetch_add(rows, std::sync::atomic::Ordering::Relaxed);
                    send(file, offset, batch)?
                }
                Some(cursor) => {
                    let parts = cursor
                        .lock()
                        .map_err(|_| polars_err!(ComputeError: "the file cursor was poisoned"))?
                        .split(batch)?;
                    for (file, offset, part) in parts {
                        send(file, offset, part)?;
                    }
                }
            }
            Ok(false) // keep going
        });
        let scanned: Vec<&Path> = members.iter().map(|&i| files[i].as_path()).collect();
        guarded_scan(first, &scanned, || {
            lazy.select(exprs)
                .sink_batches(callback, true, None)
                .and_then(|lazy| lazy.collect_with_engine(Engine::Streaming))
                .map_err(|e| not_parquet(first, e))
        })?;
        if let Some(cursor) = cursor {
            let cursor = cursor.lock().map_err(|_| IngestError::Polars {
                context: "encoders".into(),
                message: "the file cursor was poisoned".into(),
            })?;
            if let Some((file, missing)) = cursor.unread() {
                return Err(IngestError::Polars {
                    context: file_path(files, file).display().to_string(),
                    message: format!(
                        "{missing} rows announced by the parquet footer were not decoded"
                    ),
                });
            }
        }
    }
    Ok(())
}

/// Where a shared scan is in its files: their indices and footer row counts, the file now
/// read and its rows not yet seen.
pub(super) struct FileCursor {
    pub(super) files: Vec<(u32, u64)>,
    pub(super) at: usize,
    pub(super) left: u64,
}

impl FileCursor {
    pub(super) fn new(files: Vec<(u32, u64)>) -> FileCursor {
        let left = files.first().map_or(0, |f| f.1);
        FileCursor { files, at: 0, left }
    }

    /// Skips files whose rows have all been seen (empty files included).
    pub(super) fn settle(&mut self) {
        while self.left == 0 && self.at + 1 < self.files.len() {
            self.at += 1;
            self.left = self.files[self.at].1;
        }
    }

    /// The next batch of the scan cut into runs of one file, each with its file's index and
    /// the file's rows before it. More rows than the footers announce is an error (it cannot
    /// happen with valid footers).
    pub(super) fn split(&mut self, batch: DataFrame) -> PolarsResult<Vec<(u32, u64, DataFrame)>> {
        let mut parts = Vec::with_capacity(1);
        let (mut start, n) = (0usize, batch.height());
        while start < n {
            self.settle();
            if self.left == 0 {
                polars_bail!(ComputeError: "the files hold more rows than their footers announce");
            }
            let take = (self.left.min((n - start) as u64)) as usize;
            let part = if start == 0 && take == n {
                batch.clone()
            } else {
                batch.slice(start as i64, take)
            };
            let (file, rows) = self.files[self.at];
            parts.push((file, rows - self.left, part));
            self.left -= take as u64;
            start += take;
        }
        Ok(parts)
    }

    /// The first file with rows its footer announced but the scan did not give, if any.
    pub(super) fn unread(&self) -> Option<(u32, u64)> {
        let mut cursor = FileCursor {
            files: self.files.clone(),
            at: self.at,
            left: self.left,
        };
        cursor.settle();
        (cursor.left > 0).then(|| (cursor.files[cursor.at].0, cursor.left))
    }
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

/// Rejects nulls in non-nullable columns, naming the first file that has some.
pub(super) fn check_nulls(
    df: &DataFrame,
    files: &[PathBuf],
    columns: &[ColumnSpec],
) -> Result<(), IngestError> {
    for spec in columns.iter().filter(|c| !c.nullable) {
        let Ok(column) = df.column(spec.name) else {
            continue;
        };
        if column.null_count() == 0 {
            continue;
        }
        let per_file = null_rows_per_file(df, spec.name).map_err(polars_error(spec.name))?;
        if let Some((&file, &count)) = per_file.iter().next() {
            return Err(IngestError::Nulls {
                path: file_path(files, file),
                column: spec.name,
                count,
            });
        }
    }
    Ok(())
}

pub(super) fn null_rows_per_file(df: &DataFrame, column: &str) -> PolarsResult<BTreeMap<u32, u64>> {
    let is_null = df.column(column)?.is_null();
    let files = df.column(FILE_COL)?.filter(&is_null)?;
    let mut per_file = BTreeMap::new();
    for file in files.u32()?.iter().flatten() {
        *per_file.entry(file).or_insert(0u64) += 1;
    }
    Ok(per_file)
}

/// Rows of an id `campaign.toml` does not declare, dropped: an `unusable_rows` flag.
pub(super) fn unknown_id_flag(
    path: &Path,
    column: &str,
    id: &str,
    rows: u64,
    first_ns: i64,
    last_ns: i64,
    known: &str,
) -> Flag {
    let note = format!(
        "{}: {rows} rows ({} .. {}) have {column} {:?}, which campaign.toml does not declare (known: {known}): dropped",
        path.display(),
        crate::format_ns(first_ns),
        crate::format_ns(last_ns),
        id
    );
    Flag::file(FlagKind::UnusableRows, rows, note)
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

/// Rows and time range per (file, id), sorted by file then id.
pub(super) fn id_summary(df: &DataFrame, id_column: &str) -> PolarsResult<Vec<IdSummary>> {
    let summary = df
        .clone()
        .lazy()
        .filter(col(id_column).is_not_null())
        .group_by([col(FILE_COL), col(id_column)])
        .agg([
            len().cast(DataType::Int64).alias("rows"),
            col("time").min().alias("first"),
            col("time").max().alias("last"),
        ])
        .sort([FILE_COL, id_column], SortMultipleOptions::default())
        .collect()?;
    let files = summary.column(FILE_COL)?.u32()?;
    let ids = summary.column(id_column)?.str()?;
    let rows = summary.column("rows")?.i64()?;
    let first = summary.column("first")?.i64()?;
    let last = summary.column("last")?.i64()?;
    let mut out = Vec::with_capacity(summary.height());
    for i in 0..summary.height() {
        out.push(IdSummary {
            file: files.get(i).unwrap_or(u32::MAX),
            id: ids.get(i).unwrap_or_default().to_string(),
            rows: rows.get(i).unwrap_or(0).max(0) as u64,
            first_ns: first.get(i).unwrap_or(0),
            last_ns: last.get(i).unwrap_or(0),
        });
    }
    Ok(out)
}
