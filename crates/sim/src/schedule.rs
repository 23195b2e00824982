//! Where each bar is when: mounts on plate lengths with handling gaps between them, the
//! handling positions, and the read-head power switching. All times are nanoseconds after the
//! campaign start.

use rand::Rng;

use super::config::{HeadSchedule, HeadStart, SimConfig};
use super::environment::on_off_toggles;
use super::{stream_rng, streams, Grid};
use dbbcal_core::campaign::Purpose;

const SECOND_NS: i64 = 1_000_000_000;

/// Where a mount is: a plate length (true distance known) or a target device.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Site {
    Length(usize),
    Device { id: String, distance_mm: f64 },
}

/// One mount: the bar sits on `site` at `tilt_deg` during `[from_ns, to_ns]`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PlannedMount {
    pub(crate) site: Site,
    /// Tilt of the bar from horizontal, degrees.
    pub(crate) tilt_deg: f64,
    pub(crate) purpose: Purpose,
    pub(crate) from_ns: i64,
    pub(crate) to_ns: i64,
    /// Settling amplitude (µm added to the reading at `from_ns`), 0 when the effect is off.
    pub(crate) settling_um: f64,
}

impl PlannedMount {
    /// The nominal centre distance of the site, mm (calibrated length or device distance).
    pub(crate) fn nominal_mm(&self, lengths_mm: &[f64]) -> f64 {
        match &self.site {
            Site::Length(i) => lengths_mm[*i],
            Site::Device { distance_mm, .. } => *distance_mm,
        }
    }

    #[cfg(test)]
    pub(crate) fn length_index(&self) -> Option<usize> {
        match self.site {
            Site::Length(i) => Some(i),
            Site::Device { .. } => None,
        }
    }
}

/// A bar's whole campaign.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct BarPlan {
    /// Sorted, disjoint.
    pub(crate) mounts: Vec<PlannedMount>,
    /// Offset (mm) from the socket path where the bar rests during gap `k` (the gap before
    /// mount `k`; the last entry is the gap after the last mount, if any).
    pub(crate) handling_offset_mm: Vec<f64>,
    /// Start of every handling gap (a `handling` event each).
    pub(crate) handling_ns: Vec<i64>,
    /// Head power switches, on encoder sample times, each flipping the power (from off, the
    /// first being "on" at 0, unless `head_powered_at_start`); empty when the head is always on.
    pub(crate) head_toggles_ns: Vec<i64>,
    /// The head is powered before its first switch (no "on" event at the start).
    pub(crate) head_powered_at_start: bool,
    /// Readings are logged while the head is off too ([`crate::HeadHeating::logs_while_off`]).
    pub(crate) head_logs_while_off: bool,
    /// The head's heat at the start is its steady state when powered (it has been on for long),
    /// not cold.
    pub(crate) head_warm_at_start: bool,
    /// Tilt of the bar when it has no mount before or after (the plate's), degrees.
    pub(crate) rest_tilt_deg: f64,
}

/// Where a bar is at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Place {
    /// On a mount of nominal distance `nominal_mm` (on the plate, or on a device), at
    /// `tilt_deg`, mounted since `from_ns`, with the mount's settling amplitude.
    Mounted {
        nominal_mm: f64,
        on_plate: bool,
        tilt_deg: f64,
        from_ns: i64,
        settling_um: f64,
    },
    /// In someone's hands, at this nominal centre distance (mm) and tilt.
    Handling { position_mm: f64, tilt_deg: f64 },
}

/// What a bar does after the calibration phase (`docs/spec/physics.md`, calibration unit).
enum Role {
    /// Stays on one plate length with purpose `reference`.
    Reference(usize),
    /// Stays on one site (working length or device) with this purpose.
    Working(Site, f64, Purpose),
    /// Rotates over the plate lengths (purpose `calibration`).
    Rotate,
}

/// Durations of the calibration phase, whole seconds.
#[derive(Debug, Clone, Copy)]
struct CalibrationTiming {
    gap_ns: i64,
    mount_ns: i64,
    /// Rounds: tilts × lengths; round `r` is at tilt `r / n_lengths`.
    rounds: usize,
}

impl CalibrationTiming {
    fn of(cfg: &SimConfig) -> Option<Self> {
        let c = cfg.schedule.calibration.as_ref()?;
        Some(Self {
            gap_ns: gap_ns(cfg),
            mount_ns: whole_seconds(c.mount_hours * 3600.0).max(60 * SECOND_NS),
            rounds: c.tilts_deg.len() * cfg.plate.length.len(),
        })
    }

