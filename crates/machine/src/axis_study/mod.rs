//! An `axis` campaign analysed (seed 002; `docs/spec/machine-physics.md`, "Kind axis"): the
//! readings normalised per `[laser] compensation` (modified Edlén, [`crate::edlen`]), the six
//! errors at every target and direction from all runs at once, their U (k = 2), the rank and
//! what it loses by name, ISO 230-2 on the positioning error, straightness raw and without its
//! least-squares line, the point choice, and the loop: where the model fails (residuals per line
//! and run), which effect of the spec's table explains it (candidates ranked by BIC), the
//! ledger of adding them, and what these readings can never tell.
//!
//! Errors are relative to the datum: the first target of the first line in its first direction
//! (each line's laser is zeroed there; `machine-physics.md`, "Not identifiable").

mod effects;
mod model;
#[cfg(test)]
mod tests;

use std::collections::BTreeMap;

use dbbcal_core::axis_campaign::{AxisCampaignLogs, Channel as LogChannel, LaserCompensation};

use crate::axis::{self, AxisReading as Reading, Channel, Fixture, LineCandidates, PointChoice};
use crate::components::Axis;
use crate::edlen::{self, Air, Compensation, LaserSetup, ReadingConditions};
use crate::iso230_2::{self, Iso230_2, TargetDeviations};
use crate::linear::LinearError;
use crate::straightness::{self, Straightness};

use effects::{regressors, RegressorInputs};
pub use effects::{unseen, AxisEffect, Unseen};
use model::{ModelFit, PlacedReading};

/// What the analysis may do.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisStudyOptions {
    /// The effects in the model (the user's `[axis] effects` and `--add-effect`).
    pub effects: Vec<AxisEffect>,
    /// Steps of forward selection over the candidates (0: rank only).
    pub forward_steps: usize,
    /// The BIC gain an effect must bring to be proposed (10: "very strong" evidence).
    pub min_bic_gain: f64,
}

impl Default for AxisStudyOptions {
    fn default() -> Self {
        AxisStudyOptions {
            effects: Vec::new(),
            forward_steps: 3,
            min_bic_gain: 10.0,
        }
    }
}

/// Why an `axis` campaign cannot be analysed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AxisStudyError {
    /// No reading at all.
    #[error("no reading to analyse")]
    NoReadings,
    /// A reading cannot be normalised (the environment it needs is missing or not finite).
    #[error("line {line}, run {run}, target {target_mm} mm: {problem}")]
    Normalise {
        /// Line id.
        line: i64,
        /// Run.
        run: i64,
        /// Target, mm.
        target_mm: f64,
        /// What is wrong.
        problem: String,
    },
    /// The linear engine refused the problem.
    #[error(transparent)]
    Linear(#[from] LinearError),
}

/// The six errors at one target and direction.
#[derive(Debug, Clone, PartialEq)]
pub struct TargetErrors {
    /// Commanded coordinate of the axis, mm.
    pub target_mm: f64,
    /// +1 / −1: approached moving in the axis's + / − direction.
    pub direction: i8,
    /// δx, δy, δz (µm), εx, εy, εz (µrad), relative to the datum; NaN where not determined.
    pub errors: [f64; 6],
    /// Expanded uncertainty (k = 2) of each, from the readings' scatter; NaN where not determined.
    pub u_k2: [f64; 6],
    /// Which of the six the readings determine.
    pub determined: [bool; 6],
}

/// An effect's fitted parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct EffectFit {
    /// The effect.
    pub effect: AxisEffect,
    /// (name, value, U (k = 2)) of each parameter; NaN where the readings do not determine it.
    /// The warm-up's τ (`warm_up_tau_h`) is found by a search on a grid and carries no U.
    pub parameters: Vec<(String, f64, f64)>,
}

/// The residuals of one line, run and channel.
#[derive(Debug, Clone, PartialEq)]
pub struct LineRunResidual {
    /// Line id.
    pub line: i64,
    /// Run.
    pub run: i64,
    /// Channel (`dx`, `dy`, `dz`).
    pub channel: &'static str,
    /// RMS residual, µm.
    pub rms_um: f64,
    /// Readings.
    pub readings: usize,
}

/// A candidate effect: the model with it added.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// The effect.
    pub effect: AxisEffect,
    /// BIC change (negative: better).
    pub delta_bic: f64,
    /// RMS residual along the axis and across it with the effect, µm.
    pub rms_um: [f64; 2],
}

