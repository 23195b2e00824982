//! A `roll` campaign analysed (seed 004; `docs/spec/machine-physics.md`, "Kind roll";
//! `docs/spec/machine-formats.md`, "Kind roll"): readings in µm (volts × `um_per_v`), dwells
//! ([`dwells`]), station means with their Type A u ([`stations`]), station indices and passes,
//! the seed's estimator over every pass at once with the level datum (the private `model`,
//! checked against [`estimator`]), εx(n) with U, EAX, and the loop: residuals per pass, candidates of
//! the spec's table ranked by BIC, forward selection, the named missing effect, the
//! plausibility of the roll for a machine table, and what these data cannot tell.
//!
//! **EAX** *(ours, where the spec gives the rule for one case)*: the table carries the workpiece
//! and `x_mm` is the controller's coordinate (ISO 841: tool relative to workpiece), so a table
//! move of +Δx carries the surface by −Δx along M's axis; the surface moves from B to A (R's −x)
//! when `x_mm` changes by b_to_a · s, so R's +x is b_to_a times M's + axis and the roll error of
//! the axis (EAX for X, EBY for Y, ECZ for Z) is −b_to_a · εx (the spec's EAX = −εx when R's +x
//! is M's +X).

pub mod dwells;
pub mod effects;
pub mod estimator;
mod model;
pub mod stations;
#[cfg(test)]
mod tests;

use dbbcal_core::roll_campaign::{RollCampaignLogs, PROBES};

use crate::linear::LinearError;
use dwells::Dwell;
pub use effects::{RollEffect, Unseen};
use model::{Geometry, LevelObs, ModelFit, StepRow};

/// What the analysis may do.
#[derive(Debug, Clone, PartialEq)]
pub struct RollOptions {
    /// The effects in the model (`[roll] effects`, `--add-effect`).
    pub effects: Vec<RollEffect>,
    /// Steps of forward selection (0: none).
    pub forward_steps: usize,
    /// The BIC gain an effect must bring to be proposed.
    pub min_bic_gain: f64,
    /// The probes' resolution, µm; `None`: detected from the readings.
    pub resolution_um: Option<f64>,
    /// σ of a level reading whose `u_urad` is null, µrad.
    pub level_u_urad: f64,
    /// The largest |εx| plausible for a machine table, µrad (`machine-physics.md`: typical
    /// roll 5–30 µrad over the travel).
    pub plausible_roll_urad: f64,
}

impl Default for RollOptions {
    fn default() -> Self {
        RollOptions {
            effects: Vec::new(),
            forward_steps: 3,
            min_bic_gain: 10.0,
            resolution_um: None,
            level_u_urad: 1.0,
            plausible_roll_urad: 100.0,
        }
    }
}

/// Why a `roll` campaign cannot be analysed: one line naming the file, column and rows.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RollError {
    /// No dwell found.
    #[error("{file}: column x_mm: no dwell found in {samples} samples (x_mm never stays within ±{tol_um} µm for {min_s} s; dwell_min_s, dwell_tol_um in campaign.toml)")]
    NoDwells {
        /// The first probes file.
        file: String,
        /// Samples read.
        samples: usize,
        /// `dwell_tol_um`.
        tol_um: f64,
        /// `dwell_min_s`.
        min_s: f64,
    },
    /// Fewer than two stations.
    #[error("{file}: column x_mm: every dwell is at one station: the roll needs at least two stations s apart")]
    OneStation {
        /// The first probes file.
        file: String,
    },
    /// A dwell off the station grid.
    #[error("{file}: column x_mm, rows {first_row}..{last_row}: a dwell at x = {x_mm:.4} mm lies {steps:.3} steps from the first station, not a whole number of steps s (more than {off} off)")]
    OffGrid {
        /// Its file.
        file: String,
        /// First row in that file.
        first_row: u64,
        /// Last row.
        last_row: u64,
        /// Its position.
        x_mm: f64,
        /// Steps from the reference.
        steps: f64,
        /// The tolerance, steps.
        off: f64,
    },
    /// A level reading outside every dwell.
    #[error("{file}: column time, row {row}: the level reading at {time_s:.1} s after the first sample is in no dwell (its station is unknown)")]
    LevelOutsideDwell {
        /// The levels file.
        file: String,
        /// The row.
        row: u64,
        /// Its time, s after the first probe sample.
        time_s: f64,
    },
    /// A level reading with a non-finite or non-positive u.
    #[error("{file}: column u_urad, row {row}: {u} is not a positive finite uncertainty")]
    LevelU {
        /// The levels file.
        file: String,
        /// The row.
        row: u64,
        /// The value.
        u: f64,
    },
    /// The engine refused the problem.
    #[error(transparent)]
    Linear(#[from] LinearError),
}

