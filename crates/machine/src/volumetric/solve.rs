//! Every reading of a `volumetric` campaign in one least-squares problem, the gauge of what it
//! cannot see, and, for comparison, the naive closed-form inversion
//! (`docs/spec/machine-physics.md`, "Kind volumetric").
//!
//! **Joint fit.** The rows of [`super::model::Layout::row`] go to [`crate::linear::solve`]: its
//! rank and lost combinations (by name) say what the readings cannot see. With unknown pointing
//! (two β per step diagonal) the slopes' rank is 4 of 9: the readings see Σ L_k² ε_k / D² and
//! the three squareness values; the per-axis scales and the straightness slopes' antisymmetric
//! part are confounded with pointing. **Gauge** *(ours)*: the error functions are reported with
//! the lost directions fixed by the conventions "equal scale on every axis" and "symmetric
//! straightness slopes" (each squareness split half and half); the identifiable quantities do
//! not depend on it, and each is flagged by a test of orthogonality to every lost direction.
//!
//! **Naive inversion** *(standard; Wang & Liotto 2003)*: with the four step diagonals and β
//! taken as zero, per axis j and node q: D_k(j)(q) = D/(4 L_k) Σ_d s_dk F_dj(q), F_dj the series
//! of diagonal d built from the sub-moves of axis j (the sign patterns are orthogonal). The
//! fourth pattern p_d = sx·sy·sz gives ρ_j(q) = ¼ Σ_d p_d F_dj(q), zero under the additive model
//! with β = 0: the consistency residual *(ours)*.

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector};

use super::model::{Layout, Observation, Place, AXES};
use super::DiagonalSign;
use crate::linear::{self, LinearError, LinearProblem};

/// Errors of the volumetric solve.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum VolumetricError {
    /// The linear engine refused the problem.
    #[error("least squares: {0}")]
    Linear(#[from] LinearError),
    /// Fewer readings than needed.
    #[error("{0}")]
    Readings(String),
}

/// A quantity with its expanded uncertainty and whether the readings see it.
#[derive(Debug, Clone, PartialEq)]
pub struct Quantity {
    /// Its name (`S_xy`, `scale Σ L²ε/D²`, `slope Dy(x)`).
    pub name: String,
    /// The estimate (in the gauge when not identifiable).
    pub value: f64,
    /// U (k = 2); NaN when not identifiable.
    pub u_k2: f64,
    /// Whether the value is independent of the gauge (orthogonal to every lost direction).
    pub identifiable: bool,
}

/// Which instrument and test a reading comes from: `"step"` (laser step diagonal), `"bar"`
/// (a body diagonal read by a bar) or `"body"` (a laser body diagonal).
pub fn source(o: &Observation) -> &'static str {
    if o.is_step() {
        "step"
    } else if o.bar {
        "bar"
    } else {
        "body"
    }
}

/// The joint least-squares fit.
#[derive(Debug, Clone)]
pub struct JointFit {
    /// The parameters.
    pub layout: Layout,
    /// The estimate in the stated gauge.
    pub estimate: Vec<f64>,
    /// Its covariance (scaled by the residual variance).
    pub covariance: DMatrix<f64>,
    /// Numerical rank.
    pub rank: usize,
    /// What the readings cannot see, as named combinations.
    pub lost: Vec<String>,
    null: Vec<Vec<f64>>,
    /// The gauge conventions applied (empty at full rank).
    pub gauge: Vec<String>,
    /// y − A θ, per reading, µm.
    pub residuals: Vec<f64>,
    /// Residual RMS, µm.
    pub rms_um: f64,
    /// Residual standard deviation √(RSS/(n − rank)), µm.
    pub sigma_um: f64,
    /// Bayesian information criterion n ln(RSS/n) + rank ln n.
    pub bic: f64,
}

