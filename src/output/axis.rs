//! `axis.json` and `axis_errors.parquet`: an `axis` campaign's results as files. The record
//! is this module's own (a field renamed in `dbbcal-machine` changes nothing here).

use serde::Serialize;

use crate::io::{Column, Table};
use dbbcal_core::series::InputFile;

use super::kind_record::KindRecordHead;
use dbbcal_machine::axis_study::AxisStudy;

use super::axis_tables::TableRecord;

/// A number or `null` (NaN: not determined).
fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// `axis.json`.
#[derive(Debug, Serialize)]
pub(crate) struct AxisRecord {
    #[serde(flatten)]
    head: KindRecordHead,
    axis: String,
    /// ISO 230-1 names, δx … εz; δ in µm, ε in µrad; error = measured − commanded.
    names: Vec<String>,
    datum: DatumRecord,
    rank: usize,
    lost: Vec<String>,
    model: ModelRecord,
    targets: Vec<TargetRecord>,
    iso230_2: Option<IsoRecord>,
    iso230_2_missing: Option<String>,
    straightness: Vec<StraightnessRecord>,
    point_choice: Vec<PointRecord>,
    residuals: Vec<ResidualRecord>,
    diagnosis: DiagnosisRecord,
    /// The controller tables asked for: written (file, sign, unit) or refused (why).
    tables: Vec<TableRecord>,
}

#[derive(Debug, Serialize)]
struct DatumRecord {
    target_mm: f64,
    direction: i8,
}

#[derive(Debug, Serialize)]
struct ModelRecord {
    effects: Vec<EffectRecord>,
    sigma_along_um: f64,
    sigma_lateral_um: f64,
    rms_along_um: f64,
    rms_lateral_um: f64,
    readings: usize,
}

#[derive(Debug, Serialize)]
struct EffectRecord {
    effect: &'static str,
    physics: &'static str,
    parameters: Vec<ParameterRecord>,
}

#[derive(Debug, Serialize)]
struct ParameterRecord {
    name: String,
    value: Option<f64>,
    u_k2: Option<f64>,
}

#[derive(Debug, Serialize)]
struct TargetRecord {
    target_mm: f64,
    direction: i8,
    /// By name: value and U (k = 2); `null` where not determined.
    errors: Vec<(String, Option<f64>, Option<f64>)>,
}

#[derive(Debug, Serialize)]
pub(crate) struct IsoRecord {
    error: String,
    accuracy_a_um: Option<f64>,
    reversal_b_um: Option<f64>,
    repeatability_r_um: Option<f64>,
    systematic_e_um: Option<f64>,
    mean_range_m_um: Option<f64>,
    undefined: Vec<String>,
}

impl IsoRecord {
    /// ISO 230-2's quantities of error `name` (the positioning error of an axis).
    pub(crate) fn new(name: &str, i: &dbbcal_machine::iso230_2::Iso230_2) -> IsoRecord {
        IsoRecord {
            error: name.to_string(),
            accuracy_a_um: i.accuracy_a_um,
            reversal_b_um: i.reversal_b_um,
            repeatability_r_um: i.repeatability_r_um,
            systematic_e_um: i.systematic_e_um,
            mean_range_m_um: i.mean_range_m_um,
            undefined: i.undefined.clone(),
        }
    }
}

#[derive(Debug, Serialize)]
struct StraightnessRecord {
    name: String,
    slope_um_per_m: f64,
    raw_range_um: f64,
    line_removed_range_um: f64,
    targets_mm: Vec<f64>,
    raw_um: Vec<f64>,
    line_removed_um: Vec<f64>,
}

#[derive(Debug, Serialize)]
struct PointRecord {
    choice: Vec<usize>,
    trace: Option<f64>,
    best: bool,
}

#[derive(Debug, Serialize)]
struct ResidualRecord {
    line: i64,
    run: i64,
    channel: &'static str,
    rms_um: f64,
    readings: usize,
}

#[derive(Debug, Serialize)]
struct DiagnosisRecord {
    proposal: Option<&'static str>,
    candidates: Vec<CandidateRecord>,
    ledger: Vec<LedgerRecord>,
    not_identifiable: Vec<UnseenRecord>,
}

#[derive(Debug, Serialize)]
struct CandidateRecord {
    effect: &'static str,
    physics: &'static str,
    delta_bic: f64,
    rms_along_um: f64,
    rms_lateral_um: f64,
}

#[derive(Debug, Serialize)]
struct LedgerRecord {
    effect: Option<&'static str>,
    delta_bic: f64,
    rms_along_um: f64,
    rms_lateral_um: f64,
}

#[derive(Debug, Serialize)]
struct UnseenRecord {
    effect: &'static str,
    becomes: &'static str,
}

