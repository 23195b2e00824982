//! The loop for the six-bar device (`docs/spec/machine-physics.md`, "Hexapod"): compare the
//! legs' lengths with what the model says they should be, see where they fail, name the missing
//! effect from the spec's catalogue, add it, watch the error fall.
//!
//! Six lengths give six pose errors and no residual at one dwell, so the model can only be
//! checked across *repeated* dwells: a test visits each station in each direction once per run,
//! and the machine's geometric errors repeat there. The base model therefore gives each leg one
//! free length per (station, approach direction) group; what the lengths do beyond that, from
//! run to run and in time, is the residual, in µm per leg. The catalogue's effects act on it:
//!
//! | effect | in the legs (µm) | parameters |
//! |---|---|---|
//! | `machine_drift` | J_k (g_δ, g_ε) · h_k: the tool point drifting in time | 3 µm/h, 3 µrad/h |
//! | `machine_warm_up` | J_k (q_δ, q_ε) · [τ (1 − e^(−h_k/τ)) − h_k]: the drift levelling off, as a machine warming towards its steady state does (τ searched, 0.25–48 h) | 3 µm/h, 3 µrad/h; τ |
//! | `body_expansion` | (∂l_i/∂s) · c · (T_k − T0): the rings' expansion not declared | c, ppm/K |
//! | `reseated_leg` | a step s in one leg from one dwell on (a socket re-seated) | s, µm (leg and dwell searched) |
//!
//! with J_k the leg Jacobian at dwell k (µm per µm and µrad), h_k hours since the datum dwell,
//! and ∂l_i/∂s = n_i · (R p_i − b_i) µm per ppm the legs' change when both rings grow by one
//! ppm about their centres *(ours)*. A candidate is screened by its BIC gain
//! (Δ = n ln(RSS/RSS') − Δp ln n); the re-seated leg's search over N = 6 legs × every dwell
//! pays 2 ln N more, the size the largest of N noise-only χ² gains reaches. A candidate is
//! proposed only when it is also *material*: its fitted change to some leg at some dwell reaches
//! `min_effect_um` (0.1 µm by default, a tenth of the patent's ±1 µm). Slow residues of the
//! bars' thermal compensation are time-correlated, so the BIC alone (which assumes independent
//! residuals) finds nanometre "drifts" in any long test. An effect in the model is fitted and its contribution removed from
//! every dwell's lengths before the poses are solved again (the datum's too), so the six errors
//! are those of the machine's geometry at the datum's time and temperature.
//!
//! What repeats cannot show is listed by name: a joint-centre error is the same at every visit
//! of a station (it bends the six errors by about u_joint · displacement / leg length), sag
//! follows the tilt, and a clock offset between controller and logger cuts into the moves.

use nalgebra::{DMatrix, DVector, Vector3};

use crate::hexapod::Hexapod;
use crate::pose::Pose;

/// An effect of the catalogue the device's loop can test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum DeviceEffect {
    /// The machine's functional point drifting in time (thermal drift during the test).
    MachineDrift,
    /// The drift levelling off during the test: a machine warming up towards its thermal
    /// steady state drifts like 1 − e^(−t/τ), which a constant rate leaves a curve of (the
    /// second simulator's warm-up, `tests/e2e/device_foreign.rs`: `machine_drift` alone brings
    /// 0.32 µm down to 0.041 µm only, and `reseated_leg` is then proposed to soak up the
    /// curve). τ is
    /// searched: a quadratic in time followed a drift that levels off within the test (τ = 1 h
    /// over 4 h of our simulator's test) no better than to 0.038 µm.
    MachineWarmUp,
    /// The base and platform rings expanding more (or less) than declared.
    BodyExpansion,
    /// A leg's socket re-seated during the test: a step in that leg's length.
    ReseatedLeg,
}

impl DeviceEffect {
    /// Every effect, in the order the loop tries them.
    pub const ALL: [DeviceEffect; 4] = [
        DeviceEffect::MachineDrift,
        DeviceEffect::MachineWarmUp,
        DeviceEffect::BodyExpansion,
        DeviceEffect::ReseatedLeg,
    ];

