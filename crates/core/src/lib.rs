//! dbbcal-core: the analysis of a double-ballbar campaign, from plain typed series to results.
//!
//! The campaign's description ([`campaign`]), the bars' series ([`series`]), the thermal model
//! and its terms ([`model`]), the one fitting engine ([`fit`]), and the stages built on them:
//! [`identify`], [`matching`], [`diagnose`], [`calibrate`], [`compensate`], [`acceptance`].
//! Each stage has one entry point over the fleet, plain options in and one result out
//! ([`identify::identify_fleet`], [`matching::match_fleet`], [`diagnose::diagnose_fleet`],
//! [`calibrate::calibrate_fleet`], [`compensate::compensate_fleet`],
//! [`acceptance::accept_fleet`]); a per-bar stage returns a [`stage::StageOutcome`].
//! The `axis` machine kind's declared manifest and reader rules are in [`axis_campaign`].
//!
//! INVARIANT: no parquet/arrow, no plotters, no file IO, no file format (no serde, no TOML:
//! `dbbcal-io` parses and writes `campaign.toml`, the application writes every output record)
//! and no sentence for users (results are numbers and enums; the application's `narrative` words
//! them; error messages are the errors' own). Held by this crate's dependencies, its
//! `clippy.toml` (no `std::fs`) and `tests/e2e/architecture.rs` (its own dependencies and code).
//! Ingest (`dbbcal-io`) gives this crate [`series::CampaignLogs`]; the application writes what
//! it returns. See ARCHITECTURE.md.
pub mod acceptance;
pub mod axis_campaign;
pub mod calibrate;
pub mod campaign;
pub mod compensate;
pub mod diagnose;
pub mod fit;
pub mod identify;
pub mod limits;
pub mod matching;
pub mod model;
pub mod positions;
pub mod probe_campaign;
pub mod roll_campaign;
pub mod series;
pub mod signal;
pub mod stage;
pub mod volumetric_campaign;
