//! A back end from Python: `factor=obj` (and an object in `compare`'s
//! `factor=` list) is a duck-typed SPD back end, wrapped here as an
//! [`SpdBackend`] that calls the object with the GIL held. No numerics:
//! the object solves, this module passes matrices and checks what comes
//! back.
//!
//! The protocol (docs/python.md §"Your own factorisation"):
//!
//! - `obj.name`: a non-empty `str`, not a word of the catalogue of any seam
//!   (SPD, `LDLᵀ` or QR) in any letter case, without surrounding white
//!   space and without control or invisible format characters (a zero-width
//!   space): a name that reads as a built-in's is refused
//!   ([`backend_name`]). Read once, when the object is given; an exception
//!   its getter raises is the error of that call. It is the back end's name in the report
//!   (`factor_backend`) and in `compare` rows.
//! - `obj.analyze(lower)`: `lower` is a `scipy.sparse.csc_matrix` (n × n,
//!   sorted row indices, diagonal included) holding the pattern of the
//!   lower triangle, every stored value 1.0. The return value is ignored.
//!   The pattern stays fixed until the next `analyze`.
//! - `obj.factorize(lower)`: the same pattern with the values to factor
//!   (a new matrix each call). Returns `None` — the object then holds
//!   this factorisation, and `obj.solve` solves with it — or a factor
//!   object with a method `solve(rhs)`, which then solves with this
//!   factorisation whatever the object factors later.
//! - `obj.solve(rhs)` (or the factor object's): `rhs` a C-ordered float64
//!   array of shape (n, k); returns `A⁻¹ rhs` as a float64 `numpy.ndarray`
//!   of shape (n, k) (it may overwrite and return `rhs`).
//!
//! The library keeps several factorisations of one analysis alive at once
//! (`SpdSymbolic::factorize`'s contract). With `factorize` returning
//! `None`, a factorisation whose matrix the object no longer holds (another
//! was factored since) is factored again before it solves — with its own
//! values, after `analyze` again when another pattern was analysed since —
//! and the report counts it (`SpdFactor::refactorizations`). Calls into
//! one object are serialised (a lock per object, taken without holding the
//! GIL while waiting) and do not nest: a call back into the object from
//! inside one of its own methods (on the thread that holds its lock, which
//! would wait for itself) is refused at once — an `InputError` at the
//! entry point when the object is given again, else the failure of the
//! inner call's back end, an `InputError` there too.
//!
//! Errors: an object missing a member is an `InputError` naming it when it
//! is given (`InputTypeError` when it has none: not a back end at all).
//! During the work, an exception raised by the object becomes a
//! [`NumericalError::Backend`] naming the object and the method; at the
//! entry point ([`Objects::explain`]) it is raised as `NumericalError`
//! with the object's exception as `__cause__`. A `MemoryError` becomes
//! [`NumericalError::OutOfMemory`] instead, raised as `TooLargeError`
//! (with the same `__cause__`), as a built-in back end's allocation
//! failure is. A `KeyboardInterrupt`,
//! `SystemExit` or another `BaseException` that is not an `Exception`
//! stops the call instead (in `compare` too: no row is made of it): it is
//! raised as it is, by the call of the thread that called the object, and
//! the object is not called again by that call. A return value of the wrong kind (not a float64 ndarray of shape
//! (n, k), a `factorize` result without `solve`) is an `InputError` (a
//! malformed object); a non-finite value in a solution a `NumericalError`.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, Weak};

use faer::MatMut;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use numpy::{PyArray2, PyArrayDescrMethods, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};

use pyo3::prelude::*;
use pyo3::sync::MutexExt;

use super::convert;
use super::errors::{input, is_stop, stop_with, stopping, type_error};
use crate::backend::BackendName;
use crate::backend::ldlt::LdltKind;
use crate::backend::qr::QrKind;
use crate::backend::spd::{SpdBackend, SpdFactor, SpdKind, SpdSymbolic};
use crate::error::NumericalError;

