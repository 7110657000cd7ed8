//! The module's exceptions and the one place where library calls run:
//! without the GIL, with a panic turned into a Python exception rather than
//! an abort of the interpreter.
//!
//! Every error the module raises is an [`InputError`], a [`NumericalError`]
//! or a `MemoryError`, and an `Exception` (never pyo3's `PanicException`,
//! a `BaseException` that `except Exception` does not catch):
//!
//! | class | bases | for |
//! |---|---|---|
//! | `InputError` | `ValueError` | bad input (the CLI's exit code 2) |
//! | `InputTypeError` | `InputError`, `TypeError` | an argument of a type or dtype that cannot be converted |
//! | `TooLargeError` | `InputError`, `MemoryError` | an input or system beyond the memory budget, or an allocation that failed |
//! | `NumericalError` | `ArithmeticError` | numerical failure (the CLI's exit code 3) |
//!
//! A residual panic (a bug) becomes a `RuntimeError` naming it, or a
//! `TooLargeError` when it reports a failed allocation.
//!
//! The one exception outside these classes is a signal handler's: Ctrl-C
//! during a call raises `KeyboardInterrupt` (a `BaseException`, as Python
//! raises it everywhere) at the library's next check ([`released`],
//! [`crate::interrupt`]: after the numeric factorisation under way, if
//! any); and so is a back-end object's own `KeyboardInterrupt` or
//! `SystemExit` ([`stop_with`]), raised as it is by the call that called
//! the object.

use std::any::Any;
use std::cell::RefCell;
use std::panic::{AssertUnwindSafe, catch_unwind};

use pyo3::exceptions::{
    PyArithmeticError, PyKeyboardInterrupt, PyMemoryError, PyRuntimeError, PyTypeError,
    PyValueError,
};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

use crate::error::{ConstraintError, Error, MeshError, ProblemError};

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

/// `InputTypeError(InputError, TypeError)`, made at first use.
static INPUT_TYPE_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
/// `TooLargeError(InputError, MemoryError)`, made at first use.
static TOO_LARGE_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();

/// A class of two bases (which `create_exception!` cannot make), made by
/// `type(name, bases, namespace)` once and kept in `cell`.
fn two_base_class<'py>(
    py: Python<'py>,
    cell: &'static PyOnceLock<Py<PyType>>,
    name: &str,
    bases: (Bound<'py, PyType>, Bound<'py, PyType>),
    doc: &str,
) -> PyResult<Bound<'py, PyType>> {
    let class = cell.get_or_try_init(py, || -> PyResult<Py<PyType>> {
        let namespace = PyDict::new(py);
        namespace.set_item("__doc__", doc)?;
        namespace.set_item("__module__", "lse_deform")?;
        let bases = PyTuple::new(py, [bases.0, bases.1])?;
        let class = py
            .get_type::<PyType>()
            .call1((name, bases, namespace))?
            .cast_into::<PyType>()?;
        Ok(class.unbind())
    })?;
    Ok(class.bind(py).clone())
}

