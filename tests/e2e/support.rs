//! Shared helpers: simulate a campaign into a temp dir, read it back, analyse it.

use std::path::{Path, PathBuf};

use dbbcal::pipeline::{analyse, RunPlan, RunResults, Stage};
use dbbcal::simulate::{self, SimConfig, Truth};

/// A simulation TOML of the repository (e.g. `pipelines/sim-sample.toml`).
pub fn sim_config(path: &str) -> SimConfig {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    toml::from_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// Simulate `cfg` into a fresh directory under `root`; returns the directory and the truth.
pub fn simulate_campaign(root: &Path, name: &str, cfg: &SimConfig) -> (PathBuf, Truth) {
    let dir = root.join(name);
    let sim = simulate::generate(cfg).unwrap_or_else(|e| panic!("simulate {name}: {e}"));
    simulate::write(&sim, &dir, &dbbcal::io::WriteOptions::default())
        .unwrap_or_else(|e| panic!("write {name}: {e}"));
    (dir, sim.truth)
}

/// Ingest + the analysis stages `stage` needs, with `effects`.
pub fn analyse_campaign(dir: &Path, stage: Stage, effects: &[&str]) -> RunResults {
    analyse_campaign_binned(dir, stage, effects, 0.0, false)
}

/// [`analyse_campaign`] with readings compressed into bins of `bin_s` seconds: by ingest while it
/// streams (`streamed`), else from each bar's log in memory.
pub fn analyse_campaign_binned(
    dir: &Path,
    stage: Stage,
    effects: &[&str],
    bin_s: f64,
    streamed: bool,
) -> RunResults {
    let effects: Vec<String> = effects.iter().map(|s| s.to_string()).collect();
    let mut plan = RunPlan::for_stage(stage, dir.to_path_buf(), None, &effects).expect("plan");
    plan.bin_s = bin_s;
    let logs = if streamed {
        dbbcal::io::read_campaign_binned(dir, bin_s)
    } else {
        dbbcal::io::read_campaign(dir)
    }
    .unwrap_or_else(|e| panic!("ingest {}: {e}", dir.display()));
    analyse(&plan, logs)
}

/// Relative error |est − truth| / |truth|.
pub fn rel(est: f64, truth: f64) -> f64 {
    (est - truth).abs() / truth.abs()
}

/// Run the `dbbcal` binary; returns (exit code, stdout, stderr).
pub fn run_cli(args: &[&str]) -> (i32, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_dbbcal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("CI", "1")
        .output()
        .expect("run dbbcal");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}
