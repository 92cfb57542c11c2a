//! The `hil-sim` command line (clap derive): `compare`, `run`, `montecarlo`,
//! `merge`, `bench`. The binary is a thin wrapper around [`main_entry`]; everything
//! here is library code so tests can drive it.

use crate::bench::{run_bench, BenchConfig};
use crate::montecarlo::{
    run_records, stats_table, ControllerStats, McConfig, McRecords, McResult, Outcome, MAX_RUNS,
};
use crate::report::{human_summary, metrics_table, scenario_summary, write_trace_csv, RunReport};
use crate::scenario::{Scenario, Sensing, TrajectoryKind};
use crate::scenario_file::load_scenario;
use crate::shard::{default_shard_path, merge_shards, write_shard, Shard, ShardHeader};
use crate::sim::{controller_config, run_with, SimOutput};
use clap::{Args, Parser, Subcommand, ValueEnum};
use controller_core::ControllerKind;
use rayon::prelude::*;
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Host simulator: the controller-core controllers against the paper's
/// differential-drive robot with slip, skid, disturbance and actuator fault.
#[derive(Debug, Parser)]
#[command(name = "hil-sim", version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Both paper cases x the three controllers: metrics table, plots, metrics.json.
    Compare(CompareArgs),
    /// One scenario with one controller.
    Run(Box<RunArgs>),
    /// N random paper scenarios per controller, in parallel: mean/p95/max of every metric
    /// (or, with --shard, one slice of the runs written to a file for `merge`).
    Montecarlo(McArgs),
    /// Combines shard files of `montecarlo --shard` into the statistics of one run.
    Merge(MergeArgs),
    /// Time per 40 s paper scenario and Monte-Carlo throughput on this machine.
    Bench(BenchArgs),
    /// The simulated robot behind the host link: prints a pseudo-terminal's path
    /// (first stdout line) for `wmr --port PATH ...`.
    Device(Box<crate::cli_link::DeviceArgs>),
    /// Metrics and plots of a trace CSV (`hil-sim run --csv` or `wmr record`).
    Report(crate::cli_link::ReportArgs),
}

/// The controller to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ControllerArg {
    /// SMC without observer (fixed switching gain).
    Smc,
    /// Adaptive SMC without observer.
    Asmc,
    /// Fault observer + fal-ESO + adaptive SMC (the paper's).
    Proposed,
}

impl From<ControllerArg> for ControllerKind {
    fn from(c: ControllerArg) -> Self {
        match c {
            ControllerArg::Smc => ControllerKind::Smc,
            ControllerArg::Asmc => ControllerKind::Asmc,
            ControllerArg::Proposed => ControllerKind::Proposed,
        }
    }
}

/// `compare` options.
#[derive(Debug, Args)]
pub struct CompareArgs {
    /// Seed for β, ε (and noise).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory for the plots and metrics.json.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    /// Wheel slip amplitude β [rad/s] (default: drawn from the seed in (0, 0.2)).
    #[arg(long)]
    pub beta: Option<f64>,
    /// Actuator fault ε of Case 2 (default: drawn from the seed in (0.125, 0.25)).
    #[arg(long)]
    pub eps: Option<f64>,
    /// Print the rows as one JSON array instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Skip the plots (table and metrics.json only).
    #[arg(long)]
    pub no_plots: bool,
}