/// One step of forward selection.
#[derive(Debug, Clone, PartialEq)]
pub struct LedgerStep {
    /// The effect added (`None`: the starting model).
    pub effect: Option<AxisEffect>,
    /// RMS residual along and across the axis after the step, µm.
    pub rms_um: [f64; 2],
    /// BIC change of the step.
    pub delta_bic: f64,
}

/// Where the model fails and what would fix it.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisDiagnosis {
    /// Every effect not in the model, best first.
    pub candidates: Vec<Candidate>,
    /// Forward selection from the model: its start, then each effect added.
    pub ledger: Vec<LedgerStep>,
    /// The effect to add next (the ledger's first step), if any brings the BIC gain asked for.
    pub proposal: Option<AxisEffect>,
    /// The catalogue's effects these readings cannot see.
    pub unseen: Vec<Unseen>,
}

/// A straightness error of the axis.
#[derive(Debug, Clone, PartialEq)]
pub struct StraightnessResult {
    /// Its ISO 230-1 name (EYX, EZX for X).
    pub name: String,
    /// Targets, mm.
    pub targets_mm: Vec<f64>,
    /// Raw (bidirectional mean) and without its least-squares line.
    pub straightness: Straightness,
}

/// An `axis` campaign analysed.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisStudy {
    /// The axis under test.
    pub axis: Axis,
    /// ISO 230-1 names of the six errors (δx … εz order).
    pub names: [String; 6],
    /// The datum: target (mm) and direction.
    pub datum: (f64, i8),
    /// The six errors at each target and direction, sorted by direction then target.
    pub targets: Vec<TargetErrors>,
    /// The smallest rank over the targets (6: every error determined).
    pub rank: usize,
    /// The errors the readings lose, by name (e.g. `EAX` when the lines share their height).
    pub lost: Vec<String>,
    /// ISO 230-2 on the positioning error (EXX for X) over the runs; `None` with one run.
    pub iso230_2: Option<Iso230_2>,
    /// Why ISO 230-2 is missing, when it is.
    pub iso230_2_missing: Option<String>,
    /// The two straightness errors.
    pub straightness: Vec<StraightnessResult>,
    /// The reflector points per line and the noise-amplification criterion.
    pub point_choice: Option<PointChoice>,
    /// The model's effects and their parameters.
    pub effects: Vec<EffectFit>,
    /// σ of a reading along and across the axis from the residuals, µm.
    pub sigma_um: [f64; 2],
    /// RMS residual along and across the axis, µm.
    pub rms_um: [f64; 2],
    /// Residuals per line, run and channel.
    pub residuals: Vec<LineRunResidual>,
    /// The loop.
    pub diagnosis: AxisDiagnosis,
    /// Readings used.
    pub readings: usize,
}

/// Analyse an `axis` campaign's logs.
pub fn study(
    logs: &AxisCampaignLogs,
    options: &AxisStudyOptions,
) -> Result<AxisStudy, AxisStudyError> {
    let placed = place(logs)?;
    let axis = logs.campaign.axis;
    let names = axis.iso230_1_names();
    let fit = model::fit(&placed.readings, &placed.labels, &names, &options.effects)?;
    let diagnosis = diagnose(&placed, &names, &fit, options)?;
    let targets = target_errors(&placed, &fit);
    let (rank, lost) = rank_and_lost(&fit, &names);
    let (iso, iso_missing) = positioning_iso(logs, &placed, &fit, axis, &targets);
    let residuals = model::residuals_by_line_run(&placed.readings, &fit.solution)
        .into_iter()
        .map(
            |((line, run, channel), (rms_um, readings))| LineRunResidual {
                line,
                run,
                channel: channel_name(channel),
                rms_um,
                readings,
            },
        )
        .collect();
    Ok(AxisStudy {
        axis,
        names: names.clone(),
        datum: placed.blocks[placed.datum_block],
        straightness: straightness_of(axis, &names, &targets),
        point_choice: point_choice(logs).ok(),
        effects: effect_fits(&fit, placed.blocks.len()),
        sigma_um: fit.sigma_um,
        rms_um: fit.rms_um,
        residuals,
        diagnosis,
        readings: placed.readings.len(),
        targets,
        rank,
        lost,
        iso230_2: iso,
        iso230_2_missing: iso_missing,
    })
}