/// The members every back-end object has (`name` an attribute, the others
/// methods).
const MEMBERS: [&str; 4] = ["name", "analyze", "factorize", "solve"];

/// Why a call into the object failed, kept for the entry point.
enum Cause {
    /// The object raised this exception.
    Raised(PyErr),
    /// The object raised an exception that stops the call
    /// ([`stop_with`]), which the entry point raises.
    Stopped,
    /// The object returned something the protocol does not allow, or
    /// was misused (called back from inside its own method).
    Malformed,
}

/// A `MemoryError` the object raised, kept by [`Shared::fail`] as
/// `failure`, as [`NumericalError::OutOfMemory`]: like a built-in back
/// end's allocation failure, a refusal for size (`TooLargeError`, whose
/// `__cause__` is the object's `MemoryError`), not a numerical failure.
fn out_of_memory(failure: NumericalError) -> NumericalError {
    match failure {
        NumericalError::Backend { backend, message } => NumericalError::OutOfMemory {
            backend,
            what: format!("its memory ({message})"),
        },
        other => other,
    }
}

/// The last failure of a call into the object: the message the library's
/// error carries, and its cause.
struct Failure {
    message: String,
    cause: Cause,
}

/// Which analysis and factorisation the object holds now (ids from
/// [`Shared::next_id`]; 0: none).
#[derive(Default)]
struct Current {
    analysis: u64,
    factor: u64,
}

/// What a Python object holds, shared by every back end made of it (one
/// object given to two calls, or to two `Deformer`s, is one state).
#[derive(Default)]
struct Held {
    /// Locked for every call into the object.
    current: Mutex<Current>,
    /// The thread that holds `current` ([`this_thread`]; 0: none): a
    /// call back into the object from inside one of its methods comes
    /// from that thread, and waiting for the lock would wait for itself.
    owner: AtomicU64,
    /// The ids of its analyses and factorisations.
    ids: AtomicU64,
}

/// A token of the calling thread, unique in the process (from 1; a
/// thread's token is never reused).
pub(crate) fn this_thread() -> u64 {
    static NEXT: AtomicU64 = AtomicU64::new(1);
    thread_local! {
        static TOKEN: u64 = NEXT.fetch_add(1, Ordering::Relaxed);
    }
    TOKEN.with(|t| *t)
}

/// `held.current` locked by this thread, `owner` set while it is.
struct Entered<'a> {
    current: MutexGuard<'a, Current>,
    owner: &'a AtomicU64,
}

impl Drop for Entered<'_> {
    fn drop(&mut self) {
        self.owner.store(0, Ordering::Release);
    }
}

impl Held {
    /// Whether this thread is inside a call into the object.
    fn entered_here(&self) -> bool {
        self.owner.load(Ordering::Acquire) == this_thread()
    }
}

/// The state of every object that has a back end alive, by its address
/// (unique while the back end keeps the object alive).
static HELD: Mutex<Vec<(usize, Weak<Held>)>> = Mutex::new(Vec::new());

/// The state of `obj`: the one of its live back ends, or a new one.
fn held_by(obj: &Bound<'_, PyAny>) -> Arc<Held> {
    let mut held = lock(obj.py(), &HELD);
    held.retain(|(_, w)| w.strong_count() > 0);
    let address = obj.as_ptr() as usize;
    let live = held.iter().find(|(a, _)| *a == address);
    if let Some(h) = live.and_then(|(_, w)| w.upgrade()) {
        return h;
    }
    let h = Arc::new(Held::default());
    held.push((address, Arc::downgrade(&h)));
    h
}

/// What the back end, its analyses and factors share: the object and its
/// state.
struct Shared {
    object: Py<PyAny>,
    name: String,
    /// The object's class, for messages.
    class: String,
    held: Arc<Held>,
    /// The last failure, for [`Objects::explain`].
    failure: Mutex<Option<Failure>>,
}

