//! Gauss-Newton polish of a fit started at a nearby problem's optimum (`Start::NearOptimum`).
//!
//! Separate from the Levenberg-Marquardt path because it works on argmin's operator traits over
//! the variable-projection residual ([`Reduced`]) and falls back to Levenberg-Marquardt when it
//! does not converge: one concept, a start that is already close.

use super::projection::Factorised;
use super::{held_beyond_bounds, Separable, Stop, POLISH_MAX_STEPS};
use argmin::core::Executor;
use argmin::core::IterState;
use argmin::core::Jacobian;
use argmin::core::Operator;
use argmin::core::Problem;
use argmin::core::Solver;
use argmin::core::State;
use argmin::core::TerminationReason;
use argmin::core::TerminationStatus;
use argmin::core::KV;
use argmin::solver::gaussnewton::GaussNewton;
use nalgebra::DMatrix;
use nalgebra::DVector;

/// Gauss-Newton (argmin's) from `theta0`, a nearby problem's optimum, on the
/// variable-projection residual ([`Reduced`]): the time constants and the number of steps; or,
/// when it does not converge within [`POLISH_MAX_STEPS`] (a step changing the residual norm by
/// less than [`Stop::polish_tolerance`] of it), takes a step that raises the residual
/// ([`StopOnRise`]) or ends no better than it began, the better of its start and
/// stop, for Levenberg-Marquardt to go on from.
///
/// Why: from a coarse copy's optimum Levenberg-Marquardt spent 4-7 evaluations of the basis, its
/// derivatives and a factorisation before its own tolerances held; Gauss-Newton converges
/// quadratically from there.
pub(super) fn polish<P: Separable>(
    problem: &P,
    theta0: &[f64],
    stop: Stop,
) -> Result<Polished, Vec<f64>> {
    let reduced = Reduced {
        problem,
        last: Default::default(),
    };
    let start = DVector::from_column_slice(theta0);
    let Ok(r0) = reduced.apply(&start) else {
        return Err(theta0.to_vec());
    };
    let norm0 = r0.norm();
    let Ok(solver) = GaussNewton::new().with_tolerance(stop.polish_tolerance(r0.len()) * norm0)
    else {
        return Err(theta0.to_vec());
    };
    let solver = StopOnRise { inner: solver };
    let run = Executor::new(reduced, solver)
        .configure(|state| state.param(start).max_iters(POLISH_MAX_STEPS))
        .run();
    let Ok(mut result) = run else {
        return Err(theta0.to_vec());
    };
    let last = result
        .problem
        .take_problem()
        .and_then(|reduced| reduced.last.into_inner());
    let state = result.state();
    let (Some(theta), cost) = (state.get_best_param(), state.get_best_cost()) else {
        return Err(theta0.to_vec());
    };
    let converged = matches!(
        state.get_termination_status(),
        TerminationStatus::Terminated(TerminationReason::SolverConverged)
    );
    // The basis argmin last evaluated, if at the optimum, serves the uncertainties as it is.
    let solved =
        last.filter(|(at, _)| at == theta).map(|(_, solved)| {
            match std::rc::Rc::try_unwrap(solved) {
                Ok((phi, coef, _)) => (phi, coef),
                Err(shared) => (shared.0.clone(), shared.1.clone()),
            }
        });
    let theta: Vec<f64> = theta.iter().copied().collect();
    let steps = state.get_iter() as usize;
    tracing::debug!(
        ?theta,
        steps,
        converged,
        "fit: after the Gauss-Newton polish"
    );
    let finite = cost.is_finite() && theta.iter().all(|t| t.is_finite());
    match (converged, finite && cost <= norm0) {
        (true, true) => Ok(Polished {
            theta,
            steps,
            solved,
        }),
        (false, true) => Err(theta),
        _ => Err(theta0.to_vec()),
    }
}

/// argmin's Gauss-Newton, stopped at the first step that raises the residual norm without
/// converging; [`polish`] then hands its best point to Levenberg-Marquardt.
///
/// Why: where two time constants are nearly equal (a channel's heat lag beside the bar's own
/// path), `JᵀJ` is close to singular and each Gauss-Newton step moves along the valley it
/// cannot resolve. On our simulator's three-effect campaign (sensor gradient, plate expansion,
/// hidden channel) 26 exact refits of the readings had every step raise the residual from
/// the first, and each spent the 8 steps of [`POLISH_MAX_STEPS`] (a basis, its derivatives and a
/// factorisation each) before Levenberg-Marquardt started from the same point.
struct StopOnRise {
    inner: GaussNewton<f64>,
}

type PolishState = IterState<DVector<f64>, (), DMatrix<f64>, (), DVector<f64>, f64>;

