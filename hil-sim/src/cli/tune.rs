//! `hil-sim tune` and `hil-sim tune-merge`: gains for a robot file
//! (book/src/how-to/tuning.md).

use crate::progress::Progress;
use crate::scenario::Sensing;
use crate::shard::Shard;
use crate::tune::optimise::Optimizer;
use crate::tune::set::TuneSet;
use crate::tune::{self, kind_named, TuneJob, TuneOutcome};
use clap::Args;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Default training scenarios (D169: 10, five per default preset, for a
/// job within 60 s on 2 idle cores).
pub const DEFAULT_TRAIN: usize = 10;
/// Default validation scenarios.
pub const DEFAULT_VALIDATE: usize = 16;
/// Default cost evaluations per controller (D169: 80, eight CMA-ES
/// generations; the proposed controller starts from the tuned ASMC).
pub const DEFAULT_EVALUATIONS: usize = 80;
/// Default run length \[s\] (D169: the cost's window is 10-35 s).
pub const DEFAULT_DURATION_S: f64 = 35.0;

/// `tune` options.
#[derive(Debug, Args)]
pub struct TuneArgs {
    /// The robot file to tune (book/src/how-to/robot-file.md): its model is the
    /// controllers', its gains the start.
    #[arg(long, value_name = "FILE.toml")]
    pub robot: PathBuf,
    /// Sensing presets of the scenarios, used in turn (comma-separated).
    #[arg(long, value_enum, value_delimiter = ',', default_value = "mocap,imu")]
    pub sensing: Vec<Sensing>,
    /// Base seed of the set and of the optimisers.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Training scenarios (what the optimiser minimises over).
    #[arg(long, default_value_t = DEFAULT_TRAIN)]
    pub train: usize,
    /// Validation scenarios on the training path (disjoint seeds).
    #[arg(long = "validate", default_value_t = DEFAULT_VALIDATE)]
    pub validate: usize,
    /// Validation scenarios on the figure-8 (a path unlike the training
    /// one), after the --validate ones (D167).
    #[arg(long, default_value_t = crate::tune::set::DEFAULT_FIGURE8)]
    pub validate_figure8: usize,
    /// Validation scenarios on the square with quarter turns on the spot (a
    /// path where v and ω are never both non-zero), after the figure-8 ones
    /// (D213; none by default).
    #[arg(long, default_value_t = crate::tune::set::DEFAULT_SQUARE)]
    pub validate_square: usize,
    /// Skip the mismatch sweep of the written gains (their margins, D167).
    #[arg(long)]
    pub no_margins: bool,
    /// Cost evaluations per controller and restart (each runs --train simulations).
    #[arg(long, default_value_t = DEFAULT_EVALUATIONS)]
    pub evaluations: usize,
    /// Optimiser.
    #[arg(long, value_enum, default_value = "cmaes")]
    pub optimizer: Optimizer,
    /// Independent restarts per controller (0 from the file's gains).
    #[arg(long, default_value_t = 1)]
    pub restarts: u64,
    /// How the cost combines the sensing presets' p95 window RMS (D119):
    /// their mean, or their geometric mean (a relative change of any
    /// preset counts alike).
    /// Default geometric (D169: the arithmetic mean let the gyro-only
    /// drift steer the light robot's tuning into diverging gains).
    #[arg(long, value_enum, default_value = "geometric")]
    pub preset_mean: crate::tune::cost::PresetMean,
    /// Cost of chatter (D129): the cost [m] of a mean chatter of 1 (N·m/s)
    /// per N·m of torque limit, in [0, 1e-2] m·s. The default costs the
    /// paper robot's 76 /s 1.5 mm; 5e-4 makes it 3.8 cm, enough to steer
    /// the optimiser away from gains that chatter.
    #[arg(long, value_name = "m·s", default_value_t = crate::tune::cost::CHATTER_WEIGHT_M_S)]
    pub chatter_weight: f64,
    /// Controllers to tune (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "smc,asmc,proposed")]
    pub controllers: Vec<String>,
    /// Smallest torque-limit scale drawn per scenario (1 = always the robot's).
    #[arg(long, default_value_t = 1.0)]
    pub torque_scale_min: f64,
    /// Largest disturbance amplitude drawn, as a fraction of the torque
    /// limit (drawn in (0.05, F); the paper's 1 N·m on a 2 N·m robot is 0.5).
    #[arg(long, value_name = "F", default_value_t = crate::tune::set::DISTURBANCE_FRACTION.1)]
    pub disturbance_max: f64,
    /// Tune the robot with this per-wheel torque limit instead of its file's
    /// `limits.torque_nm` (written into the tuned file) [N·m].
    #[arg(long, value_name = "N·m")]
    pub torque_limit: Option<f32>,
    /// Run length [s].
    #[arg(long, value_name = "s", default_value_t = DEFAULT_DURATION_S)]
    pub duration: f64,
    /// Run only shard I of N (0-based) of the restarts; write its results to --out.
    #[arg(long, value_name = "I/N", value_parser = Shard::parse)]
    pub shard: Option<Shard>,
    /// Write the raw results (the shard file, JSON) to FILE.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Write the tuned robot file here [default: FILE.tuned.toml beside --robot].
    #[arg(long, value_name = "FILE.toml")]
    pub write: Option<PathBuf>,
    /// Print the outcome as JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// No progress on stderr.
    #[arg(long)]
    pub quiet: bool,
}

/// `tune-merge` options.
#[derive(Debug, Args)]
pub struct TuneMergeArgs {
    /// Shard files of one job (`tune --shard I/N --out FILE`).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Write the tuned robot file here.
    #[arg(long, value_name = "FILE.toml")]
    pub write: Option<PathBuf>,
    /// Print the outcome as JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Skip the mismatch sweep of the written gains (their margins).
    #[arg(long)]
    pub no_margins: bool,
}

/// `FILE.toml` → `FILE.tuned.toml`.
pub fn default_tuned_path(robot: &Path) -> PathBuf {
    let stem = robot
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "robot".into());
    robot.with_file_name(format!("{stem}.tuned.toml"))
}

