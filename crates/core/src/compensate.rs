//! Compensation of working bars (`docs/spec/physics.md`, "The calibration unit and the reference bar").
//!
//! A working bar (a plate length used as a check, purpose `check`, or a target device) gets the
//! centre distance `D(n, A)` of its calibration after its thermal error is removed. The thermal
//! error is taken, in order of preference, from
//! - two reference bars on the shortest and longest plate lengths, interpolated on distance as in
//!   the patent: `e_p = e_min + (e_max - e_min) (D_p - D_min) / (D_max - D_min)`;
//! - one reference bar (exact for a zero-expansion scale): `e_p = e_ref`;
//! - the working bar's own identified model, when no reference was logged at the time.
//!
//! A reference's thermal error is *measured*: its reading minus its reading at the reference
//! temperature (the mean over its mount of reading minus modelled thermal error, the same anchor
//! as a calibration point). Optionally the modelled reference-to-working difference
//! (`e_model(working) - interpolated e_model(references)`) is added as well.
//! References are the bars mounted with purpose `reference` during the working mount; on each
//! needed length the one nearest the fleet mean (`matching`) is used.
//!
//! Pure computation: no IO.

use std::collections::BTreeMap;

use crate::calibrate::BarCalibration;
use crate::campaign::{Campaign, Purpose};
use crate::identify::{BarModel, BarOutcome};
use crate::matching::ReferenceChoice;
use crate::model::{ModelError, ThermalProblem};
use crate::series::BarSeries;
use crate::signal::interpolate;
use crate::stage::StageOutcome;

/// What compensation needs of one bar.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CompBar<'a> {
    /// The bar's series.
    pub(crate) series: &'a BarSeries,
    /// Its identified thermal model.
    pub(crate) model: &'a BarModel,
    /// Its centre-distance function, if it was calibrated.
    pub(crate) calibration: Option<&'a BarCalibration>,
}

#[derive(Debug, Clone)]
/// How working bars are compensated.
pub struct CompensateOptions {
    /// Also compensate the modelled reference-to-working difference.
    pub model_difference: bool,
    /// A reference reading farther than this from a working sample is not used, s.
    pub max_gap_s: f64,
}

impl Default for CompensateOptions {
    fn default() -> Self {
        Self {
            model_difference: false,
            max_gap_s: 300.0,
        }
    }
}

/// Where a working bar's thermal error came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(crate) enum Mode {
    /// Interpolated between the two reference bars nearest in length (patent).
    TwoReferences,
    /// One reference bar's measured error.
    OneReference,
    /// The working bar's own thermal model (no reference mounted at the time).
    Model,
}

impl Mode {
    /// The mode of a working bar with `n` usable references.
    fn for_references(n: usize) -> Mode {
        match n {
            2 => Mode::TwoReferences,
            1 => Mode::OneReference,
            _ => Mode::Model,
        }
    }
}

/// How one working mount was compensated: its `Mode`, and whether the models' difference
/// between the working and the reference bars was added (never with `Mode::Model`). Written
/// as its name: `two_references`, `one_reference`, `model`, with `+model_difference`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct CompensationMode {
    pub(crate) source: Mode,
    pub(crate) model_difference: bool,
}

impl CompensationMode {
    pub(crate) fn new(source: Mode, model_difference: bool) -> CompensationMode {
        CompensationMode {
            source,
            model_difference: model_difference && source != Mode::Model,
        }
    }

    /// `two_references`, `one_reference` or `model`, with `+model_difference`.
    pub fn name(self) -> String {
        let base = match self.source {
            Mode::TwoReferences => "two_references",
            Mode::OneReference => "one_reference",
            Mode::Model => "model",
        };
        if self.model_difference {
            format!("{base}+model_difference")
        } else {
            base.to_string()
        }
    }
}

impl std::fmt::Display for CompensationMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(&self.name())
    }
}

/// A reference used for one working mount.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceUse {
    /// The reference bar's id.
    pub bar: String,
    /// The plate length it sat on.
    pub length_id: String,
    /// That length's calibrated centre distance, mm.
    pub length_mm: f64,
    /// Interpolation weight at the working bar's distance.
    pub weight: f64,
}

