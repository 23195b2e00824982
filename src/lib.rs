//! dbbcal: batch analysis of double-ballbar thermal campaigns. See ARCHITECTURE.md.
pub mod acceptance;
pub mod calibrate;
pub mod campaign;
pub mod compensate;
pub mod diagnose;
pub mod figures;
pub mod fit;
pub mod identify;
pub mod io;
pub mod matching;
pub mod model;
pub mod pipeline;
pub mod progress;
pub mod report;
pub mod runner;
pub mod series;
pub mod simulate;
