//! Colours, font sizes and the sequential colour map shared by every figure.

use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{Color, IntoFont, RGBAColor, RGBColor, ShapeStyle, TextStyle};

use super::font::FAMILY;

/// Default canvas size of the time-series and multi-panel figures (pixels).
pub(crate) const FIGURE_SIZE: (u32, u32) = (1600, 1000);

pub(crate) const TITLE_PX: f64 = 32.0;
pub(crate) const SUBTITLE_PX: f64 = 21.0;
pub(crate) const CAPTION_PX: f64 = 23.0;
pub(crate) const DESC_PX: f64 = 20.0;
pub(crate) const TICK_PX: f64 = 17.0;
pub(crate) const LEGEND_PX: f64 = 17.0;
pub(crate) const NOTE_PX: f64 = 15.0;

pub(crate) const BLACK: RGBColor = RGBColor(0, 0, 0);
pub(crate) const WHITE: RGBColor = RGBColor(255, 255, 255);
pub(crate) const TEXT: RGBColor = RGBColor(30, 30, 30);
pub(crate) const MUTED: RGBColor = RGBColor(110, 110, 110);
pub(crate) const GRID: RGBColor = RGBColor(215, 215, 215);
pub(crate) const GRID_MINOR: RGBColor = RGBColor(236, 236, 236);
/// Something that is fine (within tolerance, the plain measured trace).
pub(crate) const BLUE: RGBColor = RGBColor(0x4e, 0x79, 0xa7);
/// Something to look at (flagged bars, limits, the reference).
pub(crate) const RED: RGBColor = RGBColor(0xd6, 0x27, 0x28);
pub(crate) const ORANGE: RGBColor = RGBColor(0xf2, 0x8e, 0x2b);
pub(crate) const GREY: RGBColor = RGBColor(0xa0, 0xa0, 0xa0);

/// Qualitative palette (Tableau 10) for named series; cycles when exhausted.
const PALETTE: [RGBColor; 10] = [
    RGBColor(0x4e, 0x79, 0xa7),
    RGBColor(0xf2, 0x8e, 0x2b),
    RGBColor(0x59, 0xa1, 0x4f),
    RGBColor(0xe1, 0x57, 0x59),
    RGBColor(0x76, 0xb7, 0xb2),
    RGBColor(0xb0, 0x7a, 0xa1),
    RGBColor(0x9c, 0x75, 0x5f),
    RGBColor(0xed, 0xc9, 0x48),
    RGBColor(0xff, 0x9d, 0xa7),
    RGBColor(0x6b, 0x6b, 0x6b),
];

/// Colours for reference/tolerance lines and highlights, distinct from the series palette.
const ACCENTS: [RGBColor; 4] = [
    RGBColor(0xd6, 0x27, 0x28),
    RGBColor(0x8c, 0x2d, 0x9c),
    RGBColor(0xe3, 0x7b, 0x00),
    RGBColor(0x33, 0x33, 0x33),
];

/// The `i`-th colour of the series palette.
pub(crate) fn palette(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// The `i`-th accent colour (reference lines, highlights).
pub(crate) fn accent(i: usize) -> RGBColor {
    ACCENTS[i % ACCENTS.len()]
}

/// A text style of the embedded family at `px` pixels, in `colour`, anchored at `anchor`.
pub(crate) fn text(px: f64, colour: RGBColor, anchor: (HPos, VPos)) -> TextStyle<'static> {
    (FAMILY, px)
        .into_font()
        .color(&colour)
        .pos(Pos::new(anchor.0, anchor.1))
}

/// Plain dark text at `px`, anchored at its top-left corner.
pub(crate) fn plain(px: f64) -> TextStyle<'static> {
    text(px, TEXT, (HPos::Left, VPos::Top))
}

/// A solid stroke of `width` pixels.
pub(crate) fn stroke(colour: RGBColor, width: u32) -> ShapeStyle {
    colour.stroke_width(width)
}

/// A translucent fill.
pub(crate) fn fill(colour: RGBColor, alpha: f64) -> ShapeStyle {
    let c: RGBAColor = colour.mix(alpha);
    c.filled()
}

/// Viridis, sampled at nine stops (perceptually uniform, readable in grey scale).
const VIRIDIS: [(u8, u8, u8); 9] = [
    (68, 1, 84),
    (71, 44, 122),
    (59, 81, 139),
    (44, 113, 142),
    (33, 144, 141),
    (39, 173, 129),
    (92, 200, 99),
    (170, 220, 50),
    (253, 231, 37),
];

/// The colour map at `t` in [0, 1] (clamped; NaN maps to the low end).
pub(crate) fn colour_map(t: f64) -> RGBColor {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let pos = t * (VIRIDIS.len() - 1) as f64;
    let i = (pos.floor() as usize).min(VIRIDIS.len() - 2);
    let f = pos - i as f64;
    let lerp = |a: u8, b: u8| (f64::from(a) + (f64::from(b) - f64::from(a)) * f).round() as u8;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    RGBColor(lerp(a.0, b.0), lerp(a.1, b.1), lerp(a.2, b.2))
}

/// Black or white, whichever reads better on `background`.
pub(crate) fn contrast_text(background: RGBColor) -> RGBColor {
    let l = 0.299 * f64::from(background.0)
        + 0.587 * f64::from(background.1)
        + 0.114 * f64::from(background.2);
    if l > 140.0 {
        BLACK
    } else {
        WHITE
    }
}