/// Scenario selection and overrides shared by `run`.
#[derive(Debug, Args, Default, Clone)]
pub struct ScenarioArgs {
    /// Paper preset: 1 = disturbance + slip, 2 = + actuator fault [default: 2].
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=2), conflicts_with = "scenario")]
    pub case: Option<u8>,
    /// Scenario TOML file (schema: docs/scenario.md); the flags below override it.
    #[arg(long, value_name = "FILE.toml")]
    pub scenario: Option<PathBuf>,
    /// Seed: draws β, ε of the preset, and the measurement noise.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Wheel slip amplitude β [rad/s].
    #[arg(long)]
    pub beta: Option<f64>,
    /// Actuator fault ε in [0, 1) (body moves at (1 − ε)·η in the window).
    #[arg(long)]
    pub eps: Option<f64>,
    /// Scale of the lateral skid δ_sl (1 = as printed in the paper).
    #[arg(long)]
    pub skid_scale: Option<f64>,
    /// Disturbance amplitude A [N·m].
    #[arg(long, value_name = "N·m")]
    pub disturbance: Option<f64>,
    /// Per-wheel torque limit [N·m].
    #[arg(long, value_name = "N·m")]
    pub torque_limit: Option<f64>,
    /// Plant mass / controller model mass.
    #[arg(long)]
    pub mass_scale: Option<f64>,
    /// Plant inertia / controller model inertia.
    #[arg(long)]
    pub inertia_scale: Option<f64>,
    /// Reference trajectory.
    #[arg(long, value_enum)]
    pub trajectory: Option<TrajectoryKind>,
    /// Run length [s].
    #[arg(long, value_name = "s")]
    pub duration: Option<f64>,
    /// Sensor preset between plant and controller: the paper's ideal
    /// measurements, or the firmware runtime behind simulated encoders and
    /// PWM with a gyro (imu) and an external pose (mocap, uwb); the
    /// --gyro-* and --pose-* flags override the preset (docs/scenario.md).
    #[arg(long, value_enum)]
    pub sensing: Option<Sensing>,
    /// Gyro noise density [rad/s/√Hz].
    #[arg(long)]
    pub gyro_noise_density: Option<f64>,
    /// Gyro initial bias [rad/s].
    #[arg(long, value_name = "rad/s", allow_negative_numbers = true)]
    pub gyro_bias: Option<f64>,
    /// Gyro bias random walk [rad/s/√s].
    #[arg(long)]
    pub gyro_bias_walk: Option<f64>,
    /// Gyro scale-factor error (0.01 = 1 % high).
    #[arg(long, allow_negative_numbers = true)]
    pub gyro_scale_error: Option<f64>,
    /// Gyro full scale [rad/s].
    #[arg(long, value_name = "rad/s")]
    pub gyro_saturation: Option<f64>,
    /// Gyro output rate [Hz].
    #[arg(long, value_name = "Hz")]
    pub gyro_rate: Option<f64>,
    /// External pose rate [Hz].
    #[arg(long, value_name = "Hz")]
    pub pose_rate: Option<f64>,
    /// External pose latency [s].
    #[arg(long, value_name = "s")]
    pub pose_latency: Option<f64>,
    /// External pose extra latency, uniform in [0, jitter] [s].
    #[arg(long, value_name = "s")]
    pub pose_jitter: Option<f64>,
    /// External pose position noise std. dev. [m].
    #[arg(long, value_name = "m")]
    pub pose_std: Option<f64>,
    /// External pose heading noise std. dev. [rad] (0 = no heading).
    #[arg(long, value_name = "rad")]
    pub pose_heading_std: Option<f64>,
    /// Probability that an external pose is lost.
    #[arg(long)]
    pub pose_dropout: Option<f64>,
    /// Outage of the external pose from START to END [s] (e.g. 20,22).
    #[arg(
        long,
        value_name = "START,END",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    pub pose_outage: Option<Vec<f64>>,
    /// Fraction of external poses that are outliers.
    #[arg(long)]
    pub pose_outlier_fraction: Option<f64>,
    /// Position error of an outlier [m].
    #[arg(long, value_name = "m")]
    pub pose_outlier: Option<f64>,
    /// Firmware sensing: encoder counts per wheel revolution (0 = example's 24000).
    #[arg(long)]
    pub encoder_cpr: Option<u32>,
    /// Firmware sensing: speed-estimate window [ticks] (0 = example's 4).
    #[arg(long, value_name = "TICKS")]
    pub speed_window: Option<u8>,
    /// Firmware sensing: PWM counts at full duty (0 = example's 4800).
    #[arg(long)]
    pub pwm_levels: Option<u32>,
    /// Std. dev. of the position measurement noise [m].
    #[arg(long, value_name = "m")]
    pub pose_noise: Option<f64>,
    /// Std. dev. of the heading measurement noise [rad].
    #[arg(long, value_name = "rad")]
    pub heading_noise: Option<f64>,
    /// Kinematic gain k_y override.
    #[arg(long)]
    pub k_y: Option<f64>,
    /// Controller period [s].
    #[arg(long, value_name = "s")]
    pub control_period: Option<f64>,
    /// RK4 sub-steps per control period.
    #[arg(long)]
    pub substeps: Option<u32>,
    /// Reference governor and health machine (beyond the paper; default on).
    #[arg(long, value_name = "BOOL", action = clap::ArgAction::Set)]
    pub governor: Option<bool>,
    /// Large-error bound of the kinematic law (clean start; default on).
    #[arg(long, value_name = "BOOL", action = clap::ArgAction::Set)]
    pub clean_start: Option<bool>,
    /// Growing fault: ε at the window's end, ramped from --eps at its start.
    #[arg(long)]
    pub eps_end: Option<f64>,
    /// Fraction of its torque the left wheel delivers in the window (weak wheel).
    #[arg(long, value_name = "FRACTION")]
    pub left_torque_scale: Option<f64>,
}

impl ScenarioArgs {
    /// The scenario: the file or the paper preset, then the flags on top;
    /// validated.
    pub fn build(&self) -> Result<Scenario, String> {
        let mut scn = match &self.scenario {
            Some(path) => {
                let mut s = load_scenario(path)?;
                if let Some(seed) = self.seed {
                    s.seed = seed;
                }
                s
            }
            None => {
                Scenario::paper_case(self.case.unwrap_or(2), self.seed.unwrap_or(1), None, None)
            }
        };
        macro_rules! set {
            ($($flag:ident => $field:ident),* $(,)?) => {
                $( if let Some(v) = self.$flag { scn.$field = v.into(); } )*
            };
        }
        set!(
            beta => beta,
            eps => eps,
            skid_scale => skid_scale,
            disturbance => disturbance_nm,
            torque_limit => torque_limit_nm,
            mass_scale => mass_scale,
            inertia_scale => inertia_scale,
            trajectory => trajectory,
            duration => duration_s,
            sensing => sensing,
            encoder_cpr => encoder_cpr,
            speed_window => speed_window_ticks,
            pwm_levels => pwm_levels,
            pose_noise => pose_noise_m,
            heading_noise => heading_noise_rad,
            control_period => control_period_s,
            substeps => substeps,
            governor => governor,
            clean_start => clean_start,
            gyro_noise_density => gyro_noise_density,
            gyro_bias => gyro_bias_radps,
            gyro_bias_walk => gyro_bias_walk,
            gyro_scale_error => gyro_scale_error,
            gyro_saturation => gyro_saturation_radps,
            gyro_rate => gyro_rate_hz,
            pose_rate => pose_rate_hz,
            pose_latency => pose_latency_s,
            pose_jitter => pose_jitter_s,
            pose_std => pose_std_m,
            pose_heading_std => pose_heading_std_rad,
            pose_dropout => pose_dropout,
            pose_outlier_fraction => pose_outlier_fraction,
            pose_outlier => pose_outlier_m,
        );
        if let Some(w) = &self.pose_outage {
            match w[..] {
                [a, b] => scn.pose_outage_s = Some([a, b]),
                _ => return Err("--pose-outage takes START,END (two numbers)".into()),
            }
        }
        if let Some(k) = self.k_y {
            scn.k_y = Some(k);
        }
        if let Some(e) = self.eps_end {
            scn.eps_end = Some(e);
        }
        if let Some(k) = self.left_torque_scale {
            scn.wheel_torque_scale[1] = k;
        }
        scn.validate()?;
        Ok(scn)
    }
}

