//! `device.json` and `device_errors.parquet`: what the device stage produced
//! (`docs/spec/device-format.md`): per dwell the station, the commanded position, the pose, the
//! six errors with their ISO 230-1 names and U (k = 2), straightness raw and with its
//! least-squares line removed, and the flags; the inputs' hashes and the model's terms.

use serde::Serialize;

use crate::io;
use crate::pipeline::{DeviceStage, RunResults};
use dbbcal_machine::iso230_2::{Iso230Error, Iso230_2};

/// One error component at a dwell.
#[derive(Debug, Serialize)]
pub(crate) struct Component {
    pub(crate) name: String,
    pub(crate) value: f64,
    pub(crate) u_k2: Option<f64>,
    pub(crate) unit: &'static str,
}

/// One dwell.
#[derive(Debug, Serialize)]
pub(crate) struct DwellRecord {
    pub(crate) station: i64,
    pub(crate) run: Option<i64>,
    pub(crate) from: String,
    pub(crate) to: Option<String>,
    pub(crate) commanded_mm: [f64; 3],
    pub(crate) approach: [i8; 3],
    pub(crate) ring_temperature_c: f64,
    pub(crate) leg_samples: [usize; 6],
    pub(crate) leg_lengths_mm: Option<[f64; 6]>,
    pub(crate) leg_tilts_deg: Option<[f64; 6]>,
    pub(crate) leg_u_k2_um: [f64; 6],
    pub(crate) tilt_passes: usize,
    /// Measured pose of P in B: x, y, z mm, rx, ry, rz degrees.
    pub(crate) pose: Option<[f64; 6]>,
    pub(crate) commanded_pose: Option<[f64; 6]>,
    pub(crate) condition_number: Option<f64>,
    pub(crate) errors: Vec<Component>,
    /// The two straightness errors with the least-squares line removed, µm.
    pub(crate) straightness_line_removed: Vec<Component>,
    pub(crate) flag: Option<String>,
}

/// `device.json`.
#[derive(Debug, Serialize)]
pub(crate) struct DeviceRecord<'a> {
    pub(crate) campaign: &'a str,
    pub(crate) device: &'a str,
    pub(crate) kind: &'static str,
    pub(crate) error_sign: &'static str,
    pub(crate) frame: &'static str,
    pub(crate) axis: Option<char>,
    pub(crate) names: Vec<String>,
    pub(crate) datum_station: Option<i64>,
    pub(crate) reference_mm: Option<[f64; 3]>,
    pub(crate) tool_point_mm: [f64; 3],
    pub(crate) leg_bars: &'a [Vec<String>],
    /// How each quantity was obtained (the model's terms).
    pub(crate) model: Vec<&'static str>,
    /// The straightness lines removed: error name, intercept µm, slope µm/mm.
    pub(crate) straightness_lines: Vec<(String, f64, f64)>,
    pub(crate) dwells: Vec<DwellRecord>,
    pub(crate) not_evaluated: Option<String>,
    /// ISO 230-2 on the positioning error over the runs, or why not.
    pub(crate) iso230_2: Option<super::axis::IsoRecord>,
    pub(crate) iso230_2_missing: Option<String>,
    /// The loop on the legs across repeated dwells (`dbbcal_machine::device_study`).
    #[serde(rename = "loop")]
    pub(crate) device_loop: Option<LoopRecord>,
    /// The controller tables asked for (`[tables]`): written (file, sign, unit) or refused (why).
    pub(crate) tables: &'a [super::axis_tables::TableRecord],
    pub(crate) inputs: Vec<super::inputs::InputRecord>,
}

