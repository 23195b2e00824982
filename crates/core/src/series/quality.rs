//! What the logs hold besides readings, and what ingest did about it (`summary.json` →
//! `quality`): missing values (null, NaN, ±inf) dropped and counted, exact duplicates counted
//! once, and a bar's encoder checked for the faults a thermal fit would take for thermal
//! error: a frozen counter, single-sample jumps, a 32-bit counter wrap; and for the signs of a
//! clock that jumped: readings of one time with different counts (`conflicting_readings`) and
//! gaps inside a mount (`gap`). Nothing is dropped without a count, and nothing suspicious
//! reaches a fit without a flag. (Rows that two files both hold are found by ingest,
//! `io::read::resolve_repeats`.)
//!
//! The encoder checks run on a bar's *pieces* in time order within each zero segment (a mount,
//! split at `rezero` events; handling time is never fitted and the bar moves then): a piece is
//! one reading of a full-rate log, or one bin of a log compressed while it streamed
//! (`BinMoments` keeps each bin's smallest and largest counts), so both reading paths apply one
//! rule, binned flags with a bin's time resolution. Rules and thresholds, as promised:
//! `docs/guarantees.md`, "Inputs".
//!
//! # How it works
//!
//! - Temperatures outside −60 .. 150 °C, and steps beyond 5 K + 0.05 K/s from the last kept reading
//!   (walked both ways from the reading nearest the median), are dropped in `io::read::sensor_log`
//!   by `series::quality::drop_implausible_temperatures` (`implausible_temperature`).
//! - After ingest, each bar's log or bins go through `series::quality::check_log` /
//!   `check_bins` (one rule on "pieces": a reading or a bin with its min/max counts, which
//!   `BinMoments` keeps): exact duplicates, jumps, counter wraps (mount left out), frozen runs
//!   (readings left out), readings far outside the mounts. A bar with nothing left is marked
//!   `unusable`; `pipeline::analyse` fails it alone with that reason.
//! - `summary.json` → `quality` is `series::Quality`, carried by `CampaignLogs` and `RunResults`.
//!   Findings are data (`FlagNote`, `Unusable`); their words are the application's
//!   (`src/narrative/quality.rs`).

use std::collections::BTreeMap;

use super::bins::Segments;
use super::{BarBins, BarLog, Event, Region, SensorLog};
use crate::campaign::{Campaign, SensorKind, TimeNs};

mod findings;
pub use findings::{Flag, FlagKind, FlagNote, JumpPlace, LogTable, RowProblem, Unusable};

/// A step between consecutive pieces (or a spread inside a bin) is a jump when it exceeds this
/// many robust standard deviations of the segment's steps (1.4826 × their median absolute
/// deviation) ...
pub(crate) const JUMP_NOISE_FACTOR: f64 = 20.0;
/// ... and at least this much (µm): the thermal drift between two readings of a bar is far
/// below a micrometre (0.4 µm/h for 400 mm, 1 ppm/K, 1 K/h), so a noise-free log does not flag
/// every count.
pub(crate) const JUMP_FLOOR_UM: f64 = 1.0;
/// A bin's spread (largest − smallest counts) is a jump when it exceeds this many times the
/// segment's median bin spread (and [`JUMP_FLOOR_UM`]).
pub(crate) const BIN_SPREAD_FACTOR: f64 = 4.0;
/// The period of a 32-bit counter, counts.
pub const WRAP_COUNTS: i64 = 1 << 32;
/// A jump of at least half a 32-bit counter's period is a counter wrap (no bar moves by
/// 2³¹ counts, 10.7 m at 5 nm, within a mount): the mount is left out of the fits.
pub(crate) const WRAP_MIN_JUMP_COUNTS: i64 = 1 << 31;
/// A run of readings with one count value is a frozen encoder when it lasts at least this long
/// (s) ...
pub(crate) const STUCK_MIN_S: f64 = 3600.0;
/// ... holds at least this many readings ...
pub(crate) const STUCK_MIN_READINGS: u64 = 10;
/// ... and the bar's air (its sensor, else the air sensors) moved at least this much meanwhile
/// (K; a window with no air reading counts as moving): 0.05 K on 230 mm at 1 ppm/K is 11 nm,
/// two counts of 5 nm, and reading noise alone changes the count of a live encoder.
pub(crate) const STUCK_MIN_AIR_CHANGE_K: f64 = 0.05;
/// Readings more than this long (s) before a bar's first mount or after its last are flagged:
/// a clock reset or a wrong day file.
pub const FAR_OUTSIDE_MOUNTS_S: f64 = 86_400.0;

