//! The global model of one stylus on one artefact (`docs/spec/machine-physics.md`, "Kind
//! `probe`", "Touch k"): every touch's observed pretravel y_k (µm, relative to a reference
//! centre C₀) is
//!
//! ```text
//! y_k = δ̄ + ΔC · a_k [+ t · a_k rotated into the probe] + lobing(φ_k − spindle_k) + effects + noise
//! ```
//!
//! ΔC the centre's offset from C₀ (µm; fitted even when the centre is declared: it is then the
//! 1st harmonic the declared centre leaves), t a tip offset in the probe's frame (only with
//! spindle orientations 180° apart), and the lobing either harmonic (cos 3ψ, sin 3ψ) or
//! physical (seed eqs. 10–11: δ_min / cos(60° − ψ'), ψ' = (ψ − φ₀) mod 120°, φ₀ profiled).
//! Solved by [`crate::linear`], which names what the touches cannot see.

use crate::linear::{self, LinearError, LinearProblem, LinearSolution};

use super::effects::{self, ProbeEffect, TouchInputs};

/// How the lobing is modelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lobing {
    /// The seed's physical three-lobe (eqs. 10–11): δ_min and the seat phase φ₀.
    Physical,
    /// The 3rd harmonic (cos 3ψ, sin 3ψ) in the probe's frame.
    Harmonic,
}

impl Lobing {
    /// `physical` or `harmonic`.
    pub fn name(self) -> &'static str {
        match self {
            Lobing::Physical => "physical",
            Lobing::Harmonic => "harmonic",
        }
    }

    /// The lobing called `name`.
    pub fn parse(name: &str) -> Option<Lobing> {
        [Lobing::Physical, Lobing::Harmonic]
            .into_iter()
            .find(|l| l.name() == name)
    }
}

/// The seed's three-lobe shape (eqs. 10–11) relative to δ_min: 1 / cos(60° − ψ'),
/// ψ' = ψ mod 120° (1 at 60°, 2 at 0° and 120°).
pub fn three_lobe_shape(psi_deg: f64) -> f64 {
    let p = psi_deg.rem_euclid(120.0);
    1.0 / (60.0 - p).to_radians().cos()
}

/// The model's structure.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ModelSpec {
    /// 2 (ring) or 3 (sphere) centre columns.
    pub(crate) centre_dims: usize,
    /// Whether a tip offset in the probe's frame is fitted (spindle pairs 180° apart).
    pub(crate) tip_offset: bool,
    /// The lobing model.
    pub(crate) lobing: Lobing,
    /// Effects added.
    pub(crate) effects: Vec<ProbeEffect>,
    /// Directions of the setup.
    pub(crate) directions: usize,
}

/// A fitted model.
#[derive(Debug, Clone)]
pub(crate) struct ModelFit {
    pub(crate) spec: ModelSpec,
    pub(crate) solution: LinearSolution,
    /// The seat phase φ₀ (physical lobing), degrees, and its U (k = 2); NaN where not fixed.
    pub(crate) phi0_deg: Option<(f64, f64)>,
    /// BIC.
    pub(crate) bic: f64,
    /// RMS residual of first touches and of the others, µm.
    pub(crate) rms_um: [f64; 2],
}

/// The column names of `spec`.
pub(crate) fn names(spec: &ModelSpec) -> Vec<String> {
    let mut n = vec!["pretravel_mean_um".to_string()];
    for axis in ["x", "y", "z"].iter().take(spec.centre_dims) {
        n.push(format!("centre_{axis}_um"));
    }
    if spec.tip_offset {
        n.push("tip_offset_x_um".into());
        n.push("tip_offset_y_um".into());
    }
    match spec.lobing {
        Lobing::Physical => n.push("lobe_delta_min_um".into()),
        Lobing::Harmonic => {
            n.push("lobe3_cos_um".into());
            n.push("lobe3_sin_um".into());
        }
    }
    for e in &spec.effects {
        n.extend(effects::column_names(*e, spec.directions));
    }
    n
}

