//! The `volumetric` kind's logs as plain data and the reader rules
//! (`docs/spec/machine-formats.md`, "Kind volumetric"):
//!
//! - **Body diagonals** are ordered by diagonal, run and time; equal times by `target_mm` in
//!   the run's direction; without `direction` it is derived as for `axis`
//!   ([`crate::axis_campaign::derive_order`], the diagonal standing for the line).
//! - **Step diagonals** are ordered by diagonal, run, step, then time; sub-moves of one step
//!   with equal times in the order X, Y, Z (step 0, the datum, first).
//! - **Bar readings** (`docs/bar-diagonals.md`) are ordered by diagonal, segment, run, time,
//!   then distance along the diagonal.

use std::collections::BTreeMap;

use super::{DiagonalSign, VolumetricCampaign};
use crate::axis_campaign::{
    derive_order, Channel, EnvironmentRow, MachineAxis, OrderProblem, ReadingKey,
};
use crate::campaign::TimeNs;
use crate::series::{Event, InputFile, SensorLog};

/// One row of `diagonals/*.parquet`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiagonalReading {
    /// When the reading was taken, ns since the epoch.
    pub time_ns: TimeNs,
    /// Which diagonal.
    pub diagonal: DiagonalSign,
    /// Run, from 1.
    pub run: i64,
    /// +1 moving from P0 towards the end, −1 back (given or derived).
    pub direction: i8,
    /// Commanded distance from P0 along u, mm.
    pub target_mm: f64,
    /// Measured − commanded displacement along u, µm.
    pub deviation_um: f64,
}

/// One row of `steps/*.parquet`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepReading {
    /// When the reading was taken, ns since the epoch.
    pub time_ns: TimeNs,
    /// Which diagonal.
    pub diagonal: DiagonalSign,
    /// Run, from 1 (default 1).
    pub run: i64,
    /// 0 = the start corner (datum), then 1 … N.
    pub step: i64,
    /// The axis just moved; `None` at step 0.
    pub submove: Option<MachineAxis>,
    /// Commanded position after the sub-move, mm.
    pub position_mm: [f64; 3],
    /// Displacement read along the beam − 1000 u·(P − P0), µm.
    pub deviation_um: f64,
}

/// One row of `bar_diagonals/*.parquet` (`docs/bar-diagonals.md`): a body diagonal read by a
/// calibrated bar whose fixed ball sits in a socket on the diagonal's line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BarReading {
    /// When the reading was taken, ns since the epoch.
    pub time_ns: TimeNs,
    /// Which diagonal.
    pub diagonal: DiagonalSign,
    /// The segment (one socket set-up), from 1.
    pub segment: i64,
    /// Run, from 1 (default 1).
    pub run: i64,
    /// +1 moving from P0 towards the end, −1 back (default +1).
    pub direction: i8,
    /// Commanded distance from P0 along u, mm.
    pub distance_along_mm: f64,
    /// The bar's compensated centre distance (its calibration function and thermal
    /// compensation applied), mm.
    pub centre_distance_mm: f64,
    /// Standard uncertainty of the reading's random part, µm, when known.
    pub u_um: Option<f64>,
}

/// Sorts bar readings: diagonal, segment, run, time, distance, centre distance.
pub fn order_bar_readings(readings: &mut [BarReading]) {
    readings.sort_by(|a, b| {
        (a.diagonal, a.segment, a.run, a.time_ns)
            .cmp(&(b.diagonal, b.segment, b.run, b.time_ns))
            .then(a.distance_along_mm.total_cmp(&b.distance_along_mm))
            .then(a.centre_distance_mm.total_cmp(&b.centre_distance_mm))
    });
}

/// Everything a `volumetric` campaign directory holds, validated and sorted.
#[derive(Debug, Clone)]
pub struct VolumetricCampaignLogs {
    /// The validated manifest.
    pub campaign: VolumetricCampaign,
    /// Every file read (manifest first), with its hash, sorted by path.
    pub inputs: Vec<InputFile>,
    /// Body-diagonal readings, ordered ([`order_diagonal_readings`]).
    pub diagonals: Vec<DiagonalReading>,
    /// Step-diagonal readings, ordered ([`order_step_readings`]).
    pub steps: Vec<StepReading>,
    /// Bar readings of body diagonals, ordered ([`order_bar_readings`]).
    pub bar_readings: Vec<BarReading>,
    /// Environment rows, sorted by time.
    pub environment: Vec<EnvironmentRow>,
    /// Sensor id -> its log.
    pub temperatures: BTreeMap<String, SensorLog>,
    /// Events, sorted by time.
    pub events: Vec<Event>,
}

/// The tables of a `volumetric` campaign as plain rows (what the simulator writes).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct VolumetricCampaignTables {
    /// `diagonals/*.parquet` (none written when empty).
    pub diagonals: Vec<DiagonalReading>,
    /// `steps/*.parquet` (none written when empty).
    pub steps: Vec<StepReading>,
    /// `bar_diagonals/*.parquet` (none written when empty).
    pub bar_readings: Vec<BarReading>,
    /// `environment/*.parquet`.
    pub environment: Vec<EnvironmentRow>,
}

/// Orders body-diagonal readings and fills in their directions: `given[i]` is the direction
/// of `readings[i]` as the file gave it (`None`: absent or null; `readings[i].direction` is
/// ignored). Errors name the rows (indices into `readings`).
pub fn order_diagonal_readings(
    readings: &[DiagonalReading],
    given: &[Option<i8>],
) -> Result<Vec<DiagonalReading>, OrderProblem> {
    let keys: Vec<ReadingKey> = readings
        .iter()
        .zip(given)
        .map(|(r, d)| ReadingKey {
            time_ns: r.time_ns,
            line: r.diagonal.index() as i64,
            run: r.run,
            target_mm: r.target_mm,
            channel: Channel::Dx,
            deviation_um: r.deviation_um,
            direction: *d,
        })
        .collect();
    let order = derive_order(&keys)?;
    Ok(order
        .order
        .iter()
        .map(|&i| DiagonalReading {
            direction: order.direction[i],
            ..readings[i]
        })
        .collect())
}

/// Sorts step readings: diagonal, run, step, time, sub-move (none, X, Y, Z), deviation.
pub fn order_step_readings(readings: &mut [StepReading]) {
    let submove = |r: &StepReading| r.submove.map_or(0, |a| a.index() + 1);
    readings.sort_by(|a, b| {
        (a.diagonal, a.run, a.step, a.time_ns, submove(a))
            .cmp(&(b.diagonal, b.run, b.step, b.time_ns, submove(b)))
            .then(a.deviation_um.total_cmp(&b.deviation_um))
    });
}

/// The name of a diagonal's index (for messages from [`OrderProblem`], whose `line` is it).
pub fn diagonal_of_index(i: i64) -> Option<DiagonalSign> {
    DiagonalSign::ALL.get(usize::try_from(i).ok()?).copied()
}
