//! The default minimisation path: a coordinate-wise Brent start of the projected RSS (argmin)
//! and Levenberg-Marquardt (the `levenberg-marquardt` crate) on the projected problem.
//!
//! Separate from the Gauss-Newton polish and from the uncertainties: it owns the adapters to the
//! two solver crates and nothing else.

use super::projection::{projected_rss, Factorised, HeldProjection};
use super::{held_beyond_bounds, FitError, Separable, StartSearch, Stop};
use argmin::core::CostFunction;
use argmin::core::Executor;
use argmin::solver::brent::BrentOpt;
use levenberg_marquardt::LeastSquaresProblem;
use levenberg_marquardt::LevenbergMarquardt;
use nalgebra::DMatrix;
use nalgebra::DVector;
use nalgebra::Dyn;
use nalgebra::Owned;

/// Points of the grid a [`StartSearch::Global`] search evaluates over each time constant's
/// search interval before Brent refines the best of them: about one per factor of 2 over the
/// thermal model's 60 s to 30 days.
const GLOBAL_GRID_POINTS: usize = 16;
/// Relative tolerance of the Brent search within a [`StartSearch::Global`] grid's bracket:
/// 1e-3 of `ln tau` is 0.5-1.5 % of `tau` over 60 s to 30 days, and the RSS at a minimum moves
/// by the square of that. Over a whole interval (the plain start) a coarser tolerance would
/// change which minimum Brent settles in; within the lowest one's bracket it cannot.
const GLOBAL_BRENT_TOLERANCE: f64 = 1e-3;

/// One sweep of 1-D Brent searches of the projected RSS, one nonlinear parameter at a time;
/// with [`StartSearch::Global`], each within the bracket of the best point of a grid over the
/// parameter's search interval.
///
/// Why the grid: Brent's method converges to a minimum of the interval it is given, not
/// always the lowest. The RSS a screened `lag:CHANNEL` term removes has several minima over
/// its time constant (a channel can match the residual's fast part or its slow part); over
/// the whole interval Brent settles in one of them depending on its first golden-section
/// points and its tolerance, so a channel's ranking depended on the search, not on the data
/// (a tolerance of 1e-3 in place of 1e-4 moved the first or second channel of 20 of the loop
/// matrix's 270 bars: `bench/README.md`).
pub(super) fn brent_start<P: Separable>(problem: &P, theta: &mut [f64], search: StartSearch) {
    for k in 0..theta.len() {
        let Some((lo, hi)) = problem.start_search_interval(k) else {
            continue;
        };
        let cost = Profile1d::new(problem, theta, k);
        // The lowest point seen so far: its value of `θ_k` and its cost.
        let mut best_now = (theta[k], projected_rss(problem, theta));
        let (lo, hi, tolerance) = match search {
            StartSearch::Global => {
                let (bracket, best_point) = best_bracket(&cost, lo, hi, best_now);
                best_now = best_point;
                (bracket.0, bracket.1, GLOBAL_BRENT_TOLERANCE)
            }
            _ => (lo, hi, 1e-4),
        };
        let solver = BrentOpt::new(lo, hi).set_tolerance(tolerance, 1e-6);
        let result = Executor::new(cost, solver)
            .configure(|state| state.param(theta[k].clamp(lo, hi)).max_iters(60))
            .run();
        match result {
            Ok(res) => {
                let state = res.state();
                tracing::debug!(k, iters = state.iter, lo, hi, best = ?state.best_param, best_cost = state.best_cost, best_before = ?best_now, "fit: Brent start");
                if let Some(best) = state.best_param {
                    if state.best_cost < best_now.1.min(UNSOLVED_COST) {
                        best_now = (best, state.best_cost);
                    }
                }
            }
            Err(e) => tracing::debug!(k, error = %e, "fit: Brent start failed"),
        }
        theta[k] = best_now.0;
    }
}