/// One touch's design row.
pub(crate) fn row(spec: &ModelSpec, t: &TouchInputs, phi0_deg: f64) -> Vec<f64> {
    let mut r = vec![1.0];
    r.extend(t.a.iter().take(spec.centre_dims));
    let psi = t.phi_deg - t.spindle_deg;
    if spec.tip_offset {
        let p = psi.to_radians();
        r.push(p.cos());
        r.push(p.sin());
    }
    match spec.lobing {
        Lobing::Physical => r.push(three_lobe_shape(psi - phi0_deg)),
        Lobing::Harmonic => {
            let p = 3.0 * psi.to_radians();
            r.push(p.cos());
            r.push(p.sin());
        }
    }
    for e in &spec.effects {
        r.extend(effects::columns(*e, t, spec.directions));
    }
    r
}

fn solve_at(
    spec: &ModelSpec,
    touches: &[TouchInputs],
    y_um: &[f64],
    phi0_deg: f64,
) -> Result<LinearSolution, LinearError> {
    linear::solve(&LinearProblem {
        names: names(spec),
        rows: touches.iter().map(|t| row(spec, t, phi0_deg)).collect(),
        observations: y_um.to_vec(),
        sigma: None,
    })
}

fn rss(s: &LinearSolution) -> f64 {
    s.residuals.iter().map(|e| e * e).sum()
}

/// Fit `spec` to the touches (physical lobing: φ₀ profiled over 0 … 120°).
pub(crate) fn fit(
    spec: &ModelSpec,
    touches: &[TouchInputs],
    y_um: &[f64],
) -> Result<ModelFit, LinearError> {
    let (solution, phi0) = match spec.lobing {
        Lobing::Harmonic => (solve_at(spec, touches, y_um, 0.0)?, None),
        Lobing::Physical => {
            let (best, s) = profile_phi0(spec, touches, y_um)?;
            (
                with_phi0_counted(spec, touches, y_um, best.0, s),
                Some(best),
            )
        }
    };
    let n = touches.len() as f64;
    let lobe_free = spec.lobing == Lobing::Physical
        && solution
            .index("lobe_delta_min_um")
            .is_some_and(|i| solution.determined[i]);
    let k = solution.rank as f64 + if lobe_free { 1.0 } else { 0.0 };
    let bic = n * (rss(&solution) / n).max(1e-30).ln() + k * n.ln();
    let mut sums = [(0.0, 0usize); 2];
    for (t, e) in touches.iter().zip(&solution.residuals) {
        let c = usize::from(!t.first);
        sums[c].0 += e * e;
        sums[c].1 += 1;
    }
    let rms_um = sums.map(|(s, c)| {
        if c == 0 {
            f64::NAN
        } else {
            (s / c as f64).sqrt()
        }
    });
    let phi0_deg = phi0.map(|p| if lobe_free { p } else { (f64::NAN, f64::NAN) });
    Ok(ModelFit {
        spec: spec.clone(),
        solution,
        phi0_deg,
        bic,
        rms_um,
    })
}

