//! Calibration: from plate mounts to a per-bar centre-distance function `D(n, A)`.
//!
//! `docs/spec/physics.md`, "The calibration unit": every mount of a bar on a plate length of known centre
//! distance `D_i`, at a tilt `A`, gives a calibration point `P_i = (D_i, k n_i, A)`. The counts are
//! first brought to the reference temperature with the bar's identified thermal model (the reading
//! minus the modelled thermal error, averaged over the mount). The patent fits
//! `D(n) = a (k n)^2 + b (k n) + c`; the tilt may be a second input (gravity sag, largest when
//! horizontal), and a table with interpolation is equally allowed. Here every form is tried and
//! the one with the smallest leave-one-point-out cross-validated error is kept; every form's
//! error is reported so the user sees why. The forms ([`Form`], simplest first, a tie to the
//! simpler): linear, the patent's quadratic, quadratic plus gravity sag (`cos A` or `cos² A`
//! times a polynomial in the reading, the sag growing with the bar's length), and a table. A
//! point's tilt is its mount's `tilt_deg`, else the latest `tilt` event, else the plate's
//! (`BarSeries::tilt_at_deg`).
//!
//! Counts are comparable only within one counter epoch (between `rezero` events,
//! `docs/spec/campaign-format.md`): the calibration uses the epoch holding the most points and names the
//! points of other epochs as excluded; readings of other epochs cannot be converted.
//!
//! Pure computation: no IO. Fits go through the one engine, [`crate::fit::fit`].

use nalgebra::DMatrix;
use rayon::prelude::*;

use crate::campaign::{Campaign, Purpose};
use crate::fit::{self, FitOptions, Start};
use crate::identify::{BarModel, BarOutcome};
use crate::series::BarSeries;
use crate::signal::interpolate::{self, Beyond};
use crate::stage::StageOutcome;

/// One calibration point: a bar on a plate length at one tilt, within one counter epoch.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationPoint {
    /// Index into the bar's `BarSeries::mounts`.
    pub mount: usize,
    /// The plate length's id (`plate.length[].id`).
    pub length_id: String,
    /// True centre distance `D_i` (calibrated plate length), mm.
    pub length_mm: f64,
    /// Standard uncertainty of `D_i`, µm.
    pub u_length_um: f64,
    /// Tilt of the bar from horizontal at this point, degrees.
    pub tilt_deg: f64,
    /// Indicated reading `k n` brought to the reference temperature, mm.
    pub reading_mm: f64,
    /// Standard uncertainty of the mean reading (scatter over the mount, autocorrelation
    /// accounted for), µm.
    pub u_reading_um: f64,
    /// Counter epoch: number of `rezero` events before the point.
    pub epoch: usize,
    /// What the mount was for.
    pub purpose: Purpose,
    /// Readings averaged into the point.
    pub n_samples: usize,
}

/// The tilt function of a gravity-sag term (`docs/spec/physics.md`: largest horizontal, zero vertical).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SagTilt {
    /// `f(A) = cos A`.
    Cos,
    /// `f(A) = cos² A`.
    Cos2,
}

impl SagTilt {
    fn factor(self, tilt_deg: f64) -> f64 {
        let c = tilt_deg.to_radians().cos();
        match self {
            SagTilt::Cos => c,
            SagTilt::Cos2 => c * c,
        }
    }
}

/// The forms of the centre-distance function that are tried.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Form {
    /// `D = b (k n) + c`.
    Linear,
    /// The patent's `D = a (k n)^2 + b (k n) + c`.
    Quadratic,
    /// Quadratic plus gravity sag `f(A) (s0 + s1 u + ...)`, a polynomial of degree
    /// `length_degree` in the normalised reading `u` (the sag grows with the bar's length).
    Sag {
        /// The tilt function `f(A)`.
        tilt: SagTilt,
        /// Degree of the polynomial in `u`.
        length_degree: u8,
    },
    /// A table of the points, interpolated linearly in `k n` within a tilt and linearly in tilt
    /// between tilts (extrapolated from the end segments).
    Table,
}