/// `run` options.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// Controller.
    #[arg(long, value_enum, default_value = "proposed")]
    pub controller: ControllerArg,
    /// Scenario.
    #[command(flatten)]
    pub scenario: ScenarioArgs,
    /// Write the trace (every TraceSample field, with a header) to this CSV file.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Trace decimation for --csv: one row every N control steps [default: 10 ms worth].
    #[arg(long, value_name = "N")]
    pub csv_every: Option<usize>,
    /// Print exactly one JSON object (the metrics plus "controller", "scenario", "rejected_steps").
    #[arg(long)]
    pub json: bool,
}

/// `montecarlo` options.
#[derive(Debug, Args)]
pub struct McArgs {
    /// Runs per controller.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=MAX_RUNS))]
    pub runs: u64,
    /// Paper case.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(1..=2))]
    pub case: u8,
    /// Base seed; run i uses a seed derived from (seed, i).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Also draw the plant mass scale in [0.8, 1.2].
    #[arg(long)]
    pub vary_mass: bool,
    /// Run length [s] [default: the paper's 40 s].
    #[arg(long, value_name = "s")]
    pub duration: Option<f64>,
    /// Sensing preset of every run (docs/scenario.md).
    #[arg(long, value_enum, default_value = "ideal")]
    pub sensing: Sensing,
    /// Every run in the paper's setting (no governor or health machine, law (14)
    /// as printed), as `compare`'s first table.
    #[arg(long)]
    pub paper_setting: bool,
    /// Run only shard I of N (0-based: 0/N … N-1/N), a contiguous block of the run
    /// indices with the same seeds as the unsharded run; write its raw results to
    /// --out (default mc-case<C>-seed<S>-runs<R>-shard<I>of<N>.jsonl) for `merge`.
    #[arg(long, value_name = "I/N", value_parser = Shard::parse)]
    pub shard: Option<Shard>,
    /// Write the raw per-run results (JSON Lines, the shard file format) to FILE.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Print the statistics as JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// `merge` options.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// Shard files written by `montecarlo --shard I/N` (any order; together they must
    /// hold every run index of one sweep exactly once).
    #[arg(required = true, value_name = "FILE")]
    pub files: Vec<PathBuf>,
    /// Print the statistics as JSON instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// `bench` options.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Repetitions per controller (the median is reported).
    #[arg(long, default_value_t = 9, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub reps: u64,
    /// Monte-Carlo runs per controller for the throughput figure.
    #[arg(long, default_value_t = 40, value_parser = clap::value_parser!(u64).range(1..=100_000))]
    pub mc_runs: u64,
}

/// One row of `compare`: a paper case with one controller.
#[derive(Debug, Serialize)]
pub struct CompareRow {
    /// Paper case (1 or 2).
    pub case: u8,
    /// The run.
    #[serde(flatten)]
    pub report: RunReport,
}

/// Runs both paper cases with the three controllers in parallel (traced),
/// in the paper's setting ([`Scenario::as_printed`]: no governor, no
/// large-error bound) unless `beyond_paper`.
pub fn compare_runs(
    seed: u64,
    beta: Option<f64>,
    eps: Option<f64>,
    beyond_paper: bool,
) -> Result<Vec<CaseRuns>, String> {
    let cases: Vec<(u8, Scenario)> = [1u8, 2]
        .iter()
        .map(|&c| {
            let s = Scenario::paper_case(c, seed, beta, eps);
            (c, if beyond_paper { s } else { s.as_printed() })
        })
        .collect();
    for (_, s) in &cases {
        s.validate()?;
    }
    let jobs: Vec<(usize, ControllerKind)> = (0..cases.len())
        .flat_map(|i| ControllerKind::ALL.map(|k| (i, k)))
        .collect();
    let outs: Vec<Result<SimOutput, String>> = jobs
        .par_iter()
        .map(|&(i, k)| crate::sim::run(&cases[i].1, k))
        .collect();
    let mut outs = outs.into_iter();
    let mut res = Vec::new();
    for (c, s) in cases {
        let runs = outs
            .by_ref()
            .take(ControllerKind::ALL.len())
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| format!("case {c}: {e}"))?;
        res.push((c, s, runs));
    }
    Ok(res)
}