/// Where a [`StartSearch::Global`] search runs Brent, and the lowest point it has seen: the
/// bracket `[g_{i-1}, g_{i+1}]` (within `[lo, hi]`) of the lowest point `g_i` of a grid of
/// [`GLOBAL_GRID_POINTS`] evenly spaced over `[lo, hi]` (the first of equal ones), or a grid
/// step either side of the start (`start`: its value and cost) where that is lower than every
/// grid point. Brent's result is kept only where it is lower still: where the RSS is rough,
/// Brent can end above the grid point.
fn best_bracket<C: CostFunction<Param = f64, Output = f64>>(
    cost: &C,
    lo: f64,
    hi: f64,
    start: (f64, f64),
) -> ((f64, f64), (f64, f64)) {
    let last = GLOBAL_GRID_POINTS - 1;
    let step = (hi - lo) / last as f64;
    let point = |i: usize| lo + step * i as f64;
    let costs: Vec<f64> = (0..=last)
        .map(|i| cost.cost(&point(i)).unwrap_or(f64::INFINITY))
        .collect();
    let mut best = (0, f64::INFINITY);
    for (i, &c) in costs.iter().enumerate() {
        if c < best.1 {
            best = (i, c);
        }
    }
    tracing::trace!(lo, hi, ?costs, best = best.0, "fit: global start grid");
    let (x, cost_x) = start;
    if best.1 >= UNSOLVED_COST {
        return ((lo, hi), start);
    }
    if cost_x <= best.1 && (lo..=hi).contains(&x) {
        return (((x - step).max(lo), (x + step).min(hi)), start);
    }
    let bracket = (
        point(best.0.saturating_sub(1)),
        point((best.0 + 1).min(last)),
    );
    (bracket, (point(best.0), best.1))
}

/// What [`Profile1d`] reports where the projected RSS is not finite (a singular basis): a
/// finite stand-in above any real RSS.
///
/// Why: argmin's Brent fits a parabola through its three best points, and one infinite cost
/// makes that parabola NaN; from then on every step is evaluated at a NaN parameter until
/// the iteration cap. On our simulator's three-effect campaign (sensor gradient, plate
/// expansion, hidden channel) 63 of 3 657 sweeps met a singular basis at Brent's first point
/// and each spent its 60 iterations there, returning that first point.
const UNSOLVED_COST: f64 = 1e150;

/// The projected RSS as a function of one nonlinear parameter, the others held.
struct Profile1d<'a, P> {
    problem: &'a P,
    theta: Vec<f64>,
    k: usize,
    /// The columns on `θ_k` and the other columns factorised once, where the problem names
    /// them and those are finite and of full rank; else every trial factorises the whole basis.
    held: Option<(Vec<usize>, HeldProjection)>,
}

impl<'a, P: Separable> Profile1d<'a, P> {
    fn new(problem: &'a P, theta: &[f64], k: usize) -> Profile1d<'a, P> {
        let held = problem.columns_on(k).and_then(|moving| {
            let others: Vec<usize> = (0..problem.linear_names().len())
                .filter(|c| !moving.contains(c))
                .collect();
            let phi = problem.basis_columns_of(theta, &others);
            HeldProjection::new(&phi, problem.observations()).map(|held| (moving, held))
        });
        Profile1d {
            problem,
            theta: theta.to_vec(),
            k,
            held,
        }
    }
}

impl<P: Separable> CostFunction for Profile1d<'_, P> {
    type Param = f64;
    type Output = f64;
    fn cost(&self, x: &f64) -> Result<f64, argmin::core::Error> {
        let mut theta = self.theta.clone();
        theta[self.k] = *x;
        let rss = match &self.held {
            Some((moving, held)) => held
                .residual_sum_of_squares(&self.problem.basis_columns_of(&theta, moving))
                .map_or(f64::INFINITY, |rss| rss + self.problem.unexplained_rss()),
            None => projected_rss(self.problem, &theta),
        };
        Ok(if rss.is_finite() { rss } else { UNSOLVED_COST })
    }
}

/// The variable-projection problem for the `levenberg-marquardt` crate: the residual
/// `r(θ) = y − Φ(θ) c(θ)` with `c` solved at every `θ`, and Kaufman's Jacobian
/// `∂r/∂θ_k = P_Φ d_k − d_k`, `d_k = ∂Φ/∂θ_k c` (as varpro computes it).
///
/// Why not varpro's own solver: without LAPACK its only linear solver is a full SVD of the
/// `n × m` basis with both singular factors at every evaluation, which would take most of the
/// diagnosis' refits on the 300-s copies (about 8 `n m²` against the column-scaled
/// Householder QR's 2 `n m²`; the projections then cost `O(n m)` a column through the same
/// factorisation).
struct Projected<'a, P> {
    problem: &'a P,
    theta: DVector<f64>,
    /// At `theta`: the basis, its factorisation and the residual; `None` where the basis is
    /// singular or not finite.
    solved: Option<ProjectedAt>,
}

