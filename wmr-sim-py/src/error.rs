//! The package's errors: [`Error`] (typed, what went wrong where) and the
//! Python exceptions it becomes ([`InvalidInputError`], a `ValueError`;
//! [`SimulationError`], a `RuntimeError`; `FileNotFoundError` for a
//! missing file). Every message is hil-sim's own (the CLI's text: the
//! field, the value, the limit and what to do).

use pyo3::exceptions::{PyFileNotFoundError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;

pyo3::create_exception!(
    wmrsim,
    InvalidInputError,
    PyValueError,
    "Bad input: a robot file, scenario, option or array hil-sim refuses. The message is the CLI's (field, value, limit, what to do); `field` names the field when known."
);
pyo3::create_exception!(
    wmrsim,
    SimulationError,
    PyRuntimeError,
    "A simulation that could not run to its end (the message says which and why)."
);

/// What went wrong.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Input hil-sim refuses; `field` when the robot file's error names it.
    #[error("{message}")]
    Invalid {
        /// The CLI's message.
        message: String,
        /// The field (robot-file errors), when known.
        field: Option<String>,
    },
    /// A file that does not exist.
    #[error("{0}")]
    NotFound(String),
    /// A run that failed.
    #[error("{0}")]
    Simulation(String),
}

impl Error {
    /// Bad input, the message only.
    pub fn invalid(message: impl Into<String>) -> Self {
        Self::Invalid {
            message: message.into(),
            field: None,
        }
    }
}

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        match e {
            Error::Invalid { message, field } => Python::attach(|py| {
                let err = InvalidInputError::new_err(message);
                let _ = err.value(py).setattr("field", field);
                err
            }),
            Error::NotFound(m) => PyFileNotFoundError::new_err(m),
            Error::Simulation(m) => SimulationError::new_err(m),
        }
    }
}

/// Result of this crate.
pub type Result<T> = std::result::Result<T, Error>;