/// A case's simulations: the paper case number, its scenario and one output
/// per controller (in [`ControllerKind::ALL`] order).
pub type CaseRuns = (u8, Scenario, Vec<SimOutput>);

/// One [`CompareRow`] per case × controller, in the order of `results`.
pub fn compare_rows(results: &[CaseRuns]) -> Vec<CompareRow> {
    results
        .iter()
        .flat_map(|(c, s, runs)| {
            runs.iter().map(move |o| CompareRow {
                case: *c,
                report: RunReport::new(o.kind, s, o),
            })
        })
        .collect()
}

/// The rows as pretty JSON (the content of `metrics.json` and of `compare --json`).
pub fn compare_json(rows: &[CompareRow]) -> Result<String, String> {
    serde_json::to_string_pretty(rows).map_err(|e| e.to_string())
}

/// Writes `json` to `dir/metrics.json` (creating `dir`); returns the path.
pub fn write_metrics_json(dir: &Path, json: &str) -> Result<PathBuf, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let path = dir.join("metrics.json");
    std::fs::write(&path, format!("{json}\n"))
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    Ok(path)
}

/// Title of a case's figures, e.g. `Case 2 (β = 0.183 rad/s, ε = 0.152)`.
fn case_plot_title(case: u8, scn: &Scenario) -> String {
    format!(
        "Case {case} (β = {:.3} rad/s{})",
        scn.beta,
        if scn.eps > 0.0 {
            format!(", ε = {:.3}", scn.eps)
        } else {
            String::new()
        }
    )
}

/// Draws every case's figures into `dir` (cases in parallel), file names
/// `case<N><suffix>_<figure>`; the files written, per case.
pub fn draw_compare_plots(
    dir: &Path,
    results: &[CaseRuns],
    suffix: &str,
) -> Result<Vec<Vec<PathBuf>>, String> {
    results
        .par_iter()
        .map(|(c, s, runs)| {
            crate::plot::write_case_plots(
                dir,
                &format!("case{c}{suffix}"),
                &case_plot_title(*c, s),
                s,
                runs,
            )
        })
        .collect()
}

/// The text `compare` prints without `--json`: the scenarios, the metrics
/// table with its legend, the timing and where the files went.
fn compare_text(
    results: &[CaseRuns],
    rows: &[CompareRow],
    sim_time: std::time::Duration,
    metrics_path: &Path,
    plot_files: Option<(&[Vec<PathBuf>], &Path)>,
) -> String {
    let mut text = String::new();
    for (c, s, _) in results {
        text += &format!("case {c}: {}\n", scenario_summary(s));
    }
    text.push('\n');
    let table_rows: Vec<(Vec<String>, crate::Metrics)> = rows
        .iter()
        .map(|r| {
            (
                vec![r.case.to_string(), r.report.controller.to_string()],
                r.report.metrics.clone(),
            )
        })
        .collect();
    text += &metrics_table(&["case", "controller"], &table_rows);
    text += "\nrms: whole run; rms_win/max_win: perturbation window 10-35 s; rms_t>5: t >= 5 s; \
settle: error stays < 0.1 m until the window;\nsat: steps at the torque limit; F_rmse: RMS |F̂ − F| over the window (proposed only)\n";
    text += &format!(
        "\n6 simulations in {:.0} ms ({} threads); metrics written to {}\n",
        sim_time.as_secs_f64() * 1e3,
        rayon::current_num_threads(),
        metrics_path.display()
    );
    if let Some((files, dir)) = plot_files {
        if !files.is_empty() {
            text += &format!(
                "{} plot files written to {} (case<N>_{{xy,errors,velocities,torques,faults}}.{{png,svg}})\n",
                files.iter().map(Vec::len).sum::<usize>(),
                dir.display()
            );
        }
    }
    text
}

/// The second part of `compare`'s text: the same runs with the reference
/// governor, the health machine and the large-error bound (the defaults
/// beyond the paper), with their columns.
fn beyond_paper_text(
    rows: &[CompareRow],
    metrics_path: &Path,
    plot_files: Option<(&[Vec<PathBuf>], &Path)>,
) -> String {
    let table_rows: Vec<(Vec<String>, crate::Metrics)> = rows
        .iter()
        .map(|r| {
            (
                vec![r.case.to_string(), r.report.controller.to_string()],
                r.report.metrics.clone(),
            )
        })
        .collect();
    let mut text = String::from(
        "\nBeyond the paper (the simulator's and the runtime's default): reference governor, \
health machine, large-error bound of the kinematic law; error against the governed reference\n\n",
    );
    text += &crate::report::metrics_table_with(
        &["case", "controller"],
        &table_rows,
        &crate::report::PACE_COLUMNS,
    );
    text +=
        "\nlag: t − τ at the end (how far the governed reference is behind the nominal clock); \
s_min: smallest time scale;\ndegr: steps in a degraded health mode; h_tr: health transitions\n";
    text += &format!("\nmetrics written to {}\n", metrics_path.display());
    if let Some((files, dir)) = plot_files {
        if !files.is_empty() {
            text += &format!(
                "{} plot files written to {} (case<N>_gov_{{xy,errors,velocities,torques,faults,pacing}}.{{png,svg}})\n",
                files.iter().map(Vec::len).sum::<usize>(),
                dir.display()
            );
        }
    }
    text
}

