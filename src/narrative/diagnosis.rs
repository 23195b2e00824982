//! The diagnosis' verdicts in words: why each candidate was proposed, judged immaterial, not
//! significant or screened out (`diagnosis.json`'s `reason`, the page's candidate table).

use crate::diagnose::Reason;

/// Why a generic channel term's shift of the model's own terms does not count.
const CHANNEL_SHIFT: &str = "a channel term counts only for what it removes (traded against the \
     base paths, its gain moves them with hardly any change to the fit)";

/// Why a catalogue effect's screened shift does not count.
const NO_TRACE: &str = "its score test does not find the term or it leaves no trace in the fit \
     (a reparametrisation the data do not determine)";

/// The verdict's reason in one line, with the numbers it rests on.
pub fn reason(r: &Reason) -> String {
    match r {
        Reason::ScreenedOutShiftIgnored { .. }
        | Reason::ScreenedOut { .. }
        | Reason::RefitCap { .. }
        | Reason::BelowRivalShare { .. } => screened_out(r),
        Reason::CoarseBehindRivals { .. } | Reason::CoarseBelowShare { .. } => coarse(r),
        Reason::NotFittedOnAnyBar {
            bars,
            first_bar,
            error,
        } => format!("not fitted on any of the {bars} bars (on {first_bar}: {error})"),
        Reason::Proposed { .. }
        | Reason::ImmaterialShiftIgnored { .. }
        | Reason::Immaterial { .. }
        | Reason::NotSignificant { .. } => refitted(r),
    }
}

/// The reasons of a candidate the screen left out.
fn screened_out(r: &Reason) -> String {
    match r {
        Reason::ScreenedOutShiftIgnored {
            gain_um,
            share,
            min_gain_um,
            shift_um,
            channel_term,
        } => format!(
            "screened out: the linearised refit removes {} µm of the fleet RMS, below {share} of the materiality threshold {} µm; it would move the model's own terms by {} µm, but {}",
            um(*gain_um),
            um(*min_gain_um),
            um(*shift_um),
            if *channel_term { CHANNEL_SHIFT } else { NO_TRACE }
        ),
        Reason::ScreenedOut {
            gain_um,
            shift_um,
            share,
            min_gain_um,
        } => format!(
            "screened out: the linearised refit removes {} µm of the fleet RMS and moves the model's own terms by {} µm, both below {share} of the materiality threshold {} µm",
            um(*gain_um),
            um(*shift_um),
            um(*min_gain_um)
        ),
        Reason::RefitCap { refitted, gain_um } => format!(
            "screened out: {refitted} candidates of this step screened better and only so many are refitted here (the forward selection on the bars' coarse copies); the fleet RMS it removes is {} µm, screened",
            um(*gain_um)
        ),
        Reason::BelowRivalShare {
            gain_um,
            share,
            best,
            best_um,
        } => format!(
            "screened out: the fleet RMS it removes ({} µm, screened) is less than {share} of the best candidate's ({}, {} µm); if real it is found once that one is in the model",
            um(*gain_um),
            best.as_ref().map(|e| e.name()).unwrap_or_default(),
            um(*best_um)
        ),
        other => refitted(other),
    }
}

/// The reasons of a candidate the coarse copies' refits left out.
fn coarse(r: &Reason) -> String {
    let (removed_um2, removed_rms_um, why) = match r {
        Reason::CoarseBehindRivals {
            removed_um2,
            removed_rms_um,
            best,
            best_um2,
            rivals,
        } => (
            removed_um2,
            removed_rms_um,
            format!("close to the best candidate's ({best}, {} µm²), but {rivals} candidates that remove more (or as much, with a name) are refitted exactly first; if it is an alias of the one proposed, it is gone once that one is in the model", um(*best_um2)),
        ),
        Reason::CoarseBelowShare {
            removed_um2,
            removed_rms_um,
            share,
            best,
            best_um2,
        } => (
            removed_um2,
            removed_rms_um,
            format!("less than {share} of the best candidate's ({best}, {} µm²); if real it is found once that one is in the model", um(*best_um2)),
        ),
        other => return screened_out(other),
    };
    format!(
        "screened out: refitted on the bars' 300-s copies it removes {} µm² of the fleet RSS (an RMS of {} µm), {why}",
        um(*removed_um2),
        um(*removed_rms_um)
    )
}

