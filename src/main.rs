//! The `dbbcal` command line: clap flags are parsed first, then turned into a validated
//! [`RunPlan`] before any heavy IO; errors get their context here (anyhow) and one clear line.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Args, Parser, Subcommand};

use dbbcal::pipeline::{RunPlan, Stage};
use dbbcal::runner::{self, RunStatus};

/// Exit codes (also in `--help` and the README). 2 is clap's for a command-line usage error.
const EXIT_OTHER: u8 = 1;
const EXIT_UNUSABLE_INPUT: u8 = 3;
const EXIT_SOME_BARS_FAILED: u8 = 4;
const EXIT_NO_BAR_SUCCEEDED: u8 = 5;
const EXIT_OUTPUT_BUSY: u8 = 6;

const AFTER_HELP: &str = "Examples:
  dbbcal run pipelines/nightly.toml                      # the shipped sample -> reports/<campaign id>
  dbbcal run pipelines/nightly.toml --campaign /data/lab-a-2026-11 --out /tmp/out
  dbbcal run pipelines/reference-match.toml              # matching study with mismatch heat map
  dbbcal run pipelines/acceptance.toml --campaign DIR    # calibrate, compensate, accept working bars
  dbbcal calibrate --campaign DIR --out /tmp/cal          # centre-distance functions D(n, A)
  dbbcal identify --campaign data/sample --out /tmp/id --add-effect head_heating
  dbbcal simulate --config pipelines/sim-sample.toml --out /tmp/campaign

Exit codes:
  0    every bar processed; the output is in place
  1    another error (e.g. the output could not be written); the previous output is unchanged
  2    command-line usage error (nothing read or written)
  3    unusable input or configuration, or an output location dbbcal may not write (refused
       before any work; the previous output is unchanged)
  4    some bars failed (see failed_bars in summary.json); the others are in the output
  5    no bar succeeded; nothing written, the previous output is unchanged
  6    another dbbcal run is writing the same output; nothing done
  130  interrupted (Ctrl-C; 143 for SIGTERM): the partial output removed, the previous unchanged";

#[derive(Parser)]
#[command(name = "dbbcal", version, about = "Batch analysis of double-ballbar thermal campaigns", long_about = None,
    after_help = AFTER_HELP)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the staged jobs of a pipeline TOML (stages, model effects, options).
    Run {
        /// The pipeline file, e.g. pipelines/nightly.toml.
        pipeline: PathBuf,
        #[command(flatten)]
        io: IoArgs,
        /// Add an effect to the pipeline's model: a name exactly as the diagnosis prints it
        /// (e.g. head_heating, second_path, lag:T2, rate:T1@600). Repeatable.
        #[arg(long = "add-effect", value_name = "NAME")]
        add_effect: Vec<String>,
    },
    /// Read and validate a campaign; write the input record.
    Ingest(StageArgs),
    /// Ingest, then identify every bar's thermal model.
    Identify(StageArgs),
    /// Ingest, identify, then pick the reference bar and compute mismatches.
    Match(StageArgs),
    /// Ingest, identify, match, then render PNG figures.
    Report(StageArgs),
    /// Ingest, identify, then fit each bar's centre-distance function D(n, A) from its plate
    /// mounts (form chosen by leave-one-point-out cross-validation) -> calibration.json.
    Calibrate(StageArgs),
    /// Calibrate, then compensate the working bars (check lengths, devices) with the reference
    /// bars (two, one) or the identified models -> compensation.json, compensated.parquet.
    Compensate(StageArgs),
    /// Write a simulated campaign (with truth.json) from a simulation TOML.
    Simulate {
        /// Simulation config (see pipelines/sim-sample.toml); defaults when absent.
        #[arg(long)]
        config: Option<PathBuf>,
        /// Output campaign directory (must not exist yet).
        #[arg(long)]
        out: PathBuf,
        /// Override the config's random seed.
        #[arg(long)]
        seed: Option<u64>,
    },
}

#[derive(Args)]
struct IoArgs {
    /// Campaign directory (default: the pipeline's, else data/sample).
    #[arg(long)]
    campaign: Option<PathBuf>,
    /// Output directory (default: reports/<campaign id>). Written only if absent, empty or an
    /// earlier dbbcal output (it holds dbbcal-output.json); swapped in whole at the end, the
    /// previous one kept as OUT.prev.
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Args)]
struct StageArgs {
    #[command(flatten)]
    io: IoArgs,
    /// Model effects (default: the base model fixed_part, scale).
    #[arg(long, value_delimiter = ',', value_name = "NAMES")]
    effects: Vec<String>,
    /// Add an effect to the model (repeatable).
    #[arg(long = "add-effect", value_name = "NAME")]
    add_effect: Vec<String>,
    /// Compress the readings into bins of this many seconds, two weighted nodes a bin (exact for
    /// the fits; 0: every reading). Default: 60 when the bars log every 6 s or faster, else 0.
    #[arg(long = "bin-s", value_name = "SECONDS")]
    bin_s: Option<f64>,
}

