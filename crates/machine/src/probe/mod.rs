//! A `probe` campaign analysed (seed 003; `docs/spec/machine-physics.md`, "Kind `probe`"):
//! per stylus and artefact, the touches grouped by direction (two-touch pretravel, its 2σ, the
//! first-touch offset; all-touch against two-touch statistics), the global model (artefact
//! centre, mean pretravel, lobing harmonic or physical, the effects added) with U, the
//! harmonic content of the direction means, the effective tip diameter, an ISO 10360-5-style
//! form error P with its ISO 14253-1 decision against the probe's MPE, the size error on every
//! further artefact of the stylus, a direction-correction table, what the touches cannot tell
//! apart (by name), and the loop (candidates by BIC, ledger, the missing effect named).

mod diagnose;
mod effects;
mod harmonics;
mod model;
mod setup;
pub mod stats;
#[cfg(test)]
mod tests;

use dbbcal_core::acceptance::Decision;
use dbbcal_core::probe_campaign::{ArtefactKind, ProbeCampaignLogs};

use crate::linear::LinearError;

pub use effects::ProbeEffect;
pub use harmonics::{fit_harmonics, Harmonic, HarmonicFit};
pub use model::{three_lobe_shape, Lobing};
pub use stats::{DirectionSpread, TwoTouchSummary};

/// What the analysis may do.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeStudyOptions {
    /// The effects in the model (`[probe] effects` and `--add-effect`).
    pub effects: Vec<ProbeEffect>,
    /// The lobing model.
    pub lobing: Lobing,
    /// Steps of forward selection (0: rank only).
    pub forward_steps: usize,
    /// The BIC gain an effect must bring to be proposed.
    pub min_bic_gain: f64,
    /// The probe's MPE for the form error P, µm (`[probe] mpe_um`); `None`: no decision.
    pub mpe_um: Option<f64>,
}

impl Default for ProbeStudyOptions {
    fn default() -> Self {
        ProbeStudyOptions {
            effects: Vec::new(),
            lobing: Lobing::Physical,
            forward_steps: 3,
            min_bic_gain: 10.0,
            mpe_um: None,
        }
    }
}

/// Why a `probe` campaign cannot be analysed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProbeStudyError {
    /// No touch.
    #[error("no touch to analyse")]
    NoTouches,
    /// A stylus or artefact has too few directions for its centre.
    #[error("stylus {stylus} on artefact {artefact}: {problem}")]
    Setup {
        /// Stylus id.
        stylus: String,
        /// Artefact id.
        artefact: String,
        /// What is missing.
        problem: String,
    },
    /// The linear engine refused the problem.
    #[error(transparent)]
    Linear(#[from] LinearError),
}

/// One direction of a setup.
#[derive(Debug, Clone, PartialEq)]
pub struct DirectionResult {
    /// 1-based index (`d01` …), in order of spindle, then φ, then θ.
    pub index: usize,
    /// Mean approach vector (unit).
    pub approach: [f64; 3],
    /// Azimuth φ, degrees.
    pub phi_deg: f64,
    /// Elevation θ, degrees.
    pub theta_deg: f64,
    /// Spindle orientation, degrees (`None`: not given).
    pub spindle_deg: Option<f64>,
    /// All-touch and two-touch statistics of the pretravel relative to the analysis' centre.
    pub spread: DirectionSpread,
    /// The model's pretravel here (mean + lobing), µm.
    pub model_pretravel_um: f64,
    /// Correction to add along the approach to a touch point taken with the effective tip,
    /// µm: −(two-touch pretravel − its mean over directions).
    pub correction_um: f64,
    /// U (k = 2) of the correction, µm.
    pub correction_u_k2_um: f64,
    /// The first-touch offset the model fits here (with `first_touch` in the model), µm, U.
    pub first_touch_fit_um: Option<(f64, f64)>,
}

/// The lobing result.
#[derive(Debug, Clone, PartialEq)]
pub struct LobingResult {
    /// The model.
    pub model: Lobing,
    /// Physical: δ_min (µm) and U (NaN when the seat phase is not fixed); harmonic: the 3rd
    /// harmonic's amplitude and U.
    pub size_um: (f64, f64),
    /// Physical: the seat phase φ₀; harmonic: the 3rd harmonic's phase (degrees, U); NaN when
    /// the touches do not fix it.
    pub phase_deg: (f64, f64),
    /// Peak-to-valley of the lobing over a turn, µm (physical: δ_min; harmonic: 2 × amplitude).
    pub peak_to_valley_um: f64,
}

