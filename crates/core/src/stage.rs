//! What every per-bar stage returns: the bars it processed and those it could not
//! ([`StageOutcome`]; one bad bar never stops the others), and the stages' timing log
//! ([`timed`]).

use crate::series::quality::Unusable;

/// A bar a stage could not process, and why: one bad bar never stops the others. Written as
/// `{bar, error}` in every JSON output that lists failures.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BarFailure {
    /// The bar's id.
    pub bar: String,
    /// Why.
    pub reason: FailureReason,
}

/// Why a bar failed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FailureReason {
    /// Ingest found no usable signal in the bar (`series::Quality::unusable`): it is not fitted.
    Unusable(Unusable),
    /// An error, its one-line message.
    Error(String),
}

/// What a per-bar stage gave: the bars it processed, and those it could not.
#[derive(Debug, Clone)]
pub struct StageOutcome<T> {
    /// The bars processed, in the campaign's order.
    pub ok: Vec<T>,
    /// The bars the stage could not process.
    pub failed: Vec<BarFailure>,
}

impl<T> StageOutcome<T> {
    /// Per-bar results, in their order, split into the processed and the failed (each error
    /// kept as its one-line message).
    pub(crate) fn from_results<E: std::fmt::Display>(
        results: impl IntoIterator<Item = (String, Result<T, E>)>,
    ) -> Self {
        Self::from_reasons(
            results.into_iter().map(|(bar, result)| {
                (bar, result.map_err(|e| FailureReason::Error(e.to_string())))
            }),
        )
    }

    /// Per-bar results, in their order, split into the processed and the failed.
    pub(crate) fn from_reasons(
        results: impl IntoIterator<Item = (String, Result<T, FailureReason>)>,
    ) -> Self {
        let mut outcome = StageOutcome {
            ok: Vec::new(),
            failed: Vec::new(),
        };
        for (bar, result) in results {
            match result {
                Ok(t) => outcome.ok.push(t),
                Err(reason) => outcome.failed.push(BarFailure { bar, reason }),
            }
        }
        outcome
    }

    /// The outcome, its failures logged as warnings (they are also in the stage's JSON).
    pub(crate) fn with_failures_warned(self) -> Self {
        for f in &self.failed {
            match &f.reason {
                FailureReason::Error(message) => tracing::warn!("{message}"),
                FailureReason::Unusable(why) => tracing::warn!(bar = %f.bar, unusable = ?why),
            }
        }
        self
    }
}

/// Run `f` and log how long it took (`DBBCAL_LOG=info`): stage timings go to the log, never
/// into the byte-identical outputs.
pub fn timed<T>(what: &str, f: impl FnOnce() -> T) -> T {
    let start = std::time::Instant::now();
    let out = f();
    tracing::info!("{what}: {:.3} s", start.elapsed().as_secs_f64());
    out
}
