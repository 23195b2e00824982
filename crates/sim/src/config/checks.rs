//! The small checks validation is written with (finite, positive, within a `Limit`, a bounded
//! fleet spread, unique ids), each returning the key's error in `dbbcal_core::limits`' words.
//!
//! Separate so that each section's validation reads as a list of keys and rules.

use crate::SimError;
use dbbcal_core::limits::Limit;

pub(super) fn invalid(key: &str, reason: &str) -> SimError {
    SimError::Invalid {
        key: key.into(),
        reason: reason.into(),
    }
}

/// `v` within `limit`, or the key named with the range in `dbbcal_core::limits`' words.
fn within(key: &str, v: f64, limit: Limit) -> Result<(), SimError> {
    limit.check(key, v).map_err(|e| SimError::Invalid {
        key: key.into(),
        reason: format!("= {} is out of range: it must be {}", e.value, e.allowed),
    })
}

pub(super) fn finite(key: &str, v: f64) -> Result<(), SimError> {
    within(key, v, Limit::FINITE)
}

pub(super) fn positive(key: &str, v: f64) -> Result<(), SimError> {
    within(key, v, Limit::POSITIVE)
}

pub(super) fn non_negative(key: &str, v: f64) -> Result<(), SimError> {
    within(key, v, Limit::NON_NEGATIVE)
}

/// A tilt from horizontal in [0, 90] degrees.
pub(super) fn tilt(key: &str, v: f64) -> Result<(), SimError> {
    within(key, v, Limit::closed(0.0, 90.0, "degrees"))
}

/// A fleet mean and spread with `|mean| + 5 sd <= limit`.
pub(super) fn bounded(key: &str, mean: f64, sd: f64, limit: f64) -> Result<(), SimError> {
    finite(key, mean)?;
    if mean.abs() + 5.0 * sd.abs() <= limit {
        Ok(())
    } else {
        Err(invalid(key, &format!("mean + 5 sd beyond {limit}")))
    }
}

pub(super) fn unique<'a>(key: &str, ids: impl Iterator<Item = &'a str>) -> Result<(), SimError> {
    let mut seen = std::collections::BTreeSet::new();
    for id in ids {
        if !seen.insert(id) {
            return Err(invalid(key, &format!("duplicate id `{id}`")));
        }
    }
    Ok(())
}
