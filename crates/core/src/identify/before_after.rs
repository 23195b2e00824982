//! What a model's added effects bought ([`compare_with_base`]): each bar refitted with the base
//! effects only, its RMS and base parameters beside the model's.

use std::collections::BTreeMap;

use rayon::prelude::*;

use crate::matching::MATCH_PARAMS;
use crate::model::{base_effects, Effect};

use super::{identify_from, BarModel, BarOutcome};

/// The fleet's models beside the base model's refits (when the model has more than the base
/// effects).
#[derive(Debug, Clone)]
pub struct BeforeAfter {
    /// The base model's effects.
    pub before_effects: Vec<String>,
    /// The model's effects.
    pub after_effects: Vec<String>,
    /// Per bar the base refit could fit, in the fleet's order.
    pub bars: Vec<BarBeforeAfter>,
    /// Quadratic mean of the bars' base-model RMS, µm.
    pub fleet_rms_before_um: f64,
    /// Quadratic mean of the bars' model RMS, µm.
    pub fleet_rms_after_um: f64,
}

/// One bar, with the base model and with the model.
#[derive(Debug, Clone)]
pub struct BarBeforeAfter {
    /// The bar's id.
    pub bar: String,
    /// RMS residual of the base model, µm.
    pub rms_before_um: f64,
    /// RMS residual of the model, µm.
    pub rms_after_um: f64,
    /// Base parameters before and after: how much adding the effects moved them.
    pub params_before: BTreeMap<String, f64>,
    /// The same parameters in the model.
    pub params_after: BTreeMap<String, f64>,
}

/// Refit each bar with the base model (in parallel) to show what the added effects bought; a
/// bar whose base refit fails is left out.
pub fn compare_with_base(bars: &[BarOutcome]) -> BeforeAfter {
    let base = base_effects();
    let rows: Vec<BarBeforeAfter> = bars
        .par_iter()
        .filter_map(|o| bar_before_after(o, &base))
        .collect();
    let fleet = |f: &dyn Fn(&BarBeforeAfter) -> f64| {
        (rows.iter().map(|r| f(r).powi(2)).sum::<f64>() / rows.len().max(1) as f64).sqrt()
    };
    BeforeAfter {
        before_effects: base.iter().map(Effect::name).collect(),
        after_effects: bars
            .first()
            .map(|o| o.model.effect_names())
            .unwrap_or_default(),
        fleet_rms_before_um: fleet(&|r| r.rms_before_um),
        fleet_rms_after_um: fleet(&|r| r.rms_after_um),
        bars: rows,
    }
}

/// One bar refitted with `base`: values only, the trial-fit form, without the profile
/// intervals of `identify`.
fn bar_before_after(o: &BarOutcome, base: &[Effect]) -> Option<BarBeforeAfter> {
    let before = identify_from(&o.series, base, None).ok()?;
    Some(BarBeforeAfter {
        bar: o.model.bar.clone(),
        rms_before_um: before.rms_um,
        rms_after_um: o.model.rms_um,
        params_before: base_params(&before),
        params_after: base_params(&o.model),
    })
}

/// The model's values of the base parameters ([`MATCH_PARAMS`]) it has.
fn base_params(m: &BarModel) -> BTreeMap<String, f64> {
    m.params
        .iter()
        .filter(|p| MATCH_PARAMS.contains(&p.name.as_str()))
        .map(|p| (p.name.clone(), p.value))
        .collect()
}