/// The sensing presets `compare` also shows (Case 2 through the firmware
/// runtime), after the paper's ideal table.
pub const COMPARE_SENSING: [Sensing; 2] = [Sensing::Mocap, Sensing::Odometry];

/// Case 2 of `compare` under each of [`COMPARE_SENSING`], the three
/// controllers in parallel (traced): (preset, scenario, outputs).
pub fn compare_sensing_runs(
    seed: u64,
    beta: Option<f64>,
    eps: Option<f64>,
) -> Result<Vec<(Sensing, Scenario, Vec<SimOutput>)>, String> {
    let scns: Vec<Scenario> = COMPARE_SENSING
        .iter()
        .map(|&sensing| Scenario {
            sensing,
            ..Scenario::paper_case(2, seed, beta, eps).as_printed()
        })
        .collect();
    let jobs: Vec<(usize, ControllerKind)> = (0..scns.len())
        .flat_map(|i| ControllerKind::ALL.map(|k| (i, k)))
        .collect();
    let outs: Vec<Result<SimOutput, String>> = jobs
        .par_iter()
        .map(|&(i, k)| crate::sim::run(&scns[i], k))
        .collect();
    let mut outs = outs.into_iter();
    let mut res = Vec::new();
    for scn in scns {
        let runs = outs
            .by_ref()
            .take(ControllerKind::ALL.len())
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| format!("case 2, sensing {}: {e}", scn.sensing.name()))?;
        res.push((scn.sensing, scn, runs));
    }
    Ok(res)
}

/// The sensing block of `compare`: one table of Case 2 per preset and
/// controller, with the estimator's counts.
fn compare_sensing_text(results: &[(Sensing, Scenario, Vec<SimOutput>)]) -> String {
    let rows: Vec<(Vec<String>, crate::Metrics)> = results
        .iter()
        .flat_map(|(sensing, _, runs)| {
            runs.iter().map(move |o| {
                (
                    vec![sensing.name().to_string(), o.kind.name().to_string()],
                    o.metrics.clone(),
                )
            })
        })
        .collect();
    let mut text = String::from(
        "\ncase 2 through the firmware runtime, paper setting (what sensing costs on a robot; docs/scenario.md):\n",
    );
    text += &metrics_table(&["sensing", "controller"], &rows);
    text += "mocap: encoders, gyro, pose at 100 Hz 10 ms late 2 mm / 0.005 rad; odometry: encoders only\n";
    text
}

/// `compare`: run, write metrics.json, draw the plots, print (the paper's
/// setting first, exactly as before the governor existed; then the same
/// with the governor on, into `metrics_governor.json` and `case<N>_gov_*`);
/// a plot error is returned after the tables have been printed.
fn compare(a: &CompareArgs, out: &mut dyn Write) -> Result<(), String> {
    let t0 = std::time::Instant::now();
    let results = compare_runs(a.seed, a.beta, a.eps, false)?;
    let sim_time = t0.elapsed();
    let sensing = compare_sensing_runs(a.seed, a.beta, a.eps)?;
    let rows = compare_rows(&results);
    let json = compare_json(&rows)?;
    let metrics_path = write_metrics_json(&a.out, &json)?;
    let sensing_rows: Vec<serde_json::Value> = sensing
        .iter()
        .flat_map(|(s, scn, runs)| {
            runs.iter().map(move |o| {
                serde_json::json!({
                    "case": 2,
                    "sensing": s.name(),
                    "report": RunReport::new(o.kind, scn, o),
                })
            })
        })
        .collect();
    let sensing_json = serde_json::to_string_pretty(&sensing_rows).map_err(|e| e.to_string())?;
    let sensing_path = a.out.join("metrics_sensing.json");
    std::fs::write(&sensing_path, format!("{sensing_json}\n"))
        .map_err(|e| format!("cannot write {}: {e}", sensing_path.display()))?;
    let plots = if a.no_plots {
        Ok(Vec::new())
    } else {
        draw_compare_plots(&a.out, &results, "").and_then(|mut p| {
            for (s, scn, runs) in &sensing {
                p.push(crate::plot::write_case_plots(
                    &a.out,
                    &format!("case2_{}", s.name()),
                    &format!("{}, sensing {}", case_plot_title(2, scn), s.name()),
                    scn,
                    runs,
                )?);
            }
            Ok(p)
        })
    };
    // The same with the governor (the defaults beyond the paper).
    let gov = compare_runs(a.seed, a.beta, a.eps, true)?;
    let gov_rows = compare_rows(&gov);
    let gov_json = compare_json(&gov_rows)?;
    let gov_path = a.out.join("metrics_governor.json");
    std::fs::write(&gov_path, format!("{gov_json}\n"))
        .map_err(|e| format!("cannot write {}: {e}", gov_path.display()))?;
    let gov_plots = if a.no_plots {
        Ok(Vec::new())
    } else {
        draw_compare_plots(&a.out, &gov, "_gov")
    };
    let text = if a.json {
        format!("{json}\n")
    } else {
        let plot_files = plots.as_ref().ok().map(|p| (p.as_slice(), a.out.as_path()));
        let gov_files = gov_plots
            .as_ref()
            .ok()
            .map(|p| (p.as_slice(), a.out.as_path()));
        compare_text(&results, &rows, sim_time, &metrics_path, plot_files)
            + &compare_sensing_text(&sensing)
            + &format!("sensing metrics written to {}\n", sensing_path.display())
            + &beyond_paper_text(&gov_rows, &gov_path, gov_files)
    };
    out.write_all(text.as_bytes()).map_err(|e| e.to_string())?;
    plots.and(gov_plots).map(|_| ())
}

