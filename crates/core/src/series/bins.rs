//! Exact compression of a bar's encoder log into bins of two weighted nodes.
//!
//! A 1 Hz log over 30 days is 2.6 M readings per bar, while the thermal model varies on time
//! constants of 15 min to 2 h (`docs/spec/physics.md`): within a bin of a minute every regressor is a
//! straight line to `O((bin/tau)²)`. For a model that is a straight line within each bin, the
//! least-squares fit to the readings depends on them only through each bin's moments
//! `Σ 1, Σ u, Σ u², Σ u³` (`u`: time in the bin) and `Σ c, Σ u c, Σ c²` (`c`: counts), and these
//! are kept exactly:
//!
//! * each bin becomes two **nodes**, the two-point Gauss quadrature of the empirical measure of
//!   its sample times (exact for polynomials of degree 3, so for every product of two lines),
//!   with weights `w₁ + w₂ = n`;
//! * each node carries the value of the bin's own least-squares line `ĉ(u)` there. Then
//!   `Σ_i (c_i − f(u_i))² = Σ_k w_k (ĉ(s_k) − f(s_k))² + RSS_line` for every line `f`, where
//!   `RSS_line` is the scatter about the bin's line: a weighted fit to the nodes, plus that
//!   constant, is the fit to the readings (same estimates, RSS, likelihood and BIC);
//! * the two node values are uncorrelated with variances `σ²/w_k` under white noise, so the
//!   weighted fit is also the right one statistically, not only algebraically.
//!
//! The sums are integers (`i128`, time in µs from the bin start), so they do not depend on the
//! order rows arrive in: ingest accumulates them while it streams the encoder files
//! ([`BinAccumulator`]), in any order, and the full-rate log never exists; a log already in
//! memory goes through the same accumulator ([`BarBins::from_log`]) with the same result.
//!
//! Bins are cut on a grid anchored at each region's start, never crossing a region: a zero
//! segment (a mount, split again at `rezero` events), or the handling time between mounts.
//!
//! # How it works
//!
//! - `[model] bin_s` / `--bin-s` compresses each bar's readings into bins (`series::bins`): per bin
//!   the integer sums `Σ1, Σu, Σu², Σu³, Σc, Σuc, Σc²` (u: µs in the bin, c: counts) become two
//!   nodes, the Gauss quadrature of the bin's sample times, each carrying the bin's least-squares
//!   line. For a model that is a straight line within each bin, the weighted fit to the nodes plus
//!   the scatter about the lines (`BarSeries::within_bin_rss_um2`, `Separable::unexplained_rss`)
//!   *is* the fit to the readings: same estimates, RSS, likelihood, BIC, sample count. Lags are
//!   computed on the nodes plus weight-0 samples at the sensors' reading times, the first reading
//!   and the edges of gaps, so they equal the full-rate lags (`BarBins::readings`). At full rate and
//!   with bins, every sensor reading between two samples of a bar is a weight-0 sample too
//!   (`series::with_knots_between`): a gap in the log (a head off for hours) is bridged by the air
//!   the sensors logged, not by a straight line. Measured on a
//!   1 Hz campaign: estimates equal the full-rate fit's to 0.002 u for 2-60 s bins
//!   (`tests/e2e/identify.rs`). Bins never cross a zero segment or the handling time between
//!   mounts; their grid is anchored at each region's start. Nor do they straddle an event (the
//!   bar's own or a setup-wide one: a `head_power` switch, a door, a tilt change): inside a zero
//!   segment the bins restart at each event time (`series::bins::bin_edges`, at most 1 024 a bar),
//!   because an event-driven term has a kink there that no straight line within a bin holds
//!   (a 1 Hz head-heating log whose readings go on while the head is off: 0.04-0.09 u from the
//!   full-rate fit with straddling bins, within 0.009 u without;
//!   `tests/e2e/head_heating.rs::sixty_second_bins_give_the_full_rate_head_estimates`).
//! - Ingest accumulates the bins while the encoder files stream (`io::read_campaign_binned`): the
//!   sums are integers, so row order and batch boundaries change no bit, and the full-rate log never
//!   exists. Without streaming (`BarSeries::build_binned` on a log in memory) the same accumulator
//!   gives the same bits.
//! - Bins have fixed places (`series::BinAccumulator`): the bar's time line is cut into spans no bin
//!   crosses (zero segments, handling time, the stretches between events), each span's bins
//!   numbered from its anchor and kept in
//!   pages of 64 (a dense page table, a map past 65 536 pages), so a reading adds to its bin's
//!   integer moments wherever it comes from, and memory grows with the bins, not the rows. Rows in
//!   time order go run by run (a tight loop per bin, `BinMoments::add_run`, the sums in
//!   registers); rows out of order (`BinAccumulator::add_by_bin`) are split by span (a day file
//!   crosses a mount's end), then sorted by bin (counting sorts, `BlockScratch::sort_by_block`) and
//!   summed run by run as well; rows a sort would not pay for (fewer than two a bin, over more than
//!   64 spans, or before the first mount) are grouped by 64-bin time blocks (so a page is hot
//!   while they are added) and added one at a time, the bin found by arithmetic in the previous
//!   row's span (division by multiplication).
//! - No bin length set (`[model] bin_s`, `--bin-s` absent): `io::automatic_bin_s` decides before
//!   the encoder files stream, from `campaign.toml` and the files' parquet footers (row counts):
//!   `AUTOMATIC_BIN_S` (60 s) bins when the bars' mean interval between readings (each bar's first
//!   mount start to last mount end, shared by the rows) is `AUTOMATIC_MAX_INTERVAL_S` (6 s) or
//!   less, else every reading (`series::bins`, `series::automatic_bin_s`; the measurements behind the numbers: `bench/README.md`). The same for any row order or file split.

use crate::campaign::{Campaign, TimeNs};
use crate::series::Event;

/// Longest bin accepted: a bin of more than an hour is not a straight line for the time
/// constants of `docs/spec/physics.md` (15 min and more), and it bounds the integer sums.
pub const MAX_BIN_S: f64 = 3600.0;

const NS_PER_US: i64 = 1_000;

/// Earliest reading time accepted anywhere (1980-01-01T00:00:00Z, ns): no logger of this kind
/// predates it, and a time before it is a clock reset (1970) or a NaT (`i64::MIN`), refused at
/// ingest (`docs/guarantees.md`).
pub const EARLIEST_READING_NS: TimeNs = 315_532_800_000_000_000;
/// First reading time no longer accepted (2200-01-01T00:00:00Z, ns): a time past it is a broken
/// clock or a unit mix-up. The bounds keep every sum of times and bin numbers far from `i64`'s
/// ends, so no arithmetic on an accepted time can wrap.
pub const LATEST_READING_NS: TimeNs = 7_258_118_400_000_000_000;
/// Largest accepted |counts| (2⁴⁸, 1.4 km at 5 nm a count): with at most
/// [`MAX_BAR_READINGS`] readings in a bin, `Σ c²` stays below 2¹²⁷ (`i128`).
pub const MAX_ABS_COUNTS: i64 = 1 << 48;
/// Most readings one bar's accumulator takes (2³¹): bounds every bin's sums (`Σ u³ < 2¹²⁷`).
pub const MAX_BAR_READINGS: u64 = 1 << 31;

/// Why readings cannot be added to a bar's bins: a value outside what the integer sums hold
/// exactly. Ingest refuses such rows before they get here; the accumulator checks again so
/// that no caller can make it wrap, panic or loop.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BinError {
    /// A reading time outside 1980-01-01 .. 2200-01-01.
    #[error("reading time {time_ns} ns is outside 1980-01-01 .. 2200-01-01")]
    TimeOutOfRange {
        /// The time, ns since the epoch.
        time_ns: TimeNs,
    },
    /// Counts beyond ±2^48.
    #[error("counts {counts} exceed ±2^48")]
    CountsOutOfRange {
        /// The counts.
        counts: i64,
    },
    /// More than 2^31 readings for one bar.
    #[error("more than 2^31 readings for one bar")]
    TooManyReadings,
    /// Two accumulators merged that were not made on the same grid.
    #[error("bins of different grids cannot be merged")]
    OtherGrid,
    /// A reading removed from a bin that holds none.
    #[error("reading at {time_ns} ns removed from a bin that holds no reading")]
    NotAdded {
        /// Its time, ns since the epoch.
        time_ns: TimeNs,
    },
}