/// The readings placed in (target, direction) blocks, normalised, with their regressors.
struct Placed {
    readings: Vec<PlacedReading>,
    /// (target mm, direction) of each block, sorted by direction (+ first) then target.
    blocks: Vec<(f64, i8)>,
    /// Each block's label in parameter names (`250+`).
    labels: Vec<String>,
    /// The datum's block.
    datum_block: usize,
    /// Per reading of `logs.readings` kept: its run and its index in `readings`.
    runs: Vec<i64>,
}

fn to_channel(c: LogChannel) -> Channel {
    match c {
        LogChannel::Dx => Channel::Dx,
        LogChannel::Dy => Channel::Dy,
        LogChannel::Dz => Channel::Dz,
    }
}

fn channel_name(c: Channel) -> &'static str {
    ["dx", "dy", "dz"][c.index()]
}

fn to_compensation(c: LaserCompensation) -> Compensation {
    match c {
        LaserCompensation::None => Compensation::None,
        LaserCompensation::Air => Compensation::Air,
        LaserCompensation::AirMaterial => Compensation::AirMaterial,
    }
}

/// A target as a key: to the nanometre.
fn target_key(target_mm: f64) -> i64 {
    (target_mm * 1e6).round() as i64
}

fn air_at(logs: &AxisCampaignLogs, time_ns: i64) -> (Option<Air>, Option<f64>) {
    match logs.environment_at(time_ns) {
        Some(e) => (
            Some(Air {
                temperature_c: e.air_c,
                pressure_hpa: e.pressure_hpa,
                humidity_pct: e.humidity_pct,
            }),
            e.material_c,
        ),
        None => (None, None),
    }
}

/// The datum of each line: its first reading in time (the laser is zeroed there).
fn line_datums(logs: &AxisCampaignLogs) -> BTreeMap<i64, (f64, i64)> {
    let mut datums: BTreeMap<i64, (f64, i64)> = BTreeMap::new();
    for r in &logs.readings {
        let d = datums.entry(r.line).or_insert((r.target_mm, r.time_ns));
        if r.time_ns < d.1 {
            *d = (r.target_mm, r.time_ns);
        }
    }
    datums
}

fn place(logs: &AxisCampaignLogs) -> Result<Placed, AxisStudyError> {
    if logs.readings.is_empty() {
        return Err(AxisStudyError::NoReadings);
    }
    let c = &logs.campaign;
    let along = to_channel(LogChannel::of_axis(c.axis));
    let setup = LaserSetup {
        wavelength_nm: c.wavelength_nm,
        compensation: to_compensation(c.compensation),
        dead_path_mm: c.dead_path_mm,
        cte_ppm_per_k: c.cte_ppm_per_k,
        reference_temperature_c: c.reference_temperature_c,
    };
    let datums = line_datums(logs);
    let first_time = logs.readings.iter().map(|r| r.time_ns).min().unwrap_or(0);
    let (first_air, first_material) = air_at(logs, first_time);
    let n_first = first_air.and_then(|a| edlen::refractive_index(&a, c.wavelength_nm).ok());
    let mut block_keys: Vec<(i8, i64)> = logs
        .readings
        .iter()
        .map(|r| (-r.direction, target_key(r.target_mm)))
        .collect();
    block_keys.sort_unstable();
    block_keys.dedup();
    let index: BTreeMap<(i8, i64), usize> = block_keys
        .iter()
        .enumerate()
        .map(|(i, &k)| (k, i))
        .collect();
    let blocks: Vec<(f64, i8)> = block_keys
        .iter()
        .map(|&(minus_d, key)| (key as f64 * 1e-6, -minus_d))
        .collect();
    let first_line = logs
        .readings
        .iter()
        .min_by_key(|r| r.time_ns)
        .expect("readings checked non-empty");
    let datum_block = index[&(
        -first_line.direction,
        target_key(datums[&first_line.line].0),
    )];
    let mut readings = Vec::with_capacity(logs.readings.len());
    let mut runs = Vec::with_capacity(logs.readings.len());
    for r in &logs.readings {
        let channel = to_channel(r.channel);
        let is_along = channel == along;
        let (datum_target, datum_time) = datums[&r.line];
        let displacement_mm = r.target_mm - datum_target;
        let (air, material_c) = air_at(logs, r.time_ns);
        let (datum_air, _) = air_at(logs, datum_time);
        let bad = |problem: String| AxisStudyError::Normalise {
            line: r.line,
            run: r.run,
            target_mm: r.target_mm,
            problem,
        };
        let deviation_um = if is_along {
            let conditions = ReadingConditions {
                air,
                datum_air,
                material_c,
            };
            let read_mm = displacement_mm + 1e-3 * r.deviation_um;
            let true_mm = edlen::normalise_reading_mm(read_mm, &setup, &conditions)
                .map_err(|e| bad(e.to_string()))?;
            1e3 * (true_mm - displacement_mm)
        } else {
            r.deviation_um
        };
        let n = match (air, datum_air, n_first) {
            (Some(a), Some(d), Some(n0)) => Some((
                edlen::refractive_index(&a, c.wavelength_nm).map_err(|e| bad(e.to_string()))?,
                edlen::refractive_index(&d, c.wavelength_nm).map_err(|e| bad(e.to_string()))?,
                n0,
            )),
            _ => None,
        };
        let hours = |t: i64| (t - datum_time) as f64 / 3.6e12;
        let inputs = RegressorInputs {
            along: is_along,
            displacement_mm,
            hours_since_datum: hours(r.time_ns),
            hours_since_start: (r.time_ns - first_time) as f64 / 3.6e12,
            n,
            material_change_k: material_c.zip(first_material).map(|(m, m0)| m - m0),
        };
        let reflector = logs.reflector_mm(r);
        readings.push(PlacedReading {
            block: index[&(-r.direction, target_key(r.target_mm))],
            channel,
            along: is_along,
            line: r.line,
            run: r.run,
            offset_mm: std::array::from_fn(|k| reflector[k] - c.report_point_mm[k]),
            deviation_um,
            regressors: regressors(&inputs),
            hours_since_start: [
                inputs.hours_since_start,
                inputs.hours_since_start - inputs.hours_since_datum,
            ],
        });
        runs.push(r.run);
    }
    let labels = blocks
        .iter()
        .map(|&(t, d)| format!("{t}{}", if d >= 0 { "+" } else { "-" }))
        .collect();
    Ok(Placed {
        readings,
        blocks,
        labels,
        datum_block,
        runs,
    })
}

