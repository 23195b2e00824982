//! A hexapod axis test from end to end on plain data: per dwell the pose from the legs' lengths,
//! the commanded pose from the datum, the six errors with their names and U, straightness raw
//! and with its least-squares line removed (`docs/spec/device-format.md`, "Conventions").
//!
//! The legs' lengths depend on their tilts (a bar's `D(n, A)` takes the tilt), and the tilts on
//! the pose: the caller gives `lengths(dwell, tilts)`; the tilts are first those of the nominal
//! pose (at the dwell's ring temperature), then those of the pose found, until the lengths move
//! by less than [`TILT_LENGTH_TOLERANCE_MM`] (at most [`MAX_TILT_PASSES`] passes).
//!
//! A dwell is *evaluated* when its pose is found and its rotary coordinates equal the datum's;
//! a near-singular pose or a failed forward solution flags the dwell with the reason and reports
//! no errors. The datum's errors are zero by definition, with U = 0.

use crate::components::{Axis, SixErrors};
use crate::hexapod::{Hexapod, HexapodError};
use crate::iso230_2::{Iso230Error, Iso230_2, TargetDeviations};
use crate::pose::Pose;
use crate::pose_errors::axis_of_test;
use crate::straightness::remove_line;

/// The tilt iteration stops when no leg length moves by more than this, mm.
pub const TILT_LENGTH_TOLERANCE_MM: f64 = 1e-6;
/// Most forward solutions per dwell (the first from the nominal pose's tilts).
pub const MAX_TILT_PASSES: usize = 4;
/// Commanded coordinates closer than this are the same (device-format.md: 1 µm), mm.
pub const POSITION_TOLERANCE_MM: f64 = 1e-3;

/// What a dwell gives the test, besides its legs' lengths.
#[derive(Debug, Clone, PartialEq)]
pub struct DwellInput {
    /// Station number.
    pub station: i64,
    /// Run, if logged.
    pub run: Option<i64>,
    /// Commanded x, y, z, mm.
    pub position_mm: [f64; 3],
    /// Whether the rotary coordinates equal the datum's (else the dwell is not evaluated).
    pub rotary_as_datum: bool,
    /// Approach direction per axis.
    pub approach: [i8; 3],
    /// Temperature of the rings, °C.
    pub ring_temperature_c: f64,
    /// Each leg's expanded uncertainty U (k = 2) of its length, µm.
    pub leg_u_k2_um: [f64; 6],
}

/// One dwell's result.
#[derive(Debug, Clone, PartialEq)]
pub struct DwellResult {
    /// The input.
    pub input: DwellInput,
    /// Leg lengths used (at the final tilts), mm.
    pub leg_lengths_mm: Option<[f64; 6]>,
    /// Leg tilts used, degrees.
    pub leg_tilts_deg: Option<[f64; 6]>,
    /// The measured pose.
    pub pose: Option<Pose>,
    /// The commanded pose.
    pub commanded: Option<Pose>,
    /// Condition number of the Jacobian at the pose.
    pub condition: Option<f64>,
    /// Forward solutions done (tilt passes).
    pub tilt_passes: usize,
    /// The six errors (measured − commanded) in M's axes, µm and µrad.
    pub errors: Option<SixErrors>,
    /// Their expanded uncertainty U (k = 2).
    pub u_k2: Option<SixErrors>,
    /// The two straightness errors with the least-squares line removed, µm (the moved axis's
    /// `straightness_indices` order).
    pub straightness_line_removed_um: Option<[f64; 2]>,
    /// Why the dwell is not evaluated, or a note.
    pub flag: Option<String>,
}

/// The whole test's result.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceTestResult {
    /// The axis moved (`None`: none or several: generic names).
    pub axis: Option<Axis>,
    /// Names of the six errors: ISO 230-1 when one axis moved, else δx … εz.
    pub names: [String; 6],
    /// Index of the datum dwell.
    pub datum: usize,
    /// Every dwell, in time order.
    pub dwells: Vec<DwellResult>,
    /// The straightness lines removed: (error index, intercept µm, slope µm/mm).
    pub lines: Vec<(usize, f64, f64)>,
}