/// One dwell as used.
#[derive(Debug, Clone, PartialEq)]
pub struct DwellResult {
    /// Pass index (0-based, in time order).
    pub pass: usize,
    /// Station n.
    pub station: usize,
    /// Mean `x_mm`.
    pub x_mm: f64,
    /// Start and end, s after the first sample.
    pub span_s: (f64, f64),
    /// Samples in the dwell.
    pub samples: usize,
    /// Mean reading per probe A … D, µm.
    pub mean_um: [f64; 4],
    /// Its standard uncertainty (Type A with τ, resolution), µm.
    pub u_um: [f64; 4],
    /// τ of the Type A part per probe.
    pub tau: [f64; 4],
    /// Standard uncertainty of the means of C − A and D − B taken sample by sample, µm: what
    /// the estimator's step uses (`difference_u`).
    pub pair_u_um: [f64; 2],
}

/// εx at one station.
#[derive(Debug, Clone, PartialEq)]
pub struct StationResult {
    /// Station n.
    pub station: usize,
    /// Mean `x_mm` of its dwells.
    pub x_mm: f64,
    /// εx(n), µrad (NaN: not determined).
    pub roll_urad: f64,
    /// u from the readings (propagated through the estimator), µrad.
    pub u_noise_urad: f64,
    /// U (k = 2) with the scale uncertainty of L, µrad.
    pub u_k2_urad: f64,
    /// The axis's roll error (EAX for X), µrad: −b_to_a · εx.
    pub roll_error_urad: f64,
}

/// One pass: its stations in time order and its own εx by eq. 10 (anchored at the global value
/// of its first station).
#[derive(Debug, Clone, PartialEq)]
pub struct PassResult {
    /// +1 when the stations increase in time, −1 otherwise.
    pub direction: i8,
    /// Stations in time order.
    pub stations: Vec<usize>,
    /// εx by eq. 10 along the pass, µrad, one per station.
    pub roll_urad: Vec<f64>,
    /// RMS of its step rows' residuals in the final model, µrad.
    pub rms_residual_urad: f64,
}

/// A level reading as used.
#[derive(Debug, Clone, PartialEq)]
pub struct LevelResult {
    /// Station n.
    pub station: usize,
    /// roll_urad read.
    pub roll_urad: f64,
    /// Its residual in the final model, µrad.
    pub residual_urad: f64,
}

/// A candidate effect.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// The effect.
    pub effect: RollEffect,
    /// BIC change (negative: better); `None`: not identifiable with these data.
    pub delta_bic: Option<f64>,
    /// χ² with it.
    pub chi2: f64,
}

/// One step of forward selection.
#[derive(Debug, Clone, PartialEq)]
pub struct LedgerStep {
    /// The effect added (`None`: the starting model).
    pub effect: Option<RollEffect>,
    /// χ² after the step.
    pub chi2: f64,
    /// BIC change.
    pub delta_bic: f64,
}

/// The roll is implausibly large for a machine table.
#[derive(Debug, Clone, PartialEq)]
pub struct Implausible {
    /// The largest |εx|, µrad.
    pub max_abs_urad: f64,
    /// The limit, µrad.
    pub limit_urad: f64,
    /// The least-squares slope of εx over n through the datum, µrad per station.
    pub slope_urad_per_station: f64,
    /// The combined zero offset o_C − o_D − o_A + o_B that would make that slope, µm.
    pub equivalent_offset_um: f64,
}

/// Where the model fails and what would fix it.
#[derive(Debug, Clone, PartialEq)]
pub struct RollDiagnosis {
    /// Effects not in the model, each added alone.
    pub candidates: Vec<Candidate>,
    /// Forward selection.
    pub ledger: Vec<LedgerStep>,
    /// The named missing effect: the ledger's first step, else the suspect of an implausible
    /// roll (a probe zero offset, which only a level datum shows).
    pub missing: Option<RollEffect>,
    /// Why `missing` is named.
    pub missing_because: String,
    /// What these data cannot tell.
    pub unseen: Vec<Unseen>,
}

