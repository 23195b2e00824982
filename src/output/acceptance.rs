//! `acceptance.json`'s bars and fleet: per working bar the errors before and after
//! compensation, the budget term by term with what each is made of, U (k = 2) and the
//! ISO 14253-1 decision (`acceptance::BarAcceptance`).

use serde::Serialize;

use crate::acceptance::{BarAcceptance, BudgetTerm, ErrorStats, FleetAcceptance};
use crate::narrative::acceptance::budget_note;

/// One working bar's acceptance on one known length (its error series left out).
#[derive(Debug, Serialize)]
pub(crate) struct BarAcceptanceRecord<'a> {
    pub(crate) bar: &'a str,
    pub(crate) length_id: &'a str,
    pub(crate) length_mm: f64,
    pub(crate) mode: String,
    pub(crate) references: &'a [String],
    pub(crate) n_samples: usize,
    pub(crate) max_abs_error_um: f64,
    pub(crate) pv_um: f64,
    pub(crate) rms_um: f64,
    pub(crate) before: ErrorStatsRecord,
    pub(crate) budget: Vec<BudgetTermRecord>,
    pub(crate) u_c_um: f64,
    pub(crate) u_k2_um: f64,
    pub(crate) tolerance_um: f64,
    /// `pass`, `fail` or `no decision`.
    pub(crate) decision: &'static str,
}

impl<'a> From<&'a BarAcceptance> for BarAcceptanceRecord<'a> {
    fn from(a: &'a BarAcceptance) -> Self {
        BarAcceptanceRecord {
            bar: &a.bar,
            length_id: &a.length_id,
            length_mm: a.length_mm,
            mode: a.mode.name(),
            references: &a.references,
            n_samples: a.n_samples,
            max_abs_error_um: a.max_abs_error_um,
            pv_um: a.pv_um,
            rms_um: a.rms_um,
            before: ErrorStatsRecord::from(&a.before),
            budget: a.budget.iter().map(BudgetTermRecord::from).collect(),
            u_c_um: a.u_c_um,
            u_k2_um: a.u_k2_um,
            tolerance_um: a.tolerance_um,
            decision: a.decision.as_str(),
        }
    }
}

/// Max |e|, peak-to-valley and RMS of an error series, µm.
#[derive(Debug, Serialize)]
pub(crate) struct ErrorStatsRecord {
    pub(crate) max_abs_um: f64,
    pub(crate) pv_um: f64,
    pub(crate) rms_um: f64,
}

impl From<&ErrorStats> for ErrorStatsRecord {
    fn from(s: &ErrorStats) -> Self {
        ErrorStatsRecord {
            max_abs_um: s.max_abs_um,
            pv_um: s.pv_um,
            rms_um: s.rms_um,
        }
    }
}

/// One term of the budget: its name, standard uncertainty (k = 1, µm) and what it is made of.
#[derive(Debug, Serialize)]
pub(crate) struct BudgetTermRecord {
    pub(crate) name: &'static str,
    pub(crate) u_um: f64,
    pub(crate) note: String,
}

impl From<&BudgetTerm> for BudgetTermRecord {
    fn from(t: &BudgetTerm) -> Self {
        BudgetTermRecord {
            name: t.source.name(),
            u_um: t.u_um,
            note: budget_note(&t.source),
        }
    }
}

/// The fleet's acceptance at a glance.
#[derive(Debug, Serialize)]
pub(crate) struct FleetAcceptanceRecord {
    pub(crate) n_bars: usize,
    pub(crate) n_pass: usize,
    pub(crate) n_fail: usize,
    pub(crate) n_no_decision: usize,
    pub(crate) max_abs_error_um: f64,
    pub(crate) max_abs_error_before_um: f64,
    pub(crate) rms_um: f64,
    pub(crate) rms_before_um: f64,
    pub(crate) max_u_k2_um: f64,
    /// Every compensation mode that ran, by name.
    pub(crate) modes: Vec<String>,
}

impl From<&FleetAcceptance> for FleetAcceptanceRecord {
    fn from(f: &FleetAcceptance) -> Self {
        FleetAcceptanceRecord {
            n_bars: f.n_bars,
            n_pass: f.n_pass,
            n_fail: f.n_fail,
            n_no_decision: f.n_no_decision,
            max_abs_error_um: f.max_abs_error_um,
            max_abs_error_before_um: f.max_abs_error_before_um,
            rms_um: f.rms_um,
            rms_before_um: f.rms_before_um,
            max_u_k2_um: f.max_u_k2_um,
            modes: f.modes.iter().map(|m| m.name()).collect(),
        }
    }
}