/// A gap inside a mount is flagged when no reading comes for longer than this many times the
/// bar's median interval between readings ...
pub const GAP_INTERVAL_FACTOR: f64 = 10.0;
/// ... and at least this long (s).
pub const GAP_MIN_S: f64 = 600.0;

/// The gap threshold for a bar whose median interval between readings is `median_interval_ns`.
pub(crate) fn gap_threshold_ns(median_interval_ns: f64) -> TimeNs {
    (GAP_INTERVAL_FACTOR * median_interval_ns).max(GAP_MIN_S * 1e9) as TimeNs
}

/// Everything ingest found, per bar, sensor, the events and the files.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Quality {
    /// Per bar.
    pub bars: BTreeMap<String, ChannelQuality>,
    /// Per sensor.
    pub sensors: BTreeMap<String, ChannelQuality>,
    /// The events table.
    pub events: ChannelQuality,
    /// Campaign-wide flags: byte-identical files read once, naive and zoned time columns mixed.
    pub files: Vec<Flag>,
}

impl Quality {
    /// Why bar `bar` has no usable signal, if it has none (it then fails alone).
    pub fn unusable(&self, bar: &str) -> Option<Unusable> {
        self.bars.get(bar).and_then(|q| q.unusable)
    }
}

/// Counts of one bar's, sensor's or the events' rows, and the flags raised on them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ChannelQuality {
    /// Rows read (before anything was dropped).
    pub rows: u64,
    /// Rows whose value was null / NaN / ±infinite (dropped).
    pub null: u64,
    /// Rows whose value was NaN (dropped).
    pub nan: u64,
    /// Rows whose value was ±infinite (dropped).
    pub inf: u64,
    /// Exact copies of another row (same time and value; counted once, the copies dropped).
    pub duplicate_rows: u64,
    /// Readings of a frozen encoder or of a mount left out for a counter wrap (dropped).
    pub fault_rows: u64,
    /// Every row dropped: `null + nan + inf + duplicate_rows + fault_rows`.
    pub dropped_rows: u64,
    /// The flags raised, in time order.
    pub flags: Vec<Flag>,
    /// Set when no usable reading is left: the bar fails alone for this reason.
    pub unusable: Option<Unusable>,
}

/// The lowest temperature a sensor of a measuring room may read, °C (absolute zero is
/// −273.15; a logger's error codes sit far below, e.g. −999).
pub const PLAUSIBLE_MIN_C: f64 = -60.0;
/// The highest, °C (a heated head stays far below).
pub const PLAUSIBLE_MAX_C: f64 = 150.0;
/// The largest step air (or a sensor in it) makes between two readings at once, K ...
pub const PLAUSIBLE_STEP_K: f64 = 5.0;
/// ... plus this much a second between them, K/s.
pub const PLAUSIBLE_STEP_K_PER_S: f64 = 0.05;
/// The largest step between two readings `dt_s` apart that air (or a sensor in it) makes:
/// [`PLAUSIBLE_STEP_K`] at once, plus [`PLAUSIBLE_STEP_K_PER_S`] a second.
pub(crate) fn plausible_step_k(dt_s: f64) -> f64 {
    PLAUSIBLE_STEP_K + PLAUSIBLE_STEP_K_PER_S * dt_s.max(0.0)
}