/// One working mount, compensated.
#[derive(Debug, Clone)]
pub struct WorkingSeries {
    /// Working bar id.
    pub bar: String,
    /// Index into the bar's `BarSeries::mounts`.
    pub mount: usize,
    /// The plate length it sat on (a check length), if on the plate.
    pub length_id: Option<String>,
    /// Known true distance (plate length), mm.
    pub length_mm: Option<f64>,
    /// Standard uncertainty of the known distance, µm (0 without one).
    pub u_length_um: f64,
    /// The device it sat in, if any.
    pub device: Option<String>,
    /// How it was compensated.
    pub mode: CompensationMode,
    /// The references used, with their weights.
    pub references: Vec<ReferenceUse>,
    /// Distance used for the interpolation between references, mm.
    pub distance_for_weights_mm: f64,
    /// Tilt of the bar from horizontal, degrees.
    pub tilt_deg: f64,
    /// Sample times, s since the campaign's time origin.
    pub t_s: Vec<f64>,
    /// Compensated centre distance, mm.
    pub distance_mm: Vec<f64>,
    /// `D(n, A)` without thermal compensation, mm.
    pub uncompensated_mm: Vec<f64>,
    /// Thermal error removed, µm.
    pub thermal_um: Vec<f64>,
    /// The reading with the thermal error removed, `k n − e`, mm: what `D(·, A)` takes, so that a
    /// device can evaluate it at a leg's own tilt.
    pub compensated_reading_mm: Vec<f64>,
    /// Samples without a reference reading near them (compensated by the model instead).
    pub n_model_fallback: usize,
    /// Samples of another counter epoch than the calibration's (not converted).
    pub n_other_epoch: usize,
    /// Thermal model residual term of the uncertainty budget (k = 1), µm.
    pub u_thermal_residual_um: f64,
    /// Thermal model parameters' term of the uncertainty budget (k = 1), µm.
    pub u_thermal_params_um: f64,
    /// Sensitivity of the compensated distance to the temperature, µm/K.
    pub temperature_sensitivity_um_per_k: f64,
}

impl WorkingSeries {
    /// Compensated and uncompensated errors against the known length, µm.
    pub(crate) fn errors_um(&self) -> Option<(Vec<f64>, Vec<f64>)> {
        let l = self.length_mm?;
        Some((
            self.distance_mm.iter().map(|d| (d - l) * 1e3).collect(),
            self.uncompensated_mm
                .iter()
                .map(|d| (d - l) * 1e3)
                .collect(),
        ))
    }
}

#[derive(Debug, Clone, thiserror::Error, PartialEq)]
/// Why a working mount could not be compensated.
pub(crate) enum CompensateError {
    #[error("bar {bar}: no calibration, so no centre-distance function")]
    /// The bar has no centre-distance function.
    NotCalibrated {
        /// Bar id.
        bar: String,
    },
    #[error("bar {bar}, mount {mount}: no sample in the calibration's counter epoch (the counter was re-zeroed; calibrate again after the re-zero)")]
    /// The mount lies in another counter epoch than the calibration.
    OtherEpoch {
        /// Bar id.
        bar: String,
        /// Index of the mount in the bar's series.
        mount: usize,
    },
    #[error("bar {bar}, mount {mount}: no readings")]
    /// The mount has no readings.
    NoReadings {
        /// Bar id.
        bar: String,
        /// Index of the mount in the bar's series.
        mount: usize,
    },
    #[error("bar {bar}: {source}")]
    /// The thermal model cannot be evaluated on the mount.
    Model {
        /// Bar id.
        bar: String,
        /// What is wrong.
        source: ModelError,
    },
}

impl CompensateError {
    /// The bar that could not be compensated.
    pub(crate) fn bar(&self) -> &str {
        match self {
            CompensateError::NotCalibrated { bar }
            | CompensateError::OtherEpoch { bar, .. }
            | CompensateError::NoReadings { bar, .. }
            | CompensateError::Model { bar, .. } => bar,
        }
    }
}

/// A reference bar's measured thermal error over one reference mount.
struct RefTrack<'a> {
    bar: &'a CompBar<'a>,
    length_id: String,
    length_mm: f64,
    t_s: Vec<f64>,
    measured_um: Vec<f64>,
    modelled_um: Vec<f64>,
    /// Mean air temperature minus T0 over the mount, K (anchor term of the budget).
    mean_dt_k: f64,
}

