//! Times a bar's readings repeat, found while the encoder rows stream into bins.
//!
//! At full rate a bar's rows are sorted, and exact duplicates (same time and counts) and
//! conflicting readings (same time, other counts) are neighbours. Streamed into bins, the rows
//! are never held, so each binned bar gets a [`RepeatSketch`]: one bit per slot of `2^k` ns
//! over its mounted time line (±24 h). A row whose slot is already set is a *candidate*: two
//! readings within one slot. Slots are a quarter of the fleet's mean reading interval or less,
//! and at most 0.27 s, so distinct readings of a regular logger rarely share one, and every
//! repeated time does. The candidates' windows are read again afterwards
//! (`read::resolve_repeats`) and compared exactly; the sketch only decides where to look. It
//! costs one bit test per row, whatever the row order, and one bit per slot (at most
//! [`MAX_SKETCH_BITS`] a bar).

use dbbcal_core::campaign::Campaign;
use dbbcal_core::series::quality::FAR_OUTSIDE_MOUNTS_S;

/// Most bits of one bar's sketch (8 MiB): slots grow coarser beyond.
pub(crate) const MAX_SKETCH_BITS: u64 = 1 << 26;
/// Slots of at most 2^28 ns (0.27 s): a bar logging at 1 Hz among bars logging once a minute
/// still has a slot a reading (a 30-day campaign then takes 1.2 MiB a bar).
const MAX_SLOT_SHIFT: u32 = 28;
/// Candidates beyond this share of the bar's rows read the whole bar again instead of windows.
const MAX_CANDIDATE_SHARE: u64 = 8;

/// One bar's slot bitmap and the slots seen more than once.
#[derive(Debug, Clone)]
pub(crate) struct RepeatSketch {
    origin_ns: i64,
    /// Slots cover `[origin_ns, origin_ns + span_ns)`; rows outside (more than 24 h from every
    /// mount: never fitted) are not checked.
    span_ns: u64,
    shift: u32,
    bits: Vec<u64>,
    candidates: Vec<u64>,
    rows: u64,
    /// Set by a [`RepeatSketch::merge`] of sketches made differently: look everywhere.
    everything: bool,
}

/// Where a bar's rows may repeat: time windows `[from, to]` (ns, sorted, disjoint), or the
/// whole checked time line when candidates were too many to list.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum RepeatWindows {
    None,
    Windows(Vec<(i64, i64)>),
    Everything(i64, i64),
}

impl RepeatSketch {
    /// The sketch of `bar`, or `None` when it has no mount. `rows_per_bar`: the rows a bar is
    /// expected to have (the footers' rows over the bars), which sets the slot width.
    pub(crate) fn new(campaign: &Campaign, bar: &str, rows_per_bar: u64) -> Option<RepeatSketch> {
        let margin = (FAR_OUTSIDE_MOUNTS_S * 1e9) as i64;
        let mounts = campaign.mounts.iter().filter(|m| m.bar == bar);
        let from = mounts
            .clone()
            .map(|m| m.from_ns)
            .min()?
            .saturating_sub(margin);
        let to = mounts.map(|m| m.to_ns).max()?.saturating_add(margin);
        let span_ns = to.checked_sub(from).filter(|&s| s > 0)? as u64;
        // A slot of at most a quarter of the mean interval, a power of two ns (a shift per row),
        // and never above [`MAX_SLOT_SHIFT`]: the mean is the fleet's, and a bar logging faster
        // than the others would otherwise share its slots between distinct readings.
        let quarter = span_ns / rows_per_bar.max(1) / 4;
        let mut shift = quarter.max(1).ilog2().min(MAX_SLOT_SHIFT);
        while (span_ns >> shift) >= MAX_SKETCH_BITS {
            shift += 1;
        }
        let slots = (span_ns >> shift) + 1;
        Some(RepeatSketch {
            origin_ns: from,
            span_ns,
            shift,
            bits: vec![0; slots.div_ceil(64) as usize],
            candidates: Vec::new(),
            rows: 0,
            everything: false,
        })
    }

    /// Marks the slots of `time_ns`; a slot marked before becomes a candidate.
    pub(crate) fn add(&mut self, time_ns: &[i64]) {
        self.rows += time_ns.len() as u64;
        for &t in time_ns {
            let offset = t.wrapping_sub(self.origin_ns) as u64;
            if offset >= self.span_ns {
                continue;
            }
            let slot = offset >> self.shift;
            let (word, bit) = ((slot >> 6) as usize, 1u64 << (slot & 63));
            if self.bits[word] & bit != 0 {
                self.candidates.push(slot);
            } else {
                self.bits[word] |= bit;
            }
        }
    }

    /// Adds the rows `other` marked, a sketch of the same bar made the same way (ingest's
    /// consumers each mark one): a slot marked in both becomes a candidate, so the candidates
    /// are those of one sketch given every row, one per row after a slot's first.
    pub(crate) fn merge(&mut self, other: RepeatSketch) {
        let same = (self.origin_ns, self.span_ns, self.shift, self.bits.len())
            == (
                other.origin_ns,
                other.span_ns,
                other.shift,
                other.bits.len(),
            );
        self.rows += other.rows;
        if !same {
            // Cannot happen (every consumer clones one sketch per bar); were it to, every
            // checked time is looked at again rather than a repeat missed.
            self.everything = true;
            return;
        }
        self.candidates.extend(other.candidates);
        for (word, (mine, theirs)) in self.bits.iter_mut().zip(&other.bits).enumerate() {
            let mut both = *mine & theirs;
            while both != 0 {
                self.candidates
                    .push(((word as u64) << 6) | u64::from(both.trailing_zeros()));
                both &= both - 1;
            }
            *mine |= theirs;
        }
    }