/// An effect's fitted parameter: (value, U k = 2).
#[derive(Debug, Clone, PartialEq)]
pub struct EffectFit {
    /// The effect.
    pub effect: RollEffect,
    /// Value and U (k = 2); NaN where not determined.
    pub value: (f64, f64),
}

/// Everything the analysis found.
#[derive(Debug, Clone, PartialEq)]
pub struct RollStudy {
    /// Name of the roll error of the axis (`EAX` for X).
    pub roll_error_name: String,
    /// −b_to_a: EAX = sign · εx.
    pub roll_error_sign: i8,
    /// Samples read, and in dwells.
    pub samples: (usize, usize),
    /// How dwells were found (`station column` or `detected`).
    pub dwell_source: &'static str,
    /// How passes were found.
    pub pass_source: &'static str,
    /// Resolution per probe, µm (0: continuous), and whether given or detected.
    pub resolution_um: [f64; 4],
    /// `pipeline` or `detected`.
    pub resolution_source: &'static str,
    /// Dwells in time order.
    pub dwells: Vec<DwellResult>,
    /// Passes in time order.
    pub passes: Vec<PassResult>,
    /// εx per station.
    pub stations: Vec<StationResult>,
    /// Level readings as used.
    pub levels: Vec<LevelResult>,
    /// The effects in the model with their values.
    pub effects: Vec<EffectFit>,
    /// χ², its degrees of freedom and the scale applied to u.
    pub chi2: (f64, usize, f64),
    /// Whether levels at two or more stations made the model fit the probes' combined zero
    /// offset (the end-level datum removes the ramp).
    pub level_datum: bool,
    /// Mean step between consecutive stations from the dwells, mm.
    pub step_mm: f64,
    /// The rig's L, mm.
    pub l_mm: f64,
    /// Relative scale uncertainty of εx from the probes' lateral positions.
    pub scale_u: f64,
    /// Set when the roll is implausibly large.
    pub implausible: Option<Implausible>,
    /// The loop.
    pub diagnosis: RollDiagnosis,
}

/// Samples converted: time in s since the first, readings in µm.
struct Converted {
    time_s: Vec<f64>,
    x_mm: Vec<f64>,
    m_um: Vec<[f64; 4]>,
}

fn convert(logs: &RollCampaignLogs) -> Converted {
    let t0 = logs.samples.first().map_or(0, |s| s.time_ns);
    let k = logs.campaign.probes.map(|p| p.um_per_unit);
    Converted {
        time_s: logs
            .samples
            .iter()
            .map(|s| (s.time_ns - t0) as f64 * 1e-9)
            .collect(),
        x_mm: logs.samples.iter().map(|s| s.x_mm).collect(),
        m_um: logs
            .samples
            .iter()
            .map(|s| std::array::from_fn(|p| s.m[p] * k[p]))
            .collect(),
    }
}

