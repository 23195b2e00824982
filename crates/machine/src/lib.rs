//! dbbcal-machine: the pure math of the machine kinds (issue 29).
//!
//! Plain data in, plain data out: the linear least-squares engine with named identifiability
//! ([`linear`]), air refraction and laser normalisation ([`edlen`]), the ISO 230-2 evaluation
//! ([`iso230_2`]), the six errors of a linear axis from interferometer lines ([`axis`]), and the
//! hexapod device ([`pose`], [`hexapod`]).
//!
//! INVARIANT (enforced by this crate's dependencies and `tests/e2e/architecture.rs`): no file
//! IO, no polars, no plotters, no serialisation formats; the application owns those. The
//! formulas come from `docs/spec/machine-physics.md`, `docs/spec/machine-formats.md` and
//! `docs/spec/device-format.md`; each module says which section.
pub mod axis;
pub mod components;
pub mod edlen;
pub mod hexapod;
pub mod iso230_2;
pub mod linear;
pub mod pose;
pub mod pose_errors;
pub mod straightness;
