//! Small words every machine kind's narrative writes the same way, so that a kind's narrative
//! holds only its own sentences.

use std::fmt::Write as _;

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

/// A row of the page's "What the model misses" table: candidate, physics, ΔBIC, RMS after.
pub(crate) fn candidate_row(
    h: &mut String,
    name: &str,
    physics: &str,
    delta_bic: f64,
    rms_um: f64,
) {
    let _ = writeln!(
        h,
        "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
        name,
        html(physics),
        num(delta_bic, 1),
        num(rms_um, 4)
    );
}

/// The page's closing list of the output folder's `files`, each a link.
pub(crate) fn files_paragraph(files: &[&str]) -> String {
    let links: Vec<String> = files
        .iter()
        .map(|f| format!("<a href=\"{f}\">{f}</a>"))
        .collect();
    format!("<p>Files: {}.</p>\n", links.join(", "))
}
