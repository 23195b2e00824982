//! dbbcal: batch analysis of double-ballbar thermal campaigns. See ARCHITECTURE.md.
//!
//! This crate is the application: the pipeline file and its run plan ([`pipeline`]), the
//! commands ([`runner`]), every output file ([`output`]), the report page ([`narrative`]) and
//! the figures' data ([`figures`]). The analysis, the parquet IO, the plotting and the simulator
//! are the workspace's other crates, re-exported here under the module names the code and the
//! tests use (`dbbcal::fit` is `dbbcal_core::fit`, `dbbcal::io` is `dbbcal_io`, ...).
pub use dbbcal_core::probe_campaign;
pub use dbbcal_core::{
    acceptance, axis_campaign, calibrate, campaign, compensate, diagnose, fit, identify, matching,
    model, series,
};
pub use dbbcal_io as io;
pub use dbbcal_report as report;
pub use dbbcal_sim as simulate;
pub use dbbcal_supervise as supervise;

pub mod exit;
pub mod figures;
pub mod kinds;
pub mod narrative;
pub mod output;
pub mod pipeline;
pub mod progress;
pub mod runner;
