//! Human and machine output of runs: the metrics table, the JSON objects of
//! `run --json` / `compare --json` / `metrics.json`, the text of every
//! subcommand (`compare`, `run`, `montecarlo`, `merge`), and the trace CSV.

use crate::metrics::Metrics;
use crate::montecarlo::{stats_table, ControllerStats, McConfig, McRecords, McResult};
use crate::scenario::{Scenario, Sensing};
use crate::shard::{Merged, ShardHeader};
use crate::sim::SimOutput;
use controller_core::ControllerKind;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One run as printed by `run --json` and stored in `metrics.json`: the
/// [`Metrics`] keys at the top level plus `controller` and `scenario`.
#[derive(Clone, Debug, Serialize)]
pub struct RunReport {
    /// `smc`, `asmc` or `proposed`.
    pub controller: &'static str,
    /// Every knob of the run.
    pub scenario: Scenario,
    /// Control steps the controller rejected (bad input); 0 in a healthy run.
    pub rejected_steps: u32,
    /// The firmware runtime's latched stop, when it stopped the run (a
    /// safe stop of the runtime's own checks: the direction check, a stall,
    /// an encoder jump, ...); `null` otherwise. `safe_stop` is the health
    /// machine's alone.
    pub runtime_stop: Option<RuntimeStop>,
    /// The metrics (flattened into the object).
    #[serde(flatten)]
    pub metrics: Metrics,
}

impl RunReport {
    /// Report of one run.
    pub fn new(kind: ControllerKind, scenario: &Scenario, out: &crate::SimOutput) -> Self {
        Self {
            controller: kind.name(),
            scenario: scenario.clone(),
            rejected_steps: out.rejected_steps,
            runtime_stop: out.stop.map(|(step, reason)| RuntimeStop {
                t_s: step as f64 * scenario.control_period_s,
                reason: format!("{reason:?}"),
            }),
            metrics: out.metrics.clone(),
        }
    }

    /// Compact one-line JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("RunReport serialises")
    }
}

/// The runtime's latched stop in a [`RunReport`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RuntimeStop {
    /// When it latched \[s\].
    pub t_s: f64,
    /// Why (the runtime's `StopReason`, e.g. `DirectionMismatch { wheel: Right }`).
    pub reason: String,
}

/// The metric columns of [`metrics_table`]: header, unit, value.
/// A table column: header, unit, formatter.
pub type Column = (&'static str, &'static str, fn(&Metrics) -> String);

fn opt(x: Option<f64>, prec: usize) -> String {
    x.map_or_else(|| "-".into(), |v| format!("{v:.prec$}"))
}

const COLUMNS: [Column; 11] = [
    ("rms", "m", |m| format!("{:.4}", m.rms_pos_err_m)),
    ("rms_win", "m", |m| format!("{:.4}", m.rms_pos_err_window_m)),
    ("max_win", "m", |m| format!("{:.4}", m.max_pos_err_window_m)),
    ("rms_t>5", "m", |m| format!("{:.4}", m.rms_pos_err_after5_m)),
    ("final", "m", |m| format!("{:.4}", m.final_pos_err_m)),
    ("settle", "s", |m| opt(m.settling_time_s, 2)),
    ("tau_rms", "N·m", |m| format!("{:.3}", m.torque_rms_nm)),
    ("tau_max", "N·m", |m| format!("{:.2}", m.max_abs_torque_nm)),
    ("chatter", "N·m/s", |m| format!("{:.2}", m.chatter)),
    ("sat", "%", |m| {
        format!("{:.1}", 100.0 * m.saturated_fraction)
    }),
    ("F_rmse", "", |m| opt(m.fault_est_rmse, 4)),
];

/// Columns of the reference governor and health machine (runs with it on).
pub const PACE_COLUMNS: [Column; 4] = [
    ("lag", "s", |m| opt(m.time_lag_final_s, 2)),
    ("s_min", "", |m| opt(m.min_time_scale, 2)),
    ("degr", "%", |m| {
        m.degraded_fraction
            .map_or("-".into(), |f| format!("{:.1}", 100.0 * f))
    }),
    ("h_tr", "", |m| {
        m.health_transitions.map_or("-".into(), |n| n.to_string())
    }),
];

/// A fixed-width table, one row per `(label columns…, metrics)`; `labels`
/// names the leading label columns (e.g. `["case", "controller"]`).
pub fn metrics_table(labels: &[&str], rows: &[(Vec<String>, Metrics)]) -> String {
    metrics_table_with(labels, rows, &[])
}