/// Drops temperature readings (sorted by time) outside the plausible range, then those whose
/// step from the last kept reading exceeds `plausible_step_k`, walking forward and backward
/// from the reading nearest the median (so a bad first reading is not the yardstick); counts them
/// in `fault_rows` and flags them (`implausible_temperature`).
pub fn drop_implausible_temperatures(
    time_ns: &mut Vec<TimeNs>,
    celsius: &mut Vec<f64>,
    q: &mut ChannelQuality,
) {
    let n = time_ns.len().min(celsius.len());
    let mut keep: Vec<bool> = celsius[..n]
        .iter()
        .map(|c| c.is_finite() && (PLAUSIBLE_MIN_C..=PLAUSIBLE_MAX_C).contains(c))
        .collect();
    let out_of_range = keep.iter().filter(|k| !**k).count() as u64;
    let mut values: Vec<f64> = (0..n).filter(|&i| keep[i]).map(|i| celsius[i]).collect();
    if !values.is_empty() {
        let mid = values.len() / 2;
        let (_, median, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
        let median = *median;
        let anchor = (0..n)
            .filter(|&i| keep[i])
            .min_by(|&a, &b| {
                (celsius[a] - median)
                    .abs()
                    .total_cmp(&(celsius[b] - median).abs())
            })
            .unwrap_or(0);
        let step_ok = |i: usize, last: usize| {
            let dt_s = (time_ns[i] as f64 - time_ns[last] as f64).abs() * 1e-9;
            (celsius[i] - celsius[last]).abs() <= plausible_step_k(dt_s)
        };
        let mut walk = |order: &mut dyn Iterator<Item = usize>| {
            let mut last = anchor;
            for i in order {
                if keep[i] {
                    if step_ok(i, last) {
                        last = i;
                    } else {
                        keep[i] = false;
                    }
                }
            }
        };
        walk(&mut (anchor + 1..n));
        walk(&mut (0..anchor).rev());
    }
    let dropped = keep.iter().filter(|k| !**k).count() as u64;
    if dropped == 0 {
        return;
    }
    let first = (0..n).find(|&i| !keep[i]).unwrap_or(0);
    let last = (0..n).rev().find(|&i| !keep[i]).unwrap_or(0);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for i in (0..n).filter(|&i| !keep[i]) {
        lo = lo.min(celsius[i]);
        hi = hi.max(celsius[i]);
    }
    let note = FlagNote::ImplausibleTemperatures {
        outside_range: out_of_range,
        lowest_c: lo,
        highest_c: hi,
    };
    q.flags
        .push(Flag::at(note, time_ns[first], time_ns[last], dropped));
    q.fault_rows += dropped;
    q.dropped_rows += dropped;
    let mut k = 0;
    for i in 0..n {
        if keep[i] {
            time_ns[k] = time_ns[i];
            celsius[k] = celsius[i];
            k += 1;
        }
    }
    time_ns.truncate(k);
    celsius.truncate(k);
}

/// RFC 3339 rendering of ns since the epoch.
pub fn format_ns(ns: TimeNs) -> String {
    chrono::DateTime::from_timestamp_nanos(ns).to_rfc3339_opts(chrono::SecondsFormat::AutoSi, true)
}

/// Time range and number of rows of dropped values, kept while rows stream by.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Missing {
    pub(crate) null: u64,
    pub(crate) nan: u64,
    pub(crate) inf: u64,
    /// First and last time of a dropped row (`None` before any).
    pub(crate) range: Option<(TimeNs, TimeNs)>,
}

