//! A `volumetric` campaign analysed (`docs/spec/machine-physics.md`, "Kind volumetric",
//! "Interferometer readings", "ISO 230-2 quantities").
//!
//! 1. Every reading is normalised to T0 with the laser's declared compensation
//!    ([`crate::edlen::normalise_reading_mm`]; the datum of a diagonal is its first reading);
//!    the body diagonals a bar read are stitched ([`bar`]) and enter as body-diagonal readings.
//! 2. Per diagonal, ISO 230-2 (the ISO 230-6 reading): from the body diagonals (laser or bar),
//!    else from the step diagonals' points on the diagonal (the end of each step, where
//!    β·(P − P0) = 0). V_diag is the largest E; its scale term is the instrument's scale u over
//!    the distance between the two target means that make E ([`VDiagBudget`]).
//! 3. The joint fit ([`super::solve::fit`]) with the model's effects; the squareness values and
//!    Σ L_k² ε_k / D² with U (each instrument's scale u entering through the fit's own
//!    sensitivity to it, [`ScaleTerms`]); the error functions with U in the stated gauge; the naive
//!    inversion and the fourth sign pattern for comparison.
//! 4. The grid: the error vector and U at each node, V1, V2, V3.
//! 5. What cannot be seen, in words ([`VolumetricStudy::invisible`]).
//! 6. The loop ([`diagnosis`]): each effect of the catalogue not in the model, added in turn;
//!    the one whose BIC falls most (by more than the threshold) is named.

pub mod bar;
pub mod diagnosis;

use std::collections::BTreeMap;

use dbbcal_core::axis_campaign::LaserCompensation;
use dbbcal_core::volumetric_campaign::{DiagonalSign, VolumetricCampaignLogs};

use super::grid::{self, Grid};
use super::model::{Layout, Observation, Place, VolumetricEffect, AXES};
use super::solve::{self, JointFit, Naive, Quantity, StepError, VolumetricError};
use crate::edlen::{self, Air, Compensation, LaserSetup, ReadingConditions};
use crate::iso230_2::{self, Iso230Error, Iso230_2, TargetDeviations};

pub use bar::{BarCampaignError, BarCurve};
pub use diagnosis::{Candidate, Diagnosis};

/// Options of [`study`].
#[derive(Debug, Clone, PartialEq)]
pub struct VolumetricStudyOptions {
    /// Effects in the model.
    pub effects: Vec<VolumetricEffect>,
    /// Steps of forward selection (0: none).
    pub forward_steps: usize,
    /// BIC gain an effect needs to be proposed.
    pub min_bic_gain: f64,
    /// What the scale every reading shares is uncertain by (the laser's wavelength, the air's
    /// index from the environment sensors, the material normalisation). It enters the mean
    /// scale Σ L_k² ε_k / D² one to one and V_diag through the diagonal's length; squareness, a
    /// difference of diagonals, does not see it.
    pub scale_budget: ScaleBudget,
}

/// The standard uncertainties (k = 1) behind the readings' common scale, and the
/// sensitivities of `machine-physics.md` ("Interferometer readings"): −0.95 ppm/K of air,
/// +0.27 ppm/hPa, −0.0085 ppm/%RH, the machine's expansion per K of material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaleBudget {
    /// Air temperature sensor, K.
    pub air_k: f64,
    /// Air pressure sensor, hPa.
    pub pressure_hpa: f64,
    /// Humidity sensor, %RH.
    pub humidity_pct: f64,
    /// Material temperature sensors, K.
    pub material_k: f64,
    /// The laser's vacuum wavelength, ppm.
    pub wavelength_ppm: f64,
}

impl Default for ScaleBudget {
    /// A laser system's environment unit as vendors state it (air ±0.2 K, pressure ±1 hPa,
    /// humidity ±6 %RH, material ±0.1 K, each taken as rectangular) and a stabilised HeNe
    /// laser (0.02 ppm).
    fn default() -> Self {
        let rect = |half: f64| half / 3f64.sqrt();
        ScaleBudget {
            air_k: rect(0.2),
            pressure_hpa: rect(1.0),
            humidity_pct: rect(6.0),
            material_k: rect(0.1),
            wavelength_ppm: 0.02,
        }
    }
}

impl ScaleBudget {
    /// The common scale's standard uncertainty, ppm, for a machine of expansion
    /// `cte_ppm_per_k`.
    pub fn u_ppm(&self, cte_ppm_per_k: f64) -> f64 {
        [
            0.95 * self.air_k,
            0.27 * self.pressure_hpa,
            0.0085 * self.humidity_pct,
            cte_ppm_per_k * self.material_k,
            self.wavelength_ppm,
        ]
        .iter()
        .map(|x| x * x)
        .sum::<f64>()
        .sqrt()
    }
}

impl Default for VolumetricStudyOptions {
    fn default() -> Self {
        VolumetricStudyOptions {
            effects: vec![VolumetricEffect::Pointing],
            forward_steps: 2,
            min_bic_gain: 10.0,
            scale_budget: ScaleBudget::default(),
        }
    }
}