/// A Python object as an [`SpdBackend`].
pub(crate) struct PyBackend {
    shared: Arc<Shared>,
}

/// The objects given to one call (or one `Deformer`), to explain its
/// errors ([`Objects::explain`]).
#[derive(Default, Clone)]
pub(crate) struct Objects(Vec<Arc<Shared>>);

impl Objects {
    /// `backend` too.
    pub(crate) fn add(&mut self, backend: &PyBackend) {
        self.0.push(Arc::clone(&backend.shared));
    }

    /// `result`, its error explained by the objects' last failures (which
    /// are cleared): the library's error for an exception the object
    /// raised gets that exception as `__cause__`; a `KeyboardInterrupt` or
    /// other non-`Exception` the object raised is raised itself; a
    /// malformed return becomes an `InputError`.
    pub(crate) fn explain<T>(&self, py: Python<'_>, result: PyResult<T>) -> PyResult<T> {
        let failures: Vec<Failure> = self
            .0
            .iter()
            .filter_map(|s| lock(py, &s.failure).take())
            .collect();
        let Err(err) = result else {
            return result;
        };
        let text = err
            .value(py)
            .str()
            .map(|s| s.to_string())
            .unwrap_or_default();
        let Some(failure) = failures
            .into_iter()
            .find(|f| !f.message.is_empty() && text.contains(&f.message))
        else {
            return Err(err);
        };
        Err(match failure.cause {
            // Raised by [`released`](super::errors::released) already;
            // this is the fallback.
            Cause::Stopped => err,
            Cause::Raised(e) if is_stop(py, &e) => e,
            Cause::Raised(e) => {
                err.set_cause(py, Some(e));
                err
            }
            Cause::Malformed => input(text),
        })
    }
}

/// `str(value)`, or a placeholder when that raises (an exception that
/// stops the call — a signal handler's — stops it: [`stop_with`]).
fn text_of(value: &Bound<'_, PyAny>) -> String {
    match value.str() {
        Ok(s) => s.to_string_lossy().into_owned(),
        Err(e) => {
            if is_stop(value.py(), &e) {
                stop_with(e);
            }
            "(its message could not be read)".into()
        }
    }
}

/// `mutex` locked without holding the GIL while waiting (a poisoned lock
/// is used as it is: nothing here leaves it inconsistent).
fn lock<'a, T>(py: Python<'_>, mutex: &'a Mutex<T>) -> MutexGuard<'a, T> {
    mutex
        .lock_py_attached(py)
        .unwrap_or_else(|p| p.into_inner())
}

impl PyBackend {
    /// The back end of `obj`, given as keyword `keyword`, its protocol
    /// checked.
    ///
    /// Errors: `InputTypeError` when `obj` has none of the members (not a
    /// back end); `InputError` naming the first missing member, a `name`
    /// that is not a non-empty `str`, or a name of the catalogue.
    pub(crate) fn from_object(obj: &Bound<'_, PyAny>, keyword: &str) -> PyResult<PyBackend> {
        let class = obj.get_type().name()?.to_string();
        let mut missing = Vec::new();
        for m in MEMBERS {
            if !has_member(obj, m)? {
                missing.push(m);
            }
        }
        let expected = "a word of the catalogue or an object with an attribute name and methods analyze(lower), factorize(lower) and solve(rhs) (docs/python.md)";
        if missing.len() == MEMBERS.len() {
            return Err(type_error(format!(
                "{keyword}=: expected {expected}, got a {class}"
            )));
        }
        if let Some(m) = missing.first() {
            let what = if *m == "name" { "attribute" } else { "method" };
            return Err(input(format!(
                "{keyword}=: the {class} object has no {what} '{m}' (a back-end object needs name, analyze, factorize and solve; docs/python.md)"
            )));
        }
        let name = backend_name(obj, keyword, &class)?;
        let held = held_by(obj);
        if held.entered_here() {
            return Err(input(format!(
                "{keyword}=: {}",
                reentry_message(&name, &class)
            )));
        }
        Ok(PyBackend {
            shared: Arc::new(Shared {
                object: obj.clone().unbind(),
                name,
                class,
                held,
                failure: Mutex::default(),
            }),
        })
    }
}

