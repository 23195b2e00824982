//! Where a fit's time constants start: a long series' coarse copy (300-s bin means) fitted
//! first, the basin of the default starts, and a previous fit's time constants reused.
//!
//! Separate because starts decide speed and which optimum is found, not what is estimated.

use super::BarModel;
use crate::fit;
use crate::fit::Fit;
use crate::fit::FitOptions;
use crate::fit::Start;
use crate::model::Effect;
use crate::model::ThermalProblem;
use crate::series::BarSeries;

/// Series with at least this many fitted samples start their time constants on a coarse copy.
/// The engine's own Brent start sweeps the projected residual some 40 times: on the 7.5-day
/// benchmark campaign (21 600 nodes a bar with 60-s bins) that was two thirds of identify.
pub(crate) const COARSE_START_MIN_SAMPLES: usize = 20_000;
/// Series with at least this many fitted samples are profiled on their coarse copy (each
/// profile point refits the other time constants). The coarse profile's ends are 2-6 % of the
/// interval's width off the exact profile's (benchmark campaigns of 7.5-30 days, 60-s bins);
/// below this size the exact profile costs less than the fit, so it is kept.
pub(super) const COARSE_PROFILE_MIN_SAMPLES: usize = 50_000;
/// How far (in `ln tau`) the fine fit may end from the coarse optimum it started at for that
/// optimum to be taken as the coarse fit of the same basin (0.2: 22 %).
pub(super) const COARSE_BASIN_LN_TAU: f64 = 0.2;
/// Bin of the coarse copy: a fifth or less of the shortest time constants of `docs/spec/physics.md`
/// (15 min to 2 h), so the start lands in the fine fit's basin.
const COARSE_START_BIN_S: f64 = 300.0;

/// The 300-s bin means of a long series, on which its fit starts and its time constants are
/// profiled; `None` for a series short enough to work on directly (below `min_samples`:
/// [`COARSE_START_MIN_SAMPLES`] or [`COARSE_PROFILE_MIN_SAMPLES`]), or whose copy would not be
/// at least 4× shorter.
pub(crate) fn coarse_copy(series: &BarSeries, min_samples: usize) -> Option<BarSeries> {
    if series.fit_index.len() < min_samples {
        return None;
    }
    let coarse = series.binned_copy(COARSE_START_BIN_S);
    (coarse.fit_index.len() * 4 <= series.fit_index.len()).then_some(coarse)
}

/// The time constants a fit starts from: fitted (Brent start + Levenberg-Marquardt) on
/// `problem`, the 300-s bin means of a series ([`coarse_copy`]; the fit of the series itself is
/// then polished from them by argmin's Gauss-Newton, [`Start::NearOptimum`]), or for
/// [`defaults_basin`] a short series itself. On the 30-day
/// benchmark campaign the polish takes 3-4 steps where Levenberg-Marquardt takes 4-7
/// evaluations (the linear solve applies Qᵀy without forming Q); the Brent sweep evaluates the projected residual some 40 times, about half of the fit on
/// the full series (`bench/results.md`), a few per cent on the coarse copy. `None`: the start
/// failed (the engine then starts as usual).
pub(super) fn start_fit<P: fit::Separable>(
    problem: &P,
    bar: &str,
    theta0: &[f64],
) -> Option<Vec<f64>> {
    let (theta, _) = fit::minimise(
        problem,
        theta0,
        fit::StartSearch::Brent,
        fit::Stop::Statistical,
    )
    .ok()?;
    let n = fit::Separable::observations(problem).len();
    tracing::debug!(bar, ?theta, n, "identify: coarse start");
    theta.iter().all(|t| t.is_finite()).then_some(theta)
}