/// Fits the readings `obs` with `layout`'s parameters.
pub fn fit(layout: Layout, obs: &[Observation]) -> Result<JointFit, VolumetricError> {
    let problem = LinearProblem {
        names: layout.names.clone(),
        rows: obs.iter().map(|o| layout.row(o)).collect(),
        observations: obs.iter().map(|o| o.deviation_um).collect(),
        sigma: None,
    };
    let sol = linear::solve(&problem)?;
    let p = layout.len();
    let n = obs.len();
    let null: Vec<Vec<f64>> = sol
        .lost
        .iter()
        .map(|c| {
            let mut v = vec![0.0; p];
            for (name, coef) in &c.terms {
                if let Some(i) = sol.index(name) {
                    v[i] = *coef;
                }
            }
            v
        })
        .collect();
    let cov = sol
        .covariance
        .clone()
        .unwrap_or_else(|| DMatrix::zeros(p, p));
    let (estimate, covariance, gauge) = fix_gauge(&sol.estimate, &cov, &null);
    let rss: f64 = sol.residuals.iter().map(|r| r * r).sum();
    let nf = n as f64;
    Ok(JointFit {
        rank: sol.rank,
        lost: sol.lost.iter().map(|c| c.to_string()).collect(),
        null,
        gauge,
        rms_um: (rss / nf).sqrt(),
        sigma_um: if sol.dof > 0 {
            (rss / sol.dof as f64).sqrt()
        } else {
            f64::NAN
        },
        bic: nf * (rss / nf).max(1e-300).ln() + sol.rank as f64 * nf.ln(),
        residuals: sol.residuals,
        estimate,
        covariance,
        layout,
    })
}

/// The gauge rows on the nine slopes: equal scales, symmetric straightness slopes.
fn gauge_rows(p: usize) -> (Vec<Vec<f64>>, Vec<String>) {
    use super::model::slope_index as s;
    let mut rows = Vec::new();
    let mut words = Vec::new();
    for (a, b) in [(0, 1), (1, 2)] {
        let mut r = vec![0.0; p];
        r[s(a, a)] = 1.0;
        r[s(b, b)] = -1.0;
        rows.push(r);
    }
    words.push(
        "equal scales: slope Dx(x) = slope Dy(y) = slope Dz(z) (each = Σ L_k² ε_k / D²)"
            .to_string(),
    );
    for (a, b) in [(0, 1), (1, 2), (2, 0)] {
        let mut r = vec![0.0; p];
        r[s(b, a)] = 1.0;
        r[s(a, b)] = -1.0;
        rows.push(r);
        words.push(format!(
            "symmetric slopes: slope D{}({}) = slope D{}({}) (half the squareness each)",
            AXES[b], AXES[a], AXES[a], AXES[b]
        ));
    }
    (rows, words)
}

/// x_g = x + N t with t = −(G N)⁺ G x; covariance T C Tᵀ, T = I − N (G N)⁺ G.
fn fix_gauge(
    x: &[f64],
    cov: &DMatrix<f64>,
    null: &[Vec<f64>],
) -> (Vec<f64>, DMatrix<f64>, Vec<String>) {
    let p = x.len();
    if null.is_empty() {
        return (x.to_vec(), cov.clone(), Vec::new());
    }
    let (rows, words) = gauge_rows(p);
    let g = DMatrix::from_fn(rows.len(), p, |i, j| rows[i][j]);
    let nm = DMatrix::from_fn(p, null.len(), |i, j| null[j][i]);
    let gn = &g * &nm;
    let pinv = gn
        .clone()
        .pseudo_inverse(1e-10 * gn.norm().max(1e-300))
        .unwrap_or_else(|_| DMatrix::zeros(null.len(), rows.len()));
    let t = DMatrix::<f64>::identity(p, p) - &nm * &pinv * &g;
    let xg = &t * DVector::from_column_slice(x);
    let cg = &t * cov * t.transpose();
    (xg.iter().copied().collect(), cg, words)
}

impl JointFit {
    /// A basis of the lost directions, as vectors over the parameters.
    pub fn lost_vectors(&self) -> &[Vec<f64>] {
        &self.null
    }

