//! The `axis` kind's logs as plain data, and the rules every reader derives from them
//! (`docs/spec/machine-formats.md`, "Kind axis" and the reader rules at its top):
//!
//! - **Order.** Readings are handed over sorted by line, run and time; rows of one line and run
//!   with equal times (an export with one time per run) are ordered by `target_mm` in the run's
//!   direction, which must then be given ([`derive_order`]); remaining ties by channel
//!   (`dx`, `dy`, `dz`) and deviation, so any split of the files and any row order give the same
//!   logs.
//! - **Direction.** Where `direction` is absent or null it is the sign of the change of
//!   `target_mm` since the previous target of the same line and run, in time order; a run's
//!   first target takes its second's. *(ours, where the spec is silent)* Rows sharing a time and
//!   a target are one target visit (the channels of one reading); a visit at the same target as
//!   the previous one (a repeated target, the turn of a pendulum run) takes the sign of the
//!   next change in the run, else of the previous one. A run whose readings are all at one
//!   target has no direction to derive: it is refused, named.
//! - **Fixture.** A reading takes the latest fixture row of its line at or before its time, else
//!   the line's first fixture row, else the manifest's `reflector_mm` (`reflector_at`).
//! - **Environment.** A row holds until the next; before the first row, the first holds
//!   *(ours)* ([`environment_at`]).

use std::collections::BTreeMap;

use super::{AxisCampaign, MachineAxis};
use crate::campaign::TimeNs;
use crate::series::{Event, InputFile, SensorLog};

/// The component of a displacement a reading gives (`channel`: `dx`, `dy`, `dz`), in M.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Channel {
    /// Along +X.
    Dx,
    /// Along +Y.
    Dy,
    /// Along +Z.
    Dz,
}

impl Channel {
    /// Every channel, in order.
    pub const ALL: [Channel; 3] = [Channel::Dx, Channel::Dy, Channel::Dz];

    /// The word in the `channel` column; `Channel::parse(c.as_str()) == Some(c)`.
    pub fn as_str(self) -> &'static str {
        match self {
            Channel::Dx => "dx",
            Channel::Dy => "dy",
            Channel::Dz => "dz",
        }
    }

    /// The channel a word names (exactly `dx`, `dy` or `dz`).
    pub fn parse(word: &str) -> Option<Channel> {
        Self::ALL.into_iter().find(|c| c.as_str() == word)
    }

    /// 0, 1, 2 for dx, dy, dz: the component of a vector in M.
    pub fn index(self) -> usize {
        self as usize
    }

    /// The channel along `axis`.
    pub fn of_axis(axis: MachineAxis) -> Channel {
        Self::ALL[axis.index()]
    }
}

impl std::fmt::Display for Channel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.as_str())
    }
}

/// One row of `readings/*.parquet`, direction given or derived.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisReading {
    /// When the reading was taken, ns since the epoch (UTC).
    pub time_ns: TimeNs,
    /// Line id, as in the manifest.
    pub line: i64,
    /// Run within the line, from 1.
    pub run: i64,
    /// +1 / −1: the target approached moving in the axis's + / − direction.
    pub direction: i8,
    /// Commanded coordinate of the axis under test, mm.
    pub target_mm: f64,
    /// The component of the displacement read.
    pub channel: Channel,
    /// Measured − commanded displacement along `channel`, µm.
    pub deviation_um: f64,
}

/// An extra column of `readings/*.parquet`, kept by name (a candidate explanatory channel);
/// one value per reading, in the readings' order.
#[derive(Debug, Clone, PartialEq)]
pub enum ExtraColumn {
    /// A numeric (or boolean: 0/1) column, as f64.
    Real(Vec<Option<f64>>),
    /// Any other column, as text.
    Text(Vec<Option<String>>),
}

