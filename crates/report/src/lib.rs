//! Figures as PNG files. This is the only module that knows about pixels, and it knows nothing
//! of the fitting: each figure is a plain spec struct ([`BarFitFigure`], [`FleetFigure`], ...)
//! filled by the pipeline and drawn by its `render_*` function.
//!
//! Conventions: times are seconds since campaign start (shown in minutes, hours or days
//! depending on the span), lengths in µm, NaN values are skipped, degenerate ranges are
//! padded, and the same spec always gives the same bytes. Text uses the embedded DejaVu Sans
//! (see `font.rs`), so no system font is needed. Every figure is a 1600×1000 PNG; give paths
//! ending in `.png` (the encoder is chosen from the extension). Missing parent directories are
//! created. Inconsistent specs (arrays whose lengths must match, indices out of range) are
//! rejected with [`ReportError::InvalidSpec`]; empty or all-NaN data draw a "no data" note.

mod axis;
mod bar_fit;
mod before_after;
mod canvas;
mod data;
mod error_grid;
mod fleet;
mod font;
mod geometry;
mod heatmap;
mod ledger;
mod legend;
mod panel;
mod polar;
mod residuals;
mod series_panels;
mod style;
#[cfg(test)]
mod tests;

use std::path::PathBuf;

pub use bar_fit::{render_bar_fit, BarFitFigure};
pub use before_after::{render_before_after, BeforeAfterFigure};
pub use error_grid::{render_error_grid, BandedSeries, ErrorGridFigure, ErrorPanel};
pub use fleet::{render_fleet, FleetFigure, ParameterPanel};
pub use geometry::{render_geometry, GeometryFigure, GeometryView};
pub use heatmap::{render_heat_map, HeatMapFigure, MatrixHighlight};
pub use ledger::{render_ledger, LedgerFigure};
pub use polar::{render_polar, PolarFigure, PolarSeries};
pub use residuals::{render_residual_diagnostics, ResidualDiagnosticsFigure};
pub use series_panels::{render_series_panels, SeriesPanel, SeriesPanelsFigure, XAxis};

/// A named line: `y[i]` at `x[i]` (same length; NaN values leave a gap).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct NamedSeries {
    /// Legend label.
    pub name: String,
    /// X values.
    pub x: Vec<f64>,
    /// Y values, one per `x`.
    pub y: Vec<f64>,
}

/// Named values at the categories of a figure (e.g. one bar's RMS after each model step).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct NamedValues {
    /// Legend label.
    pub name: String,
    /// One value per category.
    pub values: Vec<f64>,
}

/// A horizontal reference line (tolerance, noise level, ...) with its legend label.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RefLine {
    /// Legend label.
    pub label: String,
    /// Its height, in the panel's y unit.
    pub value: f64,
}

/// Why a figure could not be written; every variant names the output file.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// The spec is structurally inconsistent (e.g. two arrays that must match in length).
    #[error("figure {path}: invalid spec: {reason}")]
    InvalidSpec {
        /// The figure's file.
        path: PathBuf,
        /// What is inconsistent.
        reason: SpecError,
    },
    /// The embedded font could not be registered (a build defect).
    #[error("figure {path}: the embedded font could not be registered")]
    Font {
        /// The figure's file.
        path: PathBuf,
    },
    /// The output directory could not be created.
    #[error("figure {path}: cannot create the output directory: {source}")]
    CreateDir {
        /// The figure's file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// The file could not be written.
    #[error("figure {path}: cannot write: {source}")]
    Write {
        /// The figure's file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// plotters failed while drawing or encoding the PNG.
    #[error("figure {path}: drawing failed: {message}")]
    Draw {
        /// The figure's file.
        path: PathBuf,
        /// plotters' message.
        message: String,
    },
}

/// What is inconsistent in a figure spec.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SpecError {
    /// Two arrays that must match in length do not.
    #[error("{what}: lengths differ ({a} vs {b})")]
    LengthsDiffer {
        /// The arrays, named (`time_s/measured_um`).
        what: String,
        /// The first one's length.
        a: usize,
        /// The second one's length.
        b: usize,
    },
    /// The fleet figure's reference is not one of its bars.
    #[error("reference index {index} out of range ({bars} bars)")]
    ReferenceOutOfRange {
        /// The index given.
        index: usize,
        /// How many bars the figure has.
        bars: usize,
    },
    /// A heat map's highlight is not a cell, row or column of the matrix.
    #[error("highlight '{label}' is outside the matrix")]
    HighlightOutside {
        /// The highlight's label.
        label: String,
    },
    /// A grid of panels without columns.
    #[error("columns must be at least 1")]
    NoColumns,
}

/// Checks that `a` and `b` have the same length, naming them in the error text.
fn same_len(what: &str, a: usize, b: usize) -> Result<(), SpecError> {
    if a == b {
        Ok(())
    } else {
        Err(SpecError::LengthsDiffer {
            what: what.to_string(),
            a,
            b,
        })
    }
}

/// Checks every series has as many x as y values.
fn check_series(what: &str, series: &[NamedSeries]) -> Result<(), SpecError> {
    series
        .iter()
        .try_for_each(|s| same_len(&format!("{what} '{}' x/y", s.name), s.x.len(), s.y.len()))
}

/// Runs a spec check and wraps its message with the output path.
fn validated(path: &std::path::Path, check: Result<(), SpecError>) -> Result<(), ReportError> {
    check.map_err(|reason| ReportError::InvalidSpec {
        path: path.to_path_buf(),
        reason,
    })
}
