//! The one integration-test binary (each extra one would link polars again).
//! Data-driven through small `check(...)` helpers in each module.

mod bad_input;
mod identify;
mod nist;
mod support;
