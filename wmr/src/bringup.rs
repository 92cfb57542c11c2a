//! `wmr bringup`: the guided bring-up of a new robot (issue 34,
//! book/src/how-to/bringup.md): commission → identification run → fit → tune →
//! push → verification, each step's result printed with its numbers and
//! what to do next, each step resumable: its outcome is kept in a state
//! file next to the robot file (`FILE.bringup.toml`), and a run starts at
//! the first step not done (`--redo STEP` runs a step and those after it
//! again). The tuning step runs `hil-sim tune` (its command line, the
//! public entry point) on the identified file; everything else is the
//! `wmr` commands' own code on one link.

use crate::commission::{commission_with, CommissionArgs, CommissionError};
use crate::link::{Link, LinkError};
use serde::{Deserialize, Serialize};
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// The steps, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, clap::ValueEnum)]
pub enum Step {
    /// `wmr commission`: wiring, directions, resolution, gyro sign.
    Commission,
    /// `wmr identify run`: the excitation, recorded.
    Identify,
    /// `wmr identify fit`: the identified robot file.
    Fit,
    /// `hil-sim tune` on the identified file.
    Tune,
    /// The circles with the running file, then `wmr robot push` of the tuned file.
    Push,
    /// The same circles with the pushed file, compared; the better file kept.
    Verify,
}

const STEPS: [Step; 6] = [
    Step::Commission,
    Step::Identify,
    Step::Fit,
    Step::Tune,
    Step::Push,
    Step::Verify,
];

impl Step {
    fn name(self) -> &'static str {
        match self {
            Step::Commission => "commission",
            Step::Identify => "identify",
            Step::Fit => "fit",
            Step::Tune => "tune",
            Step::Push => "push",
            Step::Verify => "verify",
        }
    }
}

/// `bringup` options.
#[derive(Debug, clap::Args)]
pub struct BringupArgs {
    /// The robot file the robot runs (push it first: `wmr robot push`).
    #[arg(long, value_name = "FILE.toml")]
    pub robot: PathBuf,
    /// Commission on the floor (a gyro fitted); without it on a stand,
    /// where you are asked what the wheels did (or give --turns).
    #[arg(long)]
    pub floor: bool,
    /// On a stand: the wheel turns you saw, `R,L` (see `wmr commission`).
    #[arg(long, value_name = "R,L", allow_hyphen_values = true)]
    pub turns: Option<String>,
    /// Commissioning test torque [N·m] (see `wmr commission --torque-nm`).
    #[arg(long, value_name = "N·m")]
    pub torque_nm: Option<f32>,
    /// The robot's weighed mass [kg]: fixes the fit's scale, the motor
    /// identified (see `wmr identify fit --mass-kg`).
    #[arg(long, value_name = "KG")]
    pub mass_kg: Option<f64>,
    /// Length of the identification run [s].
    #[arg(long, default_value_t = 60.0, value_name = "S")]
    pub identify_s: f32,
    /// Peak yaw rate of the identification run [rad/s].
    #[arg(long, default_value_t = 1.0, value_name = "RAD/S")]
    pub identify_w_amp: f32,
    /// Telemetry rate of the identification run [Hz] [default: probed].
    #[arg(long, value_name = "HZ")]
    pub rate: Option<u16>,
    /// The tuning budget: cost evaluations per controller (`hil-sim tune
    /// --evaluations`) [default: hil-sim tune's].
    #[arg(long, value_name = "N")]
    pub tune_evaluations: Option<u32>,
    /// More `hil-sim tune` options, as one string split at spaces (e.g.
    /// "--train 4 --validate 2 --duration 20 --controllers proposed").
    #[arg(long, value_name = "ARGS", allow_hyphen_values = true)]
    pub tune_args: Option<String>,
    /// The `hil-sim` program [default: beside `wmr`, else on PATH].
    #[arg(long, env = "WMR_HIL_SIM", value_name = "PATH")]
    pub hil_sim: Option<PathBuf>,
    /// Length of each verification circle [s].
    #[arg(long, default_value_t = 20.0, value_name = "S")]
    pub verify_s: f64,
    /// Verification circles per file (the file before the push and the
    /// tuned one, the same circle from where the robot stands): the file
    /// with the lower mean error is kept.
    #[arg(long, default_value_t = 2, value_name = "N")]
    pub verify_runs: u32,
    /// Run this step and the ones after it again (their results are
    /// replaced).
    #[arg(long, value_enum, value_name = "STEP")]
    pub redo: Option<Step>,
    /// Answer every confirmation with yes (non-interactive).
    #[arg(long)]
    pub yes: bool,
}

