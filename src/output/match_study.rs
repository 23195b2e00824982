//! `match_study.json`: the measured mismatch matrix, the nearest-the-mean pick, the best
//! candidate and the excess (`matching::MatchStudy`).

use serde::Serialize;

use crate::matching::MatchStudy;

/// `match_study.json` (NaN entries of the matrix are written as `null`).
#[derive(Debug, Serialize)]
pub(crate) struct MatchStudyRecord<'a> {
    pub(crate) bars: &'a [String],
    pub(crate) matrix_um: &'a [Vec<f64>],
    pub(crate) worst_um: &'a [f64],
    pub(crate) nearest_mean: &'a str,
    pub(crate) best: &'a str,
    pub(crate) excess_um: f64,
}

impl<'a> From<&'a MatchStudy> for MatchStudyRecord<'a> {
    fn from(m: &'a MatchStudy) -> Self {
        MatchStudyRecord {
            bars: &m.bars,
            matrix_um: &m.matrix_um,
            worst_um: &m.worst_um,
            nearest_mean: &m.nearest_mean,
            best: &m.best,
            excess_um: m.excess_um,
        }
    }
}
