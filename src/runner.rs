//! The edge between the library and the file system: run a plan end to end into an output
//! folder that appears whole or not at all, and only where dbbcal may write ([`crate::output`]).
//!
//! The output location is checked and locked before any work; everything is written into a
//! partial folder beside `OUT` and swapped into place at the end. Outputs contain no clocks or
//! host names, so the same inputs and plan give byte-identical JSON.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use crate::io;
use crate::narrative::{fit_report::fit_report, Headline};
use crate::output::{self, Marker, OutputTarget, WriteFailure};
use crate::pipeline::{self, RunPlan, RunResults, Stage};

/// How a run ended when it produced output.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RunStatus {
    /// Every bar processed.
    AllBars,
    /// This many bars failed (listed in `failed_bars`); the others are in the output.
    SomeBarsFailed(usize),
    /// Every bar failed (bar, reason): nothing was written and the previous output is as it was.
    NoBarSucceeded(Vec<pipeline::BarFailure>),
}

/// What a run leaves for the command line to say.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// How the run ended.
    pub status: RunStatus,
    /// The output folder, when one was written.
    pub out: Option<PathBuf>,
    /// The night in a few lines (absent when no bar succeeded).
    pub headline: Option<Headline>,
    /// The lines a run of another kind leaves for the terminal (label, text), when it has no
    /// ballbar headline.
    pub lines: Vec<(&'static str, String)>,
}

