//! Runs: one scenario with one controller (`hil-sim run`), a batch of them
//! across threads, and the paper comparison (`hil-sim compare`). Every run
//! goes through hil-sim's own entry points (`sim::run_with`,
//! `cli::compare::compare_runs`) with the GIL released.

use crate::convert::{controller, pool, to_py};
use crate::error::{Error, Result};
use crate::model::{Robot, Scenario};
use controller_core::ControllerKind;
use hil_sim::report::{compare_rows, RunReport};
use hil_sim::sim::{controller_config, run_with, SimOutput};
use numpy::ndarray::Array2;
use numpy::IntoPyArray;
use pyo3::prelude::*;
use rayon::prelude::*;
use track_log::csv::{trace_values, CSV_COLUMNS, CSV_HEADER};

/// One run's outcome: the metrics (the keys of `hil-sim run --json`), the
/// report (that whole JSON object), and the trace when one was asked for.
#[pyclass(module = "wmrsim", frozen)]
pub struct RunResult {
    scenario: hil_sim::Scenario,
    out: SimOutput,
}

#[pymethods]
impl RunResult {
    /// `smc`, `asmc` or `proposed`.
    #[getter]
    fn controller(&self) -> &'static str {
        self.out.kind.name()
    }

    /// Control steps the controller rejected (bad input); 0 in a healthy run.
    #[getter]
    fn rejected_steps(&self) -> u32 {
        self.out.rejected_steps
    }

    /// The metrics: a dict with the keys of `hil-sim run --json`'s metrics
    /// (None where the CLI prints null).
    #[getter]
    fn metrics<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.out.metrics)
    }

    /// The whole object `hil-sim run --json` prints: the metrics plus
    /// `controller`, `scenario`, `rejected_steps` and `runtime_stop`.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(
            py,
            &RunReport::new(self.out.kind, &self.scenario, &self.out),
        )
    }

    /// The scenario that ran.
    #[getter]
    fn scenario(&self) -> Scenario {
        Scenario {
            inner: self.scenario.clone(),
        }
    }

    /// The trace (`wmrsim.Trace`: a float64 array, one row per sample, the
    /// columns of `hil-sim run --csv`), or None when the run kept none.
    #[getter]
    fn trace<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        if self.out.trace.is_empty() {
            return Ok(None);
        }
        let flat: Vec<f64> = self.out.trace.iter().flat_map(trace_values).collect();
        let arr = Array2::from_shape_vec((self.out.trace.len(), CSV_COLUMNS), flat)
            .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?
            .into_pyarray(py);
        let cols: Vec<&str> = CSV_HEADER.split(',').collect();
        let cls = py.import("wmrsim")?.getattr("Trace")?;
        cls.call1((cols, arr)).map(Some)
    }

    fn __repr__(&self) -> String {
        format!(
            "RunResult(controller={:?}, scenario={:?}, rms_pos_err_window_m={}, trace_rows={})",
            self.out.kind.name(),
            self.scenario.name,
            self.out.metrics.rms_pos_err_window_m,
            self.out.trace.len()
        )
    }
}

/// The trace decimation of a run: 0 without a trace, `every` when given,
/// else the CLI's 10 ms; refused like `run --csv` beyond 1 GB unless
/// `force`.
fn trace_decimation(
    scn: &hil_sim::Scenario,
    trace: bool,
    every: Option<usize>,
    force: bool,
) -> Result<usize> {
    if !trace {
        return Ok(0);
    }
    if every == Some(0) {
        return Err(Error::Invalid {
            message: "trace_every must be at least 1 (control steps per trace row)".into(),
            field: Some("trace_every".into()),
        });
    }
    let n = every.unwrap_or_else(|| hil_sim::sim::trace_every(scn));
    hil_sim::limits::check_csv(scn, n, force).map_err(Error::invalid)?;
    Ok(n)
}

/// The CLI's checks before a run (`hil-sim run`).
fn check(scn: &hil_sim::Scenario) -> Result<()> {
    hil_sim::limits::check_scenario(scn).map_err(Error::invalid)?;
    hil_sim::limits::check_within_robot(scn).map_err(Error::invalid)
}

fn simulate(scn: &hil_sim::Scenario, kind: ControllerKind, every: usize) -> Result<RunResult> {
    let out = run_with(scn, controller_config(scn, kind), every).map_err(Error::Simulation)?;
    Ok(RunResult {
        scenario: scn.clone(),
        out,
    })
}

/// Runs `scenario` with `controller` (`hil-sim run`): the same checks, the
/// same numbers. `trace=True` keeps a row every `trace_every` control
/// steps (default: every 10 ms, as `run --csv`). The GIL is released while
/// the simulation runs.
#[pyfunction]
#[pyo3(signature = (scenario, controller="proposed", *, trace=true, trace_every=None, force=false))]
pub fn run(
    py: Python<'_>,
    scenario: &Scenario,
    controller: &str,
    trace: bool,
    trace_every: Option<usize>,
    force: bool,
) -> Result<RunResult> {
    let kind = crate::convert::controller(controller)?;
    let scn = &scenario.inner;
    check(scn)?;
    let every = trace_decimation(scn, trace, trace_every, force)?;
    py.detach(|| simulate(scn, kind, every))
}

