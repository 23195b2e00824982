//! Conditioning (issue 14): directions the data do not determine are refused by name, never
//! given a zero variance by a pseudo-inverse.

use super::*;

/// `y ≈ c0 x + c1 x²`, plus a nonlinear `theta` that the basis does not depend on at all.
struct Blind {
    x: Vec<f64>,
    y: Vec<f64>,
}

impl Separable for Blind {
    fn observations(&self) -> &[f64] {
        &self.y
    }
    fn nonlinear_names(&self) -> Vec<String> {
        vec!["theta".into()]
    }
    fn linear_names(&self) -> Vec<String> {
        vec!["c0".into(), "c1".into()]
    }
    fn basis(&self, _t: &[f64]) -> DMatrix<f64> {
        DMatrix::from_fn(self.x.len(), 2, |i, j| self.x[i].powi(j as i32 + 1))
    }
    fn basis_derivative(&self, _t: &[f64], _k: usize) -> DMatrix<f64> {
        DMatrix::zeros(self.x.len(), 2)
    }
}

#[test]
fn a_parameter_the_model_ignores_is_refused_by_name() {
    let x: Vec<f64> = (0..50).map(|i| i as f64 / 10.0).collect();
    let y: Vec<f64> = x
        .iter()
        .enumerate()
        .map(|(i, x)| 2.0 * x - 0.3 * x * x + 0.01 * ((i * 7 % 11) as f64 - 5.0))
        .collect();
    let problem = Blind { x, y };
    // Before: the pseudo-inverse gave theta u = 0.
    match fit(
        &problem,
        &[1.0],
        &FitOptions {
            start: Start::Given,
            ..FitOptions::default()
        },
    ) {
        Err(FitError::NotIdentifiable { params, reason }) => {
            assert_eq!(params, "theta", "{reason}");
        }
        Err(e) => panic!("expected NotIdentifiable, got {e}"),
        Ok(f) => panic!(
            "expected NotIdentifiable, got u = {:?}",
            f.cov_hac.diagonal()
        ),
    }
}

#[test]
fn undetermined_parameters_names_the_singular_directions() {
    let n = 200;
    let t: Vec<f64> = (0..n).map(|i| i as f64 / n as f64).collect();
    // Independent columns of very different sizes: determined.
    let jac = DMatrix::from_fn(n, 3, |i, j| match j {
        0 => 1e6 * t[i],
        1 => 1e-6 * (t[i] * 7.0).sin(),
        _ => t[i] * t[i],
    });
    assert_eq!(undetermined_parameters(&jac), None);
    // Column 2 = 3 × column 0 up to 1e-12: that direction is undetermined, column 1 is not.
    let jac = DMatrix::from_fn(n, 3, |i, j| match j {
        0 => t[i],
        1 => (t[i] * 7.0).sin(),
        _ => 3.0 * t[i] * (1.0 + 1e-12 * (i % 3) as f64),
    });
    let (params, ratio) = undetermined_parameters(&jac).expect("singular");
    assert_eq!(params, vec![0, 2]);
    assert!(ratio < MIN_RELATIVE_SINGULAR_VALUE, "{ratio}");
    // Nearly collinear but resolved (correlation 1 - 1e-6): determined, with a large u.
    let jac = DMatrix::from_fn(n, 2, |i, j| match j {
        0 => t[i],
        _ => t[i] + 1e-3 * (t[i] * 7.0).sin(),
    });
    assert_eq!(undetermined_parameters(&jac), None);
    // A zero column and a non-finite one.
    let jac = DMatrix::from_fn(n, 3, |i, j| match j {
        0 => t[i],
        1 => 0.0,
        _ if i == 5 => f64::NAN,
        _ => 1.0,
    });
    assert_eq!(undetermined_parameters(&jac), Some((vec![1, 2], 0.0)));
}