/// Whether an error (anywhere in a chain) means the input or configuration is unusable.
pub fn is_input_error(e: &(dyn std::error::Error + 'static)) -> bool {
    e.is::<io::IngestError>()
        || e.is::<pipeline::PlanError>()
        || e.is::<crate::campaign::CampaignError>()
        || e.is::<dbbcal_machine::volumetric::study::BarCampaignError>()
        || e.downcast_ref::<output::OutputError>()
            .is_some_and(|o| matches!(o, output::OutputError::Refused { .. }))
}

/// Whether an error is another run holding the output's lock.
pub fn is_busy_error(e: &(dyn std::error::Error + 'static)) -> bool {
    e.downcast_ref::<output::OutputError>()
        .is_some_and(|o| matches!(o, output::OutputError::Busy { .. }))
}

/// The output folder of `plan`: `--out`, else `reports/<campaign id>` (the id read from the
/// manifest alone).
fn output_folder(plan: &RunPlan) -> Result<PathBuf> {
    match &plan.out_dir {
        Some(out) => Ok(out.clone()),
        None => {
            let campaign = io::read_manifest(&plan.campaign_dir)?;
            Ok(PathBuf::from("reports").join(&campaign.id))
        }
    }
}

/// Run `plan`: claim the output, ingest, analyse, write the output folder.
pub fn run(plan: &RunPlan) -> Result<Outcome> {
    let target = OutputTarget::claim(&output_folder(plan)?, &plan.campaign_dir)?;
    // No bin length set: chosen from the campaign before ingest streams (and recorded).
    let (plan, mut results) = ingest_and_analyse(plan)?;
    let plan = &plan;
    if plan.runs(Stage::Device) {
        device_stage(plan, &mut results)?;
    }
    if plan.runs(Stage::Identify) && results.bars.is_empty() {
        return Ok(Outcome {
            status: RunStatus::NoBarSucceeded(results.failed),
            out: None,
            headline: None,
            lines: Vec::new(),
        });
    }
    let headline = Headline::from_results(plan, &results);
    let marker = Marker::new(
        &results.campaign.id,
        serde_json::to_value(&plan.stages)?,
        serde_json::to_value(plan.effects.iter().map(|e| e.name()).collect::<Vec<_>>())?,
        serde_json::to_value(output::inputs::input_records(&results.inputs))?,
    );
    let out = target.path().to_path_buf();
    pipeline::timed("write outputs", || {
        target
            .write(&marker, |tmp| write_outputs(plan, &results, &headline, tmp))
            .map_err(|e| match e {
                WriteFailure::Build(e) => e,
                WriteFailure::Output(e) => anyhow::Error::from(e),
            })
    })
    .with_context(|| format!("writing {}", out.display()))?;
    let status = match results.failed.len() {
        0 => RunStatus::AllBars,
        n => RunStatus::SomeBarsFailed(n),
    };
    Ok(Outcome {
        status,
        out: Some(out),
        headline: Some(headline),
        lines: Vec::new(),
    })
}

/// Ingest and analyse. With no bin length set, the bins are chosen from the campaign's reading
/// rate ([`io::automatic_bin_s`]) and then checked against the identified time constants: when
/// one is too short for them ([`crate::series::too_short_for_bins`]), the campaign is read
/// again with bins that short time constant allows (at most twice; below 1 s, every reading),
/// before any later stage runs on the discarded pass.
fn ingest_and_analyse(plan: &RunPlan) -> Result<(RunPlan, RunResults)> {
    let automatic = plan.automatic_bins;
    let mut plan = if automatic {
        plan.with_chosen_bins(io::automatic_bin_s(&plan.campaign_dir)?)
    } else {
        plan.clone()
    };
    for pass in 0.. {
        let logs = pipeline::timed("ingest", || {
            io::read_campaign_binned(&plan.campaign_dir, plan.bin_s)
        })?;
        let mut results = pipeline::identify_stage(&plan, logs);
        match shortest_too_short_tau_s(&results, plan.bin_s) {
            Some(tau) if automatic && pass < 2 => {
                let bin_s = (tau / crate::series::REREAD_BINS_PER_TAU).floor();
                let bin_s = if bin_s >= 1.0 { bin_s } else { 0.0 };
                tracing::info!(
                    "a fitted time constant of {tau:.0} s spans fewer than {} bins of {} s: reading again with bins of {bin_s} s",
                    crate::series::min_bins_per_tau(plan.bin_s),
                    plan.bin_s
                );
                plan = plan.with_chosen_bins(bin_s);
            }
            _ => {
                pipeline::run_later_stages(&plan, &mut results);
                return Ok((plan, results));
            }
        }
    }
    unreachable!("the loop returns by its third pass")
}

/// The shortest time constant identified on any bar that is too short for bins of `bin_s` (s;
/// [`crate::series::too_short_for_bins`]), if any.
fn shortest_too_short_tau_s(results: &RunResults, bin_s: f64) -> Option<f64> {
    results
        .bars
        .iter()
        .flat_map(|o| o.model.params.iter())
        .filter(|p| p.name.starts_with("tau") && p.value.is_finite())
        .filter(|p| crate::series::too_short_for_bins(p.value, p.ci95[1], bin_s))
        .map(|p| p.value)
        .min_by(f64::total_cmp)
}

/// Write a simulated campaign into `out` (which must not exist).
/// A simulation TOML with `kind = "axis"` makes an `axis` campaign instead
/// (`crate::simulate::generate_axis`); `kind = "probe"` a `probe` campaign
/// (`crate::simulate::generate_probe`).
pub fn simulate(config: Option<&Path>, out: &Path, seed: Option<u64>) -> Result<()> {
    let mut cfg = match config {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read {}", p.display()))?;
            if crate::simulate::volumetric::is_volumetric_config(&text) {
                return simulate_volumetric(p, &text, out, seed);
            }
            if crate::simulate::is_roll_config(&text).unwrap_or(false) {
                return simulate_roll(p, &text, out, seed);
            }
            let probe = crate::simulate::is_probe_config(&text).map_err(|e| {
                anyhow::anyhow!("{}: {}", p.display(), e.to_string().replace('\n', " "))
            })?;
            if probe {
                return simulate_probe(p, &text, out, seed);
            }
            let axis = crate::simulate::is_axis_config(&text).map_err(|e| {
                anyhow::anyhow!("{}: {}", p.display(), e.to_string().replace('\n', " "))
            })?;
            if axis {
                return simulate_axis(p, &text, out, seed);
            }
            toml::from_str::<crate::simulate::SimConfig>(&text).map_err(|e| {
                anyhow::anyhow!("{}: {}", p.display(), e.to_string().replace('\n', " "))
            })?
        }
        None => crate::simulate::SimConfig::default(),
    };
    if let Some(seed) = seed {
        cfg.seed = seed;
    }
    if std::fs::symlink_metadata(out).is_ok() {
        anyhow::bail!("{} already exists; choose a new directory", out.display());
    }
    let sim = crate::simulate::generate(&cfg)?;
    create_new_folder(out, |tmp| {
        crate::simulate::write(&sim, tmp, &io::WriteOptions::default()).map_err(anyhow::Error::from)
    })
}

/// [`simulate`] for an `axis` campaign: the configuration `text` (of file `path`).
fn simulate_axis(path: &Path, text: &str, out: &Path, seed: Option<u64>) -> Result<()> {
    let mut cfg = toml::from_str::<crate::simulate::AxisSimConfig>(text)
        .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.to_string().replace('\n', " ")))?;
    if let Some(seed) = seed {
        cfg.seed = seed;
    }
    if std::fs::symlink_metadata(out).is_ok() {
        anyhow::bail!("{} already exists; choose a new directory", out.display());
    }
    let sim = crate::simulate::generate_axis(&cfg)?;
    create_new_folder(out, |tmp| {
        crate::simulate::write_axis(&sim, tmp, &cfg.output, cfg.seed).map_err(anyhow::Error::from)
    })
}