    /// The name `--add-effect` and `[device] effects` take.
    pub fn name(self) -> &'static str {
        match self {
            DeviceEffect::MachineDrift => "machine_drift",
            DeviceEffect::MachineWarmUp => "machine_warm_up",
            DeviceEffect::BodyExpansion => "body_expansion",
            DeviceEffect::ReseatedLeg => "reseated_leg",
        }
    }

    /// The physics, in words.
    pub fn physics(self) -> &'static str {
        match self {
            DeviceEffect::MachineDrift => {
                "machine thermal drift during the test (the tool point moving in time)"
            }
            DeviceEffect::MachineWarmUp => {
                "the drift's rate changing during the test (a machine warming up towards steady state)"
            }
            DeviceEffect::BodyExpansion => {
                "base and platform expansion not declared (cte_ppm_per_k of the rings)"
            }
            DeviceEffect::ReseatedLeg => "a socket re-seated: a step in one leg's length",
        }
    }

    /// The effect named `name`, if any.
    pub fn parse(name: &str) -> Option<DeviceEffect> {
        Self::ALL.into_iter().find(|e| e.name() == name)
    }
}

/// One dwell's legs, as the device test measured them.
#[derive(Debug, Clone, PartialEq)]
pub struct DwellLegs {
    /// Hours since the datum dwell's start.
    pub hours: f64,
    /// Station and approach direction along the moved axis: the dwells that must agree.
    pub group: (i64, i8),
    /// The legs' lengths, mm.
    pub lengths_mm: [f64; 6],
    /// The rings' temperature above the reference temperature, K.
    pub body_excess_k: f64,
    /// The leg Jacobian at the dwell's pose, µm per (µm, µm, µm, µrad, µrad, µrad).
    pub jacobian_um: [[f64; 6]; 6],
    /// Each leg's change when both rings grow by 1 ppm about their centres, µm.
    pub strain_um_per_ppm: [f64; 6],
}

impl DwellLegs {
    /// The dwell's sensitivities from the device (at the dwell's temperature) and its pose.
    pub fn at_pose(
        device: &Hexapod,
        pose: &Pose,
        hours: f64,
        group: (i64, i8),
        lengths_mm: [f64; 6],
        body_excess_k: f64,
    ) -> DwellLegs {
        let j = device.jacobian_um_urad(pose);
        let centroid = |ring: &[[f64; 3]; 6]| -> Vector3<f64> {
            ring.iter().map(|p| Vector3::from(*p)).sum::<Vector3<f64>>() / 6.0
        };
        let (cb, cp) = (centroid(&device.base_mm), centroid(&device.platform_mm));
        let rot = pose.rotation();
        let legs = device.leg_vectors_mm(pose);
        let strain_um_per_ppm = std::array::from_fn(|i| {
            let n = legs[i] / legs[i].norm();
            let grown = rot * (Vector3::from(device.platform_mm[i]) - cp)
                - (Vector3::from(device.base_mm[i]) - cb);
            // 1 ppm of growth moves the legs by n · grown · 1e-6 mm.
            n.dot(&grown) * 1e-3
        });
        DwellLegs {
            hours,
            group,
            lengths_mm,
            body_excess_k,
            jacobian_um: std::array::from_fn(|i| std::array::from_fn(|c| j[(i, c)])),
            strain_um_per_ppm,
        }
    }
}

/// Options of [`study`].
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceStudyOptions {
    /// Effects in the model.
    pub effects: Vec<DeviceEffect>,
    /// The BIC gain an effect must bring to be proposed.
    pub min_bic_gain: f64,
    /// The largest change an effect must make to some leg at some dwell, µm, to be proposed:
    /// below it the effect is real but does not matter to the six errors.
    pub min_effect_um: f64,
}

