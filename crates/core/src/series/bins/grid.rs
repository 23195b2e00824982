//! Where bins are cut: each bar's regions (zero segments split at `rezero` events, handling
//! time between mounts) and the grid of bin starts anchored at each region's start.
//!
//! Separate because the grid is decided once from the campaign's events, before any reading is
//! accumulated, and both the accumulator and the tests need it alone.

use super::accumulator::Span;
use super::{MAX_BIN_S, NS_PER_US};
use crate::campaign::Campaign;
use crate::campaign::TimeNs;
use crate::series::Event;

/// The region a reading falls in, which no bin crosses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(crate) enum Region {
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
pub(crate) struct BinKey {
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
/// bins straddling the switches the estimates move by up to 0.094 u from the full-rate fit
/// (`head_growth_um`) and the HAC u of `tau_head_s` shrinks by 35 % (tau 663 s at 3.3 u from the
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
    pub(super) bin_ns: TimeNs,
    /// `(from_ns, to_ns, index into Campaign::mounts)`, sorted by start (mounts of one bar do
    /// not overlap).
    pub(super) mounts: Vec<(TimeNs, TimeNs, usize)>,
    /// Times of the `rezero` events that apply to the bar, sorted.
    pub(super) rezeros: Vec<TimeNs>,
    /// Event times inside zero segments where bins restart ([`bin_edges`]), sorted.
    pub(super) edges: Vec<TimeNs>,
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
    pub(super) fn spans(&self) -> Vec<Span> {
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
    pub(super) fn locate(&self, t: TimeNs) -> (BinKey, TimeNs) {
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
