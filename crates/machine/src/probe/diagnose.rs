//! The loop of a `probe` setup, as for `axis` (`crate::axis_study`): every effect of the
//! catalogue not in the model tried (BIC change, RMS of first touches and of the rest), then
//! forward selection; the missing effect is the first step that gains the BIC asked for.

use super::effects::{ProbeEffect, TouchInputs};
use super::model::{self, ModelFit, ModelSpec};
use super::{Candidate, LedgerStep, ProbeDiagnosis, ProbeStudyError, ProbeStudyOptions};

/// Rank the effects not in `fit`, then forward selection from it.
pub(crate) fn run(
    spec: &ModelSpec,
    touches: &[TouchInputs],
    y: &[f64],
    fit: &ModelFit,
    options: &ProbeStudyOptions,
) -> Result<ProbeDiagnosis, ProbeStudyError> {
    let try_add = |base: &ModelSpec, e: ProbeEffect| -> Result<ModelFit, ProbeStudyError> {
        let mut s = base.clone();
        s.effects.push(e);
        Ok(model::fit(&s, touches, y)?)
    };
    let mut candidates = Vec::new();
    for e in ProbeEffect::ALL
        .into_iter()
        .filter(|e| !spec.effects.contains(e))
    {
        let with = try_add(spec, e)?;
        candidates.push(Candidate {
            effect: e,
            delta_bic: with.bic - fit.bic,
            rms_um: with.rms_um,
        });
    }
    candidates.sort_by(|a, b| a.delta_bic.total_cmp(&b.delta_bic));
    let mut ledger = vec![LedgerStep {
        effect: None,
        rms_um: fit.rms_um,
        delta_bic: 0.0,
    }];
    let mut current = fit.clone();
    for _ in 0..options.forward_steps {
        let mut best: Option<(ProbeEffect, ModelFit)> = None;
        for e in ProbeEffect::ALL
            .into_iter()
            .filter(|e| !current.spec.effects.contains(e))
        {
            let with = try_add(&current.spec, e)?;
            if best.as_ref().is_none_or(|(_, b)| with.bic < b.bic) {
                best = Some((e, with));
            }
        }
        match best {
            Some((e, with)) if with.bic - current.bic <= -options.min_bic_gain => {
                ledger.push(LedgerStep {
                    effect: Some(e),
                    rms_um: with.rms_um,
                    delta_bic: with.bic - current.bic,
                });
                current = with;
            }
            _ => break,
        }
    }
    let proposal = ledger.get(1).and_then(|s| s.effect);
    Ok(ProbeDiagnosis {
        candidates,
        ledger,
        proposal,
    })
}