impl Default for DeviceStudyOptions {
    fn default() -> Self {
        DeviceStudyOptions {
            effects: Vec::new(),
            min_bic_gain: 10.0,
            min_effect_um: 0.1,
        }
    }
}

/// A fitted effect.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceEffectFit {
    /// Which.
    pub effect: DeviceEffect,
    /// Parameters: name, value and U (k = 2), in the units their names say.
    pub parameters: Vec<(String, f64, f64)>,
}

/// A candidate effect against the model in use.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceCandidate {
    /// Which.
    pub effect: DeviceEffect,
    /// BIC gain of adding it (positive: better).
    pub delta_bic: f64,
    /// RMS residual of the legs with it, µm.
    pub rms_um: f64,
    /// Its largest change to a leg at a dwell, as fitted, µm (what makes it material).
    pub size_um: f64,
    /// Where it acts (e.g. "leg 3 from dwell 27"), when that is part of the fit.
    pub detail: Option<String>,
}

impl DeviceCandidate {
    /// Whether it is both significant and material under `options`.
    pub fn proposed(&self, options: &DeviceStudyOptions) -> bool {
        self.delta_bic >= options.min_bic_gain && self.size_um >= options.min_effect_um
    }
}

/// One step of the forward selection.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceLedgerStep {
    /// The effect added at this step (`None`: the model in use).
    pub effect: Option<DeviceEffect>,
    /// RMS residual of the legs, µm.
    pub rms_um: f64,
    /// BIC gain of the step.
    pub delta_bic: f64,
}

/// The device's loop, run.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceStudy {
    /// The effects of the model, fitted.
    pub effects: Vec<DeviceEffectFit>,
    /// Per dwell (in the input's order), the model's effects on each leg, µm: subtracted from
    /// the lengths before the poses are solved again. Zero without effects.
    pub corrections_um: Vec<[f64; 6]>,
    /// RMS residual of the legs about their groups, µm, with the model's effects.
    pub rms_um: f64,
    /// Residual per leg, RMS µm.
    pub rms_per_leg_um: [f64; 6],
    /// Values that can disagree (legs × dwells in groups of two or more) and the groups.
    pub redundant: usize,
    /// Groups of two or more dwells.
    pub groups: usize,
    /// Candidates not in the model, best first.
    pub candidates: Vec<DeviceCandidate>,
    /// Forward selection from the model.
    pub ledger: Vec<DeviceLedgerStep>,
    /// The effect to add: the best candidate that gains at least `min_bic_gain` and changes a
    /// leg by at least `min_effect_um`.
    pub proposal: Option<DeviceEffect>,
    /// What repeated dwells cannot show, as (effect, what it becomes).
    pub unseen: Vec<(&'static str, &'static str)>,
}

/// Why the loop cannot run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DeviceStudyError {
    /// No station was visited twice in the same direction.
    #[error("no station was visited twice in the same direction: the legs cannot be compared (run the test with at least two runs)")]
    NoRepeats,
}

/// A regressor block: columns over (dwell, leg) rows, and their parameter names.
struct Block {
    columns: Vec<Vec<f64>>,
    names: Vec<String>,
    detail: Option<String>,
    /// The re-seated leg's step: (leg index, first dwell).
    step: Option<(usize, usize)>,
    /// The warm-up's time constant, h.
    tau_h: Option<f64>,
    /// The block's BIC penalty beyond ln n per parameter: a search's look-elsewhere cost.
    search_penalty: f64,
}

/// The six names of a drift-like block, per unit of `per` (`h`: µm/h and µrad/h).
fn six_names(per: &str) -> Vec<String> {
    ["dx", "dy", "dz"]
        .map(|c| format!("{c}_um_per_{per}"))
        .into_iter()
        .chain(["ex", "ey", "ez"].map(|c| format!("{c}_urad_per_{per}")))
        .collect()
}