/// Every form, simplest first (ties in cross-validated error go to the simpler form).
pub(crate) const FORMS: [Form; 9] = [
    Form::Linear,
    Form::Quadratic,
    Form::Sag {
        tilt: SagTilt::Cos,
        length_degree: 0,
    },
    Form::Sag {
        tilt: SagTilt::Cos2,
        length_degree: 0,
    },
    Form::Sag {
        tilt: SagTilt::Cos,
        length_degree: 1,
    },
    Form::Sag {
        tilt: SagTilt::Cos2,
        length_degree: 1,
    },
    Form::Sag {
        tilt: SagTilt::Cos,
        length_degree: 2,
    },
    Form::Sag {
        tilt: SagTilt::Cos2,
        length_degree: 2,
    },
    Form::Table,
];

impl Form {
    /// The name printed in every output, e.g. `quadratic+sag_cos2*length`.
    pub fn name(self) -> String {
        match self {
            Form::Linear => "linear".into(),
            Form::Quadratic => "quadratic".into(),
            Form::Sag {
                tilt,
                length_degree,
            } => {
                let t = if tilt == SagTilt::Cos { "cos" } else { "cos2" };
                let l = ["", "*length", "*length^2"]
                    .get(length_degree as usize)
                    .copied()
                    .unwrap_or("*length^n");
                format!("quadratic+sag_{t}{l}")
            }
            Form::Table => "table".into(),
        }
    }

    /// Names of the linear coefficients (empty for the table).
    fn columns(self) -> Vec<String> {
        let mut c: Vec<String> = vec!["c_um".into(), "b_um".into()];
        match self {
            Form::Linear => c,
            Form::Quadratic => {
                c.push("a_um".into());
                c
            }
            Form::Sag { length_degree, .. } => {
                c.push("a_um".into());
                c.extend((0..=length_degree).map(|k| format!("sag{k}_um")));
                c
            }
            Form::Table => Vec::new(),
        }
    }

    /// Whether the form has a gravity-sag term.
    pub fn has_sag(self) -> bool {
        matches!(self, Form::Sag { .. })
    }
}

/// A fitted centre-distance function `D(k n, A)`.
///
/// Parametric forms model the correction `D − k n` (µm) in the normalised reading
/// `u = (k n − centre) / half_range`, which keeps the columns well conditioned.
#[derive(Debug, Clone, PartialEq)]
pub struct DistanceFunction {
    /// The form fitted.
    pub form: Form,
    /// Centre of the normalised reading `u`, mm.
    pub reading_centre_mm: f64,
    /// Half range of the normalised reading `u`, mm.
    pub reading_half_range_mm: f64,
    /// Coefficient names and values (µm), parametric forms only.
    pub coefficients: Vec<(String, f64)>,
    /// The patent's `a` (1/mm), `b` (1) and `c` (mm) of the tilt-free part, quadratic forms only.
    pub patent_abc: Option<[f64; 3]>,
    /// Table form: (tilt, [(reading mm, correction µm)] sorted by reading), sorted by tilt.
    pub table: Vec<(f64, Vec<(f64, f64)>)>,
    /// RMS of the fit residuals at the points, µm.
    pub fit_rms_um: f64,
}

impl DistanceFunction {
    /// Centre distance, mm, for a reading `k n` (mm, at the reference temperature) at `tilt_deg`.
    pub fn distance_mm(&self, reading_mm: f64, tilt_deg: f64) -> f64 {
        reading_mm + self.correction_um(reading_mm, tilt_deg) * 1e-3
    }

    fn correction_um(&self, reading_mm: f64, tilt_deg: f64) -> f64 {
        if self.form == Form::Table {
            return table_correction_um(&self.table, reading_mm, tilt_deg);
        }
        let u = (reading_mm - self.reading_centre_mm) / self.reading_half_range_mm;
        let row = basis_row(self.form, u, tilt_deg);
        row.iter()
            .zip(&self.coefficients)
            .map(|(x, (_, c))| x * c)
            .sum()
    }
}