/// Why a call back into the object `name` (of class `class`) from inside
/// one of its own methods is refused.
fn reentry_message(name: &str, class: &str) -> String {
    format!(
        "the back-end object '{name}' (a {class}) was called back from inside one of its own methods: it is busy with the call that called it (calls into one object are serialised and do not nest); give the inner call another object"
    )
}

/// Whether `obj` has `member`: the attribute `name`, or a callable. Only
/// an `AttributeError` means it has not; any other exception (a property
/// that raises, `KeyboardInterrupt`) is the caller's error.
fn has_member(obj: &Bound<'_, PyAny>, member: &str) -> PyResult<bool> {
    match obj.getattr(member) {
        Ok(m) => Ok(member == "name" || m.is_callable()),
        Err(e) if e.is_instance_of::<pyo3::exceptions::PyAttributeError>(obj.py()) => Ok(false),
        Err(e) => Err(e),
    }
}

/// `obj.name`, checked: a non-empty `str` that is no word of the catalogue
/// (a name is the back end's identity in every table).
fn backend_name(obj: &Bound<'_, PyAny>, keyword: &str, class: &str) -> PyResult<String> {
    let value = obj.getattr("name")?;
    let name: String = value.extract().map_err(|_| {
        input(format!(
            "{keyword}=: the {class} object's name must be a str, got a {}",
            value
                .get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ))
    })?;
    if name.trim().is_empty() {
        return Err(input(format!(
            "{keyword}=: the {class} object's name is empty: give it a name for reports and compare rows"
        )));
    }
    if name.trim() != name || name.chars().any(is_invisible) {
        return Err(input(format!(
            "{keyword}=: the {class} object's name {name:?} has surrounding white space or an invisible character: give it a name that reads as what it is"
        )));
    }
    let word = name.to_lowercase();
    if word.parse::<SpdKind>().is_ok()
        || word.parse::<LdltKind>().is_ok()
        || word.parse::<QrKind>().is_ok()
    {
        return Err(input(format!(
            "{keyword}=: the {class} object's name '{name}' is a back end of the catalogue (in any letter case): give it a name of its own"
        )));
    }
    Ok(name)
}

/// A control character, or an invisible format character a name could
/// hide behind: soft hyphen, Mongolian vowel separator, zero-width space,
/// joiners and direction marks (U+200B–U+200F), the bidirectional
/// embeddings (U+202A–U+202E), word joiner and invisible operators
/// (U+2060–U+2064), the byte-order mark (U+FEFF).
fn is_invisible(c: char) -> bool {
    c.is_control()
        || matches!(
            c,
            '\u{ad}' | '\u{180e}' | '\u{200b}'..='\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2060}'..='\u{2064}' | '\u{feff}'
        )
}

impl Shared {
    /// The object's state locked for a call into it (waiting, without
    /// the GIL, while another thread is in one).
    ///
    /// Errors: a call from inside one of the object's own methods on this
    /// thread (the lock is this thread's already: waiting would never
    /// end) — malformed use, an `InputError` at the entry point.
    fn enter<'a>(&'a self, py: Python<'_>) -> Result<Entered<'a>, NumericalError> {
        if self.held.entered_here() {
            let what = reentry_message(&self.name, &self.class);
            return Err(self.fail_as(py, what, Cause::Malformed));
        }
        let current = lock(py, &self.held.current);
        self.held.owner.store(this_thread(), Ordering::Release);
        Ok(Entered {
            current,
            owner: &self.held.owner,
        })
    }