impl Missing {
    /// Counts one dropped value at `t`: null when `None`, else NaN or infinite.
    pub fn add(&mut self, t: TimeNs, value: Option<f64>) {
        match value {
            None => self.null += 1,
            Some(v) if v.is_nan() => self.nan += 1,
            Some(_) => self.inf += 1,
        }
        self.range = Some(self.range.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
    }

    pub(crate) fn total(&self) -> u64 {
        self.null + self.nan + self.inf
    }

    /// Adds the values `other` counted (the same channel, other rows).
    pub fn merge(&mut self, other: &Missing) {
        self.null += other.null;
        self.nan += other.nan;
        self.inf += other.inf;
        self.range = match (self.range, other.range) {
            (Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
            (a, b) => a.or(b),
        };
    }

    /// Adds the counts and, when any, a `missing_values` flag to `q` (rows of `table`).
    pub fn record(&self, q: &mut ChannelQuality, table: LogTable) {
        q.null += self.null;
        q.nan += self.nan;
        q.inf += self.inf;
        q.dropped_rows += self.total();
        if let Some((a, b)) = self.range {
            let note = FlagNote::MissingValues {
                table,
                null: self.null,
                nan: self.nan,
                inf: self.inf,
            };
            q.flags.push(Flag::at(note, a, b, self.total()));
        }
    }
}

/// Drops exact duplicates from sorted `(time, value)` columns; returns how many and the range.
pub fn dedup_sorted<V: PartialEq + Copy>(
    time_ns: &mut Vec<TimeNs>,
    values: &mut Vec<V>,
) -> (u64, Option<(TimeNs, TimeNs)>) {
    let n = time_ns.len().min(values.len());
    let mut keep = 0;
    let mut range: Option<(TimeNs, TimeNs)> = None;
    for i in 0..n {
        if keep > 0 && time_ns[keep - 1] == time_ns[i] && values[keep - 1] == values[i] {
            let t = time_ns[i];
            range = Some(range.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
            continue;
        }
        time_ns[keep] = time_ns[i];
        values[keep] = values[i];
        keep += 1;
    }
    let dropped = (n - keep) as u64;
    time_ns.truncate(keep);
    values.truncate(keep);
    (dropped, range)
}

/// Records `dropped` duplicates of rows of `table` (range `range`) in `q`.
pub fn record_duplicates(
    q: &mut ChannelQuality,
    dropped: u64,
    range: Option<(TimeNs, TimeNs)>,
    table: LogTable,
) {
    q.duplicate_rows += dropped;
    q.dropped_rows += dropped;
    if let Some((a, b)) = range {
        let note = FlagNote::DuplicateRows {
            table,
            out_of_bins: false,
        };
        q.flags.push(Flag::at(note, a, b, dropped));
    }
}

/// Readings of one bar at one time with different counts, in rows sorted by (time, counts)
/// without exact duplicates: a `conflicting_readings` flag (range, rows concerned), or `None`.
pub(crate) fn conflicting_sorted(time_ns: &[TimeNs], counts: &[i64]) -> Option<Flag> {
    let n = time_ns.len().min(counts.len());
    let (mut rows, mut range) = (0u64, None::<(TimeNs, TimeNs)>);
    let mut i = 0;
    while i < n {
        let mut end = i + 1;
        while end < n && time_ns[end] == time_ns[i] {
            end += 1;
        }
        if counts[i..end].iter().any(|&c| c != counts[i]) {
            rows += (end - i) as u64;
            let t = time_ns[i];
            range = Some(range.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
        }
        i = end;
    }
    let (from, to) = range?;
    Some(Flag::at(FlagNote::ConflictingRows, from, to, rows))
}

/// `gap` flags: within each mount, consecutive pieces (readings or bins) more than
/// [`gap_threshold_ns`] apart.
fn gap_flags(pieces: &[(Region, Piece)], median_interval_ns: f64) -> Vec<Flag> {
    let limit = gap_threshold_ns(median_interval_ns);
    let mut flags = Vec::new();
    for w in pieces.windows(2) {
        let (Region::Segment { mount: a, .. }, Region::Segment { mount: b, .. }) = (w[0].0, w[1].0)
        else {
            continue;
        };
        let (from, to) = (w[0].1.last_ns, w[1].1.first_ns);
        if a == b && to - from > limit {
            let note = FlagNote::Gap {
                gap_ns: to - from,
                threshold_ns: limit,
                median_interval_ns,
            };
            flags.push(Flag::at(note, from, to, 0));
        }
    }
    flags
}

// ------------------------------------------------------------------ encoder checks

/// One reading, or one bin, of a bar in time order.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Piece {
    first_ns: TimeNs,
    last_ns: TimeNs,
    n: u64,
    min: i64,
    max: i64,
    mean: f64,
}

impl Piece {
    /// One reading of `counts` at `t`.
    fn reading(t: TimeNs, counts: i64) -> Piece {
        Piece {
            first_ns: t,
            last_ns: t,
            n: 1,
            min: counts,
            max: counts,
            mean: counts as f64,
        }
    }
}

impl Segments {
    fn region(&self, t: TimeNs) -> Region {
        let after = self.mounts.partition_point(|m| m.0 <= t);
        match after.checked_sub(1).map(|i| self.mounts[i]) {
            Some((_, to, mount)) if t < to => Region::Segment {
                mount,
                rezeros: self.rezeros.partition_point(|&r| r <= t),
            },
            _ => Region::Outside,
        }
    }

    /// Time before the first mount's start or after the last mount's end, ns (0 inside).
    fn outside_by_ns(&self, t: TimeNs) -> TimeNs {
        let (Some(first), Some(last)) = (self.mounts.first(), self.mounts.last()) else {
            return 0;
        };
        let last_end = self.mounts.iter().map(|m| m.1).max().unwrap_or(last.1);
        first
            .0
            .saturating_sub(t)
            .max(t.saturating_sub(last_end))
            .max(0)
    }
}

/// The bar's air temperature logs (its sensor, else every air sensor).
fn air_logs<'a>(
    campaign: &Campaign,
    bar: &str,
    sensors: &'a BTreeMap<String, SensorLog>,
) -> Vec<&'a SensorLog> {
    let own = campaign
        .bars
        .iter()
        .find(|b| b.id == bar)
        .and_then(|b| b.sensor.clone());
    campaign
        .sensors
        .iter()
        .filter(|s| match &own {
            Some(id) => &s.id == id,
            None => s.kind == SensorKind::Air,
        })
        .filter_map(|s| sensors.get(&s.id))
        .collect()
}

/// How far the air moved within `[from, to]`, K (`None`: no reading there).
fn air_change_k(air: &[&SensorLog], from: TimeNs, to: TimeNs) -> Option<f64> {
    let mut change: Option<f64> = None;
    for log in air {
        let a = log.time_ns.partition_point(|&t| t < from);
        let b = log.time_ns.partition_point(|&t| t <= to);
        let window = &log.celsius[a..b];
        if window.is_empty() {
            continue;
        }
        let (lo, hi) = window
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &c| {
                (l.min(c), h.max(c))
            });
        change = Some(change.unwrap_or(0.0).max(hi - lo));
    }
    change
}