/// J_k · f(h_k), one column per component of the tool point's motion.
fn drift_columns(dwells: &[DwellLegs], g: &[Vec<usize>], f: impl Fn(f64) -> f64) -> Vec<Vec<f64>> {
    (0..6)
        .map(|c| within(g, |k, i| dwells[k].jacobian_um[i][c] * f(dwells[k].hours)))
        .collect()
}

/// The warm-up whose τ, fitted with a constant rate beside it, explains most of `y`; τ is a
/// parameter of the fit (its search pays ln n in the BIC).
fn best_warm_up(dwells: &[DwellLegs], g: &[Vec<usize>], y: &[f64]) -> Block {
    let linear = drift_columns(dwells, g, |h| h);
    let mut best: Option<(f64, f64, Vec<Vec<f64>>)> = None;
    for tau in crate::warm_up::tau_grid_h() {
        let curve = drift_columns(dwells, g, |h| crate::warm_up::departure_h(h, tau));
        let both: Vec<Vec<f64>> = linear.iter().chain(&curve).cloned().collect();
        let (_, _, rss) = fit(&both, y);
        if best.as_ref().is_none_or(|b| rss < b.0) {
            best = Some((rss, tau, curve));
        }
    }
    let (tau, columns) = best.map_or((1.0, drift_columns(dwells, g, |_| 0.0)), |b| (b.1, b.2));
    Block {
        columns,
        names: six_names("h_levelled"),
        detail: Some(format!("τ = {tau:.2} h")),
        step: None,
        tau_h: Some(tau),
        search_penalty: (y.len().max(2) as f64).ln(),
    }
}

/// Dwells grouped: each group's dwell indices, for groups of two or more.
fn groups(dwells: &[DwellLegs]) -> Vec<Vec<usize>> {
    let mut by: std::collections::BTreeMap<(i64, i8), Vec<usize>> = Default::default();
    for (k, d) in dwells.iter().enumerate() {
        by.entry(d.group).or_default().push(k);
    }
    by.into_values().filter(|g| g.len() >= 2).collect()
}

/// Values per (dwell, leg) minus their group's mean, over the grouped dwells: row order is
/// group by group, dwell by dwell, leg by leg.
fn within(groups: &[Vec<usize>], value: impl Fn(usize, usize) -> f64) -> Vec<f64> {
    let mut out = Vec::new();
    for g in groups {
        for leg in 0..6 {
            let mean = g.iter().map(|&k| value(k, leg)).sum::<f64>() / g.len() as f64;
            out.extend(g.iter().map(|&k| value(k, leg) - mean));
        }
    }
    out
}

fn block(dwells: &[DwellLegs], effect: DeviceEffect, g: &[Vec<usize>], y: &[f64]) -> Block {
    match effect {
        DeviceEffect::MachineDrift => Block {
            columns: drift_columns(dwells, g, |h| h),
            names: six_names("h"),
            detail: None,
            step: None,
            tau_h: None,
            search_penalty: 0.0,
        },
        DeviceEffect::MachineWarmUp => best_warm_up(dwells, g, y),
        DeviceEffect::BodyExpansion => Block {
            columns: vec![within(g, |k, i| {
                dwells[k].strain_um_per_ppm[i] * dwells[k].body_excess_k
            })],
            names: vec!["cte_error_ppm_per_k".into()],
            detail: None,
            step: None,
            tau_h: None,
            search_penalty: 0.0,
        },
        DeviceEffect::ReseatedLeg => best_step(dwells, g, y),
    }
}

