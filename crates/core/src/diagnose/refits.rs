//! The cache of exact refits shared by candidate evaluation and forward selection ([`Refits`]):
//! a bar's model refitted with a set of effects is computed once per run.
//!
//! Separate because it is the one piece of shared state of a diagnosis (a mutex-guarded map of
//! once-computed fits); the rest of the module is pure functions over it.

use super::noise;
use super::CandidateError;
use crate::identify::identify_from;
use crate::identify::identify_from_coarse_optimum;
use crate::identify::BarModel;
use crate::model::Effect;
use crate::series::BarSeries;
use std::collections::HashMap;
use std::sync::Arc;
use std::sync::Mutex;
use std::sync::OnceLock;

/// Exact refits shared by the ranking and every forward selection, fleet-wide and per bar: a bar
/// with a given set of effects is fitted once (from the model without the last effect, which
/// is itself a refit of the same cache or the identified model). A refit is kept without its
/// curves over the timeline (`BarModel::without_curves`): the diagnosis reads its
/// parameters, statistics and residuals only, and the 141 exact refits of the second
/// simulator's plate-expansion campaign (10 bars, 15 days, 10 s) held 0.44 GB of curves.
#[derive(Default)]
pub(crate) struct Refits {
    fits: Mutex<RefitCache>,
    /// Refits on the bars' coarse copies (`coarse_tier`), by the same keys: the coarse forward
    /// selection (`CoarseFleet`) starts its cache with them instead of fitting them again.
    coarse: Mutex<RefitCache>,
}

/// Refits by (bar, effect names sorted): a model is the same whichever order its effects were
/// added in, so a path that adds A then B and one that adds B then A share their refit.
///
/// Why: a forward selection confirms tied paths and the ranking's reordering of a path on the
/// readings (`selection::led_by_the_ranking`); keyed by order, the second confirmation would
/// refit every bar with the same effects again (7 s of a 44-s night on the second simulator's
/// air-gradient campaign, 10 bars, 15 days, 10 s).
type RefitCache = HashMap<(String, Vec<String>), Arc<Refit>>;

/// The cache key of `bar` fitted with `effects`.
fn key(bar: &str, effects: &[Effect]) -> (String, Vec<String>) {
    let mut names: Vec<String> = effects.iter().map(Effect::name).collect();
    names.sort();
    (bar.to_string(), names)
}

/// One exact refit, and the log-likelihood of its residual under its own noise model (fitted
/// when a test first asks for it).
pub(crate) struct Refit {
    pub(crate) model: Result<BarModel, CandidateError>,
    noise_log_likelihood: OnceLock<f64>,
}

impl Refit {
    pub(super) fn noise_log_likelihood(&self, series: &BarSeries, model: &BarModel) -> f64 {
        *self.noise_log_likelihood.get_or_init(|| {
            noise::fit_noise(&series.weighted_residuals(&model.residuals_um)).log_likelihood
        })
    }
}

impl Refits {
    /// `base` (fitted to `series`) with `effect` added and refitted.
    pub(crate) fn refit(&self, series: &BarSeries, base: &BarModel, effect: &Effect) -> Arc<Refit> {
        self.refit_from(series, base, effect, None)
    }

    /// [`Refits::refit`], polished from `start` (a refit of the same effects on the bar's coarse
    /// copy: `identify::identify_from_coarse_optimum`) when given, else started from `base`.
    pub(crate) fn refit_from(
        &self,
        series: &BarSeries,
        base: &BarModel,
        effect: &Effect,
        start: Option<&BarModel>,
    ) -> Arc<Refit> {
        let mut effects = base.effects.clone();
        effects.push(effect.clone());
        self.cached(series, &effects, || match start {
            Some(coarse) => identify_from_coarse_optimum(series, &effects, coarse),
            None => identify_from(series, &effects, Some(base)),
        })
    }

    /// `series`' bar fitted with `effects` (in this order) from `coarse`, their refit on the
    /// bar's coarse copy: the refit [`Refits::refit_from`] makes of the same set with that start.
    pub(super) fn refit_at_coarse_optimum(
        &self,
        series: &BarSeries,
        effects: &[Effect],
        coarse: &BarModel,
    ) -> Arc<Refit> {
        self.cached(series, effects, || {
            identify_from_coarse_optimum(series, effects, coarse)
        })
    }

    /// The refit of `series`' bar with `effects` from the cache, or `fit` made and kept.
    fn cached(
        &self,
        series: &BarSeries,
        effects: &[Effect],
        fit: impl FnOnce() -> Result<BarModel, crate::identify::IdentifyError>,
    ) -> Arc<Refit> {
        let key = key(&series.bar.id, effects);
        if let Some(hit) = self.lock().get(&key) {
            return hit.clone();
        }
        let started = std::time::Instant::now();
        let fitted = Arc::new(Refit {
            model: fit()
                .map(BarModel::without_curves)
                .map_err(CandidateError::from),
            noise_log_likelihood: OnceLock::new(),
        });
        // The outcome is formatted only where the debug level is on (tracing evaluates a field
        // inside its enabled check): a refit is on the diagnosis' hot path.
        tracing::debug!(bar = %key.0, effects = ?key.1, samples = series.fit_index.len(), ms = started.elapsed().as_millis(), outcome = %match &fitted.model {
            Ok(m) => format!("rms {:.5} um", m.rms_um),
            Err(e) => format!("failed: {e}"),
        }, "diagnose: refit");
        self.lock().entry(key).or_insert(fitted).clone()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, RefitCache> {
        self.fits.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The refit of `bar` with `effects` (in any order), if it was made.
    pub(super) fn get(&self, bar: &str, effects: &[Effect]) -> Option<Arc<Refit>> {
        self.lock().get(&key(bar, effects)).cloned()
    }

    /// Keep `model`, a refit of `bar` on its coarse copy, for the coarse forward selection.
    pub(super) fn remember_coarse(&self, bar: &str, model: &BarModel) {
        let key = key(bar, &model.effects);
        let refit = Arc::new(Refit {
            model: Ok(model.clone()),
            noise_log_likelihood: OnceLock::new(),
        });
        self.coarse
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .entry(key)
            .or_insert(refit);
    }

    /// A cache for fits on the bars' coarse copies, started with the coarse refits kept here.
    pub(super) fn for_coarse_copies(&self) -> Refits {
        let coarse = self
            .coarse
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        Refits {
            fits: Mutex::new(coarse),
            coarse: Mutex::default(),
        }
    }
}