/// Runs every scenario of `scenarios` with `controllers` (one name for
/// all, or one per scenario) on `threads` worker threads (None: one per
/// core), the GIL released; results in input order, each equal to
/// `run(scenario, controller)`. The first bad input or failed run raises.
#[pyfunction]
#[pyo3(signature = (scenarios, controllers=None, *, trace=false, trace_every=None, threads=None, force=false))]
#[allow(clippy::too_many_arguments)]
pub fn run_batch(
    py: Python<'_>,
    scenarios: Vec<PyRef<'_, Scenario>>,
    controllers: Option<&Bound<'_, PyAny>>,
    trace: bool,
    trace_every: Option<usize>,
    threads: Option<usize>,
    force: bool,
) -> Result<Vec<RunResult>> {
    let n = scenarios.len();
    let names: Vec<String> = match controllers {
        None => vec!["proposed".into(); n],
        Some(c) => match c.extract::<String>() {
            Ok(one) => vec![one; n],
            Err(_) => c.extract::<Vec<String>>().map_err(|_| Error::Invalid {
                message: "controllers must be a name or a list of names (smc, asmc, proposed)"
                    .into(),
                field: Some("controllers".into()),
            })?,
        },
    };
    if names.len() != scenarios.len() {
        return Err(Error::Invalid {
            message: format!(
                "controllers: {} names for {} scenarios (give one name, or one per scenario)",
                names.len(),
                scenarios.len()
            ),
            field: Some("controllers".into()),
        });
    }
    let mut jobs = Vec::with_capacity(scenarios.len());
    for (i, (s, n)) in scenarios.iter().zip(&names).enumerate() {
        let at = |e: Error| match e {
            Error::Invalid { message, field } => Error::Invalid {
                message: format!("scenarios[{i}]: {message}"),
                field,
            },
            e => e,
        };
        let kind = controller(n).map_err(at)?;
        let every = trace_decimation(&s.inner, trace, trace_every, force).map_err(at)?;
        jobs.push((s.inner.clone(), kind, every));
    }
    let pool = pool(threads)?;
    py.detach(|| {
        pool.install(|| {
            jobs.par_iter()
                .enumerate()
                .map(|(i, (scn, kind, every))| {
                    // The CLI's limit checks (about 1.5 ms a scenario) run in
                    // the pool too: serial, they capped 2 threads at 1.75x.
                    check(scn)
                        .and_then(|()| simulate(scn, *kind, *every))
                        .map_err(|e| match e {
                            Error::Simulation(m) => {
                                Error::Simulation(format!("scenarios[{i}]: {m}"))
                            }
                            Error::Invalid { message, field } => Error::Invalid {
                                message: format!("scenarios[{i}]: {message}"),
                                field,
                            },
                            e => e,
                        })
                })
                .collect()
        })
    })
}

/// The paper comparison (`hil-sim compare --json`): both paper cases × the
/// three controllers, in the paper's setting (no governor, no health
/// machine) unless `beyond_paper` (`metrics_governor.json`); one dict per
/// row with the keys of `metrics.json`.
#[pyfunction]
#[pyo3(signature = (seed=1, *, beta=None, eps=None, robot=None, plant=None, beyond_paper=false, threads=None))]
#[allow(clippy::too_many_arguments)]
pub fn compare<'py>(
    py: Python<'py>,
    seed: u64,
    beta: Option<f64>,
    eps: Option<f64>,
    robot: Option<Robot>,
    plant: Option<Robot>,
    beyond_paper: bool,
    threads: Option<usize>,
) -> Result<Bound<'py, PyAny>> {
    for (name, v) in [("beta", beta), ("eps", eps)] {
        if v.is_some_and(|x| !x.is_finite()) {
            return Err(Error::Invalid {
                message: format!("{name} must be a finite number, got {v:?}"),
                field: Some(name.into()),
            });
        }
    }
    let pool = pool(threads)?;
    let robots = (
        robot.as_ref().map(|r| &r.inner),
        plant.as_ref().map(|r| &r.inner),
    );
    let results = py.detach(|| {
        pool.install(|| hil_sim::cli::compare::compare_runs(seed, beta, eps, beyond_paper, robots))
    });
    let results = results.map_err(Error::invalid)?;
    Ok(to_py(py, &compare_rows(&results))?)
}

/// Seconds of each of `reps` runs of `scenario` with `controller` called
/// from Rust (no Python between them): the native reference of the
/// benchmark (bench/bench.py) for the per-call overhead of `run`. With
/// `checks`, each run does what `hil-sim run` and `run` do (the limits
/// checks, then the simulation); without, the simulation alone.
#[pyfunction]
#[pyo3(signature = (scenario, controller="proposed", reps=10, trace=false, checks=true))]
pub fn native_seconds(
    py: Python<'_>,
    scenario: &Scenario,
    controller: &str,
    reps: usize,
    trace: bool,
    checks: bool,
) -> Result<Vec<f64>> {
    let kind = crate::convert::controller(controller)?;
    let scn = &scenario.inner;
    check(scn)?;
    py.detach(|| {
        (0..reps)
            .map(|_| {
                let t0 = std::time::Instant::now();
                if checks {
                    check(scn)?;
                }
                let every = trace_decimation(scn, trace, None, false)?;
                let out = run_with(scn, controller_config(scn, kind), every)
                    .map_err(Error::Simulation)?;
                std::hint::black_box(&out);
                Ok(t0.elapsed().as_secs_f64())
            })
            .collect()
    })
}