/// Whether a mount is a working mount: a check length or a device.
pub(crate) fn is_working(series: &BarSeries, mount: usize) -> bool {
    let m = &series.mounts[mount];
    m.device.is_some() || (m.length_mm.is_some() && m.purpose == Purpose::Check)
}

/// The compensate stage: compensate every working mount (check lengths and devices) of the
/// identified bars, each bar with its calibration among `calibrations` (if any), the references
/// nearest the fleet mean (`reference`, the match stage's choice) preferred. A mount that cannot
/// be compensated is listed, and warned of, under its bar; the others go on.
pub fn compensate_fleet(
    bars: &[BarOutcome],
    campaign: &Campaign,
    calibrations: &[BarCalibration],
    reference: Option<&ReferenceChoice>,
    options: &CompensateOptions,
) -> StageOutcome<WorkingSeries> {
    let comp_bars: Vec<CompBar> = bars
        .iter()
        .map(|o| CompBar {
            series: &o.series,
            model: &o.model,
            calibration: calibrations.iter().find(|c| c.bar == o.model.bar),
        })
        .collect();
    let fleet_distance: BTreeMap<String, f64> = reference
        .map(|r| r.distance.iter().cloned().collect())
        .unwrap_or_default();
    let outcomes = compensate(&comp_bars, campaign, &fleet_distance, options)
        .into_iter()
        .map(|w| match w {
            Ok(w) => (w.bar.clone(), Ok(w)),
            Err(e) => (e.bar().to_string(), Err(e.to_string())),
        });
    StageOutcome::from_results(outcomes).with_failures_warned()
}

/// Compensate every working mount of every bar. `fleet_distance`: each bar's scaled distance to
/// the fleet mean (`matching::choose_reference`); the nearest is preferred as reference.
pub(crate) fn compensate(
    bars: &[CompBar],
    campaign: &Campaign,
    fleet_distance: &BTreeMap<String, f64>,
    options: &CompensateOptions,
) -> Vec<Result<WorkingSeries, CompensateError>> {
    let tracks: Vec<RefTrack> = bars
        .iter()
        .flat_map(|b| reference_tracks(b, campaign))
        .collect();
    let mut out = Vec::new();
    for b in bars {
        for m in 0..b.series.mounts.len() {
            if is_working(b.series, m) {
                out.push(compensate_mount(
                    b,
                    m,
                    campaign,
                    &tracks,
                    fleet_distance,
                    options,
                ));
            }
        }
    }
    out
}

fn reference_tracks<'a>(b: &'a CompBar<'a>, campaign: &Campaign) -> Vec<RefTrack<'a>> {
    let s = b.series;
    let mut out = Vec::new();
    for (m, span) in s.mounts.iter().enumerate() {
        let (Some(length_id), Some(length_mm)) = (span.length_id.clone(), span.length_mm) else {
            continue;
        };
        if span.purpose != Purpose::Reference {
            continue;
        }
        let idx: Vec<usize> = (0..s.t_s.len())
            .filter(|&i| {
                s.mount_of[i] == Some(m as u32)
                    && s.weight[i] > 0.0
                    && b.model.thermal_um[i].is_finite()
            })
            .collect();
        if idx.is_empty() {
            continue;
        }
        let anchors = anchors_um(s, b.model, campaign, &idx);
        let measured_um = idx
            .iter()
            .zip(&anchors)
            .map(|(&i, a)| s.reading_um(i) - a)
            .collect();
        let mean_dt_k = idx
            .iter()
            .map(|&i| s.air_c[i] - s.reference_temperature_c)
            .sum::<f64>()
            / idx.len() as f64;
        out.push(RefTrack {
            bar: b,
            length_id,
            length_mm,
            t_s: idx.iter().map(|&i| s.t_s[i]).collect(),
            measured_um,
            modelled_um: idx.iter().map(|&i| b.model.thermal_um[i]).collect(),
            mean_dt_k,
        });
    }
    out
}

/// The reading at the reference temperature for each sample of `idx`: the mean of reading
/// minus modelled thermal error over the sample's (zero segment, tilt) group.
fn anchors_um(s: &BarSeries, model: &BarModel, campaign: &Campaign, idx: &[usize]) -> Vec<f64> {
    let key = |i: usize| {
        (
            s.zero_segment[i],
            (s.tilt_at_deg(campaign, i) * 1000.0).round() as i64,
        )
    };
    let mut sums: BTreeMap<(Option<u32>, i64), (f64, usize)> = BTreeMap::new();
    for &i in idx {
        let e = sums.entry(key(i)).or_default();
        e.0 += s.reading_um(i) - model.thermal_um[i];
        e.1 += 1;
    }
    idx.iter()
        .map(|&i| {
            sums.get(&key(i))
                .map_or(f64::NAN, |(sum, n)| sum / *n as f64)
        })
        .collect()
}

