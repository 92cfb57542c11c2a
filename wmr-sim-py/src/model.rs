//! [`Robot`] and [`Scenario`]: robot files and scenarios read, checked and
//! refused exactly as the CLI reads them (`--robot FILE`, `--scenario
//! FILE`, `--case N --seed S`), the same error texts.

use crate::convert::{dict_to_table, merge_tables, toml_to_py};
use crate::error::{Error, Result};
use hil_sim::scenario::Robot as HilRobot;
use hil_sim::scenario::Scenario as HilScenario;
use hil_sim::scenario_file::{parse_scenario, to_toml};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use std::path::{Path, PathBuf};

fn robot_error(e: robot_file::RobotFileError, origin: &str) -> Error {
    let field = match &e {
        robot_file::RobotFileError::Toml { field, .. } => field.clone(),
        robot_file::RobotFileError::Invalid { error, .. } => Some(error.field.to_string()),
        _ => None,
    };
    Error::Invalid {
        message: format!("robot file {origin}: {e}"),
        field,
    }
}

fn existing(path: &Path, what: &str) -> Result<()> {
    if path.exists() {
        Ok(())
    } else {
        Err(Error::NotFound(format!(
            "cannot read {what} file {}: no such file",
            path.display()
        )))
    }
}

/// A robot file (book/src/how-to/robot-file.md): the controller's model, gains, motor,
/// encoder and limits, validated as `hil-sim --robot FILE` validates it.
///
/// Build one with `Robot.from_file(path)`, `Robot.from_toml(text)`,
/// `Robot.from_dict(d)` or `Robot.paper()`; errors are
/// `InvalidInputError` naming the field (`err.field`) and the line.
#[pyclass(module = "wmrsim", frozen, from_py_object)]
#[derive(Clone)]
pub struct Robot {
    /// The robot.
    pub inner: HilRobot,
}

#[pymethods]
impl Robot {
    /// The paper's robot (`robots/paper.toml`).
    #[staticmethod]
    fn paper() -> Self {
        Self {
            inner: HilRobot::paper(),
        }
    }

    /// Reads a robot file (TOML, every field present, no unknown key).
    #[staticmethod]
    fn from_file(path: PathBuf) -> Result<Self> {
        existing(&path, "robot")?;
        let inner = hil_sim::cli::robot_arg::load_robot(&path).map_err(|message| {
            // Same text as the CLI; the field from the typed error.
            let field = std::fs::read_to_string(&path)
                .ok()
                .and_then(|t| HilRobot::from_toml_str(&t).err())
                .and_then(|e| match robot_error(e, "") {
                    Error::Invalid { field, .. } => field,
                    _ => None,
                });
            Error::Invalid { message, field }
        })?;
        Ok(Self { inner })
    }

    /// Parses the text of a robot file.
    #[staticmethod]
    fn from_toml(text: &str) -> Result<Self> {
        HilRobot::from_toml_str(text)
            .map(|inner| Self { inner })
            .map_err(|e| robot_error(e, "<text>"))
    }

    /// A robot from a dict of the file's tables (`Robot.to_dict()`'s shape).
    #[staticmethod]
    fn from_dict(d: &Bound<'_, PyDict>) -> Result<Self> {
        let t = dict_to_table(d, "")?;
        let text = toml::to_string(&t).map_err(|e| Error::invalid(format!("robot: {e}")))?;
        Self::from_toml(&text)
    }

    /// The robot as the text of a robot file (`from_toml` reads it back to
    /// the same robot).
    fn to_toml(&self) -> String {
        self.inner.to_toml_string()
    }

    /// The robot file's tables as a dict.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v: toml::Value = toml::from_str(&self.inner.to_toml_string())
            .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
        toml_to_py(py, &v)
    }

    /// The robot's name.
    #[getter]
    fn name(&self) -> String {
        self.inner.name.to_string()
    }

    fn __repr__(&self) -> String {
        format!("Robot(name={:?})", self.inner.name)
    }

    fn __eq__(&self, other: &Self) -> bool {
        self.inner == other.inner
    }

    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let f = py.get_type::<Robot>().getattr("from_toml")?;
        let args = PyTuple::new(py, [self.to_toml()])?;
        PyTuple::new(py, [f, args.into_any()])
    }
}

