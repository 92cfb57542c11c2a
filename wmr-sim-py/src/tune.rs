//! [`TuneSet`]: the tuner's scenario set and cost (`hil-sim tune`,
//! book/src/how-to/tuning.md) for an outside optimiser or scheduler: the gains it
//! tunes and their bounds, the start point, and the cost of one gain
//! vector of the unit box (what the optimiser minimises) or of a whole
//! population. hil-sim's `tune::cost::evaluate_with` and `tune::space`
//! do the work.

use crate::error::{Error, Result};
use crate::mc::sensing_list;
use crate::model::{Robot, Scenario};
use controller_core::{ControllerConfig, ControllerKind};
use hil_sim::tune::cost::{evaluate_with, CostSpec, Evaluation, PresetMean};
use hil_sim::tune::set::{Part, TuneSet as HilTuneSet};
use hil_sim::tune::space;
use numpy::{AllowTypeChange, PyArrayLike1, PyArrayLike2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

/// The tuning set of `hil-sim tune --robot FILE` (training and validation
/// scenarios drawn around the robot) with the cost's options.
#[pyclass(module = "wmrsim", frozen)]
pub struct TuneSet {
    set: HilTuneSet,
    spec: CostSpec,
}

fn invalid(field: &str, message: String) -> Error {
    Error::Invalid {
        message,
        field: Some(field.into()),
    }
}

fn part_named(name: &str) -> Result<Part> {
    match name {
        "training" => Ok(Part::Training),
        "validation" => Ok(Part::Validation),
        _ => Err(invalid(
            "part",
            format!("part must be 'training' or 'validation', got '{name}'"),
        )),
    }
}

impl TuneSet {
    /// The unit-box point `x` checked against `kind`'s gains.
    fn point(&self, kind: ControllerKind, x: &[f64], what: &str) -> Result<Vec<f64>> {
        let dims = space::dims(kind);
        if x.len() != dims.len() {
            return Err(invalid(
                what,
                format!(
                    "{what} has {} values; {} tunes {} gains ({}): see TuneSet.dims",
                    x.len(),
                    kind.name(),
                    dims.len(),
                    dims.iter().map(|d| d.name).collect::<Vec<_>>().join(", ")
                ),
            ));
        }
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(invalid(
                what,
                format!(
                    "{what}[{i}] ({}) is {}: a point of the unit box has finite coordinates (0 = lower bound, 1 = upper bound)",
                    dims[i].name, x[i]
                ),
            ));
        }
        Ok(x.to_vec())
    }

    /// The evaluation of `x` (None: the robot file's gains) on `part`, as
    /// the tuner's objective sees it: `x` clamped into the box, the cost,
    /// plus the box penalty of `x`.
    fn evaluate(&self, kind: ControllerKind, x: Option<&[f64]>, part: Part) -> (Evaluation, f64) {
        let scenarios = self.set.scenarios(part);
        let make = |c: &ControllerConfig| match x {
            Some(u) => space::decode(c, &clamped(u)),
            None => *c,
        };
        let e = evaluate_with(&scenarios, kind, &make, &|| {}, self.spec);
        let penalty = x.map_or(0.0, space::box_penalty);
        (e, penalty)
    }
}

/// `u` clamped into the unit box (as the tuner's objective does).
fn clamped(u: &[f64]) -> Vec<f64> {
    u.iter().map(|v| v.clamp(0.0, 1.0)).collect()
}