/// The command line as typed (for the tuned file's header).
fn command_line() -> String {
    let mut v: Vec<String> = std::env::args().collect();
    if let Some(first) = v.first_mut() {
        *first = "hil-sim".into();
    }
    v.join(" ")
}

fn report(o: &TuneOutcome, json: bool, wrote: Option<&Path>) -> Result<String, String> {
    if json {
        let mut s = serde_json::to_string_pretty(o).map_err(|e| e.to_string())?;
        s.push('\n');
        return Ok(s);
    }
    let mut s = format!(
        "Tuning {}: {} training + {} validation scenarios, sensing {}, {} x {} evaluations ({}), {} simulations in {:.1} s\n",
        o.job.set.robot.name,
        o.job.set.training,
        o.job.set.validation,
        o.job.set.sensing.iter().map(|s| s.name()).collect::<Vec<_>>().join(","),
        o.job.restarts,
        o.job.evaluations,
        o.job.optimizer.name(),
        o.simulations,
        o.elapsed_s,
    );
    s.push_str(&o.table());
    s.push_str(&o.findings());
    if let Some(p) = wrote {
        s.push_str(&format!("wrote {}\n", p.display()));
    }
    Ok(s)
}

/// Exit status of `tune` and `tune-merge` when the start was kept (D165):
/// no tuned gains validate better than the robot file's own controller
/// with its own gains (the file is written with them, and says why).
pub const EXIT_KEPT_START: i32 = 3;

/// `tune`: run the job (or one shard of it), write the results and the
/// tuned robot file.
pub fn tune(a: &TuneArgs, out: &mut dyn Write) -> Result<(), String> {
    tune_status(a, out).map(|_| ())
}