/// Why no dwell can be evaluated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DeviceTestError {
    /// No dwell is at the datum.
    #[error("no dwell at the datum")]
    NoDatum,
    /// The datum's pose could not be found.
    #[error("the datum dwell (station {station}) has no pose: {source}")]
    DatumPose {
        /// The datum's station.
        station: i64,
        /// Why.
        source: PoseError,
    },
}

/// Why a dwell has no pose.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PoseError {
    /// A leg has no compensated reading in the dwell.
    #[error("a leg has no compensated reading in the dwell")]
    NoReading,
    /// The pose is near a singularity of the kinematics.
    #[error("not evaluated: {0}")]
    NearSingular(HexapodError),
    /// The forward kinematics failed.
    #[error(transparent)]
    Forward(HexapodError),
}

/// What [`measure`] found: the forward solution (or why not), the lengths and tilts used, and
/// the forward solutions done.
type Measured = (
    Result<crate::hexapod::ForwardSolution, PoseError>,
    Option<[f64; 6]>,
    Option<[f64; 6]>,
    usize,
);

fn measure(device: &Hexapod, mut lengths: impl FnMut(&[f64; 6]) -> Option<[f64; 6]>) -> Measured {
    let mut tilts = device.leg_tilts_deg(&device.nominal_pose);
    let Some(mut l) = lengths(&tilts) else {
        return (Err(PoseError::NoReading), None, None, 0);
    };
    let mut passes = 0;
    loop {
        passes += 1;
        let sol = match device.forward(&l) {
            Ok(s) => s,
            Err(e @ HexapodError::NearSingular { .. }) => {
                return (
                    Err(PoseError::NearSingular(e)),
                    Some(l),
                    Some(tilts),
                    passes,
                )
            }
            Err(e) => return (Err(PoseError::Forward(e)), Some(l), Some(tilts), passes),
        };
        let new_tilts = device.leg_tilts_deg(&sol.pose);
        let Some(new_l) = lengths(&new_tilts) else {
            return (Ok(sol), Some(l), Some(tilts), passes);
        };
        let moved = (0..6).map(|i| (new_l[i] - l[i]).abs()).fold(0.0, f64::max);
        tilts = new_tilts;
        l = new_l;
        if moved <= TILT_LENGTH_TOLERANCE_MM || passes >= MAX_TILT_PASSES {
            let sol = if moved <= TILT_LENGTH_TOLERANCE_MM {
                Ok(sol)
            } else {
                device.forward(&l).map_err(PoseError::Forward)
            };
            return (sol, Some(l), Some(tilts), passes);
        }
    }
}