/// Whether `t` is an accepted reading time ([`EARLIEST_READING_NS`] ..
/// [`LATEST_READING_NS`]).
#[inline]
pub fn reading_time_ok(t: TimeNs) -> bool {
    (EARLIEST_READING_NS..LATEST_READING_NS).contains(&t)
}

/// Whether every time is an accepted reading time ([`reading_time_ok`]). One pass without an
/// early exit, for the clean case of a whole batch: a loop that stops at the first bad row
/// cannot be unrolled, and this check runs on every row ingest reads.
#[inline]
pub fn reading_times_ok(time_ns: &[TimeNs]) -> bool {
    let width = (LATEST_READING_NS - EARLIEST_READING_NS) as u64;
    !time_ns.iter().fold(false, |bad, &t| {
        bad | (t.wrapping_sub(EARLIEST_READING_NS) as u64 >= width)
    })
}

/// Whether every |counts| is at most [`MAX_ABS_COUNTS`], in one pass without an early exit
/// (as [`reading_times_ok`]).
#[inline]
pub fn counts_ok(counts: &[i64]) -> bool {
    counts.iter().fold(0, |m: u64, c| m.max(c.unsigned_abs())) <= MAX_ABS_COUNTS as u64
}

/// The bin length chosen when none is set, s: a straight line within a minute is the thermal
/// model to `O((60 s / tau)²)`, tau being 15 min or more for the bars (`docs/spec/physics.md`); measured
/// on a 1 Hz campaign, 2-60 s bins give the full-rate estimates to 0.002 u
/// (`tests/e2e/identify.rs`).
pub const AUTOMATIC_BIN_S: f64 = 60.0;

/// Longest mean interval between a bar's readings that is compressed automatically, s: a bin of
/// [`AUTOMATIC_BIN_S`] then holds 10 readings or more, and two nodes (plus the sensors' reading
/// times, weight 0) stand for them. Slower logs gain little and keep every reading.
pub const AUTOMATIC_MAX_INTERVAL_S: f64 = 6.0;

/// A fitted time constant should span at least this many bins: the compression's straight line
/// within a bin is then off by at most (1 / 10)² = 1 % of the term's curvature. With no bin
/// length set, a run whose fit finds a shorter one reads the campaign again with shorter bins.
pub const MIN_BINS_PER_TAU: f64 = 10.0;

/// The bin length for a campaign of `encoder_rows` readings when none is set (`[model] bin_s`
/// and `--bin-s` absent): [`AUTOMATIC_BIN_S`] when the bars' mean interval between readings is
/// at most [`AUTOMATIC_MAX_INTERVAL_S`], else 0 (every reading). The interval is the bars'
/// mounted time spans (each bar's first mount start to its last mount end, handling between
/// them included) shared by the rows: known from `campaign.toml` and the parquet footers before
/// any row is read, and the same for any row order or file layout. A bar that logged only part
/// of its span makes the interval look longer (no compression), never shorter; rows logged
/// outside the spans make it look shorter.
pub fn automatic_bin_s(campaign: &Campaign, encoder_rows: u64) -> f64 {
    let mut spans: std::collections::BTreeMap<&str, (TimeNs, TimeNs)> = Default::default();
    for m in &campaign.mounts {
        let span = spans.entry(m.bar.as_str()).or_insert((m.from_ns, m.to_ns));
        *span = (span.0.min(m.from_ns), span.1.max(m.to_ns));
    }
    let span_s: f64 = spans.values().map(|(a, b)| (b - a) as f64 * 1e-9).sum();
    if encoder_rows == 0 || span_s.is_nan() || span_s <= 0.0 {
        return 0.0;
    }
    if span_s / encoder_rows as f64 <= AUTOMATIC_MAX_INTERVAL_S {
        AUTOMATIC_BIN_S
    } else {
        0.0
    }
}

/// Integer moments of one bin's readings: sums over its samples of powers of `u` (µs since the
/// bin's start) and of the counts `c`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BinMoments {
    pub(crate) n: u64,
    /// First and last reading, µs since the bin's start.
    pub(crate) first_us: i64,
    pub(crate) last_us: i64,
    /// Smallest and largest counts of the bin: a jump or a counter wrap inside a bin shows as
    /// a spread far beyond the noise (`series::quality`).
    pub(crate) min_counts: i64,
    pub(crate) max_counts: i64,
    pub(crate) su: i128,
    pub(crate) suu: i128,
    pub(crate) suuu: i128,
    pub(crate) sc: i128,
    pub(crate) suc: i128,
    pub(crate) scc: i128,
}

/// The products one reading adds to its bin's sums: `u²`, `u³`, `u·c`, `c²` (`u` µs since the
/// bin's start, `c` counts).
struct Products {
    uu: i128,
    uuu: i128,
    uc: i128,
    cc: i128,
}

impl Products {
    /// Every accepted reading has `0 <= u < 2³²` (a bin is at most an hour, 3.6e9 µs) and
    /// `|c| <= 2⁴⁸` ([`MAX_ABS_COUNTS`]), so `u² < 2⁶⁴`, `u³ < 2⁹⁶`, `|u·c| < 2⁸¹`, `c² <= 2⁹⁶`:
    /// no product can wrap, and each is one 64×64→128 multiplication. Spelled `wrapping_mul`
    /// so that the overflow checks our crates build with are not paid on products that cannot
    /// overflow (ingest computes them for every reading; the change measured no difference in
    /// ingest's time, within this VM's noise); the bounds are checked where readings enter
    /// ([`BinAccumulator::add_all`]) and again here in debug builds.
    #[inline]
    fn of(u: i64, c: i64) -> Self {
        debug_assert!((0..1 << 32).contains(&u) && c.unsigned_abs() <= MAX_ABS_COUNTS as u64);
        let uu = (u as u64 as u128).wrapping_mul(u as u64 as u128);
        Products {
            uu: uu as i128,
            uuu: (uu as i128).wrapping_mul(u as i128),
            uc: (u as i128).wrapping_mul(c as i128),
            cc: (c as i128).wrapping_mul(c as i128),
        }
    }
}

/// One node of a compressed bin: a weighted pseudo-reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    /// Time since the bin's start, µs.
    pub(crate) offset_us: f64,
    /// Number of readings the node stands for (the two weights of a bin sum to its `n`).
    pub(crate) weight: f64,
    /// The bin's least-squares line at the node, counts.
    pub(crate) counts: f64,
}

impl BinMoments {
    /// Add readings of this bin (times in ns, the bin starting at `start_ns`).
    pub(crate) fn add_run(&mut self, start_ns: TimeNs, time_ns: &[TimeNs], counts: &[i64]) {
        let mut run = BinMoments::default();
        let (mut first, mut last) = (i64::MAX, i64::MIN);
        let (mut low, mut high) = (i64::MAX, i64::MIN);
        for (&t, &c) in time_ns.iter().zip(counts) {
            let u = (t - start_ns) / NS_PER_US;
            first = first.min(u);
            last = last.max(u);
            low = low.min(c);
            high = high.max(c);
            let p = Products::of(u, c);
            run.su += u as i128;
            run.suu += p.uu;
            run.suuu += p.uuu;
            run.sc += c as i128;
            run.suc += p.uc;
            run.scc += p.cc;
        }
        run.n = time_ns.len().min(counts.len()) as u64;
        (run.first_us, run.last_us) = (first, last);
        (run.min_counts, run.max_counts) = (low, high);
        self.merge(&run);
    }

    /// Add one reading of this bin: [`BinMoments::add_run`] of one row, without a second sum
    /// to merge.
    #[inline]
    pub(crate) fn add_one(&mut self, start_ns: TimeNs, t: TimeNs, c: i64) {
        let u = (t - start_ns) / NS_PER_US;
        if self.n == 0 {
            (self.first_us, self.last_us) = (u, u);
            (self.min_counts, self.max_counts) = (c, c);
        } else {
            self.first_us = self.first_us.min(u);
            self.last_us = self.last_us.max(u);
            self.min_counts = self.min_counts.min(c);
            self.max_counts = self.max_counts.max(c);
        }
        let p = Products::of(u, c);
        self.n += 1;
        self.su += u as i128;
        self.suu += p.uu;
        self.suuu += p.uuu;
        self.sc += c as i128;
        self.suc += p.uc;
        self.scc += p.cc;
    }