/// The artefact as fitted.
#[derive(Debug, Clone, PartialEq)]
pub struct ArtefactFit {
    /// Its kind.
    pub kind: ArtefactKind,
    /// Whether the centre was declared (then `centre_mm` is the declared one and the fitted
    /// offset is a 1st harmonic).
    pub centre_declared: bool,
    /// Centre, mm (declared, or fitted).
    pub centre_mm: [f64; 3],
    /// The fitted offset from that centre (declared) or U of the fitted centre, µm, (value, U).
    pub centre_offset_um: Vec<(String, f64, f64)>,
    /// Apparent radius of the tip-centre surface (R + r − δ̄ sphere, R − r + δ̄ ring), mm.
    pub apparent_radius_mm: f64,
    /// U (k = 2) of the apparent radius, µm.
    pub apparent_radius_u_k2_um: f64,
    /// Mean pretravel δ̄ over the directions, µm, and U.
    pub mean_pretravel_um: (f64, f64),
}

/// The effective tip diameter 2r − 2δ̄.
#[derive(Debug, Clone, PartialEq)]
pub struct EffectiveTip {
    /// Nominal diameter, mm.
    pub nominal_mm: f64,
    /// Effective diameter, mm.
    pub effective_mm: f64,
    /// U (k = 2), µm.
    pub u_k2_um: f64,
}

/// The ISO 10360-5-style probing form error and its decision.
#[derive(Debug, Clone, PartialEq)]
pub struct FormCheck {
    /// Range of the radial residuals of the least-squares centre and radius over all touches, µm.
    pub p_form_um: f64,
    /// U (k = 2), µm.
    pub u_k2_um: f64,
    /// The MPE, µm.
    pub mpe_um: Option<f64>,
    /// The ISO 14253-1 decision (`None` without an MPE).
    pub decision: Option<Decision>,
    /// How far this is from the standard's test (touch count, pattern).
    pub note: String,
}

/// A size error: an artefact measured with a tip calibrated on another.
#[derive(Debug, Clone, PartialEq)]
pub struct SizeCheck {
    /// Stylus.
    pub stylus: String,
    /// Artefact the tip was calibrated on.
    pub calibrated_on: String,
    /// Artefact measured.
    pub artefact: String,
    /// Measured − certified diameter, µm.
    pub size_error_um: f64,
    /// U (k = 2), µm.
    pub u_k2_um: f64,
}

/// A statement of what the touches cannot tell apart, by its name in the spec.
#[derive(Debug, Clone, PartialEq)]
pub struct NotIdentifiable {
    /// The spec's name (`0th harmonic ≡ tip radius`, `1st harmonic ≡ centre offset`,
    /// `6 directions: sin 3φ unseen`, `stylus bending ≡ lobing`).
    pub name: &'static str,
    /// What it means here.
    pub says: String,
}

/// A model parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameter {
    /// Name (with unit).
    pub name: String,
    /// Value; NaN when not determined.
    pub value: f64,
    /// U (k = 2); NaN when not determined.
    pub u_k2: f64,
}

/// The global model as fitted.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelResult {
    /// Lobing model.
    pub lobing: Lobing,
    /// Effects in it.
    pub effects: Vec<ProbeEffect>,
    /// Parameters.
    pub parameters: Vec<Parameter>,
    /// Rank.
    pub rank: usize,
    /// What the touches cannot see, as named combinations.
    pub lost: Vec<String>,
    /// RMS residual of first touches and of touches 2…, µm.
    pub rms_um: [f64; 2],
    /// Touches.
    pub touches: usize,
}

/// A candidate effect.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// The effect.
    pub effect: ProbeEffect,
    /// BIC change (negative: better).
    pub delta_bic: f64,
    /// RMS of first touches and of the rest with it, µm.
    pub rms_um: [f64; 2],
}

/// One step of forward selection.
#[derive(Debug, Clone, PartialEq)]
pub struct LedgerStep {
    /// The effect added (`None`: the starting model).
    pub effect: Option<ProbeEffect>,
    /// RMS of first touches and of the rest, µm.
    pub rms_um: [f64; 2],
    /// BIC change of the step.
    pub delta_bic: f64,
}

/// The loop.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeDiagnosis {
    /// Every effect not in the model, best first.
    pub candidates: Vec<Candidate>,
    /// Forward selection from the model.
    pub ledger: Vec<LedgerStep>,
    /// The missing effect (the ledger's first step), if any.
    pub proposal: Option<ProbeEffect>,
}