    fn round_start_ns(&self, r: usize) -> i64 {
        r as i64 * (self.gap_ns + self.mount_ns)
    }

    fn end_ns(&self) -> i64 {
        self.round_start_ns(self.rounds)
    }
}

fn gap_ns(cfg: &SimConfig) -> i64 {
    whole_seconds(cfg.schedule.gap_minutes * 60.0).max(SECOND_NS)
}

/// The plan of bar `index` (its id `bar_id` for the reference and device lists).
pub(crate) fn plan_bar(cfg: &SimConfig, grid: &Grid, index: usize, bar_id: &str) -> BarPlan {
    let mut rng = stream_rng(cfg.seed, streams::SCHEDULE + index as u64);
    let s = &cfg.schedule;
    let mount_ns = whole_seconds(s.mount_days * 86400.0).max(60 * SECOND_NS);
    let gap_ns = gap_ns(cfg);
    let stagger_ns = whole_seconds(index as f64 * s.stagger_minutes * 60.0) % mount_ns;
    let mut mounts = calibration_mounts(cfg, grid, index);
    let calibration_end_ns = CalibrationTiming::of(cfg).map_or(0, |c| c.end_ns());
    let n_calibration = mounts.len();
    let role = role_of(cfg, bar_id);
    let visited = visited_lengths(cfg);
    let mut t = calibration_end_ns + stagger_ns;
    while t + gap_ns < grid.duration_ns {
        let from_ns = t + gap_ns;
        let (site, tilt_deg, purpose, to_ns) = match &role {
            Role::Reference(i) => (
                Site::Length(*i),
                cfg.plate.tilt_deg,
                Purpose::Reference,
                grid.duration_ns,
            ),
            Role::Working(site, tilt, purpose) => (site.clone(), *tilt, *purpose, grid.duration_ns),
            Role::Rotate => {
                let i = visited[(index + mounts.len() - n_calibration) % visited.len()];
                (
                    Site::Length(i),
                    cfg.plate.tilt_deg,
                    Purpose::Calibration,
                    (from_ns + mount_ns).min(grid.duration_ns),
                )
            }
        };
        if to_ns - from_ns < (3600 * SECOND_NS).min(mount_ns) {
            break;
        }
        mounts.push(PlannedMount {
            site,
            tilt_deg,
            purpose,
            from_ns,
            to_ns,
            settling_um: 0.0,
        });
        t = to_ns;
    }
    for m in &mut mounts {
        let amplitude = rng.gen_range(0.5..1.5) * cfg.effects.settling.amplitude_um;
        m.settling_um = if cfg.effects.settling.enabled {
            amplitude
        } else {
            0.0
        };
    }
    let n_gaps = mounts.len() + 1;
    let offset = s.handling_offset_mm;
    let handling_offset_mm = (0..n_gaps)
        .map(|_| {
            if offset > 0.0 {
                rng.gen_range(-offset..offset)
            } else {
                0.0
            }
        })
        .collect();
    let first_gap_ns = if n_calibration > 0 { 0 } else { stagger_ns };
    let handling_ns = gap_starts(&mounts, first_gap_ns, grid.duration_ns);
    let head_toggles_ns = head_toggles(cfg, grid, index);
    let (head_enabled, start) = (
        cfg.effects.head_heating.enabled,
        cfg.effects.head_heating.start,
    );
    BarPlan {
        mounts,
        handling_offset_mm,
        handling_ns,
        head_toggles_ns,
        head_powered_at_start: head_enabled && start != HeadStart::SwitchedOn,
        head_warm_at_start: head_enabled && start == HeadStart::PoweredWarm,
        head_logs_while_off: head_enabled && cfg.effects.head_heating.logs_while_off,
        rest_tilt_deg: cfg.plate.tilt_deg,
    }
}

/// Indices of the plate lengths rotating bars visit, in order (`schedule.lengths`; all of them
/// when it is empty).
fn visited_lengths(cfg: &SimConfig) -> Vec<usize> {
    if cfg.schedule.lengths.is_empty() {
        return (0..cfg.plate.length.len()).collect();
    }
    cfg.schedule
        .lengths
        .iter()
        .filter_map(|id| cfg.plate.length.iter().position(|l| &l.id == id))
        .collect()
}

