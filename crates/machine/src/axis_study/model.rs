//! The global model of an `axis` campaign's readings (`docs/spec/machine-physics.md`, "Kind
//! axis"): every reading, of every line, run and direction, is one channel of
//! Δ(p_l) = δ(x, d) + 10⁻³ ε(x, d) × p_l, the six errors free at each (target, direction), plus
//! the effects added so far. Six errors per target are exactly determined by one run of the
//! patent's three lines; the runs repeat them, and what differs between runs (in time, in the
//! air) is what an effect explains.

use std::collections::BTreeMap;

use crate::axis::{design_row, Channel};
use crate::linear::{self, LinearError, LinearProblem, LinearSolution};
use nalgebra::{DMatrix, DVector};

use super::effects::{columns_of, warm_up_regressor, AxisEffect, WARM_UP};

/// One reading, normalised and placed: what the global model fits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PlacedReading {
    /// Index of its (target, direction) block.
    pub(crate) block: usize,
    /// The channel.
    pub(crate) channel: Channel,
    /// Whether the channel is along the axis (the laser's linear reading).
    pub(crate) along: bool,
    /// Line id.
    pub(crate) line: i64,
    /// Run.
    pub(crate) run: i64,
    /// Reflector offset from the report point, mm.
    pub(crate) offset_mm: [f64; 3],
    /// Normalised deviation, µm.
    pub(crate) deviation_um: f64,
    /// The effects' regressors at this reading (one value a column of [`AxisEffect::columns`];
    /// the warm-up's slot is computed at a τ by [`PlacedReading::regressor`]).
    pub(crate) regressors: [f64; super::effects::REGRESSORS],
    /// Hours since the campaign's first reading, at this reading and at its line's datum.
    pub(crate) hours_since_start: [f64; 2],
}

impl PlacedReading {
    /// Regressor `index` at this reading, the warm-up's at time constant `warm_up_tau_h`.
    pub(crate) fn regressor(&self, index: usize, warm_up_tau_h: Option<f64>) -> f64 {
        match (index, warm_up_tau_h) {
            (WARM_UP, Some(tau)) => {
                warm_up_regressor(self.hours_since_start[0], self.hours_since_start[1], tau)
            }
            (WARM_UP, None) => 0.0,
            _ => self.regressors[index],
        }
    }
}

/// A fit of the global model with some effects.
#[derive(Debug, Clone)]
pub(crate) struct ModelFit {
    /// The effects in the model, in the order added.
    pub(crate) effects: Vec<AxisEffect>,
    /// The engine's solution (parameters: six a block, then the effects' columns).
    pub(crate) solution: LinearSolution,
    /// σ of an along-axis and of a lateral reading, µm, from the residuals.
    pub(crate) sigma_um: [f64; 2],
    /// Bayesian information criterion with one σ per channel class.
    pub(crate) bic: f64,
    /// RMS residual of along-axis and of lateral readings, µm.
    pub(crate) rms_um: [f64; 2],
    /// The warm-up's time constant, h, when `machine_warm_up` is in the model.
    pub(crate) warm_up_tau_h: Option<f64>,
}

/// The parameter names of block `b`: its six error names `@` the block's label.
pub(crate) fn block_names(names: &[String; 6], label: &str) -> Vec<String> {
    names.iter().map(|n| format!("{n}@{label}")).collect()
}

/// Fit the readings with `effects`. With `machine_warm_up`, τ is searched
/// ([`search_warm_up_tau`]) and the model fitted at the τ found; the search pays ln n.
pub(crate) fn fit(
    readings: &[PlacedReading],
    block_labels: &[String],
    error_names: &[String; 6],
    effects: &[AxisEffect],
) -> Result<ModelFit, LinearError> {
    if !effects.contains(&AxisEffect::MachineWarmUp) {
        return fit_at(readings, block_labels, error_names, effects, None);
    }
    let tau = search_warm_up_tau(readings, block_labels, error_names, effects)?;
    let mut fit = fit_at(readings, block_labels, error_names, effects, Some(tau))?;
    fit.bic += (readings.len().max(2) as f64).ln();
    Ok(fit)
}