/// Analyse a `roll` campaign.
pub fn study(logs: &RollCampaignLogs, options: &RollOptions) -> Result<RollStudy, RollError> {
    let c = &logs.campaign;
    let data = convert(logs);
    let first_file = logs.probe_files.first().cloned().unwrap_or_default();
    let pass_col: Vec<Option<i64>> = logs.samples.iter().map(|s| s.pass).collect();
    let mut dwells = if logs.has_station {
        let station: Vec<Option<i64>> = logs.samples.iter().map(|s| s.station).collect();
        dwells::marked(&station, &pass_col, &data.x_mm)
    } else {
        dwells::detect(
            &data.time_s,
            &data.x_mm,
            &pass_col,
            c.dwell_min_s,
            c.dwell_tol_um,
        )
    };
    if dwells.is_empty() {
        return Err(RollError::NoDwells {
            file: first_file,
            samples: logs.samples.len(),
            tol_um: c.dwell_tol_um,
            min_s: c.dwell_min_s,
        });
    }
    dwells::station_indices(&mut dwells, c.b_to_a, c.s_mm).map_err(|e| {
        let d = &dwells[e.dwell];
        let (file, first_row) = logs.samples[d.first].source;
        RollError::OffGrid {
            file: logs.probe_files[file as usize].clone(),
            first_row,
            last_row: logs.samples[d.last].source.1,
            x_mm: d.x_mm,
            steps: e.steps,
            off: dwells::OFF_GRID,
        }
    })?;
    let max_station = dwells.iter().map(|d| d.station).max().unwrap_or(0);
    if max_station == 0 {
        return Err(RollError::OneStation { file: first_file });
    }
    let resolution = resolution(&data, &dwells, options);
    let mut dwell_results = dwell_means(&data, &dwells, resolution);
    let pass_dwells = dwells::passes(&dwells, logs.has_pass);
    for (p, pass) in pass_dwells.iter().enumerate().rev() {
        for &k in pass {
            dwell_results[k].pass = p;
        }
    }
    let steps = step_rows(&pass_dwells, &dwell_results);
    let levels = place_levels(logs, &data, &dwells, &dwell_results, options)?;
    let probes = &c.probes;
    let geometry = Geometry {
        l_mm: c.l_mm,
        l_ac_mm: probes[2].xy_mm[1] - probes[0].xy_mm[1],
        l_bd_mm: probes[3].xy_mm[1] - probes[1].xy_mm[1],
        stations: max_station,
    };
    let mut effects = options.effects.clone();
    let datum = level_datum(&levels);
    if datum && !effects.contains(&RollEffect::ProbeZeroOffset) {
        effects.insert(0, RollEffect::ProbeZeroOffset);
    }
    let fit = model::fit(&steps, &levels, geometry, &effects)?;
    let scale_u = (probes[2].u_xy_um.powi(2) + probes[0].u_xy_um.powi(2)).sqrt() / (c.l_mm * 1e3);
    let sign = -c.b_to_a;
    let stations = station_results(&fit, &dwell_results, max_station, scale_u, sign);
    let passes = pass_results(
        &pass_dwells,
        &dwell_results,
        &stations,
        &steps,
        &fit,
        c.l_mm,
    );
    let level_results = levels
        .iter()
        .enumerate()
        .map(|(i, l)| LevelResult {
            station: l.station,
            roll_urad: l.roll_urad,
            residual_urad: fit.solution.residuals[fit.step_rows + i],
        })
        .collect();
    let implausible = plausibility(&stations, options.plausible_roll_urad, c.l_mm);
    let step_mm = mean_step_mm(&dwell_results);
    let span = reading_span_um(&dwell_results);
    let max_abs = stations
        .iter()
        .map(|s| s.roll_urad.abs())
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let unseen = effects::unseen(
        span,
        c.l_mm,
        probes.iter().map(|p| p.u_xy_um).fold(0.0, f64::max),
        max_abs,
        (step_mm - c.d_mm) * 1e3,
        !levels.is_empty(),
    );
    let diagnosis = diagnose(
        &steps,
        &levels,
        geometry,
        &fit,
        options,
        &implausible,
        unseen,
    )?;
    Ok(RollStudy {
        roll_error_name: c.axis.error_names()[3 + c.axis.index()].clone(),
        roll_error_sign: sign,
        samples: (
            logs.samples.len(),
            dwells.iter().map(|d| d.last - d.first + 1).sum(),
        ),
        dwell_source: if logs.has_station {
            "station column"
        } else {
            "detected from x_mm"
        },
        pass_source: if logs.has_pass {
            "pass column (split at reversals)"
        } else {
            "reversals of the stepping direction"
        },
        resolution_um: resolution,
        resolution_source: if options.resolution_um.is_some() {
            "pipeline"
        } else {
            "detected from the readings"
        },
        dwells: dwell_results,
        passes,
        stations,
        levels: level_results,
        effects: fit
            .effects
            .iter()
            .map(|&e| EffectFit {
                effect: e,
                value: fit
                    .effect_value(e)
                    .map_or((f64::NAN, f64::NAN), |(v, u)| (v, 2.0 * u)),
            })
            .collect(),
        chi2: (fit.chi2, fit.solution.dof, fit.scale()),
        level_datum: datum,
        step_mm,
        l_mm: c.l_mm,
        scale_u,
        implausible,
        diagnosis,
    })
}

/// Per probe: the pipeline's resolution, else the grid its dwell readings lie on, else 0.
fn resolution(data: &Converted, dwells: &[Dwell], options: &RollOptions) -> [f64; 4] {
    if let Some(r) = options.resolution_um {
        return [r; 4];
    }
    std::array::from_fn(|p| {
        let values: Vec<f64> = dwells
            .iter()
            .flat_map(|d| data.m_um[d.first..=d.last].iter().map(move |m| m[p]))
            .collect();
        stations::detect_resolution(&values).unwrap_or(0.0)
    })
}