/// [`simulate`] for a `roll` campaign: the configuration `text` (of file `path`).
fn simulate_roll(path: &Path, text: &str, out: &Path, seed: Option<u64>) -> Result<()> {
    let mut cfg = toml::from_str::<crate::simulate::RollSimConfig>(text)
        .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.to_string().replace('\n', " ")))?;
    if let Some(seed) = seed {
        cfg.seed = seed;
    }
    if std::fs::symlink_metadata(out).is_ok() {
        anyhow::bail!("{} already exists; choose a new directory", out.display());
    }
    let sim = crate::simulate::generate_roll(&cfg)
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    create_new_folder(out, |tmp| {
        crate::simulate::write_roll(&sim, tmp, &cfg).map_err(anyhow::Error::from)
    })
}

/// [`simulate`] for a `probe` campaign: the configuration `text` (of file `path`).
fn simulate_probe(path: &Path, text: &str, out: &Path, seed: Option<u64>) -> Result<()> {
    let mut cfg = toml::from_str::<crate::simulate::ProbeSimConfig>(text)
        .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.to_string().replace('\n', " ")))?;
    if let Some(seed) = seed {
        cfg.seed = seed;
    }
    cfg.validate()
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    if std::fs::symlink_metadata(out).is_ok() {
        anyhow::bail!("{} already exists; choose a new directory", out.display());
    }
    let sim = crate::simulate::generate_probe(&cfg)?;
    create_new_folder(out, |tmp| {
        crate::simulate::write_probe(&sim, tmp, &cfg).map_err(anyhow::Error::from)
    })
}

/// [`simulate`] for a `volumetric` campaign: the configuration `text` (of file `path`).
fn simulate_volumetric(path: &Path, text: &str, out: &Path, seed: Option<u64>) -> Result<()> {
    use crate::simulate::volumetric as vol;
    let mut cfg = toml::from_str::<vol::VolumetricSimConfig>(text)
        .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.to_string().replace('\n', " ")))?;
    if let Some(seed) = seed {
        cfg.seed = seed;
    }
    if std::fs::symlink_metadata(out).is_ok() {
        anyhow::bail!("{} already exists; choose a new directory", out.display());
    }
    let sim = vol::generate_volumetric(&cfg)?;
    create_new_folder(out, |tmp| {
        vol::write_volumetric(&sim, tmp, &cfg).map_err(anyhow::Error::from)
    })
}

/// Build a new folder at `out` (absent) through a temporary sibling renamed at the end. A
/// campaign carries no output marker: dbbcal never replaces it.
fn create_new_folder(out: &Path, build: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let parent = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent)
        .with_context(|| format!("cannot create {}", parent.display()))?;
    let name = out.file_name().and_then(|n| n.to_str()).unwrap_or("out");
    let tmp = parent.join(format!(".{name}.partial-{}", std::process::id()));
    std::fs::create_dir(&tmp).with_context(|| format!("cannot create {}", tmp.display()))?;
    if let Err(e) = build(&tmp) {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(e);
    }
    if std::fs::symlink_metadata(out).is_ok() {
        let _ = std::fs::remove_dir_all(&tmp);
        anyhow::bail!(
            "{} appeared meanwhile; choose a new directory",
            out.display()
        );
    }
    std::fs::rename(&tmp, out)
        .with_context(|| format!("cannot rename {} to {}", tmp.display(), out.display()))
}

fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> Result<()> {
    let mut text = serde_json::to_string_pretty(value)?;
    text.push('\n');
    Ok(output::write_file(path, text.as_bytes())?)
}

/// A parquet table (and its CSV twin when `[output] csv`), through the output's fault points.
fn write_table(plan: &RunPlan, path: &Path, table: &io::Table) -> Result<()> {
    output::fault::point("write", path)
        .with_context(|| format!("cannot write {}", path.display()))?;
    {
        let _step = output::writing();
        io::write_table(path, table)?;
    }
    if plan.output.csv {
        let csv = path.with_extension("csv");
        output::fault::point("write", &csv)
            .with_context(|| format!("cannot write {}", csv.display()))?;
        let _step = output::writing();
        io::write_table_csv(&csv, table)?;
    }
    Ok(())
}

fn write_outputs(
    plan: &RunPlan,
    results: &RunResults,
    headline: &Headline,
    dir: &Path,
) -> Result<()> {
    write_json(
        &dir.join("summary.json"),
        &crate::output::summary::summary(plan, results),
    )?;
    write_json(
        &dir.join("inputs.json"),
        &output::inputs::input_records(&results.inputs),
    )?;
    if plan.runs(Stage::Identify) {
        write_table(plan, &dir.join("models.parquet"), &models_table(results))?;
    }
    if let Some(d) = &results.diagnosis {
        write_json(
            &dir.join("diagnosis.json"),
            &crate::output::diagnosis::diagnosis_record(plan, results, d),
        )?;
    }
    if let Some(ba) = &results.before_after {
        write_json(
            &dir.join("before_after.json"),
            &output::before_after::BeforeAfterRecord::from(ba),
        )?;
    }
    if let Some(study) = &results.study {
        write_json(
            &dir.join("match_study.json"),
            &output::match_study::MatchStudyRecord::from(study),
        )?;
    }
    write_calibration_outputs(plan, results, dir)?;
    let figures = if plan.runs(Stage::Report) {
        let figures = dir.join("figures");
        {
            // `create_dir`, not `_all`: a partial folder a signal removed is not made again.
            let _step = output::writing();
            std::fs::create_dir(&figures)
                .with_context(|| format!("cannot create {}", figures.display()))?;
        }
        crate::figures::render_all(plan, results, &figures)?
    } else {
        Vec::new()
    };
    let report = fit_report(plan, results, headline);
    if plan.runs(Stage::Identify) {
        output::write_file(&dir.join("report.md"), report.as_bytes())?;
    }
    let page = crate::narrative::page::page(plan, results, headline, &figures, &report);
    output::write_file(&dir.join("index.html"), page.as_bytes())?;
    Ok(())
}

/// `models.parquet`: one row per bar and parameter.
fn models_table(results: &RunResults) -> io::Table {
    let mut bar = Vec::new();
    let mut param = Vec::new();
    let (mut value, mut u, mut u_naive, mut lo, mut hi) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut rms, mut n) = (Vec::new(), Vec::new());
    for o in &results.bars {
        for p in &o.model.params {
            bar.push(o.model.bar.clone());
            param.push(p.name.clone());
            value.push(p.value);
            u.push(p.u);
            u_naive.push(p.u_naive);
            // An end at the search bound is no confidence limit: null.
            let end = |i: usize| (!p.ci95_at_search_bound[i]).then_some(p.ci95[i]);
            lo.push(end(0));
            hi.push(end(1));
            rms.push(o.model.rms_um);
            n.push(o.model.n_samples as i64);
        }
    }
    use io::Column::*;
    io::Table {
        columns: vec![
            (
                "campaign".into(),
                Str(vec![results.campaign.id.clone(); bar.len()]),
            ),
            ("bar".into(), Str(bar)),
            ("param".into(), Str(param)),
            ("value".into(), F64(value)),
            ("u".into(), F64(u)),
            ("u_naive".into(), F64(u_naive)),
            ("ci95_low".into(), OptF64(lo)),
            ("ci95_high".into(), OptF64(hi)),
            ("rms_um".into(), F64(rms)),
            ("n_samples".into(), I64(n)),
        ],
    }
}