/// The reasons of a candidate refitted exactly and tested.
fn refitted(r: &Reason) -> String {
    match r {
        Reason::Proposed {
            p_value,
            threshold,
            gain_um,
            shift_um,
            min_gain_um,
        } => format!(
            "significant (p = {p_value:.1e} < {threshold:.1e}) and material: removes {} µm of the fleet RMS and moves the model's own terms by {} µm (threshold {} µm)",
            um(*gain_um),
            um(*shift_um),
            um(*min_gain_um)
        ),
        Reason::ImmaterialShiftIgnored {
            p_value,
            gain_um,
            min_gain_um,
            shift_um,
        } => format!(
            "detectable but immaterial: significant (p = {p_value:.1e}), but it removes only {} µm of the fleet RMS, below the materiality threshold {} µm; it would move the model's own terms by {} µm, but {CHANNEL_SHIFT}",
            um(*gain_um),
            um(*min_gain_um),
            um(*shift_um)
        ),
        Reason::Immaterial {
            p_value,
            gain_um,
            shift_um,
            min_gain_um,
        } => format!(
            "detectable but immaterial: significant (p = {p_value:.1e}), but it removes only {} µm of the fleet RMS and moves the model's own terms by {} µm, below the materiality threshold {} µm",
            um(*gain_um),
            um(*shift_um),
            um(*min_gain_um)
        ),
        Reason::NotSignificant {
            p_value,
            threshold,
            delta_bic,
        } => format!(
            "not significant: p = {p_value:.1e} against {threshold:.1e} (5 % family-wise), ΔBIC {delta_bic:.1}"
        ),
        other => screened_out(other),
    }
}

/// A length in µm with four significant digits (a reason's numbers).
fn um(v: f64) -> String {
    format!("{v:.3e}")
        .parse::<f64>()
        .map_or_else(|_| format!("{v}"), |x| format!("{x}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Effect;

    #[test]
    fn reasons_quote_their_numbers() {
        assert_eq!(
            reason(&Reason::ScreenedOut {
                gain_um: 3.2114e-6,
                shift_um: 0.0012,
                share: 0.5,
                min_gain_um: 0.005
            }),
            "screened out: the linearised refit removes 0.000003211 µm of the fleet RMS and moves the model's own terms by 0.0012 µm, both below 0.5 of the materiality threshold 0.005 µm"
        );
        assert_eq!(
            reason(&Reason::NotSignificant {
                p_value: 0.31,
                threshold: 0.0025,
                delta_bic: 12.34
            }),
            "not significant: p = 3.1e-1 against 2.5e-3 (5 % family-wise), ΔBIC 12.3"
        );
        // A candidate every bar failed on says why, not that others screened better.
        assert_eq!(
            reason(&Reason::NotFittedOnAnyBar {
                bars: 10,
                first_bar: "F01".into(),
                error: crate::diagnose::CandidateError::NotIdentifiableOnCopy {
                    first: "settling_0_um".into(),
                    second: "settling_1_um".into(),
                    correlation: 1.0,
                },
            }),
            "not fitted on any of the 10 bars (on F01: not identifiable on this bar's 300-s copy: settling_0_um and settling_1_um correlate at 1.0000)"
        );
        let coarse = reason(&Reason::CoarseBelowShare {
            removed_um2: 1.0,
            removed_rms_um: 0.001,
            share: 0.5,
            best: Effect::HeadHeating,
            best_um2: 4.0,
        });
        assert!(
            coarse.starts_with("screened out: refitted on the bars' 300-s copies it removes 1 µm² of the fleet RSS (an RMS of 0.001 µm), less than 0.5 of the best candidate's (head_heating, 4 µm²)"),
            "{coarse}"
        );
        let channel = reason(&Reason::ImmaterialShiftIgnored {
            p_value: 1e-5,
            gain_um: 0.0001,
            min_gain_um: 0.005,
            shift_um: 0.08,
        });
        assert!(channel.ends_with(CHANNEL_SHIFT), "{channel}");
        assert!(CHANNEL_SHIFT.contains("against the base paths"));
    }
}