/// What the checks of one zero segment found: flags, and pieces to leave out.
#[derive(Default)]
struct Findings {
    flags: Vec<Flag>,
    /// Indices of the pieces of frozen runs.
    stuck: Vec<std::ops::Range<usize>>,
    wrapped: bool,
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

/// The upper median (the lower for an even count would do as well: it sets a threshold), in
/// linear time: a full-rate bar has millions of steps.
fn select_median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let m = v.len() / 2;
    *v.select_nth_unstable_by(m, f64::total_cmp).1
}

/// Jumps, wraps and frozen runs in one zero segment's pieces (time order).
fn check_segment(pieces: &[Piece], resolution_nm: f64, air: &[&SensorLog]) -> Findings {
    let mut found = Findings::default();
    let floor_counts = JUMP_FLOOR_UM * 1e3 / resolution_nm.max(1e-12);
    let steps: Vec<f64> = pieces.windows(2).map(|w| w[1].mean - w[0].mean).collect();
    let centre = median(steps.clone());
    let sigma = 1.4826 * median(steps.iter().map(|d| (d - centre).abs()).collect());
    let step_limit = (JUMP_NOISE_FACTOR * sigma).max(floor_counts);
    let spreads: Vec<f64> = pieces
        .iter()
        .filter(|p| p.n >= 2)
        .map(|p| p.max as f64 - p.min as f64)
        .collect();
    let spread_limit = (BIN_SPREAD_FACTOR * median(spreads)).max(floor_counts);
    for (i, p) in pieces.iter().enumerate() {
        let spread = p.max as f64 - p.min as f64;
        if p.n >= 2 && spread > spread_limit {
            let wrap = spread >= WRAP_MIN_JUMP_COUNTS as f64;
            found.wrapped |= wrap;
            found.flags.push(jump_flag(
                wrap,
                p.first_ns,
                p.last_ns,
                p.n,
                spread,
                resolution_nm,
                JumpPlace::InsideOneBin,
            ));
        }
        if i == 0 {
            continue;
        }
        let step = steps[i - 1];
        if step.abs() > step_limit {
            let wrap = step.abs() >= WRAP_MIN_JUMP_COUNTS as f64;
            found.wrapped |= wrap;
            let before = pieces[i - 1].last_ns;
            found.flags.push(jump_flag(
                wrap,
                before,
                p.first_ns,
                2,
                step,
                resolution_nm,
                JumpPlace::BetweenTwoReadings,
            ));
        }
    }
    stuck_runs(pieces, air, &mut found);
    found
}