/// The step in one leg from one dwell on that explains most of `y` (the residual of the model
/// in use): every leg and every dwell after the first is tried.
fn best_step(dwells: &[DwellLegs], g: &[Vec<usize>], y: &[f64]) -> Block {
    let mut best: Option<(f64, usize, usize, Vec<f64>)> = None;
    for leg in 0..6 {
        for from in 1..dwells.len() {
            let col = within(g, |k, i| f64::from(u8::from(i == leg && k >= from)));
            let ss: f64 = col.iter().map(|v| v * v).sum();
            if ss <= 0.0 {
                continue;
            }
            let dot: f64 = col.iter().zip(y).map(|(a, b)| a * b).sum();
            let gain = dot * dot / ss;
            if best.as_ref().is_none_or(|b| gain > b.0) {
                best = Some((gain, leg, from, col));
            }
        }
    }
    let (leg, from, col) = best.map_or((0, 0, vec![0.0; y.len()]), |b| (b.1, b.2, b.3));
    Block {
        columns: vec![col],
        names: vec![format!("leg{}_step_um", leg + 1)],
        detail: Some(format!("leg {} from dwell {}", leg + 1, from)),
        step: Some((leg, from)),
        tau_h: None,
        // The largest of N tried steps' χ² gains grows like 2 ln N on noise alone.
        search_penalty: 2.0 * ((6 * dwells.len().saturating_sub(1)).max(1) as f64).ln(),
    }
}

/// Least squares of `y` on the columns: (coefficients, their covariance scale (AᵀA)⁻¹, RSS).
fn fit(columns: &[Vec<f64>], y: &[f64]) -> (Vec<f64>, DMatrix<f64>, f64) {
    let rss0: f64 = y.iter().map(|v| v * v).sum();
    if columns.is_empty() {
        return (Vec::new(), DMatrix::zeros(0, 0), rss0);
    }
    let a = DMatrix::from_fn(y.len(), columns.len(), |r, c| columns[c][r]);
    let b = DVector::from_column_slice(y);
    let svd = a.clone().svd(true, true);
    let x = svd
        .solve(&b, 1e-12 * svd.singular_values.max())
        .unwrap_or_else(|_| DVector::zeros(columns.len()));
    let r = &b - &a * &x;
    let ata = a.transpose() * &a;
    let cov = ata
        .pseudo_inverse(1e-12)
        .unwrap_or_else(|_| DMatrix::zeros(columns.len(), columns.len()));
    (x.iter().copied().collect(), cov, r.norm_squared())
}

/// BIC of a model with `parameters` and an extra `search_penalty`.
fn bic(n: usize, rss: f64, (parameters, search_penalty): (f64, f64)) -> f64 {
    let n = n as f64;
    n * (rss.max(1e-300) / n).ln() + parameters * n.ln() + search_penalty
}

/// The model's blocks for `effects` (a re-seated leg searched against the residual left by the
/// others).
fn model_blocks(
    dwells: &[DwellLegs],
    g: &[Vec<usize>],
    y: &[f64],
    effects: &[DeviceEffect],
) -> Vec<(DeviceEffect, Block)> {
    let mut blocks: Vec<(DeviceEffect, Block)> = effects
        .iter()
        .filter(|e| **e != DeviceEffect::ReseatedLeg)
        .map(|&e| (e, block(dwells, e, g, y)))
        .collect();
    if effects.contains(&DeviceEffect::ReseatedLeg) {
        let cols: Vec<Vec<f64>> = blocks.iter().flat_map(|b| b.1.columns.clone()).collect();
        let (x, _, _) = fit(&cols, y);
        let residual: Vec<f64> = (0..y.len())
            .map(|r| y[r] - cols.iter().zip(&x).map(|(c, v)| c[r] * v).sum::<f64>())
            .collect();
        blocks.push((
            DeviceEffect::ReseatedLeg,
            block(dwells, DeviceEffect::ReseatedLeg, g, &residual),
        ));
    }
    blocks
}

/// (RSS, (parameters, search penalty)) of a model's blocks.
fn score(blocks: &[(DeviceEffect, Block)], y: &[f64]) -> (f64, (f64, f64)) {
    let cols: Vec<Vec<f64>> = blocks.iter().flat_map(|b| b.1.columns.clone()).collect();
    let (_, _, rss) = fit(&cols, y);
    let penalty = blocks.iter().map(|b| b.1.search_penalty).sum();
    (rss, (cols.len() as f64, penalty))
}