/// The warm-up's τ on [`crate::warm_up::tau_grid_h`] whose levelling drift explains most of
/// what the other effects leave: their parameters are projected out (variable projection), so
/// that each τ costs a product with the model's column space instead of a fit. The rows are
/// weighted by σ per channel class of the model without the warm-up.
fn search_warm_up_tau(
    readings: &[PlacedReading],
    block_labels: &[String],
    error_names: &[String; 6],
    effects: &[AxisEffect],
) -> Result<f64, LinearError> {
    let without: Vec<AxisEffect> = effects
        .iter()
        .copied()
        .filter(|&e| e != AxisEffect::MachineWarmUp)
        .collect();
    let base = fit_at(readings, block_labels, error_names, &without, None)?;
    let others: Vec<AxisEffect> = without
        .into_iter()
        .filter(|&e| e != AxisEffect::MachineDrift)
        .collect();
    let weight: Vec<f64> = readings
        .iter()
        .map(|r| 1.0 / base.sigma_um[usize::from(!r.along)].max(1e-12))
        .collect();
    let (_, rows) = design(readings, block_labels, error_names, &others, None);
    let n = readings.len();
    let a = DMatrix::from_fn(n, rows.first().map_or(0, Vec::len), |i, j| {
        rows[i][j] * weight[i]
    });
    let basis = column_space(a);
    let project_out = |v: DVector<f64>| -> DVector<f64> {
        let along = basis.tr_mul(&v);
        v - &basis * along
    };
    let y = project_out(DVector::from_fn(n, |i, _| {
        readings[i].deviation_um * weight[i]
    }));
    let channels = AxisEffect::MachineWarmUp.columns();
    let mut best = (f64::NEG_INFINITY, 1.0);
    for tau in crate::warm_up::tau_grid_h() {
        let z: Vec<DVector<f64>> = channels
            .iter()
            .map(|&(regressor, channel)| {
                project_out(DVector::from_fn(n, |i, _| {
                    let r = &readings[i];
                    if channel.is_none_or(|c| c == r.channel) {
                        r.regressor(regressor, Some(tau)) * weight[i]
                    } else {
                        0.0
                    }
                }))
            })
            .collect();
        let explained = explained_square(&z, &y);
        if explained > best.0 {
            best = (explained, tau);
        }
    }
    Ok(best.1)
}

/// An orthonormal basis of `a`'s column space (left singular vectors of the non-zero singular
/// values, at the engine's rank tolerance).
fn column_space(a: DMatrix<f64>) -> DMatrix<f64> {
    let rows = a.nrows();
    if a.ncols() == 0 {
        return DMatrix::zeros(rows, 0);
    }
    let svd = a.svd(true, false);
    let u = svd.u.expect("u requested");
    let largest = svd.singular_values.max();
    let kept: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&k| svd.singular_values[k] > linear::DEFAULT_RANK_RTOL * largest)
        .collect();
    DMatrix::from_fn(rows, kept.len(), |i, j| u[(i, kept[j])])
}

/// yᵀ Z (ZᵀZ)⁺ Zᵀ y: the square of `y` that the columns `z` explain (zero columns, a channel
/// without readings, explain nothing).
fn explained_square(z: &[DVector<f64>], y: &DVector<f64>) -> f64 {
    let k = z.len();
    let gram = DMatrix::from_fn(k, k, |i, j| z[i].dot(&z[j]));
    let zy = DVector::from_fn(k, |i, _| z[i].dot(y));
    match gram.svd(true, true).solve(&zy, 1e-12) {
        Ok(coef) => coef.dot(&zy),
        Err(_) => 0.0,
    }
}

/// Fit the readings with `effects` at one warm-up τ: weights from a first unweighted pass, then
/// one weighted pass with σ per channel class, so that straightness (0.1–0.5 µm) does not drown
/// the linear reading (0.01–0.05 µm).
fn fit_at(
    readings: &[PlacedReading],
    block_labels: &[String],
    error_names: &[String; 6],
    effects: &[AxisEffect],
    warm_up_tau_h: Option<f64>,
) -> Result<ModelFit, LinearError> {
    let first = solve(
        readings,
        block_labels,
        error_names,
        effects,
        warm_up_tau_h,
        None,
    )?;
    let sigma = class_sigma(readings, &first);
    let weights: Vec<f64> = readings
        .iter()
        .map(|r| sigma[usize::from(!r.along)])
        .collect();
    let solution = solve(
        readings,
        block_labels,
        error_names,
        effects,
        warm_up_tau_h,
        Some(weights),
    )?;
    let sigma_um = class_sigma(readings, &solution);
    let rms_um = class_rms(readings, &solution);
    let bic = bic(readings, &solution);
    Ok(ModelFit {
        effects: effects.to_vec(),
        solution,
        sigma_um,
        bic,
        rms_um,
        warm_up_tau_h,
    })
}

