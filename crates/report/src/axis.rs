//! Axis ranges, tick positions and tick labels, computed here rather than by plotters so every
//! figure gets the same padding, "nice" steps, log decades and category labels.

use super::data::finite_minmax;

/// How tick values become label text.
#[derive(Debug, Clone)]
pub(crate) enum TickLabels {
    /// Fixed-point with `decimals` digits (scientific beyond 1e6).
    Numeric { decimals: usize },
    /// Log axis: ticks are log10 values, labels show the value itself.
    Log,
    /// Category axis: tick `i` is labelled `names[i]` (or `names[n-1-i]` when reversed).
    Categories { names: Vec<String>, reversed: bool },
    /// No labels at all (e.g. the colour bar's unused axis).
    Hidden,
}

/// One axis of a panel, in plot coordinates (log10 of the value on a log axis).
#[derive(Debug, Clone)]
pub(crate) struct Axis {
    pub(crate) lo: f64,
    pub(crate) hi: f64,
    pub(crate) ticks: Vec<f64>,
    pub(crate) minor: Vec<f64>,
    pub(crate) labels: TickLabels,
    pub(crate) desc: String,
}

impl Axis {
    /// A linear axis covering `values` (non-finite skipped) with 4 % padding, optionally
    /// forced to include zero; `target` is the wanted number of ticks.
    pub(crate) fn linear<I: IntoIterator<Item = f64>>(
        values: I,
        include_zero: bool,
        target: usize,
        desc: &str,
    ) -> Self {
        let (lo, hi) = finite_minmax(values).unwrap_or((0.0, 1.0));
        let (lo, hi) = if include_zero {
            (lo.min(0.0), hi.max(0.0))
        } else {
            (lo, hi)
        };
        let (lo, hi) = pad_range(lo, hi);
        let pad = 0.04 * (hi - lo);
        let lo = if include_zero && lo >= 0.0 {
            lo
        } else {
            lo - pad
        };
        let hi = if include_zero && hi <= 0.0 {
            hi
        } else {
            hi + pad
        };
        Self::fixed(lo, hi, target, desc)
    }

    /// A linear axis over exactly `[lo, hi]` (degenerate ranges padded).
    pub(crate) fn fixed(lo: f64, hi: f64, target: usize, desc: &str) -> Self {
        let (lo, hi) = pad_range(lo, hi);
        let step = nice_step((hi - lo) / target.max(2) as f64);
        let ticks = steps_between(lo, hi, step);
        let minor = steps_between(lo, hi, step / 2.0);
        let decimals = decimals_for(step);
        Self {
            lo,
            hi,
            ticks,
            minor,
            labels: TickLabels::Numeric { decimals },
            desc: desc.to_string(),
        }
    }

    /// A time axis over `secs` (seconds since campaign start, non-finite skipped), shown in the
    /// unit that suits the span.
    pub(crate) fn time<I: IntoIterator<Item = f64>>(secs: I, target: usize) -> (Self, TimeUnit) {
        let (lo, hi) = finite_minmax(secs).unwrap_or((0.0, 3600.0));
        let unit = TimeUnit::for_span(hi - lo);
        let desc = format!("time since campaign start ({})", unit.symbol());
        (
            Self::fixed(lo / unit.seconds(), hi / unit.seconds(), target, &desc),
            unit,
        )
    }

    /// The same axis without its description (for panels stacked above the one that has it).
    pub(crate) fn without_desc(&self) -> Self {
        Self {
            desc: String::new(),
            ..self.clone()
        }
    }

