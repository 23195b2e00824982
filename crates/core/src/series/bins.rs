//! Exact compression of a bar's encoder log into bins of two weighted nodes.
//!
//! A 1 Hz log over 30 days is 2.6 M readings per bar, while the thermal model varies on time
//! constants of 15 min to 2 h (`docs/spec/physics.md`): within a bin of a minute every regressor is a
//! straight line to `O((bin/tau)²)`, and the fit on the nodes unbiased to `O((bin/tau)⁴)`
//! ([`MIN_BINS_PER_TAU`]). For a model that is a straight line within each bin, the
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
//!   mount start to last mount end, shared by the rows) is `AUTOMATIC_MAX_INTERVAL_S` (12 s) or
//!   less, else every reading (`series::bins`, `series::automatic_bin_s`; the measurements behind the numbers: `bench/README.md`). The same for any row order or file split.

use crate::campaign::{Campaign, TimeNs};

mod accumulator;
mod bar_bins;
mod grid;
mod moments;
mod reorder;

pub use accumulator::BinAccumulator;
pub use bar_bins::{BarBins, Readings};
pub use grid::BinGrid;
pub(crate) use grid::Region;
pub(crate) use grid::Segments;

/// Longest bin accepted: a bin of more than an hour is not a straight line for the time
/// constants of `docs/spec/physics.md` (15 min and more), and it bounds the integer sums.
pub const MAX_BIN_S: f64 = 3600.0;

const NS_PER_US: i64 = 1_000;

/// Earliest reading time accepted anywhere (1980-01-01T00:00:00Z, ns): no logger of this kind
/// predates it, and a time before it is a clock reset (1970) or a NaT (`i64::MIN`), refused at
/// ingest (`docs/guarantees.md`).
pub(crate) const EARLIEST_READING_NS: TimeNs = 315_532_800_000_000_000;
/// First reading time no longer accepted (2200-01-01T00:00:00Z, ns): a time past it is a broken
/// clock or a unit mix-up. The bounds keep every sum of times and bin numbers far from `i64`'s
/// ends, so no arithmetic on an accepted time can wrap.
pub(crate) const LATEST_READING_NS: TimeNs = 7_258_118_400_000_000_000;
/// Largest accepted |counts| (2⁴⁸, 1.4 km at 5 nm a count): with at most
/// `MAX_BAR_READINGS` readings in a bin, `Σ c²` stays below 2¹²⁷ (`i128`).
pub const MAX_ABS_COUNTS: i64 = 1 << 48;
/// Most readings one bar's accumulator takes (2³¹): bounds every bin's sums (`Σ u³ < 2¹²⁷`).
pub(crate) const MAX_BAR_READINGS: u64 = 1 << 31;

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

/// Whether `t` is an accepted reading time (`EARLIEST_READING_NS` ..
/// `LATEST_READING_NS`).
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
pub(crate) const AUTOMATIC_BIN_S: f64 = 60.0;

/// Longest mean interval between a bar's readings that is compressed automatically, s: a bin of
/// [`AUTOMATIC_BIN_S`] then holds 5 readings or more, and two nodes (plus the sensors' reading
/// times, weight 0) stand for them. Slower logs (the machine-tool log's 15 s) keep every reading.
///
/// Why 12 s: a 10-s log's diagnosis refits each bar's readings tens of times; on 60-s bins the
/// nightly of the second simulator's 10-bar, 15-day, 10-s campaigns takes about half the CPU
/// of every reading, with the same fleet ledger to every printed digit and the estimates (the
/// true effect added) within 0.007 u of the every-reading fit's (`bench/README.md`). Not free:
/// on one of the second simulator's 25 hidden-effect checks (plate expansion, seed 2, 10 s over
/// 5 days) a bar's base fit settles in another basin on the bins and `air_gradient` is ranked
/// before `plate_expansion`, which the ledger then adds second (`docs/model.md`). The mean
/// interval counts the handling time between mounts, so a 10-s logger reads a little over 10 s.
pub(crate) const AUTOMATIC_MAX_INTERVAL_S: f64 = 12.0;