/// Rank the effects not in the model, then forward selection from it.
fn diagnose(
    placed: &Placed,
    names: &[String; 6],
    fit: &ModelFit,
    options: &AxisStudyOptions,
) -> Result<AxisDiagnosis, AxisStudyError> {
    let try_add = |base: &ModelFit, e: AxisEffect| -> Result<ModelFit, AxisStudyError> {
        let mut effects = base.effects.clone();
        effects.push(e);
        Ok(model::fit(
            &placed.readings,
            &placed.labels,
            names,
            &effects,
        )?)
    };
    let mut candidates = Vec::new();
    for e in AxisEffect::ALL
        .into_iter()
        .filter(|&e| !e.is_within(&fit.effects))
    {
        let with = try_add(fit, e)?;
        candidates.push(Candidate {
            effect: e,
            delta_bic: with.bic - fit.bic,
            rms_um: with.rms_um,
        });
    }
    candidates.sort_by(|a, b| a.delta_bic.total_cmp(&b.delta_bic));
    let mut ledger = vec![LedgerStep {
        effect: None,
        rms_um: fit.rms_um,
        delta_bic: 0.0,
    }];
    let mut current = fit.clone();
    for _ in 0..options.forward_steps {
        let mut best: Option<(AxisEffect, ModelFit)> = None;
        for e in AxisEffect::ALL
            .into_iter()
            .filter(|&e| !e.is_within(&current.effects))
        {
            let with = try_add(&current, e)?;
            if best.as_ref().is_none_or(|(_, b)| with.bic < b.bic) {
                best = Some((e, with));
            }
        }
        match best {
            Some((e, with)) if with.bic - current.bic <= -options.min_bic_gain => {
                ledger.push(LedgerStep {
                    effect: Some(e),
                    rms_um: with.rms_um,
                    delta_bic: with.bic - current.bic,
                });
                current = with;
            }
            _ => break,
        }
    }
    let proposal = ledger.get(1).and_then(|s| s.effect);
    Ok(AxisDiagnosis {
        candidates,
        ledger,
        proposal,
        unseen: unseen(),
    })
}