fn solve(
    readings: &[PlacedReading],
    block_labels: &[String],
    error_names: &[String; 6],
    effects: &[AxisEffect],
    warm_up_tau_h: Option<f64>,
    sigma: Option<Vec<f64>>,
) -> Result<LinearSolution, LinearError> {
    let (names, rows) = design(readings, block_labels, error_names, effects, warm_up_tau_h);
    linear::solve(&LinearProblem {
        names,
        rows,
        observations: readings.iter().map(|r| r.deviation_um).collect(),
        sigma,
    })
}

/// The parameter names and design rows: six errors a block, then the effects' columns.
fn design(
    readings: &[PlacedReading],
    block_labels: &[String],
    error_names: &[String; 6],
    effects: &[AxisEffect],
    warm_up_tau_h: Option<f64>,
) -> (Vec<String>, Vec<Vec<f64>>) {
    let blocks = block_labels.len();
    let mut names: Vec<String> = block_labels
        .iter()
        .flat_map(|l| block_names(error_names, l))
        .collect();
    let columns = columns_of(effects);
    names.extend(columns.iter().map(|c| c.name.to_string()));
    let width = 6 * blocks + columns.len();
    let rows = readings
        .iter()
        .map(|r| {
            let mut row = vec![0.0; width];
            let design = design_row(r.channel, r.offset_mm);
            row[6 * r.block..6 * r.block + 6].copy_from_slice(&design);
            for (k, column) in columns.iter().enumerate() {
                if column.channel.is_none_or(|c| c == r.channel) {
                    row[6 * blocks + k] = r.regressor(column.regressor, warm_up_tau_h);
                }
            }
            row
        })
        .collect();
    (names, rows)
}

/// σ of each channel class (along, lateral) from the residuals: RSS over the class's share of
/// the degrees of freedom (at least one reading's worth).
fn class_sigma(readings: &[PlacedReading], s: &LinearSolution) -> [f64; 2] {
    let n = readings.len().max(1) as f64;
    let dof_share = s.dof as f64 / n;
    let (rss, count) = class_sums(readings, s);
    std::array::from_fn(|c| {
        let dof = (count[c] as f64 * dof_share).max(1.0);
        // A floor of 1 pm keeps an exactly fitting class from a zero weight.
        (rss[c] / dof).sqrt().max(1e-6)
    })
}

/// RSS and count of the residuals of each channel class (along, lateral).
fn class_sums(readings: &[PlacedReading], s: &LinearSolution) -> ([f64; 2], [usize; 2]) {
    let mut rss = [0.0; 2];
    let mut count = [0usize; 2];
    for (r, e) in readings.iter().zip(&s.residuals) {
        let c = usize::from(!r.along);
        rss[c] += e * e;
        count[c] += 1;
    }
    (rss, count)
}

fn class_rms(readings: &[PlacedReading], s: &LinearSolution) -> [f64; 2] {
    let (rss, count) = class_sums(readings, s);
    std::array::from_fn(|c| {
        if count[c] == 0 {
            0.0
        } else {
            (rss[c] / count[c] as f64).sqrt()
        }
    })
}

/// BIC = Σ_class n_c ln(RSS_c / n_c) + k ln n, k the rank (the parameters the readings
/// determine).
fn bic(readings: &[PlacedReading], s: &LinearSolution) -> f64 {
    let (rss, count) = class_sums(readings, s);
    let n = readings.len() as f64;
    let fit: f64 = (0..2)
        .filter(|&c| count[c] > 0)
        .map(|c| {
            let nc = count[c] as f64;
            nc * (rss[c] / nc).max(1e-30).ln()
        })
        .sum();
    fit + s.rank as f64 * n.ln()
}

/// RMS residual per (line, run, channel), µm: where the model fails, by set-up and pass.
pub(crate) fn residuals_by_line_run(
    readings: &[PlacedReading],
    s: &LinearSolution,
) -> BTreeMap<(i64, i64, Channel), (f64, usize)> {
    let mut acc: BTreeMap<(i64, i64, Channel), (f64, usize)> = BTreeMap::new();
    for (r, e) in readings.iter().zip(&s.residuals) {
        let slot = acc.entry((r.line, r.run, r.channel)).or_default();
        slot.0 += e * e;
        slot.1 += 1;
    }
    for v in acc.values_mut() {
        v.0 = (v.0 / v.1 as f64).sqrt();
    }
    acc
}
