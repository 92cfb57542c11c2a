//! # wmr-sim-py
//!
//! The Python package `wmrsim` over the host simulator (issue 36): robot
//! files and scenarios read and refused as the CLI does, one run or a
//! batch across threads (the GIL released), traces as numpy arrays, the
//! CLI's metrics keys, the paper comparison, Monte-Carlo statistics and
//! the tuner's cost. Nothing is simulated here: every call goes to
//! hil-sim's library functions, the ones its CLI calls (book/src/how-to/python.md).
//!
//! The native module is `wmrsim._native`; the Python side
//! (`python/wmrsim/`) adds the `Trace` wrapper, pandas, and the Ray
//! helpers.
#![deny(missing_docs)]

mod convert;
mod error;
mod mc;
mod model;
mod runs;
mod tune;

use pyo3::prelude::*;

/// The native part of `wmrsim` (import `wmrsim`, not this).
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add(
        "InvalidInputError",
        py.get_type::<error::InvalidInputError>(),
    )?;
    m.add("SimulationError", py.get_type::<error::SimulationError>())?;
    m.add_class::<model::Robot>()?;
    m.add_class::<model::Scenario>()?;
    m.add_class::<runs::RunResult>()?;
    m.add_class::<mc::MonteCarlo>()?;
    m.add_class::<tune::TuneSet>()?;
    m.add_function(wrap_pyfunction!(runs::run, m)?)?;
    m.add_function(wrap_pyfunction!(runs::run_batch, m)?)?;
    m.add_function(wrap_pyfunction!(runs::compare, m)?)?;
    m.add_function(wrap_pyfunction!(runs::native_seconds, m)?)?;
    m.add("HIL_SIM_VERSION", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