/// One stylus on one artefact.
#[derive(Debug, Clone, PartialEq)]
pub struct SetupStudy {
    /// Stylus id.
    pub stylus: String,
    /// Artefact id.
    pub artefact: String,
    /// Directions.
    pub directions: Vec<DirectionResult>,
    /// All-touch vs two-touch.
    pub summary: TwoTouchSummary,
    /// Harmonics of the direction means (relative to the analysis' centre).
    pub harmonics: HarmonicFit,
    /// Lobing.
    pub lobing: LobingResult,
    /// Artefact fit.
    pub artefact_fit: ArtefactFit,
    /// Effective tip.
    pub tip: EffectiveTip,
    /// Form error P.
    pub form: FormCheck,
    /// The global model.
    pub model: ModelResult,
    /// The loop.
    pub diagnosis: ProbeDiagnosis,
    /// What cannot be told apart here.
    pub not_identifiable: Vec<NotIdentifiable>,
    /// Per touch (seq order): seq, direction index, touch number, pretravel relative to the
    /// analysis' centre (µm), model residual (µm).
    pub touches: Vec<TouchResult>,
}

/// One touch as analysed.
#[derive(Debug, Clone, PartialEq)]
pub struct TouchResult {
    /// `seq`.
    pub seq: i64,
    /// Direction index (1-based).
    pub direction: usize,
    /// Number within its direction.
    pub touch_in_direction: u32,
    /// Pretravel relative to the analysis' centre, µm.
    pub pretravel_um: f64,
    /// Residual of the global model, µm.
    pub residual_um: f64,
}

/// A `probe` campaign analysed.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeStudy {
    /// Each stylus on each artefact, in the manifest's order.
    pub setups: Vec<SetupStudy>,
    /// Size errors (a stylus on a further artefact).
    pub size: Vec<SizeCheck>,
    /// Touches analysed.
    pub touches: usize,
}

/// Analyse a `probe` campaign's touches.
pub fn study(
    logs: &ProbeCampaignLogs,
    options: &ProbeStudyOptions,
) -> Result<ProbeStudy, ProbeStudyError> {
    if logs.touches.is_empty() {
        return Err(ProbeStudyError::NoTouches);
    }
    let mut setups = Vec::new();
    for s in &logs.campaign.styli {
        for a in &logs.campaign.artefacts {
            let touches: Vec<_> = logs
                .touches
                .iter()
                .filter(|t| t.stylus == s.id && t.artefact == a.id)
                .cloned()
                .collect();
            if touches.is_empty() {
                continue;
            }
            setups.push(setup::study_setup(
                s,
                a,
                &touches,
                logs.campaign.same_direction_deg,
                options,
            )?);
        }
    }
    let size = size_checks(logs, &setups);
    Ok(ProbeStudy {
        setups,
        size,
        touches: logs.touches.len(),
    })
}

/// A stylus on several artefacts: calibrated on the first (manifest order), the others'
/// diameters measured with that effective tip.
fn size_checks(logs: &ProbeCampaignLogs, setups: &[SetupStudy]) -> Vec<SizeCheck> {
    let mut out = Vec::new();
    for s in &logs.campaign.styli {
        let of: Vec<&SetupStudy> = setups.iter().filter(|x| x.stylus == s.id).collect();
        let Some((cal, rest)) = of.split_first() else {
            continue;
        };
        let r_eff_mm = cal.tip.effective_mm / 2.0;
        for m in rest {
            let Some(decl) = logs.campaign.artefact(&m.artefact) else {
                continue;
            };
            let r_app = m.artefact_fit.apparent_radius_mm;
            let radius_mm = match decl.kind {
                ArtefactKind::Sphere => r_app - r_eff_mm,
                ArtefactKind::Ring => r_app + r_eff_mm,
            };
            let u = ((2.0 * m.artefact_fit.apparent_radius_u_k2_um).powi(2)
                + (cal.tip.u_k2_um).powi(2)
                + (2.0 * decl.u_um).powi(2))
            .sqrt();
            out.push(SizeCheck {
                stylus: s.id.clone(),
                calibrated_on: cal.artefact.clone(),
                artefact: m.artefact.clone(),
                size_error_um: 1e3 * (2.0 * radius_mm - decl.diameter_mm),
                u_k2_um: u,
            });
        }
    }
    out
}
