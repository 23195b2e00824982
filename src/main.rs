//! The `dbbcal` command line: clap flags are parsed first, then turned into a validated
//! [`RunPlan`] before any heavy IO; errors get their context here (anyhow) and one clear line.
//!
//! The commands that read campaign parquet run in a supervised child of this process
//! ([`dbbcal::supervise`]): a crash no `catch_unwind` can catch (a parquet decoder aborting on a
//! corrupt page) still ends in one line naming the file, exit 3, and nothing left in the output location.

use std::path::PathBuf;
use std::process::ExitCode;

use std::io::{IsTerminal, Write};

use anyhow::Context;
use clap::{Args, CommandFactory, Parser, Subcommand};

use dbbcal::pipeline::{RunPlan, Stage};
use dbbcal::runner::{self, RunStatus};
use dbbcal::supervise::{Crash, Ending, SupervisedAlloc};

use dbbcal::exit::Exit;
use dbbcal::kinds::KindPlan;

/// How long a probe of one file after a crash may take (`supervise::probe`).
const PROBE_LIMIT: std::time::Duration = std::time::Duration::from_secs(120);

const AFTER_HELP: &str = "Examples:
  dbbcal run pipelines/nightly.toml                      # the shipped sample -> reports/<campaign id>
  dbbcal run pipelines/nightly.toml --campaign /data/lab-a-2026-11 --out /tmp/out
  dbbcal run pipelines/reference-match.toml              # matching study with mismatch heat map
  dbbcal run pipelines/acceptance.toml --campaign DIR    # calibrate, compensate, accept working bars
  dbbcal calibrate --campaign DIR --out /tmp/cal          # centre-distance functions D(n, A)
  dbbcal identify --campaign data/sample --out /tmp/id --add-effect head_heating
  dbbcal simulate --config pipelines/sim-sample.toml --out /tmp/campaign
";

#[derive(Parser)]
#[command(name = "dbbcal", version, about = "Batch analysis of double-ballbar thermal campaigns", long_about = None,
    after_help = format!("{AFTER_HELP}\n{}", dbbcal::exit::help_text()))]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Print nothing but errors.
    #[arg(short, long, global = true)]
    quiet: bool,
    /// More detail on stderr: -v stage timings, -vv per-bar details (DBBCAL_LOG overrides).
    #[arg(short, long, action = clap::ArgAction::Count, global = true, conflicts_with = "quiet")]
    verbose: u8,
    /// Colour: auto (on a terminal, unless NO_COLOR is set), always, never.
    #[arg(long, value_enum, default_value_t = ColorWhen::Auto, global = true, value_name = "WHEN")]
    color: ColorWhen,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum ColorWhen {
    Auto,
    Always,
    Never,
}

impl ColorWhen {
    /// Whether to write ANSI colour to a stream that is (or is not) a terminal.
    fn enabled(self, terminal: bool) -> bool {
        match self {
            ColorWhen::Always => true,
            ColorWhen::Never => false,
            ColorWhen::Auto => {
                terminal && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty())
            }
        }
    }
}

