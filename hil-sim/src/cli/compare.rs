//! `hil-sim compare`: both paper cases x the three controllers (paper
//! setting, then the defaults beyond the paper, then Case 2 under two
//! sensing presets); the text comes from [`crate::report`].

use crate::report::{
    beyond_paper_text, case_plot_title, compare_json, compare_rows, compare_sensing_json,
    compare_sensing_text, compare_text, CaseRuns,
};
use crate::scenario::{Robot, Scenario, Sensing};
use crate::sim::SimOutput;
use clap::Args;
use controller_core::ControllerKind;
use rayon::prelude::*;
use std::io::Write;
use std::path::{Path, PathBuf};

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
    /// The robot files (`--robot`, `--plant`).
    #[command(flatten)]
    pub robots: super::robot_arg::RobotArgs,
}

/// Runs both paper cases with the three controllers in parallel (traced),
/// in the paper's setting ([`Scenario::as_printed`]: no governor, no
/// large-error bound) unless `beyond_paper`.
pub fn compare_runs(
    seed: u64,
    beta: Option<f64>,
    eps: Option<f64>,
    beyond_paper: bool,
    robots: Robots<'_>,
) -> Result<Vec<CaseRuns>, String> {
    let cases: Vec<(u8, Scenario)> = [1u8, 2]
        .iter()
        .map(|&c| {
            let s = Scenario::paper_case(c, seed, beta, eps).with_robots(robots.0, robots.1);
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

/// The controller's and the plant's robot of a comparison (None: the
/// paper's, the controller's).
pub type Robots<'a> = (Option<&'a Robot>, Option<&'a Robot>);

/// Writes `json` to `dir/metrics.json` (creating `dir`); returns the path.
pub fn write_metrics_json(dir: &Path, json: &str) -> Result<PathBuf, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let path = dir.join("metrics.json");
    std::fs::write(&path, format!("{json}\n"))
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    Ok(path)
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

/// The sensing presets `compare` also shows (Case 2 through the firmware
/// runtime), after the paper's ideal table.
pub const COMPARE_SENSING: [Sensing; 2] = [Sensing::Mocap, Sensing::Odometry];

/// Case 2 of `compare` under each of [`COMPARE_SENSING`], the three
/// controllers in parallel (traced): (preset, scenario, outputs).
pub fn compare_sensing_runs(
    seed: u64,
    beta: Option<f64>,
    eps: Option<f64>,
    robots: Robots<'_>,
) -> Result<Vec<(Sensing, Scenario, Vec<SimOutput>)>, String> {
    let scns: Vec<Scenario> = COMPARE_SENSING
        .iter()
        .map(|&sensing| {
            Scenario::paper_case(2, seed, beta, eps)
                .as_printed()
                .with_sensing(sensing)
                .with_robots(robots.0, robots.1)
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
            .map_err(|e| format!("case 2, sensing {}: {e}", scn.sensing.preset.name()))?;
        res.push((scn.sensing.preset, scn, runs));
    }
    Ok(res)
}

/// Why the paper's cases are beyond the controller's robot `r`, or None
/// when they are within it: the check `hil-sim run` refuses with
/// ([`crate::limits::check_within_robot`]: the paper's reference against
/// the robot's top speed, yaw rate and acceleration, its disturbance
/// against half of `limits.torque_nm`). `compare` then prints this on
/// stderr: the table still shows what happens, and the message points to
/// the commands whose reference and disturbance are the robot's own.
pub fn paper_cases_beyond(r: &Robot) -> Option<String> {
    let scn = Scenario::paper_case(2, 1, None, None).with_robots(Some(r), None);
    crate::limits::check_within_robot(&scn).err().map(|why| {
        format!(
            "note: the paper's cases are beyond robot {:?}: {why}. The table shows saturation, not tracking. \
             For a reference and disturbances within the robot's limits: `hil-sim sweep --robot FILE` \
             (book/src/how-to/mismatch-sweeps.md) and `hil-sim tune --robot FILE` (book/src/how-to/tuning.md)",
            r.name,
        )
    })
}

/// `compare`: run, write metrics.json, draw the plots, print (the paper's
/// setting first, exactly as before the governor existed; then the same
/// with the governor on, into `metrics_governor.json` and `case<N>_gov_*`);
/// a plot error is returned after the tables have been printed.
pub fn compare(a: &CompareArgs, out: &mut dyn Write) -> Result<(), String> {
    let (robot, plant) = a.robots.load()?;
    let robots = (robot.as_ref(), plant.as_ref());
    if let Some(note) = robot.as_ref().and_then(paper_cases_beyond) {
        eprintln!("{note}");
    }
    let t0 = std::time::Instant::now();
    let results = compare_runs(a.seed, a.beta, a.eps, false, robots)?;
    let sim_time = t0.elapsed();
    let sensing = compare_sensing_runs(a.seed, a.beta, a.eps, robots)?;
    let rows = compare_rows(&results);
    let json = compare_json(&rows)?;
    let metrics_path = write_metrics_json(&a.out, &json)?;
    let sensing_json = compare_sensing_json(&sensing)?;
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
    let gov = compare_runs(a.seed, a.beta, a.eps, true, robots)?;
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
