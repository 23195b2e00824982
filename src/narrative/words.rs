//! Small words every machine kind's narrative writes the same way, so that a kind's narrative
//! holds only its own sentences.

use crate::output::escape;

/// `v` with `decimals` decimals, or `—` when it is not a number.
pub(crate) fn num(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        "—".to_string()
    }
}

/// `text` safe inside an HTML element.
pub(crate) fn html(text: &str) -> String {
    escape(text)
        .replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}
