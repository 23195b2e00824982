//! The one vocabulary for the allowed range of a number a user sets: a manifest's value, a
//! pipeline file's, a simulator config's. Every check says the same thing the same way (the
//! key, the value, the range with its unit) through one error type, [`OutOfRange`]; the
//! tables in `docs/guarantees.md` are tested against the [`Limit`] constants that the checks
//! use (`tests/e2e/docs.rs`).
//!
//! NaN and the infinities are outside every range.

use thiserror::Error;

/// A number the user set is outside its range. Displays as one line: `KEY = VALUE is out of
/// range: it must be RANGE` (the range as [`Limit::describe`] words it).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{key} = {value} is out of range: it must be {allowed}")]
pub struct OutOfRange {
    /// The key as the user wrote it (`match.limit_um`, `plate: tilt_deg`, `bar[2] ("B03"):
    /// resolution_nm`).
    pub key: String,
    /// The value as given ([`display_number`]).
    pub value: String,
    /// The allowed range in words.
    pub allowed: String,
}

/// A point (mm) with a coordinate that is not a finite number within `±limit_mm`.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("coordinate {} is out of range: each must be a finite number within ±{limit_mm} mm", display_number(*.coordinate))]
pub struct PointOutOfRange {
    /// The first coordinate out of range, mm.
    pub coordinate: f64,
    /// The largest |coordinate| allowed, mm.
    pub limit_mm: f64,
}

/// `Ok` when every coordinate of `p` (mm) is finite and within `±limit_mm`.
pub(crate) fn check_point(p: &[f64; 3], limit_mm: f64) -> Result<(), PointOutOfRange> {
    match p.iter().find(|v| !(v.is_finite() && v.abs() <= limit_mm)) {
        None => Ok(()),
        Some(&coordinate) => Err(PointOutOfRange {
            coordinate,
            limit_mm,
        }),
    }
}

/// Whether the low end of a real range is allowed itself.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Low {
    /// `low ≤ value`.
    Included,
    /// `low < value` (a length, a resolution: zero is not one).
    Excluded,
}

/// The allowed range of a real number: finite, from `low` to `high` (included), in `unit`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limit {
    /// The low end.
    pub low: f64,
    /// Whether `low` itself is allowed.
    pub(crate) low_end: Low,
    /// The high end (always included).
    pub high: f64,
    /// The unit as printed after the numbers (`"µm"`, `"s"`, `""` for none).
    pub unit: &'static str,
}

impl Limit {
    /// `low ≤ value ≤ high`.
    pub const fn closed(low: f64, high: f64, unit: &'static str) -> Limit {
        Limit {
            low,
            low_end: Low::Included,
            high,
            unit,
        }
    }

    /// `low < value ≤ high`.
    pub const fn above(low: f64, high: f64, unit: &'static str) -> Limit {
        Limit {
            low,
            low_end: Low::Excluded,
            high,
            unit,
        }
    }

    /// Whether `value` is allowed.
    pub fn contains(&self, value: f64) -> bool {
        let low_ok = match self.low_end {
            Low::Included => value >= self.low,
            Low::Excluded => value > self.low,
        };
        value.is_finite() && low_ok && value <= self.high
    }

    /// `value` allowed, or the one-line error naming `key`.
    pub fn check(&self, key: &str, value: f64) -> Result<(), OutOfRange> {
        if self.contains(value) {
            Ok(())
        } else {
            Err(OutOfRange {
                key: key.to_string(),
                value: display_number(value),
                allowed: format!("a finite number {}", self.describe())
                    .trim_end()
                    .to_string(),
            })
        }
    }