/// A fitted time constant should span at least this many bins. With no bin length set, a run
/// whose fit finds a shorter one ([`too_short_for_bins`]) reads the campaign again with shorter
/// bins ([`REREAD_BINS_PER_TAU`]).
///
/// Why 2: the two nodes of a bin are the Gauss quadrature of its sample times, the roots of their
/// second orthogonal polynomial. What a term's bin line misses, its quadratic remainder within
/// the bin, vanishes at both nodes, so a fit on the nodes is biased only at `O((bin/tau)⁴)`;
/// what it gives up at `O((bin/tau)²)` is the readings' scatter along that remainder:
/// information (a slightly wider interval, which the fit's uncertainty carries), not a bias.
/// Measured against the fit to every reading (base model, stems' `tau_s` of 100-270 s drawn:
/// `bench/foreign_sim.py --tau-s-range 100 300`, 6 bars, 6 days, 10-s readings, held and
/// smooth air): 60-s bins (1.7-4.5 bins a time constant) within 0.036 u of every estimate,
/// 30-s bins within 0.0075 u, 120-s bins (0.8-2.3 bins) 0.15-0.25 u.
/// Bins longer than the automatic 60 s cost more than this rule sees: 240-s bins moved the
/// default stems' estimates (900-2400 s, 4-10 bins) by 0.04-0.27 u, so those are held to
/// [`LONG_BINS_MIN_PER_TAU`] ([`min_bins_per_tau`]).
/// The fit's own stop resolves about 0.1 u (`fit::STOP_CHI2`). The rule was 10 bins; on the
/// second simulator's second path + air gradient + plate expansion (`bench/loop_check.py`, k = 3,
/// seed 4) a base model's `tau_s` of 145 s, a misfit, made the nightly read the 10-s log again in
/// 14-s bins: 25 s against 15 s, the same ledger to 7 digits and every estimate within 0.013 u.
pub const MIN_BINS_PER_TAU: f64 = 2.0;

/// [`MIN_BINS_PER_TAU`] for bins longer than the automatic 60 s, which only a user sets
/// (`--bin-s`, `[model] bin_s`): the rule measured there is not the quadrature's alone (240-s
/// bins moved estimates by 0.27 u at 4 bins a time constant), so the fit report keeps warning
/// as the earlier, stricter rule did.
pub const LONG_BINS_MIN_PER_TAU: f64 = 10.0;

/// How many bins of `bin_s` a fitted time constant should span: [`MIN_BINS_PER_TAU`] up to the
/// automatic 60 s, [`LONG_BINS_MIN_PER_TAU`] beyond.
pub fn min_bins_per_tau(bin_s: f64) -> f64 {
    if bin_s > AUTOMATIC_BIN_S {
        LONG_BINS_MIN_PER_TAU
    } else {
        MIN_BINS_PER_TAU
    }
}

/// A campaign read again for a time constant too short for its bins ([`MIN_BINS_PER_TAU`]) gets
/// bins this many times shorter than it: twice the minimum, so that the time constant refitted
/// on the new bins, which moves by a fraction of its uncertainty, does not fall short again.
pub const REREAD_BINS_PER_TAU: f64 = 4.0;

/// Whether a fitted time constant `tau_s`, whose 95 % interval ends at `ci95_upper_s`, is too
/// short for bins of `bin_s` (0: every reading, never too short): it spans fewer than
/// [`min_bins_per_tau`] bins, and so does its interval's upper end, so the data rule out a
/// time constant the bins would hold. A time constant the data do not determine (its interval
/// reaching far beyond the bins, say a `tau_s` run to its 1-s search bound on a bar the base
/// model misfits) is not: reading the campaign again with shorter bins, or every reading,
/// would refit the same undetermined parameter at several times the cost. An interval not
/// known (NaN) counts as short.
pub fn too_short_for_bins(tau_s: f64, ci95_upper_s: f64, bin_s: f64) -> bool {
    let limit = min_bins_per_tau(bin_s) * bin_s;
    let interval_short = ci95_upper_s.is_nan() || ci95_upper_s < limit;
    bin_s > 0.0 && tau_s < limit && interval_short
}

/// The bin length for a campaign of `encoder_rows` readings when none is set (`[model] bin_s`
/// and `--bin-s` absent): `AUTOMATIC_BIN_S` when the bars' mean interval between readings is
/// at most `AUTOMATIC_MAX_INTERVAL_S`, else 0 (every reading). The interval is the bars'
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

#[cfg(test)]
mod tests;
