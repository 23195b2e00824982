//! The `device` stage's adapter (`docs/spec/device-format.md`): from the compensated working
//! bars in a hexapod's legs and the `positions` log to the six errors of the machine axis, dwell
//! by dwell. The rules of the log live in `dbbcal_core::positions`, the kinematics and the test
//! in `dbbcal_machine` (`hexapod`, `device_test`); this file only gathers their inputs.
//!
//! - A leg's length in a dwell is the mean, over the bar's compensated readings inside the dwell
//!   (one second plus one bin in from both ends, so that no bin reaches into a move), of
//!   `D(n − e, A)` at the leg's own tilt `A` (from its joint centres at the pose: first the
//!   nominal pose's, then the pose found; `device_test`).
//! - A leg's U (k = 2) is the compensated distance's budget (`acceptance::compensated_u_k2_um`:
//!   calibration lengths, resolution, calibration function, thermal terms).
//! - The rings' temperature is the mean of the device's `sensor` over the dwell (its last reading
//!   before the dwell when none falls inside), else the mean air temperature over the dwell (the
//!   campaign's air history).

use dbbcal_core::campaign::{Device, Place};
use dbbcal_core::positions::{self, Dwell, PositionsLog, STATION_TOLERANCE_DEG};
use dbbcal_core::series::InputFile;
use dbbcal_machine::device_study::{self, DeviceStudy, DeviceStudyError, DwellLegs};
use dbbcal_machine::device_test::{self, DeviceTestError, DeviceTestResult, DwellInput};
use dbbcal_machine::hexapod::Hexapod;
use dbbcal_machine::pose::Pose;

use super::*;

/// The device stage's result.
#[derive(Debug, Clone)]
pub struct DeviceStage {
    /// The device evaluated.
    pub device: Device,
    /// Its dwells, in time order.
    pub dwells: Vec<Dwell>,
    /// Per leg (1–6), the bar(s) it carried during the test.
    pub leg_bars: Vec<Vec<String>>,
    /// Per dwell, per leg: compensated readings averaged.
    pub samples: Vec<[usize; 6]>,
    /// The test, or why it could not be evaluated at all; with the model's effects removed
    /// from the legs when `[device] effects` names any.
    pub outcome: Result<DeviceTestResult, DeviceError>,
    /// The device's loop on the legs across repeated dwells, or why it cannot run.
    pub study: Option<Result<DeviceStudy, DeviceStudyError>>,
    /// The `positions` files read, with their hashes.
    pub positions_files: Vec<InputFile>,
    /// The controller tables `[tables]` asks for, from the six errors at each station (the
    /// same formats as an axis run's: `output::axis_tables::device_tables`).
    pub(crate) tables: Vec<crate::output::axis_tables::TableRecord>,
}

/// Why the device test cannot be evaluated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DeviceError {
    /// The campaign declares no device.
    #[error("campaign.toml has no [[device]] table: the device stage needs one")]
    NoDevice,
    /// No dwell at the declared datum.
    #[error("no dwell of device {device:?} in positions is at reference_mm = {reference_mm:?}")]
    NoDwellAtReference {
        /// The device's id.
        device: String,
        /// Its `reference_mm`.
        reference_mm: [f64; 3],
    },
    /// No dwell of the device at all.
    #[error("positions has no dwell of device {device:?}")]
    NoDwell {
        /// The device's id.
        device: String,
    },
    /// The test could not be evaluated.
    #[error(transparent)]
    Test(#[from] DeviceTestError),
}

/// The logs of the sensors the devices name (`[[device]] sensor`), for their rings' temperature.
pub(crate) fn sensor_logs(
    campaign: &crate::campaign::Campaign,
    sensors: &std::collections::BTreeMap<String, crate::series::SensorLog>,
) -> std::collections::BTreeMap<String, crate::series::SensorLog> {
    campaign
        .devices
        .iter()
        .filter_map(|d| d.sensor.as_ref())
        .filter_map(|id| Some((id.clone(), sensors.get(id)?.clone())))
        .collect()
}