/// Run the loop over the dwells (in time order; `datum` is the datum dwell).
pub fn study(
    dwells: &[DwellLegs],
    options: &DeviceStudyOptions,
) -> Result<DeviceStudy, DeviceStudyError> {
    let g = groups(dwells);
    if g.is_empty() {
        return Err(DeviceStudyError::NoRepeats);
    }
    let y = within(&g, |k, i| dwells[k].lengths_mm[i] * 1e3);
    let n = y.len();
    let dof = n - g.len() * 6;
    let model = model_blocks(dwells, &g, &y, &options.effects);
    let (rss, cost) = score(&model, &y);
    let rms = |rss: f64| (rss / n as f64).sqrt();
    let mut candidates: Vec<DeviceCandidate> = DeviceEffect::ALL
        .into_iter()
        .filter(|e| !options.effects.contains(e))
        .map(|e| {
            let mut with = options.effects.clone();
            with.push(e);
            let blocks = model_blocks(dwells, &g, &y, &with);
            let (rss_c, cost_c) = score(&blocks, &y);
            let (_, corrections) = fitted(dwells, &y, &blocks, dof, Some(e));
            DeviceCandidate {
                effect: e,
                delta_bic: bic(n, rss, cost) - bic(n, rss_c, cost_c),
                rms_um: rms(rss_c),
                size_um: corrections
                    .iter()
                    .flat_map(|c| c.iter().map(|v| v.abs()))
                    .fold(0.0, f64::max),
                detail: blocks
                    .iter()
                    .find(|b| b.0 == e)
                    .and_then(|b| b.1.detail.clone()),
            }
        })
        .collect();
    candidates.sort_by(|a, b| b.delta_bic.total_cmp(&a.delta_bic));
    let ledger = forward(dwells, &g, &y, options, (rss, cost), dof);
    let proposal = candidates
        .iter()
        .find(|c| c.proposed(options))
        .map(|c| c.effect);
    let (effects, corrections_um) = fitted(dwells, &y, &model, dof, None);
    let residual = residual_of(&model, &y);
    let rms_per_leg_um = per_leg(&g, &residual);
    Ok(DeviceStudy {
        effects,
        corrections_um,
        rms_um: rms(rss),
        rms_per_leg_um,
        redundant: dof,
        groups: g.len(),
        candidates,
        ledger,
        proposal,
        unseen: vec![
            ("joint-centre error", "the same at every visit of a station: it bends the six errors by about u_joint · displacement / leg length, which no repeat shows; only a second set-up (the device turned, or moved on the table) separates it"),
            ("sag against tilt", "follows each leg's tilt, which repeats with the pose: read as the axis's errors"),
            ("controller-logger clock offset", "dwell windows cut into the moves: a difference between approach directions, read as reversal"),
        ],
    })
}

