//! The body diagonals a campaign read by a bar (`docs/bar-diagonals.md`): each diagonal's
//! readings normalised to T0, stitched ([`super::super::bar_diagonal::stitch`]), and handed to
//! the study as body-diagonal observations, every reading less its segment's constant.
//!
//! **Normalisation** *(ours)*: the bar's compensated centre distance is a true length (its own
//! thermal state is compensated); the machine's, like a laser reading with `"air"`
//! compensation, is normalised to T0 by 1 + α (T_m − T0) with the material temperature of
//! `environment/*.parquet` at the reading's time, when the log gives one; without it the
//! readings are taken as they are (at the machine's temperature during the test), and
//! [`BarCurve::normalised`] says so.
//!
//! **In the joint fit** the additive model holds each error function on the step nodes
//! (`super::super::model`), so with step diagonals a bar's finer targets between the nodes
//! would meet a shape the model cannot hold there; each pass (segment, run, direction) enters
//! the fit at the nodes' distances D·i/N inside its span instead, read off the pass by linear
//! interpolation between its neighbouring targets ([`BarCurve::fit_observations`]). ISO 230-2
//! and V_diag use every reading.
//!
//! **Misalignment**: the largest angle between the bar and the diagonal is
//! `misalignment_mm` over the shortest centre distance of the diagonal's readings.

use std::collections::BTreeMap;

use dbbcal_core::volumetric_campaign::{BarReading, DiagonalSign, VolumetricCampaignLogs};

use super::super::bar_diagonal::{
    stitch, BarDiagonalBudget, BarDiagonalError, BarDiagonalReading, StitchedDiagonal,
};
use super::super::model::{Observation, Place};
use super::conditions;

/// A body diagonal read by the bar, stitched.
#[derive(Debug, Clone)]
pub struct BarCurve {
    /// Which diagonal.
    pub sign: DiagonalSign,
    /// The bar's id.
    pub bar: String,
    /// Dr with its U, the segments' constants.
    pub stitched: StitchedDiagonal,
    /// The readings as body-diagonal observations (each less its segment's constant, µm).
    pub observations: Vec<Observation>,
    /// The segment of each observation.
    pub segment_of: Vec<i64>,
    /// Whether every reading was normalised to T0 with a material temperature.
    pub normalised: bool,
    /// The shortest centre distance read, mm (the misalignment's angle is taken there).
    pub shortest_centre_distance_mm: f64,
}

impl BarCurve {
    /// Number of segments (socket set-ups).
    pub fn segments(&self) -> usize {
        self.stitched.segments.len()
    }

    /// The observations the joint fit takes: every reading without step nodes (`None`);
    /// with the nodes' distances along the diagonal, each pass read at those inside its span.
    pub fn fit_observations(&self, nodes_mm: Option<&[f64]>) -> Vec<Observation> {
        let Some(nodes) = nodes_mm else {
            return self.observations.clone();
        };
        let mut passes: BTreeMap<(i64, i64, i8), Vec<(usize, Observation)>> = BTreeMap::new();
        for (i, o) in self.observations.iter().enumerate() {
            passes
                .entry((self.segment_of[i], o.run, o.direction))
                .or_default()
                .push((i, *o));
        }
        let mut out = Vec::new();
        for pass in passes.values_mut() {
            pass.sort_by(|a, b| d_of(&a.1).total_cmp(&d_of(&b.1)));
            for &d in nodes {
                if let Some(o) = at(pass, d) {
                    out.push(o);
                }
            }
        }
        out
    }
}

/// A body observation's distance from P0, mm.
fn d_of(o: &Observation) -> f64 {
    match o.place {
        Place::Body { d_mm } => d_mm,
        Place::Step { .. } => f64::NAN,
    }
}

/// The pass (sorted by distance) read at `d`: a reading there, or the linear interpolation
/// between the two around it (time too); `None` outside the pass's span.
fn at(pass: &[(usize, Observation)], d: f64) -> Option<Observation> {
    const SAME_MM: f64 = 1e-6;
    let k = pass.partition_point(|(_, o)| d_of(o) < d - SAME_MM);
    let (_, hi) = pass.get(k)?;
    if (d_of(hi) - d).abs() <= SAME_MM {
        return Some(*hi);
    }
    let (_, lo) = pass.get(k.checked_sub(1)?)?;
    let w = (d - d_of(lo)) / (d_of(hi) - d_of(lo));
    Some(Observation {
        place: Place::Body { d_mm: d },
        hours: lo.hours + w * (hi.hours - lo.hours),
        deviation_um: lo.deviation_um + w * (hi.deviation_um - lo.deviation_um),
        ..*lo
    })
}

