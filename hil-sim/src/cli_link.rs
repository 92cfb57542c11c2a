//! The host-link subcommands of `hil-sim`: `device --pty` (the simulated
//! robot behind a pseudo-terminal) and `report FILE.csv` (metrics and plots
//! of any trace log).

use crate::cli::{ControllerArg, ScenarioArgs};
use crate::device::{open_pty, serve, SimRobot};
use crate::log_report::{load_trace, plot_trace, trace_metrics};
use crate::report::metrics_table;
use clap::Args;
use controller_core::ControllerKind;
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

/// `device` options.
#[derive(Debug, Args)]
pub struct DeviceArgs {
    /// Serve on a new pseudo-terminal (the only transport so far); its path is
    /// the first line on stdout.
    #[arg(long, required = true)]
    pub pty: bool,
    /// Run N times faster than real time (robot time is simulated time).
    #[arg(long, default_value_t = 1.0, value_name = "N")]
    pub speed: f64,
    /// Controller the runtime runs.
    #[arg(long, value_enum, default_value = "proposed")]
    pub controller: ControllerArg,
    /// Stop after this much robot time [s] (default: run until killed).
    #[arg(long, value_name = "s")]
    pub for_s: Option<f64>,
    /// The simulated robot: sensing, resolution, perturbations (their window is
    /// in robot time since start) and initial pose; the trajectory comes from
    /// the host.
    #[command(flatten)]
    pub scenario: ScenarioArgs,
}

/// `report` options.
#[derive(Debug, Args)]
pub struct ReportArgs {
    /// Trace CSV written by `hil-sim run --csv` or `wmr record`.
    #[arg(value_name = "FILE.csv")]
    pub file: PathBuf,
    /// Perturbation window [start end] in the log's time [s] (default: none).
    #[arg(long, num_args = 2, value_names = ["START", "END"])]
    pub window: Option<Vec<f64>>,
    /// Controller that produced the log (the fault metric needs `proposed`
    /// and a known true fault).
    #[arg(long, value_enum, default_value = "proposed")]
    pub controller: ControllerArg,
    /// Directory for the plots.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    /// Metrics only.
    #[arg(long)]
    pub no_plots: bool,
    /// Print the metrics as one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `hil-sim device --pty`.
pub fn device(a: &DeviceArgs, out: &mut dyn Write) -> Result<(), String> {
    if !(a.speed.is_finite() && a.speed > 0.0 && a.speed <= 1000.0) {
        return Err("--speed must be in (0, 1000]".into());
    }
    let scn = a.scenario.build()?;
    let kind: ControllerKind = a.controller.into();
    let mut robot = SimRobot::new(&scn, kind)?;
    let (mut master, _slave, path) = open_pty()?;
    writeln!(out, "{path}").map_err(|e| e.to_string())?;
    out.flush().map_err(|e| e.to_string())?;
    eprintln!(
        "simulated robot on {path} ({} sensing, {} controller, {}x real time); talk to it with `wmr --port {path} status`",
        match scn.sensing {
            crate::scenario::Sensing::Ideal => "mocap",
            s => s.name(),
        },
        kind.name(),
        a.speed
    );
    let stop = AtomicBool::new(false);
    match a.for_s {
        None => serve(&mut robot, &mut master, a.speed, &stop),
        Some(t) => {
            let ticks = (t / scn.control_period_s).round() as u64;
            std::thread::scope(|s| {
                let h = s.spawn(|| serve(&mut robot, &mut master, a.speed, &stop));
                let period = std::time::Duration::from_secs_f64(scn.control_period_s / a.speed);
                std::thread::sleep(period * ticks as u32);
                stop.store(true, std::sync::atomic::Ordering::Relaxed);
                h.join().map_err(|_| "device thread panicked".to_string())?
            })
        }
    }
}

/// `hil-sim report FILE.csv`.
pub fn report(a: &ReportArgs, out: &mut dyn Write) -> Result<(), String> {
    let trace = load_trace(&a.file)?;
    let window = match &a.window {
        Some(w) if w.len() == 2 && w[0].is_finite() && w[1].is_finite() && w[0] <= w[1] => {
            [w[0], w[1]]
        }
        Some(_) => return Err("--window needs START <= END".into()),
        None => [0.0, 0.0],
    };
    let kind: ControllerKind = a.controller.into();
    let m = trace_metrics(&trace, window, kind)?;
    let name = a
        .file
        .file_stem()
        .map_or_else(|| "log".to_string(), |s| s.to_string_lossy().into_owned());
    let text = if a.json {
        serde_json::to_string(&m).map_err(|e| e.to_string())? + "\n"
    } else {
        format!(
            "{}: {} rows, {:.3} s\n{}",
            a.file.display(),
            trace.len(),
            trace.last().map_or(0.0, |s| s.t_s) - trace[0].t_s,
            metrics_table(&["log"], &[(vec![name.clone()], m.clone())])
        )
    };
    out.write_all(text.as_bytes()).map_err(|e| e.to_string())?;
    if !a.no_plots {
        let files = plot_trace(&a.out, &name, trace, m, window, kind)?;
        if !a.json {
            writeln!(
                out,
                "{} plot files written to {}",
                files.len(),
                a.out.display()
            )
            .map_err(|e| e.to_string())?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use crate::cli::{execute, Cli};
    use crate::scenario::Scenario;
    use clap::Parser;
    use controller_core::ControllerKind;

    /// `hil-sim report` of a CSV logged at every control step gives the
    /// simulation's own metrics (same accumulator, same values); a file that
    /// is not a trace is a clear error.
    #[test]
    fn report_of_a_full_trace_csv_equals_the_run() {
        let scn = Scenario {
            duration_s: 6.0,
            window_s: [2.0, 4.0],
            ..Scenario::paper_case(1, 2, None, None)
        };
        let cfg = crate::sim::controller_config(&scn, ControllerKind::Asmc);
        let out = crate::sim::run_with(&scn, cfg, 1).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("t.csv");
        let f = std::fs::File::create(&csv).unwrap();
        crate::report::write_trace_csv(std::io::BufWriter::new(f), &out.trace).unwrap();
        let cli = Cli::try_parse_from([
            "hil-sim",
            "report",
            csv.to_str().unwrap(),
            "--window",
            "2",
            "4",
            "--controller",
            "asmc",
            "--no-plots",
            "--json",
        ])
        .unwrap();
        let mut buf = Vec::new();
        execute(&cli, &mut buf).unwrap();
        let m: crate::Metrics = serde_json::from_slice(&buf).unwrap();
        let s = &out.metrics;
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * (1.0 + b.abs());
        assert!(close(m.rms_pos_err_m, s.rms_pos_err_m));
        assert!(close(m.rms_pos_err_window_m, s.rms_pos_err_window_m));
        assert!(close(m.torque_rms_nm, s.torque_rms_nm));
        assert!(close(m.chatter, s.chatter));

        std::fs::write(dir.path().join("bad.csv"), "a,b\n").unwrap();
        let bad = dir.path().join("bad.csv");
        let cli = Cli::try_parse_from(["hil-sim", "report", bad.to_str().unwrap()]).unwrap();
        let e = execute(&cli, &mut Vec::new()).unwrap_err();
        assert!(
            e.contains("bad.csv") && e.contains("not a trace CSV"),
            "{e}"
        );
    }
}
