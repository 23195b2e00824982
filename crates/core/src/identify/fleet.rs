//! The identify stage over a fleet ([`identify_fleet`]): each bar's readings (or the bins ingest
//! compressed them into) become its series, which is identified, every bar in parallel; a bar
//! ingest found unusable, or whose series or fit fails, is listed and the others go on.

use std::collections::BTreeMap;

use rayon::prelude::*;

use crate::campaign::{Campaign, TimeNs};
use crate::model::Effect;
use crate::series::{
    knot_logs, sensor_knots, BarBins, BarLog, BarSeries, Event, FleetContext, Quality, SensorLog,
    SeriesError,
};
use crate::stage::{FailureReason, StageOutcome};

use super::{identify, BarModel, IdentifyError};

/// One identified bar: the series it was fitted on and its model.
#[derive(Debug, Clone)]
pub struct BarOutcome {
    /// The bar's series as fitted (readings or bins, temperatures, mounts).
    pub series: BarSeries,
    /// Its fitted thermal model.
    pub model: BarModel,
}

/// The campaign around the bars identify fits: what every bar's series is built from.
#[derive(Debug, Clone, Copy)]
pub struct FleetLogs<'a> {
    /// The validated manifest.
    pub campaign: &'a Campaign,
    /// The campaign's events, sorted by time.
    pub events: &'a [Event],
    /// Every sensor's full-rate log.
    pub sensors: &'a BTreeMap<String, SensorLog>,
    /// What ingest found of each bar (a bar with no usable signal is not fitted).
    pub quality: &'a Quality,
    /// The campaign's time origin ([`crate::series::campaign_origin_ns`]).
    pub t0_ns: TimeNs,
}

/// The bars' readings, handed over whole: identify consumes them as it builds the series.
#[derive(Debug, Clone, Default)]
pub struct FleetReadings {
    /// Bar id -> its log (empty for a bar whose readings are in `bins`).
    pub bars: BTreeMap<String, BarLog>,
    /// Bar id -> its readings compressed into bins while ingest streamed them.
    pub bins: BTreeMap<String, BarBins>,
}

/// How identify fits the fleet.
#[derive(Debug, Clone)]
pub struct IdentifyOptions {
    /// The model's effects.
    pub effects: Vec<Effect>,
    /// Bin length of the compressed readings, s (0: every reading).
    pub bin_s: f64,
    /// Keep each series' samples for the later stages; without them (a plain identify run) the
    /// fleet's series are never held at full rate.
    pub keep_samples: bool,
}

/// Identify every bar of the fleet, in parallel, in the campaign's order: its series (from its
/// bins when ingest compressed it, else binned from its readings at `options.bin_s`), then its
/// model. `on_bar_done` is called once per bar (a progress bar). Failures are logged at `info`
/// (the caller reports them) and listed in the outcome.
pub fn identify_fleet(
    logs: FleetLogs<'_>,
    readings: FleetReadings,
    options: &IdentifyOptions,
    on_bar_done: &(dyn Fn() + Sync),
) -> StageOutcome<BarOutcome> {
    // A compressed series samples the sensors at most twice a bin (`series::knot_logs`); the
    // full-rate logs stay with the caller (the air history, the device's sensors).
    let knot_sensors = knot_logs(logs.sensors, options.bin_s);
    let knots = sensor_knots(&knot_sensors);
    let fleet = FleetContext {
        campaign: logs.campaign,
        events: logs.events,
        sensors: &knot_sensors,
        knots: &knots,
        t0_ns: logs.t0_ns,
    };
    let FleetReadings { bars, mut bins } = readings;
    let outcomes: Vec<(String, Result<BarOutcome, FailureReason>)> = bars
        .into_iter()
        .map(|(id, log)| {
            let binned = bins.remove(&id);
            (id, log, binned)
        })
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|(id, log, binned)| {
            let outcome = identify_one(&fleet, logs.quality, &id, log, binned, options);
            on_bar_done();
            (id, outcome)
        })
        .collect();
    let identified = StageOutcome::from_reasons(outcomes);
    // In failed_bars and the final line.
    for f in &identified.failed {
        match &f.reason {
            FailureReason::Error(message) => tracing::info!("{message}"),
            FailureReason::Unusable(why) => tracing::info!(bar = %f.bar, unusable = ?why),
        }
    }
    identified
}

/// Why one bar of the fleet could not be fitted (each message one line naming the bar).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub(crate) enum BarError {
    /// Its series could not be built.
    #[error(transparent)]
    Series(#[from] SeriesError),
    /// Its model could not be fitted.
    #[error(transparent)]
    Identify(#[from] IdentifyError),
}

/// One bar: its series, its model; why not: no usable signal, or an error in one line.
fn identify_one(
    fleet: &FleetContext<'_>,
    quality: &Quality,
    id: &str,
    log: BarLog,
    binned: Option<BarBins>,
    options: &IdentifyOptions,
) -> Result<BarOutcome, FailureReason> {
    // A bar ingest found no usable signal in (a dead encoder) fails alone.
    if let Some(why) = quality.unusable(id) {
        return Err(FailureReason::Unusable(why));
    }
    fit_one(fleet, id, log, binned, options).map_err(|e| FailureReason::Error(e.to_string()))
}

/// One usable bar: its series, its model.
fn fit_one(
    fleet: &FleetContext<'_>,
    id: &str,
    log: BarLog,
    binned: Option<BarBins>,
    options: &IdentifyOptions,
) -> Result<BarOutcome, BarError> {
    let series = match binned {
        Some(b) => BarSeries::from_bins(fleet, id, &b),
        None => BarSeries::build_binned(fleet, id, log, options.bin_s),
    }?;
    let model = identify(&series, &options.effects)?;
    let series = if options.keep_samples {
        series
    } else {
        series.without_samples()
    };
    Ok(BarOutcome { series, model })
}
