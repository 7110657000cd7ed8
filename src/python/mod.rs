//! The Python module `lse_deform` (feature `python`; `pip install .` builds
//! it with maturin from `pyproject.toml`, the Python side is
//! `src/python/lse_deform/`). A front door: it translates numpy and
//! scipy.sparse inputs and option strings into the library's types
//! ([`convert`]), calls the library with the GIL released, and translates
//! results, reports and errors back. No numerics here.
//!
//! Conventions are those of libigl's Python bindings: `V` float64 n × 3,
//! `F` int64 m × 3, sparse matrices from `scipy.sparse`; any memory order.
//! Errors (see [`errors`]): `InputError(ValueError)` for bad input,
//! with `InputTypeError(InputError, TypeError)` for an argument that is not
//! an array of a convertible dtype and `TooLargeError(InputError,
//! MemoryError)` for what exceeds the memory budget or fails to allocate,
//! and `NumericalError(ArithmeticError)` for numerical failure, with the
//! CLI's one-line messages; every one an `Exception` (each entry point runs
//! under [`errors::guarded`], so not even a bug raises pyo3's
//! `PanicException`); report warnings become `RuntimeWarning`s.

mod convert;
mod errors;

use std::ffi::CString;
use std::sync::Mutex;

use pyo3::exceptions::{PyRuntimeError, PyRuntimeWarning, PyUserWarning};
use pyo3::prelude::*;

use crate::constraints::ConstraintSet;
use crate::error::{ProblemError, SolveOption};
use crate::formulation::{Formulation, FormulationChoice, Refine};
use crate::laplacian::{self, LaplacianKind};
use crate::mesh::Mesh;
use crate::problem::LseProblem;
use crate::report::Report;
use crate::{Deformer, Error, LseSolver};

use errors::{
    InputError, NumericalError, guarded, input, input_type_error_class, released, to_py,
    too_large_error_class, type_error,
};

/// The formulation named by the keyword arguments, with the CLI's
/// defaults (`--qr sparse-givens --spd faer-auto`) where they are absent.
fn build_formulation(
    method: &str,
    qr: Option<&str>,
    spd: Option<&str>,
    weight: Option<f64>,
) -> Result<Box<dyn Formulation>, ProblemError> {
    let mut choice = FormulationChoice::new(method.parse()?);
    if let Some(qr) = qr {
        choice.qr = qr.parse()?;
    }
    if let Some(spd) = spd {
        choice.spd = spd.parse()?;
    }
    choice.weight = weight;
    choice.build().map_err(with_keyword)
}

/// A library error about an option, with the option's keyword argument
/// (`weight=`) in front.
fn with_keyword(e: ProblemError) -> ProblemError {
    match e {
        ProblemError::InvalidOption { option, message } => {
            let keyword = match option {
                SolveOption::Method => "method",
                SolveOption::Qr => "qr",
                SolveOption::Spd => "spd",
                SolveOption::Weight => "weight",
                SolveOption::Refine => "refine",
            };
            ProblemError::InvalidArgument {
                message: format!("{keyword}=: {message}"),
            }
        }
        other => other,
    }
}

/// The formulation and refinement chosen by the keyword arguments
/// `method`, `qr`, `spd`, `weight`, `refine` (the CLI's options).
struct Chosen {
    formulation: Box<dyn Formulation>,
    refine: Option<Refine>,
}