fn dwell_means(data: &Converted, dwells: &[Dwell], resolution: [f64; 4]) -> Vec<DwellResult> {
    dwells
        .iter()
        .map(|d| {
            let means: [stations::ProbeMean; 4] = std::array::from_fn(|p| {
                let v: Vec<f64> = data.m_um[d.first..=d.last].iter().map(|m| m[p]).collect();
                stations::probe_mean(&v, resolution[p])
            });
            let readings = &data.m_um[d.first..=d.last];
            DwellResult {
                pass: 0,
                station: d.station,
                x_mm: d.x_mm,
                span_s: (data.time_s[d.first], data.time_s[d.last]),
                samples: d.last - d.first + 1,
                mean_um: means.map(|m| m.mean_um),
                u_um: means.map(|m| m.u_um),
                tau: means.map(|m| m.tau),
                pair_u_um: [
                    difference_u(readings, (2, 0), resolution),
                    difference_u(readings, (3, 1), resolution),
                ],
            }
        })
        .collect()
}

/// The standard uncertainty of a dwell's mean of `m[i] − m[j]` taken sample by sample, µm:
/// Type A with τ of the differences, the two probes' resolutions, the floor.
///
/// Why the differences: the estimator uses a dwell's readings only as C − A and D − B
/// (`docs/spec/machine-physics.md`, "Kind roll": δz enters all four, εy both of B and D), so a
/// stage that settles or vibrates during a dwell moves the four readings together and not their
/// differences. Each probe's own Type A would count that motion four times over: on a second
/// simulator whose readings follow the stage into its moves (`tests/e2e/roll_foreign.rs`), the
/// first samples of a move inside the dwell band would make U 30 times the error.
fn difference_u(readings: &[[f64; 4]], (i, j): (usize, usize), resolution: [f64; 4]) -> f64 {
    let v: Vec<f64> = readings.iter().map(|m| m[i] - m[j]).collect();
    let (_, u_a_um, _) = stations::mean_type_a(&v);
    let u_res2 = (resolution[i].powi(2) + resolution[j].powi(2)) / 12.0;
    (u_a_um * u_a_um + u_res2).sqrt().max(stations::U_FLOOR_UM)
}

/// The step rows of every pass: two dwells one station apart, consecutive in the pass.
fn step_rows(passes: &[Vec<usize>], dwells: &[DwellResult]) -> Vec<StepRow> {
    let mut rows = Vec::new();
    for (p, pass) in passes.iter().enumerate() {
        for w in pass.windows(2) {
            let (a, b) = (&dwells[w[0]], &dwells[w[1]]);
            if a.station.abs_diff(b.station) != 1 {
                continue;
            }
            let (before, after) = if a.station < b.station {
                (a, b)
            } else {
                (b, a)
            };
            let q = (after.mean_um[2] - before.mean_um[3]) - (after.mean_um[0] - before.mean_um[1]);
            let u = (after.pair_u_um[0].powi(2) + before.pair_u_um[1].powi(2)).sqrt();
            let mid = |d: &DwellResult| 0.5 * (d.span_s.0 + d.span_s.1) / 3600.0;
            rows.push(StepRow {
                pass: p,
                station: after.station,
                q_um: q,
                u_q_um: u,
                t_h: (mid(after), mid(before)),
            });
        }
    }
    rows
}

fn place_levels(
    logs: &RollCampaignLogs,
    data: &Converted,
    dwells: &[Dwell],
    results: &[DwellResult],
    options: &RollOptions,
) -> Result<Vec<LevelObs>, RollError> {
    let t0 = logs.samples.first().map_or(0, |s| s.time_ns);
    let half_gap = 0.5 * median_interval_s(&data.time_s);
    let mut out = Vec::new();
    for l in &logs.levels {
        let t = (l.time_ns - t0) as f64 * 1e-9;
        let file = logs
            .level_files
            .get(l.source.0 as usize)
            .cloned()
            .unwrap_or_default();
        let Some(k) = results
            .iter()
            .position(|d| t >= d.span_s.0 - half_gap && t <= d.span_s.1 + half_gap)
        else {
            return Err(RollError::LevelOutsideDwell {
                file,
                row: l.source.1,
                time_s: t,
            });
        };
        let u = l.u_urad.unwrap_or(options.level_u_urad);
        if !(u.is_finite() && u > 0.0) {
            return Err(RollError::LevelU {
                file,
                row: l.source.1,
                u,
            });
        }
        out.push(LevelObs {
            station: dwells[k].station,
            roll_urad: l.roll_urad,
            u_urad: u,
            t_h: t / 3600.0,
        });
    }
    Ok(out)
}

