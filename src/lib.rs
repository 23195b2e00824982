//! dbbcal: batch analysis of double-ballbar thermal campaigns. See ARCHITECTURE.md.
pub mod campaign;
pub mod io;
pub mod fit;
pub mod identify;
pub mod model;
pub mod series;
pub mod simulate;
pub mod matching;
pub mod calibrate;
pub mod compensate;
pub mod acceptance;
pub mod pipeline;
pub mod progress;
pub mod report;
pub mod diagnose;
pub mod runner;
pub mod figures;