/// Greedy forward selection from the model while an effect gains at least `min_bic_gain`.
fn forward(
    dwells: &[DwellLegs],
    g: &[Vec<usize>],
    y: &[f64],
    options: &DeviceStudyOptions,
    (rss, cost): (f64, (f64, f64)),
    dof: usize,
) -> Vec<DeviceLedgerStep> {
    let n = y.len();
    let rms = |rss: f64| (rss / n as f64).sqrt();
    let mut ledger = vec![DeviceLedgerStep {
        effect: None,
        rms_um: rms(rss),
        delta_bic: 0.0,
    }];
    let mut in_model = options.effects.clone();
    let mut current = bic(n, rss, cost);
    loop {
        let best = DeviceEffect::ALL
            .into_iter()
            .filter(|e| !in_model.contains(e))
            .filter_map(|e| {
                let mut with = in_model.clone();
                with.push(e);
                let blocks = model_blocks(dwells, g, y, &with);
                let (r, c) = score(&blocks, y);
                let (_, size) = fitted(dwells, y, &blocks, dof, Some(e));
                let size = size.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
                (size >= options.min_effect_um).then_some((e, bic(n, r, c), r))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        match best {
            Some((e, b, r)) if current - b >= options.min_bic_gain => {
                ledger.push(DeviceLedgerStep {
                    effect: Some(e),
                    rms_um: rms(r),
                    delta_bic: current - b,
                });
                in_model.push(e);
                current = b;
            }
            _ => return ledger,
        }
    }
}

fn residual_of(blocks: &[(DeviceEffect, Block)], y: &[f64]) -> Vec<f64> {
    let cols: Vec<Vec<f64>> = blocks.iter().flat_map(|b| b.1.columns.clone()).collect();
    let (x, _, _) = fit(&cols, y);
    (0..y.len())
        .map(|r| y[r] - cols.iter().zip(&x).map(|(c, v)| c[r] * v).sum::<f64>())
        .collect()
}

fn per_leg(g: &[Vec<usize>], residual: &[f64]) -> [f64; 6] {
    let mut ss = [0.0; 6];
    let mut count = [0usize; 6];
    let mut r = 0;
    for grp in g {
        for leg in 0..6 {
            for _ in grp {
                ss[leg] += residual[r] * residual[r];
                count[leg] += 1;
                r += 1;
            }
        }
    }
    std::array::from_fn(|i| (ss[i] / count[i].max(1) as f64).sqrt())
}

/// The model's effects fitted (values, U from the residual scatter) and their contribution to
/// every dwell's legs (not group-centred: the correction of the lengths themselves), of every
/// effect or of `only` that one.
fn fitted(
    dwells: &[DwellLegs],
    y: &[f64],
    model: &[(DeviceEffect, Block)],
    dof: usize,
    only: Option<DeviceEffect>,
) -> (Vec<DeviceEffectFit>, Vec<[f64; 6]>) {
    let cols: Vec<Vec<f64>> = model.iter().flat_map(|b| b.1.columns.clone()).collect();
    let mut corrections = vec![[0.0; 6]; dwells.len()];
    if cols.is_empty() {
        return (Vec::new(), corrections);
    }
    let (x, cov, rss) = fit(&cols, y);
    let s2 = rss / dof.saturating_sub(cols.len()).max(1) as f64;
    let mut fits = Vec::new();
    let mut c = 0;
    for (effect, b) in model {
        let params: Vec<(String, f64, f64)> = b
            .names
            .iter()
            .enumerate()
            .map(|(j, name)| {
                let u = 2.0 * (cov[(c + j, c + j)] * s2).max(0.0).sqrt();
                (name.clone(), x[c + j], u)
            })
            .collect();
        if only.is_none_or(|o| o == *effect) {
            for (k, d) in dwells.iter().enumerate() {
                for (leg, corr) in corrections[k].iter_mut().enumerate() {
                    *corr += contribution(d, k, leg, *effect, b, &x[c..c + b.names.len()]);
                }
            }
        }
        c += b.names.len();
        fits.push(DeviceEffectFit {
            effect: *effect,
            parameters: params,
        });
    }
    (fits, corrections)
}

/// One effect's contribution to leg `leg` of dwell `k`, µm, from its fitted parameters.
fn contribution(
    d: &DwellLegs,
    k: usize,
    leg: usize,
    effect: DeviceEffect,
    b: &Block,
    x: &[f64],
) -> f64 {
    match effect {
        DeviceEffect::MachineDrift => (0..6).map(|c| d.jacobian_um[leg][c] * d.hours * x[c]).sum(),
        DeviceEffect::MachineWarmUp => {
            let tau = b.tau_h.unwrap_or(f64::INFINITY);
            (0..6)
                .map(|c| d.jacobian_um[leg][c] * crate::warm_up::departure_h(d.hours, tau) * x[c])
                .sum()
        }
        DeviceEffect::BodyExpansion => d.strain_um_per_ppm[leg] * d.body_excess_k * x[0],
        DeviceEffect::ReseatedLeg => match b.step {
            Some((step_leg, from)) if leg == step_leg && k >= from => x[0],
            _ => 0.0,
        },
    }
}

#[cfg(test)]
mod tests;