/// Levels at two or more stations: the combined zero offset is determined.
fn level_datum(levels: &[LevelObs]) -> bool {
    let mut st: Vec<usize> = levels.iter().map(|l| l.station).collect();
    st.sort_unstable();
    st.dedup();
    st.len() >= 2
}

fn median_interval_s(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return 0.0;
    }
    d.sort_by(f64::total_cmp);
    d[d.len() / 2]
}

fn station_results(
    fit: &ModelFit,
    dwells: &[DwellResult],
    max_station: usize,
    scale_u: f64,
    sign: i8,
) -> Vec<StationResult> {
    (0..=max_station)
        .map(|n| {
            let xs: Vec<f64> = dwells
                .iter()
                .filter(|d| d.station == n)
                .map(|d| d.x_mm)
                .collect();
            let x_mm = if xs.is_empty() {
                f64::NAN
            } else {
                xs.iter().sum::<f64>() / xs.len() as f64
            };
            let (roll, u) = fit.roll(n).unwrap_or((f64::NAN, f64::NAN));
            let u_total = (u * u + (scale_u * roll).powi(2)).sqrt();
            StationResult {
                station: n,
                x_mm,
                roll_urad: roll,
                u_noise_urad: u,
                u_k2_urad: 2.0 * u_total,
                roll_error_urad: f64::from(sign) * roll,
            }
        })
        .collect()
}

fn pass_results(
    passes: &[Vec<usize>],
    dwells: &[DwellResult],
    stations: &[StationResult],
    steps: &[StepRow],
    fit: &ModelFit,
    l_mm: f64,
) -> Vec<PassResult> {
    passes
        .iter()
        .enumerate()
        .map(|(p, pass)| {
            let st: Vec<usize> = pass.iter().map(|&k| dwells[k].station).collect();
            let mut roll = vec![stations[st[0]].roll_urad];
            for w in pass.windows(2) {
                let (a, b) = (&dwells[w[0]], &dwells[w[1]]);
                let last = *roll.last().unwrap_or(&f64::NAN);
                let next = if b.station == a.station + 1 {
                    last + estimator::step_urad(&a.mean_um, &b.mean_um, l_mm)
                } else if a.station == b.station + 1 {
                    last - estimator::step_urad(&b.mean_um, &a.mean_um, l_mm)
                } else {
                    stations[b.station].roll_urad
                };
                roll.push(next);
            }
            let res: Vec<f64> = steps
                .iter()
                .enumerate()
                .filter(|(_, s)| s.pass == p)
                .map(|(i, _)| fit.solution.residuals[i])
                .collect();
            let rms = if res.is_empty() {
                0.0
            } else {
                (res.iter().map(|r| r * r).sum::<f64>() / res.len() as f64).sqrt()
            };
            PassResult {
                direction: if st.last() >= st.first() { 1 } else { -1 },
                stations: st,
                roll_urad: roll,
                rms_residual_urad: rms,
            }
        })
        .collect()
}

fn mean_step_mm(dwells: &[DwellResult]) -> f64 {
    let mut by_station: std::collections::BTreeMap<usize, Vec<f64>> = Default::default();
    for d in dwells {
        by_station.entry(d.station).or_default().push(d.x_mm);
    }
    let xs: Vec<(usize, f64)> = by_station
        .into_iter()
        .map(|(n, v)| (n, v.iter().sum::<f64>() / v.len() as f64))
        .collect();
    match (xs.first(), xs.last()) {
        (Some(a), Some(b)) if b.0 > a.0 => (b.1 - a.1).abs() / (b.0 - a.0) as f64,
        _ => f64::NAN,
    }
}

fn reading_span_um(dwells: &[DwellResult]) -> f64 {
    (0..4)
        .map(|p| {
            let v = dwells.iter().map(|d| d.mean_um[p]);
            let max = v.clone().fold(f64::NEG_INFINITY, f64::max);
            let min = v.fold(f64::INFINITY, f64::min);
            max - min
        })
        .fold(0.0, f64::max)
}