impl<O> Solver<O, PolishState> for StopOnRise
where
    GaussNewton<f64>: Solver<O, PolishState>,
{
    fn name(&self) -> &str {
        "Gauss-Newton, stopped where a step raises the residual"
    }

    fn init(
        &mut self,
        problem: &mut Problem<O>,
        state: PolishState,
    ) -> Result<(PolishState, Option<KV>), argmin::core::Error> {
        self.inner.init(problem, state)
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        state: PolishState,
    ) -> Result<(PolishState, Option<KV>), argmin::core::Error> {
        self.inner.next_iter(problem, state)
    }

    fn terminate(&mut self, state: &PolishState) -> TerminationStatus {
        let status = self.inner.terminate(state);
        if !status.terminated() && state.get_cost() > state.get_prev_cost() {
            return TerminationStatus::Terminated(TerminationReason::SolverExit(
                "a step raised the residual".into(),
            ));
        }
        status
    }
}

/// Where [`polish`] converged: the time constants, the steps taken, and the basis with its
/// linear coefficients there when argmin's last evaluation was at that point.
pub(super) struct Polished {
    pub(super) theta: Vec<f64>,
    pub(super) steps: usize,
    pub(super) solved: Option<(DMatrix<f64>, DVector<f64>)>,
}

/// `problem` reduced to its nonlinear parameters for argmin (variable projection): the residual
/// `y − Φ(θ) c(θ)`, the linear coefficients `c` solved at every `θ`, and its Jacobian in `θ`
/// (Kaufman's form: `−(I − P_Φ) ∂Φ/∂θ_k c`, the basis derivatives times the coefficients taken
/// orthogonal to the basis).
struct Reduced<'a, P> {
    problem: &'a P,
    /// The last `(θ, Φ(θ), c(θ))`: argmin asks for the Jacobian where it just took the residual.
    last: std::cell::RefCell<Option<Solved>>,
}

/// A basis and its linear coefficients, shared between the residual and the Jacobian, and the
/// basis' factorisation (the Jacobian projects its columns with it).
type BasisSolved = std::rc::Rc<(DMatrix<f64>, DVector<f64>, Factorised)>;
/// The point `θ` a [`BasisSolved`] was computed at, and it.
type Solved = (DVector<f64>, BasisSolved);

impl<P: Separable> Reduced<'_, P> {
    /// The basis at `theta` and its linear coefficients.
    fn solved(&self, theta: &DVector<f64>) -> Result<BasisSolved, argmin::core::Error> {
        if let Some((at, solved)) = self.last.borrow().as_ref() {
            if at == theta {
                return Ok(solved.clone());
            }
        }
        // The last point's basis and factorisation go before the next are made (the caller
        // holds what it needs of them): kept meanwhile, a refit's peak held two of each.
        *self.last.borrow_mut() = None;
        let phi = self.problem.basis(theta.as_slice());
        if !phi.iter().all(|v| v.is_finite()) {
            return Err(argmin::core::Error::msg("the basis is not finite"));
        }
        let singular = || argmin::core::Error::msg("the basis is singular");
        let factorised = Factorised::new(&phi).ok_or_else(singular)?;
        let coef = factorised
            .coefficients(self.problem.observations())
            .ok_or_else(singular)?;
        let solved = std::rc::Rc::new((phi, coef, factorised));
        *self.last.borrow_mut() = Some((theta.clone(), solved.clone()));
        Ok(solved)
    }
}

impl<P: Separable> Operator for Reduced<'_, P> {
    type Param = DVector<f64>;
    type Output = DVector<f64>;

    fn apply(&self, theta: &DVector<f64>) -> Result<DVector<f64>, argmin::core::Error> {
        let solved = self.solved(theta)?;
        let (phi, coef, _) = &*solved;
        let y = self.problem.observations();
        Ok(DVector::from_iterator(
            y.len(),
            (phi * coef).iter().zip(y).map(|(f, y)| y - f),
        ))
    }
}

impl<P: Separable> Jacobian for Reduced<'_, P> {
    type Param = DVector<f64>;
    type Jacobian = DMatrix<f64>;

    fn jacobian(&self, theta: &DVector<f64>) -> Result<DMatrix<f64>, argmin::core::Error> {
        let solved = self.solved(theta)?;
        let (phi, coef, factorised) = &*solved;
        let mut jac = DMatrix::zeros(phi.nrows(), theta.len());
        for k in 0..theta.len() {
            if held_beyond_bounds(self.problem, theta.as_slice(), k) {
                continue;
            }
            let d = self
                .problem
                .basis_derivative_times(theta.as_slice(), k, coef);
            // The part of `d` along the basis, `P_Φ d = Φ (Φ⁺ d)`, by the factorisation the
            // residual was solved with (forming Q explicitly cost as much as the QR itself).
            let along_coef = factorised
                .coefficients(d.as_slice())
                .ok_or_else(|| argmin::core::Error::msg("the basis is singular"))?;
            let along = phi * along_coef;
            jac.column_mut(k).copy_from(&(along - d));
        }
        Ok(jac)
    }
}