    fn next_id(&self) -> u64 {
        // From 1: 0 is "none" in [`Current`].
        self.held.ids.fetch_add(1, Ordering::Relaxed) + 1
    }

    /// A failure of `method` (its call as `call`, e.g. `solve(rhs)`),
    /// kept for [`Objects::explain`], as the library's error.
    fn fail(&self, py: Python<'_>, call: &str, what: String, cause: Cause) -> NumericalError {
        self.fail_as(py, format!("{}.{call} {what}", self.class), cause)
    }

    /// A failure with the message `message`, kept as [`Shared::fail`]
    /// keeps it.
    fn fail_as(&self, py: Python<'_>, message: String, cause: Cause) -> NumericalError {
        *lock(py, &self.failure) = Some(Failure {
            message: message.clone(),
            cause,
        });
        NumericalError::Backend {
            backend: self.name.clone(),
            message,
        }
    }

    /// `target.method(arg)` (`call` names it for messages); an exception
    /// becomes [`Shared::fail`]'s error. A `KeyboardInterrupt`,
    /// `SystemExit` or other non-`Exception` raised in the object stops
    /// the library call under way on this thread ([`stop_with`]: its next
    /// interruption check fails and the call raises that exception, in
    /// this thread only); once a call is being stopped, the object is not
    /// called again.
    fn call<'py>(
        &self,
        py: Python<'py>,
        target: &Bound<'py, PyAny>,
        method: &str,
        call: &str,
        arg: Bound<'py, PyAny>,
    ) -> Result<Bound<'py, PyAny>, NumericalError> {
        if stopping() {
            let what = "was not called: the call is being interrupted".to_string();
            return Err(self.fail(py, call, what, Cause::Stopped));
        }
        target.call_method1(method, (arg,)).map_err(|e| {
            let kind = e.get_type(py).name();
            let kind = kind.map(|n| n.to_string_lossy().into_owned());
            let kind = kind.unwrap_or_else(|_| "an exception".into());
            let what = format!("raised {kind}: {}", text_of(e.value(py)));
            if is_stop(py, &e) && stop_with(e.clone_ref(py)) {
                return self.fail(py, call, what, Cause::Stopped);
            }
            let memory = e.is_instance_of::<pyo3::exceptions::PyMemoryError>(py);
            let failure = self.fail(py, call, what, Cause::Raised(e));
            if memory {
                out_of_memory(failure)
            } else {
                failure
            }
        })
    }

    /// `obj.analyze(pattern)`; the object then holds analysis `id`.
    fn analyze(
        &self,
        py: Python<'_>,
        current: &mut Current,
        id: u64,
        pattern: &Pattern,
    ) -> Result<(), NumericalError> {
        let lower = pattern.to_scipy(py, vec![1.0; pattern.row_idx.len()]);
        let lower = lower.map_err(|e| self.conversion(py, e))?;
        self.call(py, self.object.bind(py), "analyze", "analyze(lower)", lower)?;
        *current = Current {
            analysis: id,
            factor: 0,
        };
        Ok(())
    }

    /// `obj.factorize(values)` of analysis `analysis` (analysed again
    /// first when the object holds another), as factorisation `id`: the
    /// factor object it returned, if any.
    fn factorize(
        &self,
        py: Python<'_>,
        current: &mut Current,
        (analysis, pattern): (u64, &Pattern),
        id: u64,
        values: &[f64],
    ) -> Result<Option<Py<PyAny>>, NumericalError> {
        if current.analysis != analysis {
            self.analyze(py, current, analysis, pattern)?;
        }
        let lower = pattern.to_scipy(py, values.to_vec());
        let lower = lower.map_err(|e| self.conversion(py, e))?;
        let object = self.object.bind(py);
        let r = self.call(py, object, "factorize", "factorize(lower)", lower)?;
        current.factor = id;
        if r.is_none() {
            return Ok(None);
        }
        let solves = has_member(&r, "solve").map_err(|e| {
            let what = format!("returned a factor object whose solve could not be read ({e})");
            self.fail(py, "factorize(lower)", what, Cause::Raised(e))
        })?;
        if solves {
            return Ok(Some(r.unbind()));
        }
        let kind = r.get_type().name().map(|n| n.to_string());
        let what = format!(
            "returned a {}: expected None or a factor object with a method solve(rhs)",
            kind.unwrap_or_default()
        );
        Err(self.fail(py, "factorize(lower)", what, Cause::Malformed))
    }

    /// A failure of this module to make an argument (numpy or scipy
    /// refused it).
    fn conversion(&self, py: Python<'_>, e: PyErr) -> NumericalError {
        let what = format!("could not be called: making its argument failed ({e})");
        self.fail(py, "(argument)", what, Cause::Raised(e))
    }

    /// `returned` (of `call`) as the solution of the n × k `rhs`, copied
    /// into it.
    ///
    /// Errors: malformed (not a float64 ndarray of shape (n, k)); a
    /// non-finite entry ([`NumericalError::Backend`], naming its place).
    fn read_solution(
        &self,
        py: Python<'_>,
        call: &str,
        returned: &Bound<'_, PyAny>,
        mut rhs: MatMut<'_, f64>,
    ) -> Result<(), NumericalError> {
        let (n, k) = (rhs.nrows(), rhs.ncols());
        let expected = format!("expected a float64 numpy.ndarray of shape ({n}, {k})");
        let malformed = |what: String| self.fail(py, call, what, Cause::Malformed);
        let Ok(array) = returned.cast::<PyUntypedArray>() else {
            let kind = returned.get_type().name().map(|n| n.to_string());
            let kind = kind.unwrap_or_default();
            return Err(malformed(format!("returned a {kind}: {expected}")));
        };
        if !array.dtype().is_equiv_to(&numpy::dtype::<f64>(py)) {
            let dtype = array
                .dtype()
                .str()
                .map(|s| s.to_string())
                .unwrap_or_default();
            return Err(malformed(format!("returned dtype {dtype}: {expected}")));
        }
        if array.shape() != [n, k] {
            let shape = array.shape().to_vec();
            return Err(malformed(format!("returned shape {shape:?}: {expected}")));
        }
        let Ok(typed) = array.cast::<PyArray2<f64>>() else {
            return Err(malformed(format!(
                "returned an unreadable array: {expected}"
            )));
        };
        let view = typed.readonly();
        let view = view.as_array();
        for j in 0..k {
            for i in 0..n {
                let v = view[[i, j]];
                if !v.is_finite() {
                    return Err(NumericalError::Backend {
                        backend: self.name.clone(),
                        message: format!(
                            "{}.{call} returned a non-finite value ({v}) in row {i}, column {j}",
                            self.class
                        ),
                    });
                }
                rhs[(i, j)] = v;
            }
        }
        Ok(())
    }
}