/// One form's cross-validation result.
#[derive(Debug, Clone, PartialEq)]
pub struct FormScore {
    /// The form scored.
    pub form: Form,
    /// Its number of linear coefficients (0 for the table).
    pub n_params: usize,
    /// RMS of the leave-one-point-out prediction errors, µm (`None`: the form cannot be fitted).
    pub cv_rms_um: Option<f64>,
    /// Largest absolute leave-one-point-out prediction error, µm.
    pub cv_max_abs_um: Option<f64>,
    /// RMS of the residuals of the fit on all points, µm.
    pub fit_rms_um: Option<f64>,
    /// Why the form could not be fitted or cross-validated.
    pub note: Option<FormError>,
}

/// A bar's calibration.
#[derive(Debug, Clone)]
pub struct BarCalibration {
    /// Bar id.
    pub bar: String,
    /// The counter epoch the function is valid in.
    pub epoch: usize,
    /// The calibration points fitted (those of `epoch`).
    pub points: Vec<CalibrationPoint>,
    /// The points of other counter epochs (re-zeroed: counts not comparable with `epoch`'s),
    /// left out.
    pub excluded: Vec<CalibrationPoint>,
    /// Every form tried, with its cross-validation score.
    pub forms: Vec<FormScore>,
    /// The function chosen by leave-one-point-out cross-validation.
    pub chosen: DistanceFunction,
    /// Cross-validated RMS error of the chosen form, µm: the calibration-function term of the
    /// uncertainty budget.
    pub cv_rms_um: f64,
}

impl BarCalibration {
    /// Centre distance (mm) for a reading at the reference temperature, or `None` when the
    /// reading is from another counter epoch.
    pub fn distance_mm(&self, reading_mm: f64, tilt_deg: f64, epoch: usize) -> Option<f64> {
        (epoch == self.epoch).then(|| self.chosen.distance_mm(reading_mm, tilt_deg))
    }
}

/// Why a bar has no centre-distance function.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum CalibrateError {
    /// Fewer than 3 calibration points in the counter epoch.
    #[error("bar {bar}: {n} calibration point(s) in counter epoch {epoch}; at least 3 are needed")]
    TooFewPoints {
        /// Bar id.
        bar: String,
        /// Points found.
        n: usize,
        /// The counter epoch (`rezero` events before it).
        epoch: usize,
    },
    /// No form could be fitted.
    #[error("bar {bar}: no form of the centre-distance function could be fitted ({})", form_reasons(.forms))]
    NoForm {
        /// Bar id.
        bar: String,
        /// Every form tried, with why it failed.
        forms: Vec<(Form, Option<FormError>)>,
    },
    /// The form chosen by cross-validation could not be fitted to all the points.
    #[error("bar {bar}: no form of the centre-distance function could be fitted ({source})")]
    ChosenForm {
        /// Bar id.
        bar: String,
        /// Why.
        source: FormError,
    },
}