/// A bar-read diagonal that cannot be stitched, named.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("bar_diagonals/*.parquet, diagonal {diagonal} (bar {bar}): {source}")]
pub struct BarCampaignError {
    /// Which diagonal.
    pub diagonal: DiagonalSign,
    /// The bar's id.
    pub bar: String,
    /// Why.
    #[source]
    pub source: BarDiagonalError,
}

/// Stitches every bar-read diagonal of `logs` (none without `bar_diagonals/`).
pub fn stitch_campaign(logs: &VolumetricCampaignLogs) -> Result<Vec<BarCurve>, BarCampaignError> {
    let Some(decl) = &logs.campaign.bar_diagonal else {
        return Ok(Vec::new());
    };
    let t0 = first_reading_ns(logs);
    let mut by: BTreeMap<DiagonalSign, Vec<&BarReading>> = BTreeMap::new();
    for r in &logs.bar_readings {
        by.entry(r.diagonal).or_default().push(r);
    }
    by.into_iter()
        .map(|(sign, rows)| {
            let fail = |source| BarCampaignError {
                diagonal: sign,
                bar: decl.bar.clone(),
                source,
            };
            let shortest = rows
                .iter()
                .map(|r| r.centre_distance_mm)
                .fold(f64::INFINITY, f64::min);
            let budget = BarDiagonalBudget {
                scale_u_ppm: decl.scale_u_ppm,
                max_misalignment_rad: decl.misalignment_mm / shortest,
            };
            let (normalised, readings): (Vec<bool>, Vec<f64>) =
                rows.iter().map(|r| normalise(logs, r)).unzip();
            let input: Vec<BarDiagonalReading> = rows
                .iter()
                .zip(&readings)
                .map(|(r, l)| BarDiagonalReading {
                    segment: r.segment,
                    target_mm: r.distance_along_mm,
                    reading_um: 1e3 * (l - r.distance_along_mm),
                    u_um: r.u_um.unwrap_or(f64::NAN),
                })
                .collect();
            let stitched = stitch(&input, budget).map_err(fail)?;
            let observations = rows
                .iter()
                .zip(&input)
                .map(|(r, b)| {
                    let s = stitched.segments.binary_search(&r.segment).unwrap_or(0);
                    Observation {
                        diagonal: sign,
                        run: r.run,
                        direction: r.direction,
                        place: Place::Body {
                            d_mm: r.distance_along_mm,
                        },
                        hours: (r.time_ns - t0) as f64 / 3.6e12,
                        deviation_um: b.reading_um - stitched.segment_constant_um[s],
                        bar: true,
                    }
                })
                .collect();
            Ok(BarCurve {
                sign,
                bar: decl.bar.clone(),
                stitched,
                observations,
                segment_of: rows.iter().map(|r| r.segment).collect(),
                normalised: normalised.iter().all(|n| *n),
                shortest_centre_distance_mm: shortest,
            })
        })
        .collect()
}

/// The first reading of any instrument, ns (the study's hours count from it).
pub(super) fn first_reading_ns(logs: &VolumetricCampaignLogs) -> i64 {
    logs.diagonals
        .iter()
        .map(|r| r.time_ns)
        .chain(logs.steps.iter().map(|r| r.time_ns))
        .chain(logs.bar_readings.iter().map(|r| r.time_ns))
        .min()
        .unwrap_or(0)
}

/// The centre distance normalised to T0 (whether a material temperature was there), mm.
fn normalise(logs: &VolumetricCampaignLogs, r: &BarReading) -> (bool, f64) {
    let c = &logs.campaign;
    match conditions(logs, r.time_ns, r.time_ns).material_c {
        Some(t) => (
            true,
            r.centre_distance_mm / (1.0 + c.cte_ppm_per_k * 1e-6 * (t - c.reference_temperature_c)),
        ),
        None => (false, r.centre_distance_mm),
    }
}
