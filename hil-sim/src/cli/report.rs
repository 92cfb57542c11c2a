//! `hil-sim report FILE.csv`: metrics and plots of any trace log.

use super::controller_arg::ControllerArg;
use crate::log_report::{load_trace, plot_trace, trace_metrics};
use crate::report::metrics_table;
use clap::Args;
use controller_core::ControllerKind;
use std::io::Write;
use std::path::PathBuf;

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
            let text = crate::report::plot_files_text(Some((&[files], &a.out)), "");
            out.write_all(text.as_bytes()).map_err(|e| e.to_string())?;
        }
    }
    Ok(())
}