    /// A log10 axis covering the positive finite `values`, ticks at 1-2-5 × decades.
    pub(crate) fn log<I: IntoIterator<Item = f64>>(values: I, desc: &str) -> Self {
        let logs = values.into_iter().filter(|v| *v > 0.0).map(f64::log10);
        let (lo, hi) = finite_minmax(logs).unwrap_or((-1.0, 1.0));
        let (lo, hi) = if hi - lo < 0.3 {
            ((lo + hi) / 2.0 - 0.3, (lo + hi) / 2.0 + 0.3)
        } else {
            (lo, hi)
        };
        let (lo, hi) = (lo - 0.04 * (hi - lo), hi + 0.04 * (hi - lo));
        let (ticks, minor) = log_ticks(lo, hi);
        Self {
            lo,
            hi,
            ticks,
            minor,
            labels: TickLabels::Log,
            desc: desc.to_string(),
        }
    }

    /// A category axis: category `i` sits at `i` (or `n-1-i` when `reversed`, so the first
    /// category is at the top of a vertical axis).
    pub(crate) fn categories(names: &[String], reversed: bool, desc: &str) -> Self {
        let n = names.len().max(1);
        let ticks = (0..names.len()).map(|i| i as f64).collect();
        let labels = TickLabels::Categories {
            names: names.to_vec(),
            reversed,
        };
        Self {
            lo: -0.5,
            hi: n as f64 - 0.5,
            ticks,
            minor: Vec::new(),
            labels,
            desc: desc.to_string(),
        }
    }

    /// An axis over `[lo, hi]` without ticks or labels.
    pub(crate) fn hidden(lo: f64, hi: f64) -> Self {
        let labels = TickLabels::Hidden;
        Self {
            lo,
            hi,
            ticks: Vec::new(),
            minor: Vec::new(),
            labels,
            desc: String::new(),
        }
    }

    /// Whether values go through log10 before plotting.
    pub(crate) fn is_log(&self) -> bool {
        matches!(self.labels, TickLabels::Log)
    }

    /// Whether this is a category axis.
    pub(crate) fn is_categorical(&self) -> bool {
        matches!(self.labels, TickLabels::Categories { .. })
    }

    /// Plot coordinate of category `i` (`i` itself unless reversed).
    pub(crate) fn category(&self, i: usize) -> f64 {
        match &self.labels {
            TickLabels::Categories {
                names,
                reversed: true,
            } => (names.len().max(1) - 1 - i.min(names.len().max(1) - 1)) as f64,
            _ => i as f64,
        }
    }

    /// A data value in plot coordinates; `None` for NaN/inf or non-positive on a log axis.
    pub(crate) fn map(&self, v: f64) -> Option<f64> {
        let p = if self.is_log() {
            if v > 0.0 {
                v.log10()
            } else {
                f64::NAN
            }
        } else {
            v
        };
        p.is_finite().then_some(p)
    }

    /// The label of the tick at plot coordinate `v`.
    pub(crate) fn label(&self, v: f64) -> String {
        match &self.labels {
            TickLabels::Numeric { decimals } => format_fixed(v, *decimals),
            TickLabels::Log => format_significant(10f64.powf(v)),
            TickLabels::Categories { names, reversed } => category_label(names, *reversed, v),
            TickLabels::Hidden => String::new(),
        }
    }

    /// All tick labels, for measuring label areas.
    pub(crate) fn tick_labels(&self) -> Vec<String> {
        self.ticks.iter().map(|t| self.label(*t)).collect()
    }
}

/// The name at category position `v`.
fn category_label(names: &[String], reversed: bool, v: f64) -> String {
    let r = v.round();
    if (v - r).abs() > 1e-6 || r < 0.0 || r as usize >= names.len() {
        return String::new();
    }
    let i = if reversed {
        names.len() - 1 - r as usize
    } else {
        r as usize
    };
    names[i].clone()
}

/// Widens a degenerate or inverted range so it can be drawn.
pub(crate) fn pad_range(lo: f64, hi: f64) -> (f64, f64) {
    let (lo, hi) = if lo.is_finite() && hi.is_finite() {
        (lo.min(hi), lo.max(hi))
    } else {
        (0.0, 1.0)
    };
    if hi - lo > 1e-12 * lo.abs().max(hi.abs()).max(1e-300) {
        return (lo, hi);
    }
    let half = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
    (lo - half, hi + half)
}

