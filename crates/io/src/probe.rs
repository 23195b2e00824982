//! Reading a `probe` campaign (`docs/spec/machine-formats.md`, "Kind `probe`") with the parquet crate and
//! handing it over as plain data ([`ProbeCampaignLogs`]).
//!
//! `touches/*.parquet` (required), each file decoded whole under the guard, with the reader
//! rules of the `axis` reader (timestamps ns/us/ms, integers int8 … int64, strings utf8 or
//! dictionary, optional columns absent or all null): the approach as `i, j, k` or, where those
//! are null or absent, `phi_deg, theta_deg` (θ default 0); i, j, k win where both are given. A
//! row that cannot be used (a null where a value is needed, an approach that is not a unit
//! vector within 1 %, a non-finite position, a negative feed, a stylus or artefact the manifest
//! does not declare, a `seq` given twice with different values) refuses the campaign with one
//! line naming the file, the column and the rows (from 0). A touch several files hold (equal in
//! every column) is kept once. Touches are ordered by `seq` whatever the files and the row
//! order, and their directions derived ([`derive_directions`]). `temperatures/` and `events/`
//! are not read by this version.

use std::path::{Path, PathBuf};

use super::axis::{check_rows, finite, required, Decoded};
use super::inputs::check_unchanged;
use super::kind_read::{kind_manifest_text, required_table, snapshot};
use super::IngestError;
use crate::manifest::TomlCampaign;
use dbbcal_core::axis_campaign::CampaignKind;
use dbbcal_core::probe_campaign::{
    approach_of, derive_directions, ProbeCampaign, ProbeCampaignLogs, ProbeTouch,
};

const TOUCHES: &str = "touches";

/// Reads a `probe` campaign directory: `campaign.toml` and `touches/*.parquet`.
pub fn read_probe_campaign(dir: &Path) -> Result<ProbeCampaignLogs, IngestError> {
    let manifest = dir.join("campaign.toml");
    let campaign = read_probe_manifest(dir)?;
    let files = required_table(dir, TOUCHES)?;
    let (before, inputs) = snapshot(dir, &manifest, &[&files])?;
    let mut touches = Vec::new();
    let mut origin = Vec::new();
    for (f, path) in files.iter().enumerate() {
        let rows = read_touch_file(path, &campaign)?;
        origin.extend((0..rows.len()).map(|r| (f, r as u64)));
        touches.extend(rows);
    }
    let mut touches = one_per_seq(touches, &origin, &files)?;
    derive_directions(&mut touches, campaign.same_direction_deg);
    check_unchanged(dir, &before, &inputs)?;
    Ok(ProbeCampaignLogs {
        campaign,
        inputs,
        touches,
    })
}

/// Reads and validates the `campaign.toml` of a `probe` campaign; another kind is refused.
pub fn read_probe_manifest(dir: &Path) -> Result<ProbeCampaign, IngestError> {
    let (file, text) = kind_manifest_text(dir, CampaignKind::Probe, "a probe campaign")?;
    Ok(ProbeCampaign::from_toml_str(&text, &file)?)
}

/// Sorted by seq; copies (equal in every column) kept once; a seq with two different touches
/// refused, naming the first file's rows.
fn one_per_seq(
    touches: Vec<ProbeTouch>,
    origin: &[(usize, u64)],
    files: &[PathBuf],
) -> Result<Vec<ProbeTouch>, IngestError> {
    let mut order: Vec<usize> = (0..touches.len()).collect();
    order.sort_by_key(|&i| (touches[i].seq, origin[i]));
    let mut out: Vec<ProbeTouch> = Vec::with_capacity(touches.len());
    let mut last: Option<usize> = None;
    for i in order {
        if let Some(p) = last {
            if touches[p].seq == touches[i].seq {
                if touches[p] == touches[i] {
                    continue;
                }
                let (f, row) = origin[p];
                return Err(IngestError::BadRows {
                    path: files[f].clone(),
                    column: "seq",
                    rows: 2,
                    first_row: row,
                    last_row: row,
                    problem: format!(
                        "repeat a seq with another touch (row {} of {}): seq must be strictly increasing in the order of touching",
                        origin[i].1,
                        files[origin[i].0].display()
                    ),
                    example: touches[i].seq.to_string(),
                });
            }
        }
        out.push(touches[i].clone());
        last = Some(i);
    }
    Ok(out)
}