/// [`metrics_table`] with `extra` columns after the standard ones.
pub fn metrics_table_with(
    labels: &[&str],
    rows: &[(Vec<String>, Metrics)],
    extra: &[Column],
) -> String {
    let mut header: Vec<String> = labels.iter().map(|s| s.to_string()).collect();
    let mut units: Vec<String> = labels.iter().map(|_| String::new()).collect();
    let columns: Vec<&Column> = COLUMNS.iter().chain(extra).collect();
    for (h, u, _) in &columns {
        header.push(h.to_string());
        units.push(if u.is_empty() {
            String::new()
        } else {
            format!("[{u}]")
        });
    }
    let body: Vec<Vec<String>> = rows
        .iter()
        .map(|(l, m)| {
            let mut r = l.clone();
            r.extend(columns.iter().map(|(_, _, f)| f(m)));
            r
        })
        .collect();
    let ncol = header.len();
    let width = |c: usize| {
        std::iter::once(&header[c])
            .chain(std::iter::once(&units[c]))
            .chain(body.iter().map(|r| &r[c]))
            .map(|s| s.chars().count())
            .max()
            .unwrap_or(0)
    };
    let widths: Vec<usize> = (0..ncol).map(width).collect();
    let mut out = String::new();
    let line = |out: &mut String, cells: &[String]| {
        for (c, cell) in cells.iter().enumerate() {
            let pad = widths[c] - cell.chars().count();
            if c < labels.len() {
                let _ = write!(out, "{cell}{}  ", " ".repeat(pad));
            } else {
                let _ = write!(out, "{}{cell}  ", " ".repeat(pad));
            }
        }
        let trimmed = out.trim_end().len();
        out.truncate(trimmed);
        out.push('\n');
    };
    line(&mut out, &header);
    line(&mut out, &units);
    let rule: Vec<String> = widths.iter().map(|w| "-".repeat(*w)).collect();
    line(&mut out, &rule);
    for r in &body {
        line(&mut out, r);
    }
    out
}

/// The scenario's random and physical knobs on one line (no newline), as
/// `run` and `compare` print them: `beta 0.1825 rad/s, eps 0.1524, skid x0.05,
/// disturbance 1 N·m, mass x1, torque limit 10 N·m, seed 1`.
pub fn scenario_summary(scn: &Scenario) -> String {
    format!(
        "beta {:.4} rad/s, eps {:.4}, skid x{}, disturbance {} N·m, mass x{}, torque limit {} N·m, seed {}",
        scn.perturbations.beta,
        scn.perturbations.eps,
        scn.perturbations.skid_scale,
        scn.perturbations.disturbance_nm,
        scn.plant.mass_scale,
        // The file's f32 limit as written (0.12, not 0.11999999731779099).
        scn.torque_limit_nm() as f32,
        scn.seed
    )
}

/// A human summary of one run (what `run` prints without `--json`).
pub fn human_summary(kind: ControllerKind, scn: &Scenario, out: &crate::SimOutput) -> String {
    let m = &out.metrics;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "scenario '{}' ({:?}, {} s), controller {}",
        scn.name,
        scn.trajectory,
        scn.duration_s,
        kind.name()
    );
    let _ = writeln!(s, "  {}", scenario_summary(scn));
    let _ = writeln!(
        s,
        "  position error: rms {:.4} m, window rms {:.4} m / max {:.4} m, rms after 5 s {:.4} m, final {:.4} m",
        m.rms_pos_err_m,
        m.rms_pos_err_window_m,
        m.max_pos_err_window_m,
        m.rms_pos_err_after5_m,
        m.final_pos_err_m
    );
    let _ = writeln!(
        s,
        "  settling time (< 0.1 m): {}",
        m.settling_time_s
            .map_or_else(|| "never".into(), |t| format!("{t:.3} s"))
    );
    let _ = writeln!(
        s,
        "  torque: rms {:.3} N·m, max |tau| {:.3} N·m, chatter {:.2} N·m/s, saturated {:.1} % of steps",
        m.torque_rms_nm,
        m.max_abs_torque_nm,
        m.chatter,
        100.0 * m.saturated_fraction
    );
    if let Some(f) = m.fault_est_rmse {
        let _ = writeln!(s, "  fault estimate rmse over the window: {f:.4}");
    }
    if let Some(r) = &out.sensing {
        let e = &r.estimator;
        let _ = writeln!(
            s,
            "  sensing {}: {} external poses accepted, {} rejected ({} outliers, {} too old, {} out of order), {} resets; gyro {:?}, bias {:.4} rad/s; final std x {:.4} m, θ {:.4} rad",
            scn.sensing.preset.name(),
            e.accepted,
            e.rejected.total(),
            e.rejected.outlier,
            e.rejected.too_old,
            e.rejected.out_of_order,
            e.resets,
            e.gyro,
            e.gyro_bias_radps,
            e.covariance_diag[0].sqrt(),
            e.covariance_diag[2].sqrt()
        );
        if let Some(p) = &r.pose_source {
            let _ = writeln!(
                s,
                "  pose source: {} taken, {} dropped, {} outliers injected, {} delivered",
                p.taken, p.dropped, p.outliers, p.delivered
            );
        }
    }
    if let Some((step, reason)) = out.stop {
        let _ = writeln!(
            s,
            "  SAFE STOP at t = {:.3} s: {reason:?}; the runtime held the motors off from there (book/src/explanation/decisions.md D133; `hil-sim run --csv` traces the lead-up)",
            step as f64 * scn.control_period_s
        );
    }
    if out.rejected_steps > 0 {
        let _ = writeln!(
            s,
            "  WARNING: {} controller steps output no torque ({}); a reference beyond the robot is refused before the run (`hil-sim run`), so look at the sensing and the robot file's limits",
            out.rejected_steps,
            match out.stop {
                Some(_) => "the steps after the safe stop above and any input faults",
                None => "an implausible or missing measurement each",
            }
        );
    }
    s
}