/// A lower-triangle pattern in compressed columns (sorted rows).
struct Pattern {
    n: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
}

impl Pattern {
    fn of(lower: SymbolicSparseColMatRef<'_, usize>) -> Pattern {
        let n = lower.ncols();
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for j in 0..n {
            row_idx.extend_from_slice(&lower.row_idx()[lower.col_range(j)]);
            col_ptr.push(row_idx.len());
        }
        Pattern {
            n,
            col_ptr,
            row_idx,
        }
    }

    /// The values of `lower` (this pattern) in the pattern's order.
    fn values(&self, lower: SparseColMatRef<'_, usize, f64>) -> Vec<f64> {
        let mut values = Vec::with_capacity(self.row_idx.len());
        for j in 0..self.n {
            values.extend_from_slice(&lower.val()[lower.symbolic().col_range(j)]);
        }
        values
    }

    /// The pattern with `values` as a `scipy.sparse.csc_matrix`.
    fn to_scipy<'py>(&self, py: Python<'py>, values: Vec<f64>) -> PyResult<Bound<'py, PyAny>> {
        convert::csc_parts_to_scipy(py, (self.n, self.n), &self.col_ptr, &self.row_idx, values)
    }
}

impl SpdBackend for PyBackend {
    fn name(&self) -> BackendName {
        self.shared.name.clone().into()
    }

    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        let pattern = Arc::new(Pattern::of(lower));
        let id = self.shared.next_id();
        Python::attach(|py| {
            let mut entered = self.shared.enter(py)?;
            self.shared.analyze(py, &mut entered.current, id, &pattern)
        })?;
        Ok(Box::new(PySymbolic {
            shared: Arc::clone(&self.shared),
            id,
            pattern,
        }))
    }
}