struct ProjectedAt {
    phi: DMatrix<f64>,
    factorised: Factorised,
    coef: DVector<f64>,
    residuals: DVector<f64>,
}

impl<P: Separable> Projected<'_, P> {
    fn solve(&self, theta: &DVector<f64>) -> Option<ProjectedAt> {
        let phi = self.problem.basis(theta.as_slice());
        if !phi.iter().all(|v| v.is_finite()) {
            return None;
        }
        let factorised = Factorised::new(&phi)?;
        let y = self.problem.observations();
        let coef = factorised.coefficients(y)?;
        let fitted = &phi * &coef;
        let residuals =
            DVector::from_iterator(y.len(), y.iter().zip(fitted.iter()).map(|(y, f)| y - f));
        Some(ProjectedAt {
            phi,
            factorised,
            coef,
            residuals,
        })
    }
}

impl<P: Separable> LeastSquaresProblem<f64, Dyn, Dyn> for Projected<'_, P> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    /// The previous point's basis and factorisation are dropped before the new ones are made:
    /// held while the next are computed, a refit on the readings had two of each at once.
    fn set_params(&mut self, theta: &DVector<f64>) {
        self.theta.copy_from(theta);
        self.solved = None;
        self.solved = self.solve(theta);
    }

    fn params(&self) -> DVector<f64> {
        self.theta.clone()
    }

    /// Where the basis is singular or not finite, a residual far above any the search has
    /// seen: the trial step is refused and the search goes on from where it was (an error
    /// here would end the search at that point).
    fn residuals(&self) -> Option<DVector<f64>> {
        match &self.solved {
            Some(at) => Some(at.residuals.clone()),
            None => {
                let y = self.problem.observations();
                let norm = y.iter().map(|v| v * v).sum::<f64>().sqrt().max(1.0);
                Some(DVector::from_element(
                    y.len(),
                    1e6 * norm / (y.len().max(1) as f64).sqrt(),
                ))
            }
        }
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let at = self.solved.as_ref()?;
        let mut jac = DMatrix::zeros(at.phi.nrows(), self.theta.len());
        for k in 0..self.theta.len() {
            if held_beyond_bounds(self.problem, self.theta.as_slice(), k) {
                continue;
            }
            let d = self
                .problem
                .basis_derivative_times(self.theta.as_slice(), k, &at.coef);
            if !d.iter().all(|v| v.is_finite()) {
                return None;
            }
            let along = &at.phi * at.factorised.coefficients(d.as_slice())?;
            jac.column_mut(k).copy_from(&(along - d));
        }
        Some(jac)
    }
}

/// Levenberg-Marquardt stops when a step reduces the residual sum of squares by at most
/// [`Stop::relative_rss_tolerance`] of it (MINPACK's `ftol`),
/// or when a step moves the parameters (log time constants, `ln tau`) by at most this share of
/// their norm (MINPACK's `xtol`): 1e-8 of `ln tau`, far inside any time constant's U.
const LM_XTOL: f64 = 1e-8;

pub(super) fn levenberg_marquardt<P: Separable>(
    problem: &P,
    theta0: &[f64],
    stop: Stop,
) -> Result<(Vec<f64>, usize), FitError> {
    let mut projected = Projected {
        problem,
        theta: DVector::from_column_slice(theta0),
        solved: None,
    };
    projected.solved = projected.solve(&projected.theta);
    if projected.solved.is_none() {
        return Err(FitError::NoConvergence(
            "the basis is singular or not finite at the start".into(),
        ));
    }
    let (projected, report) = LevenbergMarquardt::new()
        .with_ftol(stop.relative_rss_tolerance(problem.observations().len()))
        .with_xtol(LM_XTOL)
        .with_gtol(1e-14)
        .with_patience(200)
        .minimize(projected);
    let theta: Vec<f64> = projected.theta.iter().copied().collect();
    let evaluations = report.number_of_evaluations;
    if !report.termination.was_successful() {
        // Accept a stop on iteration limits only if it is no worse than the start.
        let term = format!("{:?}", report.termination);
        if !theta.iter().all(|t| t.is_finite())
            || projected_rss(problem, &theta) > projected_rss(problem, theta0)
        {
            return Err(FitError::NoConvergence(term));
        }
    }
    Ok((theta, evaluations))
}