/// mimalloc: see Cargo.toml for why and what it measured.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> ExitCode {
    init_tracing();
    let cli = Cli::parse();
    dbbcal::output::install_signal_handlers();
    match execute(cli) {
        Ok(RunStatus::AllBars) => ExitCode::SUCCESS,
        Ok(RunStatus::SomeBarsFailed(n)) => {
            eprintln!("dbbcal: {n} bar(s) failed; the others were processed (see failed_bars in summary.json)");
            ExitCode::from(EXIT_SOME_BARS_FAILED)
        }
        Ok(RunStatus::NoBarSucceeded(failed)) => {
            let reasons: Vec<String> = failed
                .iter()
                .map(|(bar, why)| {
                    let why = why.strip_prefix(&format!("bar {bar}: ")).unwrap_or(why);
                    format!("{bar}: {why}")
                })
                .collect();
            eprintln!(
                "dbbcal: no bar succeeded ({}); nothing written, the previous output is unchanged",
                reasons.join("; ")
            );
            ExitCode::from(EXIT_NO_BAR_SUCCEEDED)
        }
        Err(e) => {
            eprintln!("dbbcal: error: {}", one_line(&e));
            ExitCode::from(if e.chain().any(runner::is_busy_error) {
                EXIT_OUTPUT_BUSY
            } else if e.chain().any(runner::is_input_error) {
                EXIT_UNUSABLE_INPUT
            } else {
                EXIT_OTHER
            })
        }
    }
}

/// The error and its causes on one line.
fn one_line(e: &anyhow::Error) -> String {
    let mut parts: Vec<String> = Vec::new();
    for cause in e.chain() {
        let s = cause.to_string();
        if !parts.iter().any(|p| p.contains(&s)) {
            parts.push(s);
        }
    }
    parts.join(": ")
}

fn execute(cli: Cli) -> anyhow::Result<RunStatus> {
    match cli.command {
        Command::Run {
            pipeline,
            io,
            add_effect,
        } => {
            let plan = RunPlan::from_pipeline_file(&pipeline, io.campaign, io.out, &add_effect)?;
            runner::run(&plan)
        }
        Command::Ingest(a) => stage(Stage::Ingest, a),
        Command::Identify(a) => stage(Stage::Identify, a),
        Command::Match(a) => stage(Stage::Match, a),
        Command::Report(a) => stage(Stage::Report, a),
        Command::Calibrate(a) => stage(Stage::Calibrate, a),
        Command::Compensate(a) => stage(Stage::Compensate, a),
        Command::Simulate { config, out, seed } => {
            runner::simulate(config.as_deref(), &out, seed)
                .with_context(|| format!("simulate into {}", out.display()))?;
            Ok(RunStatus::AllBars)
        }
    }
}

fn stage(stage: Stage, a: StageArgs) -> anyhow::Result<RunStatus> {
    let mut effects = a.effects;
    if effects.is_empty() && !a.add_effect.is_empty() {
        effects = dbbcal::model::base_effects()
            .iter()
            .map(|e| e.name())
            .collect();
    }
    effects.extend(a.add_effect);
    let campaign =
        a.io.campaign
            .unwrap_or_else(|| PathBuf::from("data/sample"));
    if a.bin_s
        .is_some_and(|b| !(0.0..=dbbcal::series::MAX_BIN_S).contains(&b))
    {
        anyhow::bail!(dbbcal::pipeline::PlanError::Pipeline {
            path: "--bin-s".into(),
            message: format!("must be between 0 and {} s", dbbcal::series::MAX_BIN_S)
        });
    }
    let mut plan = RunPlan::for_stage(stage, campaign, a.io.out, &effects)?;
    if let Some(bin_s) = a.bin_s {
        (plan.bin_s, plan.automatic_bins) = (bin_s, false);
    }
    runner::run(&plan)
}

fn init_tracing() {
    let filter = tracing_subscriber::EnvFilter::try_from_env("DBBCAL_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn"));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .init();
}