/// `FORM: why; FORM: why; …` (an empty why for a form that did not say).
fn form_reasons(forms: &[(Form, Option<FormError>)]) -> String {
    forms
        .iter()
        .map(|(form, why)| {
            let why = why.as_ref().map(ToString::to_string).unwrap_or_default();
            format!("{}: {why}", form.name())
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// Why a form of `D(n, A)` could not be fitted to a set of points or cross-validated.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum FormError {
    /// No point to fit.
    #[error("no points")]
    NoPoints,
    /// A table interpolates between points: one is not enough.
    #[error("a table needs at least 2 points")]
    TableNeedsTwoPoints,
    /// The least-squares fit failed.
    #[error(transparent)]
    Fit(#[from] fit::FitError),
    /// The fit without one point (leave-one-point-out) failed.
    #[error("without point {point}: {source}")]
    WithoutPoint {
        /// The point left out (index in the points).
        point: usize,
        /// Why the fit without it failed.
        source: Box<FormError>,
    },
}

// ------------------------------------------------------------------------------------ points

/// Calibration points of one bar: one per (plate mount, counter epoch, tilt), check mounts left
/// out (they verify, never fit). The reading at the reference temperature is the mean over the
/// mount of the reading minus the model's thermal error.
pub(crate) fn calibration_points(
    series: &BarSeries,
    model: &BarModel,
    campaign: &Campaign,
) -> Vec<CalibrationPoint> {
    let epochs = series.counter_epochs();
    let mut groups: std::collections::BTreeMap<(usize, usize, i64), Vec<(f64, f64)>> =
        Default::default();
    // One epoch per sample (`counter_epochs`).
    for (i, &epoch) in epochs.iter().enumerate() {
        // Weight-0 samples (the lag grid of a compressed series) are not readings.
        let Some(m) = series.mount_of[i].filter(|_| series.weight[i] > 0.0) else {
            continue;
        };
        let span = &series.mounts[m as usize];
        if span.length_mm.is_none() || span.purpose == Purpose::Check {
            continue;
        }
        let Some(thermal) = model.thermal_um.get(i).copied().filter(|v| v.is_finite()) else {
            continue;
        };
        let tilt_key = (series.tilt_at_deg(campaign, i) * 1000.0).round() as i64;
        let key = (m as usize, epoch, tilt_key);
        let value = series.reading_um(i) - thermal;
        groups
            .entry(key)
            .or_default()
            .push((value, series.weight[i]));
    }
    groups
        .into_iter()
        .filter_map(|((m, epoch, tilt), values)| {
            point(series, campaign, m, epoch, tilt as f64 / 1000.0, &values)
        })
        .collect()
}

fn point(
    series: &BarSeries,
    campaign: &Campaign,
    m: usize,
    epoch: usize,
    tilt_deg: f64,
    weighted: &[(f64, f64)],
) -> Option<CalibrationPoint> {
    let span = &series.mounts[m];
    let length_id = span.length_id.clone()?;
    let length_mm = span.length_mm?;
    // Samples are readings (weight 1) or compressed bins' nodes (weight: the readings they stand
    // for); the spread and its correlation time are taken over the samples as they are.
    let values: Vec<f64> = weighted.iter().map(|(v, _)| *v).collect();
    let values = values.as_slice();
    let n = values.len();
    let total_weight: f64 = weighted.iter().map(|(_, w)| w).sum();
    let mean = weighted.iter().map(|(v, w)| v * w).sum::<f64>() / total_weight;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>()
        / (n.saturating_sub(1).max(1)) as f64;
    let n_eff = n as f64 / fit::integrated_autocorrelation_time(values).max(1.0);
    let u_length_um = campaign
        .plate
        .lengths
        .iter()
        .find(|l| l.id == length_id)
        .map_or(0.0, |l| l.u_um);
    Some(CalibrationPoint {
        mount: m,
        length_id,
        length_mm,
        u_length_um,
        tilt_deg,
        reading_mm: mean * 1e-3,
        u_reading_um: (var / n_eff.max(1.0)).sqrt(),
        epoch,
        purpose: span.purpose,
        n_samples: total_weight.round() as usize,
    })
}

// ------------------------------------------------------------------------------------ fitting

/// The basis row of a parametric form at normalised reading `u` and tilt.
fn basis_row(form: Form, u: f64, tilt_deg: f64) -> Vec<f64> {
    let mut row = vec![1.0, u];
    if form == Form::Linear {
        return row;
    }
    row.push(u * u);
    if let Form::Sag {
        tilt,
        length_degree,
    } = form
    {
        let f = tilt.factor(tilt_deg);
        row.extend((0..=length_degree as i32).map(|k| f * u.powi(k)));
    }
    row
}

/// Fit one form to `points` (all assumed in one counter epoch).
pub(crate) fn fit_form(
    form: Form,
    points: &[CalibrationPoint],
) -> Result<DistanceFunction, FormError> {
    if points.is_empty() {
        return Err(FormError::NoPoints);
    }
    let (lo, hi) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.reading_mm), hi.max(p.reading_mm))
        });
    let centre = 0.5 * (lo + hi);
    let half = (0.5 * (hi - lo)).max(1.0);
    if form == Form::Table {
        return fit_table(points, centre, half);
    }
    let names: Vec<String> = form.columns();
    let y: Vec<f64> = points
        .iter()
        .map(|p| (p.length_mm - p.reading_mm) * 1e3)
        .collect();
    let rows: Vec<Vec<f64>> = points
        .iter()
        .map(|p| basis_row(form, (p.reading_mm - centre) / half, p.tilt_deg))
        .collect();
    let phi = DMatrix::from_fn(points.len(), names.len(), |i, j| rows[i][j]);
    let problem = fit::FixedColumns {
        y,
        phi,
        names: names.clone(),
    };
    let options = FitOptions {
        start: Start::Given,
        hac_batch_len: Some(1),
        absorbed_params: 0,
        stop: fit::Stop::Numerical,
    };
    let f = fit::fit(&problem, &[], &options)?;
    let coefficients: Vec<(String, f64)> =
        names.into_iter().zip(f.values.iter().copied()).collect();
    let patent_abc = (form != Form::Linear).then(|| patent_abc(&coefficients, centre, half));
    Ok(DistanceFunction {
        form,
        reading_centre_mm: centre,
        reading_half_range_mm: half,
        coefficients,
        patent_abc,
        table: Vec::new(),
        fit_rms_um: f.rms(),
    })
}