/// What the steps done so far left: the state file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct State {
    /// Steps done, by name, in order.
    pub done: Vec<String>,
    /// The identification log.
    pub log: Option<PathBuf>,
    /// The identified robot file.
    pub identified: Option<PathBuf>,
    /// The tuned robot file.
    pub tuned: Option<PathBuf>,
    /// Mean over [`Self::before_runs_m`] \[m\].
    pub before_rms_m: Option<f64>,
    /// Mean over [`Self::after_runs_m`] \[m\].
    pub after_rms_m: Option<f64>,
    /// RMS position error after 5 s of each verification circle with the
    /// file before the push \[m\].
    #[serde(default)]
    pub before_runs_m: Vec<f64>,
    /// The same with the tuned file \[m\].
    #[serde(default)]
    pub after_runs_m: Vec<f64>,
    /// The file the robot runs once the verification is done: the tuned
    /// file, or the file before it when that tracked better (pushed back).
    #[serde(default)]
    pub running: Option<PathBuf>,
}

/// Mean and standard error of the mean of `x` (NaN SE for one value).
pub fn mean_se(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// Why the bring-up stopped.
#[derive(Debug, thiserror::Error)]
pub enum BringupError {
    /// The link or the robot.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// Commissioning.
    #[error("commission: {0}; fix it, then run `wmr bringup` again (it starts at commissioning)")]
    Commission(#[from] CommissionError),
    /// `identify fit`.
    #[error("fit: {0}")]
    Fit(#[from] crate::identify::FitError),
    /// A file.
    #[error("{path}: {err}")]
    File {
        /// The file.
        path: String,
        /// Why.
        err: String,
    },
    /// The tuner.
    #[error("tune: {0}")]
    Tune(String),
    /// Every try of a circle ended with nothing recorded after 5 s.
    #[error(
        "{CIRCLE_TRIES} circles with {} recorded nothing after 5 s (the run ended at once, or the link lost it): \
         check the robot and the link (`wmr status`), then `wmr bringup` again", file.display()
    )]
    NotMeasured {
        /// The file the robot ran.
        file: PathBuf,
    },
    /// Bad options.
    #[error("{0}")]
    Option(String),
    /// Writing the output.
    #[error("cannot write the output: {0}")]
    Output(String),
}

fn out_err(e: std::io::Error) -> BringupError {
    BringupError::Output(e.to_string())
}

/// `FILE.toml` → `FILE.<suffix>` beside it.
pub fn beside(robot: &Path, suffix: &str) -> PathBuf {
    let stem = robot
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "robot".into());
    robot.with_file_name(format!("{stem}.{suffix}"))
}

/// The state file of a robot file: `FILE.bringup.toml` beside it.
pub fn state_path(robot: &Path) -> PathBuf {
    beside(robot, "bringup.toml")
}

fn load_state(path: &Path) -> Result<State, BringupError> {
    match std::fs::read_to_string(path) {
        Ok(t) => toml::from_str(&t).map_err(|e| BringupError::File {
            path: path.display().to_string(),
            err: format!(
                "{} (a bring-up state file: delete it to start over)",
                e.to_string().trim_end()
            ),
        }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(State::default()),
        Err(e) => Err(BringupError::File {
            path: path.display().to_string(),
            err: e.to_string(),
        }),
    }
}

fn save_state(path: &Path, s: &State) -> Result<(), BringupError> {
    let text = toml::to_string(s).map_err(|e| BringupError::Output(e.to_string()))?;
    std::fs::write(
        path,
        format!("# wmr bringup's state (book/src/how-to/bringup.md); delete to start over\n{text}"),
    )
    .map_err(|e| BringupError::File {
        path: path.display().to_string(),
        err: e.to_string(),
    })
}

/// `hil-sim tune`'s exit status when it keeps the start gains (hil-sim's
/// `cli::tune::EXIT_KEPT_START`; wmr runs hil-sim as a program and does not
/// link it).
pub const HIL_SIM_TUNE_KEPT_START: i32 = 3;

/// The `hil-sim` program: `--hil-sim`, else beside this executable, else
/// `hil-sim` on PATH.
fn hil_sim_program(a: &BringupArgs) -> PathBuf {
    if let Some(p) = &a.hil_sim {
        return p.clone();
    }
    if let Some(dir) = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(Path::to_path_buf))
    {
        let p = dir.join("hil-sim");
        if p.is_file() {
            return p;
        }
    }
    PathBuf::from("hil-sim")
}