/// `calibration.json`, `compensation.json` + `compensated.parquet`, `acceptance.json`: what the
/// calibrate, compensate and acceptance stages produced (formats in `output::stage_records`).
fn write_calibration_outputs(plan: &RunPlan, results: &RunResults, dir: &Path) -> Result<()> {
    use crate::output::stage_records as records;
    // These two go through a `serde_json::Value`, whose maps sort their keys at every level:
    // the files have always been written so.
    if let Some(record) = records::calibration_record(results) {
        write_json(
            &dir.join("calibration.json"),
            &serde_json::to_value(&record)?,
        )?;
    }
    if let Some(record) = records::compensation_record(plan, results) {
        write_json(
            &dir.join("compensation.json"),
            &serde_json::to_value(&record)?,
        )?;
    }
    if let Some(c) = &results.compensation {
        write_table(
            plan,
            &dir.join("compensated.parquet"),
            &compensated_table(results, &c.ok),
        )?;
    }
    if let Some(record) = records::acceptance_record(plan, results) {
        write_json(&dir.join("acceptance.json"), &record)?;
    }
    if let Some(record) = crate::output::device_record::device_record(results) {
        write_json(&dir.join("device.json"), &record)?;
        crate::output::axis_tables::write_tables(dir, record.tables)?;
    }
    if let Some(table) = crate::output::device_record::device_errors_table(results) {
        write_table(plan, &dir.join("device_errors.parquet"), &table)?;
    }
    Ok(())
}

/// `compensated.parquet`: one row per working sample.
fn compensated_table(
    results: &RunResults,
    working: &[crate::compensate::WorkingSeries],
) -> io::Table {
    let (mut bar, mut mode, mut mount) = (Vec::new(), Vec::new(), Vec::new());
    let (mut t, mut d, mut du, mut th, mut err) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for w in working {
        for k in 0..w.t_s.len() {
            bar.push(w.bar.clone());
            mode.push(w.mode.name());
            mount.push(w.mount as i64);
            t.push(w.t_s[k]);
            d.push(w.distance_mm[k]);
            du.push(w.uncompensated_mm[k]);
            th.push(w.thermal_um[k]);
            err.push(w.length_mm.map(|l| (w.distance_mm[k] - l) * 1e3));
        }
    }
    use io::Column::*;
    io::Table {
        columns: vec![
            (
                "campaign".into(),
                Str(vec![results.campaign.id.clone(); bar.len()]),
            ),
            ("bar".into(), Str(bar)),
            ("mount".into(), I64(mount)),
            ("mode".into(), Str(mode)),
            ("t_s".into(), F64(t)),
            ("distance_mm".into(), F64(d)),
            ("uncompensated_mm".into(), F64(du)),
            ("thermal_um".into(), F64(th)),
            ("error_um".into(), OptF64(err)),
        ],
    }
}

/// The device stage (`pipeline::device`): reads `positions/*.parquet` (a bad file is an input
/// error, one line naming file, column and rows) and records its hashes with the other inputs.
fn device_stage(plan: &RunPlan, results: &mut RunResults) -> Result<()> {
    let Some((log, files)) = io::read_positions(&plan.campaign_dir)? else {
        return Err(io::IngestError::MissingTable {
            folder: plan.campaign_dir.join("positions"),
            table: "positions",
        }
        .into());
    };
    pipeline::timed("device", || {
        pipeline::run_device(plan, results, &log, files.clone())
    })
    .map_err(|problem| io::IngestError::UnusableCampaign {
        path: plan.campaign_dir.join("campaign.toml"),
        problem: problem.to_string(),
    })?;
    results.inputs.extend(files);
    results.inputs.sort_by(|a, b| a.path.cmp(&b.path));
    Ok(())
}
