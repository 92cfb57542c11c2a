//! [`MonteCarlo`]: `hil-sim montecarlo` (random paper scenarios per
//! controller, their mean/p95/max): the whole sweep, or the records of a
//! block of run indices (what a `--shard` computes, what a Ray task
//! computes) and the statistics of records gathered from anywhere
//! (`merge`). hil-sim's `run_records` and `stats_from_records` do the work.

use crate::convert::{pool, sensing, to_py};
use crate::error::{Error, Result};
use crate::model::{Robot, Scenario};
use hil_sim::montecarlo::{
    run_records, stats_from_records, McConfig, McResult, SimRecord, MAX_RUNS,
};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

/// A Monte-Carlo sweep (`hil-sim montecarlo`): `runs` random paper
/// scenarios of `case` per controller, run i seeded from (`seed`, i), so
/// any block of run indices computed anywhere gives the same records.
#[pyclass(module = "wmrsim", frozen)]
pub struct MonteCarlo {
    cfg: McConfig,
}

fn invalid(field: &str, message: String) -> Error {
    Error::Invalid {
        message,
        field: Some(field.into()),
    }
}

#[pymethods]
impl MonteCarlo {
    /// The sweep of `hil-sim montecarlo --runs RUNS --case CASE --seed SEED
    /// [--vary-mass] [--duration D] [--sensing S] [--paper-setting]
    /// [--robot] [--plant]`, checked as the CLI checks it.
    #[new]
    #[pyo3(signature = (runs, *, case=2, seed=1, vary_mass=false, duration_s=None, sensing="ideal", paper_setting=false, robot=None, plant=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        runs: u64,
        case: u8,
        seed: u64,
        vary_mass: bool,
        duration_s: Option<f64>,
        sensing: &str,
        paper_setting: bool,
        robot: Option<Robot>,
        plant: Option<Robot>,
    ) -> Result<Self> {
        if !(1..=MAX_RUNS).contains(&runs) {
            return Err(invalid(
                "runs",
                format!("runs must be in 1..={MAX_RUNS}, got {runs}"),
            ));
        }
        if !(1..=2).contains(&case) {
            return Err(invalid("case", format!("case must be 1 or 2, got {case}")));
        }
        let cfg = McConfig {
            runs: runs as usize,
            case,
            seed,
            vary_mass,
            duration_s,
            sensing: crate::convert::sensing(sensing)?,
            paper_setting,
            robot: robot.map(|r| r.inner),
            plant: plant.map(|r| r.inner),
        };
        cfg.validate().map_err(Error::invalid)?;
        hil_sim::limits::check_scenario(&cfg.scenario(0)).map_err(Error::invalid)?;
        hil_sim::limits::check_within_robot(&cfg.scenario(0)).map_err(Error::invalid)?;
        Ok(Self { cfg })
    }

    /// Runs per controller.
    #[getter]
    fn runs(&self) -> usize {
        self.cfg.runs
    }

    /// The scenario of run `i`.
    fn scenario(&self, i: u64) -> Scenario {
        Scenario {
            inner: self.cfg.scenario(i),
        }
    }

    /// The whole sweep on `threads` threads (None: one per core): the
    /// object `hil-sim montecarlo --json` prints (`stats`, one entry per
    /// controller with mean/p95/max/n of every metric; `simulations`;
    /// and the timing: `elapsed_s`, `runs_per_s`, `threads`).
    #[pyo3(signature = (*, threads=None))]
    fn run<'py>(&self, py: Python<'py>, threads: Option<usize>) -> Result<Bound<'py, PyAny>> {
        let pool = pool(threads)?;
        let rec =
            py.detach(|| pool.install(|| run_records(&self.cfg, 0..self.cfg.runs as u64, &|| {})));
        Ok(to_py(py, &McResult::from_records(&rec))?)
    }

    /// The records of run indices `start..stop` (every controller): a list
    /// of dicts, each a line of `montecarlo --shard`'s file (`run`, `seed`,
    /// `controller`, then `metrics` or `error`). Pass the records of every
    /// block to `MonteCarlo.stats`.
    #[pyo3(signature = (start, stop, *, threads=None))]
    fn records<'py>(
        &self,
        py: Python<'py>,
        start: u64,
        stop: u64,
        threads: Option<usize>,
    ) -> Result<Bound<'py, PyAny>> {
        let n = self.cfg.runs as u64;
        if start > stop || stop > n {
            return Err(invalid(
                "stop",
                format!("run indices {start}..{stop} are not within 0..{n} (0 <= start <= stop <= runs)"),
            ));
        }
        let pool = pool(threads)?;
        let rec = py.detach(|| pool.install(|| run_records(&self.cfg, start..stop, &|| {})));
        Ok(to_py(py, &rec.records)?)
    }

    /// The statistics of `records` (from `records`, in any order and
    /// split): `montecarlo --json`'s `stats`, as `hil-sim merge` computes
    /// them.
    #[staticmethod]
    fn stats<'py>(py: Python<'py>, records: &Bound<'py, PyAny>) -> Result<Bound<'py, PyAny>> {
        let json = py.import("json")?.call_method1("dumps", (records,))?;
        let text: String = json.extract()?;
        let recs: Vec<SimRecord> = serde_json::from_str(&text).map_err(|e| {
            invalid(
                "records",
                format!("records: not records of MonteCarlo.records: {e}"),
            )
        })?;
        Ok(to_py(py, &stats_from_records(&recs))?)
    }

    /// The sweep as `hil-sim montecarlo` describes it.
    fn describe(&self) -> String {
        self.cfg.describe()
    }

    fn __repr__(&self) -> String {
        format!("MonteCarlo({})", self.cfg.describe())
    }

    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let c = &self.cfg;
        let kw = PyDict::new(py);
        kw.set_item("case", c.case)?;
        kw.set_item("seed", c.seed)?;
        kw.set_item("vary_mass", c.vary_mass)?;
        kw.set_item("duration_s", c.duration_s)?;
        kw.set_item("sensing", c.sensing.name())?;
        kw.set_item("paper_setting", c.paper_setting)?;
        kw.set_item("robot", c.robot.clone().map(|inner| Robot { inner }))?;
        kw.set_item("plant", c.plant.clone().map(|inner| Robot { inner }))?;
        let f = py.import("wmrsim")?.getattr("_rebuild")?;
        let args = (py.get_type::<MonteCarlo>(), (c.runs,), kw);
        PyTuple::new(py, [f, args.into_pyobject(py)?.into_any()])
    }
}

/// Checks `sensing` names (used by [`crate::tune`]).
pub fn sensing_list(names: &[String]) -> Result<Vec<hil_sim::scenario::Sensing>> {
    names.iter().map(|n| sensing(n)).collect()
}