/// The class `InputTypeError(InputError, TypeError)`.
pub(crate) fn input_type_error_class(py: Python<'_>) -> PyResult<Bound<'_, PyType>> {
    two_base_class(
        py,
        &INPUT_TYPE_ERROR,
        "InputTypeError",
        (py.get_type::<InputError>(), py.get_type::<PyTypeError>()),
        "An argument of a type or dtype that cannot be converted (a complex array, a string where an array belongs): an InputError and a TypeError.",
    )
}

/// The class `TooLargeError(InputError, MemoryError)`.
pub(crate) fn too_large_error_class(py: Python<'_>) -> PyResult<Bound<'_, PyType>> {
    two_base_class(
        py,
        &TOO_LARGE_ERROR,
        "TooLargeError",
        (py.get_type::<InputError>(), py.get_type::<PyMemoryError>()),
        "An input or a system too large for the memory budget (LSE_MEMORY_LIMIT, or the memory available when the module first needs it), or an allocation that failed: an InputError and a MemoryError. The message names the array and the bytes it would need.",
    )
}

/// An exception of a class made by [`two_base_class`] (its creation error
/// if that failed).
fn raise(class: fn(Python<'_>) -> PyResult<Bound<'_, PyType>>, message: String) -> PyErr {
    Python::attach(|py| match class(py) {
        Ok(ty) => PyErr::from_type(ty, message),
        Err(e) => e,
    })
}

/// Whether `e` is a refusal against the memory budget.
fn is_too_large(e: &Error) -> bool {
    matches!(
        e,
        Error::Problem(ProblemError::TooLarge { .. })
            | Error::Mesh(MeshError::TooLarge { .. })
            | Error::Constraint(ConstraintError::TooLarge { .. })
    )
}

/// The exception for a library error: `TooLargeError` for a refusal
/// against the memory budget, [`InputError`] for other bad input,
/// [`NumericalError`] for numerical failure, with the CLI's message.
pub(crate) fn to_py(e: Error) -> PyErr {
    if matches!(e, Error::Interrupted) {
        // Only [`released`]'s hook interrupts, and it raises the signal
        // handler's own exception; this is the fallback.
        PyKeyboardInterrupt::new_err("interrupted")
    } else if is_too_large(&e) {
        raise(too_large_error_class, e.to_string())
    } else if e.is_input_error() {
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

/// An `InputTypeError` (an [`InputError`] and a `TypeError`): an argument
/// of a type or dtype that cannot be converted.
pub(crate) fn type_error(message: impl Into<String>) -> PyErr {
    raise(input_type_error_class, message.into())
}

/// A `TooLargeError` for `what` (e.g. "the 2147483648 × 3 array C") whose
/// allocation of `bytes` failed although the budget allowed it.
pub(crate) fn allocation_failed(what: &str, bytes: u64, e: impl std::fmt::Display) -> PyErr {
    to_py(
        ProblemError::TooLarge {
            detail: format!(
                "{what} needs about {}, which could not be allocated ({e})",
                crate::limits::format_bytes(bytes)
            ),
        }
        .into(),
    )
}

/// The exception for a caught panic: a `TooLargeError` when it reports a
/// failed allocation (a container that panics on allocation failure), a
/// `RuntimeError` naming the bug otherwise.
fn panic_to_py(payload: Box<dyn Any + Send>) -> PyErr {
    let message = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".into());
    let allocation = [
        "AllocError",
        "CapacityOverflow",
        "capacity overflow",
        "memory allocation",
    ]
    .iter()
    .any(|w| message.contains(w));
    if allocation {
        raise(
            too_large_error_class,
            format!("out of memory: an allocation failed ({message})"),
        )
    } else {
        PyRuntimeError::new_err(format!(
            "lse_deform internal error (a bug, please report it with the input): {message}"
        ))
    }
}

/// Runs the body of an entry point (with the GIL): a residual panic — the
/// causes are fixed where they are known — becomes an exception derived
/// from `Exception` ([`panic_to_py`]) instead of pyo3's `PanicException`.
pub(crate) fn guarded<T>(f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|payload| Err(panic_to_py(payload)))
}

/// Runs `f` with the GIL released. A library error becomes [`to_py`]'s
/// exception; a panic (a bug: the library does not panic on input)
/// becomes [`panic_to_py`]'s instead of unwinding into Python.
///
/// Signals: while `f` runs, the library's interruption checks
/// ([`crate::interrupt`]) re-attach to the interpreter and run Python's
/// signal handlers (`PyErr_CheckSignals`, at most every
/// [`crate::interrupt::CONSULT_INTERVAL`]); the first exception a handler
/// raises (`KeyboardInterrupt` for Ctrl-C) stops `f` at its next check and
/// is raised here, whatever `f` returned. Python runs handlers on the main
/// thread only: a call made from another thread is not interrupted by
/// Ctrl-C. A back-end object's `KeyboardInterrupt` or `SystemExit`
/// (own_backend.rs) stops the call the same way through [`stop_with`]: on
/// the thread whose call it is, whichever thread that is.
pub(crate) fn released<T, F>(py: Python<'_>, f: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> Result<T, Error> + Send,
{
    // rayon's pool, started fallibly before any work: a limit too tight
    // for its threads is a TooLargeError, not the panic of a parallel
    // loop (`resources::start_thread_pool`).
    crate::resources::start_thread_pool().map_err(|e| to_py(e.into()))?;
    let (outcome, signalled) = py.detach(|| {
        let _slot = StopSlot::push();
        let stop = || {
            if stopping() {
                return true;
            }
            match Python::attach(|py| py.check_signals()) {
                Ok(()) => false,
                Err(e) => {
                    stop_with(e);
                    true
                }
            }
        };
        let outcome = crate::interrupt::with_hook(stop, || catch_unwind(AssertUnwindSafe(f)));
        (outcome, StopSlot::take())
    });
    if let Some(e) = signalled {
        return Err(e);
    }
    match outcome {
        Ok(result) => result.map_err(to_py),
        Err(payload) => Err(panic_to_py(payload)),
    }
}

thread_local! {
    /// One slot per [`released`] call under way on this thread, innermost
    /// last (an object's method may call the library again): the exception
    /// that stops that call, once there is one.
    static STOP: RefCell<Vec<Option<PyErr>>> = const { RefCell::new(Vec::new()) };
}

/// The slot of one [`released`] call, popped when the call ends (also by
/// a panic).
struct StopSlot;

impl StopSlot {
    fn push() -> StopSlot {
        STOP.with(|s| s.borrow_mut().push(None));
        StopSlot
    }

    /// The exception of the innermost call, taken.
    fn take() -> Option<PyErr> {
        STOP.with(|s| s.borrow_mut().last_mut().and_then(Option::take))
    }
}

impl Drop for StopSlot {
    fn drop(&mut self) {
        STOP.with(|s| s.borrow_mut().pop());
    }
}

/// Stops the innermost [`released`] call of this thread with `e` (its
/// first such exception is kept): the library's next interruption check
/// fails, and the call raises `e` whatever the library returned. `false`
/// when this thread runs no such call (the caller then reports `e`
/// itself).
pub(crate) fn stop_with(e: PyErr) -> bool {
    STOP.with(|s| match s.borrow_mut().last_mut() {
        Some(slot) => {
            if slot.is_none() {
                *slot = Some(e);
            }
            true
        }
        None => false,
    })
}

/// Whether the innermost [`released`] call of this thread is being
/// stopped ([`stop_with`]).
pub(crate) fn stopping() -> bool {
    STOP.with(|s| s.borrow().last().is_some_and(Option::is_some))
}

/// Whether `e` stops a call rather than failing it: a `BaseException`
/// that is not an `Exception` (`KeyboardInterrupt`, `SystemExit`,
/// `GeneratorExit`), which Python code does not catch with
/// `except Exception` either.
pub(crate) fn is_stop(py: Python<'_>, e: &PyErr) -> bool {
    !e.is_instance_of::<pyo3::exceptions::PyException>(py)
}