impl Chosen {
    fn parse(
        method: &str,
        qr: Option<&str>,
        spd: Option<&str>,
        weight: Option<f64>,
        refine: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Chosen> {
        let formulation =
            build_formulation(method, qr, spd, weight).map_err(|e| to_py(e.into()))?;
        let refine = match refine {
            None => None,
            Some(r) if r.is_none() => None,
            Some(r) if r.is_instance_of::<pyo3::types::PyBool>() => {
                return Err(type_error(
                    "refine must be 'auto', 'off', a number of steps or None",
                ));
            }
            Some(r) => Some(match r.extract::<usize>() {
                Ok(steps) => Refine::Steps(steps),
                Err(_) => {
                    let word: String = r.extract().map_err(|_| {
                        type_error("refine must be 'auto', 'off', a number of steps or None")
                    })?;
                    word.parse::<Refine>().map_err(|e| to_py(e.into()))?
                }
            }),
        };
        Ok(Chosen {
            formulation,
            refine,
        })
    }
}

fn laplacian_kind(name: &str) -> PyResult<LaplacianKind> {
    name.parse()
        .map_err(|e: crate::error::ParseWordError| to_py(e.into()))
}

/// The mesh of `V`, `F` (validated by [`Mesh::new`], GIL released).
fn mesh(py: Python<'_>, v: &Bound<'_, PyAny>, f: &Bound<'_, PyAny>) -> PyResult<Mesh> {
    let positions = convert::rows3(v, "V")?;
    let faces = convert::faces(f, positions.len())?;
    released(py, move || Ok(Mesh::new(positions, faces)?))
}

/// The constraints argument for `mesh`; a file made for another mesh is a
/// `UserWarning`, as the CLI warns.
fn constraints_for(obj: &Bound<'_, PyAny>, mesh: &Mesh) -> PyResult<ConstraintSet> {
    let set = convert::constraints(obj)?;
    if let Some(detail) = set.mesh_mismatch(mesh) {
        warn::<PyUserWarning>(obj.py(), &format!("the constraints file was {detail}"))?;
    }
    set.check_vertices(mesh.n_vertices())
        .map_err(|e| to_py(e.into()))?;
    Ok(set)
}

fn warn<W: pyo3::PyTypeInfo>(py: Python<'_>, message: &str) -> PyResult<()> {
    let text = CString::new(message.replace('\0', " ")).unwrap_or_default();
    PyErr::warn(py, &py.get_type::<W>(), &text, 1)
}

/// The report as a dict, its warnings raised as `RuntimeWarning`s.
fn report_with_warnings<'py>(py: Python<'py>, report: &Report) -> PyResult<Bound<'py, PyAny>> {
    for w in &report.warnings {
        warn::<PyRuntimeWarning>(py, w)?;
    }
    convert::report_dict(py, report)
}

/// Deforms the mesh `(V, F)` under `constraints`: set-up, precompute and
/// solve in one call. Returns `(U, report)`.
#[pyfunction]
#[pyo3(signature = (V, F, constraints, laplacian="cotan", method="nullspace-qr", qr=None, spd=None, weight=None, refine=None))]
#[allow(non_snake_case, clippy::too_many_arguments)]
fn deform<'py>(
    py: Python<'py>,
    V: &Bound<'py, PyAny>,
    F: &Bound<'py, PyAny>,
    constraints: &Bound<'py, PyAny>,
    laplacian: &str,
    method: &str,
    qr: Option<&str>,
    spd: Option<&str>,
    weight: Option<f64>,
    refine: Option<&Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    guarded(|| {
        let kind = laplacian_kind(laplacian)?;
        let m = Chosen::parse(method, qr, spd, weight, refine)?;
        let mesh = mesh(py, V, F)?;
        let set = constraints_for(constraints, &mesh)?;
        let solution = released(py, move || {
            let mut deformer = Deformer::new(mesh, kind, set)?;
            deformer.set_refine(m.refine);
            deformer.precompute(m.formulation.as_ref())?;
            deformer.solve()
        })?;
        Ok((
            convert::positions_to_numpy(py, &solution.positions).into_any(),
            report_with_warnings(py, &solution.report)?,
        ))
    })
}

/// The Laplacian of `(V, F)` as a `scipy.sparse.csc_matrix` (n × n; the
/// crate's sign convention: `L_ii = Σ_j w_ij`, `L_ij = −w_ij`, `δ = L V`).
#[pyfunction]
#[pyo3(name = "laplacian", signature = (V, F, kind="cotan"))]
#[allow(non_snake_case)]
fn laplacian_matrix<'py>(
    py: Python<'py>,
    V: &Bound<'py, PyAny>,
    F: &Bound<'py, PyAny>,
    kind: &str,
) -> PyResult<Bound<'py, PyAny>> {
    guarded(|| {
        let kind = laplacian_kind(kind)?;
        let mesh = mesh(py, V, F)?;
        let l = released(py, move || Ok(laplacian::laplacian(&mesh, kind)?))?;
        convert::csc_to_scipy(py, &l)
    })
}