/// One file's touches, checked.
fn read_touch_file(path: &Path, campaign: &ProbeCampaign) -> Result<Vec<ProbeTouch>, IngestError> {
    let file = Decoded::read(path)?;
    let time = required(path, "time", file.time("time")?)?;
    let seq = required(path, "seq", file.int("seq")?)?;
    let ijk = [
        file.optional("i", Decoded::real)?,
        file.optional("j", Decoded::real)?,
        file.optional("k", Decoded::real)?,
    ];
    let phi = file.optional("phi_deg", Decoded::real)?;
    let theta = file.optional("theta_deg", Decoded::real)?;
    if !file.has("i") && !file.has("phi_deg") {
        file.column("i")?;
    }
    let pos = [
        required(path, "x_mm", file.real("x_mm")?)?,
        required(path, "y_mm", file.real("y_mm")?)?,
        required(path, "z_mm", file.real("z_mm")?)?,
    ];
    for (name, p) in ["x_mm", "y_mm", "z_mm"].into_iter().zip(&pos) {
        finite(path, name, p)?;
    }
    let feed = file.optional("feed_mm_min", Decoded::real)?;
    let spindle = file.optional("spindle_deg", Decoded::real)?;
    let stylus = required(path, "stylus", file.text("stylus")?)?;
    let artefact = required(path, "artefact", file.text("artefact")?)?;
    check_rows(
        path,
        "feed_mm_min",
        &feed,
        |f| f.is_none_or(|f| f.is_finite() && f >= 0.0),
        "are not finite numbers of at least 0 mm/min",
    )?;
    check_rows(
        path,
        "spindle_deg",
        &spindle,
        |s| s.is_none_or(f64::is_finite),
        "are not finite numbers",
    )?;
    check_rows(
        path,
        "stylus",
        &stylus,
        |s| campaign.stylus(s).is_some(),
        &format!(
            "name a stylus campaign.toml does not declare (known: {})",
            campaign
                .styli
                .iter()
                .map(|s| s.id.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    )?;
    check_rows(
        path,
        "artefact",
        &artefact,
        |a| campaign.artefact(a).is_some(),
        &format!(
            "name an artefact campaign.toml does not declare (known: {})",
            campaign
                .artefacts
                .iter()
                .map(|a| a.id.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    )?;
    let approach: Vec<Option<[f64; 3]>> = (0..file.rows())
        .map(|r| match (ijk[0][r], ijk[1][r], ijk[2][r], phi[r]) {
            (Some(i), Some(j), Some(k), _) => Some([i, j, k]),
            (None, None, None, Some(p)) => Some(approach_of(p, theta[r].unwrap_or(0.0))),
            _ => None,
        })
        .collect();
    let column = if file.has("i") { "i" } else { "phi_deg" };
    check_rows(
        path,
        column,
        &approach,
        |a| {
            a.is_some_and(|a| {
                let n = a.iter().map(|v| v * v).sum::<f64>().sqrt();
                n.is_finite() && (n - 1.0).abs() <= 0.01
            })
        },
        "do not give an approach: i, j, k must be a unit vector (within 1 %), or i, j, k null and phi_deg given",
    )?;
    Ok((0..file.rows())
        .map(|r| {
            let a = approach[r].unwrap_or([1.0, 0.0, 0.0]);
            let n = a.iter().map(|v| v * v).sum::<f64>().sqrt();
            ProbeTouch {
                time_ns: time[r],
                seq: seq[r],
                approach: a.map(|v| v / n),
                position_mm: [pos[0][r], pos[1][r], pos[2][r]],
                feed_mm_min: feed[r],
                stylus: stylus[r].clone(),
                artefact: artefact[r].clone(),
                spindle_deg: spindle[r],
                touch_in_direction: 0,
            }
        })
        .collect())
}
