//! The global model of a `roll` campaign (`docs/spec/machine-physics.md`, "Kind roll"): the seed's
//! estimator written as one weighted least-squares problem over every pass, the level datum and
//! the effects added so far, solved by the machine kinds' engine ([`crate::linear`]).
//!
//! Unknowns: εx(1) … εx(N) (εx(0) := 0, the datum), the level's zero when levels are read, one
//! parameter an effect. Rows:
//!
//! - a **step row** for every two dwells of one pass at stations n − 1 and n:
//!   10³ Q/L = (L_AC/L) εx(n) − (L_BD/L) εx(n − 1) + effects, Q = [m_C(n) − m_D(n−1)] −
//!   [m_A(n) − m_B(n−1)] (µm), L_AC = y_C − y_A and L_BD = y_D − y_B from the probes' positions
//!   (both L when nominal: the seed's eq. 10). σ = 10³ √(u_C² + u_D² + u_A² + u_B²)/L from the
//!   station means; two step rows share no reading, so the rows are independent;
//! - a **level row** per level reading at station n: roll = εx(n) + zero, σ its `u_urad`.
//!
//! One pass at nominal positions gives back eq. 10 exactly (tested). The uncertainty of εx(n)
//! is the a-priori covariance (from the station means' u), scaled up by √(χ²/ν) when the rows
//! are redundant and disagree more than their u say (never down). BIC = χ² + k ln(rows): the σ
//! are known, so χ² is the likelihood's data term *(ours)*.

use crate::linear::{self, LinearError, LinearProblem, LinearSolution};

use super::effects::RollEffect;

/// A step row before its effects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct StepRow {
    /// Pass index.
    pub(crate) pass: usize,
    /// Station n (the later of the two; ≥ 1).
    pub(crate) station: usize,
    /// Q, µm.
    pub(crate) q_um: f64,
    /// u(Q), µm.
    pub(crate) u_q_um: f64,
    /// Mid-times of the dwells at n and n − 1, hours since the first sample.
    pub(crate) t_h: (f64, f64),
}

/// A level reading placed at its station.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LevelObs {
    /// Station n.
    pub(crate) station: usize,
    /// roll, µrad.
    pub(crate) roll_urad: f64,
    /// σ, µrad.
    pub(crate) u_urad: f64,
    /// Hours since the first sample.
    pub(crate) t_h: f64,
}

/// The rig's geometry the rows need.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Geometry {
    /// Nominal L, mm.
    pub(crate) l_mm: f64,
    /// y_C − y_A, mm.
    pub(crate) l_ac_mm: f64,
    /// y_D − y_B, mm.
    pub(crate) l_bd_mm: f64,
    /// The largest station.
    pub(crate) stations: usize,
}

/// A fit of the global model with some effects.
#[derive(Debug, Clone)]
pub(crate) struct ModelFit {
    /// The effects, in the order added.
    pub(crate) effects: Vec<RollEffect>,
    /// The engine's solution: εx(1..N), then the level zero (if levels), then the effects.
    pub(crate) solution: LinearSolution,
    /// χ² of the weighted residuals.
    pub(crate) chi2: f64,
    /// BIC.
    pub(crate) bic: f64,
    /// How many rows are step rows (the rest are level rows).
    pub(crate) step_rows: usize,
}

/// The parameter name of εx(n).
pub(crate) fn roll_name(n: usize) -> String {
    format!("ex({n})")
}

/// The level zero's parameter name.
pub(crate) const LEVEL_ZERO: &str = "level_zero_urad";

/// Fit `steps` and `levels` with `effects`.
pub(crate) fn fit(
    steps: &[StepRow],
    levels: &[LevelObs],
    g: Geometry,
    effects: &[RollEffect],
) -> Result<ModelFit, LinearError> {
    let n_eps = g.stations;
    let has_levels = !levels.is_empty();
    let mut names: Vec<String> = (1..=n_eps).map(roll_name).collect();
    if has_levels {
        names.push(LEVEL_ZERO.into());
    }
    let first_effect = names.len();
    names.extend(effects.iter().map(|e| e.parameter_name().to_string()));
    let width = names.len();
    let k_now = g.l_ac_mm / g.l_mm;
    let k_before = -g.l_bd_mm / g.l_mm;
    let mut rows = Vec::new();
    let mut obs = Vec::new();
    let mut sigma = Vec::new();
    for s in steps {
        let mut row = vec![0.0; width];
        row[s.station - 1] = k_now;
        if s.station >= 2 {
            row[s.station - 2] = k_before;
        }
        for (j, e) in effects.iter().enumerate() {
            row[first_effect + j] = e.step_column(g.l_mm, (k_now, k_before), s.t_h);
        }
        rows.push(row);
        obs.push(1e3 * s.q_um / g.l_mm);
        sigma.push(1e3 * s.u_q_um / g.l_mm);
    }
    for l in levels {
        let mut row = vec![0.0; width];
        if l.station >= 1 {
            row[l.station - 1] = 1.0;
        }
        row[n_eps] = 1.0;
        for (j, e) in effects.iter().enumerate() {
            row[first_effect + j] = e.level_column(l.t_h);
        }
        rows.push(row);
        obs.push(l.roll_urad);
        sigma.push(l.u_urad);
    }
    let solution = linear::solve(&LinearProblem {
        names,
        rows,
        observations: obs,
        sigma: Some(sigma),
    })?;
    let chi2 = solution.rss_weighted;
    let n = (steps.len() + levels.len()) as f64;
    let bic = chi2 + solution.rank as f64 * n.ln();
    Ok(ModelFit {
        effects: effects.to_vec(),
        solution,
        chi2,
        bic,
        step_rows: steps.len(),
    })
}

impl ModelFit {
    /// √(χ²/ν) when the rows are redundant and it exceeds 1, else 1.
    pub(crate) fn scale(&self) -> f64 {
        let dof = self.solution.dof;
        if dof == 0 {
            return 1.0;
        }
        (self.chi2 / dof as f64).sqrt().max(1.0)
    }

    /// εx(n) and its standard uncertainty, µrad; `None` where not determined.
    pub(crate) fn roll(&self, n: usize) -> Option<(f64, f64)> {
        if n == 0 {
            return Some((0.0, 0.0));
        }
        let s = &self.solution;
        let k = n - 1;
        if !s.determined[k] {
            return None;
        }
        let cov = s.covariance_given.as_ref()?;
        Some((s.estimate[k], cov[(k, k)].max(0.0).sqrt() * self.scale()))
    }

    /// An effect's value and standard uncertainty; `None` when not determined.
    pub(crate) fn effect_value(&self, e: RollEffect) -> Option<(f64, f64)> {
        let s = &self.solution;
        let k = s.index(e.parameter_name())?;
        if !s.determined[k] {
            return None;
        }
        let cov = s.covariance_given.as_ref()?;
        Some((s.estimate[k], cov[(k, k)].max(0.0).sqrt() * self.scale()))
    }

    /// Whether every effect's parameter is determined.
    pub(crate) fn effects_determined(&self) -> bool {
        self.effects.iter().all(|e| self.effect_value(*e).is_some())
    }
}