// ---- `compare` ----

/// One row of `compare`: a paper case with one controller.
#[derive(Debug, Serialize)]
pub struct CompareRow {
    /// Paper case (1 or 2).
    pub case: u8,
    /// The run.
    #[serde(flatten)]
    pub report: RunReport,
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

/// Title of a case's figures, e.g. `Case 2 (β = 0.183 rad/s, ε = 0.152)`.
pub fn case_plot_title(case: u8, scn: &Scenario) -> String {
    format!(
        "Case {case} (β = {:.3} rad/s{})",
        scn.perturbations.beta,
        if scn.perturbations.eps > 0.0 {
            format!(", ε = {:.3}", scn.perturbations.eps)
        } else {
            String::new()
        }
    )
}

/// The text `compare` prints without `--json`: the scenarios, the metrics
/// table with its legend, the timing and where the files went.
pub fn compare_text(
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
    text += &plot_files_text(
        plot_files,
        "case<N>_{xy,errors,velocities,torques,faults}.{png,svg}",
    );
    text
}

/// The line saying how many plot files went where (`what`: their names),
/// or nothing when no plot was written: every subcommand's one wording.
pub fn plot_files_text(plot_files: Option<(&[Vec<PathBuf>], &Path)>, what: &str) -> String {
    match plot_files {
        Some((files, dir)) if !files.is_empty() => {
            let n = files.iter().map(Vec::len).sum::<usize>();
            let what = if what.is_empty() {
                String::new()
            } else {
                format!(" ({what})")
            };
            format!("{n} plot files written to {}{what}\n", dir.display())
        }
        _ => String::new(),
    }
}

/// The second part of `compare`'s text: the same runs with the reference
/// governor, the health machine and the large-error bound (the defaults
/// beyond the paper), with their columns.
pub fn beyond_paper_text(
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
    text += &plot_files_text(
        plot_files,
        "case<N>_gov_{xy,errors,velocities,torques,faults,pacing}.{png,svg}",
    );
    text
}

/// The sensing block of `compare`: one table of Case 2 per preset and
/// controller, with the estimator's counts.
pub fn compare_sensing_text(results: &[(Sensing, Scenario, Vec<SimOutput>)]) -> String {
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
        "\ncase 2 through the firmware runtime, paper setting (what sensing costs on a robot; book/src/reference/scenario-file.md):\n",
    );
    text += &metrics_table(&["sensing", "controller"], &rows);
    text += "mocap: encoders, gyro, pose at 100 Hz 10 ms late 2 mm / 0.005 rad; odometry: encoders only\n";
    text
}

/// The content of `metrics_sensing.json`: one object per sensing preset and
/// controller of Case 2 (`case`, `sensing`, `report`), pretty JSON.
pub fn compare_sensing_json(
    results: &[(Sensing, Scenario, Vec<SimOutput>)],
) -> Result<String, String> {
    let sensing_rows: Vec<serde_json::Value> = results
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
    serde_json::to_string_pretty(&sensing_rows).map_err(|e| e.to_string())
}

// ---- `run` ----

