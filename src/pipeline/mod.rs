//! Staged jobs. A pipeline TOML names the stages and the model; [`RunPlan`] is its validated
//! form, checked before any heavy IO (`plan`). [`analyse`] runs the stages in order (`run`),
//! each as one call of its entry point in core with its options from the plan, into
//! [`RunResults`] (`results`): plain data types the outputs (`crate::output`) turn into files.
//!
//! Data flow: ingest (`io`) -> series -> identify (per bar, in parallel) -> match -> diagnose ->
//! calibrate -> compensate -> acceptance -> outputs (JSON, parquet, figures, the page).

mod device;
mod file;
mod plan;
mod results;
mod run;

pub(crate) use device::hexapod_of;
pub use device::{run_device, DeviceStage};
pub use file::*;
pub use plan::*;
pub use results::*;
pub use run::*;

#[cfg(test)]
mod plan_tests;
