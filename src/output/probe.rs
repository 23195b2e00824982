//! `probe.json`, `probe_directions.parquet` (the direction-correction table) and
//! `probe_touches.parquet`: a `probe` campaign's results as files. The record is this module's
//! own (a field renamed in `dbbcal-machine` changes nothing here). Sign of the correction
//! table: `correction_um` is added along the approach direction to a touch point taken with
//! the effective tip diameter (µm); it is −(the direction's two-touch pretravel − their mean).

use serde::Serialize;

use crate::io::{Column, Table};
use dbbcal_core::series::InputFile;

use super::kind_record::KindRecordHead;
use dbbcal_machine::probe::{ProbeStudy, ProbeStudyOptions, SetupStudy};

/// A number or `null` (NaN: not determined).
fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// `probe.json`.
#[derive(Debug, Serialize)]
pub(crate) struct ProbeRecord {
    #[serde(flatten)]
    head: KindRecordHead,
    touches: usize,
    mpe_um: Option<f64>,
    decision_rule: &'static str,
    setups: Vec<SetupRecord>,
    size: Vec<SizeRecord>,
}

#[derive(Debug, Serialize)]
struct ValueU {
    value: Option<f64>,
    u_k2: Option<f64>,
}

fn vu(v: (f64, f64)) -> ValueU {
    ValueU {
        value: finite(v.0),
        u_k2: finite(v.1),
    }
}

#[derive(Debug, Serialize)]
struct SetupRecord {
    stylus: String,
    artefact: String,
    directions: Vec<DirectionRecord>,
    two_touch: TwoTouchRecord,
    harmonics: Vec<HarmonicRecord>,
    harmonics_lost: Vec<String>,
    lobing: LobingRecord,
    artefact_fit: ArtefactRecord,
    effective_tip: TipRecord,
    form: FormRecord,
    model: ModelRecord,
    diagnosis: DiagnosisRecord,
    not_identifiable: Vec<StatementRecord>,
}

#[derive(Debug, Serialize)]
struct DirectionRecord {
    direction: usize,
    phi_deg: f64,
    theta_deg: f64,
    spindle_deg: Option<f64>,
    touches: usize,
    visits: usize,
    pretravel_um: Option<f64>,
    pretravel_two_sigma_um: Option<f64>,
    all_touch_mean_um: Option<f64>,
    all_touch_two_sigma_um: Option<f64>,
    first_touch_offset_um: Option<f64>,
    range_all_um: Option<f64>,
    range_2on_um: Option<f64>,
    model_pretravel_um: Option<f64>,
    correction_um: Option<f64>,
    correction_u_k2_um: Option<f64>,
    first_touch_fit: Option<ValueU>,
}

#[derive(Debug, Serialize)]
struct TwoTouchRecord {
    mean_range_all_um: Option<f64>,
    mean_range_2on_um: Option<f64>,
    range_ratio: Option<f64>,
    two_sigma_all_um: Option<f64>,
    two_sigma_2on_um: Option<f64>,
    first_touch_offset_min_um: Option<f64>,
    first_touch_offset_max_um: Option<f64>,
    direction_means_spread_um: Option<f64>,
}

#[derive(Debug, Serialize)]
struct HarmonicRecord {
    order: u32,
    amplitude_um: Option<f64>,
    amplitude_u_k2_um: Option<f64>,
    phase_deg: Option<f64>,
    determined: bool,
}

#[derive(Debug, Serialize)]
struct LobingRecord {
    model: &'static str,
    /// Physical: δ_min; harmonic: the 3rd harmonic's amplitude (µm).
    size_um: ValueU,
    /// Physical: the seat phase φ₀; harmonic: the 3rd harmonic's phase (degrees).
    phase_deg: ValueU,
    peak_to_valley_um: Option<f64>,
}

#[derive(Debug, Serialize)]
struct ArtefactRecord {
    kind: &'static str,
    centre_declared: bool,
    centre_mm: [f64; 3],
    /// Declared centre: the fitted offset (a 1st harmonic); fitted centre: the last step's
    /// change and U of the centre.
    centre_offset_um: Vec<(String, Option<f64>, Option<f64>)>,
    apparent_radius_mm: f64,
    apparent_radius_u_k2_um: Option<f64>,
    mean_pretravel: ValueU,
}

#[derive(Debug, Serialize)]
struct TipRecord {
    nominal_mm: f64,
    effective_mm: f64,
    u_k2_um: Option<f64>,
}

#[derive(Debug, Serialize)]
struct FormRecord {
    p_form_um: Option<f64>,
    u_k2_um: Option<f64>,
    mpe_um: Option<f64>,
    decision: Option<&'static str>,
    note: String,
}

#[derive(Debug, Serialize)]
struct ModelRecord {
    lobing: &'static str,
    effects: Vec<&'static str>,
    parameters: Vec<(String, Option<f64>, Option<f64>)>,
    rank: usize,
    lost: Vec<String>,
    rms_first_touch_um: Option<f64>,
    rms_other_touches_um: Option<f64>,
    touches: usize,
}