impl ExtraColumn {
    /// Its values, in the order `order` gives (indices into the column).
    pub fn reordered(&self, order: &[usize]) -> ExtraColumn {
        match self {
            ExtraColumn::Real(v) => ExtraColumn::Real(order.iter().map(|&i| v[i]).collect()),
            ExtraColumn::Text(v) => {
                ExtraColumn::Text(order.iter().map(|&i| v[i].clone()).collect())
            }
        }
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            ExtraColumn::Real(v) => v.len(),
            ExtraColumn::Text(v) => v.len(),
        }
    }

    /// Whether it holds no value.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One row of `fixture/*.parquet`: the three fixture scales, read as one reflector point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixtureRow {
    /// From when the row holds (until the next row of the same line), ns since the epoch.
    pub time_ns: TimeNs,
    /// Line id.
    pub line: i64,
    /// The reflector's measuring point in the fixture frame F (`x_mm`, `y_mm`, `z_mm`).
    pub reflector_mm: [f64; 3],
}

/// One row of `environment/*.parquet` (`machine-formats.md`, "Laser and environment").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnvironmentRow {
    /// From when the row holds (until the next), ns since the epoch.
    pub time_ns: TimeNs,
    /// Air temperature near the beam, °C.
    pub air_c: f64,
    /// Air pressure, hPa.
    pub pressure_hpa: f64,
    /// Relative humidity, %.
    pub humidity_pct: f64,
    /// Machine (material) temperature, °C; `None`: not measured.
    pub material_c: Option<f64>,
    /// The correction the laser system applied at that time, ppm; `None`: not stated.
    pub env_factor_ppm: Option<f64>,
}

/// Everything an `axis` campaign directory holds, validated and sorted: what
/// `dbbcal_io::read_axis_campaign` hands over.
#[derive(Debug, Clone)]
pub struct AxisCampaignLogs {
    /// The validated manifest.
    pub campaign: AxisCampaign,
    /// Every file read (manifest first), with its hash, sorted by path.
    pub inputs: Vec<InputFile>,
    /// The readings, sorted by line, run and time ([`derive_order`]), directions filled in.
    pub readings: Vec<AxisReading>,
    /// The readings' extra columns by name, each in the readings' order.
    pub extra: BTreeMap<String, ExtraColumn>,
    /// Rows equal in every spec column to another (a reading two files hold), left out.
    pub duplicate_readings: u64,
    /// The fixture rows, sorted by line and time (empty without `fixture/`).
    pub fixture: Vec<FixtureRow>,
    /// The environment rows, sorted by time (empty without `environment/`).
    pub environment: Vec<EnvironmentRow>,
    /// Sensor id -> its log (`temperatures/*.parquet`), sorted by time.
    pub temperatures: BTreeMap<String, SensorLog>,
    /// `events/*.parquet`, sorted by time.
    pub events: Vec<Event>,
}

impl AxisCampaignLogs {
    /// The reflector point (in F, mm) of `reading`: `reflector_at` with the manifest's
    /// fallback. A line the manifest does not declare (never in read logs) gives F's origin.
    pub fn reflector_mm(&self, reading: &AxisReading) -> [f64; 3] {
        let default = self
            .campaign
            .line(reading.line)
            .map_or([0.0; 3], |l| l.reflector_mm);
        reflector_at(&self.fixture, reading.line, reading.time_ns, default)
    }

    /// The environment at `time_ns` ([`environment_at`]).
    pub fn environment_at(&self, time_ns: TimeNs) -> Option<&EnvironmentRow> {
        environment_at(&self.environment, time_ns)
    }
}

/// The tables of an `axis` campaign as plain rows: what the simulator produces and
/// `dbbcal_io::write_axis_campaign` writes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AxisCampaignTables {
    /// `readings/*.parquet`.
    pub readings: Vec<AxisReading>,
    /// `fixture/*.parquet` (none written when empty).
    pub fixture: Vec<FixtureRow>,
    /// `environment/*.parquet` (none written when empty).
    pub environment: Vec<EnvironmentRow>,
}