    /// c · θ with U (k = 2) and whether it is identifiable.
    pub fn quantity(&self, name: impl Into<String>, c: &[f64]) -> Quantity {
        let value: f64 = c.iter().zip(&self.estimate).map(|(a, b)| a * b).sum();
        let cv = DVector::from_column_slice(c);
        let var = (cv.transpose() * &self.covariance * &cv)[(0, 0)];
        let scale = cv.norm().max(1e-300);
        let identifiable = self.null.iter().all(|v| {
            let nv = DVector::from_column_slice(v);
            cv.dot(&nv).abs() <= 1e-7 * scale * nv.norm()
        });
        Quantity {
            name: name.into(),
            value,
            u_k2: if identifiable {
                2.0 * var.max(0.0).sqrt()
            } else {
                f64::NAN
            },
            identifiable,
        }
    }

    /// The squareness values S_xy, S_yz, S_zx (µrad): sums of least-squares straightness
    /// slopes (`machine-physics.md`, "Common model").
    pub fn squareness(&self) -> [Quantity; 3] {
        [(0, 1, "S_xy"), (1, 2, "S_yz"), (2, 0, "S_zx")].map(|(a, b, name)| {
            let l = &self.layout;
            let c: Vec<f64> = l
                .ls_slope_coefficients(b, a)
                .iter()
                .zip(l.ls_slope_coefficients(a, b))
                .map(|(u, v)| u + v)
                .collect();
            self.quantity(name, &c)
        })
    }

    /// Σ L_k² ε_k / D², ε_k the least-squares slope of D_k(k) (µm/m).
    pub fn mean_scale(&self) -> Quantity {
        let l = &self.layout;
        let d2: f64 = l.lengths_mm.iter().map(|v| v * v).sum();
        let mut c = vec![0.0; l.len()];
        for k in 0..3 {
            let w = l.lengths_mm[k].powi(2) / d2;
            for (ci, v) in c.iter_mut().zip(l.ls_slope_coefficients(k, k)) {
                *ci += w * v;
            }
        }
        self.quantity("Σ L_k² ε_k / D²", &c)
    }

    /// The least-squares slope of every D_k(j), µm/m, `[j][k]`.
    pub fn slopes(&self) -> [[Quantity; 3]; 3] {
        [0, 1, 2].map(|j| {
            [0, 1, 2].map(|k| {
                let c = self.layout.ls_slope_coefficients(k, j);
                self.quantity(format!("slope D{}({})", AXES[k], AXES[j]), &c)
            })
        })
    }

    /// D_k(j) at the nodes of axis j, with U: `[j][k]` → (node, value, U).
    pub fn functions(&self) -> [[Vec<(f64, Quantity)>; 3]; 3] {
        [0, 1, 2].map(|j| {
            [0, 1, 2].map(|k| {
                self.layout
                    .nodes(j)
                    .into_iter()
                    .map(|q| {
                        let c = self.layout.function_coefficients(k, j, q);
                        (q, self.quantity(format!("D{}({})", AXES[k], AXES[j]), &c))
                    })
                    .collect()
            })
        })
    }

    /// The shape of every D_k(j): the function less its least-squares line over the nodes of
    /// axis j, at those nodes, with U: `[j][k]` → (node, value, U). Pointing adds straight
    /// lines only, so the shapes stay seen where the slopes are not.
    pub fn shapes(&self) -> [[Vec<(f64, Quantity)>; 3]; 3] {
        [0, 1, 2].map(|j| {
            [0, 1, 2].map(|k| {
                let l = &self.layout;
                let nodes = l.nodes(j);
                let n = nodes.len() as f64;
                let q_mean = nodes.iter().sum::<f64>() / n;
                let mut mean = vec![0.0; l.len()];
                for q in &nodes {
                    for (m, c) in mean.iter_mut().zip(l.function_coefficients(k, j, *q)) {
                        *m += c / n;
                    }
                }
                let slope = l.ls_slope_coefficients(k, j);
                nodes
                    .iter()
                    .map(|&q| {
                        let c: Vec<f64> = l
                            .function_coefficients(k, j, q)
                            .iter()
                            .zip(&mean)
                            .zip(&slope)
                            .map(|((f, m), s)| f - m - 1e-3 * (q - q_mean) * s)
                            .collect();
                        let name = format!("shape D{}({})", AXES[k], AXES[j]);
                        (q, self.quantity(name, &c))
                    })
                    .collect()
            })
        })
    }