    /// Take back one reading added with [`BinMoments::add_one`] or [`BinMoments::add_run`]:
    /// the sums are integers, so this is exact. The first/last time and the smallest/largest
    /// counts cannot be taken back in general; they stay as they were, which is exact when the
    /// reading removed is a copy of one that stays (a duplicate row), and a bin left empty
    /// becomes the empty bin. Returns `false` (and changes nothing) on an empty bin.
    #[inline]
    pub(crate) fn remove_one(&mut self, start_ns: TimeNs, t: TimeNs, c: i64) -> bool {
        if self.n == 0 {
            return false;
        }
        if self.n == 1 {
            *self = BinMoments::default();
            return true;
        }
        let u = (t - start_ns) / NS_PER_US;
        let p = Products::of(u, c);
        self.n -= 1;
        self.su -= u as i128;
        self.suu -= p.uu;
        self.suuu -= p.uuu;
        self.sc -= c as i128;
        self.suc -= p.uc;
        self.scc -= p.cc;
        true
    }

    /// Sums of two parts of one bin.
    pub(crate) fn merge(&mut self, other: &BinMoments) {
        if other.n == 0 {
            return;
        }
        if self.n == 0 {
            (self.first_us, self.last_us) = (other.first_us, other.last_us);
            (self.min_counts, self.max_counts) = (other.min_counts, other.max_counts);
        }
        self.first_us = self.first_us.min(other.first_us);
        self.last_us = self.last_us.max(other.last_us);
        self.min_counts = self.min_counts.min(other.min_counts);
        self.max_counts = self.max_counts.max(other.max_counts);
        self.n += other.n;
        self.su += other.su;
        self.suu += other.suu;
        self.suuu += other.suuu;
        self.sc += other.sc;
        self.suc += other.suc;
        self.scc += other.scc;
    }

    /// The bin's nodes (two; one when its readings share one time) and the scatter of its counts
    /// about its least-squares line, counts².
    pub(crate) fn nodes(&self) -> (Vec<Node>, f64) {
        if self.n == 0 {
            return (Vec::new(), 0.0);
        }
        let n = self.n as i128;
        // n² × centred second moments, exact.
        let nuu = n * self.suu - self.su * self.su;
        let nuc = n * self.suc - self.su * self.sc;
        let ncc = n * self.scc - self.sc * self.sc;
        let nf = self.n as f64;
        let mean_u = self.su as f64 / nf;
        let mean_c = self.sc as f64 / nf;
        if nuu <= 0 {
            let node = Node {
                offset_us: mean_u,
                weight: nf,
                counts: mean_c,
            };
            return (vec![node], (ncc as f64 / nf).max(0.0));
        }
        let slope = nuc as f64 / nuu as f64;
        let line_rss = ((ncc as f64 - (nuc as f64) * slope) / nf).max(0.0);
        // Centred moments of the sample times; x = u - mean_u.
        let m2 = nuu as f64 / (nf * nf);
        let m3 = (self.suuu as f64 - 3.0 * mean_u * self.suu as f64) / nf
            + 2.0 * mean_u * mean_u * mean_u;
        // Nodes: roots of the degree-2 orthogonal polynomial x² - (m3/m2) x - m2.
        let a = m3 / m2;
        let root = (a * a + 4.0 * m2).sqrt();
        let (x1, x2) = ((a - root) / 2.0, (a + root) / 2.0);
        let (w1, w2) = (nf * x2 / (x2 - x1), -nf * x1 / (x2 - x1));
        let node = |x: f64, w: f64| Node {
            offset_us: mean_u + x,
            weight: w,
            counts: mean_c + slope * x,
        };
        (vec![node(x1, w1), node(x2, w2)], line_rss)
    }
}

/// The region a reading falls in, which no bin crosses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Region {
    /// Inside the bar's mount (index into `Campaign::mounts`), after this many `rezero` events.
    Segment {
        /// Index into `Campaign::mounts`.
        mount: usize,
        /// `rezero` events since the mount began.
        rezeros: usize,
    },
    /// Handling time (outside every mount).
    Outside,
}

/// Key of one bin: its start (ns) and region. Bins sort in time order by key: regions follow
/// one another in time and each region's bins start at or after the region's start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct BinKey {
    pub(crate) start_ns: TimeNs,
    pub(crate) region: Region,
}

/// Where a bar's readings fall: its mounts and the `rezero` events that apply to it (the bins'
/// grid and the quality checks read them alike).
#[derive(Debug, Clone)]
pub(crate) struct Segments {
    /// `(from_ns, to_ns, index into Campaign::mounts)`, sorted by start (mounts of one bar do
    /// not overlap).
    pub(crate) mounts: Vec<(TimeNs, TimeNs, usize)>,
    /// Times of the `rezero` events that apply to the bar, sorted.
    pub(crate) rezeros: Vec<TimeNs>,
    /// Times of the bar's other events and the setup-wide ones, sorted and distinct, where
    /// bins restart ([`bin_edges`]).
    pub(crate) edges: Vec<TimeNs>,
}

/// Most event times one bar's bins restart at ([`bin_edges`]): thirty a day over a month. A
/// bar with more (a channel logged as events) keeps whole bins across its events.
pub(crate) const MAX_BIN_EDGES: usize = 1024;

/// The times no bin of `bar` may straddle besides its mounts and rezeros: its own events and
/// the setup-wide ones (a `head_power` switch, a door, a tilt change). An event-driven term
/// (the head's lag of its power, a lag of an event channel) has a kink at its event; over a bin
/// that straddles one it is not the straight line the compression is exact for. Measured
/// (a 1 Hz, 2-day head-heating campaign of `bench/foreign_check.py`, seed 10, 60-s bins): with
/// bins straddling the switches the estimates moved by up to 0.094 u from the full-rate fit
/// (`head_growth_um`) and the HAC u of `tau_head_s` shrank by 35 % (tau 663 s at 3.3 u from the
/// truth); with these edges every estimate is within 0.003 u of the full-rate fit, that u 13 %
/// below the full rate's.
fn bin_edges(events: &[Event], bar: &str) -> Vec<TimeNs> {
    let mut edges: Vec<TimeNs> = events
        .iter()
        .filter(|e| {
            e.kind != crate::series::EventKind::Rezero && e.bar.as_deref().is_none_or(|b| b == bar)
        })
        .map(|e| e.time_ns)
        .collect();
    edges.sort_unstable();
    edges.dedup();
    if edges.len() > MAX_BIN_EDGES {
        edges.clear();
    }
    edges
}

impl Segments {
    /// The mounts, `rezero` events and bin edges ([`bin_edges`]) of bar `bar`.
    pub(crate) fn new(campaign: &Campaign, events: &[Event], bar: &str) -> Segments {
        let mut mounts: Vec<(TimeNs, TimeNs, usize)> = campaign
            .mounts
            .iter()
            .enumerate()
            .filter(|(_, m)| m.bar == bar)
            .map(|(i, m)| (m.from_ns, m.to_ns, i))
            .collect();
        mounts.sort();
        let mut rezeros: Vec<TimeNs> = events
            .iter()
            .filter(|e| {
                e.kind == crate::series::EventKind::Rezero
                    && e.bar.as_deref().is_none_or(|b| b == bar)
            })
            .map(|e| e.time_ns)
            .collect();
        rezeros.sort();
        Segments {
            mounts,
            rezeros,
            edges: bin_edges(events, bar),
        }
    }
}

/// Where one bar's bins lie: its mounts and `rezero` events (`Segments`), and the bin length.
#[derive(Debug, Clone)]
pub struct BinGrid {
    bin_ns: TimeNs,
    /// `(from_ns, to_ns, index into Campaign::mounts)`, sorted by start (mounts of one bar do
    /// not overlap).
    mounts: Vec<(TimeNs, TimeNs, usize)>,
    /// Times of the `rezero` events that apply to the bar, sorted.
    rezeros: Vec<TimeNs>,
    /// Event times inside zero segments where bins restart ([`bin_edges`]), sorted.
    edges: Vec<TimeNs>,
}