/// `D = a x^2 + b x + c` (x = k n in mm) from the normalised correction `c0 + c1 u + c2 u^2` µm.
fn patent_abc(coefficients: &[(String, f64)], centre: f64, half: f64) -> [f64; 3] {
    let (c0, c1, c2) = (
        coefficients[0].1 * 1e-3,
        coefficients[1].1 * 1e-3,
        coefficients[2].1 * 1e-3,
    );
    let a = c2 / (half * half);
    let b = 1.0 + c1 / half - 2.0 * c2 * centre / (half * half);
    let c = c0 - c1 * centre / half + c2 * centre * centre / (half * half);
    [a, b, c]
}

fn fit_table(
    points: &[CalibrationPoint],
    centre: f64,
    half: f64,
) -> Result<DistanceFunction, FormError> {
    if points.len() < 2 {
        return Err(FormError::TableNeedsTwoPoints);
    }
    let mut table: Vec<(f64, Vec<(f64, f64)>)> = Vec::new();
    for p in points {
        let row = (p.reading_mm, (p.length_mm - p.reading_mm) * 1e3);
        match table
            .iter_mut()
            .find(|(t, _)| (t - p.tilt_deg).abs() < 1e-3)
        {
            Some((_, rows)) => rows.push(row),
            None => table.push((p.tilt_deg, vec![row])),
        }
    }
    table.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (_, rows) in &mut table {
        *rows = merge_close(rows);
    }
    let mut f = DistanceFunction {
        form: Form::Table,
        reading_centre_mm: centre,
        reading_half_range_mm: half,
        coefficients: Vec::new(),
        patent_abc: None,
        table,
        fit_rms_um: 0.0,
    };
    let rss: f64 = points
        .iter()
        .map(|p| ((f.distance_mm(p.reading_mm, p.tilt_deg) - p.length_mm) * 1e3).powi(2))
        .sum();
    f.fit_rms_um = (rss / points.len() as f64).sqrt();
    Ok(f)
}

/// Sort rows by reading and average rows closer than 0.5 mm (repeated mounts of one length).
fn merge_close(rows: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut sorted = rows.to_vec();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out: Vec<(f64, f64, usize)> = Vec::new();
    for (x, y) in sorted {
        match out.last_mut() {
            Some((xs, ys, n)) if (x - *xs / *n as f64).abs() < 0.5 => {
                *xs += x;
                *ys += y;
                *n += 1;
            }
            _ => out.push((x, y, 1)),
        }
    }
    out.into_iter()
        .map(|(x, y, n)| (x / n as f64, y / n as f64))
        .collect()
}

/// Piecewise-linear interpolation in a table's rows, continued past its ends
/// ([`Beyond::Extend`]).
fn interpolate_rows(rows: &[(f64, f64)], x: f64) -> f64 {
    let (xs, ys): (Vec<f64>, Vec<f64>) = rows.iter().copied().unzip();
    interpolate::linear(&xs, &ys, x, Beyond::Extend)
}

fn table_correction_um(table: &[(f64, Vec<(f64, f64)>)], reading_mm: f64, tilt_deg: f64) -> f64 {
    let per_tilt: Vec<(f64, f64)> = table
        .iter()
        .map(|(t, rows)| (*t, interpolate_rows(rows, reading_mm)))
        .collect();
    interpolate_rows(&per_tilt, tilt_deg)
}

