//! `report.md`: the fit report in words, per bar in the manner of lmfit's `fit_report()` (n,
//! parameters, RMS, BIC, whiteness; value ± u with its relative size, the 95 % interval;
//! correlations above [`STRONG_CORRELATION`]; warnings in plain words).

use std::fmt::Write;

use super::Headline;
use crate::pipeline::{BarOutcome, RunPlan, RunResults};
use crate::series::min_bins_per_tau;

/// Correlations of parameters listed when |r| is above this (lmfit lists above 0.1 by default;
/// a metrologist reading for trouble wants the near-collinear pairs only).
pub(crate) const STRONG_CORRELATION: f64 = 0.9;
/// Fewer effective degrees of freedom than this in a parameter's HAC variance: its interval
/// rests on too few independent batches of residuals and is flagged.
pub(crate) const FEW_BATCHES_DOF: f64 = 10.0;

/// The whole report, Markdown.
pub(crate) fn fit_report(plan: &RunPlan, results: &RunResults, headline: &Headline) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# Fit report: campaign {}\n", results.campaign.id);
    let effects: Vec<String> = plan.effects.iter().map(|e| e.name()).collect();
    let _ = writeln!(
        md,
        "Pipeline `{}`; model `{}`; dbbcal {}.\n",
        plan.pipeline_name,
        effects.join(" + "),
        env!("CARGO_PKG_VERSION")
    );
    for (label, text) in headline.lines() {
        let _ = writeln!(md, "- **{label}**: {text}");
    }
    // The ledger, and why it differs from the ranking where it does: the page's words.
    if let Some(text) = results
        .diagnosis
        .as_ref()
        .and_then(|d| super::page::ledger_text(d, plan.bin_s))
    {
        let _ = writeln!(md, "- **Ledger**: {text}");
    }
    md.push('\n');
    let whiteness = |bar: &str| {
        results
            .diagnosis
            .as_ref()
            .and_then(|d| d.bars.iter().find(|b| b.bar == bar))
            .map(|b| b.whiteness_p)
    };
    for o in &results.bars {
        let quality = results
            .quality
            .bars
            .get(&o.model.bar)
            .and_then(quality_line);
        bar_section(&mut md, o, whiteness(&o.model.bar), plan.bin_s, quality);
    }
    if let Some(device) = super::device::markdown(results) {
        md.push_str(&device);
    }
    if !results.failed.is_empty() {
        let _ = writeln!(md, "## Failed bars\n");
        for f in &results.failed {
            let _ = writeln!(md, "- **{}**: {}", f.bar, super::quality::failure(f));
        }
        md.push('\n');
    }
    md
}