/// The device's loop in `device.json`.
#[derive(Debug, Serialize)]
pub(crate) struct LoopRecord {
    /// Why the loop could not run.
    pub(crate) not_run: Option<String>,
    pub(crate) rms_um: Option<f64>,
    pub(crate) rms_per_leg_um: Option<[f64; 6]>,
    pub(crate) station_groups: Option<usize>,
    pub(crate) effects: Vec<LoopEffect>,
    pub(crate) candidates: Vec<LoopCandidate>,
    pub(crate) ledger: Vec<(Option<&'static str>, f64, f64)>,
    pub(crate) proposal: Option<&'static str>,
    pub(crate) not_identifiable: Vec<(&'static str, &'static str)>,
}

#[derive(Debug, Serialize)]
pub(crate) struct LoopEffect {
    pub(crate) effect: &'static str,
    pub(crate) physics: &'static str,
    /// Name, value, U (k = 2).
    pub(crate) parameters: Vec<(String, f64, f64)>,
}

#[derive(Debug, Serialize)]
pub(crate) struct LoopCandidate {
    pub(crate) effect: &'static str,
    pub(crate) delta_bic: f64,
    pub(crate) rms_um: f64,
    pub(crate) size_um: f64,
    pub(crate) detail: Option<String>,
}

/// ISO 230-2 on the positioning error (its name and the statistics), or why not.
pub(crate) fn positioning_iso(s: &DeviceStage) -> Option<Result<(String, Iso230_2), Iso230Error>> {
    let t = s.outcome.as_ref().ok()?;
    let name = t.names[t.axis?.index()].clone();
    Some(dbbcal_machine::device_test::positioning_iso230_2(t)?.map(|i| (name, i)))
}

fn loop_record(s: &DeviceStage) -> Option<LoopRecord> {
    let empty = |not_run: String| LoopRecord {
        not_run: Some(not_run),
        rms_um: None,
        rms_per_leg_um: None,
        station_groups: None,
        effects: Vec::new(),
        candidates: Vec::new(),
        ledger: Vec::new(),
        proposal: None,
        not_identifiable: Vec::new(),
    };
    Some(match s.study.as_ref()? {
        Err(e) => empty(e.to_string()),
        Ok(st) => LoopRecord {
            not_run: None,
            rms_um: Some(st.rms_um),
            rms_per_leg_um: Some(st.rms_per_leg_um),
            station_groups: Some(st.groups),
            effects: st
                .effects
                .iter()
                .map(|e| LoopEffect {
                    effect: e.effect.name(),
                    physics: e.effect.physics(),
                    parameters: e.parameters.clone(),
                })
                .collect(),
            candidates: st
                .candidates
                .iter()
                .map(|c| LoopCandidate {
                    effect: c.effect.name(),
                    delta_bic: c.delta_bic,
                    rms_um: c.rms_um,
                    size_um: c.size_um,
                    detail: c.detail.clone(),
                })
                .collect(),
            ledger: st
                .ledger
                .iter()
                .map(|l| (l.effect.map(|e| e.name()), l.rms_um, l.delta_bic))
                .collect(),
            proposal: st.proposal.map(|e| e.name()),
            not_identifiable: st.unseen.clone(),
        },
    })
}

const UNITS: [&str; 6] = ["µm", "µm", "µm", "µrad", "µrad", "µrad"];

const MODEL: [&str; 7] = [
    "leg length: mean over the dwell of D(n - e, A) of the bar in the leg (compensate stage), A the leg's tilt from its joint centres at the pose",
    "leg U (k=2): the compensated distance's budget (calibration lengths, resolution, calibration function, thermal terms)",
    "rings: joint centres scaled by 1 + cte (T - T0) about each ring's centroid, T the device's sensor over the dwell, else the mean air temperature",
    "pose: forward kinematics by Newton from nominal_pose; near-singular poses flagged, not evaluated",
    "commanded pose: R_cmd = R0, t_cmd = t0 + R_MB^T (c - c0) from the datum dwell",
    "errors: measured - commanded at the tool point, in M's axes (delta µm, epsilon µrad)",
    "U (k=2): first order, legs' U independent between the dwell and the datum, joints' u shared",
];

/// The device stage's record, if it ran.
pub(crate) fn device_record<'a>(results: &'a RunResults) -> Option<DeviceRecord<'a>> {
    let s = results.device.as_ref()?;
    let names: Vec<String> = match &s.outcome {
        Ok(t) => t.names.to_vec(),
        Err(_) => ["dx", "dy", "dz", "ex", "ey", "ez"]
            .map(String::from)
            .to_vec(),
    };
    let (axis, datum_station, lines, dwells) = match &s.outcome {
        Ok(t) => (
            t.axis.map(|a| a.letter()),
            s.dwells.get(t.datum).map(|d| d.station),
            t.lines
                .iter()
                .map(|(c, i, sl)| (names[*c].clone(), *i, *sl))
                .collect(),
            dwell_records(s, &names),
        ),
        Err(_) => (None, None, Vec::new(), Vec::new()),
    };
    let iso = positioning_iso(s);
    Some(DeviceRecord {
        campaign: &results.campaign.id,
        device: &s.device.id,
        kind: "hexapod",
        error_sign: "error = measured - commanded",
        frame: "M (the machine's axes); translations at tool_point_mm",
        axis,
        names,
        datum_station,
        reference_mm: s.device.reference_mm,
        tool_point_mm: s.device.tool_point_mm,
        leg_bars: &s.leg_bars,
        model: MODEL.to_vec(),
        straightness_lines: lines,
        dwells,
        not_evaluated: s.outcome.as_ref().err().map(ToString::to_string),
        iso230_2: iso
            .as_ref()
            .and_then(|i| i.as_ref().ok())
            .map(|(n, i)| super::axis::IsoRecord::new(n, i)),
        iso230_2_missing: iso.and_then(|i| i.err()).map(|e| e.to_string()),
        device_loop: loop_record(s),
        tables: &s.tables,
        inputs: super::inputs::input_records(&results.inputs),
    })
}