fn jump_flag(
    wrap: bool,
    from: TimeNs,
    to: TimeNs,
    rows: u64,
    size: f64,
    resolution_nm: f64,
    place: JumpPlace,
) -> Flag {
    let note = if wrap {
        FlagNote::CounterWrap {
            place,
            size_counts: size,
        }
    } else {
        FlagNote::Jump { place }
    };
    Flag::at(note, from, to, rows).sized(size, resolution_nm)
}

/// Runs of constant pieces of one value, long enough and while the air moved.
fn stuck_runs(pieces: &[Piece], air: &[&SensorLog], found: &mut Findings) {
    let constant = |p: &Piece| p.min == p.max;
    let mut start = 0;
    while start < pieces.len() {
        if !constant(&pieces[start]) {
            start += 1;
            continue;
        }
        let value = pieces[start].min;
        let mut end = start + 1;
        while end < pieces.len() && constant(&pieces[end]) && pieces[end].min == value {
            end += 1;
        }
        let run = &pieces[start..end];
        let readings: u64 = run.iter().map(|p| p.n).sum();
        let (from, to) = (run[0].first_ns, run[run.len() - 1].last_ns);
        let long = (to - from) as f64 * 1e-9 >= STUCK_MIN_S;
        let moved = air_change_k(air, from, to).is_none_or(|k| k >= STUCK_MIN_AIR_CHANGE_K);
        if long && readings >= STUCK_MIN_READINGS && moved {
            let note = FlagNote::Stuck {
                counts: value,
                duration_ns: to - from,
            };
            found.flags.push(Flag::at(note, from, to, readings));
            found.stuck.push(start..end);
        }
        start = end;
    }
}

/// Pieces of each zero segment, and the readings far outside the bar's mounts.
fn far_outside_flag(segments: &Segments, pieces: &[(Region, Piece)]) -> Option<Flag> {
    let limit = (FAR_OUTSIDE_MOUNTS_S * 1e9) as TimeNs;
    let far: Vec<&Piece> = pieces
        .iter()
        .filter(|(r, p)| {
            *r == Region::Outside
                && (segments.outside_by_ns(p.first_ns) > limit
                    || segments.outside_by_ns(p.last_ns) > limit)
        })
        .map(|(_, p)| p)
        .collect();
    let rows: u64 = far.iter().map(|p| p.n).sum();
    let from = far.iter().map(|p| p.first_ns).min()?;
    let to = far.iter().map(|p| p.last_ns).max()?;
    Some(Flag::at(FlagNote::FarOutsideMounts, from, to, rows))
}

