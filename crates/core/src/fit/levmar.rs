//! The default minimisation path: a coordinate-wise Brent start of the projected RSS (argmin)
//! and Levenberg-Marquardt on the projected problem (varpro).
//!
//! Separate from the Gauss-Newton polish and from the uncertainties: it owns the adapters to the
//! two solver crates and nothing else.

use super::projection::projected_rss;
use super::{FitError, Separable};
use argmin::core::CostFunction;
use argmin::core::Executor;
use argmin::solver::brent::BrentOpt;
use nalgebra::DMatrix;
use nalgebra::DVector;
use nalgebra::Dyn;
use nalgebra::OMatrix;
use nalgebra::OVector;
use varpro::model::SeparableNonlinearModel;
use varpro::problem::SeparableProblemBuilder;
use varpro::solvers::levmar::LevMarSolver;

/// One sweep of 1-D Brent searches of the projected RSS, one nonlinear parameter at a time.
pub(super) fn brent_start<P: Separable>(problem: &P, theta: &mut [f64]) {
    for k in 0..theta.len() {
        let Some((lo, hi)) = problem.start_search_interval(k) else {
            continue;
        };
        let cost = Profile1d {
            problem,
            theta: theta.to_vec(),
            k,
        };
        let best_now = projected_rss(problem, theta);
        let solver = BrentOpt::new(lo, hi).set_tolerance(1e-4, 1e-6);
        let result = Executor::new(cost, solver)
            .configure(|state| state.param(theta[k].clamp(lo, hi)).max_iters(60))
            .run();
        match result {
            Ok(res) => {
                let state = res.state();
                tracing::debug!(k, best = ?state.best_param, best_cost = state.best_cost, start_cost = best_now, "fit: Brent start");
                if let Some(best) = state.best_param {
                    if state.best_cost < best_now {
                        theta[k] = best;
                    }
                }
            }
            Err(e) => tracing::debug!(k, error = %e, "fit: Brent start failed"),
        }
    }
}

/// The projected RSS as a function of one nonlinear parameter, the others held.
struct Profile1d<'a, P> {
    problem: &'a P,
    theta: Vec<f64>,
    k: usize,
}

impl<P: Separable> CostFunction for Profile1d<'_, P> {
    type Param = f64;
    type Output = f64;
    fn cost(&self, x: &f64) -> Result<f64, argmin::core::Error> {
        let mut theta = self.theta.clone();
        theta[self.k] = *x;
        Ok(projected_rss(self.problem, &theta))
    }
}

/// Adapter from [`Separable`] to varpro's model trait.
struct VarproModel<'a, P> {
    problem: &'a P,
    theta: DVector<f64>,
}

#[derive(Debug, thiserror::Error)]
#[error("model evaluation failed")]
struct ModelEvalError;

impl<P: Separable> SeparableNonlinearModel for VarproModel<'_, P> {
    type ScalarType = f64;
    type Error = ModelEvalError;
    fn parameter_count(&self) -> usize {
        self.theta.len()
    }
    fn base_function_count(&self) -> usize {
        self.problem.linear_names().len()
    }
    fn output_len(&self) -> usize {
        self.problem.observations().len()
    }
    fn set_params(&mut self, parameters: OVector<f64, Dyn>) -> Result<(), Self::Error> {
        self.theta = parameters;
        Ok(())
    }
    fn params(&self) -> OVector<f64, Dyn> {
        self.theta.clone()
    }
    // Non-finite values are refused here: nalgebra's SVD inside varpro never returns on NaN.
    fn eval(&self) -> Result<OMatrix<f64, Dyn, Dyn>, Self::Error> {
        finite(self.problem.basis(self.theta.as_slice()))
    }
    fn eval_partial_deriv(&self, k: usize) -> Result<OMatrix<f64, Dyn, Dyn>, Self::Error> {
        finite(self.problem.basis_derivative(self.theta.as_slice(), k))
    }
}

fn finite(m: DMatrix<f64>) -> Result<DMatrix<f64>, ModelEvalError> {
    if m.iter().all(|v| v.is_finite()) {
        Ok(m)
    } else {
        Err(ModelEvalError)
    }
}

pub(super) fn levenberg_marquardt<P: Separable>(
    problem: &P,
    theta0: &[f64],
) -> Result<(Vec<f64>, usize), FitError> {
    let model = VarproModel {
        problem,
        theta: DVector::from_column_slice(theta0),
    };
    let y = DVector::from_column_slice(problem.observations());
    let separable = SeparableProblemBuilder::new(model)
        .observations(y)
        .build()
        .map_err(|e| FitError::NoConvergence(e.to_string()))?;
    let solver = LevMarSolver::with_solver(
        levenberg_marquardt::LevenbergMarquardt::new()
            .with_ftol(1e-12)
            .with_xtol(1e-12)
            .with_gtol(1e-14)
            .with_patience(200),
    );
    let (result, ok) = match solver.solve(separable) {
        Ok(r) => (r, true),
        Err(r) => (r, false),
    };
    let theta: Vec<f64> = result.nonlinear_parameters().iter().copied().collect();
    let evaluations = result.minimization_report.number_of_evaluations;
    if !ok {
        // Accept a stop on iteration limits only if it is no worse than the start.
        let term = format!("{:?}", result.minimization_report.termination);
        if !theta.iter().all(|t| t.is_finite())
            || projected_rss(problem, &theta) > projected_rss(problem, theta0)
        {
            return Err(FitError::NoConvergence(term));
        }
    }
    Ok((theta, evaluations))
}