/// Run the test: `device` at T0 (`reference_temperature_c`), the dwells in time order, the
/// datum's index, and each dwell's leg lengths at given tilts.
pub fn evaluate(
    device: &Hexapod,
    reference_temperature_c: f64,
    dwells: &[DwellInput],
    datum: usize,
    mut lengths: impl FnMut(usize, &[f64; 6]) -> Option<[f64; 6]>,
) -> Result<DeviceTestResult, DeviceTestError> {
    let d0 = dwells.get(datum).ok_or(DeviceTestError::NoDatum)?;
    let at = |d: &DwellInput| device.at_temperature(d.ring_temperature_c, reference_temperature_c);
    let dev0 = at(d0);
    let (sol0, ..) = measure(&dev0, |t| lengths(datum, t));
    let datum_pose = sol0
        .map_err(|source| DeviceTestError::DatumPose {
            station: d0.station,
            source,
        })?
        .pose;
    let u0 = d0.leg_u_k2_um;
    let mut out: Vec<DwellResult> = Vec::with_capacity(dwells.len());
    for (k, d) in dwells.iter().enumerate() {
        let dev = at(d);
        let (sol, leg_lengths_mm, leg_tilts_deg, tilt_passes) = measure(&dev, |t| lengths(k, t));
        let commanded = dev.commanded_pose(&datum_pose, d0.position_mm, d.position_mm);
        let mut r = DwellResult {
            input: d.clone(),
            leg_lengths_mm,
            leg_tilts_deg,
            pose: None,
            commanded: Some(commanded),
            condition: None,
            tilt_passes,
            errors: None,
            u_k2: None,
            straightness_line_removed_um: None,
            flag: None,
        };
        match sol {
            Err(reason) => r.flag = Some(reason.to_string()),
            Ok(s) => {
                r.pose = Some(s.pose);
                r.condition = Some(s.condition);
                if !d.rotary_as_datum {
                    r.flag = Some(
                        "rotary coordinates differ from the datum's: kept, not evaluated".into(),
                    );
                } else if k == datum {
                    r.errors = Some(SixErrors::default());
                    r.u_k2 = Some(SixErrors::default());
                    r.flag = Some("datum: errors zero by definition".into());
                } else {
                    r.errors = Some(dev.pose_errors(&s.pose, &commanded));
                    let legs: [f64; 6] = std::array::from_fn(|i| d.leg_u_k2_um[i].max(u0[i]));
                    match dev.error_uncertainty(&datum_pose, &s.pose, &legs) {
                        Ok(u) => r.u_k2 = Some(u),
                        Err(e) => r.flag = Some(format!("no uncertainty: {e}")),
                    }
                }
            }
        }
        out.push(r);
    }
    let evaluated: Vec<usize> = (0..out.len())
        .filter(|&k| out[k].errors.is_some())
        .collect();
    let positions: Vec<[f64; 3]> = evaluated
        .iter()
        .map(|&k| out[k].input.position_mm)
        .collect();
    let axis = axis_of_test(&positions, POSITION_TOLERANCE_MM);
    let names = axis.map_or_else(
        || ["dx", "dy", "dz", "ex", "ey", "ez"].map(String::from),
        |a| a.iso230_1_names(),
    );
    let mut lines = Vec::new();
    if let Some(a) = axis {
        let q: Vec<f64> = positions.iter().map(|p| p[a.index()]).collect();
        let mut removed = vec![[f64::NAN; 2]; evaluated.len()];
        for (slot, c) in a.straightness_indices().into_iter().enumerate() {
            let values: Vec<f64> = evaluated
                .iter()
                .map(|&k| out[k].errors.map_or(f64::NAN, |e| e.to_array()[c]))
                .collect();
            if let Ok(s) = remove_line(&q, &values) {
                for (j, v) in s.detrended_um.iter().enumerate() {
                    removed[j][slot] = *v;
                }
                lines.push((c, s.intercept_um, s.slope_um_per_mm));
            }
        }
        if lines.len() == 2 {
            for (j, &k) in evaluated.iter().enumerate() {
                out[k].straightness_line_removed_um = Some(removed[j]);
            }
        }
    }
    Ok(DeviceTestResult {
        axis,
        names,
        datum,
        dwells: out,
        lines,
    })
}

/// The direction of the sweep dwell `i` belongs to, given every dwell's approach along the
/// moved axis: its approach, or for a dwell approached from rest (the datum, a run's start) the
/// next dwell's, else the previous one's; 0 when no dwell moved.
pub fn sweep_direction(approach: &[i8], i: usize) -> i8 {
    let next = approach[i..].iter().copied().find(|&a| a != 0);
    let previous = || approach[..i].iter().rev().copied().find(|&a| a != 0);
    next.or_else(previous).unwrap_or(0)
}