/// The errors of every block relative to the datum block, with U (k = 2) of the difference.
fn target_errors(placed: &Placed, fit: &ModelFit) -> Vec<TargetErrors> {
    let s = &fit.solution;
    let d0 = 6 * placed.datum_block;
    let cov = s.covariance_given.as_ref().or(s.covariance.as_ref());
    placed
        .blocks
        .iter()
        .enumerate()
        .map(|(b, &(target_mm, direction))| {
            let mut errors = [f64::NAN; 6];
            let mut u_k2 = [f64::NAN; 6];
            let mut determined = [false; 6];
            for k in 0..6 {
                let (i, j) = (6 * b + k, d0 + k);
                let det = s.determined[i] && s.determined[j];
                determined[k] = det;
                if !det {
                    continue;
                }
                errors[k] = if b == placed.datum_block {
                    0.0
                } else {
                    s.estimate[i] - s.estimate[j]
                };
                u_k2[k] = match cov {
                    Some(c) if b != placed.datum_block => {
                        2.0 * (c[(i, i)] + c[(j, j)] - 2.0 * c[(i, j)]).max(0.0).sqrt()
                    }
                    Some(_) => 0.0,
                    None => f64::NAN,
                };
            }
            TargetErrors {
                target_mm,
                direction,
                errors,
                u_k2,
                determined,
            }
        })
        .collect()
}

/// The smallest rank of a block's rows (6 − the combinations it loses) and what is lost, by
/// error name (the block label dropped: the same loss repeats at every target).
fn rank_and_lost(fit: &ModelFit, names: &[String; 6]) -> (usize, Vec<String>) {
    let s = &fit.solution;
    let mut lost: Vec<String> = Vec::new();
    let mut per_block: BTreeMap<String, usize> = BTreeMap::new();
    for combo in &s.lost {
        let terms: Vec<&(String, f64)> =
            combo.terms.iter().filter(|(_, w)| w.abs() > 1e-6).collect();
        let Some(block) = terms
            .iter()
            .find_map(|(n, _)| n.split_once('@').map(|(_, b)| b.to_string()))
        else {
            continue;
        };
        *per_block.entry(block).or_default() += 1;
        let text = terms
            .iter()
            .map(|(n, _)| n.split('@').next().unwrap_or(n).to_string())
            .collect::<std::collections::BTreeSet<_>>()
            .into_iter()
            .collect::<Vec<_>>()
            .join(" + ");
        if names.iter().any(|n| text.contains(n.as_str())) && !lost.contains(&text) {
            lost.push(text);
        }
    }
    let rank = 6usize.saturating_sub(per_block.values().copied().max().unwrap_or(0));
    (rank, lost)
}

/// The effects' parameters.
fn effect_fits(fit: &ModelFit, blocks: usize) -> Vec<EffectFit> {
    let s = &fit.solution;
    let cov = s.covariance_given.as_ref().or(s.covariance.as_ref());
    let columns = effects::columns_of(&fit.effects);
    fit.effects
        .iter()
        .map(|&effect| {
            let mut parameters: Vec<(String, f64, f64)> = columns
                .iter()
                .enumerate()
                .filter(|(_, c)| c.effect == effect)
                .map(|(k, c)| {
                    let i = 6 * blocks + k;
                    let (value, u) = if s.determined[i] {
                        let u = cov.map_or(f64::NAN, |c| 2.0 * c[(i, i)].max(0.0).sqrt());
                        (s.estimate[i], u)
                    } else {
                        (f64::NAN, f64::NAN)
                    };
                    (c.name.to_string(), value, u)
                })
                .collect();
            if let (AxisEffect::MachineWarmUp, Some(tau)) = (effect, fit.warm_up_tau_h) {
                parameters.push(("warm_up_tau_h".to_string(), tau, f64::NAN));
            }
            EffectFit { effect, parameters }
        })
        .collect()
}

