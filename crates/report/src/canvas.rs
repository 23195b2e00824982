//! Opening a PNG canvas, the figure header (title and subtitle lines), free text, and the
//! mapping of plotters' errors into [`ReportError`].

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::style::{self, SUBTITLE_PX, TEXT, TITLE_PX};
use super::{font, ReportError};

/// A rectangular region of the bitmap, in pixels relative to its top-left corner.
pub(crate) type Area<'b> = DrawingArea<BitMapBackend<'b>, Shift>;

/// A drawing failure inside plotters, as text (its error types are generic over backends).
#[derive(Debug)]
pub(crate) struct DrawError(pub String);

impl<E: std::error::Error + Send + Sync> From<DrawingAreaErrorKind<E>> for DrawError {
    fn from(e: DrawingAreaErrorKind<E>) -> Self {
        Self(e.to_string())
    }
}

/// Validates nothing, draws with `draw` on a white `size` canvas and writes the PNG at `path`.
///
/// Registers the embedded font and creates the parent directory first; every error names `path`.
pub(crate) fn render_with<F>(path: &Path, size: (u32, u32), draw: F) -> Result<(), ReportError>
where
    F: FnOnce(&Area<'_>) -> Result<(), DrawError>,
{
    let path_buf = path.to_path_buf();
    if !font::ensure_registered() {
        return Err(ReportError::Font { path: path_buf });
    }
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| ReportError::CreateDir {
            path: path_buf.clone(),
            source,
        })?;
    }
    let to_err = |e: DrawError| ReportError::Draw {
        path: path_buf.clone(),
        message: e.0,
    };
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&style::WHITE).map_err(|e| to_err(e.into()))?;
    draw(&root).map_err(to_err)?;
    root.present().map_err(|e| to_err(e.into()))
}

/// Draws the centred title and the subtitle lines (split at `\n`), returns the area below.
pub(crate) fn header<'b>(
    root: &Area<'b>,
    title: &str,
    subtitle: &str,
) -> Result<Area<'b>, DrawError> {
    let lines: Vec<&str> = subtitle
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect();
    let centre = root.dim_in_pixel().0 as i32 / 2;
    let title_style = style::text(TITLE_PX, TEXT, (HPos::Center, VPos::Top));
    root.draw(&Text::new(title.to_string(), (centre, 14), title_style))?;
    let line_h = SUBTITLE_PX as i32 + 7;
    let first = 14 + TITLE_PX as i32 + 12;
    for (i, line) in lines.iter().enumerate() {
        let st = style::text(SUBTITLE_PX, style::MUTED, (HPos::Center, VPos::Top));
        root.draw(&Text::new(
            line.to_string(),
            (centre, first + i as i32 * line_h),
            st,
        ))?;
    }
    let height = first + lines.len() as i32 * line_h + 6;
    Ok(root.split_vertically(height).1)
}

/// Draws `lines` (warnings) centred in red at the top of `area`, returns the area below (all
/// of `area` when there are none).
pub(crate) fn notes<'b>(area: &Area<'b>, lines: &[String]) -> Result<Area<'b>, DrawError> {
    let lines: Vec<&str> = lines
        .iter()
        .map(|l| l.trim())
        .filter(|l| !l.is_empty())
        .collect();
    if lines.is_empty() {
        return Ok(area.clone());
    }
    let centre = area.dim_in_pixel().0 as i32 / 2;
    let line_h = SUBTITLE_PX as i32 + 7;
    for (i, line) in lines.iter().enumerate() {
        let st = style::text(SUBTITLE_PX, style::RED, (HPos::Center, VPos::Top));
        area.draw(&Text::new(
            line.to_string(),
            (centre, 2 + i as i32 * line_h),
            st,
        ))?;
    }
    Ok(area.split_vertically(4 + lines.len() as i32 * line_h).1)
}

/// Width and height in pixels of `s` in `style`, (0, 0) if it cannot be measured.
pub(crate) fn text_size(area: &Area<'_>, s: &str, style: &TextStyle<'_>) -> (u32, u32) {
    if s.is_empty() {
        return (0, 0);
    }
    area.estimate_text_size(s, style).unwrap_or((0, 0))
}

/// Splits `area` into a grid whose column widths and row heights are proportional to
/// `cols` and `rows`; cells come row by row.
pub(crate) fn split_grid<'b>(area: &Area<'b>, cols: &[f64], rows: &[f64]) -> Vec<Area<'b>> {
    let (w, h) = area.dim_in_pixel();
    area.split_by_breakpoints(breakpoints(cols, w), breakpoints(rows, h))
}

/// Interior cut positions (pixels) dividing `len` in proportion to `weights`.
fn breakpoints(weights: &[f64], len: u32) -> Vec<i32> {
    let total: f64 = weights.iter().sum::<f64>().max(f64::MIN_POSITIVE);
    let mut acc = 0.0;
    weights[..weights.len().saturating_sub(1)]
        .iter()
        .map(|w| {
            acc += w;
            (acc / total * f64::from(len)).round() as i32
        })
        .collect()
}