/// ISO 230-2 on the positioning error of the moved axis (EXX for X) over the evaluated dwells:
/// per station, the runs' values approached moving + (↑) and − (↓), a dwell from rest joining
/// its sweep ([`sweep_direction`]). `None` when no single axis moved.
pub fn positioning_iso230_2(r: &DeviceTestResult) -> Option<Result<Iso230_2, Iso230Error>> {
    let k = r.axis?.index();
    let approach: Vec<i8> = r.dwells.iter().map(|d| d.input.approach[k]).collect();
    let mut targets: Vec<TargetDeviations> = Vec::new();
    for (i, d) in r.dwells.iter().enumerate() {
        let Some(e) = d.errors else { continue };
        let x = d.input.position_mm[k];
        let at = match targets
            .iter()
            .position(|t| (t.position_mm - x).abs() < POSITION_TOLERANCE_MM)
        {
            Some(at) => at,
            None => {
                targets.push(TargetDeviations {
                    position_mm: x,
                    up_um: Vec::new(),
                    down_um: Vec::new(),
                });
                targets.len() - 1
            }
        };
        let value = e.to_array()[k];
        match sweep_direction(&approach, i) {
            1 => targets[at].up_um.push(value),
            -1 => targets[at].down_um.push(value),
            _ => {}
        }
    }
    targets.sort_by(|a, b| a.position_mm.total_cmp(&b.position_mm));
    Some(crate::iso230_2::evaluate(&targets))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hexapod::tests::example;

    #[test]
    fn errors_applied_to_the_commanded_poses_are_recovered_with_their_names() {
        let device = example();
        let c0 = [400.0, 300.0, -200.0];
        let truth = |q: f64| {
            let s = (q - 400.0) / 60.0;
            SixErrors::from_array([3.0 * s, 2.0 * s * s, -s, 10.0 * s, -5.0 * s * s, 8.0 * s])
        };
        let positions: Vec<[f64; 3]> = (0..7)
            .map(|k| [400.0 + 10.0 * k as f64, 300.0, -200.0])
            .collect();
        let dwells: Vec<DwellInput> = positions
            .iter()
            .enumerate()
            .map(|(k, p)| DwellInput {
                station: k as i64 + 1,
                run: Some(1),
                position_mm: *p,
                rotary_as_datum: true,
                approach: [1, 0, 0],
                ring_temperature_c: 20.0,
                leg_u_k2_um: [0.5; 6],
            })
            .collect();
        let nominal = device.nominal_pose;
        let lengths = |k: usize, _tilts: &[f64; 6]| {
            let cmd = device.commanded_pose(&nominal, c0, positions[k]);
            Some(device.leg_lengths_mm(&device.apply_errors(&cmd, &truth(positions[k][0]))))
        };
        let r = evaluate(&device, 20.0, &dwells, 0, lengths).unwrap();
        assert_eq!(r.axis, Some(Axis::X));
        assert_eq!(r.names[0], "EXX");
        for d in &r.dwells {
            let e = d.errors.unwrap().to_array();
            let t = truth(d.input.position_mm[0]).to_array();
            for c in 0..6 {
                assert!((e[c] - t[c]).abs() < 1e-6, "{c}: {e:?} vs {t:?}");
            }
            if d.input.station > 1 {
                assert!(d.u_k2.unwrap().dx_um > 0.0);
            }
            // EYX is a parabola: its line removed leaves a parabola of zero mean.
            assert!(d.straightness_line_removed_um.is_some());
        }
        assert_eq!(r.lines.len(), 2);
        // One run: ISO 230-2 needs a standard deviation per target, so it says why not.
        assert!(matches!(
            positioning_iso230_2(&r),
            Some(Err(Iso230Error::TooFewRuns { runs: 1, .. }))
        ));
    }

    #[test]
    fn a_dwell_from_rest_joins_the_sweep_it_starts_or_ends() {
        let approach = [0, 1, 1, 0, -1, -1, 0];
        let d: Vec<i8> = (0..approach.len())
            .map(|i| sweep_direction(&approach, i))
            .collect();
        assert_eq!(d, [1, 1, 1, -1, -1, -1, -1]);
        assert_eq!(sweep_direction(&[0, 0], 1), 0);
    }
}