impl BinGrid {
    /// The grid of bar `bar_id` for bins of `bin_s` seconds (at most [`MAX_BIN_S`]).
    pub fn new(campaign: &Campaign, events: &[Event], bar_id: &str, bin_s: f64) -> BinGrid {
        let bin_s = bin_s.clamp(1e-6, MAX_BIN_S);
        let Segments {
            mounts,
            rezeros,
            edges,
        } = Segments::new(campaign, events, bar_id);
        BinGrid {
            bin_ns: ((bin_s * 1e9).round() as TimeNs).max(NS_PER_US),
            mounts,
            rezeros,
            edges,
        }
    }

    /// The bar's time line cut into the stretches no bin crosses, in time order: handling time
    /// before, between and after the mounts, and each mount's zero segments (split at `rezero`
    /// events), each with the anchor of its bins ([`BinGrid::locate`] of any time in a span
    /// gives that span's region and grid). Inside a zero segment the bins also restart at each
    /// of the bar's other events ([`bin_edges`]): the same region, a new anchor.
    fn spans(&self) -> Vec<Span> {
        let bin_ns = self.bin_ns;
        let edges = &self.edges;
        let segment = |spans: &mut Vec<Span>, from: TimeNs, to: TimeNs, region: Region| {
            let mut start = from;
            let first = edges.partition_point(|&e| e <= from);
            for &e in edges[first..].iter().take_while(|&&e| e < to) {
                spans.push(Span::new(start, e, start, region, bin_ns));
                start = e;
            }
            spans.push(Span::new(start, to, start, region, bin_ns));
        };
        let outside = |from: TimeNs, to: TimeNs| {
            // Before the first mount the bins lie on the epoch's grid.
            let anchor = if from == TimeNs::MIN { 0 } else { from };
            Span::new(from, to, anchor, Region::Outside, bin_ns)
        };
        let mut spans = Vec::new();
        let mut cursor = TimeNs::MIN;
        for &(from, to, mount) in &self.mounts {
            if from > cursor {
                spans.push(outside(cursor, from));
            }
            let mut start = from;
            let mut rezeros = self.rezeros.partition_point(|&r| r <= from);
            while let Some(&r) = self.rezeros.get(rezeros).filter(|&&r| r < to) {
                segment(&mut spans, start, r, Region::Segment { mount, rezeros });
                start = r;
                rezeros = self.rezeros.partition_point(|&q| q <= r);
            }
            segment(&mut spans, start, to, Region::Segment { mount, rezeros });
            cursor = to;
        }
        spans.push(outside(cursor, TimeNs::MAX));
        spans.retain(|s| s.from < s.to);
        spans
    }

    /// The bin holding a reading at `t`: its key and the end (exclusive, ns) of the time it
    /// covers. The reference [`BinAccumulator`] is tested against.
    #[cfg(test)]
    fn locate(&self, t: TimeNs) -> (BinKey, TimeNs) {
        let after = self.mounts.partition_point(|m| m.0 <= t);
        let inside = after
            .checked_sub(1)
            .map(|i| self.mounts[i])
            .filter(|m| t < m.1);
        let (region, anchor, region_end) = match inside {
            Some((from, to, mount)) => {
                let rezeros = self.rezeros.partition_point(|&r| r <= t);
                let edges = self.edges.partition_point(|&e| e <= t);
                let anchor = rezeros
                    .checked_sub(1)
                    .map_or(from, |k| self.rezeros[k].max(from));
                let anchor = edges
                    .checked_sub(1)
                    .map_or(anchor, |k| self.edges[k].max(anchor));
                let end = self.rezeros.get(rezeros).map_or(to, |&r| r.min(to));
                let end = self.edges.get(edges).map_or(end, |&e| e.min(end));
                (Region::Segment { mount, rezeros }, anchor, end)
            }
            None => {
                // Handling time: after the previous mount's end, before the next mount's start.
                let anchor = after
                    .checked_sub(1)
                    .map_or(TimeNs::MIN, |i| self.mounts[i].1);
                let end = self.mounts.get(after).map_or(TimeNs::MAX, |m| m.0);
                (Region::Outside, anchor, end)
            }
        };
        let start = if anchor == TimeNs::MIN {
            t.div_euclid(self.bin_ns) * self.bin_ns
        } else {
            anchor + (t - anchor).div_euclid(self.bin_ns) * self.bin_ns
        };
        let end = start.saturating_add(self.bin_ns).min(region_end);
        (
            BinKey {
                start_ns: start,
                region,
            },
            end,
        )
    }
}

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
struct Span {
    /// `[from, to)`; `TimeNs::MIN` / `TimeNs::MAX` for the handling time before the first and
    /// after the last mount.
    from: TimeNs,
    to: TimeNs,
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
    /// [`BinAccumulator::add_span_by_bin`].
    scratch: BlockScratch,
    /// Reused buffers of [`BinAccumulator::add_by_bin`]'s split by span.
    span_split: BlockScratch,
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

/// Rows at least this many out of time order are grouped by time block before they are added.
const MIN_BLOCK_SORT_ROWS: usize = 256;
/// Most time blocks of one grouping.
const MAX_SORT_BLOCKS: u64 = 1 << 16;
/// Most spans (zero segments and handling times) rows out of order are split over before they
/// are sorted by bin: a batch of a day file crosses a few; more go by blocks.
const MAX_SPLIT_SPANS: usize = 64;

/// The first and last of `time_ns` (one pass); `None` when empty.
fn time_range(time_ns: &[TimeNs]) -> Option<(TimeNs, TimeNs)> {
    let (&head, rest) = time_ns.split_first()?;
    Some(
        rest.iter()
            .fold((head, head), |(a, b), &t| (a.min(t), b.max(t))),
    )
}

/// Reused buffers of a counting sort of rows by a small key (time block, bin or span).
#[derive(Debug, Clone, Default)]
struct BlockScratch {
    /// Each row's key.
    block: Vec<u32>,
    /// `start[g]..start[g + 1]`: the sorted rows of key `g`.
    start: Vec<usize>,
    next: Vec<usize>,
    time: Vec<TimeNs>,
    counts: Vec<i64>,
}

impl BlockScratch {
    /// Stable counting sort of the rows `time_ns`/`counts` by their keys in `block` (each below
    /// `groups`) into `time`/`counts`.
    fn sort_by_block(&mut self, groups: usize, time_ns: &[TimeNs], counts: &[i64]) {
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
            start[b as usize + 1] += 1;
        }
        for g in 0..groups {
            start[g + 1] += start[g];
        }
        next.clear();
        next.extend_from_slice(&start[..groups]);
        time.resize(block.len(), 0);
        sorted_counts.resize(block.len(), 0);
        for ((&b, &t), &c) in block.iter().zip(time_ns).zip(counts) {
            let at = &mut next[b as usize];
            time[*at] = t;
            sorted_counts[*at] = c;
            *at += 1;
        }
    }
}

/// Exact unsigned division by a fixed divisor with a multiplication: `m = ⌊(2⁶⁴ − 1) / d⌋`
/// gives `⌊n m / 2⁶⁴⌋` at most 2 below `⌊n / d⌋`, corrected by comparing the remainder with `d`
/// (a 64-bit `div` takes several times longer, once per shuffled row).
#[derive(Debug, Clone, Copy)]
struct Divide {
    d: u64,
    m: u64,
}

impl Divide {
    fn new(d: u64) -> Divide {
        let d = d.max(1);
        Divide { d, m: u64::MAX / d }
    }