#[derive(Debug, Serialize)]
struct DiagnosisRecord {
    proposal: Option<&'static str>,
    candidates: Vec<CandidateRecord>,
    ledger: Vec<LedgerRecord>,
}

#[derive(Debug, Serialize)]
struct CandidateRecord {
    effect: &'static str,
    physics: &'static str,
    delta_bic: f64,
    rms_first_touch_um: Option<f64>,
    rms_other_touches_um: Option<f64>,
}

#[derive(Debug, Serialize)]
struct LedgerRecord {
    effect: Option<&'static str>,
    delta_bic: f64,
    rms_first_touch_um: Option<f64>,
    rms_other_touches_um: Option<f64>,
}

#[derive(Debug, Serialize)]
struct StatementRecord {
    name: &'static str,
    says: String,
}

#[derive(Debug, Serialize)]
struct SizeRecord {
    stylus: String,
    calibrated_on: String,
    artefact: String,
    size_error_um: Option<f64>,
    u_k2_um: Option<f64>,
}

impl ProbeRecord {
    pub(crate) fn new(
        campaign: &str,
        pipeline: (&str, &str),
        inputs: &[InputFile],
        study: &ProbeStudy,
        options: &ProbeStudyOptions,
    ) -> ProbeRecord {
        ProbeRecord {
            head: KindRecordHead::new("probe", campaign, pipeline, inputs),
            touches: study.touches,
            mpe_um: options.mpe_um,
            decision_rule: crate::narrative::acceptance::DECISION_RULE,
            setups: study.setups.iter().map(setup_record).collect(),
            size: study
                .size
                .iter()
                .map(|s| SizeRecord {
                    stylus: s.stylus.clone(),
                    calibrated_on: s.calibrated_on.clone(),
                    artefact: s.artefact.clone(),
                    size_error_um: finite(s.size_error_um),
                    u_k2_um: finite(s.u_k2_um),
                })
                .collect(),
        }
    }
}

fn setup_record(s: &SetupStudy) -> SetupRecord {
    let t = &s.summary;
    let a = &s.artefact_fit;
    let d = &s.diagnosis;
    SetupRecord {
        stylus: s.stylus.clone(),
        artefact: s.artefact.clone(),
        directions: s
            .directions
            .iter()
            .map(|d| DirectionRecord {
                direction: d.index,
                phi_deg: d.phi_deg,
                theta_deg: d.theta_deg,
                spindle_deg: d.spindle_deg,
                touches: d.spread.touches,
                visits: d.spread.visits,
                pretravel_um: finite(d.spread.mean_2on_um),
                pretravel_two_sigma_um: finite(d.spread.two_sigma_2on_um),
                all_touch_mean_um: finite(d.spread.mean_all_um),
                all_touch_two_sigma_um: finite(d.spread.two_sigma_all_um),
                first_touch_offset_um: finite(d.spread.first_touch_offset_um),
                range_all_um: finite(d.spread.range_all_um),
                range_2on_um: finite(d.spread.range_2on_um),
                model_pretravel_um: finite(d.model_pretravel_um),
                correction_um: finite(d.correction_um),
                correction_u_k2_um: finite(d.correction_u_k2_um),
                first_touch_fit: d.first_touch_fit_um.map(vu),
            })
            .collect(),
        two_touch: TwoTouchRecord {
            mean_range_all_um: finite(t.mean_range_all_um),
            mean_range_2on_um: finite(t.mean_range_2on_um),
            range_ratio: finite(t.range_ratio),
            two_sigma_all_um: finite(t.two_sigma_all_um),
            two_sigma_2on_um: finite(t.two_sigma_2on_um),
            first_touch_offset_min_um: finite(t.first_touch_offset_span_um.0),
            first_touch_offset_max_um: finite(t.first_touch_offset_span_um.1),
            direction_means_spread_um: finite(t.means_spread_um),
        },
        harmonics: s
            .harmonics
            .harmonics
            .iter()
            .map(|h| HarmonicRecord {
                order: h.order,
                amplitude_um: finite(h.amplitude_um),
                amplitude_u_k2_um: finite(h.amplitude_u_k2_um),
                phase_deg: finite(h.phase_deg),
                determined: h.determined,
            })
            .collect(),
        harmonics_lost: s.harmonics.lost.clone(),
        lobing: LobingRecord {
            model: s.lobing.model.name(),
            size_um: vu(s.lobing.size_um),
            phase_deg: vu(s.lobing.phase_deg),
            peak_to_valley_um: finite(s.lobing.peak_to_valley_um),
        },
        artefact_fit: ArtefactRecord {
            kind: a.kind.as_str(),
            centre_declared: a.centre_declared,
            centre_mm: a.centre_mm,
            centre_offset_um: a
                .centre_offset_um
                .iter()
                .map(|(n, v, u)| (n.clone(), finite(*v), finite(*u)))
                .collect(),
            apparent_radius_mm: a.apparent_radius_mm,
            apparent_radius_u_k2_um: finite(a.apparent_radius_u_k2_um),
            mean_pretravel: vu(a.mean_pretravel_um),
        },
        effective_tip: TipRecord {
            nominal_mm: s.tip.nominal_mm,
            effective_mm: s.tip.effective_mm,
            u_k2_um: finite(s.tip.u_k2_um),
        },
        form: FormRecord {
            p_form_um: finite(s.form.p_form_um),
            u_k2_um: finite(s.form.u_k2_um),
            mpe_um: s.form.mpe_um,
            decision: s.form.decision.map(|d| d.as_str()),
            note: s.form.note.clone(),
        },
        model: ModelRecord {
            lobing: s.model.lobing.name(),
            effects: s.model.effects.iter().map(|e| e.name()).collect(),
            parameters: s
                .model
                .parameters
                .iter()
                .map(|p| (p.name.clone(), finite(p.value), finite(p.u_k2)))
                .collect(),
            rank: s.model.rank,
            lost: s.model.lost.clone(),
            rms_first_touch_um: finite(s.model.rms_um[0]),
            rms_other_touches_um: finite(s.model.rms_um[1]),
            touches: s.model.touches,
        },
        diagnosis: DiagnosisRecord {
            proposal: d.proposal.map(|e| e.name()),
            candidates: d
                .candidates
                .iter()
                .map(|c| CandidateRecord {
                    effect: c.effect.name(),
                    physics: c.effect.physics(),
                    delta_bic: c.delta_bic,
                    rms_first_touch_um: finite(c.rms_um[0]),
                    rms_other_touches_um: finite(c.rms_um[1]),
                })
                .collect(),
            ledger: d
                .ledger
                .iter()
                .map(|l| LedgerRecord {
                    effect: l.effect.map(|e| e.name()),
                    delta_bic: l.delta_bic,
                    rms_first_touch_um: finite(l.rms_um[0]),
                    rms_other_touches_um: finite(l.rms_um[1]),
                })
                .collect(),
        },
        not_identifiable: s
            .not_identifiable
            .iter()
            .map(|n| StatementRecord {
                name: n.name,
                says: n.says.clone(),
            })
            .collect(),
    }
}