/// Series with at least this many fitted samples go from their coarse copy's optimum to a
/// [`NEARER_START_BIN_S`] copy's before the series itself ([`nearer_start`]).
const NEARER_START_MIN_SAMPLES: usize = 50_000;
/// Bin of the copy between the coarse copy and the series: a fifteenth or less of the model's
/// time constants (15 min to 2 h), where the 300-s copy is a third to a twelfth of them.
const NEARER_START_BIN_S: f64 = 60.0;

/// The optimum of `effects` on the 60-s means of a long series ([`NEARER_START_BIN_S`]),
/// Levenberg-Marquardt from `theta0` (the coarse copy's optimum): where the series' own fit
/// starts. `None` for a series under [`NEARER_START_MIN_SAMPLES`] fitted samples, one whose
/// 60-s copy is not 4× shorter (a series already in 60-s bins), or when that fit fails.
///
/// Why: the 300-s means blur terms with short time constants and event kinks (head heating's
/// 10-25 min), so on a 10-s, 15-day bar (130 k readings) the coarse optimum can lie 10-15 % in
/// `τ` from the readings' own. From there the Gauss-Newton polish overshoots wherever two time
/// constants are nearly equal (the two paths of a bar whose `I_p` varies little), and
/// Levenberg-Marquardt takes 10-15 evaluations of the readings (0.6-0.8 s a refit). The 60-s
/// copy's optimum lies within about 1 % of the readings' (the bin's bias is `(60 s/τ)²/24`),
/// and the readings then take a polish or a few iterations: on the second simulator's
/// three-effect campaign (every reading) this spares about a tenth of the diagnosis' refits on
/// the readings and a quarter of identify, with the same ledger to every printed digit.
pub(super) fn nearer_start(
    series: &BarSeries,
    effects: &[Effect],
    theta0: &[f64],
) -> Option<Vec<f64>> {
    if series.fit_index.len() < NEARER_START_MIN_SAMPLES {
        return None;
    }
    let copy = series.binned_copy(NEARER_START_BIN_S);
    if copy.fit_index.len() * 4 > series.fit_index.len() {
        return None;
    }
    let problem = ThermalProblem::new(&copy, effects).ok()?;
    let (theta, _) = fit::minimise(
        &problem,
        theta0,
        fit::StartSearch::None,
        fit::Stop::Statistical,
    )
    .ok()?;
    tracing::debug!(bar = %series.bar.id, ?theta, n = copy.fit_index.len(), "identify: nearer start");
    theta.iter().all(|t| t.is_finite()).then_some(theta)
}

/// For a refit (`fit`, started from another model's time constants): the basin of the default
/// time constants, where it is lower. Its start is searched ([`start_fit`]) on `coarse`, else on
/// a short series' 300-s copy if that is 4× shorter, else on the series; the series is fitted
/// from there ([`Start::NearOptimum`]) only when the start's residual is already below `fit`'s,
/// and that fit is returned, with its start, when it ends lower.
///
/// Why: a base model that bent its time constants to mimic a missing effect is a poor start
/// for the model with that effect. On the second simulator's plate-expansion campaign
/// (`bench/foreign_sim.py X --effect plate_expansion --seed 2 --air linear --files bar
/// --sample-s 10 --days 5`) the refit with `plate_expansion` from the base alone stopped at
/// 20.47 nm on bar F01, where a fresh fit reaches 20.03, and the diagnosis ranked
/// `air_gradient` first (ΔBIC −12 329 against −11 973); with the defaults' basin too,
/// `plate_expansion` comes first (−14 010) and reaches the noise. In the usual case (one basin)
/// this costs a search on the coarse copy and one residual of the series, and it makes a second
/// full fit from the bent start unnecessary: the nightly runs of that simulator's 25
/// hidden-effect campaigns take 4 % less in all than with that second fit and no search, where
/// a second full fit for every refit costs 1.5-2.5 times the diagnosis.
pub(super) fn defaults_basin(
    series: &BarSeries,
    problem: &ThermalProblem,
    coarse: Option<&ThermalProblem>,
    defaults: &[f64],
    fit: &Fit,
    options: &FitOptions,
) -> Option<(Vec<f64>, Fit)> {
    let short_copy;
    let short_problem;
    let search = match coarse {
        Some(p) => p,
        None => {
            short_copy = coarse_copy(series, 0);
            short_problem = short_copy
                .as_ref()
                .and_then(|c| ThermalProblem::new(c, &problem.effects()).ok());
            short_problem.as_ref().unwrap_or(problem)
        }
    };
    let theta = start_fit(search, &series.bar.id, defaults)?;
    if fit::projected_rss(problem, &theta) >= fit.rss {
        return None;
    }
    let options = FitOptions {
        start: Start::NearOptimum,
        ..*options
    };
    let lower = fit::fit(problem, &theta, &options)
        .ok()
        .filter(|f| f.rss < fit.rss)?;
    Some((theta, lower))
}