/// Mean of `log` over the dwell, else its last reading before it.
fn sensor_over(log: &crate::series::SensorLog, d: &Dwell) -> Option<f64> {
    let lo = log.time_ns.partition_point(|&t| t < d.from_ns);
    let hi = d
        .to_ns
        .map_or(log.time_ns.len(), |e| {
            log.time_ns.partition_point(|&t| t < e)
        })
        .max(lo);
    let inside: Vec<f64> = log.celsius[lo..hi]
        .iter()
        .copied()
        .filter(|c| c.is_finite())
        .collect();
    if inside.is_empty() {
        log.celsius[..lo]
            .iter()
            .rev()
            .copied()
            .find(|c| c.is_finite())
    } else {
        Some(inside.iter().sum::<f64>() / inside.len() as f64)
    }
}

pub(crate) fn hexapod_of(d: &Device) -> Hexapod {
    Hexapod {
        base_mm: d.base_mm,
        platform_mm: d.platform_mm,
        u_base_um: d.u_base_um,
        u_platform_um: d.u_platform_um,
        nominal_pose: Pose::from_array(d.nominal_pose),
        tool_point_mm: d.tool_point_mm,
        base_orientation_deg: d.base_orientation_deg,
        up: d.up,
        cte_ppm_per_k: d.cte_ppm_per_k,
    }
}

/// Run the device stage on `results` (compensate must have run) with the `positions` log.
pub fn run_device(
    plan: &RunPlan,
    results: &mut RunResults,
    log: &PositionsLog,
    positions_files: Vec<InputFile>,
) -> Result<(), DeviceError> {
    let named = log.devices();
    let device = results
        .campaign
        .devices
        .iter()
        .find(|d| named.contains(&d.id))
        .or_else(|| results.campaign.devices.first())
        .cloned()
        .ok_or(DeviceError::NoDevice)?;
    let dwells = log.dwells(&device.id);
    let mut stage = evaluate_device(plan, results, device, dwells, positions_files);
    if let Ok(test) = &stage.outcome {
        stage.tables = crate::output::axis_tables::device_tables(test, &plan.tables);
    }
    results.device = Some(stage);
    Ok(())
}