/// A scenario: every knob of one run except the controller (the paper's
/// presets, scenario files of book/src/reference/scenario-file.md, any field changed with
/// `replace`), validated as `hil-sim run` validates it.
#[pyclass(module = "wmrsim", frozen, from_py_object)]
#[derive(Clone)]
pub struct Scenario {
    /// The scenario.
    pub inner: HilScenario,
}

impl Scenario {
    /// `scn` with the robots given, validated (the CLI's `build`).
    fn checked(scn: HilScenario, robot: Option<&Robot>, plant: Option<&Robot>) -> Result<Self> {
        let scn = scn.with_robots(robot.map(|r| &r.inner), plant.map(|r| &r.inner));
        scn.validate().map_err(Error::invalid)?;
        Ok(Self { inner: scn })
    }

    /// The scenario from its TOML table (a version-2 scenario file),
    /// validated, with the robots of `like`.
    fn from_table(t: toml::Table, origin: &str, like: &HilScenario) -> Result<Self> {
        let text = toml::to_string(&t).map_err(|e| Error::invalid(format!("{origin}: {e}")))?;
        let mut scn = parse_scenario(&text, origin).map_err(Error::invalid)?;
        scn.robot = like.robot.clone();
        scn.plant.robot = like.plant.robot.clone();
        scn.validate().map_err(Error::invalid)?;
        Ok(Self { inner: scn })
    }

    fn table(&self) -> toml::Table {
        match toml::Value::try_from(&self.inner) {
            Ok(toml::Value::Table(t)) => t,
            _ => unreachable!("a Scenario serialises to a TOML table"),
        }
    }
}

#[pymethods]
impl Scenario {
    /// The paper's Case 1 (disturbance + slip) or Case 2 (+ actuator fault):
    /// `hil-sim run --case CASE --seed SEED`, β and ε drawn from the seed
    /// unless given; `robot`/`plant` as `--robot`/`--plant`.
    #[staticmethod]
    #[pyo3(signature = (case=2, seed=1, *, beta=None, eps=None, robot=None, plant=None))]
    fn paper_case(
        case: u8,
        seed: u64,
        beta: Option<f64>,
        eps: Option<f64>,
        robot: Option<Robot>,
        plant: Option<Robot>,
    ) -> Result<Self> {
        if !(1..=2).contains(&case) {
            return Err(Error::Invalid {
                message: format!("case must be 1 or 2, got {case}"),
                field: Some("case".into()),
            });
        }
        for (name, v) in [("beta", beta), ("eps", eps)] {
            if v.is_some_and(|x| !x.is_finite()) {
                return Err(Error::Invalid {
                    message: format!("{name} must be a finite number, got {v:?}"),
                    field: Some(name.into()),
                });
            }
        }
        let scn = HilScenario::paper_case(case, seed, beta, eps);
        Self::checked(scn, robot.as_ref(), plant.as_ref())
    }

    /// A scenario file (`hil-sim run --scenario FILE`), version 1 or 2.
    #[staticmethod]
    #[pyo3(signature = (path, *, robot=None, plant=None))]
    fn from_file(path: PathBuf, robot: Option<Robot>, plant: Option<Robot>) -> Result<Self> {
        existing(&path, "scenario")?;
        let scn = hil_sim::scenario_file::load_scenario(&path).map_err(Error::invalid)?;
        Self::checked(scn, robot.as_ref(), plant.as_ref())
    }

    /// The text of a scenario file.
    #[staticmethod]
    #[pyo3(signature = (text, *, robot=None, plant=None))]
    fn from_toml(text: &str, robot: Option<Robot>, plant: Option<Robot>) -> Result<Self> {
        let scn = parse_scenario(text, "<text>").map_err(Error::invalid)?;
        Self::checked(scn, robot.as_ref(), plant.as_ref())
    }

