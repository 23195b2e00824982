//! Where each bar is when: mounts on plate lengths with handling gaps between them, the
//! handling positions, and the read-head power switching. All times are nanoseconds after the
//! campaign start.

use rand::Rng;

use super::config::SimConfig;
use super::environment::on_off_toggles;
use super::{stream_rng, streams, Grid};
use crate::campaign::Purpose;

const SECOND_NS: i64 = 1_000_000_000;

/// One mount: the bar sits on plate length `length_index` during `[from_ns, to_ns]`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PlannedMount {
    pub length_index: usize,
    pub purpose: Purpose,
    pub from_ns: i64,
    pub to_ns: i64,
    /// Settling amplitude (µm added to the reading at `from_ns`), 0 when the effect is off.
    pub settling_um: f64,
}

/// A bar's whole campaign.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct BarPlan {
    /// Sorted, disjoint.
    pub mounts: Vec<PlannedMount>,
    /// Offset (mm) from the socket path where the bar rests during gap `k` (the gap before
    /// mount `k`; the last entry is the gap after the last mount, if any).
    pub handling_offset_mm: Vec<f64>,
    /// Start of every handling gap (a `handling` event each).
    pub handling_ns: Vec<i64>,
    /// Head power switches (on at 0, then off, on, ...), on encoder sample times; empty when
    /// the head is always on.
    pub head_toggles_ns: Vec<i64>,
}

/// Where a bar is at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Place {
    /// On a plate length, mounted since `from_ns`, with the mount's settling amplitude.
    Mounted { length_index: usize, from_ns: i64, settling_um: f64 },
    /// In someone's hands, at this nominal centre distance (mm).
    Handling { position_mm: f64 },
}

/// The plan of bar `index` (its id `bar_id` for the reference list).
pub(crate) fn plan_bar(cfg: &SimConfig, grid: &Grid, index: usize, bar_id: &str) -> BarPlan {
    let mut rng = stream_rng(cfg.seed, streams::SCHEDULE + index as u64);
    let s = &cfg.schedule;
    let mount_ns = whole_seconds(s.mount_days * 86400.0).max(60 * SECOND_NS);
    let gap_ns = whole_seconds(s.gap_minutes * 60.0).max(SECOND_NS);
    let stagger_ns = whole_seconds(index as f64 * s.stagger_minutes * 60.0) % mount_ns;
    let reference = s.reference.iter().find(|r| r.bar == bar_id);
    let n_lengths = cfg.plate.length.len();
    let mut mounts = Vec::new();
    let mut t = stagger_ns;
    while t + gap_ns < grid.duration_ns {
        let from_ns = t + gap_ns;
        let (length_index, purpose, to_ns) = match reference {
            Some(r) => {
                let i = cfg.plate.length.iter().position(|l| l.id == r.length).unwrap_or(0);
                (i, Purpose::Reference, grid.duration_ns)
            }
            None => ((index + mounts.len()) % n_lengths, Purpose::Calibration, (from_ns + mount_ns).min(grid.duration_ns)),
        };
        if to_ns - from_ns < (3600 * SECOND_NS).min(mount_ns) {
            break;
        }
        let amplitude = rng.gen_range(0.5..1.5) * cfg.effects.settling.amplitude_um;
        let settling_um = if cfg.effects.settling.enabled { amplitude } else { 0.0 };
        mounts.push(PlannedMount { length_index, purpose, from_ns, to_ns, settling_um });
        t = to_ns;
    }
    let n_gaps = mounts.len() + 1;
    let offset = s.handling_offset_mm;
    let handling_offset_mm = (0..n_gaps).map(|_| if offset > 0.0 { rng.gen_range(-offset..offset) } else { 0.0 }).collect();
    let handling_ns = gap_starts(&mounts, stagger_ns, grid.duration_ns);
    let head_toggles_ns = head_toggles(cfg, grid, index);
    BarPlan { mounts, handling_offset_mm, handling_ns, head_toggles_ns }
}

fn whole_seconds(seconds: f64) -> i64 {
    seconds.round() as i64 * SECOND_NS
}

/// Start of every handling gap: the first before the first mount, one after each mount that
/// ends before the campaign does.
fn gap_starts(mounts: &[PlannedMount], first_ns: i64, end_ns: i64) -> Vec<i64> {
    let mut starts = vec![first_ns];
    starts.extend(mounts.iter().map(|m| m.to_ns).filter(|&t| t < end_ns));
    starts
}