#[derive(Subcommand)]
enum Command {
    // (see `Command::reads_campaign` when adding one)
    /// Run the staged jobs of a pipeline TOML (stages, model effects, options).
    Run {
        /// The pipeline file, e.g. pipelines/nightly.toml.
        pipeline: PathBuf,
        #[command(flatten)]
        io: IoArgs,
        #[command(flatten)]
        model: ModelArgs,
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
    /// Print an output folder's fit report (OUT/report.md) on the terminal.
    Show {
        /// An output folder of dbbcal.
        out: PathBuf,
    },
    /// Print a shell completion script (e.g. `dbbcal completions bash > ~/.local/share/bash-completion/completions/dbbcal`).
    Completions { shell: clap_complete::Shell },
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

impl Command {
    /// The commands that decode campaign parquet: they run in a supervised child.
    fn reads_campaign(&self) -> bool {
        match self {
            Command::Run { .. }
            | Command::Ingest(_)
            | Command::Identify(_)
            | Command::Match(_)
            | Command::Report(_)
            | Command::Calibrate(_)
            | Command::Compensate(_) => true,
            Command::Show { .. } | Command::Completions { .. } | Command::Simulate { .. } => false,
        }
    }
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
    #[command(flatten)]
    model: ModelArgs,
}

/// The model and compression overrides, the same for `run` and the stage subcommands.
#[derive(Args)]
struct ModelArgs {
    /// Model effects, replacing the pipeline's (default: the base model fixed_part, scale).
    #[arg(long, value_delimiter = ',', value_name = "NAMES")]
    effects: Vec<String>,
    /// Add an effect to the model: a name exactly as the diagnosis prints it (e.g.
    /// head_heating, second_path, lag:T2, rate:T1@600). Repeatable.
    #[arg(long = "add-effect", value_name = "NAME")]
    add_effect: Vec<String>,
    /// Compress the readings into bins of this many seconds, two weighted nodes a bin (exact for
    /// the fits; 0: every reading). Default: 60 when the bars log every 12 s or faster, else 0.
    #[arg(long = "bin-s", value_name = "SECONDS")]
    bin_s: Option<f64>,
}

/// mimalloc: see Cargo.toml for why and what it measured. The wrapper changes nothing but the
/// failure of an absurd allocation in a supervised child (`dbbcal::supervise`). Freed memory
/// stays in the process for reuse, without huge pages (`dbbcal::io::tune_memory`, first thing
/// in `main`).
#[global_allocator]
static GLOBAL: SupervisedAlloc<mimalloc::MiMalloc> = SupervisedAlloc(mimalloc::MiMalloc);

fn main() -> ExitCode {
    dbbcal::io::tune_memory();
    let supervised = dbbcal::supervise::child_init();
    if let Some(file) = std::env::var_os(dbbcal::supervise::PROBE_ENV).filter(|_| supervised) {
        // A probe (`supervise::probe`): the answer is whether this process survives.
        let _ = dbbcal::io::decode_whole_file(std::path::Path::new(&file));
        return Exit::Success.into();
    }
    let cli = Cli::parse();
    let color = cli.color.enabled(std::io::stderr().is_terminal());
    init_tracing(cli.verbose, color);
    let say = Say {
        quiet: cli.quiet,
        color,
    };
    if !supervised && cli.command.reads_campaign() {
        match dbbcal::supervise::run_self_supervised() {
            Ok(ending) => return supervisor_exit(ending, say),
            Err(e) => tracing::debug!("the run goes on without a supervisor: {e}"),
        }
    }
    dbbcal::output::install_signal_handlers();
    let started = std::time::Instant::now();
    match execute(cli.command, say, cli.color) {
        Ok(None) => Exit::Success.into(),
        Ok(Some(outcome)) => {
            say.outcome(&outcome, started.elapsed());
            match outcome.status {
                RunStatus::AllBars => Exit::Success.into(),
                RunStatus::SomeBarsFailed(n) => {
                    say.error(&format!("{n} bar(s) failed; the others were processed (see failed_bars in summary.json)"));
                    Exit::SomeBarsFailed.into()
                }
                RunStatus::NoBarSucceeded(failed) => {
                    say.error(&no_bar_succeeded(&failed));
                    Exit::NoBarSucceeded.into()
                }
            }
        }
        Err(e) => {
            say.error(&format!("error: {}", one_line(&e)));
            ExitCode::from(if e.chain().any(runner::is_busy_error) {
                Exit::OutputBusy
            } else if e.chain().any(runner::is_input_error) {
                Exit::UnusableInput
            } else {
                Exit::Other
            })
        }
    }
}

/// The supervisor's end: the child's exit code; or, when the child died from a signal, clean up
/// what it left beside the output and say one line: interrupted (128 + the signal), or crashed
/// (exit 3 when files were being decoded, they are named; else 1).
fn supervisor_exit(ending: Ending, say: Say) -> ExitCode {
    let (mut death, interrupted) = match ending {
        Ending::Exited(code) => {
            return ExitCode::from(u8::try_from(code).unwrap_or(Exit::Other.code()))
        }
        Ending::Interrupted(d) => (d, true),
        Ending::Crashed(d) => (d, false),
    };
    if death.fault_kill {
        // `DBBCAL_FAULT=kill@K` stands for a power cut: the supervisor dies too, unclean.
        // SAFETY: a signal to this process.
        unsafe { libc::kill(libc::getpid(), libc::SIGKILL) };
    }
    let cleanup = match death
        .output
        .as_deref()
        .map(dbbcal::output::clean_up_after_dead_run)
    {
        Some(Err(e)) => format!(" (could not clean up after it: {e})"),
        _ => String::new(),
    };
    if interrupted {
        say.error(&format!(
            "interrupted ({}); the previous output is unchanged{cleanup}",
            dbbcal::supervise::signal_name(death.signal)
        ));
        return ExitCode::from((128 + death.signal).clamp(0, 255) as u8);
    }
    if death.reading.len() > 1 && death.signal != libc::SIGKILL {
        // A scan of several files: find which of them crash the decoder alone.
        let crashed = dbbcal::supervise::probe(&death.reading, PROBE_LIMIT);
        if !crashed.is_empty() {
            death.reading = crashed;
        }
    }
    let crash = Crash(death);
    say.error(&format!("error: {crash}{cleanup}"));
    ExitCode::from(if crash.blames_input() {
        Exit::UnusableInput
    } else {
        Exit::Other
    })
}

fn no_bar_succeeded(failed: &[dbbcal::pipeline::BarFailure]) -> String {
    let reasons: Vec<String> = failed
        .iter()
        .map(|f| {
            let (bar, why) = (&f.bar, dbbcal::narrative::quality::failure(f));
            let why = why.strip_prefix(&format!("bar {bar}: ")).unwrap_or(&why);
            format!("{bar}: {why}")
        })
        .collect();
    format!(
        "no bar succeeded ({}); nothing written, the previous output is unchanged",
        reasons.join("; ")
    )
}

/// What the command line says on stderr, cargo's way: a right-aligned bold label, then text.
#[derive(Clone, Copy)]
struct Say {
    quiet: bool,
    color: bool,
}

impl Say {
    fn line(&self, label: &str, text: &str, style: &str) {
        // Paths and ids from the user's files: raw newlines and escape codes are escaped.
        let text = dbbcal::output::escape(text);
        if self.color {
            let _ = writeln!(std::io::stderr(), "\x1b[{style}m{label:>12}\x1b[0m {text}");
        } else {
            let _ = writeln!(std::io::stderr(), "{label:>12} {text}");
        }
    }

    /// The run's block: where the output is, the bars, the verdict, the next command.
    fn outcome(&self, outcome: &runner::Outcome, elapsed: std::time::Duration) {
        if self.quiet {
            return;
        }
        let Some(h) = &outcome.headline else {
            for (label, text) in &outcome.lines {
                let style = if *label == "Next" { "1;36" } else { "1;32" };
                self.line(label, text, style);
            }
            if let Some(out) = &outcome.out {
                self.line("Output", &out.display().to_string(), "1;32");
            }
            return;
        };
        let finished = format!(
            "{} on campaign {} in {:.1} s",
            h.pipeline,
            h.campaign,
            elapsed.as_secs_f64()
        );
        self.line("Finished", &finished, "1;32");
        if let Some(out) = &outcome.out {
            let page = out.join("index.html");
            let text = if page.is_file() {
                format!("{} (open {})", out.display(), page.display())
            } else {
                out.display().to_string()
            };
            self.line("Output", &text, "1;32");
        }
        for (label, text) in h.lines() {
            let style = match label {
                "Diagnosis" if text.starts_with("missing") => "1;33",
                "Note" => "1;33",
                "Acceptance" if !text.contains(" 0 do not") => "1;31",
                "Next" => "1;36",
                _ => "1;32",
            };
            self.line(label, &text, style);
        }
    }

    /// One line that always prints (errors and failures), `dbbcal: ` first.
    fn error(&self, text: &str) {
        let text = dbbcal::output::escape(text);
        if self.color {
            let _ = writeln!(std::io::stderr(), "\x1b[1;31mdbbcal:\x1b[0m {text}");
        } else {
            let _ = writeln!(std::io::stderr(), "dbbcal: {text}");
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

fn execute(
    command: Command,
    say: Say,
    color: ColorWhen,
) -> anyhow::Result<Option<runner::Outcome>> {
    let plan = match command {
        Command::Run {
            pipeline,
            io,
            model,
        } => match dbbcal::kinds::plan_run(&pipeline, io.campaign, io.out, &model.add_effect)? {
            KindPlan::Ballbar(plan) => with_model_overrides(*plan, &model)?,
            other => {
                if !model.effects.is_empty() || model.bin_s.is_some() {
                    anyhow::bail!(dbbcal::pipeline::PlanError::NotInCampaign(Box::new(
                        dbbcal::pipeline::PlanProblem::BallbarOptions
                    )));
                }
                return dbbcal::kinds::run(&other).map(Some);
            }
        },
        Command::Ingest(a) => stage_plan(Stage::Ingest, a)?,
        Command::Identify(a) => stage_plan(Stage::Identify, a)?,
        Command::Match(a) => stage_plan(Stage::Match, a)?,
        Command::Report(a) => stage_plan(Stage::Report, a)?,
        Command::Calibrate(a) => stage_plan(Stage::Calibrate, a)?,
        Command::Compensate(a) => stage_plan(Stage::Compensate, a)?,
        Command::Show { out } => {
            show(&out, color.enabled(std::io::stdout().is_terminal()))?;
            return Ok(None);
        }
        Command::Completions { shell } => {
            let mut cmd = Cli::command();
            clap_complete::generate(shell, &mut cmd, "dbbcal", &mut std::io::stdout());
            return Ok(None);
        }
        Command::Simulate { config, out, seed } => {
            runner::simulate(config.as_deref(), &out, seed)
                .with_context(|| format!("simulate into {}", out.display()))?;
            if !say.quiet {
                say.line("Simulated", &out.display().to_string(), "1;32");
            }
            return Ok(None);
        }
    };
    runner::run(&plan).map(Some)
}

fn stage_plan(stage: Stage, a: StageArgs) -> anyhow::Result<RunPlan> {
    let campaign =
        a.io.campaign
            .unwrap_or_else(|| PathBuf::from(dbbcal::pipeline::DEFAULT_CAMPAIGN_DIR));
    let mut effects = a.model.effects.clone();
    if effects.is_empty() && !a.model.add_effect.is_empty() {
        effects = dbbcal::model::base_effects()
            .iter()
            .map(|e| e.name())
            .collect();
    }
    effects.extend(a.model.add_effect.iter().cloned());
    let plan = RunPlan::for_stage(stage, campaign, a.io.out, &effects)?;
    Ok(plan.with_bin_s(a.model.bin_s)?)
}

/// `run`'s model overrides: `--effects` (replacing the pipeline's), `--add-effect`, `--bin-s`.
fn with_model_overrides(plan: RunPlan, m: &ModelArgs) -> anyhow::Result<RunPlan> {
    let plan = if m.effects.is_empty() && m.add_effect.is_empty() {
        plan
    } else {
        plan.with_effects(&m.effects, &m.add_effect)?
    };
    Ok(plan.with_bin_s(m.bin_s)?)
}

/// `dbbcal show OUT`: the fit report, headings and warnings coloured on a terminal.
fn show(out: &std::path::Path, color: bool) -> anyhow::Result<()> {
    let path = out.join("report.md");
    let text = std::fs::read_to_string(&path).with_context(|| {
        format!(
            "{}: no fit report here (is it an output folder of dbbcal?)",
            path.display()
        )
    })?;
    let mut stdout = std::io::stdout().lock();
    for line in text.lines() {
        let styled = if !color {
            line.to_string()
        } else if line.starts_with('#') {
            format!("\x1b[1;36m{line}\x1b[0m")
        } else if line.starts_with("- ") && line.contains(": the data do not bound")
            || line.contains("not identifiable")
            || line.contains("few independent batches")
        {
            format!("\x1b[33m{line}\x1b[0m")
        } else {
            line.to_string()
        };
        if writeln!(stdout, "{styled}").is_err() {
            break; // a closed pipe (`| head`) is no error
        }
    }
    Ok(())
}

/// Logs on stderr: warnings; `-v` adds the stage timings, `-vv` everything at debug level.
/// `DBBCAL_LOG` (a tracing filter) overrides.
fn init_tracing(verbose: u8, color: bool) {
    let default = match verbose {
        0 => "warn",
        1 => "warn,dbbcal=info",
        _ => "info,dbbcal=debug",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_env("DBBCAL_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(color)
        .with_target(false)
        .without_time()
        .init();
}