/// Solves `min ‖A X − C‖ subject to B X = D` for sparse `A` (l × n) and
/// `B` (m × n) and dense `C` (l × k) and `D` (m × k); returns `(X, report)`.
#[pyfunction]
#[pyo3(signature = (A, C, B, D, method="nullspace-qr", qr=None, spd=None, weight=None, refine=None))]
#[allow(non_snake_case, clippy::too_many_arguments)]
fn solve_lse<'py>(
    py: Python<'py>,
    A: &Bound<'py, PyAny>,
    C: &Bound<'py, PyAny>,
    B: &Bound<'py, PyAny>,
    D: &Bound<'py, PyAny>,
    method: &str,
    qr: Option<&str>,
    spd: Option<&str>,
    weight: Option<f64>,
    refine: Option<&Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    guarded(|| {
        let m = Chosen::parse(method, qr, spd, weight, refine)?;
        let a = convert::sparse(A, "A")?;
        let b = convert::sparse(B, "B")?;
        let (c, one_d) = convert::dense(C, "C", None, true)?;
        let (d, _) = convert::dense(D, "D", None, true)?;
        let (x, report) = released(py, move || {
            let problem = LseProblem::from_parts(a.as_ref(), c.as_ref(), b.as_ref(), d.as_ref())?;
            let mut solver = LseSolver::new(problem);
            solver.set_refine(m.refine);
            solver.precompute(m.formulation.as_ref())?;
            let x = solver.solve()?;
            Ok((x, solver.report().clone()))
        })?;
        Ok((
            convert::matrix_to_numpy(py, x.as_ref(), one_d),
            report_with_warnings(py, &report)?,
        ))
    })
}

/// What a `Deformer` holds behind its lock.
struct DeformerState {
    deformer: Deformer,
    formulation: Box<dyn Formulation>,
}

/// A mesh with constraints, deformed again and again: `precompute()` once,
/// then `set_targets` / `transform_group` and `solve()` per frame, reusing
/// the factorisation.
#[pyclass(name = "Deformer", module = "lse_deform")]
struct PyDeformer {
    state: Mutex<DeformerState>,
}

impl PyDeformer {
    /// Runs `f` on the state with the GIL released.
    fn with_state<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut DeformerState) -> Result<T, Error> + Send,
    ) -> PyResult<T> {
        let state = &self.state;
        let result = released(py, move || match state.lock() {
            Ok(mut guard) => f(&mut guard).map(Ok),
            Err(_) => Ok(Err(())),
        })?;
        result.map_err(|()| {
            PyRuntimeError::new_err(
                "this Deformer is unusable after an internal error in an earlier call",
            )
        })
    }
}

#[pymethods]
impl PyDeformer {
    /// Set-up: validates the mesh and constraints, builds the Laplacian and
    /// the system. Options as for `deform`.
    #[new]
    #[pyo3(signature = (V, F, constraints, laplacian="cotan", method="nullspace-qr", qr=None, spd=None, weight=None, refine=None))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        V: &Bound<'_, PyAny>,
        F: &Bound<'_, PyAny>,
        constraints: &Bound<'_, PyAny>,
        laplacian: &str,
        method: &str,
        qr: Option<&str>,
        spd: Option<&str>,
        weight: Option<f64>,
        refine: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyDeformer> {
        guarded(|| {
            let kind = laplacian_kind(laplacian)?;
            let m = Chosen::parse(method, qr, spd, weight, refine)?;
            let mesh = mesh(py, V, F)?;
            let set = constraints_for(constraints, &mesh)?;
            let deformer = released(py, move || {
                let mut deformer = Deformer::new(mesh, kind, set)?;
                deformer.set_refine(m.refine);
                Ok(deformer)
            })?;
            Ok(PyDeformer {
                state: Mutex::new(DeformerState {
                    deformer,
                    formulation: m.formulation,
                }),
            })
        })
    }

    /// Precompute: factors the system (GIL released).
    fn precompute(&self, py: Python<'_>) -> PyResult<()> {
        self.with_state(py, |s| s.deformer.precompute(s.formulation.as_ref()))
    }