/// One diagonal's curve and its ISO 230-2 evaluation.
#[derive(Debug, Clone)]
pub struct DiagonalCurve {
    /// Which.
    pub sign: DiagonalSign,
    /// `"body"` (laser), `"bar"` (a bar in segments) or `"step"` (points of the step
    /// diagonal on the diagonal).
    pub source: &'static str,
    /// D, mm.
    pub length_mm: f64,
    /// The evaluation, or why there is none.
    pub iso: Result<Iso230_2, Iso230Error>,
    /// E (bidirectional, else of the one direction), µm.
    pub e_um: Option<f64>,
}

/// V_diag's budget: where its E comes from and what U holds (k = 1 parts, µm).
#[derive(Debug, Clone, PartialEq)]
pub struct VDiagBudget {
    /// The diagonal whose E is V_diag.
    pub diagonal: DiagonalSign,
    /// Its instrument: `"body"` (laser), `"bar"` or `"step"` (laser).
    pub source: &'static str,
    /// Distance of the largest target mean from P0, mm.
    pub d_max_mm: f64,
    /// Distance of the smallest target mean from P0, mm.
    pub d_min_mm: f64,
    /// The runs' scatter of a difference of two target means (the largest over every target),
    /// and for a bar the stitching's covariance of the two targets, µm.
    pub random_um: f64,
    /// The instrument's scale u over |d_max − d_min|, µm.
    pub scale_um: f64,
    /// The scale u used, ppm.
    pub scale_u_ppm: f64,
    /// A bar's misalignment (cosine) over |d_max − d_min|, µm (0 for the laser).
    pub cosine_um: f64,
}

impl VDiagBudget {
    /// The instrument's share of U² (scale and misalignment), 0 … 1.
    pub fn instrument_share(&self) -> f64 {
        let i = self.scale_um.powi(2) + self.cosine_um.powi(2);
        let all = i + self.random_um.powi(2);
        if all > 0.0 {
            i / all
        } else {
            0.0
        }
    }
}

/// How each instrument's scale u enters the mean scale and the squareness values: the fit's
/// own sensitivity (the estimate's change for a 1 ppm scale error on that instrument's
/// readings alone) times the u.
#[derive(Debug, Clone, PartialEq)]
pub struct ScaleTerms {
    /// The laser's common scale u, ppm (0 without laser readings).
    pub laser_u_ppm: f64,
    /// The bar's scale and misalignment u, ppm (0 without bar readings).
    pub bar_u_ppm: f64,
    /// ∂(Σ L_k² ε_k / D²)/∂(laser scale), (µm/m)/ppm.
    pub mean_scale_per_laser_ppm: f64,
    /// ∂(Σ L_k² ε_k / D²)/∂(bar scale).
    pub mean_scale_per_bar_ppm: f64,
    /// ∂S/∂(laser scale) for S_xy, S_yz, S_zx, µrad/ppm.
    pub squareness_per_laser_ppm: [f64; 3],
    /// ∂S/∂(bar scale).
    pub squareness_per_bar_ppm: [f64; 3],
}

/// A grid node's error vector with U.
#[derive(Debug, Clone)]
pub struct NodeError {
    /// Line l.
    pub line: usize,
    /// (i, j, k).
    pub node: [usize; 3],
    /// Position, mm.
    pub position_mm: [f64; 3],
    /// ex, ey, ez with U.
    pub error: [Quantity; 3],
}

/// A volumetric figure with its U (k = 2; an estimate, correlations between nodes neglected).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Figure {
    /// Value, µm.
    pub value_um: f64,
    /// U (k = 2), µm; NaN when not available.
    pub u_k2_um: f64,
}