/// The reflector point of a reading on `line` at `time_ns`: the latest row of the line in
/// `fixture` at or before the time, else the line's first row, else `default` (the manifest's
/// `reflector_mm`). `fixture` must be sorted by (line, time).
pub(crate) fn reflector_at(
    fixture: &[FixtureRow],
    line: i64,
    time_ns: TimeNs,
    default: [f64; 3],
) -> [f64; 3] {
    let start = fixture.partition_point(|r| r.line < line);
    let end = fixture.partition_point(|r| r.line <= line);
    let rows = &fixture[start..end];
    let Some(first) = rows.first() else {
        return default;
    };
    let upto = rows.partition_point(|r| r.time_ns <= time_ns);
    if upto == 0 {
        first.reflector_mm
    } else {
        rows[upto - 1].reflector_mm
    }
}

/// The environment row that holds at `time_ns`: the latest at or before it, else the first;
/// `None` when there is none. `rows` must be sorted by time.
pub fn environment_at(rows: &[EnvironmentRow], time_ns: TimeNs) -> Option<&EnvironmentRow> {
    let upto = rows.partition_point(|r| r.time_ns <= time_ns);
    rows.get(upto.saturating_sub(1))
}

// ---------------------------------------------------------------- order and direction

/// What [`derive_order`] needs of one reading: its keys, with the direction as given (`None`:
/// absent or null).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReadingKey {
    /// Time, ns since the epoch.
    pub time_ns: TimeNs,
    /// Line id.
    pub line: i64,
    /// Run.
    pub run: i64,
    /// Commanded coordinate, mm (finite).
    pub target_mm: f64,
    /// Channel.
    pub channel: Channel,
    /// Deviation, µm (the last tie-break).
    pub deviation_um: f64,
    /// The given direction (+1 / −1), if any.
    pub direction: Option<i8>,
}

/// The readings' order and directions.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReadingOrder {
    /// Indices into the keys, in the handed-over order.
    pub order: Vec<usize>,
    /// Direction of each key (indexed like the keys): the given one, or derived.
    pub direction: Vec<i8>,
}

/// Why readings cannot be ordered, or a direction cannot be derived: the rows concerned
/// (indices into the keys) and what is wrong, for a reader to name by file and row.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("line {line}, run {run}: {problem}")]
pub struct OrderProblem {
    /// Line id.
    pub line: i64,
    /// Run.
    pub run: i64,
    /// The rows concerned (indices into the keys), sorted.
    pub rows: Vec<usize>,
    /// What is wrong, in words.
    pub problem: String,
}

/// Sorts readings and fills in their directions (this module's rules: order, direction).
/// Deterministic: the same readings in any order give the same sequence of rows (rows equal in
/// every key are interchangeable).
pub fn derive_order(keys: &[ReadingKey]) -> Result<ReadingOrder, OrderProblem> {
    let mut order: Vec<usize> = (0..keys.len()).collect();
    order.sort_by(|&a, &b| {
        let (ka, kb) = (&keys[a], &keys[b]);
        (ka.line, ka.run, ka.time_ns).cmp(&(kb.line, kb.run, kb.time_ns))
    });
    let mut direction: Vec<i8> = keys.iter().map(|k| k.direction.unwrap_or(0)).collect();
    if let Some(i) = keys
        .iter()
        .position(|k| k.direction.is_some_and(|d| d != 1 && d != -1))
    {
        return Err(OrderProblem {
            line: keys[i].line,
            run: keys[i].run,
            rows: vec![i],
            problem: format!(
                "direction {} is neither +1 nor -1",
                keys[i].direction.unwrap_or(0)
            ),
        });
    }
    let mut start = 0;
    while start < order.len() {
        let (line, run) = (keys[order[start]].line, keys[order[start]].run);
        let end = start
            + order[start..]
                .iter()
                .take_while(|&&i| keys[i].line == line && keys[i].run == run)
                .count();
        order_run(keys, &mut order[start..end])?;
        derive_run(keys, &order[start..end], &mut direction)?;
        start = end;
    }
    Ok(ReadingOrder { order, direction })
}