/// One bar: the fit statistics, the variables, strong correlations, warnings.
fn bar_section(
    md: &mut String,
    o: &BarOutcome,
    whiteness_p: Option<f64>,
    bin_s: f64,
    quality: Option<String>,
) {
    let m = &o.model;
    let _ = writeln!(md, "## Bar {}\n", m.bar);
    md.push_str("```text\n[[Fit statistics]]\n");
    let _ = writeln!(md, "    data points      = {}", m.n_samples);
    if bin_s > 0.0 {
        let _ = writeln!(
            md,
            "    compression      = {bin_s:.0}-s bins, two weighted nodes each (exact for a model straight within a bin)"
        );
    }
    let _ = writeln!(
        md,
        "    variables        = {} ({} physical parameters below)",
        m.n_params,
        m.params.len()
    );
    let _ = writeln!(md, "    RMS residual     = {:.4} µm", m.rms_um);
    let _ = writeln!(md, "    BIC              = {:.1}", m.bic);
    if let Some(p) = whiteness_p {
        let _ = writeln!(
            md,
            "    whiteness p      = {p:.3}{}",
            if p < 0.05 {
                "  (below 0.05: the residuals keep some structure)"
            } else {
                ""
            }
        );
    }
    md.push_str("[[Variables]]\n");
    let width = m.params.iter().map(|p| p.name.len()).max().unwrap_or(0);
    for p in &m.params {
        let rel = match 100.0 * p.u / p.value.abs() {
            r if !r.is_finite() => String::new(),
            r if r >= 1e3 => format!(" ({r:.1e} %)"),
            r => format!(" ({r:.2} %)"),
        };
        let (value, u) = value_and_uncertainty(p.value, p.u);
        let lo = value_and_uncertainty(p.ci95[0], p.u).0;
        let hi = value_and_uncertainty(p.ci95[1], p.u).0;
        let _ = writeln!(
            md,
            "    {:width$}  {value} ± {u}{rel}  95 %: [{lo}, {hi}]",
            p.name,
        );
    }
    let strong = strong_correlations(o);
    if !strong.is_empty() {
        let _ = writeln!(md, "[[Correlations]] (|r| > {STRONG_CORRELATION})");
        for (a, b, r) in &strong {
            let _ = writeln!(md, "    C({a}, {b}) = {r:+.3}");
        }
    }
    md.push_str("```\n\n");
    let warnings = warnings(o, bin_s);
    if !warnings.is_empty() || quality.is_some() {
        md.push_str("Warnings:\n\n");
        if let Some(q) = quality {
            let _ = writeln!(md, "- {q} (ranges in summary.json → quality)");
        }
        for w in warnings {
            let _ = writeln!(md, "- {}", w.sentence());
        }
        md.push('\n');
    }
}

/// `value` and `u` as a metrologist writes them (GUM 7.2.6): `u` to two significant digits,
/// `value` to the same decimal place; both with an exponent, to two significant digits, where
/// that place would round the value away or `u` reaches [`PLAIN_UNCERTAINTY_MAX`].
///
/// Why the exponent: a parameter the data do not determine (a time constant run to the model's
/// limit, 1e9 s, with u 3e12 s) was written `0 ± 3000000000000`, and its gain `-0 ± 63000000`:
/// the value read as zero where it is 1e9 and -2.1e4.
pub(crate) fn value_and_uncertainty(value: f64, u: f64) -> (String, String) {
    if !(u.is_finite() && u > 0.0 && value.is_finite()) {
        return (sig(value), sig(u));
    }
    let decimals = 1 - u.log10().floor() as i32;
    let scale = 10f64.powi(-decimals);
    if decimals < 0 && (u >= PLAIN_UNCERTAINTY_MAX || value.abs() < scale) {
        (format!("{value:.1e}"), format!("{u:.1e}"))
    } else if (0..=12).contains(&decimals) {
        let d = decimals as usize;
        (format!("{value:.d$}"), format!("{u:.d$}"))
    } else if decimals < 0 {
        let round = |v: f64| format!("{:.0}", (v / scale).round() * scale);
        (round(value), round(u))
    } else {
        (sig(value), sig(u))
    }
}

/// Uncertainties from this size on are written with an exponent ([`value_and_uncertainty`]).
const PLAIN_UNCERTAINTY_MAX: f64 = 1e6;

/// Four significant digits, plainly (no exponent between 1e-3 and 1e6).
fn sig(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let magnitude = v.abs().log10().floor() as i32;
    if (-3..6).contains(&magnitude) {
        let decimals = (3 - magnitude).max(0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.3e}")
    }
}

/// Parameter pairs with |r| above [`STRONG_CORRELATION`], strongest first.
pub(crate) fn strong_correlations(o: &BarOutcome) -> Vec<(String, String, f64)> {
    let m = &o.model;
    let mut pairs = Vec::new();
    for i in 0..m.params.len() {
        for j in i + 1..m.params.len() {
            let r = m.correlation.get(i).and_then(|row| row.get(j)).copied();
            if let Some(r) = r.filter(|r| r.abs() > STRONG_CORRELATION) {
                pairs.push((m.params[i].name.clone(), m.params[j].name.clone(), r));
            }
        }
    }
    pairs.sort_by(|a, b| b.2.abs().total_cmp(&a.2.abs()));
    pairs
}