fn dwell_records(s: &DeviceStage, names: &[String]) -> Vec<DwellRecord> {
    let Ok(t) = &s.outcome else {
        return Vec::new();
    };
    let straightness = t.axis.map(|a| a.straightness_indices());
    t.dwells
        .iter()
        .zip(&s.dwells)
        .zip(&s.samples)
        .map(|((r, d), n)| {
            let errors = match (r.errors, r.u_k2) {
                (Some(e), u) => {
                    let e = e.to_array();
                    let u = u.map(|u| u.to_array());
                    (0..6)
                        .map(|c| Component {
                            name: names[c].clone(),
                            value: e[c],
                            u_k2: u.map(|u| u[c]),
                            unit: UNITS[c],
                        })
                        .collect()
                }
                _ => Vec::new(),
            };
            let straightness_line_removed = match (r.straightness_line_removed_um, straightness) {
                (Some(v), Some(idx)) => (0..2)
                    .map(|j| Component {
                        name: names[idx[j]].clone(),
                        value: v[j],
                        u_k2: r.u_k2.map(|u| u.to_array()[idx[j]]),
                        unit: "µm",
                    })
                    .collect(),
                _ => Vec::new(),
            };
            DwellRecord {
                station: d.station,
                run: d.run,
                from: io::format_ns(d.from_ns),
                to: d.to_ns.map(io::format_ns),
                commanded_mm: d.position_mm,
                approach: d.approach,
                ring_temperature_c: r.input.ring_temperature_c,
                leg_samples: *n,
                leg_lengths_mm: r.leg_lengths_mm,
                leg_tilts_deg: r.leg_tilts_deg,
                leg_u_k2_um: r.input.leg_u_k2_um,
                tilt_passes: r.tilt_passes,
                pose: r.pose.map(|p| p.to_array()),
                commanded_pose: r.commanded.map(|p| p.to_array()),
                condition_number: r.condition,
                errors,
                straightness_line_removed,
                flag: r.flag.clone(),
            }
        })
        .collect()
}

/// `device_errors.parquet`: one row per dwell and error component.
pub(crate) fn device_errors_table(results: &RunResults) -> Option<io::Table> {
    let s = results.device.as_ref()?;
    let t = s.outcome.as_ref().ok();
    let (mut station, mut run, mut name, mut unit) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut x, mut y, mut z) = (Vec::new(), Vec::new(), Vec::new());
    let (mut value, mut u, mut detrended, mut flag) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let straightness = t.and_then(|t| t.axis).map(|a| a.straightness_indices());
    for r in t.map(|t| t.dwells.as_slice()).unwrap_or_default() {
        let Some(e) = r.errors else { continue };
        let e = e.to_array();
        let uk = r.u_k2.map(|u| u.to_array());
        for c in 0..6 {
            station.push(r.input.station);
            run.push(r.input.run);
            name.push(t.map_or(String::new(), |t| t.names[c].clone()));
            unit.push(UNITS[c].to_string());
            x.push(r.input.position_mm[0]);
            y.push(r.input.position_mm[1]);
            z.push(r.input.position_mm[2]);
            value.push(e[c]);
            u.push(uk.map(|u| u[c]));
            let slot = straightness.and_then(|idx| idx.iter().position(|&i| i == c));
            detrended.push(slot.and_then(|j| r.straightness_line_removed_um.map(|v| v[j])));
            flag.push(r.flag.clone().unwrap_or_default());
        }
    }
    use io::Column::*;
    Some(io::Table {
        columns: vec![
            (
                "campaign".into(),
                Str(vec![results.campaign.id.clone(); station.len()]),
            ),
            (
                "device".into(),
                Str(vec![s.device.id.clone(); station.len()]),
            ),
            ("station".into(), I64(station)),
            ("run".into(), OptI64(run)),
            ("x_mm".into(), F64(x)),
            ("y_mm".into(), F64(y)),
            ("z_mm".into(), F64(z)),
            ("name".into(), Str(name)),
            ("unit".into(), Str(unit)),
            ("value".into(), F64(value)),
            ("u_k2".into(), OptF64(u)),
            ("line_removed".into(), OptF64(detrended)),
            ("flag".into(), Str(flag)),
        ],
    })
}