fn run_cmd(a: &RunArgs, out: &mut dyn Write) -> Result<(), String> {
    let scn = a.scenario.build()?;
    if a.scenario.case == Some(1) && a.scenario.eps.is_some_and(|e| e > 0.0) {
        eprintln!("note: --eps with --case 1 injects the actuator fault of Case 2");
    }
    let kind: ControllerKind = a.controller.into();
    let every = match (a.csv.is_some(), a.csv_every) {
        (false, _) => 0,
        (true, Some(n)) => n.max(1),
        (true, None) => crate::sim::trace_every(&scn),
    };
    let res = run_with(&scn, controller_config(&scn, kind), every)?;
    if let Some(path) = &a.csv {
        let f = std::fs::File::create(path)
            .map_err(|e| format!("cannot create {}: {e}", path.display()))?;
        write_trace_csv(std::io::BufWriter::new(f), &res.trace)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    }
    let text = if a.json {
        RunReport::new(kind, &scn, &res).to_json() + "\n"
    } else {
        let mut t = human_summary(kind, &scn, &res);
        if let Some(p) = &a.csv {
            t += &format!(
                "  trace: {} rows written to {}\n",
                res.trace.len(),
                p.display()
            );
        }
        t
    };
    out.write_all(text.as_bytes()).map_err(|e| e.to_string())
}

/// A progress bar on stderr for `total` simulations (hidden with `quiet`).
fn progress_bar(total: u64, quiet: bool) -> indicatif::ProgressBar {
    if quiet {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::with_draw_target(
        Some(total),
        indicatif::ProgressDrawTarget::stderr(),
    );
    pb.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos}/{len} simulations, eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    pb
}

/// The error of a sweep with `failed` simulations, after its output;
/// `where_` says where their messages are.
fn failed_error(failed: usize, where_: &str) -> Result<(), String> {
    if failed > 0 {
        return Err(format!("{failed} simulations failed ({where_})"));
    }
    Ok(())
}

/// The sweep's description and statistics table, as both `montecarlo` and
/// `merge` print them (followed by one line on timing or shard files).
fn mc_text(sweep: &McConfig, stats: &[ControllerStats]) -> String {
    format!("{}\n\n{}\n", sweep.describe(), stats_table(stats))
}

/// What an unsharded `montecarlo` prints: the statistics (table or JSON)
/// and the throughput; `file` is where `--out` wrote the records.
fn mc_report(
    cfg: &McConfig,
    rec: &McRecords,
    file: Option<&Path>,
    json: bool,
) -> Result<String, String> {
    let res = McResult::from_records(rec);
    if json {
        return Ok(serde_json::to_string_pretty(&res).map_err(|e| e.to_string())? + "\n");
    }
    let mut t = mc_text(cfg, &res.stats)
        + &format!(
            "{} simulations in {:.2} s on {} threads: {:.1} runs/s\n",
            res.simulations, res.elapsed_s, res.threads, res.runs_per_s
        );
    if let Some(path) = file {
        t += &format!("raw results written to {}\n", path.display());
    }
    Ok(t)
}

/// What `montecarlo --shard` prints: the shard, its throughput and its file
/// (no statistics: those come from `merge`).
fn shard_report(
    cfg: &McConfig,
    header: &ShardHeader,
    rec: &McRecords,
    file: &Path,
    json: bool,
) -> Result<String, String> {
    let [start, end] = header.runs;
    if json {
        let v = serde_json::json!({
            "file": file.display().to_string(),
            "shard": header.shard,
            "runs": header.runs,
            "simulations": rec.records.len(),
            "elapsed_s": rec.elapsed_s,
            "runs_per_s": rec.sims_per_s(),
            "threads": rec.threads,
        });
        return Ok(serde_json::to_string_pretty(&v).map_err(|e| e.to_string())? + "\n");
    }
    Ok(format!(
        "{}\nshard {}/{}: runs {start}..{end}, {} simulations in {:.2} s on {} threads: {:.1} runs/s\n\
         raw results written to {} (combine with `hil-sim merge FILE...`)\n",
        cfg.describe(),
        header.shard.index,
        header.shard.count,
        rec.records.len(),
        rec.elapsed_s,
        rec.threads,
        rec.sims_per_s(),
        file.display()
    ))
}

