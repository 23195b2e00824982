//! The global model of an `axis` campaign's readings (`docs/spec/machine-physics.md`, "Kind
//! axis"): every reading, of every line, run and direction, is one channel of
//! Δ(p_l) = δ(x, d) + 10⁻³ ε(x, d) × p_l, the six errors free at each (target, direction), plus
//! the effects added so far. Six errors per target are exactly determined by one run of the
//! patent's three lines; the runs repeat them, and what differs between runs (in time, in the
//! air) is what an effect explains.

use std::collections::BTreeMap;

use crate::axis::{design_row, Channel};
use crate::linear::{self, LinearError, LinearProblem, LinearSolution};

use super::effects::AxisEffect;

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
    /// The effects' regressors at this reading (one value a column of [`AxisEffect::columns`]).
    pub(crate) regressors: [f64; super::effects::REGRESSORS],
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
}

/// The parameter names of block `b`: its six error names `@` the block's label.
pub(crate) fn block_names(names: &[String; 6], label: &str) -> Vec<String> {
    names.iter().map(|n| format!("{n}@{label}")).collect()
}

/// Fit the readings with `effects`: weights from a first unweighted pass, then one weighted
/// pass with σ per channel class, so that straightness (0.1–0.5 µm) does not drown the linear
/// reading (0.01–0.05 µm).
pub(crate) fn fit(
    readings: &[PlacedReading],
    block_labels: &[String],
    error_names: &[String; 6],
    effects: &[AxisEffect],
) -> Result<ModelFit, LinearError> {
    let first = solve(readings, block_labels, error_names, effects, None)?;
    let sigma = class_sigma(readings, &first);
    let weights: Vec<f64> = readings
        .iter()
        .map(|r| sigma[usize::from(!r.along)])
        .collect();
    let solution = solve(readings, block_labels, error_names, effects, Some(weights))?;
    let sigma_um = class_sigma(readings, &solution);
    let rms_um = class_rms(readings, &solution);
    let bic = bic(readings, &solution);
    Ok(ModelFit {
        effects: effects.to_vec(),
        solution,
        sigma_um,
        bic,
        rms_um,
    })
}

fn solve(
    readings: &[PlacedReading],
    block_labels: &[String],
    error_names: &[String; 6],
    effects: &[AxisEffect],
    sigma: Option<Vec<f64>>,
) -> Result<LinearSolution, LinearError> {
    let blocks = block_labels.len();
    let mut names: Vec<String> = block_labels
        .iter()
        .flat_map(|l| block_names(error_names, l))
        .collect();
    let columns: Vec<(usize, Option<Channel>)> = effects
        .iter()
        .flat_map(|e| e.columns().iter().copied())
        .collect();
    names.extend(
        effects
            .iter()
            .flat_map(|e| e.parameter_names().iter().map(|n| n.to_string())),
    );
    let width = 6 * blocks + columns.len();
    let rows = readings
        .iter()
        .map(|r| {
            let mut row = vec![0.0; width];
            let design = design_row(r.channel, r.offset_mm);
            row[6 * r.block..6 * r.block + 6].copy_from_slice(&design);
            for (k, &(regressor, channel)) in columns.iter().enumerate() {
                if channel.is_none_or(|c| c == r.channel) {
                    row[6 * blocks + k] = r.regressors[regressor];
                }
            }
            row
        })
        .collect();
    linear::solve(&LinearProblem {
        names,
        rows,
        observations: readings.iter().map(|r| r.deviation_um).collect(),
        sigma,
    })
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
