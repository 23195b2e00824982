//! The model linearised at fixed time constants: its Jacobian in all parameters, the
//! residuals there, and a problem with given directions projected out ([`Orthogonalised`]).
//!
//! Separate because score tests, conditioning checks and the covariances all start from the same
//! Jacobian, and none of them needs the minimisers.

use super::projection::solve_linear;
use super::Separable;
use nalgebra::DMatrix;
use nalgebra::DVector;

/// The Jacobian of `problem`'s model in all parameters at `theta`, the linear coefficients
/// solved there (`None` when the basis is singular).
pub(crate) fn jacobian_at<P: Separable>(problem: &P, theta: &[f64]) -> Option<DMatrix<f64>> {
    linearise(problem, theta).map(|l| l.jacobian)
}

/// A model linearised at fixed nonlinear parameters: what a score (Lagrange-multiplier) test of
/// an added term needs.
pub(crate) struct Linearised {
    /// Jacobian in all parameters, `n × p`: the directions a refit can move the model in.
    pub(crate) jacobian: DMatrix<f64>,
    /// Observations minus the model, the linear coefficients solved at `theta` (the engine's
    /// rows, as [`Separable::observations`]).
    pub(crate) residuals: Vec<f64>,
}

/// `problem` linearised at `theta` (the linear coefficients solved there); `None` when the basis
/// is singular.
pub(crate) fn linearise<P: Separable>(problem: &P, theta: &[f64]) -> Option<Linearised> {
    let phi = problem.basis(theta);
    let y = problem.observations();
    let coef = solve_linear(&phi, y)?;
    let residuals = (&phi * &coef).iter().zip(y).map(|(f, y)| y - f).collect();
    Some(Linearised {
        jacobian: full_jacobian(problem, theta, &phi, &coef),
        residuals,
    })
}

/// `problem` seen in the orthogonal complement of some fixed directions: its observations and
/// every basis column (and derivative) have their components along `directions` removed.
///
/// With `directions` the Jacobian of a fitted model, fitting a new term here measures what the
/// term adds beyond a (linearised) refit of that model: the screening form of a score test.
/// Fitting the term to the residual alone misses terms whose benefit comes with moving the
/// model's own parameters (on the machine-tool run, a channel explaining 0.5 % of the
/// residual alone removed 28 % of it once the model was refitted with it).
pub(crate) struct Orthogonalised<'a, P> {
    inner: &'a P,
    /// Orthonormal basis of the removed directions, `n × r`.
    q: std::borrow::Cow<'a, DMatrix<f64>>,
    /// `Qᵀ`, `r × n`: products with it run in nalgebra's matrix kernel, several times faster
    /// than `tr_mul` on tall matrices.
    q_t: DMatrix<f64>,
    y: Vec<f64>,
}

impl<'a, P: Separable> Orthogonalised<'a, P> {
    /// `directions`: `n × k` columns, possibly rank-deficient (directions with a singular value
    /// below `1e-10` of the largest are dropped).
    #[cfg(test)]
    pub(crate) fn new(inner: &'a P, directions: &DMatrix<f64>) -> Self {
        Self::with_orthonormal_basis(
            inner,
            std::borrow::Cow::Owned(orthonormal_basis(directions)),
        )
    }

    /// As [`Orthogonalised::new`], with the directions' [`orthonormal_basis`] computed once by
    /// the caller (screening many terms against one model).
    pub(crate) fn with_orthonormal_basis(
        inner: &'a P,
        q: std::borrow::Cow<'a, DMatrix<f64>>,
    ) -> Self {
        let q_t = q.transpose();
        let y0 = DVector::from_column_slice(inner.observations());
        let y = (&y0 - q.as_ref() * (&q_t * &y0)).iter().copied().collect();
        Orthogonalised { inner, q, q_t, y }
    }

    fn project(&self, m: DMatrix<f64>) -> DMatrix<f64> {
        let along = self.q.as_ref() * (&self.q_t * &m);
        m - along
    }

    fn project_vector(&self, v: DVector<f64>) -> DVector<f64> {
        let along = self.q.as_ref() * (&self.q_t * &v);
        v - along
    }
}

/// Orthonormal basis of the span of `a`'s columns (columns scaled to unit norm first;
/// directions with a singular value below `1e-10` of the largest dropped).
pub(crate) fn orthonormal_basis(a: &DMatrix<f64>) -> DMatrix<f64> {
    if a.ncols() == 0 || a.nrows() == 0 {
        return DMatrix::zeros(a.nrows(), 0);
    }
    // Scale columns first: gains and ln-tau derivatives differ by many orders of magnitude.
    let mut scaled = a.clone();
    for mut c in scaled.column_iter_mut() {
        let norm = c.norm();
        if norm > 0.0 {
            c /= norm;
        }
    }
    let svd = scaled.svd(true, false);
    let (Some(u), s) = (svd.u, svd.singular_values) else {
        return DMatrix::zeros(a.nrows(), 0);
    };
    let smax = s.iter().copied().fold(0.0, f64::max);
    let keep: Vec<usize> = (0..s.len()).filter(|&i| s[i] > 1e-10 * smax).collect();
    DMatrix::from_fn(a.nrows(), keep.len(), |r, c| u[(r, keep[c])])
}

impl<P: Separable> Separable for Orthogonalised<'_, P> {
    fn observations(&self) -> &[f64] {
        &self.y
    }
    fn nonlinear_names(&self) -> Vec<String> {
        self.inner.nonlinear_names()
    }
    fn linear_names(&self) -> Vec<String> {
        self.inner.linear_names()
    }
    fn basis(&self, theta: &[f64]) -> DMatrix<f64> {
        self.project(self.inner.basis(theta))
    }
    fn basis_derivative(&self, theta: &[f64], k: usize) -> DMatrix<f64> {
        self.project(self.inner.basis_derivative(theta, k))
    }
    fn basis_derivative_times(&self, theta: &[f64], k: usize, coef: &DVector<f64>) -> DVector<f64> {
        self.project_vector(self.inner.basis_derivative_times(theta, k, coef))
    }
    fn start_search_interval(&self, k: usize) -> Option<(f64, f64)> {
        self.inner.start_search_interval(k)
    }
    fn nonlinear_bounds(&self, k: usize) -> Option<(f64, f64)> {
        self.inner.nonlinear_bounds(k)
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

/// `J = [Φ | Σ_j c_j ∂φ_j/∂θ_k]`, the Jacobian of the model in all parameters.
pub(super) fn full_jacobian<P: Separable>(
    problem: &P,
    theta: &[f64],
    phi: &DMatrix<f64>,
    coef: &DVector<f64>,
) -> DMatrix<f64> {
    let (n, m) = phi.shape();
    let mut jac = DMatrix::zeros(n, m + theta.len());
    jac.columns_mut(0, m).copy_from(phi);
    for k in 0..theta.len() {
        let d = problem.basis_derivative_times(theta, k, coef);
        jac.column_mut(m + k).copy_from(&d);
    }
    jac
}