    /// New targets for the constraints `indices` (positions in the
    /// constraint list; for `(b, bc)`, positions in `b`): a k × 3 array of
    /// targets, or of vectors for relative constraints. They become the
    /// rest targets of `transform_group`. On error nothing changes.
    fn set_targets(
        &self,
        py: Python<'_>,
        indices: &Bound<'_, PyAny>,
        targets: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        guarded(|| {
            let indices = convert::indices(indices, "indices")?;
            let targets = convert::rows3(targets, "targets")?;
            if indices.len() != targets.len() {
                return Err(input(format!(
                    "{} indices but {} targets (one row of targets per index)",
                    indices.len(),
                    targets.len()
                )));
            }
            let updates: Vec<(usize, [f64; 3])> = indices.into_iter().zip(targets).collect();
            self.with_state(py, move |s| s.deformer.set_targets(&updates))
        })
    }

    /// Applies the affine map `M` (3 × 4 `[R | t]`, or 4 × 4 with last row
    /// `[0, 0, 0, 1]`) to the rest targets of group `name`: positions, edge
    /// and face targets become `R u + t`, relative vectors `R v`. Calls do
    /// not accumulate; the identity puts the group back.
    #[pyo3(signature = (name, M))]
    #[allow(non_snake_case)]
    fn transform_group(&self, py: Python<'_>, name: &str, M: &Bound<'_, PyAny>) -> PyResult<()> {
        guarded(|| self.transform_group_unguarded(py, name, M))
    }

    /// The constraint indices of group `name`, increasing.
    fn group(&self, py: Python<'_>, name: &str) -> PyResult<Vec<usize>> {
        let name = name.to_string();
        self.with_state(py, move |s| s.deformer.group_members(&name))
    }

    /// Solve: the deformed positions (n × 3) for the current targets,
    /// reusing the factorisation (GIL released). Call `precompute()` first.
    fn solve<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        guarded(|| {
            let (positions, report) = self.with_state(py, |s| {
                let solution = s.deformer.solve()?;
                Ok((solution.positions, solution.report))
            })?;
            for w in &report.warnings {
                warn::<PyRuntimeWarning>(py, w)?;
            }
            Ok(convert::positions_to_numpy(py, &positions).into_any())
        })
    }

    /// The report of the last precompute and solve, a dict with the keys
    /// of the CLI's JSON report.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        guarded(|| {
            let report = self.with_state(py, |s| Ok(s.deformer.report().clone()))?;
            convert::report_dict(py, &report)
        })
    }
}

impl PyDeformer {
    #[allow(non_snake_case)]
    fn transform_group_unguarded(
        &self,
        py: Python<'_>,
        name: &str,
        M: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let (m, _) = convert::dense(M, "M", Some(4), false)?;
        let homogeneous_ok = m.nrows() == 4 && (0..4).all(|j| m[(3, j)] == [0.0, 0.0, 0.0, 1.0][j]);
        if !(m.nrows() == 3 || homogeneous_ok) {
            return Err(input(format!(
                "M must be 3 × 4 [R | t] or 4 × 4 with last row [0, 0, 0, 1], got {} × 4{}",
                m.nrows(),
                if m.nrows() == 4 {
                    " with another last row"
                } else {
                    ""
                }
            )));
        }
        let affine = [0, 1, 2].map(|r| [0, 1, 2, 3].map(|c| m[(r, c)]));
        let name = name.to_string();
        self.with_state(py, move |s| s.deformer.transform_group(&name, &affine))
    }
}

/// The native module `lse_deform._native`; the package `lse_deform`
/// re-exports it.
#[pymodule]
#[pyo3(name = "_native")]
pub fn native_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("NumericalError", py.get_type::<NumericalError>())?;
    m.add("InputTypeError", input_type_error_class(py)?)?;
    m.add("TooLargeError", too_large_error_class(py)?)?;
    m.add_class::<PyDeformer>()?;
    m.add_function(wrap_pyfunction!(deform, m)?)?;
    m.add_function(wrap_pyfunction!(laplacian_matrix, m)?)?;
    m.add_function(wrap_pyfunction!(solve_lse, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