/// Read-head on/off switching on encoder sample times (on at 0), when the effect is on.
fn head_toggles(cfg: &SimConfig, grid: &Grid, index: usize) -> Vec<i64> {
    let h = &cfg.effects.head_heating;
    if !h.enabled {
        return Vec::new();
    }
    let mut rng = stream_rng(cfg.seed, streams::HEAD + index as u64);
    let mut toggles = vec![0];
    for t_s in on_off_toggles(&mut rng, h.mean_on_h, h.mean_off_h, grid.duration_s()) {
        let t_ns = ((t_s * 1e9) / grid.sample_ns as f64).round() as i64 * grid.sample_ns;
        if toggles.last().is_some_and(|&last| t_ns <= last) {
            continue; // (never with the 5-minute floor unless samples are longer)
        }
        toggles.push(t_ns);
    }
    toggles
}

impl BarPlan {
    /// Where the bar is at `t_ns`. `cursor` is a hint (index of the current or next mount) that
    /// makes a forward sweep linear.
    pub fn place_at(&self, t_ns: i64, lengths_mm: &[f64], cursor: &mut usize) -> Place {
        while *cursor < self.mounts.len() && self.mounts[*cursor].to_ns < t_ns {
            *cursor += 1;
        }
        let k = *cursor;
        if let Some(m) = self.mounts.get(k).filter(|m| m.from_ns <= t_ns) {
            return Place::Mounted { length_index: m.length_index, from_ns: m.from_ns, settling_um: m.settling_um };
        }
        Place::Handling { position_mm: self.handling_position_mm(k, t_ns, lengths_mm) }
    }

    /// In gap `k` the bar travels linearly from the previous socket length to the next one,
    /// offset by the gap's random rest offset.
    fn handling_position_mm(&self, k: usize, t_ns: i64, lengths_mm: &[f64]) -> f64 {
        let prev = k.checked_sub(1).and_then(|p| self.mounts.get(p));
        let next = self.mounts.get(k);
        let length = |m: &PlannedMount| lengths_mm[m.length_index];
        let offset = self.handling_offset_mm.get(k).copied().unwrap_or(0.0);
        let nominal = match (prev, next) {
            (Some(a), Some(b)) => {
                let frac = (t_ns - a.to_ns) as f64 / (b.from_ns - a.to_ns).max(1) as f64;
                length(a) + frac.clamp(0.0, 1.0) * (length(b) - length(a))
            }
            (Some(a), None) => length(a),
            (None, Some(b)) => length(b),
            (None, None) => lengths_mm[0],
        };
        nominal + offset
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::config::ReferenceMount;

    fn plans(cfg: &SimConfig) -> Vec<BarPlan> {
        let grid = Grid::new(cfg).unwrap();
        (0..6).map(|i| plan_bar(cfg, &grid, i, &format!("B{:02}", i + 1))).collect()
    }

    #[test]
    fn rotating_bars_visit_all_lengths_with_gaps() {
        let cfg = SimConfig::default();
        for plan in plans(&cfg) {
            let mut seen: Vec<usize> = plan.mounts.iter().map(|m| m.length_index).collect();
            seen.sort();
            seen.dedup();
            assert_eq!(seen, vec![0, 1, 2]);
            for pair in plan.mounts.windows(2) {
                let gap_s = (pair[1].from_ns - pair[0].to_ns) / SECOND_NS;
                assert_eq!(gap_s, 20 * 60, "handling gap");
                assert_ne!(pair[0].length_index, pair[1].length_index);
            }
            assert!(plan.mounts[0].from_ns > 0, "starts with a gap");
            assert_eq!(plan.handling_ns.len(), plan.mounts.len() + usize::from(plan.mounts.last().unwrap().to_ns < Grid::new(&cfg).unwrap().duration_ns));
        }
    }

    #[test]
    fn handling_positions_are_off_socket_and_mounts_on_socket() {
        let cfg = SimConfig::default();
        let lengths: Vec<f64> = cfg.plate.length.iter().map(|l| l.mm).collect();
        let plan = &plans(&cfg)[1];
        let mut cursor = 0;
        let m = &plan.mounts[1];
        let inside = plan.place_at(m.from_ns + 1000, &lengths, &mut cursor);
        assert!(matches!(inside, Place::Mounted { length_index, .. } if length_index == m.length_index));
        let in_gap = plan.place_at(m.to_ns + 60 * SECOND_NS, &lengths, &mut cursor);
        let Place::Handling { position_mm } = in_gap else { panic!("expected handling") };
        assert!(lengths.iter().all(|l| (l - position_mm).abs() > 1e-6));
    }

    #[test]
    fn reference_bar_stays_on_its_length() {
        let mut cfg = SimConfig::default();
        cfg.schedule.reference = vec![ReferenceMount { bar: "B03".into(), length: "max".into() }];
        let plan = &plans(&cfg)[2];
        assert_eq!(plan.mounts.len(), 1);
        assert_eq!(plan.mounts[0].length_index, 2);
        assert_eq!(plan.mounts[0].purpose, Purpose::Reference);
    }
}