#[pymethods]
impl TuneSet {
    /// The set of `hil-sim tune --robot FILE --sensing S --seed SEED
    /// --train N --validate M --torque-scale-min T --duration D
    /// --disturbance-max F --preset-mean P --chatter-weight W`, checked
    /// as the CLI checks it.
    #[new]
    #[pyo3(signature = (robot, *, sensing=vec!["mocap".to_string(), "imu".to_string()], seed=1, train=hil_sim::cli::tune::DEFAULT_TRAIN, validate=hil_sim::cli::tune::DEFAULT_VALIDATE, figure8=hil_sim::tune::set::DEFAULT_FIGURE8, square=hil_sim::tune::set::DEFAULT_SQUARE, torque_scale_min=1.0, duration_s=hil_sim::cli::tune::DEFAULT_DURATION_S, disturbance_max=hil_sim::tune::set::DISTURBANCE_FRACTION.1, preset_mean="geometric", chatter_weight=hil_sim::tune::cost::CHATTER_WEIGHT_M_S))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        robot: Robot,
        sensing: Vec<String>,
        seed: u64,
        train: usize,
        validate: usize,
        figure8: usize,
        square: usize,
        torque_scale_min: f64,
        duration_s: f64,
        disturbance_max: f64,
        preset_mean: &str,
        chatter_weight: f64,
    ) -> Result<Self> {
        let preset_mean = match preset_mean {
            "arithmetic" => PresetMean::Arithmetic,
            "geometric" => PresetMean::Geometric,
            _ => {
                return Err(invalid(
                    "preset_mean",
                    format!("preset_mean must be 'arithmetic' or 'geometric', got '{preset_mean}'"),
                ))
            }
        };
        let set = HilTuneSet {
            robot: robot.inner,
            sensing: sensing_list(&sensing)?,
            seed,
            training: train,
            validation: validate,
            figure8,
            square,
            torque_scale_min,
            duration_s,
            disturbance_max_fraction: disturbance_max,
        };
        let spec = CostSpec {
            preset_mean,
            chatter_weight_m_s: chatter_weight,
        };
        spec.validate().map_err(|e| invalid("chatter_weight", e))?;
        set.validate().map_err(Error::invalid)?;
        Ok(Self { set, spec })
    }

    /// The gains `controller` tunes, in the order of the vector: a list of
    /// (robot-file key, lower bound, upper bound); coordinate u in [0, 1]
    /// is the gain lo·(hi/lo)^u.
    #[staticmethod]
    fn dims(controller: &str) -> Result<Vec<(&'static str, f64, f64)>> {
        let k = crate::convert::controller(controller)?;
        Ok(space::dims(k)
            .iter()
            .map(|d| (d.name, d.lo, d.hi))
            .collect())
    }

    /// The robot file's gains of `controller` as a point of the unit box
    /// (the tuner's restart 0).
    fn start(&self, controller: &str) -> Result<Vec<f64>> {
        let k = crate::convert::controller(controller)?;
        Ok(space::encode(
            &self.set.scenario(Part::Training, 0).controller_config(k),
        ))
    }

    /// The scenarios of `part` ('training' or 'validation').
    #[pyo3(signature = (part="training"))]
    fn scenarios(&self, part: &str) -> Result<Vec<Scenario>> {
        Ok(self
            .set
            .scenarios(part_named(part)?)
            .into_iter()
            .map(|inner| Scenario { inner })
            .collect())
    }

    /// The cost of `controller` with the gains of unit-box point `x` (None:
    /// the robot file's own gains) on `part`: a dict with the tuner's
    /// evaluation (`cost`, `p95_rms_win_m`, `per_sensing`, ... as in
    /// `hil-sim tune --json`) plus `box_penalty` and `objective` (= cost +
    /// box_penalty: what the optimiser minimises). GIL released; the
    /// scenarios run on every core.
    #[pyo3(signature = (controller, x=None, *, part="training"))]
    fn cost<'py>(
        &self,
        py: Python<'py>,
        controller: &str,
        x: Option<PyArrayLike1<'py, f64, AllowTypeChange>>,
        part: &str,
    ) -> Result<Bound<'py, PyAny>> {
        let k = crate::convert::controller(controller)?;
        let part = part_named(part)?;
        let x = match x {
            Some(a) => Some(self.point(
                k,
                a.as_slice().map_err(|e| invalid("x", e.to_string()))?,
                "x",
            )?),
            None => None,
        };
        let (e, penalty) = py.detach(|| self.evaluate(k, x.as_deref(), part));
        let d = crate::convert::to_py(py, &e)?;
        let d = d
            .cast_into::<PyDict>()
            .map_err(|e| Error::Simulation(e.to_string()))?;
        d.set_item("box_penalty", penalty)?;
        d.set_item("objective", e.cost + penalty)?;
        Ok(d.into_any())
    }

    /// The objective (cost + box penalty) of each row of `population` (an
    /// n × len(dims) array of unit-box points) on `part`, in row order:
    /// one generation of the tuner, the rows one after the other, each
    /// row's scenarios on every core.
    #[pyo3(signature = (controller, population, *, part="training"))]
    fn costs<'py>(
        &self,
        py: Python<'py>,
        controller: &str,
        population: PyArrayLike2<'py, f64, AllowTypeChange>,
        part: &str,
    ) -> Result<Vec<f64>> {
        let k = crate::convert::controller(controller)?;
        let part = part_named(part)?;
        let rows: Vec<Vec<f64>> = population
            .as_array()
            .outer_iter()
            .enumerate()
            .map(|(i, r)| self.point(k, &r.to_vec(), &format!("population[{i}]")))
            .collect::<Result<_>>()?;
        Ok(py.detach(|| {
            rows.iter()
                .map(|x| {
                    let (e, p) = self.evaluate(k, Some(x), part);
                    e.cost + p
                })
                .collect()
        }))
    }

    fn __repr__(&self) -> String {
        format!(
            "TuneSet(robot={:?}, sensing={:?}, seed={}, train={}, validate={})",
            self.set.robot.name,
            self.set
                .sensing
                .iter()
                .map(|s| s.name())
                .collect::<Vec<_>>(),
            self.set.seed,
            self.set.training,
            self.set.validation
        )
    }

    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let s = &self.set;
        let kw = PyDict::new(py);
        kw.set_item(
            "sensing",
            s.sensing.iter().map(|x| x.name()).collect::<Vec<_>>(),
        )?;
        kw.set_item("seed", s.seed)?;
        kw.set_item("train", s.training)?;
        kw.set_item("validate", s.validation)?;
        kw.set_item("torque_scale_min", s.torque_scale_min)?;
        kw.set_item("duration_s", s.duration_s)?;
        kw.set_item("disturbance_max", s.disturbance_max_fraction)?;
        kw.set_item("preset_mean", self.spec.preset_mean.name())?;
        kw.set_item("chatter_weight", self.spec.chatter_weight_m_s)?;
        let robot = Robot {
            inner: s.robot.clone(),
        };
        let f = py.import("wmrsim")?.getattr("_rebuild")?;
        let args = (py.get_type::<TuneSet>(), (robot,), kw);
        PyTuple::new(py, [f, args.into_pyobject(py)?.into_any()])
    }
}
