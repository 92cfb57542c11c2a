//! `hil-sim report FILE.csv`: the metrics and the plots of a trace log,
//! written by `hil-sim run --csv` or by `wmr record` (the same columns),
//! computed by the same code as a simulation's ([`track_log`]).

use crate::metrics::Metrics;
use crate::scenario::Scenario;
use crate::sim::SimOutput;
use controller_core::ControllerKind;
use std::path::{Path, PathBuf};

/// Reads a trace CSV.
pub fn load_trace(path: &Path) -> Result<Vec<crate::TraceSample>, String> {
    let f =
        std::fs::File::open(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    track_log::csv::read_trace_csv(std::io::BufReader::new(f), &path.display().to_string())
}

/// Metrics of a trace log; `window_s` as in a scenario (`[0, 0]`: none).
pub fn trace_metrics(
    trace: &[crate::TraceSample],
    window_s: [f64; 2],
    kind: ControllerKind,
) -> Result<Metrics, String> {
    let fault_known = trace.iter().all(|s| s.f_true.iter().all(|x| x.is_finite()));
    track_log::metrics_from_trace(
        trace,
        window_s,
        kind == ControllerKind::Proposed && fault_known,
    )
    .ok_or_else(|| "the log needs at least two rows with increasing time".to_string())
}

/// Draws the case figures of one logged run into `dir` (`<prefix>_*.png|svg`).
pub fn plot_trace(
    dir: &Path,
    prefix: &str,
    trace: Vec<crate::TraceSample>,
    metrics: Metrics,
    window_s: [f64; 2],
    kind: ControllerKind,
) -> Result<Vec<PathBuf>, String> {
    let duration = trace.last().map_or(0.0, |s| s.t_s);
    let mut scn = Scenario {
        name: prefix.into(),
        duration_s: duration.max(1e-3),
        ..Scenario::default()
    };
    scn.perturbations.window_s = window_s;
    let run = SimOutput {
        kind,
        trace,
        metrics,
        rejected_steps: 0,
        stop: None,
        sensing: None,
    };
    crate::plot::write_case_plots(dir, prefix, prefix, &scn, std::slice::from_ref(&run))
}
