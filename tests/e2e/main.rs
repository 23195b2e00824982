//! The one integration-test binary (each extra one would link parquet/arrow again).
//! Data-driven through small `check(...)` helpers in each module.

mod acceptance;
mod architecture;
mod axis_campaign;
mod axis_foreign;
mod bad_config;
mod bad_input;
mod base_noise;
mod cli;
mod corpus;
mod determinism;
mod device;
mod device_foreign;
mod diagnose;
mod docs;
mod false_alarms;
mod head_heating;
mod identify;
mod machine_tool;
mod nist;
mod one_length;
mod page;
mod probe;
mod probe_foreign;
mod roll;
mod roll_foreign;
mod row_order;
mod safe_outputs;
mod support;
mod tclab;
mod volumetric;
mod volumetric_bar;
mod volumetric_bar_foreign;
mod volumetric_foreign;