/// Linear interpolation of a track at `t`, `None` when no sample lies within `max_gap_s`.
fn at_time(t_s: &[f64], v: &[f64], t: f64, max_gap_s: f64) -> Option<f64> {
    interpolate::within(t_s, v, t, max_gap_s)
}

/// References for a working mount: overlapping reference mounts of other bars, grouped by
/// length; the shortest and longest lengths (or the only one), nearest the fleet mean on each.
fn choose_references<'t>(
    tracks: &'t [RefTrack<'t>],
    bar: &str,
    from_s: f64,
    to_s: f64,
    fleet_distance: &BTreeMap<String, f64>,
) -> Vec<&'t RefTrack<'t>> {
    let overlapping: Vec<&RefTrack> = tracks
        .iter()
        .filter(|r| r.bar.series.bar.id != bar)
        .filter(|r| {
            r.t_s.first().is_some_and(|&a| a < to_s) && r.t_s.last().is_some_and(|&b| b > from_s)
        })
        .collect();
    let best_on = |mm: f64| {
        overlapping
            .iter()
            .filter(|r| (r.length_mm - mm).abs() < 1e-6)
            .min_by(|a, b| {
                let d = |r: &RefTrack| {
                    fleet_distance
                        .get(&r.bar.series.bar.id)
                        .copied()
                        .unwrap_or(f64::INFINITY)
                };
                d(a).total_cmp(&d(b))
                    .then_with(|| a.bar.series.bar.id.cmp(&b.bar.series.bar.id))
            })
            .copied()
    };
    let lo = overlapping
        .iter()
        .map(|r| r.length_mm)
        .fold(f64::INFINITY, f64::min);
    let hi = overlapping
        .iter()
        .map(|r| r.length_mm)
        .fold(f64::NEG_INFINITY, f64::max);
    match (best_on(lo), best_on(hi)) {
        (Some(a), Some(b)) if hi > lo => vec![a, b],
        (Some(a), _) => vec![a],
        _ => Vec::new(),
    }
}

/// Interpolation weights of the references at distance `d_mm` (patent formula).
fn weights(refs: &[&RefTrack], d_mm: f64) -> Vec<f64> {
    match refs {
        [_] => vec![1.0],
        [a, b] => {
            let w = (d_mm - a.length_mm) / (b.length_mm - a.length_mm);
            vec![1.0 - w, w]
        }
        _ => Vec::new(),
    }
}

/// The working bar's modelled thermal error with its travel set for `mount` (needed on a
/// device, where the series has no known `I_p`).
fn model_thermal_at(b: &CompBar, mount: usize, i_p_mm: f64) -> Result<Vec<f64>, ModelError> {
    if (b.series.mounts[mount].i_p_mm - i_p_mm).abs() < 1e-9 {
        return Ok(b.model.thermal_um.clone());
    }
    let mut s = b.series.clone();
    s.mounts[mount].i_p_mm = i_p_mm;
    let problem = ThermalProblem::new(&s, &b.model.effects)?;
    let columns = problem.full_columns(&b.model.theta);
    let mut out = vec![0.0; s.t_s.len()];
    for (col, g) in columns.iter().zip(&b.model.gains) {
        out.iter_mut().zip(col).for_each(|(o, c)| *o += g * c);
    }
    Ok(out)
}