/// The 1-2-2.5-5 × 10^k step nearest above `raw`.
pub(crate) fn nice_step(raw: f64) -> f64 {
    if !(raw.is_finite() && raw > 0.0) {
        return 1.0;
    }
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    let nice = [1.0, 2.0, 2.5, 5.0, 10.0]
        .into_iter()
        .find(|m| *m >= f - 1e-9)
        .unwrap_or(10.0);
    nice * mag
}

/// Multiples of `step` inside `[lo, hi]` (at most a few hundred).
fn steps_between(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    if last < first || last - first > 400 {
        return Vec::new();
    }
    (first..=last).map(|k| k as f64 * step).collect()
}

/// Log ticks: decades (plus 2 and 5 when the range spans few decades), minor at 1..9.
fn log_ticks(lo: f64, hi: f64) -> (Vec<f64>, Vec<f64>) {
    let (d0, d1) = (lo.floor() as i32, hi.ceil() as i32);
    let mults: &[f64] = if hi - lo > 4.0 {
        &[1.0]
    } else if hi - lo > 1.5 {
        &[1.0, 3.0]
    } else {
        &[1.0, 2.0, 5.0]
    };
    let inside = |v: f64| v >= lo && v <= hi;
    let mut ticks = Vec::new();
    let mut minor = Vec::new();
    for d in d0..=d1 {
        for m in 1..10 {
            let v = (f64::from(m) * 10f64.powi(d)).log10();
            if inside(v) {
                minor.push(v);
                if mults.contains(&f64::from(m)) {
                    ticks.push(v);
                }
            }
        }
    }
    (ticks, minor)
}

/// Digits after the point needed to tell ticks `step` apart.
fn decimals_for(step: f64) -> usize {
    let d = -(step.log10() + 1e-9).floor();
    let extra = usize::from(d >= 0.0 && (step / 10f64.powf(-d) - 2.5).abs() < 1e-6);
    (d.max(0.0) as usize + extra).min(9)
}

/// Fixed-point text with a typographic minus and without "-0"; scientific for very large
/// magnitudes.
pub(crate) fn format_fixed(v: f64, decimals: usize) -> String {
    if v.abs() >= 1e6 {
        return format!("{v:.1e}");
    }
    let s = format!("{v:.decimals$}");
    match s.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_string(),
        Some(rest) => format!("−{rest}"),
        None => s,
    }
}

/// A value with about three significant digits, trailing zeros trimmed.
pub(crate) fn format_significant(v: f64) -> String {
    if !v.is_finite() {
        return "–".to_string();
    }
    if v == 0.0 {
        return "0".to_string();
    }
    let decimals = (2.0 - v.abs().log10().floor()).clamp(0.0, 9.0) as usize;
    let s = format_fixed(v, decimals);
    if s.contains('.') && !s.contains('e') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// Time unit for an axis in seconds since campaign start, chosen from the span shown.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum TimeUnit {
    Minutes,
    Hours,
    Days,
}

impl TimeUnit {
    /// Minutes up to 3 h, hours up to 3 days, days beyond.
    pub(crate) fn for_span(span_s: f64) -> Self {
        if span_s <= 3.0 * 3600.0 {
            Self::Minutes
        } else if span_s <= 3.0 * 86_400.0 {
            Self::Hours
        } else {
            Self::Days
        }
    }

    /// Seconds per unit.
    pub(crate) fn seconds(self) -> f64 {
        match self {
            Self::Minutes => 60.0,
            Self::Hours => 3600.0,
            Self::Days => 86_400.0,
        }
    }

    /// Unit symbol for axis labels.
    pub(crate) fn symbol(self) -> &'static str {
        match self {
            Self::Minutes => "min",
            Self::Hours => "h",
            Self::Days => "d",
        }
    }

    /// `secs` converted to this unit.
    pub(crate) fn convert(self, secs: &[f64]) -> Vec<f64> {
        secs.iter().map(|s| s / self.seconds()).collect()
    }
}
