//! The temperature table, streamed: each file decoded in batches and every row put straight into
//! its sensor's log, so that reading a 1 Hz temperature log costs its rows' decode and one copy,
//! never a stacked table of every file beside the per-sensor logs.

use super::*;

/// One declared sensor's rows gathered from every file: its finite readings in arrival order
/// (the log they become, unsorted), the rows read, and the missing values (null, NaN, ±inf)
/// dropped.
#[derive(Default)]
struct SensorRows {
    log: SensorLog,
    rows: u64,
    missing: Missing,
}

/// Rows of one file that cannot be used, by problem: a null time, a null sensor, a time that is
/// no accepted reading time.
#[derive(Default)]
struct FileProblems {
    null_time: Option<BadRange>,
    null_sensor: Option<BadRange>,
    bad_time: Option<BadRange>,
}

impl FileProblems {
    /// The flags of the rows dropped, in the order the spec lists the columns.
    fn flags(self, path: &Path) -> impl Iterator<Item = Flag> + '_ {
        [
            self.null_time
                .map(|b| b.flag(path, "time", RowProblem::Null)),
            self.null_sensor
                .map(|b| b.flag(path, "sensor", RowProblem::Null)),
            self.bad_time
                .map(|b| b.flag(path, "time", RowProblem::TimeOutOfBounds)),
        ]
        .into_iter()
        .flatten()
    }
}

/// What the temperature batches leave behind: per declared sensor its rows, per (file, id) the
/// rows of undeclared sensors.
struct SensorSink {
    /// Declared sensors first (the indices of `sensors`), then undeclared ids as they appear.
    ids: IdIndex,
    sensors: Vec<SensorRows>,
    unknown: BTreeMap<(u32, String), FileRange>,
    /// Scratch: each row's id index, and the current file's undeclared rows by id index.
    row_ids: Vec<u32>,
    unknown_in_file: Vec<Option<FileRange>>,
}

impl SensorSink {
    fn new(sensor_ids: &BTreeSet<&str>, rows_hint: u64) -> SensorSink {
        let declared = sensor_ids.len();
        let each = usize::try_from(rows_hint / declared.max(1) as u64).unwrap_or(0);
        SensorSink {
            ids: IdIndex::new(sensor_ids.iter().copied()),
            sensors: (0..declared)
                .map(|_| SensorRows {
                    log: SensorLog {
                        time_ns: Vec::with_capacity(each),
                        celsius: Vec::with_capacity(each),
                    },
                    ..SensorRows::default()
                })
                .collect(),
            unknown: BTreeMap::new(),
            row_ids: Vec::new(),
            unknown_in_file: Vec::new(),
        }
    }

    /// Adds one batch whose first row is row `offset` of its file; rows that cannot be used are
    /// recorded in `problems` by their row in the file.
    fn push(
        &mut self,
        batch: &Canonical,
        offset: u64,
        unit: TimeColumn,
        problems: &mut FileProblems,
    ) -> Result<(), ArrowError> {
        let time = batch.i64("time")?;
        let sensor = batch.text("sensor")?;
        let celsius = batch.f64("celsius")?;
        let mut row_ids = std::mem::take(&mut self.row_ids);
        self.ids.indices(sensor, &mut row_ids);
        let raw = time.values();
        for (i, &index) in row_ids.iter().enumerate() {
            let row = offset + i as u64;
            let ns = if time.is_valid(i) {
                let ns = unit.to_ns(raw[i]);
                if ns.is_none() {
                    let t = raw[i];
                    BadRange::add(&mut problems.bad_time, row, || {
                        format!("{t} {}", unit.unit())
                    });
                }
                ns
            } else {
                BadRange::add(&mut problems.null_time, row, || "null".into());
                None
            };
            if sensor.is_null(i) {
                BadRange::add(&mut problems.null_sensor, row, || "null".into());
                continue;
            }
            let Some(t) = ns else { continue };
            let value = celsius.is_valid(i).then(|| celsius.value(i));
            self.add(index as usize, t, value);
        }
        self.row_ids = row_ids;
        Ok(())
    }