fn compensate_mount(
    b: &CompBar,
    m: usize,
    campaign: &Campaign,
    tracks: &[RefTrack],
    fleet_distance: &BTreeMap<String, f64>,
    options: &CompensateOptions,
) -> Result<WorkingSeries, CompensateError> {
    let s = b.series;
    let bar = s.bar.id.clone();
    let cal = b
        .calibration
        .ok_or_else(|| CompensateError::NotCalibrated { bar: bar.clone() })?;
    let span = &s.mounts[m];
    let epochs = s.counter_epochs();
    // Readings only: weight-0 samples are a compressed series' lag grid.
    let all: Vec<usize> = (0..s.t_s.len())
        .filter(|&i| s.mount_of[i] == Some(m as u32) && s.weight[i] > 0.0)
        .collect();
    if all.is_empty() {
        return Err(CompensateError::NoReadings { bar, mount: m });
    }
    let idx: Vec<usize> = all
        .iter()
        .copied()
        .filter(|&i| epochs[i] == cal.epoch)
        .collect();
    if idx.is_empty() {
        return Err(CompensateError::OtherEpoch { bar, mount: m });
    }
    let tilts: Vec<f64> = idx.iter().map(|&i| s.tilt_at_deg(campaign, i)).collect();
    let uncompensated_mm: Vec<f64> = idx
        .iter()
        .zip(&tilts)
        .map(|(&i, a)| cal.chosen.distance_mm(s.reading_um(i) * 1e-3, *a))
        .collect();
    let d_p = span.length_mm.unwrap_or_else(|| median(&uncompensated_mm));
    let own = model_thermal_at(b, m, d_p - s.bar.fixed_length_mm).map_err(|source| {
        CompensateError::Model {
            bar: bar.clone(),
            source,
        }
    })?;
    let refs = choose_references(tracks, &bar, span.from_s, span.to_s, fleet_distance);
    let w = weights(&refs, d_p);
    let mut thermal_um = Vec::with_capacity(idx.len());
    let mut n_model_fallback = 0;
    let mut delta_sq = 0.0;
    for &i in &idx {
        let t = s.t_s[i];
        let measured: Option<Vec<f64>> = refs
            .iter()
            .map(|r| at_time(&r.t_s, &r.measured_um, t, options.max_gap_s))
            .collect();
        let modelled: Option<Vec<f64>> = refs
            .iter()
            .map(|r| at_time(&r.t_s, &r.modelled_um, t, options.max_gap_s))
            .collect();
        let e = match (measured.filter(|v| !v.is_empty()), modelled) {
            (Some(meas), Some(model)) => {
                let e_ref: f64 = meas.iter().zip(&w).map(|(v, w)| v * w).sum();
                let delta = own[i] - model.iter().zip(&w).map(|(v, w)| v * w).sum::<f64>();
                delta_sq += delta * delta;
                e_ref + if options.model_difference { delta } else { 0.0 }
            }
            _ => {
                n_model_fallback += 1;
                own[i]
            }
        };
        thermal_um.push(e);
    }
    let compensated_reading_mm: Vec<f64> = idx
        .iter()
        .zip(&thermal_um)
        .map(|(&i, e)| (s.reading_um(i) - e) * 1e-3)
        .collect();
    let distance_mm = compensated_reading_mm
        .iter()
        .zip(&tilts)
        .map(|(x, a)| cal.chosen.distance_mm(*x, *a))
        .collect();
    let mode = Mode::for_references(refs.len());
    let n_ref = idx.len() - n_model_fallback;
    let rms_delta = if n_ref > 0 {
        (delta_sq / n_ref as f64).sqrt()
    } else {
        0.0
    };
    let budget = thermal_budget(b, &refs, &w, d_p, &idx, rms_delta, options.model_difference);
    Ok(WorkingSeries {
        bar,
        mount: m,
        length_id: span.length_id.clone(),
        length_mm: span.length_mm,
        u_length_um: span
            .length_id
            .as_ref()
            .and_then(|id| campaign.plate.lengths.iter().find(|l| &l.id == id))
            .map_or(0.0, |l| l.u_um),
        device: span.device.clone(),
        mode: CompensationMode::new(mode, options.model_difference),
        references: refs
            .iter()
            .zip(&w)
            .map(|(r, w)| ReferenceUse {
                bar: r.bar.series.bar.id.clone(),
                length_id: r.length_id.clone(),
                length_mm: r.length_mm,
                weight: *w,
            })
            .collect(),
        distance_for_weights_mm: d_p,
        tilt_deg: median(&tilts),
        t_s: idx.iter().map(|&i| s.t_s[i]).collect(),
        distance_mm,
        uncompensated_mm,
        thermal_um,
        compensated_reading_mm,
        n_model_fallback,
        n_other_epoch: all.len() - idx.len(),
        u_thermal_residual_um: budget.0,
        u_thermal_params_um: budget.1,
        temperature_sensitivity_um_per_k: budget.2,
    })
}

