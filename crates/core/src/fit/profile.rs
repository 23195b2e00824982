//! Profile-likelihood intervals of one nonlinear parameter: the projected RSS minimised over
//! the other parameters with it held fixed, and where that profile crosses its cut.
//!
//! Separate from the fit itself: `identify` asks for these intervals after a fit, and they need
//! their own refit machinery ([`FixedTheta`]) and tolerances.

use super::linearise::{full_jacobian, jacobian_at};
use super::projection::solve_linear;
use super::Separable;
use nalgebra::DMatrix;
use nalgebra::DVector;

/// The profile RSS of nonlinear parameter `k` at `x`: the projected RSS minimised over the
/// other nonlinear parameters with `θ_k = x`, started from `start` (`start[k]` ignored).
///
/// The refit is Gauss-Newton on all the other parameters (linear ones solved exactly at every
/// trial, steps halved until the RSS falls), stopped once the step's predicted decrease
/// `|J δ|²` is below `rss_tol`: from a start on the linearised profile trace one or two steps
/// suffice, a fraction of the evaluations Levenberg-Marquardt spends on its own tolerances.
/// Every trial is an upper bound of the profile. `None` when the basis is singular or
/// non-finite at the start.
pub(crate) fn profile_rss<P: Separable>(
    problem: &P,
    start: &[f64],
    k: usize,
    x: f64,
    rss_tol: f64,
) -> Option<f64> {
    let mut theta = start.to_vec();
    theta[k] = x;
    let y = problem.observations();
    let rss_of = |phi: &DMatrix<f64>| -> Option<(DVector<f64>, f64)> {
        let c = solve_linear(phi, y)?;
        let rss: f64 = (phi * &c)
            .iter()
            .zip(y)
            .map(|(f, y)| (y - f) * (y - f))
            .sum::<f64>()
            + problem.unexplained_rss();
        rss.is_finite().then_some((c, rss))
    };
    let mut phi = problem.basis(&theta);
    let (mut coef, mut rss) = rss_of(&phi)?;
    if theta.len() == 1 {
        return Some(rss);
    }
    let fixed = FixedTheta {
        inner: problem,
        k,
        value: x,
    };
    let mut rest = fixed.rest(&theta);
    let m = phi.ncols();
    for _ in 0..20 {
        let jac = full_jacobian(&fixed, &rest, &phi, &coef);
        let resid: Vec<f64> = (&phi * &coef).iter().zip(y).map(|(f, y)| y - f).collect();
        let Some(delta) = solve_linear(&jac, &resid) else {
            break;
        };
        // Gauss-Newton's predicted decrease, |J δ|²: converged when it is below `rss_tol`.
        if (&jac * &delta).norm_squared() < rss_tol {
            break;
        }
        let mut scale = 1.0;
        let mut improved = None;
        for _ in 0..8 {
            let trial: Vec<f64> = rest
                .iter()
                .zip(delta.iter().skip(m))
                .map(|(t, d)| t + scale * d)
                .collect();
            let phi_t = fixed.basis(&trial);
            if phi_t.iter().all(|v| v.is_finite()) {
                if let Some((c_t, rss_t)) = rss_of(&phi_t) {
                    if rss_t < rss {
                        improved = Some((trial, phi_t, c_t, rss_t));
                        break;
                    }
                }
            }
            scale /= 2.0;
        }
        let Some((trial, phi_t, c_t, rss_t)) = improved else {
            break;
        };
        (rest, phi, coef, rss) = (trial, phi_t, c_t, rss_t);
    }
    Some(rss)
}

