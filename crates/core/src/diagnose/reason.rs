//! Why a candidate got its verdict, as the numbers the verdict rests on (the words are the
//! application's: `src/narrative/diagnosis.rs`).

use crate::model::Effect;

/// Why a candidate got its [`Verdict`](super::Verdict): which rule decided, with every number
/// it compared. Shares and counts are the rule's constants at the time of the decision.
#[derive(Debug, Clone, PartialEq)]
pub enum Reason {
    /// Not refitted: the linearised refit removes less than `share` of the materiality
    /// threshold; it would move the model's own terms by at least that much, but the shift does
    /// not count (`channel_term`: a generic channel term, which counts only for what it removes;
    /// otherwise its score test does not find the term or it leaves no trace in the fit).
    ScreenedOutShiftIgnored {
        /// Fleet RMS the linearised refit removes, µm.
        gain_um: f64,
        /// The share of the threshold a screened change must reach (`SCREEN_SHARE`).
        share: f64,
        /// The materiality threshold, µm.
        min_gain_um: f64,
        /// How much it would move the model's own terms, µm.
        shift_um: f64,
        /// The candidate is a generic channel term.
        channel_term: bool,
    },
    /// Not refitted: what the linearised refit removes and how much it moves the model's own
    /// terms are both below `share` of the materiality threshold.
    ScreenedOut {
        /// Fleet RMS the linearised refit removes, µm.
        gain_um: f64,
        /// How much it moves the model's own terms, µm.
        shift_um: f64,
        /// The share of the threshold a screened change must reach (`SCREEN_SHARE`).
        share: f64,
        /// The materiality threshold, µm.
        min_gain_um: f64,
    },
    /// Not refitted: `refitted` candidates of this step screened better, and only so many are
    /// refitted (the forward selection on the bars' coarse copies).
    RefitCap {
        /// How many candidates a step refits.
        refitted: usize,
        /// Fleet RMS it removes as screened, µm.
        gain_um: f64,
    },
    /// Not refitted: it removes less than `share` of what the best-screened candidate removes.
    BelowRivalShare {
        /// Fleet RMS it removes as screened, µm.
        gain_um: f64,
        /// The share of the best's gain a rival must reach (`RIVAL_SHARE`).
        share: f64,
        /// The best-screened candidate.
        best: Option<Effect>,
        /// Fleet RMS the best removes as screened, µm.
        best_um: f64,
    },
    /// Not refitted on the readings: refitted on the bars' 300-s coarse copies it comes close
    /// to the best candidate, but `rivals` candidates that remove more (or as much, with a
    /// name) are refitted exactly first.
    CoarseBehindRivals {
        /// Fleet RSS it removes on the coarse copies, µm².
        removed_um2: f64,
        /// That RSS as a fleet RMS, µm.
        removed_rms_um: f64,
        /// The best candidate on the coarse copies.
        best: Effect,
        /// Fleet RSS the best removes there, µm².
        best_um2: f64,
        /// How many candidates are refitted exactly (`MAX_EXACT_RIVALS`).
        rivals: usize,
    },
    /// Not refitted on the readings: refitted on the bars' 300-s coarse copies it removes less
    /// than `share` of what the best candidate removes there.
    CoarseBelowShare {
        /// Fleet RSS it removes on the coarse copies, µm².
        removed_um2: f64,
        /// That RSS as a fleet RMS, µm.
        removed_rms_um: f64,
        /// The share of the best's a rival must reach (`COARSE_RIVAL_SHARE`).
        share: f64,
        /// The best candidate on the coarse copies.
        best: Effect,
        /// Fleet RSS the best removes there, µm².
        best_um2: f64,
    },
    /// Significant and material.
    Proposed {
        /// Fleet p-value.
        p_value: f64,
        /// The test's threshold (the family-wise level over the step's candidates).
        threshold: f64,
        /// Fleet RMS it removes, µm.
        gain_um: f64,
        /// How much it moves the model's own terms, µm.
        shift_um: f64,
        /// The materiality threshold, µm.
        min_gain_um: f64,
    },
    /// Significant, but it removes less than the materiality threshold and its shift, though
    /// past the threshold, does not count: a generic channel term counts only for what it
    /// removes.
    ImmaterialShiftIgnored {
        /// Fleet p-value.
        p_value: f64,
        /// Fleet RMS it removes, µm.
        gain_um: f64,
        /// The materiality threshold, µm.
        min_gain_um: f64,
        /// How much it would move the model's own terms, µm.
        shift_um: f64,
    },
    /// Significant, but what it removes and how much it moves the model are below the
    /// materiality threshold.
    Immaterial {
        /// Fleet p-value.
        p_value: f64,
        /// Fleet RMS it removes, µm.
        gain_um: f64,
        /// How much it moves the model's own terms, µm.
        shift_um: f64,
        /// The materiality threshold, µm.
        min_gain_um: f64,
    },
    /// Fitted on no bar: every bar's screen or refit failed; `error` is the first bar's.
    NotFittedOnAnyBar {
        /// How many bars tried it.
        bars: usize,
        /// The first bar.
        first_bar: String,
        /// Why it failed there.
        error: super::CandidateError,
    },
    /// Refitted exactly, not significant.
    NotSignificant {
        /// Fleet p-value.
        p_value: f64,
        /// The test's threshold.
        threshold: f64,
        /// Fleet-wide ΔBIC of adding it.
        delta_bic: f64,
    },
}