/// What to leave out of one bar after the checks: mounts (wrap) and time ranges (frozen runs).
struct LeaveOut {
    mounts: Vec<usize>,
    ranges: Vec<(TimeNs, TimeNs)>,
}

impl LeaveOut {
    fn drops(&self, region: Region, first_ns: TimeNs, last_ns: TimeNs) -> bool {
        let in_mount =
            matches!(region, Region::Segment { mount, .. } if self.mounts.contains(&mount));
        in_mount
            || self
                .ranges
                .iter()
                .any(|&(a, b)| first_ns >= a && last_ns <= b)
    }
}

/// Runs the checks on a bar's pieces; adds flags to `q` and says what to leave out.
fn check_pieces(
    pieces: &[(Region, Piece)],
    segments: &Segments,
    resolution_nm: f64,
    air: &[&SensorLog],
    q: &mut ChannelQuality,
) -> LeaveOut {
    let mut leave = LeaveOut {
        mounts: Vec::new(),
        ranges: Vec::new(),
    };
    let mut start = 0;
    while start < pieces.len() {
        let region = pieces[start].0;
        let end = start
            + pieces[start..]
                .iter()
                .position(|(r, _)| *r != region)
                .unwrap_or(pieces.len() - start);
        if let Region::Segment { mount, .. } = region {
            let segment: Vec<Piece> = pieces[start..end].iter().map(|(_, p)| *p).collect();
            let found = check_segment(&segment, resolution_nm, air);
            if found.wrapped && !leave.mounts.contains(&mount) {
                leave.mounts.push(mount);
            }
            for run in found.stuck {
                leave
                    .ranges
                    .push((segment[run.start].first_ns, segment[run.end - 1].last_ns));
            }
            q.flags.extend(found.flags);
        }
        start = end;
    }
    q.flags.extend(far_outside_flag(segments, pieces));
    leave
}

/// Why nothing usable is left of a bar whose mounted readings were all left out.
fn unusable_reason(q: &ChannelQuality) -> Unusable {
    let stuck = q.flags.iter().any(|f| f.kind() == FlagKind::Stuck);
    let wrap = q.flags.iter().any(|f| f.kind() == FlagKind::CounterWrap);
    match (stuck, wrap) {
        (true, false) => Unusable::EncoderDead,
        (false, true) => Unusable::EveryMountWrapped,
        _ => Unusable::FrozenOrWrapped,
    }
}

/// Checks a bar's sorted full-rate log: drops exact duplicates, flags jumps, wraps and frozen
/// runs, drops the readings of frozen runs and of mounts with a wrap.
pub fn check_log(
    campaign: &Campaign,
    events: &[Event],
    sensors: &BTreeMap<String, SensorLog>,
    bar: &str,
    log: &mut BarLog,
    q: &mut ChannelQuality,
) {
    let (dups, range) = dedup_sorted(&mut log.time_ns, &mut log.counts);
    record_duplicates(q, dups, range, LogTable::Encoders);
    q.flags
        .extend(conflicting_sorted(&log.time_ns, &log.counts));
    let segments = Segments::new(campaign, events, bar);
    let pieces: Vec<(Region, Piece)> = log
        .time_ns
        .iter()
        .zip(&log.counts)
        .map(|(&t, &c)| {
            let piece = Piece::reading(t, c);
            (segments.region(t), piece)
        })
        .collect();
    let steps: Vec<f64> = log
        .time_ns
        .windows(2)
        .map(|w| (w[1] - w[0]) as f64)
        .filter(|&d| d > 0.0)
        .collect();
    q.flags.extend(gap_flags(&pieces, select_median(steps)));
    let air = air_logs(campaign, bar, sensors);
    let leave = check_pieces(&pieces, &segments, resolution(campaign, bar), &air, q);
    let mounted_before = pieces.iter().filter(|(r, _)| *r != Region::Outside).count();
    let before = log.time_ns.len();
    let mut k = 0;
    for (i, (r, p)) in pieces.iter().enumerate() {
        if !leave.drops(*r, p.first_ns, p.last_ns) {
            log.time_ns[k] = log.time_ns[i];
            log.counts[k] = log.counts[i];
            k += 1;
        }
    }
    log.time_ns.truncate(k);
    log.counts.truncate(k);
    let mounted_after = log
        .time_ns
        .iter()
        .filter(|&&t| segments.region(t) != Region::Outside)
        .count();
    finish(
        q,
        (before - k) as u64,
        mounted_before > 0 && mounted_after == 0,
    );
}

