//! Exact compression of a bar's encoder log into bins of two weighted nodes.
//!
//! A 1 Hz log over 30 days is 2.6 M readings per bar, while the thermal model varies on time
//! constants of 15 min to 2 h (`physics.md`): within a bin of a minute every regressor is a
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

use crate::campaign::{Campaign, TimeNs};
use crate::series::Event;

/// Longest bin accepted: a bin of more than an hour is not a straight line for the time
/// constants of `physics.md` (15 min and more), and it bounds the integer sums.
pub const MAX_BIN_S: f64 = 3600.0;

const NS_PER_US: i64 = 1_000;

/// Integer moments of one bin's readings: sums over its samples of powers of `u` (µs since the
/// bin's start) and of the counts `c`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BinMoments {
    pub n: u64,
    /// First and last reading, µs since the bin's start.
    pub first_us: i64,
    pub last_us: i64,
    pub su: i128,
    pub suu: i128,
    pub suuu: i128,
    pub sc: i128,
    pub suc: i128,
    pub scc: i128,
}

/// One node of a compressed bin: a weighted pseudo-reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    /// Time since the bin's start, µs.
    pub offset_us: f64,
    /// Number of readings the node stands for (the two weights of a bin sum to its `n`).
    pub weight: f64,
    /// The bin's least-squares line at the node, counts.
    pub counts: f64,
}

impl BinMoments {
    /// Add readings of this bin (times in ns, the bin starting at `start_ns`).
    pub fn add_run(&mut self, start_ns: TimeNs, time_ns: &[TimeNs], counts: &[i64]) {
        let mut run = BinMoments::default();
        let (mut first, mut last) = (i64::MAX, i64::MIN);
        for (&t, &c) in time_ns.iter().zip(counts) {
            let u = (t - start_ns) / NS_PER_US;
            first = first.min(u);
            last = last.max(u);
            // 0 <= u < 3.6e9 µs (an hour) < 2³², so u² fits u64 (not i64: bins longer than
            // 50.6 min overflowed it); each product below is one 64x64->128.
            let uu = u as u64 * u as u64;
            run.su += u as i128;
            run.suu += uu as i128;
            run.suuu += uu as i128 * u as i128;
            run.sc += c as i128;
            run.suc += u as i128 * c as i128;
            run.scc += c as i128 * c as i128;
        }
        run.n = time_ns.len().min(counts.len()) as u64;
        (run.first_us, run.last_us) = (first, last);
        self.merge(&run);
    }

    /// Sums of two parts of one bin.
    pub fn merge(&mut self, other: &BinMoments) {
        if other.n == 0 {
            return;
        }
        if self.n == 0 {
            (self.first_us, self.last_us) = (other.first_us, other.last_us);
        }
        self.first_us = self.first_us.min(other.first_us);
        self.last_us = self.last_us.max(other.last_us);
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
    pub fn nodes(&self) -> (Vec<Node>, f64) {
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
    Segment { mount: usize, rezeros: usize },
    /// Handling time (outside every mount).
    Outside,
}

/// Key of one bin: its start (ns) and region. Bins sort in time order by key: regions follow
/// one another in time and each region's bins start at or after the region's start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct BinKey {
    pub start_ns: TimeNs,
    pub region: Region,
}

/// Where one bar's bins lie: its mounts and `rezero` events, and the bin length.
#[derive(Debug, Clone)]
pub struct BinGrid {
    bin_ns: TimeNs,
    /// `(from_ns, to_ns, index into Campaign::mounts)`, sorted by start (mounts of one bar do
    /// not overlap).
    mounts: Vec<(TimeNs, TimeNs, usize)>,
    /// Times of the `rezero` events that apply to the bar, sorted.
    rezeros: Vec<TimeNs>,
}

impl BinGrid {
    /// The grid of bar `bar_id` for bins of `bin_s` seconds (at most [`MAX_BIN_S`]).
    pub fn new(campaign: &Campaign, events: &[Event], bar_id: &str, bin_s: f64) -> BinGrid {
        let bin_s = bin_s.clamp(1e-6, MAX_BIN_S);
        let mut mounts: Vec<(TimeNs, TimeNs, usize)> = campaign
            .mounts
            .iter()
            .enumerate()
            .filter(|(_, m)| m.bar == bar_id)
            .map(|(i, m)| (m.from_ns, m.to_ns, i))
            .collect();
        mounts.sort();
        let mut rezeros: Vec<TimeNs> = events
            .iter()
            .filter(|e| e.kind == "rezero" && e.bar.as_deref().is_none_or(|b| b == bar_id))
            .map(|e| e.time_ns)
            .collect();
        rezeros.sort();
        BinGrid {
            bin_ns: ((bin_s * 1e9).round() as TimeNs).max(NS_PER_US),
            mounts,
            rezeros,
        }
    }