/// An analysis of the object.
struct PySymbolic {
    shared: Arc<Shared>,
    id: u64,
    pattern: Arc<Pattern>,
}

impl SpdSymbolic for PySymbolic {
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn SpdFactor>, NumericalError> {
        let values = self.pattern.values(lower);
        let id = self.shared.next_id();
        let own = Python::attach(|py| {
            let mut entered = self.shared.enter(py)?;
            let analysis = (self.id, self.pattern.as_ref());
            self.shared
                .factorize(py, &mut entered.current, analysis, id, &values)
        })?;
        Ok(Box::new(PyFactor {
            shared: Arc::clone(&self.shared),
            analysis: self.id,
            pattern: Arc::clone(&self.pattern),
            id,
            values,
            own,
            refactorizations: 0,
        }))
    }

    /// The entries of the lower triangle: what this side keeps of a
    /// factorisation (its values, to factor again); the object's own
    /// storage is not known.
    fn factor_nnz(&self) -> usize {
        self.pattern.row_idx.len()
    }
}

/// A factorisation by the object.
struct PyFactor {
    shared: Arc<Shared>,
    analysis: u64,
    pattern: Arc<Pattern>,
    id: u64,
    /// The factored values, to factor again when the object holds another
    /// factorisation.
    values: Vec<f64>,
    /// The factor object `factorize` returned, if any.
    own: Option<Py<PyAny>>,
    refactorizations: usize,
}

impl PyFactor {
    /// The object that solves with this factorisation: the factor object,
    /// or the back-end object once it holds this factorisation (factored
    /// again if it holds another: counted).
    fn solver<'py>(
        &mut self,
        py: Python<'py>,
        current: &mut Current,
    ) -> Result<Bound<'py, PyAny>, NumericalError> {
        if let Some(own) = &self.own {
            return Ok(own.bind(py).clone());
        }
        if current.factor != self.id {
            let analysis = (self.analysis, self.pattern.as_ref());
            self.own = self
                .shared
                .factorize(py, current, analysis, self.id, &self.values)?;
            self.refactorizations += 1;
        }
        Ok(match &self.own {
            Some(own) => own.bind(py).clone(),
            None => self.shared.object.bind(py).clone(),
        })
    }
}

impl SpdFactor for PyFactor {
    fn dim(&self) -> usize {
        self.pattern.n
    }

    fn solve_in_place(&mut self, mut rhs: MatMut<'_, f64>) -> Result<(), NumericalError> {
        let shared = Arc::clone(&self.shared);
        Python::attach(|py| {
            let mut entered = shared.enter(py)?;
            let solver = self.solver(py, &mut entered.current)?;
            let arg = convert::matrix_to_numpy(py, rhs.as_ref(), false);
            let x = shared.call(py, &solver, "solve", "solve(rhs)", arg)?;
            shared.read_solution(py, "solve(rhs)", &x, rhs.as_mut())
        })
    }

    fn nnz(&self) -> usize {
        self.values.len()
    }

    fn bytes(&self) -> usize {
        self.values.len() * 16 + self.pattern.col_ptr.len() * 8
    }

    fn refactorizations(&self) -> usize {
        self.refactorizations
    }
}