    /// Where repeated times may be: the candidate slots as merged time windows (two readings
    /// of one time always share a slot).
    pub(crate) fn windows(mut self) -> RepeatWindows {
        let last = self.origin_ns + self.span_ns as i64 - 1;
        if self.everything {
            return RepeatWindows::Everything(self.origin_ns, last);
        }
        if self.candidates.is_empty() {
            return RepeatWindows::None;
        }
        if self.candidates.len() as u64 > self.rows / MAX_CANDIDATE_SHARE {
            return RepeatWindows::Everything(self.origin_ns, last);
        }
        self.candidates.sort_unstable();
        self.candidates.dedup();
        let slot_ns = 1i64 << self.shift;
        let mut windows: Vec<(i64, i64)> = Vec::new();
        for &slot in &self.candidates {
            let from = self.origin_ns + slot as i64 * slot_ns;
            let to = (from + slot_ns - 1).min(last);
            match windows.last_mut() {
                Some(w) if from <= w.1.saturating_add(1) => w.1 = w.1.max(to),
                _ => windows.push((from, to)),
            }
        }
        RepeatWindows::Windows(windows)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dbbcal_core::campaign::{Campaign, Manifest};

    fn sketch(span_ns: u64, shift: u32) -> RepeatSketch {
        RepeatSketch {
            origin_ns: 1_000,
            span_ns,
            shift,
            bits: vec![0; ((span_ns >> shift) + 1).div_ceil(64) as usize],
            candidates: Vec::new(),
            rows: 0,
            everything: false,
        }
    }

    #[test]
    fn a_time_seen_twice_is_a_window_in_any_order_and_distinct_slots_are_not() {
        let times: Vec<i64> = (0..1000).map(|i| 1_000 + i * 1024).collect();
        let mut s = sketch(2_000_000, 8);
        let mut shuffled = times.clone();
        shuffled.reverse();
        shuffled.push(times[500]);
        s.add(&shuffled);
        let t = times[500];
        match s.windows() {
            RepeatWindows::Windows(w) => {
                assert_eq!(w.len(), 1);
                assert!(w[0].0 <= t && t <= w[0].1 && w[0].1 - w[0].0 < 256, "{w:?}");
            }
            other => panic!("{other:?}"),
        }
        let mut clean = sketch(2_000_000, 8);
        clean.add(&times);
        assert_eq!(clean.windows(), RepeatWindows::None);
    }

    #[test]
    fn sketches_merged_find_the_times_one_sketch_finds() {
        let times: Vec<i64> = (0..1000).map(|i| 1_000 + i * 1024).collect();
        // A time repeated across the two halves, one repeated within the second, one not at all.
        let (mut first, mut second) = (sketch(2_000_000, 8), sketch(2_000_000, 8));
        first.add(&times[..600]);
        second.add(&times[600..]);
        second.add(&[times[100], times[900]]);
        let mut one = sketch(2_000_000, 8);
        one.add(&times);
        one.add(&[times[100], times[900]]);
        first.merge(second);
        assert_eq!(first.rows, one.rows);
        assert_eq!(first.candidates.len(), one.candidates.len());
        assert_eq!(first.windows(), one.windows());
        let mut other_shift = sketch(2_000_000, 8);
        other_shift.merge(sketch(2_000_000, 9));
        assert!(matches!(
            other_shift.windows(),
            RepeatWindows::Everything(..)
        ));
    }

    #[test]
    fn a_bar_logging_at_1_hz_in_a_fleet_logging_once_a_minute_keeps_a_slot_a_reading() {
        // B01: 4 h of mounts, checked over 52 h; the fleet's mean: one reading a minute.
        use crate::manifest::TomlManifest;
        let manifest = Manifest::from_toml_str(dbbcal_testkit::ONE_BAR_MANIFEST, "m").unwrap();
        let c = Campaign::from_manifest(manifest).unwrap();
        let mut s = RepeatSketch::new(&c, "B01", 52 * 60).unwrap();
        assert_eq!(
            s.shift, MAX_SLOT_SHIFT,
            "a minute's quarter is above the cap"
        );
        let start = c.mounts[0].from_ns;
        let hours: Vec<i64> = (0..4 * 3600).map(|i| start + i * 1_000_000_000).collect();
        s.add(&hours);
        s.add(&[hours[1234]]);
        match s.windows() {
            RepeatWindows::Windows(w) => {
                assert_eq!(w.len(), 1, "{w:?}");
                assert!(w[0].0 <= hours[1234] && hours[1234] <= w[0].1);
            }
            other => panic!("{other:?}"),
        }
        // A bar without a mount has no sketch.
        assert!(RepeatSketch::new(&c, "B99", 1000).is_none());
    }

    #[test]
    fn rows_outside_the_checked_span_are_ignored_and_many_candidates_mean_everything() {
        let mut s = sketch(10_000, 4);
        s.add(&[0, 0, 999, 999, 11_000, 11_000, i64::MIN, i64::MAX]);
        assert_eq!(s.windows(), RepeatWindows::None);
        let mut dense = sketch(10_000, 4);
        dense.add(&[1_000; 100]);
        assert_eq!(dense.windows(), RepeatWindows::Everything(1_000, 10_999));
    }
}