/// [`check_log`] for a bar compressed into bins while it streamed: each bin is a piece; bins
/// of frozen runs and of mounts with a wrap are dropped.
pub fn check_bins(
    campaign: &Campaign,
    events: &[Event],
    sensors: &BTreeMap<String, SensorLog>,
    bar: &str,
    bins: &mut BarBins,
    q: &mut ChannelQuality,
) {
    let segments = Segments::new(campaign, events, bar);
    let pieces: Vec<(Region, Piece)> = bins
        .bins
        .iter()
        .map(|(key, m)| {
            let piece = Piece {
                first_ns: key.start_ns + m.first_us * 1_000,
                last_ns: key.start_ns + m.last_us * 1_000,
                n: m.n,
                min: m.min_counts,
                max: m.max_counts,
                mean: m.sc as f64 / m.n.max(1) as f64,
            };
            (key.region, piece)
        })
        .collect();
    // The median interval between readings from the bins: (last − first) / (n − 1) of each
    // bin of two readings or more.
    // bin of two readings or more; with no such bin (a reading a bin or less), the steps
    // between bins.
    let mut intervals: Vec<f64> = pieces
        .iter()
        .filter(|(_, p)| p.n >= 2 && p.last_ns > p.first_ns)
        .map(|(_, p)| (p.last_ns - p.first_ns) as f64 / (p.n - 1) as f64)
        .collect();
    if intervals.is_empty() {
        intervals = pieces
            .windows(2)
            .map(|w| (w[1].1.first_ns - w[0].1.last_ns) as f64)
            .filter(|&d| d > 0.0)
            .collect();
    }
    q.flags.extend(gap_flags(&pieces, select_median(intervals)));
    let air = air_logs(campaign, bar, sensors);
    let leave = check_pieces(&pieces, &segments, resolution(campaign, bar), &air, q);
    let mounted_before = pieces.iter().any(|(r, _)| *r != Region::Outside);
    let before: u64 = bins.n_readings();
    let mut index = 0;
    bins.bins.retain(|_| {
        let (r, p) = pieces[index];
        index += 1;
        !leave.drops(r, p.first_ns, p.last_ns)
    });
    let mounted_after = bins.bins.iter().any(|(k, _)| k.region != Region::Outside);
    finish(
        q,
        before - bins.n_readings(),
        mounted_before && !mounted_after,
    );
}

fn resolution(campaign: &Campaign, bar: &str) -> f64 {
    campaign
        .bars
        .iter()
        .find(|b| b.id == bar)
        .map_or(1.0, |b| b.resolution_nm)
}

fn finish(q: &mut ChannelQuality, left_out: u64, nothing_left: bool) {
    q.fault_rows += left_out;
    q.dropped_rows += left_out;
    if nothing_left {
        q.unusable = Some(unusable_reason(q));
    }
}

#[cfg(test)]
#[path = "quality_tests.rs"]
mod tests;
