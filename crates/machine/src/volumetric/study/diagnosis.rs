//! The loop of a `volumetric` campaign (`docs/spec/machine-physics.md`, "Kind volumetric", the
//! table of effects a model may miss): each effect of the catalogue not in the model is added
//! to the joint fit in turn; the one whose BIC falls most, by more than the threshold, is named
//! as the missing effect, with the residual and the fourth sign pattern's consistency residual
//! before and after. Forward selection repeats this from the augmented model.

use super::super::model::{Layout, Observation, VolumetricEffect};
use super::super::solve::{self, JointFit, VolumetricError};
use super::VolumetricStudyOptions;

/// One candidate effect added to the model.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// The effect.
    pub effect: VolumetricEffect,
    /// BIC of the model without − with it (positive: better with it).
    pub delta_bic: f64,
    /// Residual RMS with it, µm.
    pub rms_after_um: f64,
    /// RMS of the residuals' fourth sign pattern with it, µm.
    pub fourth_rms_after_um: Option<f64>,
    /// Parameters it adds that the readings see (rank gained).
    pub rank_gained: usize,
}

/// The loop's result.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnosis {
    /// Residual RMS of the model as run, µm.
    pub base_rms_um: f64,
    /// RMS of its residuals' fourth sign pattern, µm.
    pub base_fourth_rms_um: Option<f64>,
    /// Every candidate not in the model, best first.
    pub candidates: Vec<Candidate>,
    /// The effect named as missing, if any passes the threshold.
    pub proposal: Option<VolumetricEffect>,
    /// Forward selection: effects added in turn with the residual RMS after each.
    pub path: Vec<(VolumetricEffect, f64)>,
}

fn fourth_rms(fit: &JointFit, obs: &[Observation]) -> Option<f64> {
    let s = solve::step_series(&fit.layout, obs, &fit.residuals).ok()?;
    let f = solve::fourth_pattern(&s)?;
    let all: Vec<f64> = f.iter().flatten().copied().collect();
    Some((all.iter().map(|v| v * v).sum::<f64>() / all.len().max(1) as f64).sqrt())
}

fn candidates(
    base: &JointFit,
    obs: &[Observation],
    layout: &impl Fn(&[VolumetricEffect]) -> Layout,
) -> Result<Vec<Candidate>, VolumetricError> {
    let mut out = Vec::new();
    for effect in VolumetricEffect::ALL {
        if base.layout.effects.contains(&effect) {
            continue;
        }
        let mut effects = base.layout.effects.clone();
        effects.push(effect);
        let fit = solve::fit(layout(&effects), obs)?;
        out.push(Candidate {
            effect,
            delta_bic: base.bic - fit.bic,
            rms_after_um: fit.rms_um,
            fourth_rms_after_um: fourth_rms(&fit, obs),
            rank_gained: fit.rank.saturating_sub(base.rank),
        });
    }
    out.sort_by(|a, b| b.delta_bic.total_cmp(&a.delta_bic));
    Ok(out)
}

/// Runs the loop from the fitted model `fit`.
pub(crate) fn diagnose(
    fit: &JointFit,
    obs: &[Observation],
    options: &VolumetricStudyOptions,
    layout: impl Fn(&[VolumetricEffect]) -> Layout,
) -> Result<Diagnosis, VolumetricError> {
    let cands = candidates(fit, obs, &layout)?;
    let passes = |c: &Candidate| c.delta_bic > options.min_bic_gain && c.rank_gained > 0;
    let proposal = cands.first().filter(|c| passes(c)).map(|c| c.effect);
    let mut path = Vec::new();
    let mut effects = fit.layout.effects.clone();
    let mut current = fit.clone();
    for _ in 0..options.forward_steps {
        let c = candidates(&current, obs, &layout)?;
        let Some(best) = c.first().filter(|c| passes(c)) else {
            break;
        };
        effects.push(best.effect);
        current = solve::fit(layout(&effects), obs)?;
        path.push((best.effect, current.rms_um));
    }
    Ok(Diagnosis {
        base_rms_um: fit.rms_um,
        base_fourth_rms_um: fourth_rms(fit, obs),
        candidates: cands,
        proposal,
        path,
    })
}