/// The bar's role after the calibration phase.
fn role_of(cfg: &SimConfig, bar_id: &str) -> Role {
    let s = &cfg.schedule;
    let length_index = |id: &str| {
        cfg.plate
            .length
            .iter()
            .position(|l| l.id == id)
            .unwrap_or(0)
    };
    if let Some(r) = s.reference.iter().find(|r| r.bar == bar_id) {
        return Role::Reference(length_index(&r.length));
    }
    let Some(w) = &s.working else {
        return Role::Rotate;
    };
    match w
        .device
        .as_ref()
        .filter(|d| d.bars.iter().any(|b| b == bar_id))
    {
        Some(d) => Role::Working(
            Site::Device {
                id: d.id.clone(),
                distance_mm: d.distance_mm,
            },
            d.tilt_deg,
            w.purpose,
        ),
        None => Role::Working(
            Site::Length(length_index(&w.length)),
            cfg.plate.tilt_deg,
            w.purpose,
        ),
    }
}

/// The calibration phase of bar `index`: round `r` at tilt `tilts[r / n_lengths]` on length
/// `(index + r) mod n_lengths`, so each bar visits every (length, tilt) pair once.
fn calibration_mounts(cfg: &SimConfig, grid: &Grid, index: usize) -> Vec<PlannedMount> {
    let (Some(c), Some(timing)) = (&cfg.schedule.calibration, CalibrationTiming::of(cfg)) else {
        return Vec::new();
    };
    let n_lengths = cfg.plate.length.len();
    (0..timing.rounds)
        .map(|r| {
            let from_ns = timing.round_start_ns(r) + timing.gap_ns;
            PlannedMount {
                site: Site::Length((index + r) % n_lengths),
                tilt_deg: c.tilts_deg[r / n_lengths],
                purpose: Purpose::Calibration,
                from_ns,
                to_ns: (from_ns + timing.mount_ns).min(grid.duration_ns),
                settling_um: 0.0,
            }
        })
        .filter(|m| m.from_ns < m.to_ns)
        .collect()
}