impl AxisRecord {
    /// The record of `study` for campaign `campaign`, run by `pipeline` (name, sha256 of its
    /// file), from `inputs`.
    pub(crate) fn new(
        campaign: &str,
        pipeline: (&str, &str),
        inputs: &[InputFile],
        study: &AxisStudy,
        tables: &[TableRecord],
    ) -> AxisRecord {
        let d = &study.diagnosis;
        AxisRecord {
            head: KindRecordHead::new("axis", campaign, pipeline, inputs),
            axis: study.axis.letter().to_string(),
            names: study.names.to_vec(),
            datum: DatumRecord {
                target_mm: study.datum.0,
                direction: study.datum.1,
            },
            rank: study.rank,
            lost: study.lost.clone(),
            model: ModelRecord {
                effects: study
                    .effects
                    .iter()
                    .map(|e| EffectRecord {
                        effect: e.effect.name(),
                        physics: e.effect.physics(),
                        parameters: e
                            .parameters
                            .iter()
                            .map(|(name, v, u)| ParameterRecord {
                                name: name.clone(),
                                value: finite(*v),
                                u_k2: finite(*u),
                            })
                            .collect(),
                    })
                    .collect(),
                sigma_along_um: study.sigma_um[0],
                sigma_lateral_um: study.sigma_um[1],
                rms_along_um: study.rms_um[0],
                rms_lateral_um: study.rms_um[1],
                readings: study.readings,
            },
            targets: study
                .targets
                .iter()
                .map(|t| TargetRecord {
                    target_mm: t.target_mm,
                    direction: t.direction,
                    errors: (0..6)
                        .map(|k| {
                            (
                                study.names[k].clone(),
                                finite(t.errors[k]),
                                finite(t.u_k2[k]),
                            )
                        })
                        .collect(),
                })
                .collect(),
            iso230_2: study
                .iso230_2
                .as_ref()
                .map(|i| IsoRecord::new(&study.names[study.axis.positioning_index()], i)),
            iso230_2_missing: study.iso230_2_missing.clone(),
            straightness: study
                .straightness
                .iter()
                .map(|s| StraightnessRecord {
                    name: s.name.clone(),
                    slope_um_per_m: 1e3 * s.straightness.slope_um_per_mm,
                    raw_range_um: range(&s.straightness.raw_um),
                    line_removed_range_um: s.straightness.detrended_range_um(),
                    targets_mm: s.targets_mm.clone(),
                    raw_um: s.straightness.raw_um.clone(),
                    line_removed_um: s.straightness.detrended_um.clone(),
                })
                .collect(),
            point_choice: study.point_choice.as_ref().map_or(Vec::new(), |c| {
                c.all
                    .iter()
                    .map(|p| PointRecord {
                        choice: p.choice.clone(),
                        trace: p.trace,
                        best: c.best.as_ref() == Some(p),
                    })
                    .collect()
            }),
            residuals: study
                .residuals
                .iter()
                .map(|r| ResidualRecord {
                    line: r.line,
                    run: r.run,
                    channel: r.channel,
                    rms_um: r.rms_um,
                    readings: r.readings,
                })
                .collect(),
            diagnosis: DiagnosisRecord {
                proposal: d.proposal.map(|e| e.name()),
                candidates: d
                    .candidates
                    .iter()
                    .map(|c| CandidateRecord {
                        effect: c.effect.name(),
                        physics: c.effect.physics(),
                        delta_bic: c.delta_bic,
                        rms_along_um: c.rms_um[0],
                        rms_lateral_um: c.rms_um[1],
                    })
                    .collect(),
                ledger: d
                    .ledger
                    .iter()
                    .map(|s| LedgerRecord {
                        effect: s.effect.map(|e| e.name()),
                        delta_bic: s.delta_bic,
                        rms_along_um: s.rms_um[0],
                        rms_lateral_um: s.rms_um[1],
                    })
                    .collect(),
                not_identifiable: d
                    .unseen
                    .iter()
                    .map(|u| UnseenRecord {
                        effect: u.effect,
                        becomes: u.becomes,
                    })
                    .collect(),
            },
            tables: tables.to_vec(),
        }
    }
}

fn range(v: &[f64]) -> f64 {
    let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let min = v.iter().copied().fold(f64::INFINITY, f64::min);
    if v.is_empty() {
        0.0
    } else {
        max - min
    }
}

/// `axis_errors.parquet`: one row a target, direction and error (name, value, U k = 2; null
/// where not determined).
pub(crate) fn errors_table(study: &AxisStudy) -> Table {
    let mut target = Vec::new();
    let mut direction = Vec::new();
    let mut name = Vec::new();
    let mut value = Vec::new();
    let mut u = Vec::new();
    for t in &study.targets {
        for k in 0..6 {
            target.push(t.target_mm);
            direction.push(i64::from(t.direction));
            name.push(study.names[k].clone());
            value.push(t.errors[k]);
            u.push(t.u_k2[k]);
        }
    }
    Table::new()
        .with("target_mm", Column::F64(target))
        .with("direction", Column::I64(direction))
        .with("error", Column::Str(name))
        .with(
            "value",
            Column::OptF64(value.into_iter().map(finite).collect()),
        )
        .with("u_k2", Column::OptF64(u.into_iter().map(finite).collect()))
}