    /// The model's error vector at P (µm), each component with U.
    pub fn error_at(&self, p_mm: [f64; 3]) -> [Quantity; 3] {
        [0, 1, 2].map(|k| {
            let c = self.layout.error_coefficients(k, p_mm);
            self.quantity(format!("e{}", AXES[k]), &c)
        })
    }
}

/// Why the step diagonals give no series, or no naive inversion.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StepError {
    /// No step diagonal in the layout.
    #[error("no step diagonals")]
    NoSteps,
    /// No step diagonal measured: the naive inversion has nothing to invert.
    #[error("no step diagonals: the naive inversion needs the four step diagonals")]
    NoStepsToInvert,
    /// A sub-move ends off the nodes.
    #[error("diagonal {diagonal} run {run}: {axis} = {position_mm} mm is not a step node")]
    OffNode {
        /// The diagonal.
        diagonal: DiagonalSign,
        /// The run.
        run: i64,
        /// The axis of the sub-move.
        axis: &'static str,
        /// Where it ended, mm.
        position_mm: f64,
    },
    /// A node was not visited.
    #[error("diagonal {diagonal} run {run}: not every step node of {axis} was reached")]
    NodeMissed {
        /// The diagonal.
        diagonal: DiagonalSign,
        /// The run.
        run: i64,
        /// The axis whose nodes were not all reached.
        axis: &'static str,
    },
    /// Fewer than the four step diagonals.
    #[error("the naive inversion needs the four step diagonals; {measured} measured")]
    NotFour {
        /// How many were measured.
        measured: usize,
    },
    /// The fourth pattern needs the four diagonals.
    #[error("four diagonals needed")]
    NoFourthPattern,
}

/// The series F_dj of each step diagonal (mean over runs), at the nodes of axis j, zero at
/// the axis's min: from the increments of `values` (one per reading of `obs`, in the logs'
/// order) at each sub-move. `Err`: the layout is not the standard one (a sub-move off the
/// nodes, a node not visited).
pub fn step_series(
    layout: &Layout,
    obs: &[Observation],
    values: &[f64],
) -> Result<BTreeMap<DiagonalSign, [Vec<f64>; 3]>, StepError> {
    let n = layout.intervals;
    if n < 1 {
        return Err(StepError::NoSteps);
    }
    let mut runs: BTreeMap<(DiagonalSign, i64), Vec<usize>> = BTreeMap::new();
    for (i, o) in obs.iter().enumerate() {
        if matches!(o.place, Place::Step { .. }) {
            runs.entry((o.diagonal, o.run)).or_default().push(i);
        }
    }
    let mut sums: BTreeMap<DiagonalSign, ([Vec<f64>; 3], usize)> = BTreeMap::new();
    for ((d, run), rows) in &runs {
        let diag = layout.diagonal(*d);
        let h = [0, 1, 2].map(|j| layout.lengths_mm[j] / n as f64);
        let node_of = |j: usize, q: f64| -> Result<usize, StepError> {
            let t = (q - layout.min_mm[j]) / h[j];
            let r = t.round();
            if (t - r).abs() > 1e-3 || r < 0.0 || r > n as f64 {
                return Err(StepError::OffNode {
                    diagonal: *d,
                    run: *run,
                    axis: AXES[j],
                    position_mm: q,
                });
            }
            Ok(r as usize)
        };
        let mut f = [0, 1, 2].map(|_| vec![f64::NAN; n + 1]);
        let mut cur = [0usize; 3];
        for j in 0..3 {
            cur[j] = node_of(j, diag.p0_mm[j])?;
            f[j][cur[j]] = 0.0;
        }
        let mut prev = 0.0;
        for &i in rows {
            let Place::Step {
                position_mm,
                submove,
                ..
            } = obs[i].place
            else {
                continue;
            };
            if let Some(j) = submove {
                let to = node_of(j, position_mm[j])?;
                f[j][to] = f[j][cur[j]] + values[i] - prev;
                cur[j] = to;
            }
            prev = values[i];
        }
        let entry = sums
            .entry(*d)
            .or_insert_with(|| ([0, 1, 2].map(|_| vec![0.0; n + 1]), 0));
        for j in 0..3 {
            if f[j].iter().any(|v| v.is_nan()) {
                return Err(StepError::NodeMissed {
                    diagonal: *d,
                    run: *run,
                    axis: AXES[j],
                });
            }
            let base = f[j][0];
            for (s, v) in entry.0[j].iter_mut().zip(&f[j]) {
                *s += v - base;
            }
        }
        entry.1 += 1;
    }
    Ok(sums
        .into_iter()
        .map(|(d, (mut s, runs))| {
            for series in &mut s {
                for v in series.iter_mut() {
                    *v /= runs as f64;
                }
            }
            (d, s)
        })
        .collect())
}

