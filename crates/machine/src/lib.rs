//! dbbcal-machine: the pure math of the machine kinds (issue 29).
//!
//! Plain data in, plain data out:
//! - [`linear`]: the linear least-squares engine, with the rank and what is lost named;
//! - [`edlen`]: air refraction (modified Edlén) and laser-reading normalisation;
//! - [`iso230_2`]: the ISO 230-2 evaluation (A, B, R, E, M);
//! - [`components`]: the six component errors of a linear axis and their ISO 230-1 names;
//! - [`axis`]: kind `axis`, the six errors at a target from interferometer channels;
//! - [`axis_study`]: an `axis` campaign analysed: all runs at once, ISO 230-2, straightness,
//!   and the loop (candidates, ledger, what the readings cannot see);
//! - [`pose`], [`hexapod`], [`pose_errors`]: the hexapod device, its kinematics, and the
//!   errors of the machine under test from its poses, with their uncertainty;
//! - [`probe`]: kind `probe`, touch-trigger probe touches on a ring or sphere (seed 003);
//! - [`straightness`]: straightness raw and without its least-squares line;
//! - [`device_test`]: a hexapod axis test on plain data, dwell by dwell (pose, errors, U).
//! - [`warm_up`]: a machine warming up, the drift levelling off (device and axis loops).
//!
//! INVARIANT: no file IO, no parquet/arrow, no plotters, no serialisation formats; the
//! application owns those. Held by this crate's dependencies, its `clippy.toml` (no `std::fs`)
//! and `tests/e2e/architecture.rs` (its closure, its own dependencies and code). The
//! formulas come from `docs/spec/machine-physics.md`, `docs/spec/machine-formats.md` and
//! `docs/spec/device-format.md`; each module says which section.
pub mod axis;
pub mod axis_study;
pub mod components;
pub mod device_study;
pub mod device_test;
pub mod edlen;
pub mod hexapod;
pub mod iso230_2;
pub mod linear;
pub mod pose;
pub mod pose_errors;
pub mod probe;
pub mod roll;
pub mod straightness;
pub mod volumetric;
pub mod warm_up;