/// ISO 230-2 on the positioning error: each run's six errors solved at every target from the
/// readings with the model's effects taken out, relative to the datum's mean.
fn positioning_iso(
    logs: &AxisCampaignLogs,
    placed: &Placed,
    fit: &ModelFit,
    axis: Axis,
    targets: &[TargetErrors],
) -> (Option<Iso230_2>, Option<String>) {
    let s = &fit.solution;
    let effect_start = 6 * placed.blocks.len();
    let columns = effects::columns_of(&fit.effects);
    let k = axis.positioning_index();
    let fixture = Fixture {
        report_point_mm: [0.0; 3],
        u_um: logs.campaign.fixture_u_um,
    };
    // (run, block) -> readings with the effects removed.
    let mut groups: BTreeMap<(i64, usize), Vec<Reading>> = BTreeMap::new();
    for (r, &run) in placed.readings.iter().zip(&placed.runs) {
        let effect: f64 = columns
            .iter()
            .enumerate()
            .filter(|(_, column)| column.channel.is_none_or(|c| c == r.channel))
            .map(|(j, column)| {
                let v = s.estimate[effect_start + j];
                if v.is_finite() {
                    v * r.regressor(column.regressor, fit.warm_up_tau_h)
                } else {
                    0.0
                }
            })
            .sum();
        groups.entry((run, r.block)).or_default().push(Reading {
            line: u32::try_from(r.line.rem_euclid(1 << 31)).unwrap_or(0),
            channel: r.channel,
            reflector_mm: r.offset_mm,
            deviation_um: r.deviation_um - effect,
            sigma_um: fit.sigma_um[usize::from(!r.along)],
        });
    }
    let datum_value = {
        let d = &s.estimate[6 * placed.datum_block..6 * placed.datum_block + 6];
        d[k]
    };
    let mut per_target: BTreeMap<i64, TargetDeviations> = BTreeMap::new();
    for ((_, block), readings) in &groups {
        let Ok(solved) = axis::solve_target(axis, readings, &fixture) else {
            continue;
        };
        if !solved.determined[k] {
            continue;
        }
        let (target_mm, direction) = placed.blocks[*block];
        let value = solved.errors.to_array()[k] - datum_value;
        let entry = per_target
            .entry(target_key(target_mm))
            .or_insert_with(|| TargetDeviations {
                position_mm: target_mm,
                up_um: Vec::new(),
                down_um: Vec::new(),
            });
        if direction >= 0 {
            entry.up_um.push(value);
        } else {
            entry.down_um.push(value);
        }
    }
    if targets.iter().all(|t| !t.determined[k]) {
        return (
            None,
            Some(format!("{} is not determined", axis.iso230_1_names()[k])),
        );
    }
    let list: Vec<TargetDeviations> = per_target.into_values().collect();
    match iso230_2::evaluate(&list) {
        Ok(iso) => (Some(iso), None),
        Err(e) => (None, Some(e.to_string())),
    }
}

/// The two straightness errors: bidirectional means per target, raw and without their line.
fn straightness_of(
    axis: Axis,
    names: &[String; 6],
    targets: &[TargetErrors],
) -> Vec<StraightnessResult> {
    axis.straightness_indices()
        .into_iter()
        .filter_map(|k| {
            let mut by_target: BTreeMap<i64, (f64, f64, usize)> = BTreeMap::new();
            for t in targets.iter().filter(|t| t.determined[k]) {
                let slot =
                    by_target
                        .entry(target_key(t.target_mm))
                        .or_insert((t.target_mm, 0.0, 0));
                slot.1 += t.errors[k];
                slot.2 += 1;
            }
            let (xs, ys): (Vec<f64>, Vec<f64>) = by_target
                .values()
                .map(|&(x, sum, n)| (x, sum / n as f64))
                .unzip();
            let line = straightness::remove_line(&xs, &ys).ok()?;
            Some(StraightnessResult {
                name: names[k].clone(),
                targets_mm: xs,
                straightness: line,
            })
        })
        .collect()
}

/// The reflector points each line used and the criterion of each combination.
fn point_choice(logs: &AxisCampaignLogs) -> Result<PointChoice, axis::AxisError> {
    let c = &logs.campaign;
    let lines: Vec<LineCandidates> = c
        .lines
        .iter()
        .filter_map(|line| {
            let mut points: Vec<[f64; 3]> = Vec::new();
            let mut channels: Vec<Channel> = Vec::new();
            for r in logs.readings.iter().filter(|r| r.line == line.id) {
                let p = logs.reflector_mm(r);
                let p = std::array::from_fn(|k| p[k] - c.report_point_mm[k]);
                if !points.contains(&p) {
                    points.push(p);
                }
                let ch = to_channel(r.channel);
                if !channels.contains(&ch) {
                    channels.push(ch);
                }
            }
            (!points.is_empty()).then(|| LineCandidates {
                line: u32::try_from(line.id.rem_euclid(1 << 31)).unwrap_or(0),
                channels,
                candidates_mm: points,
            })
        })
        .collect();
    axis::choose_points(&lines)
}