/// Leave-one-point-out prediction errors (µm) of `form`.
pub(crate) fn cross_validate(
    form: Form,
    points: &[CalibrationPoint],
) -> Result<Vec<f64>, FormError> {
    (0..points.len())
        .map(|k| {
            let rest: Vec<CalibrationPoint> = points
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != k)
                .map(|(_, p)| p.clone())
                .collect();
            let f = fit_form(form, &rest).map_err(|e| FormError::WithoutPoint {
                point: k,
                source: Box::new(e),
            })?;
            let p = &points[k];
            Ok((f.distance_mm(p.reading_mm, p.tilt_deg) - p.length_mm) * 1e3)
        })
        .collect()
}

fn score(form: Form, points: &[CalibrationPoint]) -> FormScore {
    let n_params = if form == Form::Table {
        0
    } else {
        form.columns().len()
    };
    let full = fit_form(form, points);
    let cv = full
        .as_ref()
        .map_err(|e| e.clone())
        .and_then(|_| cross_validate(form, points));
    let note = match (&full, &cv) {
        (Err(e), _) | (Ok(_), Err(e)) => Some(e.clone()),
        _ => None,
    };
    let cv = cv.ok().filter(|e| e.iter().all(|v| v.is_finite()));
    FormScore {
        form,
        n_params,
        cv_rms_um: cv
            .as_ref()
            .map(|e| (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt()),
        cv_max_abs_um: cv
            .as_ref()
            .map(|e| e.iter().fold(0.0, |m: f64, v| m.max(v.abs()))),
        fit_rms_um: full.ok().map(|f| f.fit_rms_um),
        note,
    }
}

/// The counter epoch holding the most points (ties: the latest).
fn main_epoch(points: &[CalibrationPoint]) -> usize {
    let mut counts: std::collections::BTreeMap<usize, usize> = Default::default();
    for p in points {
        *counts.entry(p.epoch).or_default() += 1;
    }
    counts
        .into_iter()
        .max_by_key(|(e, n)| (*n, *e))
        .map_or(0, |(e, _)| e)
}

/// Fit every form to `points`, cross-validate, keep the best.
pub fn calibrate_points(
    bar: &str,
    points: Vec<CalibrationPoint>,
) -> Result<BarCalibration, CalibrateError> {
    let epoch = main_epoch(&points);
    let (points, other): (Vec<_>, Vec<_>) = points.into_iter().partition(|p| p.epoch == epoch);
    let excluded = other;
    if points.len() < 3 {
        return Err(CalibrateError::TooFewPoints {
            bar: bar.to_string(),
            n: points.len(),
            epoch,
        });
    }
    let forms: Vec<FormScore> = FORMS.iter().map(|&f| score(f, &points)).collect();
    let best = forms
        .iter()
        .filter_map(|s| s.cv_rms_um.map(|cv| (s.form, cv)))
        .fold(None, |best: Option<(Form, f64)>, (f, cv)| match best {
            Some((_, b)) if b <= cv * (1.0 + 1e-9) => best,
            _ => Some((f, cv)),
        });
    let Some((form, cv_rms_um)) = best else {
        return Err(CalibrateError::NoForm {
            bar: bar.to_string(),
            forms: forms.into_iter().map(|s| (s.form, s.note)).collect(),
        });
    };
    let chosen = fit_form(form, &points).map_err(|source| CalibrateError::ChosenForm {
        bar: bar.to_string(),
        source,
    })?;
    Ok(BarCalibration {
        bar: bar.to_string(),
        epoch,
        points,
        excluded,
        forms,
        chosen,
        cv_rms_um,
    })
}

/// The calibrate stage: calibrate every identified bar, in parallel, in the fleet's order (a bar
/// that cannot be calibrated is listed, and warned of, the others go on).
pub fn calibrate_fleet(bars: &[BarOutcome], campaign: &Campaign) -> StageOutcome<BarCalibration> {
    let outcomes: Vec<(String, Result<BarCalibration, CalibrateError>)> = bars
        .par_iter()
        .map(|o| {
            let calibrated = calibrate_bar(&o.series, &o.model, campaign);
            (o.model.bar.clone(), calibrated)
        })
        .collect();
    StageOutcome::from_results(outcomes).with_failures_warned()
}

/// Calibrate one bar from its series and identified model.
pub(crate) fn calibrate_bar(
    series: &BarSeries,
    model: &BarModel,
    campaign: &Campaign,
) -> Result<BarCalibration, CalibrateError> {
    calibrate_points(&series.bar.id, calibration_points(series, model, campaign))
}

/// Sensitivity of the calibrated distance at (`reading_mm`, `tilt_deg`) to each point's true
/// length (dimensionless weights, by linearity of every form in the lengths): the plate-length
/// uncertainties propagate as `sqrt(sum w_i^2 u_i^2)`.
pub(crate) fn length_weights(cal: &BarCalibration, reading_mm: f64, tilt_deg: f64) -> Vec<f64> {
    let base = cal.chosen.distance_mm(reading_mm, tilt_deg);
    (0..cal.points.len())
        .map(|k| {
            let mut shifted = cal.points.clone();
            shifted[k].length_mm += 1e-3;
            fit_form(cal.chosen.form, &shifted)
                .map_or(0.0, |f| (f.distance_mm(reading_mm, tilt_deg) - base) / 1e-3)
        })
        .collect()
}

/// Standard uncertainty (µm) of the calibrated distance from the plate lengths used in the fit.
pub(crate) fn u_from_lengths_um(cal: &BarCalibration, reading_mm: f64, tilt_deg: f64) -> f64 {
    length_weights(cal, reading_mm, tilt_deg)
        .iter()
        .zip(&cal.points)
        .map(|(w, p)| (w * p.u_length_um).powi(2))
        .sum::<f64>()
        .sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bar whose true relation is `D = D_zero + x (1 + g) + q (x - 80)^2 - sag cos A (1 + x/400)`,
    /// at lengths (mm) × tilts (deg), with reading noise `noise_um` (deterministic pattern).
    fn synthetic_points(
        lengths: &[f64],
        tilts: &[f64],
        sag_um: f64,
        noise_um: f64,
    ) -> Vec<CalibrationPoint> {
        let d_zero = 230.0;
        let (g, q) = (-40e-6, 2e-8);
        let mut out = Vec::new();
        let mut k = 0;
        for &l in lengths {
            for &a in tilts {
                // Invert D(x) by fixed-point iteration.
                let mut x = l - d_zero;
                for _ in 0..50 {
                    let d = d_zero + x * (1.0 + g) + q * (x - 80.0).powi(2)
                        - sag_um * 1e-3 * a.to_radians().cos() * (1.0 + x / 400.0);
                    x += l - d;
                }
                let noise =
                    noise_um * 1e-3 * [0.3, -0.8, 0.5, 1.0, -0.2, -0.6, 0.9, -1.0, 0.1][k % 9];
                k += 1;
                out.push(CalibrationPoint {
                    mount: k,
                    length_id: format!("L{l}"),
                    length_mm: l,
                    u_length_um: 0.1,
                    tilt_deg: a,
                    reading_mm: x + noise,
                    u_reading_um: noise_um,
                    epoch: 0,
                    purpose: Purpose::Calibration,
                    n_samples: 100,
                });
            }
        }
        out
    }

    #[test]
    fn quadratic_recovers_the_patent_coefficients() {
        let pts = synthetic_points(&[250.0, 300.0, 325.0, 350.0, 400.0], &[60.0], 0.0, 0.0);
        let f = fit_form(Form::Quadratic, &pts).expect("fit");
        let [a, b, c] = f.patent_abc.expect("quadratic");
        // D = 230 + x (1 + g) + q (x - 80)^2  =>  a = q, b = 1 + g - 160 q, c = 230 + 6400 q.
        assert!((a - 2e-8).abs() < 1e-12, "a = {a}");
        assert!((b - (1.0 - 40e-6 - 160.0 * 2e-8)).abs() < 1e-9, "b = {b}");
        assert!((c - (230.0 + 6400.0 * 2e-8)).abs() < 1e-7, "c = {c}");
        assert!(f.fit_rms_um < 1e-6);
    }

    #[test]
    fn cross_validation_picks_a_sag_form_when_tilt_matters() {
        let pts = synthetic_points(&[250.0, 325.0, 400.0], &[0.0, 30.0, 60.0, 90.0], 1.5, 0.01);
        let cal = calibrate_points("S", pts.clone()).expect("calibrate");
        assert!(
            cal.chosen.form.has_sag(),
            "chose {:?}: {:#?}",
            cal.chosen.form,
            cal.forms
        );
        let quad = cal
            .forms
            .iter()
            .find(|s| s.form == Form::Quadratic)
            .and_then(|s| s.cv_rms_um)
            .expect("quadratic scored");
        assert!(
            cal.cv_rms_um < quad / 5.0,
            "cv {} vs quadratic {}",
            cal.cv_rms_um,
            quad
        );
        // Held-out tilt: fit without 30°, predict it.
        let (held, train): (Vec<_>, Vec<_>) = pts.into_iter().partition(|p| p.tilt_deg == 30.0);
        let f = fit_form(cal.chosen.form, &train).expect("fit");
        for p in &held {
            let err = (f.distance_mm(p.reading_mm, p.tilt_deg) - p.length_mm) * 1e3;
            assert!(err.abs() < 0.05, "held-out error {err} µm");
        }
    }

    #[test]
    fn without_tilt_variation_sag_forms_are_reported_singular() {
        let pts = synthetic_points(&[250.0, 300.0, 325.0, 350.0, 400.0], &[60.0], 0.0, 0.01);
        let cal = calibrate_points("S", pts).expect("calibrate");
        assert!(matches!(
            cal.chosen.form,
            Form::Quadratic | Form::Linear | Form::Table
        ));
        let sag = cal.forms.iter().find(|s| s.form.has_sag()).expect("scored");
        assert!(sag.cv_rms_um.is_none() && sag.note.is_some(), "{sag:?}");
    }

    #[test]
    fn table_interpolates_exactly_at_its_points_and_between_tilts() {
        let pts = synthetic_points(&[250.0, 325.0, 400.0], &[30.0, 90.0], 1.0, 0.0);
        let f = fit_form(Form::Table, &pts).expect("table");
        for p in &pts {
            assert!(((f.distance_mm(p.reading_mm, p.tilt_deg) - p.length_mm) * 1e3).abs() < 1e-9);
        }
        assert!(f.distance_mm(95.0, 60.0).is_finite());
    }

    #[test]
    fn other_counter_epochs_are_excluded() {
        let mut pts = synthetic_points(&[250.0, 325.0, 400.0], &[60.0, 90.0], 0.5, 0.0);
        pts[0].epoch = 1;
        let cal = calibrate_points("S", pts).expect("calibrate");
        assert_eq!(cal.epoch, 0);
        assert_eq!(cal.excluded.len(), 1);
        assert_eq!(cal.excluded[0].epoch, 1);
        assert!(cal.distance_mm(95.0, 60.0, 1).is_none());
    }

    #[test]
    fn too_few_points_is_a_typed_error() {
        let pts = synthetic_points(&[250.0, 400.0], &[60.0], 0.0, 0.0);
        assert!(matches!(
            calibrate_points("S", pts),
            Err(CalibrateError::TooFewPoints { n: 2, .. })
        ));
    }

    #[test]
    fn length_uncertainty_propagates_with_interpolation_weights() {
        let pts = synthetic_points(&[250.0, 325.0, 400.0], &[60.0], 0.0, 0.0);
        let cal = calibrate_points("S", pts).expect("calibrate");
        let w = length_weights(&cal, cal.points[1].reading_mm, 60.0);
        assert!(
            (w.iter().sum::<f64>() - 1.0).abs() < 1e-6,
            "weights sum to one: {w:?}"
        );
        let u = u_from_lengths_um(&cal, cal.points[1].reading_mm, 60.0);
        assert!(u > 0.0 && u <= 0.1 + 1e-9, "u = {u}");
    }
}