    /// One usable row (a time and an id) of the sensor with index `index`.
    fn add(&mut self, index: usize, t: i64, value: Option<f64>) {
        if let Some(sensor) = self.sensors.get_mut(index) {
            sensor.rows += 1;
            match value {
                Some(c) if c.is_finite() => {
                    sensor.log.time_ns.push(t);
                    sensor.log.celsius.push(c);
                }
                other => sensor.missing.add(t, other),
            }
            return;
        }
        if self.unknown_in_file.len() <= index {
            self.unknown_in_file.resize(index + 1, None);
        }
        let range = FileRange {
            first_ns: t,
            last_ns: t,
            rows: 1,
        };
        match &mut self.unknown_in_file[index] {
            Some(r) => {
                r.first_ns = r.first_ns.min(t);
                r.last_ns = r.last_ns.max(t);
                r.rows += 1;
            }
            slot => *slot = Some(range),
        }
    }

    /// The current file's undeclared rows, kept by (file, id).
    fn end_file(&mut self, file: u32) {
        for (index, range) in self.unknown_in_file.drain(..).enumerate() {
            if let Some(range) = range {
                let id = self.ids.names[index].clone();
                FileRange::add_to(&mut self.unknown, (file, id), range);
            }
        }
    }
}

/// Streams one temperature file (`index` in the table's files) into `sink`, its unusable rows
/// flagged in `dropped`; returns how its times are stored.
fn stream_file(
    path: &Path,
    index: u32,
    sink: &mut SensorSink,
    dropped: &mut Vec<Flag>,
) -> Result<TimeColumn, IngestError> {
    let scan = checked_scan(path, &TEMPERATURE_COLUMNS)?;
    let mut problems = FileProblems::default();
    let mut offset = 0u64;
    for batch in scan.reader(path, None)? {
        let batch = batch.map_err(|e| not_parquet(path, e))?;
        let rows = scan.canonical(&batch).map_err(|e| not_parquet(path, e))?;
        sink.push(&rows, offset, scan.time, &mut problems)
            .map_err(|e| not_parquet(path, e))?;
        offset += rows.rows as u64;
    }
    sink.end_file(index);
    dropped.extend(problems.flags(path));
    Ok(scan.time)
}

/// Every temperature file streamed, in file order, into per-sensor logs: rows without a time or
/// a sensor, or with a time out of range, dropped and flagged by file and rows; rows of
/// undeclared sensors dropped and flagged by file and id (after the files' own flags); each
/// declared sensor's log sorted, its missing values and duplicates recorded
/// ([`sensor_log`]), the sensors in parallel.
pub(super) fn read_temperatures(
    files: &CampaignFiles,
    sensor_ids: &BTreeSet<&str>,
) -> Result<TemperatureTables, IngestError> {
    let clock = std::time::Instant::now();
    let paths = &files.temperatures;
    // A hint only (each sensor's log reserved once); a footer that cannot be read is reported
    // by the read below, in file order.
    let hint = paths
        .iter()
        .filter_map(|p| ParquetFile::open(p).ok())
        .fold(0u64, |n, f| n.saturating_add(f.rows()));
    let mut sink = SensorSink::new(sensor_ids, hint);
    let (mut zones, mut dropped) = (Vec::new(), Vec::new());
    for (index, path) in paths.iter().enumerate() {
        let index = u32::try_from(index).unwrap_or(u32::MAX);
        let time = guarded(path, || stream_file(path, index, &mut sink, &mut dropped))?;
        zones.push((path.clone(), time.zoned));
    }
    let declared: Vec<String> = sensor_ids.iter().map(|s| s.to_string()).collect();
    dropped.extend(sink.unknown.iter().map(|((file, id), u)| {
        unknown_id_flag(
            &file_path(paths, *file),
            "sensor",
            id,
            u.rows,
            u.first_ns,
            u.last_ns,
            &declared,
        )
    }));
    use rayon::prelude::*;
    let finished: Vec<(SensorLog, ChannelQuality)> = std::mem::take(&mut sink.sensors)
        .into_par_iter()
        .map(sensor_log)
        .collect();
    let mut sensors = BTreeMap::new();
    let mut quality = BTreeMap::new();
    for (id, (log, q)) in sensor_ids.iter().zip(finished) {
        sensors.insert(id.to_string(), log);
        quality.insert(id.to_string(), q);
    }
    tracing::debug!(elapsed = ?clock.elapsed(), "temperatures read");
    Ok((sensors, quality, zones, dropped))
}