    /// A scenario from a dict of a scenario file's keys (`to_dict()`'s
    /// shape; missing keys take the defaults, unknown keys are refused).
    #[staticmethod]
    #[pyo3(signature = (d, *, robot=None, plant=None))]
    fn from_dict(
        d: &Bound<'_, PyDict>,
        robot: Option<Robot>,
        plant: Option<Robot>,
    ) -> Result<Self> {
        let t = dict_to_table(d, "")?;
        let text = toml::to_string(&t).map_err(|e| Error::invalid(format!("scenario: {e}")))?;
        let scn = parse_scenario(&text, "<dict>").map_err(Error::invalid)?;
        Self::checked(scn, robot.as_ref(), plant.as_ref())
    }

    /// `hil-sim sweep`'s base scenario for `robot`: the 2 m circle at
    /// 0.5 m/s, a disturbance in 10-35 s, motion capture through the
    /// firmware runtime (book/src/how-to/mismatch-sweeps.md).
    #[staticmethod]
    #[pyo3(signature = (robot, *, seed=1, duration_s=40.0))]
    fn sweep_base(robot: Robot, seed: u64, duration_s: f64) -> Result<Self> {
        let scn = hil_sim::sweep::base_scenario(&robot.inner, seed, duration_s);
        Self::checked(scn, None, None)
    }

    /// A copy with the keys of `changes` (a dict shaped as `to_dict()`,
    /// e.g. `{"duration_s": 5, "plant": {"mass_scale": 1.1}}`) set,
    /// validated; the robots are kept unless `robot`/`plant` are given.
    #[pyo3(signature = (changes=None, *, robot=None, plant=None))]
    fn replace(
        &self,
        changes: Option<&Bound<'_, PyDict>>,
        robot: Option<Robot>,
        plant: Option<Robot>,
    ) -> Result<Self> {
        let mut t = self.table();
        if let Some(c) = changes {
            merge_tables(&mut t, dict_to_table(c, "")?);
        }
        let s = Self::from_table(t, "<replace>", &self.inner)?;
        Self::checked(s.inner, robot.as_ref(), plant.as_ref())
    }

    /// Every key of the scenario as a dict (a version-2 scenario file's
    /// tables; the robots are not keys of the file).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        toml_to_py(py, &toml::Value::Table(self.table()))
    }

    /// The scenario as the text of a version-2 scenario file.
    fn to_toml(&self) -> String {
        to_toml(&self.inner)
    }

    /// The controller's robot.
    #[getter]
    fn robot(&self) -> Robot {
        Robot {
            inner: self.inner.robot.clone(),
        }
    }

    /// The plant's own robot file, when it differs from the controller's.
    #[getter]
    fn plant(&self) -> Option<Robot> {
        self.inner.plant.robot.clone().map(|inner| Robot { inner })
    }

    /// Name shown in tables.
    #[getter]
    fn name(&self) -> String {
        self.inner.name.clone()
    }

    /// Run length [s].
    #[getter]
    fn duration_s(&self) -> f64 {
        self.inner.duration_s
    }

    /// Seed of the measurement noise.
    #[getter]
    fn seed(&self) -> u64 {
        self.inner.seed
    }

    fn __repr__(&self) -> String {
        format!(
            "Scenario(name={:?}, duration_s={}, seed={}, sensing={:?}, robot={:?})",
            self.inner.name,
            self.inner.duration_s,
            self.inner.seed,
            self.inner.sensing.preset.name(),
            self.inner.robot.name
        )
    }

    fn __eq__(&self, other: &Self) -> bool {
        self.inner == other.inner
    }

    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let f = py.get_type::<Scenario>().getattr("_from_state")?;
        let state = (
            self.to_toml(),
            self.inner.robot.to_toml_string(),
            self.inner.plant.robot.as_ref().map(|r| r.to_toml_string()),
        );
        PyTuple::new(py, [f, state.into_pyobject(py)?.into_any()])
    }

    /// Rebuilds a pickled scenario (`__reduce__`).
    #[staticmethod]
    fn _from_state(scenario: &str, robot: &str, plant: Option<&str>) -> Result<Self> {
        let robot = Robot::from_toml(robot)?;
        let plant = plant.map(Robot::from_toml).transpose()?;
        Self::from_toml(scenario, Some(robot), plant)
    }
}