    #[inline]
    fn quotient(&self, n: u64) -> u64 {
        let mut q = ((n as u128 * self.m as u128) >> 64) as u64;
        let mut r = n - q * self.d;
        while r >= self.d {
            q += 1;
            r -= self.d;
        }
        q
    }
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
            span_split: BlockScratch::default(),
            readings: 0,
        }
    }

    /// Add readings given as two columns, in any order (ingest streams tens of millions of rows
    /// through here). Rows in time order go run by run, each run of one bin in a tight loop;
    /// rows out of order are first grouped by time block (`BinAccumulator::add_by_block`).
    ///
    /// Every row is checked first (times within [`EARLIEST_READING_NS`] ..
    /// [`LATEST_READING_NS`], |counts| ≤ [`MAX_ABS_COUNTS`], at most [`MAX_BAR_READINGS`] in
    /// all): out of those bounds the bin arithmetic could wrap, so nothing of the call is added
    /// and the first offending value is returned.
    pub fn add_all(&mut self, time_ns: &[TimeNs], counts: &[i64]) -> Result<(), BinError> {
        let n = time_ns.len().min(counts.len());
        let (time_ns, counts) = (&time_ns[..n], &counts[..n]);
        check_readings(time_ns, counts)?;
        self.readings = self
            .readings
            .checked_add(n as u64)
            .filter(|&r| r <= MAX_BAR_READINGS)
            .ok_or(BinError::TooManyReadings)?;
        if n >= MIN_BLOCK_SORT_ROWS && !time_ns.is_sorted() {
            self.add_by_bin(time_ns, counts);
        } else {
            self.add_in_order(time_ns, counts);
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
    /// in memory per row: the rows are split by span first (a counting sort over the few spans
    /// they cover: a day file crosses a mount's end), then each span's rows by bin
    /// ([`BinAccumulator::add_span_by_bin`]). Rows a sort would not pay for (over more than
    /// [`MAX_SPLIT_SPANS`] spans, or a span's rows it declines) go to
    /// [`BinAccumulator::add_by_block`]. The sums are integers, so the path taken changes no bit.
    fn add_by_bin(&mut self, time_ns: &[TimeNs], counts: &[i64]) {
        let n = time_ns.len().min(counts.len());
        let (time_ns, counts) = (&time_ns[..n], &counts[..n]);
        let Some((first, last)) = time_range(time_ns) else {
            return;
        };
        let (s0, s1) = (self.span_index(first), self.span_index(last));
        if s1 - s0 >= MAX_SPLIT_SPANS {
            self.add_by_block(time_ns, counts);
            return;
        }
        if s0 == s1 {
            // One span: no split needed.
            if !self.add_span_by_bin(s0, time_ns, counts, (first, last)) {
                self.add_by_block(time_ns, counts);
            }
            return;
        }
        let edges: Vec<TimeNs> = self.spans[s0 + 1..=s1].iter().map(|s| s.from).collect();
        let mut split = std::mem::take(&mut self.span_split);
        split.block.clear();
        split.block.extend(
            time_ns
                .iter()
                .map(|&t| edges.partition_point(|&e| e <= t) as u32),
        );
        split.sort_by_block(s1 - s0 + 1, time_ns, counts);
        for g in 0..=s1 - s0 {
            let rows = split.start[g]..split.start[g + 1];
            let (t, c) = (&split.time[rows.clone()], &split.counts[rows]);
            let Some(range) = time_range(t) else {
                continue;
            };
            if !self.add_span_by_bin(s0 + g, t, c, range) {
                self.add_by_block(t, c);
            }
        }
        self.span_split = split;
    }

    /// Rows of span `s` (`range`: their first and last time) sorted by bin with a counting sort
    /// and each bin summed in one run. Returns `false`, adding nothing, for rows before the
    /// first mount (the epoch grid) or too sparse for the sort to pay (fewer than two rows a
    /// bin).
    fn add_span_by_bin(
        &mut self,
        s: usize,
        time_ns: &[TimeNs],
        counts: &[i64],
        (first, last): (TimeNs, TimeNs),
    ) -> bool {
        let span = &self.spans[s];
        if span.anchor > span.from || first < span.from || last >= span.to {
            return false;
        }
        let anchor = span.anchor;
        let divide = self.divide;
        let k0 = divide.quotient((first - anchor) as u64);
        let bins = divide.quotient((last - anchor) as u64) - k0 + 1;
        if bins > (time_ns.len() as u64 / 2).min(MAX_SORT_BLOCKS * PAGE_BINS as u64) {
            return false;
        }
        let mut scratch = std::mem::take(&mut self.scratch);
        scratch.block.clear();
        scratch.block.extend(
            time_ns
                .iter()
                .map(|&t| (divide.quotient((t - anchor) as u64) - k0) as u32),
        );
        scratch.sort_by_block(bins as usize, time_ns, counts);
        for b in 0..bins as usize {
            let rows = scratch.start[b]..scratch.start[b + 1];
            if rows.is_empty() {
                continue;
            }
            let k = (k0 + b as u64) as i64;
            let page = self.page_of(s, k >> PAGE_SHIFT);
            let start = anchor + k * self.bin_ns;
            let index = (k & (PAGE_BINS as i64 - 1)) as usize;
            self.pages[page as usize][index].add_run(
                start,
                &scratch.time[rows.clone()],
                &scratch.counts[rows],
            );
        }
        self.scratch = scratch;
        self.current = None;
        true
    }

    /// Rows out of time order, grouped first by blocks of [`PAGE_BINS`] bins (a stable counting
    /// sort): a bin's moments are then updated while its page is in the cache, not once per
    /// row at a random place among the bar's bins (a shuffled day of 1 440 one-minute bins is
    /// 184 kB a bar, 2.2 MB for twelve, more than a core's L2 cache). The sums are integers,
    /// so the order changes no bit.
    fn add_by_block(&mut self, time_ns: &[TimeNs], counts: &[i64]) {
        let n = time_ns.len();
        let Some((first, last)) = time_range(time_ns) else {
            return;
        };
        let block_ns = (self.bin_ns as u64).saturating_mul(PAGE_BINS as u64);
        let blocks = (last.abs_diff(first) / block_ns).saturating_add(1);
        // Many blocks for few rows gain nothing (and cost their counters).
        if blocks > (n as u64 / 8).min(MAX_SORT_BLOCKS) {
            self.add_in_order(time_ns, counts);
            return;
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
    fn new(from: TimeNs, to: TimeNs, anchor: TimeNs, region: Region, bin_ns: TimeNs) -> Span {
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

/// One bar's readings as bins, in time order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BarBins {
    pub(crate) bin_ns: TimeNs,
    pub(crate) bins: Vec<(BinKey, BinMoments)>,
}

/// Weighted pseudo-readings: what a series is built from (`BarBins::readings`; a full-rate
/// log is the case of unit weights and no scatter).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Readings {
    /// Node times, ns (rounded), sorted.
    pub(crate) time_ns: Vec<TimeNs>,
    pub(crate) counts: Vec<f64>,
    pub(crate) weight: Vec<f64>,
    /// Scatter of each bin's counts about its line, counts², carried by the bin's first node
    /// (0 on the others).
    pub(crate) line_rss_counts2: Vec<f64>,
}

impl BarBins {
    /// Bins of a log held in memory (the same sums as streaming it through a
    /// [`BinAccumulator`]).
    pub(crate) fn from_log(
        grid: BinGrid,
        time_ns: &[TimeNs],
        counts: &[i64],
    ) -> Result<BarBins, BinError> {
        let mut acc = BinAccumulator::new(grid);
        acc.add_all(time_ns, counts)?;
        Ok(acc.finish())
    }

    /// Time of the first reading.
    pub fn first_reading_ns(&self) -> Option<TimeNs> {
        self.bins
            .first()
            .map(|(k, m)| k.start_ns + m.first_us * NS_PER_US)
    }

    /// Number of readings.
    pub(crate) fn n_readings(&self) -> u64 {
        self.bins.iter().map(|(_, m)| m.n).sum()
    }

    /// The nodes of every bin, in time order, with weight-0 samples (never fitted) that give a
    /// model's lags the full-rate grid's input:
    ///
    /// * `knots` (sorted times: the temperature sensors' readings) between consecutive nodes at
    ///   most two bins apart;
    /// * the first reading, and the last reading before and the first after every longer gap.
    ///
    /// Why: lags are computed along the series' own times, the input held linear between them
    /// (`signal::lag`). At full rate every sensor reading lies on the encoder's grid, so the
    /// lag sees each kink of the interpolated temperature, starts at the first reading and
    /// bridges a gap from its last reading to its next; along the nodes alone it would see a
    /// coarser line (mostly sensor noise, smoothed) and start and bridge elsewhere, which
    /// moved gains by up to two standard uncertainties on a 1 Hz campaign. With these samples
    /// the lag at the nodes is the full-rate one. Counts of a weight-0 sample are interpolated
    /// between its nodes (for plots only).
    pub(crate) fn readings(&self, knots: &[TimeNs]) -> Readings {
        let mut out = Readings::default();
        // Previous node (time, counts) and the last reading of its bin.
        let mut last: Option<(TimeNs, f64, TimeNs)> = None;
        // Knots before this one lie before the previous node.
        let mut next_knot = 0;
        for (key, moments) in &self.bins {
            let (nodes, line_rss) = moments.nodes();
            let first_reading = key.start_ns + moments.first_us * NS_PER_US;
            let last_reading = key.start_ns + moments.last_us * NS_PER_US;
            for (k, node) in nodes.iter().enumerate() {
                let time = key.start_ns + (node.offset_us * NS_PER_US as f64).round() as TimeNs;
                match last {
                    None => {
                        if first_reading < time {
                            out.push(first_reading, node.counts, 0.0, 0.0);
                        }
                    }
                    Some((t_prev, c_prev, prev_reading)) if time - t_prev > 2 * self.bin_ns => {
                        if prev_reading > t_prev {
                            out.push(prev_reading, c_prev, 0.0, 0.0);
                        }
                        if k == 0 && first_reading < time {
                            out.push(first_reading, node.counts, 0.0, 0.0);
                        }
                    }
                    Some((t_prev, c_prev, _)) => {
                        // Nodes come in time order: one walk over the knots, not a search each.
                        while knots.get(next_knot).is_some_and(|&t| t <= t_prev) {
                            next_knot += 1;
                        }
                        let from = next_knot;
                        while knots.get(next_knot).is_some_and(|&t| t < time) {
                            next_knot += 1;
                        }
                        for &t in &knots[from..next_knot] {
                            let f = (t - t_prev) as f64 / (time - t_prev) as f64;
                            out.push(t, c_prev + f * (node.counts - c_prev), 0.0, 0.0);
                        }
                    }
                }
                out.push(
                    time,
                    node.counts,
                    node.weight,
                    if k == 0 { line_rss } else { 0.0 },
                );
                last = Some((time, node.counts, last_reading));
            }
        }
        out
    }
}

impl Readings {
    fn push(&mut self, time_ns: TimeNs, counts: f64, weight: f64, line_rss_counts2: f64) {
        self.time_ns.push(time_ns);
        self.counts.push(counts);
        self.weight.push(weight);
        self.line_rss_counts2.push(line_rss_counts2);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Moments of readings given as (µs after the bin's start, counts).
    fn moments(samples: &[(i64, i64)]) -> BinMoments {
        let (time, counts): (Vec<TimeNs>, Vec<i64>) =
            samples.iter().map(|&(u, c)| (u * NS_PER_US, c)).unzip();
        let mut m = BinMoments::default();
        m.add_run(0, &time, &counts);
        m
    }

    /// Σ w_k p(s_k) = Σ_i p(u_i) for polynomials of degree ≤ 3, and Σ (c - f)² over the readings
    /// equals the nodes' weighted RSS plus the line scatter for any straight line f.
    #[test]
    fn nodes_keep_every_moment_a_straight_line_model_sees() {
        let samples: Vec<(i64, i64)> = [0, 1_000_000, 2_500_000, 2_600_000, 7_000_000, 9_900_000]
            .iter()
            .zip([100, 103, 98, 120, 111, 95])
            .map(|(&u, c)| (u, c))
            .collect();
        let (nodes, line_rss) = moments(&samples).nodes();
        assert_eq!(nodes.len(), 2);
        for degree in 0..=3 {
            let exact: f64 = samples.iter().map(|&(u, _)| (u as f64).powi(degree)).sum();
            let quad: f64 = nodes
                .iter()
                .map(|n| n.weight * n.offset_us.powi(degree))
                .sum();
            assert!(
                (quad - exact).abs() <= 1e-9 * exact.abs().max(1.0),
                "degree {degree}"
            );
        }
        for (a, b) in [(100.0, 0.0), (90.0, 3e-6), (120.0, -1e-5)] {
            let f = |u: f64| a + b * u;
            let full: f64 = samples
                .iter()
                .map(|&(u, c)| (c as f64 - f(u as f64)).powi(2))
                .sum();
            let compressed: f64 = nodes
                .iter()
                .map(|n| n.weight * (n.counts - f(n.offset_us)).powi(2))
                .sum::<f64>()
                + line_rss;
            assert!(
                (full - compressed).abs() < 1e-9 * full,
                "{full} vs {compressed}"
            );
        }
    }

    #[test]
    fn a_bin_of_one_time_is_one_node_with_the_mean() {
        let (nodes, rss) = moments(&[(5, 10), (5, 14)]).nodes();
        assert_eq!(nodes.len(), 1);
        assert_eq!((nodes[0].weight, nodes[0].counts), (2.0, 12.0));
        assert!((rss - 8.0).abs() < 1e-12);
        let (two, rss) = moments(&[(0, 1), (10, 5)]).nodes();
        assert_eq!(two.len(), 2);
        assert!((two[0].offset_us - 0.0).abs() < 1e-9 && (two[1].offset_us - 10.0).abs() < 1e-9);
        assert!((two[0].counts - 1.0).abs() < 1e-9 && (two[1].counts - 5.0).abs() < 1e-9);
        assert!(rss.abs() < 1e-9);
    }

    /// The integer sums are exact up to the longest bin: times near an hour (u² > i64::MAX)
    /// and counts near the i64 range, against sums done one reading at a time in i128.
    #[test]
    fn bin_sums_are_exact_up_to_an_hour() {
        let us = [0, 1, 3_037_000_499, 3_037_000_500, 3_599_999_999];
        // Σc² of these is 2¹²⁷ − 2⁶⁵ + 2⁶⁴ + 51, just inside i128 (with 1 << 40 it overflowed:
        // found by overflow-checks, issue 14).
        let counts = [i64::MAX, i64::MIN + 1, -7, 0, 1 << 32];
        let samples: Vec<(i64, i64)> = us.iter().copied().zip(counts).collect();
        let m = moments(&samples);
        let sum = |f: &dyn Fn(i128, i128) -> i128| -> i128 {
            samples.iter().map(|&(u, c)| f(u as i128, c as i128)).sum()
        };
        assert_eq!(m.su, sum(&|u, _| u));
        assert_eq!(m.suu, sum(&|u, _| u * u));
        assert_eq!(m.suuu, sum(&|u, _| u * u * u));
        assert_eq!(m.sc, sum(&|_, c| c));
        assert_eq!(m.suc, sum(&|u, c| u * c));
        assert_eq!(m.scc, sum(&|_, c| c * c));
        assert_eq!((m.n, m.first_us, m.last_us), (5, 0, 3_599_999_999));
    }

    /// 2027-01-15: an accepted reading time (`reading_time_ok`).
    const B: TimeNs = 1_800_000_000_000_000_000;

    /// 500 readings a second apart from [`B`], on a grid of 60-s bins with one mount and one
    /// rezero.
    fn five_hundred_readings() -> (BinGrid, Vec<TimeNs>, Vec<i64>) {
        let time: Vec<TimeNs> = (0..500).map(|i| B + 1_000_000_000 * i + 7).collect();
        let counts: Vec<i64> = (0..500).map(|i| (i * 37) % 101 - 50).collect();
        let grid = BinGrid {
            bin_ns: 60_000_000_000,
            mounts: vec![(B + 100_000_000_000, B + 400_000_000_000, 0)],
            rezeros: vec![B + 250_000_000_000],
            edges: vec![],
        };
        (grid, time, counts)
    }

    #[test]
    fn the_order_of_the_readings_does_not_change_the_bins() {
        let (grid, time, counts) = five_hundred_readings();
        let sorted = BarBins::from_log(grid.clone(), &time, &counts).unwrap();
        let mut order: Vec<usize> = (0..500).collect();
        order.reverse();
        order.swap(3, 400);
        let (t2, c2): (Vec<_>, Vec<_>) = order.iter().map(|&i| (time[i], counts[i])).unzip();
        assert_eq!(BarBins::from_log(grid, &t2, &c2).unwrap(), sorted);
        assert_eq!(sorted.n_readings(), 500);
        // Bins never cross the mount start/end or the rezero, and start on their region's grid.
        let starts: Vec<(TimeNs, Region)> = sorted
            .bins
            .iter()
            .map(|(k, _)| (k.start_ns, k.region))
            .collect();
        assert!(starts.contains(&(
            B + 100_000_000_000,
            Region::Segment {
                mount: 0,
                rezeros: 0
            }
        )));
        assert!(starts.contains(&(
            B + 250_000_000_000,
            Region::Segment {
                mount: 0,
                rezeros: 1
            }
        )));
        assert!(starts.contains(&(B + 400_000_000_000, Region::Outside)));
        assert!(sorted.bins.windows(2).all(|w| w[0].0 < w[1].0));
    }

    #[test]
    fn accumulators_of_other_grids_are_not_merged() {
        let (grid, time, counts) = five_hundred_readings();
        let mut acc = BinAccumulator::new(grid.clone());
        acc.add_all(&time, &counts).unwrap();
        let coarser = BinGrid {
            bin_ns: 2 * grid.bin_ns,
            ..grid.clone()
        };
        let mut other = BinAccumulator::new(coarser);
        other.add_all(&time, &counts).unwrap();
        assert_eq!(acc.clone().merge(other), Err(BinError::OtherGrid));
        let mut doubled = acc.clone();
        doubled.merge(acc).unwrap();
        assert_eq!(doubled.finish().n_readings(), 1000);
    }

    #[test]
    fn removing_readings_gives_back_the_bins_without_them() {
        let (grid, time, counts) = five_hundred_readings();
        let clean = BarBins::from_log(grid.clone(), &time, &counts).unwrap();
        // Add then remove everything: no bin left.
        let mut acc = BinAccumulator::new(grid.clone());
        acc.add_all(&time, &counts).unwrap();
        acc.remove_all(&time, &counts).unwrap();
        assert!(acc.finish().bins.is_empty());
        // The log plus copies of some of its rows (another file, another order), the copies
        // removed: exactly the bins of the log, bit for bit (first/last, min/max included).
        let mut acc = BinAccumulator::new(grid.clone());
        acc.add_all(&time, &counts).unwrap();
        let copies: Vec<usize> = (120..340).rev().chain([0, 499]).collect();
        let (ct, cc): (Vec<_>, Vec<_>) = copies.iter().map(|&i| (time[i], counts[i])).unzip();
        acc.add_all(&ct, &cc).unwrap();
        assert_ne!(acc.clone().finish(), clean);
        acc.remove_all(&ct, &cc).unwrap();
        let back = acc.finish();
        assert_eq!(back, clean);
        assert_eq!(back.n_readings(), 500);
        // A reading where no bin holds one is refused.
        let mut acc = BinAccumulator::new(grid);
        assert_eq!(
            acc.remove_all(&[B + 7], &[1]),
            Err(BinError::NotAdded { time_ns: B + 7 })
        );
    }

    /// Bins by the definition: each reading's bin from [`BinGrid::locate`], equal bins merged.
    fn reference_bins(grid: &BinGrid, time: &[TimeNs], counts: &[i64]) -> BarBins {
        let mut runs: Vec<(BinKey, BinMoments)> = time
            .iter()
            .zip(counts)
            .map(|(&t, &c)| {
                let (key, end) = grid.locate(t);
                assert!(key.start_ns <= t && t < end);
                let mut m = BinMoments::default();
                m.add_run(key.start_ns, &[t], &[c]);
                (key, m)
            })
            .collect();
        runs.sort_by_key(|(key, _)| *key);
        let mut bins: Vec<(BinKey, BinMoments)> = Vec::new();
        for (key, moments) in runs {
            match bins.last_mut() {
                Some((last, sum)) if *last == key => sum.merge(&moments),
                _ => bins.push((key, moments)),
            }
        }
        BarBins {
            bin_ns: grid.bin_ns,
            bins,
        }
    }

    /// The paged accumulator gives the bins of the definition for readings in any order:
    /// before, between and after mounts, across rezeros (two at one instant, one at a mount
    /// start, one outside), far from every mount, and for bins so short that a span's pages
    /// overflow its dense table.
    #[test]
    fn the_accumulator_gives_the_bins_of_the_definition_in_any_order() {
        use rand::seq::SliceRandom;
        use rand::{Rng, SeedableRng};
        const S: i64 = 1_000_000_000;
        // Times from 2027-01-15 (accepted reading times, `reading_time_ok`).
        const B: TimeNs = 1_800_000_000 * S;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(13);
        let mounts = vec![
            (B + 1_000 * S, B + 5_000 * S, 0),
            (B + 5_000 * S, B + 9_000 * S + 7, 2),
            (B + 20_000 * S, B + 30_000 * S, 1),
        ];
        let rezeros: Vec<TimeNs> = [
            500 * S,
            3_000 * S,
            3_000 * S,
            5_000 * S,
            12_000 * S,
            25_000 * S + 3,
        ]
        .iter()
        .map(|&t| B + t)
        .collect();
        // Event edges: inside segments, on a rezero, on a mount's end, in handling time.
        let edges: Vec<TimeNs> = [
            2_000 * S + 1,
            3_000 * S,
            4_999 * S,
            9_000 * S + 7,
            15_000 * S,
        ]
        .iter()
        .map(|&t| B + t)
        .collect();
        let mut time: Vec<TimeNs> = (0..20_000)
            .map(|_| B + rng.gen_range(-2_000 * S..40_000 * S))
            .collect();
        time.extend([
            EARLIEST_READING_NS,
            B - 1,
            B,
            B + 1_000 * S,
            B + 5_000 * S - 1,
            B + 3_000 * S,
            B + 9_000 * S + 7,
            LATEST_READING_NS - 1,
        ]);
        let counts: Vec<i64> = (0..time.len())
            .map(|_| rng.gen_range(-1000..1000))
            .collect();
        for bin_ns in [60 * S, 7 * S + 3, 1_000, 1 << 20] {
            let grid = BinGrid {
                bin_ns,
                mounts: mounts.clone(),
                rezeros: rezeros.clone(),
                edges: edges.clone(),
            };
            let want = reference_bins(&grid, &time, &counts);
            let mut order: Vec<usize> = (0..time.len()).collect();
            for pass in 0..3 {
                match pass {
                    0 => order.sort_by_key(|&i| time[i]),
                    1 => order.reverse(),
                    _ => order.shuffle(&mut rng),
                }
                let (t, c): (Vec<_>, Vec<_>) = order.iter().map(|&i| (time[i], counts[i])).unzip();
                let mut acc = BinAccumulator::new(grid.clone());
                for (tc, cc) in t.chunks(777).zip(c.chunks(777)) {
                    acc.add_all(tc, cc).unwrap();
                }
                assert_eq!(acc.finish(), want, "bin {bin_ns} ns, pass {pass}");
            }
        }
    }

    #[test]
    fn division_by_multiplication_is_exact() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let divisors = [
            1,
            2,
            3,
            7,
            1_000,
            60_000_000_000,
            (1 << 40) + 1,
            u64::MAX / 3,
            u64::MAX,
        ];
        for &d in &divisors {
            let divide = Divide::new(d);
            let edges = [0, 1, d - 1, d, d.saturating_add(1), u64::MAX - 1, u64::MAX];
            for n in edges
                .into_iter()
                .chain((0..10_000).map(|_| rng.gen::<u64>() >> rng.gen_range(0..64)))
            {
                assert_eq!(divide.quotient(n), n / d, "{n} / {d}");
            }
        }
    }

    /// The weight-0 samples: the first reading, sensor times between close nodes, and the last
    /// reading before and first after a gap; none inside a gap.
    #[test]
    fn readings_carry_the_full_rate_grid_of_the_lags() {
        const S: i64 = 1_000_000_000;
        let grid = BinGrid {
            bin_ns: 60 * S,
            mounts: vec![],
            rezeros: vec![],
            edges: vec![],
        };
        // 1 Hz for 10 min, a 30-min gap, 1 Hz for 10 min again.
        const B: TimeNs = 1_800_000_000 * S;
        let time: Vec<TimeNs> = (0..600).chain(2400..3000).map(|i| B + i * S).collect();
        let counts: Vec<i64> = (0..time.len() as i64).map(|i| i % 7).collect();
        let bins = BarBins::from_log(grid, &time, &counts).unwrap();
        let knots: Vec<TimeNs> = (0..100).map(|i| B + i * 30 * S + 5 * S).collect();
        let r = bins.readings(&knots);
        assert!(r.time_ns.windows(2).all(|w| w[0] < w[1]), "sorted");
        let zero: Vec<TimeNs> = r
            .time_ns
            .iter()
            .zip(&r.weight)
            .filter(|(_, &w)| w == 0.0)
            .map(|(&t, _)| t)
            .collect();
        assert_eq!(zero[0], B, "the first reading");
        assert!(
            zero.contains(&(B + 599 * S)) && zero.contains(&(B + 2400 * S)),
            "gap edges"
        );
        assert!(
            zero.contains(&(B + 35 * S)) && zero.contains(&(B + 2435 * S)),
            "sensor times"
        );
        assert!(
            !zero.iter().any(|&t| t > B + 599 * S && t < B + 2400 * S),
            "nothing in the gap"
        );
        let total: f64 = r.weight.iter().sum();
        assert!((total - 1200.0).abs() < 1e-9);
    }

    mod properties {
        use super::*;
        use proptest::prelude::*;

        const S: TimeNs = 1_000_000_000;
        const B: TimeNs = 1_800_000_000 * S;

        fn grid(bin_s: i64) -> BinGrid {
            BinGrid {
                bin_ns: bin_s * S,
                mounts: vec![
                    (B + 1_000 * S, B + 50_000 * S, 0),
                    (B + 60_000 * S, B + 90_000 * S, 1),
                ],
                rezeros: vec![B + 20_000 * S],
                // Events: inside a segment, on a mount's start, in handling time.
                edges: vec![
                    B + 7_777 * S + 3,
                    B + 33_333 * S,
                    B + 55_000 * S,
                    B + 60_000 * S,
                ],
            }
        }

        /// The rows shuffled by `keys`, added in one call, give the bins of the definition.
        fn check_shuffled(
            time: &[TimeNs],
            counts: &[i64],
            keys: &[u32],
            bin_s: i64,
        ) -> Result<(), TestCaseError> {
            let want = reference_bins(&grid(bin_s), time, counts);
            let mut order: Vec<usize> = (0..time.len()).collect();
            order.sort_by_key(|&i| keys[i % keys.len()]);
            let t: Vec<TimeNs> = order.iter().map(|&i| time[i]).collect();
            let c: Vec<i64> = order.iter().map(|&i| counts[i]).collect();
            let mut acc = BinAccumulator::new(grid(bin_s));
            acc.add_all(&t, &c).unwrap();
            prop_assert_eq!(acc.finish(), want);
            Ok(())
        }

        proptest! {
            #![proptest_config(ProptestConfig::with_cases(64))]

            /// Any row order and any split into batches gives the same bins.
            #[test]
            fn any_order_or_batch_split_gives_the_same_bins(
                rows in prop::collection::vec((-5_000i64..100_000, -100_000i64..100_000), 1..600),
                keys in prop::collection::vec(any::<u32>(), 600),
                batch in 1usize..300,
                bin_s in 1i64..3600,
            ) {
                let time: Vec<TimeNs> = rows.iter().map(|r| B + r.0 * S + r.0 % 7).collect();
                let counts: Vec<i64> = rows.iter().map(|r| r.1).collect();
                let want = BarBins::from_log(grid(bin_s), &time, &counts).unwrap();
                let mut order: Vec<usize> = (0..rows.len()).collect();
                order.sort_by_key(|&i| keys[i]);
                let t: Vec<TimeNs> = order.iter().map(|&i| time[i]).collect();
                let c: Vec<i64> = order.iter().map(|&i| counts[i]).collect();
                let mut acc = BinAccumulator::new(grid(bin_s));
                for (tc, cc) in t.chunks(batch).zip(c.chunks(batch)) {
                    acc.add_all(tc, cc).unwrap();
                }
                prop_assert_eq!(acc.finish(), want);
            }

            /// Shuffled rows within one zero segment (a shuffled day file: the per-bin counting
            /// sort) give the bins of the definition, with or without a few rows beyond it.
            #[test]
            fn shuffled_rows_of_one_segment_give_the_same_bins(
                rows in prop::collection::vec((1_000i64..20_000, -100_000i64..100_000), 256..1200),
                keys in prop::collection::vec(any::<u32>(), 1200),
                outside in 0usize..3,
                bin_s in 1i64..600,
            ) {
                let mut time: Vec<TimeNs> = rows.iter().map(|r| B + r.0 * S + r.0 % 7).collect();
                let mut counts: Vec<i64> = rows.iter().map(|r| r.1).collect();
                for k in 0..outside {
                    time.push(B + 30_000 * S + k as i64); // after the rezero: another span
                    counts.push(k as i64);
                }
                check_shuffled(&time, &counts, &keys, bin_s)?;
            }

            /// Shuffled rows over both mounts, the rezero and the handling time between them (a
            /// day file crossing a mount's end: split by span, then sorted by bin) give the bins
            /// of the definition.
            #[test]
            fn shuffled_rows_over_several_spans_give_the_same_bins(
                rows in prop::collection::vec((1_000i64..90_000, -100_000i64..100_000), 256..1500),
                keys in prop::collection::vec(any::<u32>(), 1500),
                bin_s in 300i64..3600,
            ) {
                let time: Vec<TimeNs> = rows.iter().map(|r| B + r.0 * S + r.0 % 7).collect();
                let counts: Vec<i64> = rows.iter().map(|r| r.1).collect();
                check_shuffled(&time, &counts, &keys, bin_s)?;
            }

            /// Batches dealt between two accumulators (as ingest's two consumers take them) and
            /// merged give the bins of one accumulator given every row.
            #[test]
            fn batches_dealt_to_two_accumulators_merge_to_the_same_bins(
                rows in prop::collection::vec((-5_000i64..100_000, -100_000i64..100_000), 1..600),
                deal in prop::collection::vec(any::<bool>(), 600),
                batch in 1usize..300,
                bin_s in 1i64..3600,
            ) {
                let time: Vec<TimeNs> = rows.iter().map(|r| B + r.0 * S + r.0 % 7).collect();
                let counts: Vec<i64> = rows.iter().map(|r| r.1).collect();
                let want = reference_bins(&grid(bin_s), &time, &counts);
                let mut two = [BinAccumulator::new(grid(bin_s)), BinAccumulator::new(grid(bin_s))];
                for (k, (tc, cc)) in time.chunks(batch).zip(counts.chunks(batch)).enumerate() {
                    two[usize::from(deal[k])].add_all(tc, cc).unwrap();
                }
                let [mut first, second] = two;
                first.merge(second).unwrap();
                prop_assert_eq!(first.finish(), want);
            }

            /// Extreme times and counts are refused (an error, nothing added), never a panic,
            /// a hang or a wrapped sum; accepted ones are summed exactly.
            #[test]
            fn extreme_values_are_refused_not_wrapped(
                t in prop_oneof![
                    Just(i64::MIN), Just(i64::MAX), Just(0i64), Just(-1i64),
                    Just(EARLIEST_READING_NS - 1), Just(EARLIEST_READING_NS),
                    Just(LATEST_READING_NS - 1), Just(LATEST_READING_NS), any::<i64>()
                ],
                c in prop_oneof![
                    Just(i64::MIN), Just(i64::MAX), Just(MAX_ABS_COUNTS),
                    Just(-MAX_ABS_COUNTS), Just(MAX_ABS_COUNTS + 1), any::<i64>()
                ],
            ) {
                let mut acc = BinAccumulator::new(grid(60));
                let ok = reading_time_ok(t) && c.unsigned_abs() <= MAX_ABS_COUNTS as u64;
                let r = acc.add_all(&[t, t], &[c, c]);
                prop_assert_eq!(r.is_ok(), ok);
                let bins = acc.finish();
                if ok {
                    prop_assert_eq!(bins.n_readings(), 2);
                    let m = bins.bins[0].1;
                    prop_assert_eq!(m.sc, 2 * c as i128);
                    prop_assert_eq!(m.scc, 2 * (c as i128) * (c as i128));
                } else {
                    prop_assert_eq!(bins.n_readings(), 0);
                }
            }
        }
    }
}
