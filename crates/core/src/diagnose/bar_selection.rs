//! Forward selection for one bar on its own channels and tests, for bars that need their own
//! (a bar whose channels the fleet does not share), and the bar's ledger read from the fleet's.
//!
//! Separate because a bar's own search has its own stopping rule and result type ([`Search`]).

use super::candidates::{candidate_effects, evaluate_candidates};
use super::refits::Refits;
use super::screen::ScreenBase;
use super::selection::{forward_selection, Added, LedgerStep};
use super::{BarDiagnosis, Criteria};
use crate::identify::BarModel;
use crate::model::Effect;
use crate::series::BarSeries;

/// One bar's own forward selection.
#[derive(Debug, Clone, PartialEq)]
pub struct BarLedger {
    /// Bar id.
    pub bar: String,
    /// The steps, the starting model first.
    pub steps: Vec<LedgerStep>,
    /// The bar was not searched on its own: the fleet's selection already brings it within the
    /// materiality threshold of its reading-noise floor (`needs_own_selection`), and its
    /// steps are the fleet's, on this bar.
    pub from_fleet: bool,
}

/// Whether a bar needs a forward selection of its own: the fleet's selected model for it
/// (`fleet_model`) leaves its RMS at least the materiality threshold above the white reading
/// noise under its residual (`base`, `ScreenBase::white_noise_variance`).
///
/// Why: a bar's own search serves bars that are different physical objects and need different
/// terms (the axes of a machine tool). Where the fleet's terms already bring a bar to its noise,
/// nothing left on it can be material, and its own search (a beam of exact refits from the base
/// model, seconds each) would only find the fleet's terms again.
pub(crate) fn needs_own_selection(
    fleet_model: &BarModel,
    base: Option<&ScreenBase>,
    criteria: &Criteria,
) -> bool {
    let noise_um = base.map_or(f64::NAN, |b| b.white_noise_variance().sqrt());
    !noise_um.is_finite() || fleet_model.rms_um - noise_um >= criteria.min_gain_um
}

/// The fleet's `ledger` seen on one bar: its RMS at each step (for a bar that needs no search of
/// its own, [`needs_own_selection`]).
pub(crate) fn bar_ledger_from_fleet(bar: &str, ledger: &[LedgerStep]) -> BarLedger {
    let steps = ledger
        .iter()
        .filter_map(|step| {
            let rms = step.rms_um.iter().find(|(b, _)| b == bar)?.1;
            Some(LedgerStep {
                added: step.added.clone(),
                effects: step.effects.clone(),
                rms_um: vec![(bar.to_string(), rms)],
                fleet_rms_um: rms,
                delta_bic: None,
                p_value: None,
            })
        })
        .collect();
    BarLedger {
        bar: bar.to_string(),
        steps,
        from_fleet: true,
    }
}

/// How far forward selection searches: at most `max_steps` effects added, the `beam` best
/// paths kept at each step (`[diagnose] forward_steps`, `beam`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Search {
    /// Most effects added.
    pub(crate) max_steps: usize,
    /// Paths kept at each step.
    pub(crate) beam: usize,
}

/// Forward selection on one bar alone: candidates from its own channel ranking (`diagnosis`
/// of `model`), significance from its own likelihood-ratio tests, materiality by the fleet's
/// `criteria`.
pub(crate) fn forward_selection_of_bar(
    series: &BarSeries,
    model: BarModel,
    base: &Option<ScreenBase>,
    diagnosis: &BarDiagnosis,
    search: Search,
    criteria: &Criteria,
    refits: &Refits,
) -> BarLedger {
    let Search { max_steps, beam } = search;
    let bar = model.bar.clone();
    if max_steps == 0 {
        return BarLedger {
            bar,
            steps: vec![ledger_step(
                Added::Base,
                model.effects.clone(),
                std::slice::from_ref(&model),
                None,
                None,
            )],
            from_fleet: false,
        };
    }
    let candidates = candidate_effects(&model.effects, std::slice::from_ref(diagnosis));
    let (first, _) = evaluate_candidates(
        &[(series, &model)],
        std::slice::from_ref(base),
        &candidates,
        criteria,
        refits,
    );
    let (steps, _) = forward_selection(
        &[series],
        vec![model],
        &first,
        max_steps,
        beam,
        criteria,
        refits,
    );
    BarLedger {
        bar,
        steps,
        from_fleet: false,
    }
}

pub(super) fn ledger_step(
    added: Added,
    effects: Vec<Effect>,
    models: &[BarModel],
    delta_bic: Option<f64>,
    p_value: Option<f64>,
) -> LedgerStep {
    let n_total: usize = models.iter().map(|m| m.n_samples).sum();
    let ss: f64 = models
        .iter()
        .map(|m| m.rms_um.powi(2) * m.n_samples as f64)
        .sum();
    LedgerStep {
        added,
        effects,
        rms_um: models.iter().map(|m| (m.bar.clone(), m.rms_um)).collect(),
        fleet_rms_um: if n_total > 0 {
            (ss / n_total as f64).sqrt()
        } else {
            f64::NAN
        },
        delta_bic,
        p_value,
    }
}
