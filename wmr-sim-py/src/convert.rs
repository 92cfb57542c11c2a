//! Values between Python and hil-sim: Python dicts to TOML (scenario and
//! robot tables), TOML and JSON to Python objects, the names of
//! controllers and sensing presets.

use crate::error::{Error, Result};
use controller_core::ControllerKind;
use hil_sim::scenario::Sensing;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

/// A Python value (dict, list, tuple, str, bool, int, float, numpy scalar
/// or 1-D array) as TOML; `path` names it in errors.
pub fn py_to_toml(v: &Bound<'_, PyAny>, path: &str) -> Result<toml::Value> {
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract::<bool>().unwrap_or(false)));
    }
    if let Ok(s) = v.cast::<PyString>() {
        return Ok(toml::Value::String(s.to_string()));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        return Ok(toml::Value::Table(dict_to_table(d, path)?));
    }
    if v.is_instance_of::<PyInt>() {
        return v
            .extract::<i64>()
            .map(toml::Value::Integer)
            .map_err(|_| Error::invalid(format!("{path}: integer {v} out of range")));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract::<f64>().unwrap_or(f64::NAN)));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() || v.hasattr("tolist")? {
        // numpy arrays and scalars: through their Python values.
        let v = if v.hasattr("tolist")? {
            v.call_method0("tolist")?
        } else {
            v.clone()
        };
        if let Ok(items) = v.extract::<Vec<Bound<'_, PyAny>>>() {
            return items
                .iter()
                .enumerate()
                .map(|(i, x)| py_to_toml(x, &format!("{path}[{i}]")))
                .collect::<Result<Vec<_>>>()
                .map(toml::Value::Array);
        }
        return py_to_toml(&v, path);
    }
    Err(Error::invalid(format!(
        "{path}: a {} is not a value of the file (bool, int, float, str, list or dict)",
        v.get_type().name().map_or("?".into(), |n| n.to_string())
    )))
}

impl From<PyErr> for Error {
    fn from(e: PyErr) -> Self {
        Error::invalid(e.to_string())
    }
}

/// A Python dict (string keys) as a TOML table.
pub fn dict_to_table(d: &Bound<'_, PyDict>, path: &str) -> Result<toml::Table> {
    let mut t = toml::Table::new();
    for (k, v) in d.iter() {
        let key: String = k
            .extract()
            .map_err(|_| Error::invalid(format!("{path}: key {k} is not a string")))?;
        let sub = if path.is_empty() {
            key.clone()
        } else {
            format!("{path}.{key}")
        };
        t.insert(key, py_to_toml(&v, &sub)?);
    }
    Ok(t)
}

/// `over` merged into `base`: tables recursively, any other value replaced.
pub fn merge_tables(base: &mut toml::Table, over: toml::Table) {
    for (k, v) in over {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge_tables(b, o),
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

/// A TOML value as a Python object (tables as dicts, arrays as lists).
pub fn toml_to_py<'py>(py: Python<'py>, v: &toml::Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        toml::Value::String(s) => s.into_pyobject(py)?.into_any(),
        toml::Value::Integer(i) => i.into_pyobject(py)?.into_any(),
        toml::Value::Float(f) => f.into_pyobject(py)?.into_any(),
        toml::Value::Boolean(b) => PyBool::new(py, *b).to_owned().into_any(),
        toml::Value::Datetime(d) => d.to_string().into_pyobject(py)?.into_any(),
        toml::Value::Array(a) => {
            let l = PyList::empty(py);
            for x in a {
                l.append(toml_to_py(py, x)?)?;
            }
            l.into_any()
        }
        toml::Value::Table(t) => {
            let d = PyDict::new(py);
            for (k, x) in t {
                d.set_item(k, toml_to_py(py, x)?)?;
            }
            d.into_any()
        }
    })
}

/// A JSON value as a Python object (`null` as None).
pub fn json_to_py<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        serde_json::Value::Null => py.None().into_bound(py),
        serde_json::Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        serde_json::Value::Number(n) => match (n.as_i64(), n.as_u64()) {
            (Some(i), _) => i.into_pyobject(py)?.into_any(),
            (None, Some(u)) => u.into_pyobject(py)?.into_any(),
            _ => n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any(),
        },
        serde_json::Value::String(s) => s.into_pyobject(py)?.into_any(),
        serde_json::Value::Array(a) => {
            let l = PyList::empty(py);
            for x in a {
                l.append(json_to_py(py, x)?)?;
            }
            l.into_any()
        }
        serde_json::Value::Object(o) => {
            let d = PyDict::new(py);
            for (k, x) in o {
                d.set_item(k, json_to_py(py, x)?)?;
            }
            d.into_any()
        }
    })
}

/// Anything serde serialises, as the Python object of its JSON (the keys
/// and values the CLI's `--json` prints).
pub fn to_py<'py, T: serde::Serialize>(py: Python<'py>, x: &T) -> PyResult<Bound<'py, PyAny>> {
    let v = serde_json::to_value(x)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    json_to_py(py, &v)
}

/// The controller named `name` (`smc`, `asmc`, `proposed`).
pub fn controller(name: &str) -> Result<ControllerKind> {
    hil_sim::tune::kind_named(name).map_err(|e| Error::Invalid {
        message: format!("controller: {e}"),
        field: Some("controller".into()),
    })
}

/// The sensing preset named `name`.
pub fn sensing(name: &str) -> Result<Sensing> {
    Sensing::ALL
        .into_iter()
        .find(|s| s.name() == name)
        .ok_or_else(|| Error::Invalid {
            message: format!(
                "sensing: unknown preset '{name}' ({})",
                Sensing::ALL.map(|s| s.name()).join(", ")
            ),
            field: Some("sensing".into()),
        })
}

/// A thread pool of `threads` workers (None: rayon's default, one per
/// core); refuses 0.
pub fn pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    if threads == Some(0) {
        return Err(Error::Invalid {
            message: "threads must be at least 1 (None: one per core)".into(),
            field: Some("threads".into()),
        });
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads.unwrap_or(0))
        .build()
        .map_err(|e| Error::Simulation(format!("cannot start the thread pool: {e}")))
}