/// `solution` (the linear fit at the profiled φ₀) with its covariance and degrees of freedom
/// those of the fit linearised in φ₀ too: the design gains the column ∂(model)/∂φ₀ at the
/// estimate (a central difference), so the residual variance counts φ₀ as the parameter it is
/// and every gain's variance includes what φ₀'s uncertainty moves it by. The estimates and
/// residuals stay those of the exact fit (at the optimum the extra column's coefficient is
/// zero). Unchanged when the lobes are not determined there or the column adds no rank.
///
/// Why: φ₀ is estimated like any other parameter and its uncertainty moves the gains. Over
/// ten simulated campaigns the first-touch errors' RMS in units of U/2 is 1.040 with φ₀
/// counted and 1.045 without (222 and 221 of 240 within U): a small effect, within the
/// scatter of 240 errors.
fn with_phi0_counted(
    spec: &ModelSpec,
    touches: &[TouchInputs],
    y_um: &[f64],
    phi0_deg: f64,
    solution: LinearSolution,
) -> LinearSolution {
    const H_DEG: f64 = 0.05;
    let lobes = solution.index("lobe_delta_min_um");
    if !lobes.is_some_and(|i| solution.determined[i]) {
        return solution;
    }
    let model = |t: &TouchInputs, p: f64| -> f64 {
        row(spec, t, p)
            .iter()
            .zip(&solution.estimate)
            .map(|(a, x)| a * x)
            .sum()
    };
    let mut names = names(spec);
    names.push("phi0_linearised".into());
    let rows: Vec<Vec<f64>> = touches
        .iter()
        .map(|t| {
            let mut r = row(spec, t, phi0_deg);
            r.push((model(t, phi0_deg + H_DEG) - model(t, phi0_deg - H_DEG)) / (2.0 * H_DEG));
            r
        })
        .collect();
    let Ok(full) = linear::solve(&LinearProblem {
        names,
        rows,
        observations: y_um.to_vec(),
        sigma: None,
    }) else {
        return solution;
    };
    let p = solution.names.len();
    match &full.covariance {
        Some(c) if full.rank == solution.rank + 1 && full.determined[p] => LinearSolution {
            covariance: Some(c.view((0, 0), (p, p)).into_owned()),
            dof: full.dof,
            ..solution
        },
        _ => solution,
    }
}

/// The best φ₀ and its U (k = 2: where the RSS rises by 4 s²; NaN when that interval spans
/// more than 30°, half the period: the phase is then not fixed), with the solution there.
fn profile_phi0(
    spec: &ModelSpec,
    touches: &[TouchInputs],
    y_um: &[f64],
) -> Result<((f64, f64), LinearSolution), LinearError> {
    const STEP_DEG: f64 = 1.0;
    let grid: Vec<f64> = (0..120).map(|i| i as f64 * STEP_DEG).collect();
    let mut profile = Vec::with_capacity(grid.len());
    for &p in &grid {
        profile.push(rss(&solve_at(spec, touches, y_um, p)?));
    }
    let i_best = (0..grid.len())
        .min_by(|&a, &b| profile[a].total_cmp(&profile[b]))
        .unwrap_or(0);
    // Golden-section refinement around the best grid point.
    let f = |p: f64| solve_at(spec, touches, y_um, p).map(|s| rss(&s));
    let (mut lo, mut hi) = (grid[i_best] - STEP_DEG, grid[i_best] + STEP_DEG);
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut fc, mut fd) = (f(c)?, f(d)?);
    for _ in 0..30 {
        if fc < fd {
            hi = d;
            d = c;
            fd = fc;
            c = hi - g * (hi - lo);
            fc = f(c)?;
        } else {
            lo = c;
            c = d;
            fc = fd;
            d = lo + g * (hi - lo);
            fd = f(d)?;
        }
    }
    let best = (0.5 * (lo + hi)).rem_euclid(120.0);
    let solution = solve_at(spec, touches, y_um, best)?;
    let rss_min = rss(&solution);
    let dof = solution.dof.saturating_sub(1).max(1) as f64;
    let threshold = rss_min + 4.0 * rss_min / dof;
    let mut half_width: f64 = 0.0;
    for (p, r) in grid.iter().zip(&profile) {
        if *r <= threshold {
            let d = (p - best + 60.0).rem_euclid(120.0) - 60.0;
            half_width = half_width.max(d.abs());
        }
    }
    let u = if half_width > 30.0 {
        f64::NAN
    } else {
        half_width.max(STEP_DEG)
    };
    Ok(((best, u), solution))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_three_lobe_shape_is_the_seeds() {
        assert!((three_lobe_shape(60.0) - 1.0).abs() < 1e-12);
        assert!((three_lobe_shape(0.0) - 2.0).abs() < 1e-12);
        assert!((three_lobe_shape(180.0) - 1.0).abs() < 1e-12);
        // 30° off the lobes: 1.155 δ_min (machine-physics.md, "Not identifiable").
        assert!((three_lobe_shape(30.0) - 1.1547).abs() < 1e-4);
    }
}