/// Something a reader must know before using a bar's numbers.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Warning {
    /// The 95 % interval of a time constant ends at the search bound on `side`.
    Unbounded {
        param: String,
        side: &'static str,
        bound: f64,
    },
    /// The HAC variance rests on fewer than [`FEW_BATCHES_DOF`] effective degrees of freedom.
    FewBatches { param: String, dof: f64 },
    /// Parameters the bar's data cannot determine (left out of its fit).
    NotIdentifiable { params: Vec<String>, reason: String },
    /// A fitted time constant shorter than [`min_bins_per_tau`] compressed bins, interval and
    /// all (`series::too_short_for_bins`), where the compression was measured to move estimates
    /// by up to 0.25 u (`series::MIN_BINS_PER_TAU`, `series::LONG_BINS_MIN_PER_TAU`).
    CoarseBins {
        param: String,
        tau_s: f64,
        bin_s: f64,
    },
}

impl Warning {
    /// In plain words (the fit report).
    pub(crate) fn sentence(&self) -> String {
        match self {
            Warning::Unbounded { param, side, bound } => format!(
                "{param}: the data do not bound it {side}; its 95 % interval ends at the search bound ({})",
                duration(*bound)
            ),
            Warning::FewBatches { param, dof } => format!(
                "{param}: its uncertainty rests on few independent batches of residuals ({dof:.1} effective degrees of freedom); read the interval as rough"
            ),
            Warning::NotIdentifiable { params, reason } => format!(
                "not identifiable from this bar's data: {} ({reason})",
                params.join(", ")
            ),
            Warning::CoarseBins { param, tau_s, bin_s } => format!(
                "{param} = {tau_s:.0} s spans fewer than {} bins of {bin_s:.0} s, where the compression was measured to move estimates by up to a quarter of their uncertainty; rerun with --bin-s 0 (every reading) to be exact",
                min_bins_per_tau(*bin_s)
            ),
        }
    }
}

/// The bar's warnings; `bin_s`: the length of the compressed bins (0: every reading).
pub(crate) fn warnings(o: &BarOutcome, bin_s: f64) -> Vec<Warning> {
    let m = &o.model;
    let mut out = Vec::new();
    // A parameter the data cannot determine gets its one warning below, not these.
    let determined = |p: &&crate::identify::Estimate| !m.undetermined(&p.name);
    for p in m.params.iter().filter(determined) {
        if !p.name.starts_with("tau") {
            continue;
        }
        if crate::series::too_short_for_bins(p.value, p.ci95[1], bin_s) {
            out.push(Warning::CoarseBins {
                param: p.name.clone(),
                tau_s: p.value,
                bin_s,
            });
        }
    }
    for p in m.params.iter().filter(determined) {
        for (end, side) in [(0, "below"), (1, "above")] {
            if p.ci95_at_search_bound[end] {
                out.push(Warning::Unbounded {
                    param: p.name.clone(),
                    side,
                    bound: p.ci95[end],
                });
            }
        }
    }
    for (p, dof) in m.params.iter().zip(&m.dof) {
        if *dof < FEW_BATCHES_DOF && !m.undetermined(&p.name) {
            out.push(Warning::FewBatches {
                param: p.name.clone(),
                dof: *dof,
            });
        }
    }
    for n in &m.not_identifiable {
        out.push(Warning::NotIdentifiable {
            params: n.params.clone(),
            reason: super::model::not_identifiable_reason(&n.reason),
        });
    }
    out
}

