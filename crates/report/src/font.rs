//! The one place that knows about fonts: DejaVu Sans is embedded in the binary and registered
//! with plotters' ab_glyph text backend under the family name every figure uses.
//!
//! plotters plans to replace `register_font`; when it does, only this file changes.

use std::sync::OnceLock;

use plotters::style::{register_font, FontStyle};

/// The family name all text styles in `report` use.
pub(crate) const FAMILY: &str = "sans-serif";

/// DejaVu Sans (see `assets/fonts/LICENSE-DejaVu.txt`), embedded so no system font is needed.
static DEJAVU_SANS: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

/// Registers the embedded font once per process; later calls return the first outcome.
///
/// Returns `false` if the embedded bytes are not a valid font (a build defect, never data).
pub(crate) fn ensure_registered() -> bool {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    *REGISTERED.get_or_init(|| register_font(FAMILY, FontStyle::Normal, DEJAVU_SANS).is_ok())
}