/// (alpha I_min + beta I_p) in µm/K, and its standard uncertainty from the parameters'.
fn sensitivity_um_per_k(model: &BarModel, i_min_mm: f64, i_p_mm: f64) -> (f64, f64) {
    let p = |n: &str| model.param(n).map_or((0.0, 0.0), |e| (e.value, e.u));
    let (a, ua) = p("alpha_ppm_per_k");
    let (b, ub) = p("beta_ppm_per_k");
    (
        (a * i_min_mm + b * i_p_mm) * 1e-3,
        ((ua * i_min_mm).powi(2) + (ub * i_p_mm).powi(2)).sqrt() * 1e-3,
    )
}

/// Thermal terms of the budget (k = 1): (residual µm, parameters µm, temperature sensitivity µm/K).
///
/// - residual: model mode, the working model's RMS residual; reference modes, the RMS of the
///   modelled reference-to-working difference left uncompensated, or (when it is compensated)
///   the models' residuals combined;
/// - parameters: `u(alpha) I_min, u(beta) I_p` times the RMS temperature excursion (model mode),
///   plus each reference's anchor (its mean excursion), weighted;
/// - temperature: sensitivities combined without correlation credit (conservative).
fn thermal_budget(
    b: &CompBar,
    refs: &[&RefTrack],
    w: &[f64],
    d_p: f64,
    idx: &[usize],
    rms_delta: f64,
    model_difference: bool,
) -> (f64, f64, f64) {
    let mode = Mode::for_references(refs.len());
    let s = b.series;
    let dt_rms = (idx
        .iter()
        .map(|&i| (s.air_c[i] - s.reference_temperature_c).powi(2))
        .sum::<f64>()
        / idx.len().max(1) as f64)
        .sqrt();
    let (sens_w, u_sens_w) =
        sensitivity_um_per_k(b.model, s.bar.fixed_length_mm, d_p - s.bar.fixed_length_mm);
    if mode == Mode::Model {
        return (b.model.rms_um, u_sens_w * dt_rms, sens_w.abs());
    }
    let mut params_sq = 0.0;
    let mut sens_sq = sens_w * sens_w;
    let mut ref_rms_sq = 0.0;
    for (r, w) in refs.iter().zip(w) {
        let rs = r.bar.series;
        let (sens_r, u_sens_r) = sensitivity_um_per_k(
            r.bar.model,
            rs.bar.fixed_length_mm,
            r.length_mm - rs.bar.fixed_length_mm,
        );
        params_sq += (w * u_sens_r * r.mean_dt_k).powi(2);
        sens_sq += (w * sens_r).powi(2);
        ref_rms_sq += (w * r.bar.model.rms_um).powi(2);
    }
    let residual = if model_difference {
        params_sq += (u_sens_w * dt_rms).powi(2);
        (b.model.rms_um.powi(2) + ref_rms_sq).sqrt()
    } else {
        rms_delta
    };
    (residual, params_sq.sqrt(), sens_sq.sqrt())
}

fn median(v: &[f64]) -> f64 {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if s.is_empty() {
        return f64::NAN;
    }
    s.sort_by(f64::total_cmp);
    s[s.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patent_interpolation_weights() {
        // Weights are linear in distance and reproduce the references at their own lengths.
        let w_mid: f64 = (325.0 - 250.0) / (400.0 - 250.0);
        assert!((w_mid - 0.5).abs() < 1e-12);
        assert_eq!(
            CompensationMode::new(Mode::TwoReferences, true).name(),
            "two_references+model_difference"
        );
        assert_eq!(CompensationMode::new(Mode::Model, true).name(), "model");
        assert_eq!(
            CompensationMode::new(Mode::OneReference, false).to_string(),
            "one_reference"
        );
    }

    #[test]
    fn interpolation_in_time_respects_the_gap() {
        let t = [0.0, 10.0, 20.0];
        let v = [0.0, 1.0, 3.0];
        assert_eq!(at_time(&t, &v, 15.0, 60.0), Some(2.0));
        assert_eq!(at_time(&t, &v, 25.0, 60.0), Some(3.0));
        assert_eq!(at_time(&t, &v, 200.0, 60.0), None);
        assert_eq!(at_time(&t, &v, -5.0, 60.0), Some(0.0));
    }
}