/// A `volumetric` campaign analysed.
#[derive(Debug, Clone)]
pub struct VolumetricStudy {
    /// The readings, normalised.
    pub observations: Vec<Observation>,
    /// Per diagonal measured.
    pub curves: Vec<DiagonalCurve>,
    /// V_diag = max E over the diagonals, µm.
    pub v_diag: Option<Figure>,
    /// Where V_diag's E lies and what its U holds.
    pub v_diag_budget: Option<VDiagBudget>,
    /// The body diagonals a bar read, stitched.
    pub bars: Vec<BarCurve>,
    /// How the instruments' scales enter Σ L_k² ε_k / D² and the squareness values.
    pub scale_terms: ScaleTerms,
    /// With both instruments: the bar's scale less the laser's, ppm, with U (the random part
    /// only; the laser's and the bar's scale u add to it).
    pub bar_scale_vs_laser: Option<Quantity>,
    /// The joint fit.
    pub fit: JointFit,
    /// S_xy, S_yz, S_zx.
    pub squareness: [Quantity; 3],
    /// Σ L_k² ε_k / D².
    pub mean_scale: Quantity,
    /// Slopes `[j][k]`.
    pub slopes: [[Quantity; 3]; 3],
    /// The naive inversion, or why there is none.
    pub naive: Result<Naive, StepError>,
    /// RMS of the fourth pattern of the readings and of the fit's residuals, µm (`None`
    /// without four standard step diagonals).
    pub fourth_rms_um: Option<(f64, f64)>,
    /// The fourth pattern of the fit's residuals per axis at its nodes, µm.
    pub fourth_residual_um: Option<[Vec<f64>; 3]>,
    /// The grid.
    pub grid: Grid,
    /// Error vectors at the grid's nodes, in line order.
    pub nodes: Vec<NodeError>,
    /// V1, V2, V3.
    pub v1: Figure,
    /// V2.
    pub v2: Figure,
    /// V3.
    pub v3: Figure,
    /// Whether every grid error is identifiable (else V1 … V3 are in the gauge).
    pub figures_identifiable: bool,
    /// What the readings cannot see, in words.
    pub invisible: Vec<String>,
    /// The loop.
    pub diagnosis: Diagnosis,
    /// Residual RMS per diagonal and source, µm.
    pub residual_rms: Vec<(DiagonalSign, &'static str, f64, usize)>,
}

/// Why a study cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StudyError {
    /// A reading cannot be normalised.
    #[error("diagonal {diagonal} at {time_ns} ns: {message}")]
    Normalise {
        /// Which diagonal.
        diagonal: DiagonalSign,
        /// Reading time.
        time_ns: i64,
        /// What is wrong.
        message: String,
    },
    /// The solve failed.
    #[error(transparent)]
    Solve(#[from] VolumetricError),
    /// A bar-read diagonal cannot be stitched.
    #[error(transparent)]
    Bar(#[from] BarCampaignError),
}

fn to_compensation(c: LaserCompensation) -> Compensation {
    match c {
        LaserCompensation::None => Compensation::None,
        LaserCompensation::Air => Compensation::Air,
        LaserCompensation::AirMaterial => Compensation::AirMaterial,
    }
}

fn conditions(logs: &VolumetricCampaignLogs, t: i64, datum: i64) -> ReadingConditions {
    let air = |t: i64| {
        let i = logs.environment.partition_point(|r| r.time_ns <= t);
        logs.environment.get(i.saturating_sub(1))
    };
    let to_air = |e: &dbbcal_core::axis_campaign::EnvironmentRow| Air {
        temperature_c: e.air_c,
        pressure_hpa: e.pressure_hpa,
        humidity_pct: e.humidity_pct,
    };
    ReadingConditions {
        air: air(t).map(to_air),
        datum_air: air(datum).map(to_air),
        material_c: air(t).and_then(|e| e.material_c),
    }
}

/// The laser's readings as observations normalised to T0 (none without `[laser]`).
pub fn observations(logs: &VolumetricCampaignLogs) -> Result<Vec<Observation>, StudyError> {
    let c = &logs.campaign;
    let Some(laser) = &c.laser else {
        return Ok(Vec::new());
    };
    let setup = LaserSetup {
        wavelength_nm: laser.wavelength_nm,
        compensation: to_compensation(laser.compensation),
        dead_path_mm: laser.dead_path_mm,
        cte_ppm_per_k: c.cte_ppm_per_k,
        reference_temperature_c: c.reference_temperature_c,
    };
    let t0 = bar::first_reading_ns(logs);
    let mut datum: BTreeMap<DiagonalSign, i64> = BTreeMap::new();
    for (d, t) in logs
        .diagonals
        .iter()
        .map(|r| (r.diagonal, r.time_ns))
        .chain(logs.steps.iter().map(|r| (r.diagonal, r.time_ns)))
    {
        let e = datum.entry(d).or_insert(t);
        *e = (*e).min(t);
    }
    let normalise = |d: DiagonalSign, t: i64, commanded_mm: f64, dev_um: f64| {
        let read = commanded_mm + dev_um * 1e-3;
        let at = conditions(logs, t, datum[&d]);
        edlen::normalise_reading_mm(read, &setup, &at)
            .map(|l| (l - commanded_mm) * 1e3)
            .map_err(|e| StudyError::Normalise {
                diagonal: d,
                time_ns: t,
                message: e.to_string(),
            })
    };
    let hours = |t: i64| (t - t0) as f64 / 3.6e12;
    let mut out = Vec::new();
    for r in &logs.diagonals {
        out.push(Observation {
            diagonal: r.diagonal,
            run: r.run,
            direction: r.direction,
            place: Place::Body { d_mm: r.target_mm },
            hours: hours(r.time_ns),
            deviation_um: normalise(r.diagonal, r.time_ns, r.target_mm, r.deviation_um)?,
            bar: false,
        });
    }
    for r in &logs.steps {
        let diag = super::Diagonal::new(r.diagonal, c.min_mm, c.max_mm);
        let rel = [0, 1, 2].map(|k| r.position_mm[k] - diag.p0_mm[k]);
        let commanded = super::dot(diag.u, rel);
        out.push(Observation {
            diagonal: r.diagonal,
            run: r.run,
            direction: 1,
            place: Place::Step {
                position_mm: r.position_mm,
                step: r.step,
                submove: r.submove.map(|a| a.index()),
            },
            hours: hours(r.time_ns),
            deviation_um: normalise(r.diagonal, r.time_ns, commanded, r.deviation_um)?,
            bar: false,
        });
    }
    Ok(out)
}

/// The step intervals N: the largest step of any step diagonal (0 without).
pub fn intervals(obs: &[Observation]) -> usize {
    obs.iter()
        .filter_map(|o| match o.place {
            Place::Step { step, .. } => Some(step.max(0) as usize),
            Place::Body { .. } => None,
        })
        .max()
        .unwrap_or(0)
}

/// The workspace and grid an analysis needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Workspace min corner, mm.
    pub min_mm: [f64; 3],
    /// Workspace max corner, mm.
    pub max_mm: [f64; 3],
    /// The lattice of V2, V3 and the table.
    pub grid: Grid,
    /// The machine's expansion, ppm/K (its material normalisation enters the scale budget).
    pub cte_ppm_per_k: f64,
}

/// Analyse a campaign.
pub fn study(
    logs: &VolumetricCampaignLogs,
    options: &VolumetricStudyOptions,
) -> Result<VolumetricStudy, StudyError> {
    study_with_bars(logs, bar::stitch_campaign(logs)?, options)
}

/// Analyse a campaign whose bar-read diagonals are already stitched
/// ([`bar::stitch_campaign`]).
pub fn study_with_bars(
    logs: &VolumetricCampaignLogs,
    bars: Vec<BarCurve>,
    options: &VolumetricStudyOptions,
) -> Result<VolumetricStudy, StudyError> {
    let c = &logs.campaign;
    let g = &c.grid;
    let frame = Frame {
        min_mm: c.min_mm,
        max_mm: c.max_mm,
        grid: Grid {
            counts: [g.i, g.j, g.k],
            origin_mm: g.origin_mm,
            spacing_mm: g.spacing_mm,
        },
        cte_ppm_per_k: c.cte_ppm_per_k,
    };
    let laser_u_ppm = if c.laser.is_some() {
        options.scale_budget.u_ppm(frame.cte_ppm_per_k)
    } else {
        0.0
    };
    analyse_readings(observations(logs)?, bars, &frame, options, laser_u_ppm)
}

/// Analyse normalised laser readings (what [`study`] does after [`observations`], without
/// bar-read diagonals).
pub fn analyse(
    obs: Vec<Observation>,
    frame: &Frame,
    options: &VolumetricStudyOptions,
) -> Result<VolumetricStudy, StudyError> {
    let laser_u_ppm = options.scale_budget.u_ppm(frame.cte_ppm_per_k);
    analyse_readings(obs, Vec::new(), frame, options, laser_u_ppm)
}

/// Analyse the laser's normalised readings `obs` with the stitched bar-read diagonals `bars`;
/// `laser_u_ppm` is the laser's common scale u.
pub fn analyse_readings(
    mut obs: Vec<Observation>,
    bars: Vec<BarCurve>,
    frame: &Frame,
    options: &VolumetricStudyOptions,
    laser_u_ppm: f64,
) -> Result<VolumetricStudy, StudyError> {
    let n = intervals(&obs);
    // Every reading for ISO 230-2; the fit's bar readings at the step nodes (see `bar`).
    let mut all = obs.clone();
    let nodes: Option<Vec<f64>> = (n > 0).then(|| {
        let d = frame
            .min_mm
            .iter()
            .zip(frame.max_mm)
            .map(|(a, b)| (b - a).powi(2))
            .sum::<f64>()
            .sqrt();
        (0..=n).map(|i| d * i as f64 / n as f64).collect()
    });
    for b in &bars {
        all.extend(b.observations.iter().copied());
        obs.extend(b.fit_observations(nodes.as_deref()));
    }
    let layout =
        |effects: &[VolumetricEffect]| Layout::new(frame.min_mm, frame.max_mm, n, effects, &obs);
    let fit = solve::fit(layout(&options.effects), &obs)?;
    let diagnosis = diagnosis::diagnose(&fit, &obs, options, layout)?;
    let naive = if n > 0 {
        solve::naive(&fit.layout, &obs)
    } else {
        Err(StepError::NoStepsToInvert)
    };
    let data: Vec<f64> = obs.iter().map(|o| o.deviation_um).collect();
    let fourth = |v: &[f64]| {
        solve::step_series(&fit.layout, &obs, v)
            .ok()
            .and_then(|s| solve::fourth_pattern(&s))
    };
    let fourth_data = fourth(&data);
    let fourth_residual_um = fourth(&fit.residuals);
    let fourth_rms_um = fourth_data
        .as_ref()
        .zip(fourth_residual_um.as_ref())
        .map(|(a, b)| (rms(a), rms(b)));
    let grid = frame.grid;
    let nodes: Vec<NodeError> = (1..=grid.counts.iter().product())
        .filter_map(|l| {
            let node = grid.node(l)?;
            let position_mm = grid.position(node);
            Some(NodeError {
                line: l,
                node,
                position_mm,
                error: fit.error_at(position_mm),
            })
        })
        .collect();
    let (v1, v2, v3) = figures(&fit, &nodes);
    let figures_identifiable = nodes.iter().all(|n| n.error.iter().all(|q| q.identifiable));
    let curves = curves(&all, &bars, frame.min_mm, frame.max_mm);
    let bar_u_ppm = bars.first().map_or(0.0, |b| {
        let budget = b.stitched.budget;
        budget.scale_u_ppm.hypot(budget.cosine_ppm())
    });
    let scale_terms = scale_terms(&fit, &obs, laser_u_ppm, bar_u_ppm)?;
    let bar_scale_vs_laser = fit.layout.bar_scale_index().map(|i| {
        let mut c = vec![0.0; fit.layout.len()];
        c[i] = 1.0;
        fit.quantity(super::model::BAR_SCALE, &c)
    });
    let (v_diag, v_diag_budget) = v_diag(&curves, &bars, laser_u_ppm).unzip();
    let mut invisible = invisible(&fit, &obs, n);
    if !bars.is_empty() {
        invisible.extend(bar_invisible(&bars, &obs));
    }
    if !figures_identifiable {
        invisible.push("V1, V2, V3 and the 3-D table hold terms the readings cannot see: they are given in the stated gauge, not measured".to_string());
    }
    for c in diagnosis.candidates.iter().filter(|c| c.rank_gained == 0) {
        invisible.push(format!(
            "{} ({}): adds nothing these readings can separate (rank unchanged): it is confounded with the model's terms, so the loop can neither name it nor rule it out",
            c.effect.name(),
            c.effect.physics()
        ));
    }
    let residual_rms = residual_rms(&fit, &obs);
    let squareness = fit.squareness();
    let squareness = [0, 1, 2].map(|i| {
        with_scales(
            squareness[i].clone(),
            &[
                scale_terms.squareness_per_laser_ppm[i] * laser_u_ppm,
                scale_terms.squareness_per_bar_ppm[i] * bar_u_ppm,
            ],
        )
    });
    let mean_scale = with_scales(
        fit.mean_scale(),
        &[
            scale_terms.mean_scale_per_laser_ppm * laser_u_ppm,
            scale_terms.mean_scale_per_bar_ppm * bar_u_ppm,
        ],
    );
    Ok(VolumetricStudy {
        squareness,
        mean_scale,
        slopes: fit.slopes(),
        observations: obs,
        curves,
        v_diag,
        v_diag_budget,
        bars,
        scale_terms,
        bar_scale_vs_laser,
        naive,
        fourth_rms_um,
        fourth_residual_um,
        grid,
        nodes,
        v1,
        v2,
        v3,
        figures_identifiable,
        invisible,
        diagnosis,
        residual_rms,
        fit,
    })
}

fn rms(series: &[Vec<f64>; 3]) -> f64 {
    let all: Vec<f64> = series.iter().flatten().copied().collect();
    (all.iter().map(|v| v * v).sum::<f64>() / all.len().max(1) as f64).sqrt()
}

fn figures(fit: &JointFit, nodes: &[NodeError]) -> (Figure, Figure, Figure) {
    let f = fit.functions();
    let positioning = [0, 1, 2].map(|k| f[k][k].iter().map(|(_, q)| q.value).collect::<Vec<_>>());
    let v1u = (0..3)
        .map(|k| {
            // NaN (not seen) wins over max: a range in the gauge has no U.
            let u = f[k][k].iter().map(|(_, q)| q.u_k2).fold(0.0_f64, |a, b| {
                if a.is_nan() || b.is_nan() {
                    f64::NAN
                } else {
                    a.max(b)
                }
            });
            u.powi(2) * 2.0
        })
        .sum::<f64>()
        .sqrt();
    let errors: Vec<[f64; 3]> = nodes
        .iter()
        .map(|n| n.error.clone().map(|q| q.value))
        .collect();
    let v2 = grid::v2_um(&errors);
    let mut u2 = 0.0;
    for k in 0..3 {
        let col: Vec<f64> = errors.iter().map(|e| e[k]).collect();
        let r = grid::range(col.iter().copied());
        if v2 > 0.0 && !col.is_empty() {
            let imax = argmax(&col, |v| v);
            let imin = argmax(&col, |v| -v);
            let um = |i: usize| nodes[i].error[k].u_k2;
            u2 += (r / v2).powi(2) * (um(imax).powi(2) + um(imin).powi(2));
        }
    }
    let v3 = grid::v3_um(&errors);
    let u3 = if errors.is_empty() {
        f64::NAN
    } else {
        let norms: Vec<f64> = errors.iter().map(|e| super::norm(*e)).collect();
        let i = argmax(&norms, |v| v);
        if norms[i] > 0.0 {
            (0..3)
                .map(|k| (errors[i][k] / norms[i] * nodes[i].error[k].u_k2).powi(2))
                .sum::<f64>()
                .sqrt()
        } else {
            nodes[i].error.iter().map(|q| q.u_k2).fold(0.0, f64::max)
        }
    };
    (
        Figure {
            value_um: grid::v1_um(&positioning),
            u_k2_um: v1u,
        },
        Figure {
            value_um: v2,
            u_k2_um: u2.sqrt(),
        },
        Figure {
            value_um: v3,
            u_k2_um: u3,
        },
    )
}

fn argmax(v: &[f64], key: impl Fn(f64) -> f64) -> usize {
    (0..v.len())
        .max_by(|&a, &b| key(v[a]).total_cmp(&key(v[b])))
        .unwrap_or(0)
}

/// Per diagonal: ISO 230-2 from the body readings (laser or bar), else from the step points on
/// the diagonal.
fn curves(
    obs: &[Observation],
    bars: &[BarCurve],
    min_mm: [f64; 3],
    max_mm: [f64; 3],
) -> Vec<DiagonalCurve> {
    let mut out = Vec::new();
    for sign in DiagonalSign::ALL {
        let diag = super::Diagonal::new(sign, min_mm, max_mm);
        let body: Vec<&Observation> = obs
            .iter()
            .filter(|o| o.diagonal == sign && matches!(o.place, Place::Body { .. }))
            .collect();
        let (source, points): (&'static str, Vec<(f64, i64, i8, f64)>) = if !body.is_empty() {
            let pts = body
                .iter()
                .map(|o| match o.place {
                    Place::Body { d_mm } => (d_mm, o.run, o.direction, o.deviation_um),
                    Place::Step { .. } => unreachable!("filtered"),
                })
                .collect();
            let by_bar = bars.iter().any(|b| b.sign == sign);
            (if by_bar { "bar" } else { "body" }, pts)
        } else {
            let pts: Vec<_> = obs
                .iter()
                .filter(|o| o.diagonal == sign)
                .filter_map(|o| {
                    let p = o.position_mm(&diag);
                    let rel = [0, 1, 2].map(|k| p[k] - diag.p0_mm[k]);
                    let d = super::dot(diag.u, rel);
                    let off = [0, 1, 2].map(|k| rel[k] - d * diag.u[k]);
                    (super::norm(off) < 1e-3).then_some((d, o.run, 1i8, o.deviation_um))
                })
                .collect();
            if pts.is_empty() {
                continue;
            }
            ("step", pts)
        };
        let iso = evaluate(&points);
        let e_um = iso.as_ref().ok().and_then(|i| {
            i.systematic_e_um
                .or(i.up.map(|u| u.systematic_um))
                .or(i.down.map(|u| u.systematic_um))
        });
        out.push(DiagonalCurve {
            sign,
            source,
            length_mm: diag.length_mm,
            iso,
            e_um,
        });
    }
    out
}

/// ISO 230-2 of (d, run, direction, deviation) points: one value per run and direction at
/// each target (repeated visits averaged).
fn evaluate(points: &[(f64, i64, i8, f64)]) -> Result<Iso230_2, Iso230Error> {
    let mut by: BTreeMap<i64, BTreeMap<(i8, i64), Vec<f64>>> = BTreeMap::new();
    for (d, run, dir, v) in points {
        by.entry((d * 1e3).round() as i64)
            .or_default()
            .entry((*dir, *run))
            .or_default()
            .push(*v);
    }
    let targets: Vec<TargetDeviations> = by
        .into_iter()
        .map(|(key, runs)| {
            let mean = |v: &Vec<f64>| v.iter().sum::<f64>() / v.len() as f64;
            TargetDeviations {
                position_mm: key as f64 / 1e3,
                up_um: runs
                    .iter()
                    .filter(|(k, _)| k.0 > 0)
                    .map(|(_, v)| mean(v))
                    .collect(),
                down_um: runs
                    .iter()
                    .filter(|(k, _)| k.0 < 0)
                    .map(|(_, v)| mean(v))
                    .collect(),
            }
        })
        .collect();
    iso230_2::evaluate(&targets)
}

/// A quantity's U with scale terms added (each a k = 1 contribution), where the readings see
/// the quantity.
fn with_scales(q: Quantity, terms: &[f64]) -> Quantity {
    let u_k2 = if q.u_k2.is_finite() {
        let extra: f64 = terms.iter().map(|t| t * t).sum();
        2.0 * ((q.u_k2 / 2.0).powi(2) + extra).sqrt()
    } else {
        q.u_k2
    };
    Quantity { u_k2, ..q }
}

/// The fit's sensitivity to each instrument's scale: the same layout fitted to the readings a
/// 1 ppm scale error of that instrument alone would make (10⁻³ µm per mm of commanded travel
/// along the beam or the bar).
fn scale_terms(
    fit: &JointFit,
    obs: &[Observation],
    laser_u_ppm: f64,
    bar_u_ppm: f64,
) -> Result<ScaleTerms, StudyError> {
    let by_bar = |o: &Observation| o.bar;
    let travel_mm = |o: &Observation| {
        let diag = fit.layout.diagonal(o.diagonal);
        let p = o.position_mm(diag);
        super::dot(diag.u, [0, 1, 2].map(|k| p[k] - diag.p0_mm[k]))
    };
    let response = |bar: bool| -> Result<(f64, [f64; 3]), StudyError> {
        let pattern: Vec<Observation> = obs
            .iter()
            .map(|o| Observation {
                deviation_um: if by_bar(o) == bar {
                    1e-3 * travel_mm(o)
                } else {
                    0.0
                },
                ..*o
            })
            .collect();
        if pattern.iter().all(|o| o.deviation_um == 0.0) {
            return Ok((0.0, [0.0; 3]));
        }
        let f = solve::fit(fit.layout.clone(), &pattern)?;
        Ok((f.mean_scale().value, f.squareness().map(|q| q.value)))
    };
    let (ms_laser, sq_laser) = response(false)?;
    let (ms_bar, sq_bar) = response(true)?;
    Ok(ScaleTerms {
        laser_u_ppm: if obs.iter().any(|o| !by_bar(o)) {
            laser_u_ppm
        } else {
            0.0
        },
        bar_u_ppm,
        mean_scale_per_laser_ppm: ms_laser,
        mean_scale_per_bar_ppm: ms_bar,
        squareness_per_laser_ppm: sq_laser,
        squareness_per_bar_ppm: sq_bar,
    })
}

/// The target means that make E: (distance of the largest, of the smallest).
fn extremes(iso: &Iso230_2) -> Option<(f64, f64)> {
    let means: Vec<(f64, f64)> = iso
        .targets
        .iter()
        .flat_map(|t| [t.up, t.down].map(|d| (t.position_mm, d)))
        .filter_map(|(x, d)| d.map(|d| (x, d.mean_um)))
        .collect();
    let hi = means.iter().max_by(|a, b| a.1.total_cmp(&b.1))?;
    let lo = means.iter().min_by(|a, b| a.1.total_cmp(&b.1))?;
    Some((hi.0, lo.0))
}

/// V_diag, the largest E over the diagonals, and its U: the runs' scatter (the difference of
/// two target means, the largest over every target of every diagonal: a few runs estimate one
/// target's s poorly); for a bar-read diagonal also the stitching's covariance of the two
/// targets that make E (conservative: it holds part of the same scatter); the instrument's
/// scale u over the distance between those two targets (the laser's common scale, or the bar's
/// calibration and its misalignment).
fn v_diag(
    curves: &[DiagonalCurve],
    bars: &[BarCurve],
    laser_u_ppm: f64,
) -> Option<(Figure, VDiagBudget)> {
    let c =
        curves
            .iter()
            .filter(|c| c.e_um.is_some())
            .fold(None, |a: Option<&DiagonalCurve>, c| match a {
                Some(a) if a.e_um >= c.e_um => Some(a),
                _ => Some(c),
            })?;
    let e = c.e_um?;
    let (d_max_mm, d_min_mm) = extremes(c.iso.as_ref().ok()?)?;
    let scatter_um = curves
        .iter()
        .filter_map(|c| c.iso.as_ref().ok())
        .flat_map(|i| i.targets.iter())
        .flat_map(|t| [t.up, t.down])
        .flatten()
        .map(|s| std::f64::consts::SQRT_2 * s.s_um / (s.runs as f64).sqrt())
        .fold(0.0, f64::max);
    let span = (d_max_mm - d_min_mm).abs();
    let bar = bars.iter().find(|b| b.sign == c.sign && c.source == "bar");
    let (random_um, scale_um, scale_u_ppm, cosine_um) = match bar {
        Some(b) => {
            let s = &b.stitched;
            let [stitch_u, scale, cosine] =
                s.difference_u_um(s.index_of(d_min_mm), s.index_of(d_max_mm));
            (
                scatter_um.hypot(stitch_u),
                scale,
                s.budget.scale_u_ppm,
                cosine,
            )
        }
        None => (scatter_um, laser_u_ppm * 1e-3 * span, laser_u_ppm, 0.0),
    };
    let budget = VDiagBudget {
        diagonal: c.sign,
        source: c.source,
        d_max_mm,
        d_min_mm,
        random_um,
        scale_um,
        scale_u_ppm,
        cosine_um,
    };
    let u = (random_um.powi(2) + scale_um.powi(2) + cosine_um.powi(2)).sqrt();
    Some((
        Figure {
            value_um: e,
            u_k2_um: 2.0 * u,
        },
        budget,
    ))
}

/// What the bar-read diagonals cannot see, in words.
fn bar_invisible(bars: &[BarCurve], obs: &[Observation]) -> Vec<String> {
    let mut out = Vec::new();
    let laser = obs
        .iter()
        .any(|o| o.is_step() || !bars.iter().any(|b| b.sign == o.diagonal));
    let b = &bars[0];
    if !laser {
        out.push(format!(
            "read by bar {} alone: every reading's scale is the bar's calibration, so Σ L_k² ε_k / D² is known only to its scale u ({} ppm, fully correlated over every segment and diagonal); a bar reads along a body diagonal only, so the step diagonals' sub-moves, which separate the per-axis functions and their shapes, are not available",
            b.bar, b.stitched.budget.scale_u_ppm
        ));
    }
    for b in bars.iter().filter(|b| !b.normalised) {
        out.push(format!(
            "diagonal {} (bar {}): no material temperature in environment/*.parquet at its readings: they are taken at the machine's temperature during the test, not normalised to T0",
            b.sign, b.bar
        ));
    }
    out
}

/// What the readings cannot see, in words (`machine-physics.md`, "Not identifiable").
fn invisible(fit: &JointFit, obs: &[Observation], n: usize) -> Vec<String> {
    let mut out = Vec::new();
    let has_body = obs.iter().any(|o| matches!(o.place, Place::Body { .. }));
    let slopes = fit.slopes();
    let confounded: Vec<String> = slopes
        .iter()
        .flatten()
        .filter(|q| !q.identifiable)
        .map(|q| q.name.clone())
        .collect();
    if n == 0 && has_body {
        out.push("with body diagonals only: 4 of 9 linear terms: Σ L_k² ε_k / D² and three squareness values; per-axis scale differences are invisible".to_string());
        out.push("with body diagonals only the error functions' shapes are not separable: the fit holds their slopes only, the rest stays in the residual".to_string());
    }
    if n > 0 {
        let pointing = fit.layout.effects.contains(&VolumetricEffect::Pointing);
        if pointing && !confounded.is_empty() {
            out.push(format!(
                "with step diagonals and unknown pointing: the slopes' rank is {} of 9 (Σ L_k² ε_k / D² and the three squareness values remain); confounded with the beams' pointing: {}; non-linear shapes stay identifiable",
                9 - count_lost_slopes(fit),
                confounded.join(", ")
            ));
        } else if !pointing {
            out.push("pointing is taken as zero (effect `pointing` not in the model): every slope is seen, but a mis-pointed beam biases them".to_string());
        }
    }
    let diags: std::collections::BTreeSet<DiagonalSign> = obs.iter().map(|o| o.diagonal).collect();
    if diags.len() < 4 {
        out.push(format!(
            "{} of 4 diagonals measured ({}): the missing sign patterns leave more unseen, listed below",
            diags.len(),
            diags.iter().map(|d| d.as_str()).collect::<Vec<_>>().join(", ")
        ));
    }
    if !fit.lost.is_empty() {
        out.push(format!(
            "rank {} of {} parameters; lost combinations: {}",
            fit.rank,
            fit.layout.len(),
            fit.lost.join("; ")
        ));
        for g in &fit.gauge {
            out.push(format!("reported in the gauge: {g}"));
        }
    }
    let _ = AXES;
    out
}

/// 9 − the slopes' rank: the dimension of the slopes' lost space (estimated as the number of
/// lost directions with a slope component, at most 9).
fn count_lost_slopes(fit: &JointFit) -> usize {
    // Rank of the identifiable slope functionals: 4 when pointing hides the rest (the spec's
    // count); computed from the quantities that are identifiable among slope combinations.
    let p = fit.layout.len();
    let mut basis: Vec<Vec<f64>> = Vec::new();
    for a in 0..9 {
        let mut c = vec![0.0; p];
        c[a] = 1.0;
        basis.push(c);
    }
    // The identifiable subspace of the 9 slopes: 9 − rank of the null vectors' slope parts.
    let null_slopes: Vec<Vec<f64>> = fit.lost_vectors().iter().map(|v| v[..9].to_vec()).collect();
    let m = nalgebra::DMatrix::from_fn(null_slopes.len().max(1), 9, |i, j| {
        null_slopes.get(i).map_or(0.0, |v| v[j])
    });
    let _ = basis;
    m.rank(1e-8 * m.norm().max(1e-300))
}

fn residual_rms(
    fit: &JointFit,
    obs: &[Observation],
) -> Vec<(DiagonalSign, &'static str, f64, usize)> {
    let mut acc: BTreeMap<(DiagonalSign, &'static str), (f64, usize)> = BTreeMap::new();
    for (o, r) in obs.iter().zip(&fit.residuals) {
        let src = solve::source(o);
        let e = acc.entry((o.diagonal, src)).or_insert((0.0, 0));
        e.0 += r * r;
        e.1 += 1;
    }
    acc.into_iter()
        .map(|((d, s), (ss, n))| (d, s, (ss / n as f64).sqrt(), n))
        .collect()
}