fn evaluate_device(
    plan: &RunPlan,
    r: &RunResults,
    device: Device,
    dwells: Vec<Dwell>,
    positions_files: Vec<InputFile>,
) -> DeviceStage {
    let t0_ns = r
        .campaign
        .mounts
        .iter()
        .map(|m| m.from_ns)
        .min()
        .unwrap_or(0);
    let margin_ns = ((plan.bin_s.max(0.0) + 1.0) * 1e9) as i64;
    let (cals, comp) = (
        r.calibration
            .as_ref()
            .map(|c| c.ok.as_slice())
            .unwrap_or_default(),
        r.compensation
            .as_ref()
            .map(|c| c.ok.as_slice())
            .unwrap_or_default(),
    );
    let options = crate::acceptance::AcceptanceOptions {
        tolerance_um: plan.acceptance.tolerance_um,
        u_temperature_k: plan.acceptance.u_temperature_k,
    };
    // Per leg: (bar, its mount interval) of every mount in that leg.
    let mut leg_bars = vec![Vec::new(); 6];
    // Per dwell, per leg: compensated readings (mm) and the leg's U (k = 2).
    let mut readings: Vec<[Vec<f64>; 6]> = vec![Default::default(); dwells.len()];
    let mut leg_u: Vec<[f64; 6]> = vec![[f64::NAN; 6]; dwells.len()];
    let mut calibration_of: Vec<[Option<&crate::calibrate::BarCalibration>; 6]> =
        vec![[None; 6]; dwells.len()];
    for m in &r.campaign.mounts {
        let (Place::Device(id), Some(leg)) = (&m.place, m.leg) else {
            continue;
        };
        if id != &device.id {
            continue;
        }
        let leg = leg as usize - 1;
        if !leg_bars[leg].contains(&m.bar) {
            leg_bars[leg].push(m.bar.clone());
        }
        let Some(cal) = cals.iter().find(|c| c.bar == m.bar) else {
            continue;
        };
        let resolution_nm = r.campaign.bar(&m.bar).map_or(0.0, |b| b.resolution_nm);
        for w in comp
            .iter()
            .filter(|w| w.bar == m.bar && w.length_mm.is_none())
        {
            let times: Vec<i64> = w
                .t_s
                .iter()
                .map(|t| t0_ns + (t * 1e9).round() as i64)
                .collect();
            let u = crate::acceptance::compensated_u_k2_um(w, cal, resolution_nm, &options);
            for (k, d) in dwells.iter().enumerate() {
                // A dwell still open at the log's end holds while the leg stays mounted
                // (`device-format.md`: a row states the position until the next row).
                let end = d.to_ns.unwrap_or(m.to_ns);
                if d.from_ns < m.from_ns || end > m.to_ns {
                    continue;
                }
                let lo = times.partition_point(|&t| t < d.from_ns.saturating_add(margin_ns));
                let hi = times.partition_point(|&t| t < end.saturating_sub(margin_ns));
                if hi > lo {
                    readings[k][leg].extend(&w.compensated_reading_mm[lo..hi]);
                    leg_u[k][leg] = u;
                    calibration_of[k][leg] = Some(cal);
                }
            }
        }
    }
    let samples: Vec<[usize; 6]> = readings
        .iter()
        .map(|legs| std::array::from_fn(|i| legs[i].len()))
        .collect();
    let device_reference_mm = device.reference_mm;
    let outcome = (|| -> Result<_, DeviceError> {
        let datum = positions::datum_index(&dwells, device.reference_mm).ok_or_else(|| {
            let device = device.id.clone();
            match device_reference_mm {
                Some(reference_mm) => DeviceError::NoDwellAtReference {
                    device,
                    reference_mm,
                },
                None => DeviceError::NoDwell { device },
            }
        })?;
        let datum_rotary = dwells[datum].rotary_deg;
        let ring_sensor = device
            .sensor
            .as_ref()
            .and_then(|id| r.device_sensors.get(id));
        let ring_c = |d: &Dwell| {
            if let Some(c) = ring_sensor.and_then(|log| sensor_over(log, d)) {
                return c;
            }
            let (a, b) = (
                (d.from_ns - t0_ns) as f64 * 1e-9,
                d.to_ns.map_or(f64::INFINITY, |e| (e - t0_ns) as f64 * 1e-9),
            );
            let h = &r.history;
            let inside: Vec<f64> = h
                .t_s
                .iter()
                .zip(&h.delta_c)
                .filter(|(t, _)| **t >= a && **t < b)
                .map(|(_, v)| *v)
                .collect();
            let mid = if b.is_finite() { 0.5 * (a + b) } else { a };
            let delta = if inside.is_empty() {
                dbbcal_core::signal::interpolate::within(&h.t_s, &h.delta_c, mid, f64::INFINITY)
                    .unwrap_or(0.0)
            } else {
                inside.iter().sum::<f64>() / inside.len() as f64
            };
            r.campaign.reference_temperature_c + delta
        };
        let inputs: Vec<DwellInput> = dwells
            .iter()
            .zip(&leg_u)
            .map(|(d, u)| DwellInput {
                station: d.station,
                run: d.run,
                position_mm: d.position_mm,
                rotary_as_datum: (0..3).all(|k| match (d.rotary_deg[k], datum_rotary[k]) {
                    (None, None) => true,
                    (Some(a), Some(b)) => (a - b).abs() <= STATION_TOLERANCE_DEG,
                    _ => false,
                }),
                approach: d.approach,
                ring_temperature_c: ring_c(d),
                leg_u_k2_um: u.map(|v| if v.is_finite() { v } else { 0.0 }),
            })
            .collect();
        let hexapod = hexapod_of(&device);
        let t_ref = r.campaign.reference_temperature_c;
        let leg_means = |k: usize, tilts: &[f64; 6]| -> Option<[f64; 6]> {
            let mut out = [0.0; 6];
            for leg in 0..6 {
                let cal = calibration_of[k][leg]?;
                let xs = &readings[k][leg];
                if xs.is_empty() {
                    return None;
                }
                out[leg] = xs
                    .iter()
                    .map(|x| cal.chosen.distance_mm(*x, tilts[leg]))
                    .sum::<f64>()
                    / xs.len() as f64;
            }
            Some(out)
        };
        let first = device_test::evaluate(&hexapod, t_ref, &inputs, datum, leg_means)?;
        let legs = study_inputs(&hexapod, t_ref, &dwells, &first);
        let study = device_study::study(
            &legs.iter().map(|(_, d)| d.clone()).collect::<Vec<_>>(),
            &plan.device,
        );
        let corrections: Vec<[f64; 6]> = match &study {
            Ok(s) if !s.effects.is_empty() => {
                let mut c = vec![[0.0; 6]; dwells.len()];
                for ((k, _), corr) in legs.iter().zip(&s.corrections_um) {
                    c[*k] = *corr;
                }
                c
            }
            _ => return Ok((first, Some(study))),
        };
        let corrected = device_test::evaluate(&hexapod, t_ref, &inputs, datum, |k, tilts| {
            let l = leg_means(k, tilts)?;
            Some(std::array::from_fn(|i| l[i] - corrections[k][i] * 1e-3))
        })?;
        Ok((corrected, Some(study)))
    })();
    let (outcome, study) = match outcome {
        Ok((test, study)) => (Ok(test), study),
        Err(e) => (Err(e), None),
    };
    DeviceStage {
        device,
        dwells,
        leg_bars,
        samples,
        outcome,
        study,
        positions_files,
        tables: Vec::new(),
    }
}