/// Where the profile RSS of nonlinear parameter `k` rises `delta_rss` above `rss_min` (its value
/// at the estimate `theta_hat`), below and above `theta_hat[k]`: `[low, high]`.
///
/// `step` is the expected half-width (the Wald one). Each side is bracketed from it, then the
/// crossing of `√(P(x) − rss_min) − √delta_rss` (close to linear in `x` when the profile is
/// close to quadratic, so about three profile points per side suffice) is found by the
/// Illinois variant of regula falsi to `PROFILE_TOL · step`. A side that does not cross within
/// the problem's start search interval (or 64 steps when it has none) ends there. `None` when a
/// profile refit fails.
pub(crate) fn profile_interval<P: Separable>(
    problem: &P,
    theta_hat: &[f64],
    k: usize,
    rss_min: f64,
    delta_rss: f64,
    step: f64,
) -> Option<ProfileInterval> {
    if !(delta_rss > 0.0 && step > 0.0 && step.is_finite()) {
        return None;
    }
    let x0 = theta_hat[k];
    let (lo_bound, hi_bound) = problem
        .start_search_interval(k)
        .map(|(lo, hi)| (lo.min(x0), hi.max(x0)))
        .unwrap_or((x0 - 64.0 * step, x0 + 64.0 * step));
    let target = delta_rss.sqrt();
    // Start each refit on the linearised profile trace: the other parameters move with `θ_k` as
    // their regression on it under `(JᵀJ)⁻¹`, which saves most Gauss-Newton steps.
    let n_lin = problem.linear_names().len();
    let slope: Vec<f64> = jacobian_at(problem, theta_hat)
        .and_then(|j| j.tr_mul(&j).try_inverse())
        .map(|c| {
            let ckk = c[(n_lin + k, n_lin + k)];
            (0..theta_hat.len())
                .map(|j| c[(n_lin + j, n_lin + k)] / ckk)
                .map(|v| if v.is_finite() { v } else { 0.0 })
                .collect()
        })
        .unwrap_or_else(|| vec![0.0; theta_hat.len()]);
    let h = |s: f64, dir: f64| -> Option<f64> {
        let x = x0 + dir * s;
        let start: Vec<f64> = theta_hat
            .iter()
            .zip(&slope)
            .map(|(t, b)| t + b * (x - x0))
            .collect();
        let rss = profile_rss(problem, &start, k, x, PROFILE_RSS_TOL * delta_rss)?;
        Some((rss - rss_min).max(0.0).sqrt() - target)
    };
    let mut out = ProfileInterval {
        ends: [x0; 2],
        at_search_bound: [false; 2],
    };
    for (side, dir) in [(0usize, -1.0f64), (1, 1.0)] {
        let limit = if dir < 0.0 {
            x0 - lo_bound
        } else {
            hi_bound - x0
        };
        // Bracket: h(0) = −target < 0. While h ≤ 0, step on to the secant's root (h is close
        // to linear), at least 1.2 and at most 2 times as far.
        let (mut a, mut fa) = (0.0, -target);
        let mut b = step.min(limit);
        let mut fb = h(b, dir)?;
        while fb <= 0.0 && b < limit {
            let secant = if fb > fa {
                b - fb * (b - a) / (fb - fa)
            } else {
                2.0 * b
            };
            (a, fa) = (b, fb);
            b = secant.clamp(1.2 * a, 2.0 * a).min(limit);
            fb = h(b, dir)?;
        }
        if fb <= 0.0 {
            out.ends[side] = x0 + dir * limit;
            out.at_search_bound[side] = true;
            continue;
        }
        // Illinois regula falsi on [a, b], until two successive estimates agree within `tol`.
        let tol = PROFILE_TOL * step;
        let mut last_side = 0i8;
        let mut root = b - fb * (b - a) / (fb - fa);
        for _ in 0..40 {
            let fc = h(root, dir)?;
            if fc > 0.0 {
                (b, fb) = (root, fc);
                if last_side == 1 {
                    fa /= 2.0;
                }
                last_side = 1;
            } else {
                (a, fa) = (root, fc);
                if last_side == -1 {
                    fb /= 2.0;
                }
                last_side = -1;
            }
            let next = b - fb * (b - a) / (fb - fa);
            let done = (next - root).abs() < tol;
            root = next;
            if done {
                break;
            }
        }
        out.ends[side] = x0 + dir * root;
    }
    Some(out)
}

/// A profile-likelihood interval of one nonlinear parameter ([`profile_interval`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ProfileInterval {
    /// Lower and upper end, in the parameter's own scale.
    pub(crate) ends: [f64; 2],
    /// The profile RSS never reached the cut on that side before the problem's search bound
    /// ([`Separable::start_search_interval`], else 64 steps): the end is the bound, and the
    /// data do not limit the parameter there.
    pub(crate) at_search_bound: [bool; 2],
}

/// Accuracy of a profile interval's ends, relative to the Wald half-width: far below what
/// matters for coverage, and reached in one or two regula falsi steps.
const PROFILE_TOL: f64 = 5e-3;
/// Accuracy of a profile RSS, relative to the rise that ends the interval: an error `ε` moves an
/// end by about `ε / 2` of the half-width, so `2e-3` keeps it within `1e-3` of it.
const PROFILE_RSS_TOL: f64 = 2e-3;

/// `problem` with nonlinear parameter `k` held at `value`: the other nonlinear parameters are
/// free (a profile refit).
struct FixedTheta<'a, P> {
    inner: &'a P,
    k: usize,
    value: f64,
}

impl<P: Separable> FixedTheta<'_, P> {
    fn full(&self, rest: &[f64]) -> Vec<f64> {
        let mut t = rest.to_vec();
        t.insert(self.k, self.value);
        t
    }
    fn rest(&self, full: &[f64]) -> Vec<f64> {
        let mut t = full.to_vec();
        t.remove(self.k);
        t
    }
}

impl<P: Separable> Separable for FixedTheta<'_, P> {
    fn observations(&self) -> &[f64] {
        self.inner.observations()
    }
    fn nonlinear_names(&self) -> Vec<String> {
        let mut names = self.inner.nonlinear_names();
        names.remove(self.k);
        names
    }
    fn linear_names(&self) -> Vec<String> {
        self.inner.linear_names()
    }
    fn basis(&self, theta: &[f64]) -> DMatrix<f64> {
        self.inner.basis(&self.full(theta))
    }
    fn basis_derivative(&self, theta: &[f64], j: usize) -> DMatrix<f64> {
        let j = if j >= self.k { j + 1 } else { j };
        self.inner.basis_derivative(&self.full(theta), j)
    }
    fn basis_derivative_times(&self, theta: &[f64], j: usize, coef: &DVector<f64>) -> DVector<f64> {
        let j = if j >= self.k { j + 1 } else { j };
        self.inner
            .basis_derivative_times(&self.full(theta), j, coef)
    }
    fn nonlinear_bounds(&self, j: usize) -> Option<(f64, f64)> {
        let j = if j >= self.k { j + 1 } else { j };
        self.inner.nonlinear_bounds(j)
    }
    fn absorbed_groups(&self) -> Option<Vec<Option<usize>>> {
        self.inner.absorbed_groups()
    }
    fn unexplained_rss(&self) -> f64 {
        self.inner.unexplained_rss()
    }
    fn represented_samples(&self) -> usize {
        self.inner.represented_samples()
    }
}