/// Reuse the time constants a previous fit found for the same effects; returns which were
/// reused.
pub(super) fn warm_start(
    problem: &ThermalProblem,
    start: &BarModel,
    theta0: &mut [f64],
) -> Vec<bool> {
    let taus = problem.tau_names();
    let mut reused = vec![false; theta0.len()];
    for (k, name) in taus.iter().enumerate() {
        if let Some(v) = start.value(name) {
            theta0[k] = v.ln();
            reused[k] = true;
        }
    }
    reused
}

/// A problem whose Brent start searches only the time constants not reused from a previous
/// fit ([`warm_start`]); everything else is the problem's own.
///
/// Why: a refit adds one effect to a fitted model, whose time constants are already at their
/// optimum for the smaller model; the sweep of each of them (some 40 residuals each) found the
/// same place again and cost half of a refit on the bars' coarse copies. The new effect's own
/// time constant still gets its search, Levenberg-Marquardt then moves all of them together,
/// and the basin of the defaults is searched afresh ([`defaults_basin`]).
pub(super) struct SearchNew<'a, P> {
    pub(super) problem: &'a P,
    pub(super) reused: &'a [bool],
}

impl<P: fit::Separable> fit::Separable for SearchNew<'_, P> {
    fn observations(&self) -> &[f64] {
        self.problem.observations()
    }
    fn nonlinear_names(&self) -> Vec<String> {
        self.problem.nonlinear_names()
    }
    fn linear_names(&self) -> Vec<String> {
        self.problem.linear_names()
    }
    fn basis(&self, theta: &[f64]) -> nalgebra::DMatrix<f64> {
        self.problem.basis(theta)
    }
    fn basis_derivative(&self, theta: &[f64], k: usize) -> nalgebra::DMatrix<f64> {
        self.problem.basis_derivative(theta, k)
    }
    fn basis_derivative_times(
        &self,
        theta: &[f64],
        k: usize,
        coef: &nalgebra::DVector<f64>,
    ) -> nalgebra::DVector<f64> {
        self.problem.basis_derivative_times(theta, k, coef)
    }
    fn nonlinear_bounds(&self, k: usize) -> Option<(f64, f64)> {
        self.problem.nonlinear_bounds(k)
    }
    fn columns_on(&self, k: usize) -> Option<Vec<usize>> {
        self.problem.columns_on(k)
    }
    fn basis_columns_of(&self, theta: &[f64], columns: &[usize]) -> nalgebra::DMatrix<f64> {
        self.problem.basis_columns_of(theta, columns)
    }
    fn start_search_interval(&self, k: usize) -> Option<(f64, f64)> {
        if self.reused.get(k).copied().unwrap_or(false) {
            None
        } else {
            self.problem.start_search_interval(k)
        }
    }
    fn absorbed_groups(&self) -> Option<Vec<Option<usize>>> {
        self.problem.absorbed_groups()
    }
    fn unexplained_rss(&self) -> f64 {
        self.problem.unexplained_rss()
    }
    fn represented_samples(&self) -> usize {
        self.problem.represented_samples()
    }
}