/// `montecarlo`: run the sweep or one shard of it, write the records with
/// `--shard`/`--out`, print the statistics (unsharded) or the shard's summary.
fn montecarlo(a: &McArgs, out: &mut dyn Write) -> Result<(), String> {
    let cfg = McConfig {
        runs: a.runs as usize,
        case: a.case,
        seed: a.seed,
        vary_mass: a.vary_mass,
        duration_s: a.duration,
        sensing: a.sensing,
        paper_setting: a.paper_setting,
    };
    cfg.validate()?;
    let shard = a.shard.unwrap_or(Shard::WHOLE);
    let runs = shard.runs(a.runs);
    let pb = progress_bar(
        (runs.end - runs.start) * ControllerKind::ALL.len() as u64,
        a.quiet,
    );
    let rec = run_records(&cfg, runs, &|| pb.inc(1));
    pb.finish_and_clear();
    let header = ShardHeader::new(&cfg, shard, rec.elapsed_s, rec.threads);
    let file = match (&a.out, a.shard) {
        (Some(p), _) => Some(p.clone()),
        (None, Some(s)) => Some(default_shard_path(&cfg, s)),
        (None, None) => None,
    };
    if let Some(path) = &file {
        write_shard(path, &header, &rec.records)?;
    }
    let text = match &file {
        Some(path) if a.shard.is_some() => shard_report(&cfg, &header, &rec, path, a.json)?,
        _ => mc_report(&cfg, &rec, file.as_deref(), a.json)?,
    };
    out.write_all(text.as_bytes()).map_err(|e| e.to_string())?;
    let failed = rec
        .records
        .iter()
        .filter(|r| matches!(r.outcome, Outcome::Error(_)))
        .count();
    let where_ = match &file {
        Some(p) if a.shard.is_some() => format!("their errors are in {}", p.display()),
        _ => "see above".to_string(),
    };
    failed_error(failed, &where_)
}

fn merge(a: &MergeArgs, out: &mut dyn Write) -> Result<(), String> {
    let m = merge_shards(&a.files)?;
    let text = if a.json {
        serde_json::to_string_pretty(&m).map_err(|e| e.to_string())? + "\n"
    } else {
        mc_text(&m.sweep, &m.stats)
            + &format!(
                "{} simulations merged from {} shard files (the shards ran {:.2} s in total)\n",
                m.simulations,
                m.shard_files.len(),
                m.shards_elapsed_s
            )
    };
    out.write_all(text.as_bytes()).map_err(|e| e.to_string())?;
    failed_error(m.stats.iter().map(|s| s.failed).sum(), "see above")
}

/// Executes a parsed command line, writing results to `out`.
pub fn execute(cli: &Cli, out: &mut dyn Write) -> Result<(), String> {
    match &cli.command {
        Command::Compare(a) => compare(a, out),
        Command::Run(a) => run_cmd(a, out),
        Command::Montecarlo(a) => montecarlo(a, out),
        Command::Merge(a) => merge(a, out),
        Command::Bench(a) => {
            let r = run_bench(&BenchConfig {
                reps: a.reps as usize,
                mc_runs: a.mc_runs as usize,
            });
            out.write_all(r.to_string().as_bytes())
                .map_err(|e| e.to_string())
        }
        Command::Device(a) => crate::cli_link::device(a, out),
        Command::Report(a) => crate::cli_link::report(a, out),
    }
}

