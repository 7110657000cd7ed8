//! The module's exceptions and the one place where library calls run:
//! without the GIL, with a panic turned into a Python exception rather than
//! an abort of the interpreter.

use std::panic::{AssertUnwindSafe, catch_unwind};

use pyo3::exceptions::{PyArithmeticError, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;

use crate::error::Error;

pyo3::create_exception!(
    lse_deform,
    InputError,
    PyValueError,
    "Bad input: a mesh, constraint, matrix or option that the library refuses (the CLI's exit code 2). The message is the CLI's one line: what is wrong and where."
);
pyo3::create_exception!(
    lse_deform,
    NumericalError,
    PyArithmeticError,
    "A numerical failure: a non-positive pivot, a singular system, a free unknown, a non-finite result (the CLI's exit code 3)."
);

/// The exception for a library error: [`InputError`] for bad input,
/// [`NumericalError`] for numerical failure, with the CLI's message.
pub(crate) fn to_py(e: Error) -> PyErr {
    if e.is_input_error() {
        InputError::new_err(e.to_string())
    } else {
        NumericalError::new_err(e.to_string())
    }
}

/// An [`InputError`] raised by the translation itself (a shape, an index
/// that is not one).
pub(crate) fn input(message: impl Into<String>) -> PyErr {
    InputError::new_err(message.into())
}

/// A `TypeError`: an argument of a type or dtype that cannot be converted.
pub(crate) fn type_error(message: impl Into<String>) -> PyErr {
    PyTypeError::new_err(message.into())
}

/// Runs `f` with the GIL released. A library error becomes [`to_py`]'s
/// exception; a panic (a bug: the library does not panic on input)
/// becomes a `RuntimeError` instead of unwinding into Python.
pub(crate) fn released<T, F>(py: Python<'_>, f: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> Result<T, Error> + Send,
{
    match py.detach(|| catch_unwind(AssertUnwindSafe(f))) {
        Ok(result) => result.map_err(to_py),
        Err(payload) => {
            let message = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic without a message".into());
            Err(PyRuntimeError::new_err(format!(
                "lse_deform internal error (a bug, please report it with the input): {message}"
            )))
        }
    }
}