/// [`tune`], returning the exit status (0, or [`EXIT_KEPT_START`]).
pub fn tune_status(a: &TuneArgs, out: &mut dyn Write) -> Result<i32, String> {
    let mut robot = super::robot_arg::load_robot(&a.robot)?;
    if let Some(t) = a.torque_limit {
        robot.limits.torque_nm = t;
        robot = crate::scenario::Robot::from_toml_str(&robot.to_toml_string())
            .map_err(|e| format!("--torque-limit {t}: {e}"))?;
    }
    let controllers = {
        let mut v = Vec::new();
        for n in &a.controllers {
            let k = kind_named(n)?;
            if !v.contains(&k) {
                v.push(k);
            }
        }
        v.sort_by_key(|k| {
            controller_core::ControllerKind::ALL
                .iter()
                .position(|x| x == k)
        });
        v
    };
    let job = TuneJob {
        set: TuneSet {
            robot,
            sensing: a.sensing.clone(),
            seed: a.seed,
            training: a.train,
            validation: a.validate,
            torque_scale_min: a.torque_scale_min,
            duration_s: a.duration,
            disturbance_max_fraction: a.disturbance_max,
            figure8: a.validate_figure8,
            square: a.validate_square,
        },
        optimizer: a.optimizer,
        evaluations: a.evaluations,
        restarts: a.restarts,
        controllers,
        preset_mean: a.preset_mean,
        chatter_weight_m_s: a.chatter_weight,
    };
    job.validate()?;
    let shard = a.shard.unwrap_or(Shard::WHOLE);
    let restarts = shard.runs(job.restarts);
    let pb = Progress::new("simulations", job.simulations(&restarts), a.quiet);
    let quiet = a.quiet;
    let file = tune::run_shard(&job, shard, &|| pb.inc(), &|line| {
        if !quiet {
            pb.println(line)
        }
    })?;
    pb.finish();
    let out_path = match (&a.out, a.shard) {
        (Some(p), _) => Some(p.clone()),
        (None, Some(s)) => Some(PathBuf::from(format!(
            "tune-{}-seed{}-shard{}of{}.json",
            job.set.robot.name, job.set.seed, s.index, s.count
        ))),
        (None, None) => None,
    };
    if let Some(p) = &out_path {
        let text = serde_json::to_string(&file).map_err(|e| e.to_string())?;
        tune::write_atomic(p, &text)?;
    }
    if a.shard.is_some() && a.shard != Some(Shard::WHOLE) {
        let p = out_path.expect("a shard has a file");
        let text = format!(
            "tuning shard {}/{}: restarts {}..{}, {} simulations in {:.1} s on {} threads; wrote {} (combine with `hil-sim tune-merge`)\n",
            shard.index,
            shard.count,
            file.restarts.start,
            file.restarts.end,
            file.simulations,
            file.elapsed_s,
            file.threads,
            p.display()
        );
        return out
            .write_all(text.as_bytes())
            .map(|_| 0)
            .map_err(|e| e.to_string());
    }
    let mut outcome = tune::merge(std::slice::from_ref(&file))?;
    if !a.no_margins {
        let pb = Progress::new("margin simulations", outcome.margin_simulations(), a.quiet);
        outcome.add_margins(&|| pb.inc())?;
        pb.finish();
    }
    let path = a
        .write
        .clone()
        .unwrap_or_else(|| default_tuned_path(&a.robot));
    tune::write_atomic(&path, &outcome.robot_file_text(&command_line())?)?;
    let text = report(&outcome, a.json, Some(&path))?;
    out.write_all(text.as_bytes()).map_err(|e| e.to_string())?;
    Ok(status(&outcome))
}

fn status(o: &TuneOutcome) -> i32 {
    if o.kept_start.is_some() {
        EXIT_KEPT_START
    } else {
        0
    }
}

/// `tune-merge`: combine shard files, write the tuned robot file.
pub fn tune_merge(a: &TuneMergeArgs, out: &mut dyn Write) -> Result<(), String> {
    tune_merge_status(a, out).map(|_| ())
}

/// [`tune_merge`], returning the exit status (0, or [`EXIT_KEPT_START`]).
pub fn tune_merge_status(a: &TuneMergeArgs, out: &mut dyn Write) -> Result<i32, String> {
    let files = a
        .files
        .iter()
        .map(|p| tune::read_shard_file(p))
        .collect::<Result<Vec<_>, _>>()?;
    let mut outcome = tune::merge(&files)?;
    if !a.no_margins {
        outcome.add_margins(&|| {})?;
    }
    if let Some(p) = &a.write {
        tune::write_atomic(p, &outcome.robot_file_text(&command_line())?)?;
    }
    let text = report(&outcome, a.json, a.write.as_deref())?;
    out.write_all(text.as_bytes()).map_err(|e| e.to_string())?;
    Ok(status(&outcome))
}