    /// The range in words, as the error and the docs' tables say it: `from 1 to 86400 s`,
    /// `above 0 and at most 10000 mm`, `above 0` (no high end), `` (any finite number).
    pub fn describe(&self) -> String {
        let unit = if self.unit.is_empty() {
            String::new()
        } else {
            format!(" {}", self.unit)
        };
        let (low, high) = (display_number(self.low), display_number(self.high));
        match (self.low.is_finite(), self.high.is_finite(), self.low_end) {
            (false, false, _) => String::new(),
            (true, false, Low::Included) => format!("at least {low}{unit}"),
            (true, false, Low::Excluded) => format!("above {low}{unit}"),
            (false, true, _) => format!("at most {high}{unit}"),
            (true, true, Low::Included) => format!("from {low} to {high}{unit}"),
            (true, true, Low::Excluded) => format!("above {low} and at most {high}{unit}"),
        }
    }

    /// Any finite number.
    pub const FINITE: Limit = Limit::closed(f64::NEG_INFINITY, f64::INFINITY, "");
    /// A finite number above 0.
    pub const POSITIVE: Limit = Limit::above(0.0, f64::INFINITY, "");
    /// A finite number of at least 0.
    pub const NON_NEGATIVE: Limit = Limit::closed(0.0, f64::INFINITY, "");
}

/// The allowed range of a whole number (a count): from `low` to `high`, both included.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CountLimit {
    /// The low end.
    pub low: usize,
    /// The high end.
    pub high: usize,
}

impl CountLimit {
    /// `low ≤ value ≤ high`.
    pub const fn new(low: usize, high: usize) -> CountLimit {
        CountLimit { low, high }
    }

    /// `value` allowed, or the one-line error naming `key`.
    pub fn check(&self, key: &str, value: usize) -> Result<(), OutOfRange> {
        if (self.low..=self.high).contains(&value) {
            Ok(())
        } else {
            Err(OutOfRange {
                key: key.to_string(),
                value: value.to_string(),
                allowed: format!("a whole number {}", self.describe()),
            })
        }
    }

    /// `from 0 to 10`.
    pub fn describe(&self) -> String {
        format!("from {} to {}", self.low, self.high)
    }
}

/// A number for a one-line message: plain decimals, an exponent for very large or small ones
/// (`1e300`, not three hundred digits).
pub fn display_number(v: f64) -> String {
    if v.is_finite() && v != 0.0 && !(1e-6..1e15).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_nan_and_infinities() {
        let closed = Limit::closed(0.0, 10.0, "K");
        let above = Limit::above(0.0, 10.0, "mm");
        for (v, c, a) in [
            (0.0, true, false),
            (10.0, true, true),
            (5.0, true, true),
            (-1e-300, false, false),
            (10.000001, false, false),
            (f64::NAN, false, false),
            (f64::INFINITY, false, false),
            (f64::NEG_INFINITY, false, false),
        ] {
            assert_eq!(closed.contains(v), c, "{v}");
            assert_eq!(above.contains(v), a, "{v}");
        }
    }

    #[test]
    fn messages_name_the_key_the_value_and_the_range() {
        let e = Limit::closed(1.0, 86_400.0, "s")
            .check("match.study_step_s", f64::NAN)
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "match.study_step_s = NaN is out of range: it must be a finite number from 1 to 86400 s"
        );
        let e = Limit::above(0.0, 1e6, "nm")
            .check("bar[0] (\"B02\"): resolution_nm", 1e300)
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "bar[0] (\"B02\"): resolution_nm = 1e300 is out of range: it must be a finite number above 0 and at most 1000000 nm"
        );
        let e = Limit::POSITIVE.check("noise_um", -1.0).unwrap_err();
        assert_eq!(
            e.to_string(),
            "noise_um = -1 is out of range: it must be a finite number above 0"
        );
        let e = Limit::FINITE.check("seed_offset", f64::NAN).unwrap_err();
        assert_eq!(
            e.to_string(),
            "seed_offset = NaN is out of range: it must be a finite number"
        );
        let e = CountLimit::new(1, 10)
            .check("diagnose.beam", 0)
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "diagnose.beam = 0 is out of range: it must be a whole number from 1 to 10"
        );
    }
}
