//! `roll.json`, `roll_stations.parquet` and `roll_dwells.parquet`: a `roll` campaign's results
//! as files. The record is this module's own (a field renamed in `dbbcal-machine` changes
//! nothing here).

use serde::Serialize;

use crate::io::{Column, Table};
use dbbcal_core::series::InputFile;

use super::kind_record::KindRecordHead;
use dbbcal_machine::roll::RollStudy;

/// A number or `null` (NaN: not determined).
fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// `roll.json`.
#[derive(Debug, Serialize)]
pub(crate) struct RollRecord {
    #[serde(flatten)]
    head: KindRecordHead,
    /// εx in µrad, right-handed about R's +x (frame R of docs/spec/machine-formats.md), datum
    /// εx = 0 at station 0; the roll error of the axis = sign · εx.
    roll_error: String,
    roll_error_sign: i8,
    samples: usize,
    samples_in_dwells: usize,
    dwells_from: &'static str,
    passes_from: &'static str,
    resolution_um: [f64; 4],
    resolution_from: &'static str,
    level_datum: bool,
    mean_step_mm: Option<f64>,
    scale_u_relative: f64,
    chi2: f64,
    dof: usize,
    u_scale: f64,
    stations: Vec<StationRecord>,
    passes: Vec<PassRecord>,
    levels: Vec<LevelRecord>,
    effects: Vec<EffectRecord>,
    implausible: Option<ImplausibleRecord>,
    diagnosis: DiagnosisRecord,
}

#[derive(Debug, Serialize)]
struct StationRecord {
    station: usize,
    x_mm: Option<f64>,
    roll_urad: Option<f64>,
    u_noise_urad: Option<f64>,
    u_k2_urad: Option<f64>,
    roll_error_urad: Option<f64>,
}

#[derive(Debug, Serialize)]
struct PassRecord {
    direction: i8,
    stations: Vec<usize>,
    roll_eq10_urad: Vec<Option<f64>>,
    rms_residual_urad: f64,
}

#[derive(Debug, Serialize)]
struct LevelRecord {
    station: usize,
    roll_urad: f64,
    residual_urad: f64,
}

#[derive(Debug, Serialize)]
struct EffectRecord {
    effect: &'static str,
    physics: &'static str,
    parameter: &'static str,
    value: Option<f64>,
    u_k2: Option<f64>,
}

#[derive(Debug, Serialize)]
struct ImplausibleRecord {
    max_abs_urad: f64,
    limit_urad: f64,
    slope_urad_per_station: f64,
    equivalent_offset_um: f64,
}

#[derive(Debug, Serialize)]
struct DiagnosisRecord {
    missing: Option<&'static str>,
    missing_physics: Option<&'static str>,
    because: String,
    candidates: Vec<CandidateRecord>,
    ledger: Vec<LedgerRecord>,
    not_identifiable: Vec<UnseenRecord>,
}

#[derive(Debug, Serialize)]
struct CandidateRecord {
    effect: &'static str,
    physics: &'static str,
    /// `null`: not identifiable with these data.
    delta_bic: Option<f64>,
    chi2: f64,
}

#[derive(Debug, Serialize)]
struct LedgerRecord {
    effect: Option<&'static str>,
    delta_bic: f64,
    chi2: f64,
}

#[derive(Debug, Serialize)]
struct UnseenRecord {
    effect: &'static str,
    becomes: String,
}