/// What `run` prints: one JSON object with `json`, else the human summary
/// and, with a CSV (`csv`: its path and the rows written), where it went.
pub fn run_text(
    kind: ControllerKind,
    scn: &Scenario,
    res: &SimOutput,
    csv: Option<&Path>,
    json: bool,
) -> String {
    if json {
        RunReport::new(kind, scn, res).to_json() + "\n"
    } else {
        let mut t = human_summary(kind, scn, res);
        if let Some(p) = csv {
            t += &format!(
                "  trace: {} rows written to {}\n",
                res.trace.len(),
                p.display()
            );
        }
        t
    }
}

// ---- `montecarlo` and `merge` ----

/// The error of a sweep with `failed` simulations, after its output;
/// `where_` says where their messages are.
pub fn failed_error(failed: usize, where_: &str) -> Result<(), String> {
    if failed > 0 {
        return Err(format!("{failed} simulations failed ({where_})"));
    }
    Ok(())
}

/// The sweep's description and statistics table, as both `montecarlo` and
/// `merge` print them (followed by one line on timing or shard files).
pub fn mc_text(sweep: &McConfig, stats: &[ControllerStats]) -> String {
    format!("{}\n\n{}\n", sweep.describe(), stats_table(stats))
}

/// What an unsharded `montecarlo` prints: the statistics (table or JSON)
/// and the throughput; `file` is where `--out` wrote the records.
pub fn mc_report(
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
pub fn shard_report(
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

/// What `merge` prints: the merged statistics (table or JSON) and where
/// they came from.
pub fn merge_text(m: &Merged, json: bool) -> Result<String, String> {
    Ok(if json {
        serde_json::to_string_pretty(m).map_err(|e| e.to_string())? + "\n"
    } else {
        mc_text(&m.sweep, &m.stats)
            + &format!(
                "{} simulations merged from {} shard files (the shards ran {:.2} s in total)\n",
                m.simulations,
                m.shard_files.len(),
                m.shards_elapsed_s
            )
    })
}

pub use track_log::csv::{read_trace_csv, write_trace_csv, CSV_HEADER};

#[cfg(test)]
mod tests {
    use super::*;

    /// The metrics of a trace logged at every control step, computed from
    /// its rows by `metrics_from_trace`, equal the simulator's own (the same
    /// accumulator fed the same values).
    #[test]
    fn metrics_from_a_full_trace_equal_the_simulation() {
        let mut scn = Scenario {
            duration_s: 12.0,
            ..Scenario::paper_case(2, 3, None, None)
        };
        scn.perturbations.window_s = [4.0, 9.0];
        let cfg = crate::sim::controller_config(&scn, ControllerKind::Proposed);
        let out = crate::sim::run_with(&scn, cfg, 1).unwrap();
        let m =
            track_log::metrics_from_trace(&out.trace, scn.perturbations.window_s, true).unwrap();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * (1.0 + a.abs());
        let s = &out.metrics;
        assert!(close(m.rms_pos_err_m, s.rms_pos_err_m));
        assert!(close(m.rms_pos_err_window_m, s.rms_pos_err_window_m));
        assert!(close(m.max_pos_err_window_m, s.max_pos_err_window_m));
        assert!(close(m.torque_rms_nm, s.torque_rms_nm));
        assert!(close(m.chatter, s.chatter));
        assert!(close(m.fault_est_rmse.unwrap(), s.fault_est_rmse.unwrap()));
        assert_eq!(m.settling_time_s.is_some(), s.settling_time_s.is_some());
        assert!(close(m.saturated_fraction, s.saturated_fraction));
    }

    #[test]
    fn table_has_one_row_per_entry_and_aligned_columns() {
        let m = Metrics {
            rms_pos_err_m: 0.5,
            rms_pos_err_window_m: 0.1,
            max_pos_err_window_m: 0.2,
            rms_pos_err_after5_m: 0.05,
            final_pos_err_m: 0.01,
            settling_time_s: None,
            torque_rms_nm: 1.0,
            max_abs_torque_nm: 5.0,
            chatter: 3.0,
            saturated_fraction: 0.25,
            fault_est_rmse: Some(0.03),
            time_lag_final_s: None,
            min_time_scale: None,
            degraded_fraction: None,
            health_transitions: None,
            safe_stop: None,
            rms_est_err_window_m: None,
        };
        let rows = vec![
            (vec!["1".into(), "smc".into()], m.clone()),
            (vec!["2".into(), "proposed".into()], m),
        ];
        let t = metrics_table(&["case", "controller"], &rows);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines.len(), 5);
        assert!(lines[0].starts_with("case  controller"));
        assert!(lines[4].contains("proposed") && lines[4].contains("25.0"));
        assert!(lines[3].contains(" - "), "None shows as '-': {}", lines[3]);
    }
}