/// The arguments of the tuning step's `hil-sim tune`.
pub fn tune_argv(a: &BringupArgs, identified: &Path, tuned: &Path) -> Vec<String> {
    let mut v = vec![
        "tune".to_string(),
        "--robot".into(),
        identified.display().to_string(),
        "--write".into(),
        tuned.display().to_string(),
        "--quiet".into(),
    ];
    if let Some(n) = a.tune_evaluations {
        v.push("--evaluations".into());
        v.push(n.to_string());
    }
    if let Some(extra) = &a.tune_args {
        v.extend(extra.split_whitespace().map(str::to_string));
    }
    v
}

/// The circle from where the robot stands for `seconds`: the RMS position
/// error after the first 5 s \[m\] (`wmr upload` + `wmr record --arm`, then
/// a disarm: the circle goes on after the recording).
fn circle(
    link: &mut Link,
    robot_file: &Path,
    dir_file: &Path,
    seconds: f64,
    out: &mut dyn Write,
) -> Result<Option<f64>, BringupError> {
    link.command(&wmr_protocol::Request::SetTelemetry {
        selection: wmr_protocol::TELEMETRY_ALL,
        rate_hz: 50,
    })?;
    let p = crate::identify::current_pose(link)?;
    let _ = link.command(&wmr_protocol::Request::SetTelemetry {
        selection: wmr_protocol::TELEMETRY_ALL,
        rate_hz: 0,
    });
    let traj = PathBuf::from(format!("{}.circle.toml", dir_file.display()));
    let file_err = |path: &Path, e: std::io::Error| BringupError::File {
        path: path.display().to_string(),
        err: e.to_string(),
    };
    std::fs::write(
        &traj,
        format!(
            "trajectory = \"circle\"\nstart_pose = [{}, {}, {}]\n",
            p.x_m, p.y_m, p.theta_rad
        ),
    )
    .map_err(|e| file_err(&traj, e))?;
    let mut sink = Vec::new();
    crate::upload::upload(
        &crate::upload::UploadArgs {
            file: traj.clone(),
            arm: false,
            robot: Some(robot_file.to_path_buf()),
            scale_time: 1.0,
        },
        link,
        &mut sink,
    )?;
    let csv = PathBuf::from(format!("{}.csv", dir_file.display()));
    let mut summary = Vec::new();
    let r = crate::record::record(
        &crate::record::RecordArgs {
            seconds,
            out: csv.clone(),
            rate: 100,
            arm: true,
            quiet: true,
            mcap: None,
            com_offset_m: None,
        },
        link,
        &mut summary,
    );
    // The circle goes on after the recording: a deliberate stop, seen to
    // take (a disarm lost on the way would leave this circle running into
    // the next one's arm).
    stop_running(link)?;
    r?;
    let text = String::from_utf8_lossy(&summary);
    let json: serde_json::Value = text
        .lines()
        .rev()
        .find_map(|l| serde_json::from_str(l).ok())
        .ok_or_else(|| BringupError::Output(format!("no recording summary in: {text}")))?;
    let Some(rms) = json["metrics"]["rms_pos_err_after5_m"].as_f64() else {
        // No row after the first 5 s: the telemetry reached the host only
        // after the circle's recorded time (seen right after a push's
        // reboot on a loaded host), a measurement lost, not a result.
        writeln!(
            out,
            "  circle for {seconds:.0} s: the recording holds no row after 5 s ({} row(s)): not measured",
            json["rows"]
        )
        .map_err(out_err)?;
        return Ok(None);
    };
    writeln!(
        out,
        "  circle for {seconds:.0} s: RMS position error after 5 s {rms:.4} m, final {:.4} m, torque saturated {:.1} % ({})",
        json["metrics"]["final_pos_err_m"].as_f64().unwrap_or(f64::NAN),
        100.0 * json["metrics"]["saturated_fraction"].as_f64().unwrap_or(f64::NAN),
        csv.display()
    )
    .map_err(out_err)?;
    Ok(Some(rms))
}