    /// The bin holding a reading at `t`: its key and the end (exclusive, ns) of the time it
    /// covers, so that a caller can keep adding readings before that end without a search.
    pub fn locate(&self, t: TimeNs) -> (BinKey, TimeNs) {
        let after = self.mounts.partition_point(|m| m.0 <= t);
        let inside = after
            .checked_sub(1)
            .map(|i| self.mounts[i])
            .filter(|m| t < m.1);
        let (region, anchor, region_end) = match inside {
            Some((from, to, mount)) => {
                let rezeros = self.rezeros.partition_point(|&r| r <= t);
                let anchor = rezeros
                    .checked_sub(1)
                    .map_or(from, |k| self.rezeros[k].max(from));
                let end = self.rezeros.get(rezeros).map_or(to, |&r| r.min(to));
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

/// Accumulates one bar's readings, in any order, into bins.
#[derive(Debug, Clone)]
pub struct BinAccumulator {
    grid: BinGrid,
    /// The bin readings are being added to: key, end (ns), moments.
    current: Option<(BinKey, TimeNs, BinMoments)>,
    /// Finished runs of readings (a bin may appear several times when rows are not sorted).
    runs: Vec<(BinKey, BinMoments)>,
}

impl BinAccumulator {
    pub fn new(grid: BinGrid) -> BinAccumulator {
        BinAccumulator {
            grid,
            current: None,
            runs: Vec::new(),
        }
    }

    /// Add readings given as two columns: each run of rows in one bin in a tight loop (ingest
    /// streams tens of millions of rows through here).
    pub fn add_all(&mut self, time_ns: &[TimeNs], counts: &[i64]) {
        let n = time_ns.len().min(counts.len());
        let mut i = 0;
        while i < n {
            let (key, end, mut moments) = match self.current.take() {
                Some((key, end, m)) if time_ns[i] >= key.start_ns && time_ns[i] < end => {
                    (key, end, m)
                }
                other => {
                    if let Some((key, _, m)) = other {
                        self.runs.push((key, m));
                    }
                    let (key, end) = self.grid.locate(time_ns[i]);
                    (key, end, BinMoments::default())
                }
            };
            let run = time_ns[i..n]
                .iter()
                .position(|&t| t < key.start_ns || t >= end)
                .map_or(n, |k| i + k);
            moments.add_run(key.start_ns, &time_ns[i..run], &counts[i..run]);
            self.current = Some((key, end, moments));
            i = run;
        }
    }

    /// The bins, in time order, each run of the same bin merged.
    pub fn finish(mut self) -> BarBins {
        if let Some((key, _, moments)) = self.current.take() {
            self.runs.push((key, moments));
        }
        self.runs.sort_by_key(|(key, _)| *key);
        let mut bins: Vec<(BinKey, BinMoments)> = Vec::with_capacity(self.runs.len());
        for (key, moments) in self.runs {
            match bins.last_mut() {
                Some((last, sum)) if *last == key => sum.merge(&moments),
                _ => bins.push((key, moments)),
            }
        }
        BarBins {
            bin_ns: self.grid.bin_ns,
            bins,
        }
    }
}

/// One bar's readings as bins, in time order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BarBins {
    pub bin_ns: TimeNs,
    pub bins: Vec<(BinKey, BinMoments)>,
}

/// Weighted pseudo-readings: what a series is built from ([`BarBins::readings`]; a full-rate
/// log is the case of unit weights and no scatter).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Readings {
    /// Node times, ns (rounded), sorted.
    pub time_ns: Vec<TimeNs>,
    pub counts: Vec<f64>,
    pub weight: Vec<f64>,
    /// Scatter of each bin's counts about its line, counts², carried by the bin's first node
    /// (0 on the others).
    pub line_rss_counts2: Vec<f64>,
}

impl BarBins {
    /// Bins of a log held in memory (the same sums as streaming it through a
    /// [`BinAccumulator`]).
    pub fn from_log(grid: BinGrid, time_ns: &[TimeNs], counts: &[i64]) -> BarBins {
        let mut acc = BinAccumulator::new(grid);
        acc.add_all(time_ns, counts);
        acc.finish()
    }

    /// Time of the first reading.
    pub fn first_reading_ns(&self) -> Option<TimeNs> {
        self.bins
            .first()
            .map(|(k, m)| k.start_ns + m.first_us * NS_PER_US)
    }

    /// Number of readings.
    pub fn n_readings(&self) -> u64 {
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
    /// (`model::lag`). At full rate every sensor reading lies on the encoder's grid, so the
    /// lag sees each kink of the interpolated temperature, starts at the first reading and
    /// bridges a gap from its last reading to its next; along the nodes alone it would see a
    /// coarser line (mostly sensor noise, smoothed) and start and bridge elsewhere, which
    /// moved gains by up to two standard uncertainties on a 1 Hz campaign. With these samples
    /// the lag at the nodes is the full-rate one. Counts of a weight-0 sample are interpolated
    /// between its nodes (for plots only).
    pub fn readings(&self, knots: &[TimeNs]) -> Readings {
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
        let counts = [i64::MAX, i64::MIN + 1, -7, 0, 1 << 40];
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

    #[test]
    fn the_order_of_the_readings_does_not_change_the_bins() {
        let time: Vec<TimeNs> = (0..500).map(|i| 1_000_000_000 * i + 7).collect();
        let counts: Vec<i64> = (0..500).map(|i| (i * 37) % 101 - 50).collect();
        let grid = BinGrid {
            bin_ns: 60_000_000_000,
            mounts: vec![(100_000_000_000, 400_000_000_000, 0)],
            rezeros: vec![250_000_000_000],
        };
        let sorted = BarBins::from_log(grid.clone(), &time, &counts);
        let mut order: Vec<usize> = (0..500).collect();
        order.reverse();
        order.swap(3, 400);
        let (t2, c2): (Vec<_>, Vec<_>) = order.iter().map(|&i| (time[i], counts[i])).unzip();
        assert_eq!(BarBins::from_log(grid, &t2, &c2), sorted);
        assert_eq!(sorted.n_readings(), 500);
        // Bins never cross the mount start/end or the rezero, and start on their region's grid.
        let starts: Vec<(TimeNs, Region)> = sorted
            .bins
            .iter()
            .map(|(k, _)| (k.start_ns, k.region))
            .collect();
        assert!(starts.contains(&(
            100_000_000_000,
            Region::Segment {
                mount: 0,
                rezeros: 0
            }
        )));
        assert!(starts.contains(&(
            250_000_000_000,
            Region::Segment {
                mount: 0,
                rezeros: 1
            }
        )));
        assert!(starts.contains(&(400_000_000_000, Region::Outside)));
        assert!(sorted.bins.windows(2).all(|w| w[0].0 < w[1].0));
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
        };
        // 1 Hz for 10 min, a 30-min gap, 1 Hz for 10 min again.
        let time: Vec<TimeNs> = (0..600).chain(2400..3000).map(|i| i * S).collect();
        let counts: Vec<i64> = (0..time.len() as i64).map(|i| i % 7).collect();
        let bins = BarBins::from_log(grid, &time, &counts);
        let knots: Vec<TimeNs> = (0..100).map(|i| i * 30 * S + 5 * S).collect();
        let r = bins.readings(&knots);
        assert!(r.time_ns.windows(2).all(|w| w[0] < w[1]), "sorted");
        let zero: Vec<TimeNs> = r
            .time_ns
            .iter()
            .zip(&r.weight)
            .filter(|(_, &w)| w == 0.0)
            .map(|(&t, _)| t)
            .collect();
        assert_eq!(zero[0], 0, "the first reading");
        assert!(
            zero.contains(&(599 * S)) && zero.contains(&(2400 * S)),
            "gap edges"
        );
        assert!(
            zero.contains(&(35 * S)) && zero.contains(&(2435 * S)),
            "sensor times"
        );
        assert!(
            !zero.iter().any(|&t| t > 599 * S && t < 2400 * S),
            "nothing in the gap"
        );
        let total: f64 = r.weight.iter().sum();
        assert!((total - 1200.0).abs() < 1e-9);
    }
}