/// Orders the rows of one line and run (already sorted by time): within equal times by target
/// in the given direction, then channel and deviation.
fn order_run(keys: &[ReadingKey], rows: &mut [usize]) -> Result<(), OrderProblem> {
    let mut start = 0;
    while start < rows.len() {
        let t = keys[rows[start]].time_ns;
        let end = start
            + rows[start..]
                .iter()
                .take_while(|&&i| keys[i].time_ns == t)
                .count();
        let block = &mut rows[start..end];
        let first_target = keys[block[0]].target_mm;
        let one_target = block.iter().all(|&i| keys[i].target_mm == first_target);
        let sign = if one_target {
            1.0
        } else {
            let problem = |rows: Vec<usize>, problem: String| {
                let k = &keys[block[0]];
                let mut rows = rows;
                rows.sort_unstable();
                OrderProblem {
                    line: k.line,
                    run: k.run,
                    rows,
                    problem,
                }
            };
            let missing: Vec<usize> = block
                .iter()
                .copied()
                .filter(|&i| keys[i].direction.is_none())
                .collect();
            if !missing.is_empty() {
                return Err(problem(
                    block.to_vec(),
                    format!(
                        "{} readings share one time at different targets and {} of them have no `direction`: their order cannot be known (give `direction`)",
                        block.len(),
                        missing.len()
                    ),
                ));
            }
            let d0 = keys[block[0]].direction;
            if block.iter().any(|&i| keys[i].direction != d0) {
                return Err(problem(
                    block.to_vec(),
                    format!(
                        "{} readings share one time at different targets in both directions: their order cannot be known",
                        block.len()
                    ),
                ));
            }
            f64::from(d0.unwrap_or(1))
        };
        block.sort_by(|&a, &b| {
            let (ka, kb) = (&keys[a], &keys[b]);
            (sign * ka.target_mm)
                .total_cmp(&(sign * kb.target_mm))
                .then(ka.channel.cmp(&kb.channel))
                .then(ka.deviation_um.total_cmp(&kb.deviation_um))
        });
        start = end;
    }
    Ok(())
}

/// Fills in the directions of the rows of one run (in their final order) that have none.
fn derive_run(
    keys: &[ReadingKey],
    rows: &[usize],
    direction: &mut [i8],
) -> Result<(), OrderProblem> {
    if rows.iter().all(|&i| keys[i].direction.is_some()) {
        return Ok(());
    }
    // Visits: consecutive rows sharing time and target; each visit's change of target.
    let mut visits: Vec<(usize, usize, i8)> = Vec::new(); // (start, end, change sign)
    let mut start = 0;
    while start < rows.len() {
        let k0 = &keys[rows[start]];
        let end = start
            + rows[start..]
                .iter()
                .take_while(|&&i| {
                    keys[i].time_ns == k0.time_ns && keys[i].target_mm == k0.target_mm
                })
                .count();
        let change = match visits.last() {
            None => 0,
            Some(&(s, _, _)) => {
                let previous = keys[rows[s]].target_mm;
                match k0.target_mm.total_cmp(&previous) {
                    std::cmp::Ordering::Greater => 1,
                    std::cmp::Ordering::Less => -1,
                    std::cmp::Ordering::Equal => 0,
                }
            }
        };
        visits.push((start, end, change));
        start = end;
    }
    for v in 0..visits.len() {
        let (s, e, change) = visits[v];
        let sign = if change != 0 {
            change
        } else {
            let next = visits[v + 1..].iter().map(|w| w.2).find(|&c| c != 0);
            let previous = visits[..v].iter().rev().map(|w| w.2).find(|&c| c != 0);
            match next.or(previous) {
                Some(c) => c,
                None => {
                    let k = &keys[rows[0]];
                    let mut all = rows.to_vec();
                    all.sort_unstable();
                    return Err(OrderProblem {
                        line: k.line,
                        run: k.run,
                        rows: all,
                        problem: format!(
                            "every reading of the run is at target_mm = {}: its direction cannot be derived (give `direction`)",
                            k.target_mm
                        ),
                    });
                }
            }
        };
        for &i in &rows[s..e] {
            if keys[i].direction.is_none() {
                direction[i] = sign;
            }
        }
    }
    Ok(())
}