/// The naive inversion and the fourth pattern.
#[derive(Debug, Clone, PartialEq)]
pub struct Naive {
    /// D_k(j) at the nodes of axis j, `[j][k]`.
    pub functions: [[Vec<f64>; 3]; 3],
    /// S_xy, S_yz, S_zx from the inverted functions' least-squares slopes, µrad.
    pub squareness_urad: [f64; 3],
    /// ε_k, the least-squares slope of D_k(k), µm/m.
    pub scale_um_per_m: [f64; 3],
    /// ρ_j at the nodes of axis j, µm.
    pub fourth_um: [Vec<f64>; 3],
}

/// The fourth sign pattern's consistency residual ρ_j(q) = ¼ Σ_d sx·sy·sz F_dj(q) of series
/// from [`step_series`]; `None` without all four diagonals.
pub fn fourth_pattern(series: &BTreeMap<DiagonalSign, [Vec<f64>; 3]>) -> Option<[Vec<f64>; 3]> {
    if series.len() != 4 {
        return None;
    }
    let len = series.values().next()?[0].len();
    Some([0, 1, 2].map(|j| {
        (0..len)
            .map(|n| {
                series
                    .iter()
                    .map(|(d, f)| d.signs().iter().product::<f64>() * f[j][n])
                    .sum::<f64>()
                    / 4.0
            })
            .collect()
    }))
}

/// The naive closed-form inversion of the four step diagonals (β taken as zero).
pub fn naive(layout: &Layout, obs: &[Observation]) -> Result<Naive, StepError> {
    let values: Vec<f64> = obs.iter().map(|o| o.deviation_um).collect();
    let series = step_series(layout, obs, &values)?;
    if series.len() != 4 {
        return Err(StepError::NotFour {
            measured: series.len(),
        });
    }
    let d_len = layout.diagonals[0].length_mm;
    let functions = [0, 1, 2].map(|j| {
        [0, 1, 2].map(|k| {
            let len = layout.intervals + 1;
            (0..len)
                .map(|n| {
                    series
                        .iter()
                        .map(|(d, f)| d.signs()[k] * f[j][n])
                        .sum::<f64>()
                        * d_len
                        / (4.0 * layout.lengths_mm[k])
                })
                .collect::<Vec<f64>>()
        })
    });
    let slope = |k: usize, j: usize| ls_slope(&layout.nodes(j), &functions[j][k]);
    Ok(Naive {
        squareness_urad: [
            slope(1, 0) + slope(0, 1),
            slope(2, 1) + slope(1, 2),
            slope(0, 2) + slope(2, 0),
        ],
        scale_um_per_m: [slope(0, 0), slope(1, 1), slope(2, 2)],
        fourth_um: fourth_pattern(&series).ok_or(StepError::NoFourthPattern)?,
        functions,
    })
}

/// Least-squares slope of (q mm, v µm), µm/m.
pub fn ls_slope(q: &[f64], v: &[f64]) -> f64 {
    let n = q.len() as f64;
    let qm = q.iter().sum::<f64>() / n;
    let vm = v.iter().sum::<f64>() / n;
    let sxy: f64 = q.iter().zip(v).map(|(a, b)| (a - qm) * (b - vm)).sum();
    let sxx: f64 = q.iter().map(|a| (a - qm).powi(2)).sum();
    1e3 * sxy / sxx
}