/// The roll is implausible when its largest |εx| exceeds `limit_urad`.
fn plausibility(stations: &[StationResult], limit_urad: f64, l_mm: f64) -> Option<Implausible> {
    let ok: Vec<&StationResult> = stations
        .iter()
        .filter(|s| s.roll_urad.is_finite())
        .collect();
    let max_abs = ok.iter().map(|s| s.roll_urad.abs()).fold(0.0, f64::max);
    if max_abs <= limit_urad {
        return None;
    }
    let sxy: f64 = ok.iter().map(|s| s.station as f64 * s.roll_urad).sum();
    let sxx: f64 = ok.iter().map(|s| (s.station as f64).powi(2)).sum();
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    Some(Implausible {
        max_abs_urad: max_abs,
        limit_urad,
        slope_urad_per_station: slope,
        equivalent_offset_um: slope * l_mm / 1e3,
    })
}

/// Candidates, forward selection, the named missing effect.
fn diagnose(
    steps: &[StepRow],
    levels: &[LevelObs],
    g: Geometry,
    fit: &ModelFit,
    options: &RollOptions,
    implausible: &Option<Implausible>,
    unseen: Vec<Unseen>,
) -> Result<RollDiagnosis, RollError> {
    let with = |base: &ModelFit, e: RollEffect| -> Result<Option<ModelFit>, RollError> {
        let mut effects = base.effects.clone();
        effects.push(e);
        let f = model::fit(steps, levels, g, &effects)?;
        Ok(f.effects_determined().then_some(f))
    };
    let mut candidates = Vec::new();
    for e in RollEffect::ALL
        .into_iter()
        .filter(|e| !fit.effects.contains(e))
    {
        let f = with(fit, e)?;
        candidates.push(Candidate {
            effect: e,
            delta_bic: f.as_ref().map(|f| f.bic - fit.bic),
            chi2: f.as_ref().map_or(fit.chi2, |f| f.chi2),
        });
    }
    candidates.sort_by(|a, b| {
        a.delta_bic
            .unwrap_or(f64::INFINITY)
            .total_cmp(&b.delta_bic.unwrap_or(f64::INFINITY))
    });
    let mut ledger = vec![LedgerStep {
        effect: None,
        chi2: fit.chi2,
        delta_bic: 0.0,
    }];
    let mut current = fit.clone();
    for _ in 0..options.forward_steps {
        let mut best: Option<(RollEffect, ModelFit)> = None;
        for e in RollEffect::ALL
            .into_iter()
            .filter(|e| !current.effects.contains(e))
        {
            if let Some(f) = with(&current, e)? {
                if best.as_ref().is_none_or(|(_, b)| f.bic < b.bic) {
                    best = Some((e, f));
                }
            }
        }
        match best {
            Some((e, f)) if f.bic - current.bic <= -options.min_bic_gain => {
                ledger.push(LedgerStep {
                    effect: Some(e),
                    chi2: f.chi2,
                    delta_bic: f.bic - current.bic,
                });
                current = f;
            }
            _ => break,
        }
    }
    let (missing, because) = if let Some(step) = ledger.get(1) {
        (
            step.effect,
            format!(
                "adding it lowers the BIC by {:.1} (χ² {:.1} → {:.1})",
                -step.delta_bic, fit.chi2, step.chi2
            ),
        )
    } else if let (Some(i), false) = (
        implausible,
        fit.effects.contains(&RollEffect::ProbeZeroOffset),
    ) {
        (
            Some(RollEffect::ProbeZeroOffset),
            format!(
                "the roll reaches {:.0} µrad, implausible for a machine table (> {:.0} µrad), and grows as a ramp of {:.1} µrad per station: a combined zero offset o_C − o_D − o_A + o_B of {:.2} µm makes it; read a level at both ends (levels/) to separate it",
                i.max_abs_urad, i.limit_urad, i.slope_urad_per_station, i.equivalent_offset_um
            ),
        )
    } else {
        (None, String::new())
    };
    Ok(RollDiagnosis {
        candidates,
        ledger,
        missing,
        missing_because: because,
        unseen,
    })
}

/// The probe names, A … D.
pub const PROBE_NAMES: [&str; 4] = PROBES;