/// The binary: parse (clap prints usage errors and exits 2), execute, print
/// any error to stderr and return the exit code (0 or 1).
pub fn main_entry() -> i32 {
    let cli = Cli::parse();
    let stdout = std::io::stdout();
    let mut lock = stdout.lock();
    match execute(&cli, &mut lock) {
        Ok(()) => 0,
        Err(e) => {
            let _ = lock.flush();
            eprintln!("error: {e}");
            1
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> Result<Cli, clap::Error> {
        Cli::try_parse_from(std::iter::once("hil-sim").chain(args.iter().copied()))
    }

    fn run_to_string(args: &[&str]) -> Result<String, String> {
        let cli = parse(args).map_err(|e| e.to_string())?;
        let mut buf = Vec::new();
        execute(&cli, &mut buf)?;
        Ok(String::from_utf8(buf).unwrap())
    }

    #[test]
    fn argument_errors_are_rejected_by_the_parser() {
        for bad in [
            &["run", "--controller", "pid"][..],
            &["run", "--case", "3"],
            &["run", "--trajectory", "spiral"],
            &["run", "--beta", "abc"],
            &["run", "--case", "1", "--scenario", "x.toml"],
            &["montecarlo"],
            &["montecarlo", "--runs", "0"],
            &["frobnicate"],
        ] {
            assert!(parse(bad).is_err(), "{bad:?} should not parse");
        }
        let e = parse(&["run", "--controller", "pid"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("smc") && e.contains("proposed"), "{e}");
    }

    #[test]
    fn invalid_values_give_errors_not_panics() {
        let e = run_to_string(&["run", "--eps", "1.5", "--json"]).unwrap_err();
        assert!(e.contains("eps must be"), "{e}");
        let e = run_to_string(&["run", "--duration=-1"]).unwrap_err();
        assert!(e.contains("duration"), "{e}");
        let e = run_to_string(&["run", "--torque-limit", "NaN"]).unwrap_err();
        assert!(e.contains("torque"), "{e}");
        let e = run_to_string(&["run", "--scenario", "/nonexistent/x.toml"]).unwrap_err();
        assert!(e.contains("cannot read"), "{e}");
    }

    #[test]
    fn flags_override_the_preset_and_the_file() {
        let cli = parse(&[
            "run",
            "--case",
            "1",
            "--seed",
            "4",
            "--beta",
            "0.15",
            "--mass-scale",
            "1.1",
            "--trajectory",
            "figure8",
            "--k-y",
            "10",
            "--sensing",
            "odometry",
            "--encoder-cpr",
            "1024",
        ])
        .unwrap();
        let Command::Run(a) = cli.command else {
            panic!()
        };
        let s = a.scenario.build().unwrap();
        assert_eq!(s.name, "case1");
        assert_eq!((s.beta, s.eps, s.seed), (0.15, 0.0, 4));
        assert_eq!(s.mass_scale, 1.1);
        assert_eq!(s.trajectory, TrajectoryKind::Figure8);
        assert_eq!(s.k_y, Some(10.0));
        assert_eq!(s.encoder_cpr, 1024);

        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("s.toml");
        std::fs::write(
            &f,
            "name = \"file\"\nbeta = 0.01\nsensing = \"mocap\"\npwm_levels = 255\npose_rate_hz = 50.0\n",
        )
        .unwrap();
        let a = ScenarioArgs {
            scenario: Some(f),
            beta: Some(0.02),
            ..Default::default()
        };
        let s = a.build().unwrap();
        assert_eq!((s.name.as_str(), s.beta, s.pwm_levels), ("file", 0.02, 255));
    }

    #[test]
    fn sensing_flags_override_the_preset() {
        let cli = parse(&[
            "run",
            "--sensing",
            "uwb",
            "--pose-rate",
            "20",
            "--pose-outage",
            "20,22",
            "--gyro-bias",
            "-0.01",
        ])
        .unwrap();
        let Command::Run(a) = cli.command else {
            panic!()
        };
        let s = a.scenario.build().unwrap();
        assert_eq!(s.sensing, Sensing::Uwb);
        assert_eq!(s.pose_rate_hz, Some(20.0));
        assert_eq!(s.pose_outage_s, Some([20.0, 22.0]));
        assert_eq!(s.gyro_bias_radps, Some(-0.01));
        let cli = parse(&["run", "--sensing", "mocap", "--pose-outage", "20"]).unwrap();
        let Command::Run(a) = cli.command else {
            panic!()
        };
        assert!(a.scenario.build().unwrap_err().contains("START,END"));
        let e = run_to_string(&["run", "--sensing", "odometry", "--pose-rate", "5"]).unwrap_err();
        assert!(e.contains("pose_*"), "{e}");
        let text = run_to_string(&[
            "run",
            "--sensing",
            "mocap",
            "--duration",
            "2",
            "--pose-outlier-fraction",
            "0.2",
        ])
        .unwrap();
        assert!(
            text.contains("sensing mocap") && text.contains("outliers injected"),
            "{text}"
        );
    }

    #[test]
    fn run_json_is_one_object_with_every_metric_key() {
        let text =
            run_to_string(&["run", "--duration", "2", "--json", "--controller", "asmc"]).unwrap();
        assert_eq!(text.trim_end().lines().count(), 1);
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        let o = v.as_object().unwrap();
        for k in [
            "rms_pos_err_m",
            "rms_pos_err_window_m",
            "max_pos_err_window_m",
            "rms_pos_err_after5_m",
            "final_pos_err_m",
            "settling_time_s",
            "torque_rms_nm",
            "max_abs_torque_nm",
            "chatter",
            "saturated_fraction",
            "fault_est_rmse",
            "controller",
            "scenario",
        ] {
            assert!(o.contains_key(k), "missing {k}");
        }
        assert!(o["fault_est_rmse"].is_null());
        assert_eq!(o["controller"], "asmc");
        let text = run_to_string(&["run", "--duration", "2", "--json"]).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert!(v["fault_est_rmse"].is_number());
    }

    #[test]
    fn run_csv_has_header_and_one_row_per_10ms() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("t.csv");
        let text =
            run_to_string(&["run", "--duration", "1.5", "--csv", f.to_str().unwrap()]).unwrap();
        assert!(text.contains("150 rows"), "{text}");
        let csv = std::fs::read_to_string(&f).unwrap();
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines[0], crate::report::CSV_HEADER);
        assert_eq!(lines.len(), 151);
        let t_last: f64 = lines[150].split(',').next().unwrap().parse().unwrap();
        assert!((t_last - 1.49).abs() < 1e-9);
        run_to_string(&[
            "run",
            "--duration",
            "1",
            "--csv",
            f.to_str().unwrap(),
            "--csv-every",
            "1",
        ])
        .unwrap();
        assert_eq!(std::fs::read_to_string(&f).unwrap().lines().count(), 1001);
    }

    #[test]
    fn compare_without_plots_writes_metrics_json() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().to_str().unwrap();
        let text = run_to_string(&["compare", "--out", out, "--no-plots"]).unwrap();
        assert_eq!(
            text.lines()
                .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()) && l.contains("proposed"))
                .count(),
            4,
            "the paper table and the governed one: {text}"
        );
        let v: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("metrics.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(v.as_array().unwrap().len(), 6);
        assert_eq!(v[5]["case"], 2);
        assert_eq!(v[5]["controller"], "proposed");
        // The paper's setting: no governor, so no governor metrics.
        assert!(v[5].get("time_lag_final_s").is_none());
        assert_eq!(v[5]["scenario"]["governor"], false);
        let g: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("metrics_governor.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(g.as_array().unwrap().len(), 6);
        assert!(g[5]["time_lag_final_s"].as_f64().unwrap() >= 0.0);
        assert!(
            g[5]["scenario"].get("governor").is_none(),
            "on: the default"
        );
    }
}