/// Plate re-tilts (time after the start, tilt in degrees): mid-gap before each tilt block of the
/// calibration phase (every bar is in its handling gap), and the return to `plate.tilt_deg`
/// mid-gap after the phase. Empty without a calibration phase.
pub(crate) fn plate_tilts(cfg: &SimConfig, grid: &Grid) -> Vec<(i64, f64)> {
    let (Some(c), Some(timing)) = (&cfg.schedule.calibration, CalibrationTiming::of(cfg)) else {
        return Vec::new();
    };
    let n_lengths = cfg.plate.length.len();
    let mid_gap = |start_ns: i64| start_ns + timing.gap_ns / 2;
    let mut tilts: Vec<(i64, f64)> = c
        .tilts_deg
        .iter()
        .enumerate()
        .map(|(b, &t)| (mid_gap(timing.round_start_ns(b * n_lengths)), t))
        .collect();
    tilts.push((mid_gap(timing.end_ns()), cfg.plate.tilt_deg));
    tilts.retain(|&(t, _)| t < grid.duration_ns);
    tilts
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

/// Read-head on/off switching on encoder sample times, when the effect is on: "on" at 0 when the
/// head is switched on at the start, then alternately off and on.
fn head_toggles(cfg: &SimConfig, grid: &Grid, index: usize) -> Vec<i64> {
    let h = &cfg.effects.head_heating;
    if !h.enabled {
        return Vec::new();
    }
    let mut rng = stream_rng(cfg.seed, streams::HEAD + index as u64);
    let switches_s = match h.schedule {
        HeadSchedule::Random => {
            on_off_toggles(&mut rng, h.mean_on_h, h.mean_off_h, grid.duration_s())
        }
        HeadSchedule::Daily => daily_off(&mut rng, h.daily_off_h, grid.duration_s()),
    };
    let mut toggles = if h.start == HeadStart::SwitchedOn {
        vec![0]
    } else {
        Vec::new()
    };
    for t_s in switches_s {
        let t_ns = ((t_s * 1e9) / grid.sample_ns as f64).round() as i64 * grid.sample_ns;
        if t_ns <= 0 || toggles.last().is_some_and(|&last| t_ns <= last) {
            continue; // (never with the 5-minute floor unless samples are longer)
        }
        toggles.push(t_ns);
    }
    toggles
}

/// Off once a day (off, then on, seconds after the start): each day, a duration drawn uniformly
/// from `off_h` hours, at a time drawn uniformly among those that keep the head on for at least
/// 5 minutes after midnight and before the next.
fn daily_off(rng: &mut impl Rng, off_h: [f64; 2], duration_s: f64) -> Vec<f64> {
    const MARGIN_S: f64 = 300.0;
    let mut switches = Vec::new();
    let mut day = 0.0;
    while day * 86400.0 < duration_s {
        let off_s = rng.gen_range(off_h[0]..=off_h[1]) * 3600.0;
        let latest_s = (86400.0 - off_s - MARGIN_S).max(MARGIN_S);
        let from_s = day * 86400.0 + rng.gen_range(MARGIN_S..=latest_s);
        for t in [from_s, from_s + off_s] {
            if t < duration_s {
                switches.push(t);
            }
        }
        day += 1.0;
    }
    switches
}

impl BarPlan {
    /// Where the bar is at `t_ns`. `cursor` is a hint (index of the current or next mount) that
    /// makes a forward sweep linear.
    pub(crate) fn place_at(&self, t_ns: i64, lengths_mm: &[f64], cursor: &mut usize) -> Place {
        while *cursor < self.mounts.len() && self.mounts[*cursor].to_ns < t_ns {
            *cursor += 1;
        }
        let k = *cursor;
        if let Some(m) = self.mounts.get(k).filter(|m| m.from_ns <= t_ns) {
            return Place::Mounted {
                nominal_mm: m.nominal_mm(lengths_mm),
                on_plate: matches!(m.site, Site::Length(_)),
                tilt_deg: m.tilt_deg,
                from_ns: m.from_ns,
                settling_um: m.settling_um,
            };
        }
        let tilt_deg = self
            .mounts
            .get(k)
            .or(k.checked_sub(1).and_then(|p| self.mounts.get(p)))
            .map_or(self.rest_tilt_deg, |m| m.tilt_deg);
        Place::Handling {
            position_mm: self.handling_position_mm(k, t_ns, lengths_mm),
            tilt_deg,
        }
    }

    /// In gap `k` the bar travels linearly from the previous site distance to the next one,
    /// offset by the gap's random rest offset.
    fn handling_position_mm(&self, k: usize, t_ns: i64, lengths_mm: &[f64]) -> f64 {
        let prev = k.checked_sub(1).and_then(|p| self.mounts.get(p));
        let next = self.mounts.get(k);
        let length = |m: &PlannedMount| m.nominal_mm(lengths_mm);
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
    use crate::config::ReferenceMount;

    fn plans(cfg: &SimConfig) -> Vec<BarPlan> {
        let grid = Grid::new(cfg).unwrap();
        (0..6)
            .map(|i| plan_bar(cfg, &grid, i, &format!("B{:02}", i + 1)))
            .collect()
    }

    #[test]
    fn rotating_bars_visit_all_lengths_with_gaps() {
        let cfg = SimConfig::default();
        for plan in plans(&cfg) {
            let mut seen: Vec<usize> = plan
                .mounts
                .iter()
                .filter_map(|m| m.length_index())
                .collect();
            seen.sort();
            seen.dedup();
            assert_eq!(seen, vec![0, 1, 2]);
            for pair in plan.mounts.windows(2) {
                let gap_s = (pair[1].from_ns - pair[0].to_ns) / SECOND_NS;
                assert_eq!(gap_s, 20 * 60, "handling gap");
                assert_ne!(pair[0].site, pair[1].site);
            }
            assert!(plan.mounts[0].from_ns > 0, "starts with a gap");
            assert_eq!(
                plan.handling_ns.len(),
                plan.mounts.len()
                    + usize::from(
                        plan.mounts.last().unwrap().to_ns < Grid::new(&cfg).unwrap().duration_ns
                    )
            );
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
        assert!(
            matches!(inside, Place::Mounted { nominal_mm, on_plate: true, .. } if nominal_mm == m.nominal_mm(&lengths))
        );
        let in_gap = plan.place_at(m.to_ns + 60 * SECOND_NS, &lengths, &mut cursor);
        let Place::Handling { position_mm, .. } = in_gap else {
            panic!("expected handling")
        };
        assert!(lengths.iter().all(|l| (l - position_mm).abs() > 1e-6));
    }

    #[test]
    fn reference_bar_stays_on_its_length() {
        let mut cfg = SimConfig::default();
        cfg.schedule.reference = vec![ReferenceMount {
            bar: "B03".into(),
            length: "max".into(),
        }];
        let plan = &plans(&cfg)[2];
        assert_eq!(plan.mounts.len(), 1);
        assert_eq!(plan.mounts[0].site, Site::Length(2));
        assert_eq!(plan.mounts[0].purpose, Purpose::Reference);
    }
}