impl RollRecord {
    /// The record of `s` for campaign `campaign`, run by `pipeline` (name, sha256), from `inputs`.
    pub(crate) fn new(
        campaign: &str,
        pipeline: (&str, &str),
        inputs: &[InputFile],
        s: &RollStudy,
    ) -> RollRecord {
        let d = &s.diagnosis;
        RollRecord {
            head: KindRecordHead::new("roll", campaign, pipeline, inputs),
            roll_error: s.roll_error_name.clone(),
            roll_error_sign: s.roll_error_sign,
            samples: s.samples.0,
            samples_in_dwells: s.samples.1,
            dwells_from: s.dwell_source,
            passes_from: s.pass_source,
            resolution_um: s.resolution_um,
            resolution_from: s.resolution_source,
            level_datum: s.level_datum,
            mean_step_mm: finite(s.step_mm),
            scale_u_relative: s.scale_u,
            chi2: s.chi2.0,
            dof: s.chi2.1,
            u_scale: s.chi2.2,
            stations: s
                .stations
                .iter()
                .map(|st| StationRecord {
                    station: st.station,
                    x_mm: finite(st.x_mm),
                    roll_urad: finite(st.roll_urad),
                    u_noise_urad: finite(st.u_noise_urad),
                    u_k2_urad: finite(st.u_k2_urad),
                    roll_error_urad: finite(st.roll_error_urad),
                })
                .collect(),
            passes: s
                .passes
                .iter()
                .map(|p| PassRecord {
                    direction: p.direction,
                    stations: p.stations.clone(),
                    roll_eq10_urad: p.roll_urad.iter().copied().map(finite).collect(),
                    rms_residual_urad: p.rms_residual_urad,
                })
                .collect(),
            levels: s
                .levels
                .iter()
                .map(|l| LevelRecord {
                    station: l.station,
                    roll_urad: l.roll_urad,
                    residual_urad: l.residual_urad,
                })
                .collect(),
            effects: s
                .effects
                .iter()
                .map(|e| EffectRecord {
                    effect: e.effect.name(),
                    physics: e.effect.physics(),
                    parameter: e.effect.parameter_name(),
                    value: finite(e.value.0),
                    u_k2: finite(e.value.1),
                })
                .collect(),
            implausible: s.implausible.as_ref().map(|i| ImplausibleRecord {
                max_abs_urad: i.max_abs_urad,
                limit_urad: i.limit_urad,
                slope_urad_per_station: i.slope_urad_per_station,
                equivalent_offset_um: i.equivalent_offset_um,
            }),
            diagnosis: DiagnosisRecord {
                missing: d.missing.map(|e| e.name()),
                missing_physics: d.missing.map(|e| e.physics()),
                because: d.missing_because.clone(),
                candidates: d
                    .candidates
                    .iter()
                    .map(|c| CandidateRecord {
                        effect: c.effect.name(),
                        physics: c.effect.physics(),
                        delta_bic: c.delta_bic,
                        chi2: c.chi2,
                    })
                    .collect(),
                ledger: d
                    .ledger
                    .iter()
                    .map(|l| LedgerRecord {
                        effect: l.effect.map(|e| e.name()),
                        delta_bic: l.delta_bic,
                        chi2: l.chi2,
                    })
                    .collect(),
                not_identifiable: d
                    .unseen
                    .iter()
                    .map(|u| UnseenRecord {
                        effect: u.effect,
                        becomes: u.becomes.clone(),
                    })
                    .collect(),
            },
        }
    }
}

/// `roll_stations.parquet`: one row a station (εx, its u and U, the axis's roll error; null
/// where not determined).
pub(crate) fn stations_table(s: &RollStudy) -> Table {
    let col = |f: &dyn Fn(&dbbcal_machine::roll::StationResult) -> f64| {
        Column::OptF64(s.stations.iter().map(|st| finite(f(st))).collect())
    };
    Table::new()
        .with(
            "station",
            Column::I64(s.stations.iter().map(|st| st.station as i64).collect()),
        )
        .with("x_mm", col(&|st| st.x_mm))
        .with("ex_urad", col(&|st| st.roll_urad))
        .with("u_noise_urad", col(&|st| st.u_noise_urad))
        .with("u_k2_urad", col(&|st| st.u_k2_urad))
        .with(
            format!("{}_urad", s.roll_error_name),
            col(&|st| st.roll_error_urad),
        )
}

/// `roll_dwells.parquet`: one row a dwell (pass, station, x, span, samples, the four means and
/// their u, µm).
pub(crate) fn dwells_table(s: &RollStudy) -> Table {
    let d = &s.dwells;
    let mut t = Table::new()
        .with(
            "pass",
            Column::I64(d.iter().map(|w| w.pass as i64 + 1).collect()),
        )
        .with(
            "station",
            Column::I64(d.iter().map(|w| w.station as i64).collect()),
        )
        .with("x_mm", Column::F64(d.iter().map(|w| w.x_mm).collect()))
        .with(
            "start_s",
            Column::F64(d.iter().map(|w| w.span_s.0).collect()),
        )
        .with("end_s", Column::F64(d.iter().map(|w| w.span_s.1).collect()))
        .with(
            "samples",
            Column::I64(d.iter().map(|w| w.samples as i64).collect()),
        );
    for (k, p) in ["a", "b", "c", "d"].iter().enumerate() {
        t = t
            .with(
                format!("m_{p}_um"),
                Column::F64(d.iter().map(|w| w.mean_um[k]).collect()),
            )
            .with(
                format!("u_{p}_um"),
                Column::F64(d.iter().map(|w| w.u_um[k]).collect()),
            )
            .with(
                format!("tau_{p}"),
                Column::F64(d.iter().map(|w| w.tau[k]).collect()),
            );
    }
    t
}
