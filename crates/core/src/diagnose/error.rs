//! Why a candidate term could not be screened or fitted on one bar.

use crate::identify::IdentifyError;
use crate::model::{Effect, ModelError};

/// Why a candidate term could not be screened or refitted on one bar (each message one line).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CandidateError {
    /// The bar's model could not be linearised, so nothing is screened on it.
    #[error("the model could not be linearised on this bar")]
    NotLinearised,
    /// The term cannot be built for this bar (e.g. no events of its kind).
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The term is already in the model.
    #[error("{effect} adds no term to this model")]
    NoTerm {
        /// The candidate.
        effect: Effect,
    },
    /// The linearised refit cannot tell the term from the model's own.
    #[error("{effect} cannot be separated from the model")]
    NotSeparable {
        /// The candidate.
        effect: Effect,
    },
    /// The refit failed.
    #[error(transparent)]
    Refit(#[from] IdentifyError),
    /// A new parameter of the refit and another correlate beyond
    /// `MAX_PARAM_CORRELATION` (0.9999): one combination the
    /// data cannot split.
    #[error("not identifiable on this bar: {first} and {second} correlate at {correlation:.4}")]
    NotIdentifiable {
        /// One parameter.
        first: String,
        /// The other.
        second: String,
        /// Their correlation.
        correlation: f64,
    },
    /// As [`CandidateError::NotIdentifiable`], on the bar's 300-s copy: the refit on the
    /// readings, which would start there, is not made.
    #[error(
        "not identifiable on this bar's 300-s copy: {first} and {second} correlate at {correlation:.4}"
    )]
    NotIdentifiableOnCopy {
        /// One parameter.
        first: String,
        /// The other.
        second: String,
        /// Their correlation.
        correlation: f64,
    },
}