/// "0.0042 m (1 circle)", "0.0042 m ± 0.0003 (mean of 2 circles)".
fn runs_text(x: &[f64]) -> String {
    match mean_se(x) {
        (m, _) if x.len() == 1 => format!("{m:.4} m (1 circle)"),
        (m, se) => format!("{m:.4} m ± {se:.4} (mean of {} circles)", x.len()),
    }
}

/// Disarms the robot and waits until its status is no longer running (at
/// most 20 tries, the disarm sent again each time).
fn stop_running(link: &mut Link) -> Result<(), BringupError> {
    for _ in 0..20 {
        let _ = crate::session::Motion::Disarm.send(link);
        if crate::session::status(link)?.state != wmr_protocol::RunStateMsg::Running {
            return Ok(());
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    Err(BringupError::Output(
        "the robot still runs after 20 disarms: stop it (the button), then `wmr bringup` again"
            .into(),
    ))
}

/// `a.verify_runs` circles of `a.verify_s` with `robot_file` (the file the
/// robot runs), their logs `FILE.<tag>-<n>.csv`: each one's RMS position
/// error after 5 s \[m\].
fn circles(
    link: &mut Link,
    robot_file: &Path,
    tag: &str,
    a: &BringupArgs,
    out: &mut dyn Write,
) -> Result<Vec<f64>, BringupError> {
    let mut runs = Vec::new();
    for n in 1..=a.verify_runs {
        let file = beside(&a.robot, &format!("{tag}-{n}"));
        let mut rms = None;
        for _ in 0..CIRCLE_TRIES {
            rms = circle(link, robot_file, &file, a.verify_s, out)?;
            if rms.is_some() {
                break;
            }
        }
        runs.push(rms.ok_or_else(|| BringupError::NotMeasured {
            file: robot_file.to_path_buf(),
        })?);
    }
    Ok(runs)
}

/// Circles tried for one measurement whose recording missed it.
const CIRCLE_TRIES: usize = 3;

/// `wmr bringup` reading answers from stdin: see [`bringup_with`].
pub fn bringup(a: &BringupArgs, link: &mut Link, out: &mut dyn Write) -> Result<(), BringupError> {
    let stdin = std::io::stdin();
    let mut input = stdin.lock();
    bringup_with(a, link, out, &mut input)
}

/// `wmr bringup`, the questions answered from `input`: every step not yet
/// done, in order; `Ok` when all are done. The verification keeps the
/// better of the two files on the robot (the tuned one when its mean
/// circle error is no larger, else the file before it, pushed back): the
/// bring-up never leaves the robot tracking worse than it found it.
pub fn bringup_with(
    a: &BringupArgs,
    link: &mut Link,
    out: &mut dyn Write,
    input: &mut dyn BufRead,
) -> Result<(), BringupError> {
    if !(a.verify_s.is_finite() && a.verify_s >= 6.0 && a.verify_s <= 600.0) {
        return Err(BringupError::Option(format!(
            "--verify-s {}: must be in 6..=600 s (the error is measured after the first 5 s)",
            a.verify_s
        )));
    }
    if !(a.identify_s.is_finite() && a.identify_s >= 5.0) {
        return Err(BringupError::Option(format!(
            "--identify-s {}: must be at least 5 s (the fit needs a run; 60 s is the default)",
            a.identify_s
        )));
    }
    if !(1..=20).contains(&a.verify_runs) {
        return Err(BringupError::Option(format!(
            "--verify-runs {}: must be in 1..=20 circles per file (2 is the default)",
            a.verify_runs
        )));
    }
    let spath = state_path(&a.robot);
    let mut st = load_state(&spath)?;
    if let Some(r) = a.redo {
        st.done
            .retain(|d| STEPS.iter().any(|s| s.name() == d && *s < r));
    }
    writeln!(
        out,
        "bring-up of {} (state: {}): {}",
        a.robot.display(),
        spath.display(),
        STEPS
            .iter()
            .map(|s| format!(
                "{}{}",
                s.name(),
                if st.done.iter().any(|d| d == s.name()) {
                    " (done)"
                } else {
                    ""
                }
            ))
            .collect::<Vec<_>>()
            .join(" → ")
    )
    .map_err(out_err)?;
    let log = st.log.clone().unwrap_or_else(|| beside(&a.robot, "id.csv"));
    let identified = st
        .identified
        .clone()
        .unwrap_or_else(|| beside(&a.robot, "identified.toml"));
    let tuned = st
        .tuned
        .clone()
        .unwrap_or_else(|| beside(&a.robot, "tuned.toml"));
    for (n, step) in STEPS.iter().enumerate() {
        if st.done.iter().any(|d| d == step.name()) {
            continue;
        }
        writeln!(out, "step {}/6: {}", n + 1, step.name()).map_err(out_err)?;
        match step {
            Step::Commission => {
                let c = CommissionArgs {
                    robot: a.robot.clone(),
                    floor: a.floor,
                    output: Some(beside(&a.robot, "commissioned.toml")),
                    push: false,
                    yes: a.yes,
                    turns: a.turns.clone(),
                    duration_ms: 1500,
                    torque_nm: a.torque_nm,
                };
                match commission_with(&c, link, out, input) {
                    Ok(()) => writeln!(out, "  commissioned: wiring, directions and resolution agree with the file; next: the identification run").map_err(out_err)?,
                    Err(CommissionError::Findings { count, wiring }) => {
                        return Err(BringupError::Option(format!(
                            "commission: {count} finding(s){}: {}",
                            if wiring { ", a wiring fix among them" } else { "" },
                            if wiring {
                                "fix the wiring, then run `wmr bringup` again".to_string()
                            } else {
                                format!(
                                    "the proposed file is {}: push it (`wmr robot push {}`), then run `wmr bringup --robot {}`",
                                    c.output.as_ref().map(|p| p.display().to_string()).unwrap_or_default(),
                                    c.output.as_ref().map(|p| p.display().to_string()).unwrap_or_default(),
                                    c.output.as_ref().map(|p| p.display().to_string()).unwrap_or_default()
                                )
                            }
                        )))
                    }
                    Err(e) => return Err(e.into()),
                }
            }
            Step::Identify => {
                let r = crate::identify::RunArgs {
                    out: log.clone(),
                    v_amp: 0.5,
                    w_amp: a.identify_w_amp,
                    w_base: 1.5,
                    duration: a.identify_s,
                    area: 2.5,
                    rate: a.rate,
                    robot: Some(a.robot.clone()),
                };
                crate::identify::run(&r, link, out)?;
                st.log = Some(log.clone());
                writeln!(out, "  next: the fit of {}", log.display()).map_err(out_err)?;
            }
            Step::Fit => {
                let f = crate::identify::FitArgs {
                    log: log.clone(),
                    robot: Some(a.robot.clone()),
                    timer_clock_hz: None,
                    out: Some(identified.clone()),
                    filter_window: 0.15,
                    mass_kg: a.mass_kg,
                    pose_measured: false,
                };
                crate::identify::fit(&f, out)?;
                st.identified = Some(identified.clone());
                writeln!(
                    out,
                    "  identified robot file: {}{}; next: tuning it",
                    identified.display(),
                    if a.mass_kg.is_none() {
                        " (no --mass-kg: mass, inertia and friction carry the file's motor constant's error; see the notes)"
                    } else {
                        ""
                    }
                )
                .map_err(out_err)?;
            }
            Step::Tune => {
                let prog = hil_sim_program(a);
                let argv = tune_argv(a, &identified, &tuned);
                writeln!(out, "  {} {}", prog.display(), argv.join(" ")).map_err(out_err)?;
                let _ = std::fs::remove_file(&tuned);
                let o = Command::new(&prog)
                    .args(&argv)
                    .stdin(Stdio::null())
                    .output()
                    .map_err(|e| {
                        BringupError::Tune(format!(
                            "cannot run {}: {e} (give its path with --hil-sim or WMR_HIL_SIM)",
                            prog.display()
                        ))
                    })?;
                out.write_all(&o.stdout).map_err(out_err)?;
                // Exit 3 (hil-sim's EXIT_KEPT_START): the file's own gains and
                // controller validated best and were written back: not a failure.
                let kept_start = o.status.code() == Some(HIL_SIM_TUNE_KEPT_START);
                if kept_start {
                    writeln!(
                        out,
                        "  hil-sim tune kept the file's own gains (they validated best; its report above says why)"
                    )
                    .map_err(out_err)?;
                }
                if !o.status.success() && !kept_start {
                    return Err(BringupError::Tune(format!(
                        "{} exited with {}: {}",
                        prog.display(),
                        o.status,
                        String::from_utf8_lossy(&o.stderr).trim_end()
                    )));
                }
                if !tuned.is_file() {
                    return Err(BringupError::Tune(format!(
                        "{} wrote no tuned file at {}: {}",
                        prog.display(),
                        tuned.display(),
                        String::from_utf8_lossy(&o.stderr).trim_end()
                    )));
                }
                st.tuned = Some(tuned.clone());
                writeln!(
                    out,
                    "  tuned robot file: {}; next: the circle with the running file, then the push",
                    tuned.display()
                )
                .map_err(out_err)?;
            }
            Step::Push => {
                writeln!(
                    out,
                    "  {} circle(s) with the file the robot runs now ({}):",
                    a.verify_runs,
                    a.robot.display()
                )
                .map_err(out_err)?;
                st.before_runs_m = circles(link, &a.robot, "before", a, out)?;
                st.before_rms_m = Some(mean_se(&st.before_runs_m).0);
                st.after_runs_m.clear();
                st.after_rms_m = None;
                st.running = None;
                crate::robot::push(link, &tuned, true, false, out)?;
                writeln!(
                    out,
                    "  pushed {}; next: the same circle(s) with it",
                    tuned.display()
                )
                .map_err(out_err)?;
            }
            Step::Verify => {
                if st.running.as_deref() == Some(a.robot.as_path()) {
                    // A verification before this one pushed the file before
                    // the tuned one back: the tuned file goes on again.
                    crate::robot::push(link, &tuned, true, false, out)?;
                }
                // A tuned file whose circles record nothing (its run ends
                // at once) loses to the file before it.
                st.after_runs_m = match circles(link, &tuned, "after", a, out) {
                    Err(BringupError::NotMeasured { .. }) if !st.before_runs_m.is_empty() => {
                        writeln!(out, "  no circle with the tuned file recorded anything after 5 s: it counts as worse").map_err(out_err)?;
                        vec![f64::INFINITY]
                    }
                    r => r?,
                };
                let after = mean_se(&st.after_runs_m).0;
                st.after_rms_m = Some(after);
                if st.before_runs_m.is_empty() {
                    writeln!(out, "  verified: {after:.4} m RMS with the tuned file (no circle before it in the state: `--redo push` measures it)").map_err(out_err)?;
                    st.running = Some(tuned.clone());
                } else {
                    let before = mean_se(&st.before_runs_m).0;
                    let both = format!(
                        "tuned file {}, file before it {}: {:+.0} %",
                        runs_text(&st.after_runs_m),
                        runs_text(&st.before_runs_m),
                        100.0 * (after / before - 1.0)
                    );
                    if after <= before {
                        writeln!(
                            out,
                            "  verified: {both}; the robot runs {}",
                            tuned.display()
                        )
                        .map_err(out_err)?;
                        st.running = Some(tuned.clone());
                    } else {
                        // Never worse than before the bring-up: the file
                        // before it goes back on the robot.
                        writeln!(
                            out,
                            "  the tuned file tracked worse: {both}; pushing the file before it back ({})",
                            a.robot.display()
                        )
                        .map_err(out_err)?;
                        crate::robot::push(link, &a.robot, true, false, out)?;
                        writeln!(
                            out,
                            "  kept {}: tune with a larger budget (--tune-evaluations) and `wmr bringup --redo tune` to try again",
                            a.robot.display()
                        )
                        .map_err(out_err)?;
                        st.running = Some(a.robot.clone());
                    }
                }
            }
        }
        st.done.push(step.name().to_string());
        save_state(&spath, &st)?;
    }
    writeln!(
        out,
        "bring-up done: the robot runs {} (`wmr bringup --redo STEP` repeats a step)",
        st.running.as_ref().unwrap_or(&tuned).display()
    )
    .map_err(out_err)?;
    Ok(())
}