/// The warnings as short tags (the page's table of bars), one per kind.
pub(crate) fn short_flags(warnings: &[Warning]) -> Vec<String> {
    let mut unbounded = Vec::new();
    let mut few = Vec::new();
    let mut flags = Vec::new();
    for w in warnings {
        match w {
            Warning::Unbounded { param, side, .. } => unbounded.push(format!("{param} ({side})")),
            Warning::FewBatches { param, .. } => few.push(param.clone()),
            Warning::NotIdentifiable { params, .. } => {
                flags.push(format!("not identifiable: {}", params.join(", ")))
            }
            Warning::CoarseBins { param, bin_s, .. } => flags.push(format!(
                "{param} < {} bins: rerun with --bin-s 0",
                min_bins_per_tau(*bin_s)
            )),
        }
    }
    if !unbounded.is_empty() {
        flags.insert(0, format!("at search bound: {}", unbounded.join(", ")));
    }
    if !few.is_empty() {
        flags.push(format!(
            "few batches (dof < {FEW_BATCHES_DOF}): {}",
            few.join(", ")
        ));
    }
    flags
}

/// A bar's data quality in one line (`summary.json` → `quality` has the ranges), if anything was
/// dropped or flagged.
pub(crate) fn quality_line(q: &crate::series::quality::ChannelQuality) -> Option<String> {
    let mut kinds: Vec<(String, usize)> = Vec::new();
    for f in &q.flags {
        let kind = crate::output::quality::flag_kind_word(f.kind()).to_string();
        match kinds.iter_mut().find(|(k, _)| *k == kind) {
            Some((_, n)) => *n += 1,
            None => kinds.push((kind, 1)),
        }
    }
    if q.dropped_rows == 0 && kinds.is_empty() {
        return None;
    }
    let flags: Vec<String> = kinds.iter().map(|(k, n)| format!("{k} ×{n}")).collect();
    Some(format!(
        "data: {} of {} readings dropped{}",
        q.dropped_rows,
        q.rows,
        if flags.is_empty() {
            String::new()
        } else {
            format!("; flagged {}", flags.join(", "))
        }
    ))
}

/// A duration in seconds as a person reads it.
fn duration(s: f64) -> String {
    if s >= 2.0 * 86_400.0 {
        format!("{:.0} days", s / 86_400.0)
    } else if s >= 2.0 * 3_600.0 {
        format!("{:.0} h", s / 3_600.0)
    } else {
        format!("{s:.0} s")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uncertainties_take_two_digits_and_values_follow() {
        assert_eq!(
            value_and_uncertainty(1.99412, 0.002089),
            ("1.9941".into(), "0.0021".into())
        );
        assert_eq!(
            value_and_uncertainty(3004.2, 15.08),
            ("3004".into(), "15".into())
        );
        assert_eq!(
            value_and_uncertainty(1661.0, 91.85),
            ("1661".into(), "92".into())
        );
        assert_eq!(
            value_and_uncertainty(123456.0, 1234.0),
            ("123500".into(), "1200".into())
        );
    }

    /// A value its uncertainty's second digit would round to zero, and an uncertainty of a
    /// million or more, are written with exponents (a base model's `beta` and `tau_S` bent to
    /// the model's limit: `-0 ± 63000000` and `0 ± 3000000000000` before).
    #[test]
    fn undetermined_values_keep_their_size() {
        assert_eq!(
            value_and_uncertainty(-20550.4, 62_506_304.0),
            ("-2.1e4".into(), "6.3e7".into())
        );
        assert_eq!(
            value_and_uncertainty(1e9, 3.04e12),
            ("1.0e9".into(), "3.0e12".into())
        );
        assert_eq!(
            value_and_uncertainty(4.0, 120.0),
            ("4.0e0".into(), "1.2e2".into())
        );
        assert_eq!(
            value_and_uncertainty(40.0, 120.0),
            ("40".into(), "120".into())
        );
        assert_eq!(
            value_and_uncertainty(3.0e6, 2.5e6),
            ("3.0e6".into(), "2.5e6".into())
        );
    }
}