/// `probe_directions.parquet`: the direction-correction table, one row a setup and direction.
pub(crate) fn directions_table(study: &ProbeStudy) -> Table {
    let mut cols: (Vec<String>, Vec<String>, Vec<i64>) = Default::default();
    let mut num: [Vec<f64>; 9] = Default::default();
    for s in &study.setups {
        for d in &s.directions {
            cols.0.push(s.stylus.clone());
            cols.1.push(s.artefact.clone());
            cols.2.push(d.index as i64);
            let vals = [
                d.phi_deg,
                d.theta_deg,
                d.approach[0],
                d.approach[1],
                d.approach[2],
                d.spread.mean_2on_um,
                d.spread.two_sigma_2on_um,
                d.correction_um,
                d.correction_u_k2_um,
            ];
            for (c, v) in num.iter_mut().zip(vals) {
                c.push(v);
            }
        }
    }
    let names = [
        "phi_deg",
        "theta_deg",
        "i",
        "j",
        "k",
        "pretravel_um",
        "pretravel_two_sigma_um",
        "correction_um",
        "correction_u_k2_um",
    ];
    let mut t = Table::new()
        .with("stylus", Column::Str(cols.0))
        .with("artefact", Column::Str(cols.1))
        .with("direction", Column::I64(cols.2));
    for (n, c) in names.iter().zip(num) {
        t = t.with(*n, Column::OptF64(c.into_iter().map(finite).collect()));
    }
    t
}

/// `probe_touches.parquet`: every touch with its direction, number, pretravel and residual.
pub(crate) fn touches_table(study: &ProbeStudy) -> Table {
    let mut seq = Vec::new();
    let mut dir = Vec::new();
    let mut num = Vec::new();
    let mut pre = Vec::new();
    let mut res = Vec::new();
    let mut stylus = Vec::new();
    let mut artefact = Vec::new();
    for s in &study.setups {
        for t in &s.touches {
            seq.push(t.seq);
            dir.push(t.direction as i64);
            num.push(i64::from(t.touch_in_direction));
            pre.push(t.pretravel_um);
            res.push(t.residual_um);
            stylus.push(s.stylus.clone());
            artefact.push(s.artefact.clone());
        }
    }
    Table::new()
        .with("seq", Column::I64(seq))
        .with("stylus", Column::Str(stylus))
        .with("artefact", Column::Str(artefact))
        .with("direction", Column::I64(dir))
        .with("touch_in_direction", Column::I64(num))
        .with("pretravel_um", Column::F64(pre))
        .with("residual_um", Column::F64(res))
}
