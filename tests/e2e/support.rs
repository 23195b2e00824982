//! Shared helpers: simulate a campaign into a temp dir, read it back, analyse it.

use std::path::{Path, PathBuf};

use dbbcal::fit::Separable;
use dbbcal::pipeline::{analyse, RunPlan, RunResults, Stage};
use dbbcal::simulate::{self, SimConfig, Truth};
use nalgebra::DMatrix;

/// A simulation TOML of the repository (e.g. `pipelines/sim-sample.toml`).
pub(crate) fn sim_config(path: &str) -> SimConfig {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    toml::from_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// Simulate `cfg` into a fresh directory under `root`; returns the directory and the truth.
pub(crate) fn simulate_campaign(root: &Path, name: &str, cfg: &SimConfig) -> (PathBuf, Truth) {
    let dir = root.join(name);
    let sim = simulate::generate(cfg).unwrap_or_else(|e| panic!("simulate {name}: {e}"));
    simulate::write(&sim, &dir, &dbbcal::io::WriteOptions::default())
        .unwrap_or_else(|e| panic!("write {name}: {e}"));
    (dir, sim.truth)
}

/// Ingest + the analysis stages `stage` needs, with `effects`.
pub(crate) fn analyse_campaign(dir: &Path, stage: Stage, effects: &[&str]) -> RunResults {
    analyse_campaign_binned(dir, stage, effects, 0.0, false)
}

/// [`analyse_campaign`] with readings compressed into bins of `bin_s` seconds: by ingest while it
/// streams (`streamed`), else from each bar's log in memory.
pub(crate) fn analyse_campaign_binned(
    dir: &Path,
    stage: Stage,
    effects: &[&str],
    bin_s: f64,
    streamed: bool,
) -> RunResults {
    let effects: Vec<String> = effects.iter().map(|s| s.to_string()).collect();
    let plan = RunPlan::for_stage(stage, dir.to_path_buf(), None, &effects)
        .and_then(|p| p.with_bin_s(Some(bin_s)))
        .expect("plan");
    let logs = if streamed {
        dbbcal::io::read_campaign_binned(dir, bin_s)
    } else {
        dbbcal::io::read_campaign(dir)
    }
    .unwrap_or_else(|e| panic!("ingest {}: {e}", dir.display()));
    analyse(&plan, logs)
}

/// Relative error |est − truth| / |truth|.
pub(crate) fn rel(est: f64, truth: f64) -> f64 {
    (est - truth).abs() / truth.abs()
}

/// Run the `dbbcal` binary; returns (exit code, stdout, stderr).
pub(crate) fn run_cli(args: &[&str]) -> (i32, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_dbbcal"))
        .args(args)
        .current_dir(crate::support::root())
        .env("CI", "1")
        .output()
        .expect("run dbbcal");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `dbbcal simulate --config CONFIG --out OUT`, which must succeed (its output in the message).
pub(crate) fn simulate_ok(config: &str, out: &str) {
    let (code, stdout, stderr) = run_cli(&["simulate", "--config", config, "--out", out]);
    assert_eq!(code, 0, "simulate {config}: {stdout}\n{stderr}");
}

/// A base-only campaign (issue 13): the identification room of
/// `pipelines/sim-identification.toml` (daily swing ±1 K, air conditioning ±0.2 K every 20 min,
/// 1 K set-point steps every 6 h) with `n_bars` bars over `days`, white reading noise 0.020 µm,
/// no effect beyond the base model, encoder period `sample_s` and temperature period
/// `temperature_sample_s`; the truth's air between two temperature readings is `air` and the
/// room runs `prehistory_hours` before the logging starts (the bars are then not in steady state
/// at their first reading).
pub(crate) fn base_only_config(
    seed: u64,
    air: simulate::AirBetweenReadings,
    prehistory_hours: f64,
    sample_s: f64,
    temperature_sample_s: f64,
    n_bars: usize,
    days: f64,
) -> SimConfig {
    let mut cfg = sim_config("pipelines/sim-identification.toml");
    cfg.seed = seed;
    cfg.campaign_id = format!("base-only-{seed}");
    cfg.duration_days = days;
    cfg.sample_s = sample_s;
    cfg.room.temperature_sample_s = temperature_sample_s;
    cfg.record_true_error = true;
    if let Some(f) = cfg.fleet.as_mut() {
        f.n_bars = n_bars;
    }
    cfg.generation = simulate::GenerationConfig {
        air_between_readings: air,
        prehistory_hours,
    };
    cfg
}

/// A simulated campaign on disk with its truth and the reading noise it actually drew.
pub(crate) struct NoisyCampaign {
    pub(crate) dir: PathBuf,
    pub(crate) truth: Truth,
    /// Per bar: RMS of the noise actually added to its fitted readings (white noise and
    /// quantization: reading minus true thermal error, each mount's mean removed), µm. What a
    /// model that contains the truth fits down to (a little below, by its parameters).
    pub(crate) noise_rms_um: std::collections::BTreeMap<String, f64>,
    /// The same over every bar's fitted readings.
    pub(crate) fleet_noise_rms_um: f64,
}

/// Simulate `cfg` (with `record_true_error` on) into `root/name` and measure the noise it drew.
pub(crate) fn noisy_campaign(root: &Path, name: &str, cfg: &SimConfig) -> NoisyCampaign {
    let mut cfg = cfg.clone();
    cfg.record_true_error = true;
    let dir = root.join(name);
    let sim = simulate::generate(&cfg).unwrap_or_else(|e| panic!("simulate {name}: {e}"));
    simulate::write(&sim, &dir, &dbbcal::io::WriteOptions::default())
        .unwrap_or_else(|e| panic!("write {name}: {e}"));
    let ns = |rfc: &str| {
        chrono::DateTime::parse_from_rfc3339(rfc)
            .unwrap()
            .timestamp_nanos_opt()
            .unwrap()
    };
    let mut noise_rms_um = std::collections::BTreeMap::new();
    let (mut ss_all, mut n_all) = (0.0, 0usize);
    for bar in &sim.truth.bars {
        let log = &sim.tables.encoders[&bar.id];
        let error = &sim.true_error_um[&bar.id];
        let k_um = bar.resolution_nm * 1e-3;
        let (mut ss, mut n) = (0.0, 0usize);
        for m in sim.truth.mounts.iter().filter(|m| m.bar == bar.id) {
            if m.device.is_some() || m.purpose == dbbcal::campaign::Purpose::Check {
                continue;
            }
            let (from, to) = (ns(&m.from), ns(&m.to));
            let noise: Vec<f64> = (0..log.time_ns.len())
                .filter(|&i| log.time_ns[i] >= from && log.time_ns[i] <= to)
                .map(|i| (log.counts[i] as f64 - m.zero_counts) * k_um - error[i])
                .collect();
            let mean = noise.iter().sum::<f64>() / noise.len().max(1) as f64;
            ss += noise.iter().map(|v| (v - mean).powi(2)).sum::<f64>();
            n += noise.len();
        }
        noise_rms_um.insert(bar.id.clone(), (ss / n.max(1) as f64).sqrt());
        ss_all += ss;
        n_all += n;
    }
    NoisyCampaign {
        dir,
        truth: sim.truth,
        noise_rms_um,
        fleet_noise_rms_um: (ss_all / n_all.max(1) as f64).sqrt(),
    }
}

/// [`noisy_campaign`] of [`base_only_config`]: the base-only campaign of seed `seed` (3 bars,
/// 4 days) with the truth's air between readings `air`, the room running `prehistory_hours`
/// before the logging, and encoder and temperature periods `sample_s` and
/// `temperature_sample_s`, in a fresh directory under `root`.
pub(crate) fn base_only_campaign(
    root: &Path,
    seed: u64,
    air: simulate::AirBetweenReadings,
    prehistory_hours: f64,
    sample_s: f64,
    temperature_sample_s: f64,
) -> NoisyCampaign {
    let cfg = base_only_config(
        seed,
        air,
        prehistory_hours,
        sample_s,
        temperature_sample_s,
        3,
        4.0,
    );
    noisy_campaign(
        root,
        &format!("base-{seed}-{air:?}-{prehistory_hours}-{sample_s}-{temperature_sample_s}"),
        &cfg,
    )
}

/// [`run_cli`] with extra environment variables on the child process (e.g.
/// `RAYON_NUM_THREADS`).
pub(crate) fn run_cli_env(args: &[&str], env: &[(&str, &str)]) -> (i32, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_dbbcal"))
        .args(args)
        .current_dir(crate::support::root())
        .env("CI", "1")
        .envs(env.iter().copied())
        .output()
        .expect("run dbbcal");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `dbbcal run PIPELINE --out OUT` (a file under `pipelines/`), asserted to exit 0; its stderr.
pub(crate) fn run_pipeline_ok(pipeline: &str, out: &Path) -> String {
    let (code, _, stderr) = run_cli(&["run", pipeline, "--out", out.to_str().unwrap()]);
    assert_eq!(code, 0, "{pipeline}: {stderr}");
    stderr
}

/// `dbbcal run PIPELINE --campaign CAMPAIGN --out OUT EXTRA…`: (exit code, stdout and stderr
/// together).
pub(crate) fn run_on(pipeline: &str, campaign: &Path, out: &Path, extra: &[&str]) -> (i32, String) {
    let mut args = vec![
        "run",
        pipeline,
        "--campaign",
        campaign.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let (code, stdout, stderr) = run_cli(&args);
    (code, format!("{stdout}{stderr}"))
}

/// [`run_on`], asserted to exit 0, and the JSON record `record` it wrote in `out` (with the
/// run's output, for messages).
pub(crate) fn run_record(
    pipeline: &str,
    campaign: &Path,
    out: &Path,
    extra: &[&str],
    record: &str,
) -> (serde_json::Value, String) {
    let (code, said) = run_on(pipeline, campaign, out, extra);
    assert_eq!(code, 0, "{}: {said}", campaign.display());
    let text = std::fs::read_to_string(out.join(record))
        .unwrap_or_else(|e| panic!("{}: {e}", out.join(record).display()));
    (serde_json::from_str(&text).unwrap(), said)
}

/// The repository root, read when the test runs (cargo sets `CARGO_MANIFEST_DIR` for it; tests
/// also run there). Not `env!`: checkouts that share one target directory share this binary,
/// and a path baked in at compile time would point into whichever checkout built it.
pub(crate) fn root() -> PathBuf {
    std::env::var_os("CARGO_MANIFEST_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| std::env::current_dir().expect("the tests' working directory"))
}

pub(crate) type BasisFn = fn(x: f64, theta: &[f64]) -> Vec<f64>;

/// A model in closed separable form, `y = Σ_j c_j φ_j(x; θ)` (the NIST and TCLab reference
/// fits): its basis derivatives by central differences.
pub(crate) struct ClosedForm {
    pub(crate) x: Vec<f64>,
    pub(crate) y: Vec<f64>,
    pub(crate) n_nonlinear: usize,
    pub(crate) n_linear: usize,
    pub(crate) basis: BasisFn,
}

impl Separable for ClosedForm {
    fn observations(&self) -> &[f64] {
        &self.y
    }
    fn nonlinear_names(&self) -> Vec<String> {
        (0..self.n_nonlinear).map(|k| format!("t{k}")).collect()
    }
    fn linear_names(&self) -> Vec<String> {
        (0..self.n_linear).map(|k| format!("c{k}")).collect()
    }
    fn basis(&self, theta: &[f64]) -> DMatrix<f64> {
        DMatrix::from_fn(self.x.len(), self.n_linear, |i, j| {
            (self.basis)(self.x[i], theta)[j]
        })
    }
    fn basis_derivative(&self, theta: &[f64], k: usize) -> DMatrix<f64> {
        // Central difference, relative step: accurate to ~1e-10, ample for 6 certified digits.
        let h = 1e-6 * theta[k].abs().max(1e-8);
        let (mut tp, mut tm) = (theta.to_vec(), theta.to_vec());
        tp[k] += h;
        tm[k] -= h;
        DMatrix::from_fn(self.x.len(), self.n_linear, |i, j| {
            ((self.basis)(self.x[i], &tp)[j] - (self.basis)(self.x[i], &tm)[j]) / (2.0 * h)
        })
    }
}