/// The evaluated dwells of a first pass as the loop's input, each with its index in `dwells`:
/// hours since the datum's start, (station, approach along the moved axis), lengths, the rings'
/// excess over T0 and the sensitivities at the pose found.
fn study_inputs(
    hexapod: &Hexapod,
    t_ref: f64,
    dwells: &[Dwell],
    test: &DeviceTestResult,
) -> Vec<(usize, DwellLegs)> {
    let axis = test.axis.map_or(0, |a| a.index());
    let t0_ns = dwells.get(test.datum).map_or(0, |d| d.from_ns);
    test.dwells
        .iter()
        .enumerate()
        .filter(|(_, d)| d.errors.is_some())
        .filter_map(|(k, d)| {
            let (pose, lengths) = (d.pose?, d.leg_lengths_mm?);
            let at = hexapod.at_temperature(d.input.ring_temperature_c, t_ref);
            let excess_k = d.input.ring_temperature_c - t_ref;
            let mut legs = DwellLegs::at_pose(
                &at,
                &pose,
                (dwells[k].from_ns - t0_ns) as f64 / 3600e9,
                (d.input.station, d.input.approach[axis]),
                lengths,
                excess_k,
            );
            // The declared expansion is in the model: the legs really grow with the rings, so
            // what repeats compare is the lengths without it (`body_expansion` is only what the
            // declaration misses). Found by the second simulator (tests/e2e/device_foreign.rs):
            // with 11.5 ppm/K declared and right, the loop proposed `body_expansion`.
            for (l, strain) in legs.lengths_mm.iter_mut().zip(legs.strain_um_per_ppm) {
                *l -= 1e-3 * hexapod.cte_ppm_per_k * excess_k * strain;
            }
            Some((k, legs))
        })
        .collect()
}