/// A sensor's log from its rows: sorted by time, ties by value, so that the order never
/// depends on how the rows were split into files and batches (already sorted rows, a logger's
/// usual output, are only checked); exact duplicates counted once; implausible readings
/// dropped. The missing values (null, NaN, ±inf: a missing reading, not a temperature, which
/// would otherwise spread through every bar that interpolates the sensor) were dropped while
/// streaming; all of it recorded in the sensor's quality.
fn sensor_log(rows: SensorRows) -> (SensorLog, ChannelQuality) {
    let SensorRows {
        mut log,
        rows,
        missing,
    } = rows;
    let mut q = ChannelQuality {
        rows,
        ..ChannelQuality::default()
    };
    missing.record(&mut q, LogTable::Temperatures);
    sort_by_time_then_value(&mut log);
    let (dups, range) = quality::dedup_sorted(&mut log.time_ns, &mut log.celsius);
    quality::record_duplicates(&mut q, dups, range, LogTable::Temperatures);
    quality::drop_implausible_temperatures(&mut log.time_ns, &mut log.celsius, &mut q);
    (log, q)
}

/// Rows per bucket of [`sort_by_time_then_value`]'s bucket sort, on average over a log's time
/// range (a power of two).
const ROWS_PER_BUCKET: usize = 4;

/// Sorts a log by time, ties by value (`f64::total_cmp`). Already sorted (a logger's usual
/// output), it is only checked: no memory beside it. Otherwise the readings are dealt out as
/// pairs into buckets of equal time width (a counting sort on the time's high bits, about
/// [`ROWS_PER_BUCKET`] rows a bucket), each bucket sorted, and written back: on a shuffled 1 Hz
/// log a quarter of a comparison sort's time, and never worse than one on times bunched into a
/// few buckets. Rows equal in this order are the same bits, so the unstable sorts are
/// deterministic.
fn sort_by_time_then_value(log: &mut SensorLog) {
    let (time, celsius) = (&mut log.time_ns, &mut log.celsius);
    let in_order = |i: usize| {
        time[i] < time[i + 1]
            || (time[i] == time[i + 1] && celsius[i].total_cmp(&celsius[i + 1]).is_le())
    };
    if (0..time.len().saturating_sub(1)).all(in_order) {
        return;
    }
    let (Some(&first), Some(&last)) = (time.iter().min(), time.iter().max()) else {
        return;
    };
    // Bucket `b` holds the times `first + [b << shift, (b + 1) << shift)`: at most the buckets
    // aimed at. Accepted reading times: the range cannot wrap.
    let range = last.wrapping_sub(first) as u64;
    let aimed = (time.len() / ROWS_PER_BUCKET).max(1).next_power_of_two();
    let shift = (u64::BITS - range.leading_zeros()).saturating_sub(aimed.trailing_zeros());
    let bucket = |t: i64| (t.wrapping_sub(first) as u64 >> shift) as usize;
    let mut start = vec![0usize; (range >> shift) as usize + 2];
    for &t in time.iter() {
        start[bucket(t) + 1] += 1;
    }
    for b in 1..start.len() {
        start[b] += start[b - 1];
    }
    let mut rows = vec![(0i64, 0f64); time.len()];
    let mut next = start.clone();
    for (&t, &c) in time.iter().zip(celsius.iter()) {
        let at = &mut next[bucket(t)];
        rows[*at] = (t, c);
        *at += 1;
    }
    for b in start.windows(2) {
        if b[1] - b[0] > 1 {
            rows[b[0]..b[1]].sort_unstable_by(|x, y| x.0.cmp(&y.0).then(x.1.total_cmp(&y.1)));
        }
    }
    for ((t, c), (rt, rc)) in time.iter_mut().zip(celsius.iter_mut()).zip(rows) {
        (*t, *c) = (rt, rc);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The order of a comparison sort by (time, value), whatever the buckets.
    #[test]
    fn bucket_sort_gives_the_order_of_time_then_value() {
        use rand::{seq::SliceRandom, Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let t0 = 1_793_491_200_000_000_000i64;
        for (rows, spread_ns) in [
            (1, 1),
            (2, 0),
            (50, 3),
            (1000, 1_000_000_000),
            (5000, 1 << 40),
        ] {
            let mut pairs: Vec<(i64, f64)> = (0..rows)
                .map(|_| {
                    let t = t0 + rng.gen_range(0..=spread_ns);
                    (t, f64::from(rng.gen_range(-3i32..3)) * 0.5)
                })
                .collect();
            pairs.shuffle(&mut rng);
            let mut log = SensorLog {
                time_ns: pairs.iter().map(|p| p.0).collect(),
                celsius: pairs.iter().map(|p| p.1).collect(),
            };
            sort_by_time_then_value(&mut log);
            pairs.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
            let sorted: Vec<(i64, f64)> = log.time_ns.into_iter().zip(log.celsius).collect();
            assert_eq!(sorted, pairs, "{rows} rows over {spread_ns} ns");
        }
    }
}
