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

mod basis;
mod convert;
mod errors;
mod own_backend;
mod state;

use std::ffi::CString;
use std::sync::{Arc, Mutex};

use pyo3::exceptions::{PyRuntimeWarning, PyUserWarning};
use pyo3::prelude::*;

use crate::LseSolver;
use crate::backend::FactorStorage;
use crate::backend::qr::QrKind;
use crate::backend::spd::SpdKind;
use crate::choice::{ArapEnergy, ArapInit, Energy, Method};
use crate::compare::{self, CompareOptions, Configuration};
use crate::constraints::ConstraintSet;
use crate::deform::UnitScaled;
use crate::error::{ProblemError, SolveOption};
use crate::formulation::{Chosen, Refine, SpdChoice};
use crate::laplacian::{self, LaplacianKind};
use crate::limits::{MemoryBudget, parse_bytes};
use crate::mesh::Mesh;
use crate::options::{ArapOptions, DeformOptions};
use crate::problem::LseProblem;
use crate::report::Report;
use crate::request::{self, Given, Request, RequestOption};
use crate::resources::{FillOrdering, OrderingWord, Resources, Threads};

use errors::{
    InputError, NumericalError, guarded, input, input_type_error_class, released, to_py,
    too_large_error_class, type_error,
};
use own_backend::{Objects, PyBackend};
use state::{Changes, DeformerState, PyDeformer, Stage};

/// A library error about an option, with the option's keyword argument
/// (`weight=`) in front.
fn with_keyword(e: ProblemError) -> ProblemError {
    match e {
        ProblemError::InvalidOption { option, message } => {
            let keyword = match option {
                SolveOption::Method => "method",
                SolveOption::Qr => "qr",
                SolveOption::Spd => "factor",
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

/// The keyword arguments `method`, `qr`, `factor` (or `spd`, its old
/// name), `weight`, `refine`, `memory_limit` and `out_of_core` (the CLI's
/// options); each
/// `None` keeps [`DeformOptions::default`]'s value.
struct Keywords<'a, 'py> {
    method: Option<&'a str>,
    qr: Option<&'a str>,
    /// `factor=`: a word, or a back-end object ([`own_backend`]); `spd=`:
    /// a word.
    factor: Factor<Option<&'a Bound<'py, PyAny>>, Option<&'a str>>,
    weight: Option<f64>,
    refine: Option<&'a Bound<'py, PyAny>>,
    memory_limit: Option<&'a Bound<'py, PyAny>>,
    /// `threads=` and `ordering=` ([`held`]).
    held: Held<'a, 'py>,
    /// `out_of_core=`: the directory of an out-of-core factor (`None`: in
    /// core), as [`out_of_core_dir`] reads it.
    out_of_core: Option<&'a Bound<'py, PyAny>>,
}

/// `out_of_core=`'s directory: a `str`, `bytes` or `os.PathLike` (what
/// `os.fspath` takes), or `None`; anything else is a `TypeError` saying
/// so.
fn out_of_core_dir(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Option<std::path::PathBuf>> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(None);
    };
    let expected = || {
        type_error(format!(
            "out_of_core must be a directory (str, bytes or os.PathLike) or None, got {}",
            basis::type_name(obj)
        ))
    };
    let path = obj
        .py()
        .import("os")?
        .call_method1("fspath", (obj,))
        .map_err(|_| expected())?;
    if let Ok(bytes) = path.cast::<pyo3::types::PyBytes>() {
        #[cfg(unix)]
        {
            use std::os::unix::ffi::OsStrExt;
            let os = std::ffi::OsStr::from_bytes(bytes.as_bytes());
            return Ok(Some(std::path::PathBuf::from(os)));
        }
        #[cfg(not(unix))]
        return String::from_utf8(bytes.as_bytes().to_vec())
            .map(|s| Some(s.into()))
            .map_err(|_| expected());
    }
    path.extract().map(Some).map_err(|_| expected())
}

/// The `factor=` keyword and `spd=`, its old name (kept for one release).
struct Factor<T, S = T> {
    factor: T,
    spd: S,
}

impl<T: PartialEq + std::fmt::Debug> Factor<Option<T>> {
    /// The one given (either name; both only when they agree).
    ///
    /// Errors: `InputError` when both are given with different values.
    fn given(self) -> PyResult<Option<T>> {
        match (self.factor, self.spd) {
            (Some(f), Some(s)) if f != s => Err(input(format!(
                "factor= and spd= (its old name) were both given, with different values ({f:?} and {s:?}): give one"
            ))),
            (f, s) => Ok(f.or(s)),
        }
    }
}

impl Factor<Option<&Bound<'_, PyAny>>, Option<&str>> {
    /// The SPD back end named (`None`: the default's), an object's
    /// back end added to `objects`.
    ///
    /// Errors: `InputError` for an unknown word, a malformed object
    /// ([`PyBackend::from_object`]), or both keywords given differently.
    fn choice(self, objects: &mut Objects) -> PyResult<Option<SpdChoice>> {
        let Some(factor) = self.factor.filter(|f| !f.is_none()) else {
            return self.spd.map(spd_word).transpose();
        };
        if let Ok(word) = factor.extract::<String>() {
            let words = Factor {
                factor: Some(word.as_str()),
                spd: self.spd,
            };
            return words.given()?.map(spd_word).transpose();
        }
        if self.spd.is_some() {
            return Err(input(
                "factor= (an object) and spd= (its old name) were both given: give one",
            ));
        }
        Ok(Some(own_choice(factor, "factor", objects)?))
    }
}

/// A word of the SPD catalogue.
fn spd_word(word: &str) -> PyResult<SpdChoice> {
    Ok(option_word::<SpdKind>(word)?.into())
}

/// The back end of a back-end object given as `keyword`, added to
/// `objects`.
fn own_choice(obj: &Bound<'_, PyAny>, keyword: &str, objects: &mut Objects) -> PyResult<SpdChoice> {
    let backend = PyBackend::from_object(obj, keyword)?;
    objects.add(&backend);
    Ok(Chosen::Own(Arc::new(backend)))
}

impl Keywords<'_, '_> {
    /// The options they name over [`DeformOptions::default`], the
    /// formulation checked ([`crate::formulation::FormulationChoice::build`]) before any
    /// work, with the back-end objects among them.
    fn options(self) -> PyResult<(DeformOptions, Objects)> {
        let mut options = DeformOptions::default();
        let mut objects = Objects::default();
        let f = &mut options.solve.formulation;
        if let Some(method) = self.method {
            f.method = option_word::<Method>(method)?;
        }
        if let Some(qr) = self.qr {
            f.qr = option_word::<QrKind>(qr)?.into();
        }
        if let Some(spd) = self.factor.choice(&mut objects)? {
            f.spd = spd;
        }
        f.weight = self.weight.or(f.weight);
        if let Some(dir) = out_of_core_dir(self.out_of_core)? {
            options.solve.factor_storage = FactorStorage::OutOfCore(dir);
        }
        let f = &options.solve.formulation;
        f.validate(&options.solve.factor_storage)
            .map_err(|e| to_py(with_keyword(e).into()))?;
        options.solve.refine = parse_refine(self.refine)?.or(options.solve.refine);
        options.solve.resources = self
            .held
            .resources(parse_memory_limit(self.memory_limit)?)?;
        Ok((options, objects))
    }
}

/// A word of a solve option (method, back end), as the library's
/// [`ProblemError`] (its message lists the accepted words).
fn option_word<T>(value: &str) -> PyResult<T>
where
    T: std::str::FromStr<Err = crate::error::ParseWordError>,
{
    value
        .parse()
        .map_err(|e: crate::error::ParseWordError| to_py(ProblemError::from(e).into()))
}

/// The `threads=` and `ordering=` keywords.
#[derive(Clone, Copy, Default)]
struct Held<'a, 'py> {
    threads: Option<&'a Bound<'py, PyAny>>,
    ordering: Option<&'a Bound<'py, PyAny>>,
}

impl Held<'_, '_> {
    /// `budget` with these threads and ordering: `threads=` `None`,
    /// `"own"` or a positive int; `ordering=` `None`, a word (`"own"`,
    /// `"amd"`, `"metis"`, `"natural"`) or a sequence of ints, the
    /// permutation of the unknowns to eliminate in (entry `i` eliminated
    /// `i`-th).
    fn resources(self, budget: MemoryBudget) -> PyResult<Resources> {
        Ok(Resources {
            budget,
            threads: parse_threads(self.threads)?,
            ordering: parse_ordering(self.ordering, budget)?,
        })
    }
}

fn parse_threads(threads: Option<&Bound<'_, PyAny>>) -> PyResult<Threads> {
    const EXPECTED: &str = "threads must be a positive int (at most 1024), 'own' or None";
    let Some(t) = threads.filter(|t| !t.is_none()) else {
        return Ok(Threads::Own);
    };
    if t.is_instance_of::<pyo3::types::PyBool>() {
        return Err(type_error(EXPECTED));
    }
    if let Ok(word) = t.extract::<String>() {
        return word
            .parse()
            .map_err(|e: String| input(format!("threads=: {e}")));
    }
    // An integer is anything with `__index__` (`operator.index`): Python's
    // int and numpy's integer scalars alike, not a float.
    let index = t
        .py()
        .import("operator")?
        .call_method1("index", (t,))
        .map_err(|_| type_error(EXPECTED))?;
    index
        .extract::<usize>()
        .ok()
        .and_then(Threads::count)
        .ok_or_else(|| input(format!("threads=: {EXPECTED}")))
}

fn parse_ordering(
    ordering: Option<&Bound<'_, PyAny>>,
    budget: MemoryBudget,
) -> PyResult<FillOrdering> {
    let Some(o) = ordering.filter(|o| !o.is_none()) else {
        return Ok(FillOrdering::Own);
    };
    if let Ok(word) = o.extract::<String>() {
        return Ok(option_word::<OrderingWord>(&word)?.into());
    }
    Ok(FillOrdering::Given(convert::ordering(o, budget)?))
}

/// The `memory_limit` keyword: `None` (the default budget:
/// `LSE_MEMORY_LIMIT`, else the available memory), a positive number of
/// bytes, or a size such as `"2G"` (powers of 1024).
fn parse_memory_limit(limit: Option<&Bound<'_, PyAny>>) -> PyResult<MemoryBudget> {
    const EXPECTED: &str =
        "memory_limit must be a positive number of bytes, a size such as '2G', or None";
    let l = match limit {
        None => return environment_budget(),
        Some(l) if l.is_none() => return environment_budget(),
        Some(l) if l.is_instance_of::<pyo3::types::PyBool>() => return Err(type_error(EXPECTED)),
        Some(l) => l,
    };
    let bytes = match l.extract::<u64>() {
        Ok(bytes) => Some(bytes).filter(|&b| b > 0),
        // An integer out of u64's range: a value error, not a type error.
        Err(_) if l.is_instance_of::<pyo3::types::PyInt>() => None,
        Err(_) => parse_bytes(&l.extract::<String>().map_err(|_| type_error(EXPECTED))?),
    };
    bytes
        .map(MemoryBudget::bytes)
        .ok_or_else(|| input(format!("memory_limit=: {EXPECTED}")))
}

/// The process's budget (`LSE_MEMORY_LIMIT`, else the system's), or an
/// `InputError` when the variable is malformed.
fn environment_budget() -> PyResult<MemoryBudget> {
    MemoryBudget::from_environment().map_err(|e| to_py(e.into()))
}

/// The `refine` keyword: `None`, a number of steps, or a word of
/// [`Refine`] (`auto`, `off`).
fn parse_refine(refine: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Refine>> {
    const EXPECTED: &str = "refine must be 'auto', 'off', a number of steps or None";
    let r = match refine {
        None => return Ok(None),
        Some(r) if r.is_none() => return Ok(None),
        Some(r) if r.is_instance_of::<pyo3::types::PyBool>() => return Err(type_error(EXPECTED)),
        Some(r) => r,
    };
    if let Ok(steps) = r.extract::<usize>() {
        return Ok(Some(Refine::Steps(steps)));
    }
    if r.is_instance_of::<pyo3::types::PyInt>() {
        return Err(input(format!("refine=: {EXPECTED}, got {r}")));
    }
    let word: String = r.extract().map_err(|_| type_error(EXPECTED))?;
    word.parse::<Refine>()
        .map(Some)
        .map_err(|e| to_py(e.into()))
}

/// A word of one of the library's word enums (`FromStr` with
/// [`ParseWordError`](crate::error::ParseWordError), which lists the
/// accepted words), as an `InputError` naming the keyword.
fn word<T>(keyword: &str, value: &str) -> PyResult<T>
where
    T: std::str::FromStr<Err = crate::error::ParseWordError>,
{
    value
        .parse()
        .map_err(|e: crate::error::ParseWordError| input(format!("{keyword}=: {e}")))
}

/// The `laplacian` (or `kind`) keyword; `None`: [`DeformOptions::default`]'s.
fn laplacian_kind(name: Option<&str>) -> PyResult<LaplacianKind> {
    match name {
        None => Ok(DeformOptions::default().laplacian),
        Some(name) => name
            .parse()
            .map_err(|e: crate::error::ParseWordError| to_py(e.into())),
    }
}

/// The mesh of `V`, `F` (validated by [`Mesh::new`], GIL released).
fn mesh(
    py: Python<'_>,
    v: &Bound<'_, PyAny>,
    f: &Bound<'_, PyAny>,
    budget: MemoryBudget,
) -> PyResult<Mesh> {
    let positions = convert::rows3(v, "V", budget)?;
    let faces = convert::faces(f, positions.len(), budget)?;
    released(py, move || Ok(Mesh::new(positions, faces)?))
}

/// The constraints argument for `mesh`; a file made for another mesh is a
/// `UserWarning`, as the CLI warns.
fn constraints_for(
    obj: &Bound<'_, PyAny>,
    mesh: &Mesh,
    budget: MemoryBudget,
) -> PyResult<ConstraintSet> {
    let set = convert::constraints(obj, budget)?;
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
        warn::<PyRuntimeWarning>(py, &w.message)?;
    }
    convert::report_dict(py, report)
}

/// The energy keywords of `deform` (the CLI's `--energy` options); each
/// `None` keeps the library's default ([`DeformOptions::default`],
/// [`ArapOptions::default`]).
struct EnergyKeywords<'a> {
    energy: Option<&'a str>,
    arap_energy: Option<&'a str>,
    iterations: Option<usize>,
    tolerance: Option<f64>,
    arap_init: Option<&'a str>,
}

impl EnergyKeywords<'_> {
    /// The request of `options` with these energy keywords (and
    /// `laplacian=`, `qr=` as given).
    fn request(&self, options: DeformOptions, given: Given) -> PyResult<Request> {
        let d = ArapOptions::default();
        let energy = match self.energy {
            Some(w) => word::<Energy>("energy", w)?,
            None => options.energy,
        };
        let arap_energy = self
            .arap_energy
            .map(|w| word::<ArapEnergy>("arap_energy", w))
            .transpose()?;
        let init = self
            .arap_init
            .map(|w| word::<ArapInit>("arap_init", w))
            .transpose()?;
        Ok(Request {
            options: DeformOptions { energy, ..options },
            arap: ArapOptions {
                energy: arap_energy.unwrap_or(d.energy),
                iterations: self.iterations.unwrap_or(d.iterations),
                tolerance: self.tolerance.unwrap_or(d.tolerance),
                init: init.unwrap_or(d.init),
            },
            given: Given {
                arap_energy: arap_energy.is_some(),
                iterations: self.iterations.is_some(),
                tolerance: self.tolerance.is_some(),
                arap_init: init.is_some(),
                ..given
            },
            condition: false,
        })
    }
}

/// The request's options that do not apply, as `RuntimeWarning`s in
/// Python's words (`weight= applies to method='penalty' only; ignored
/// with method='kkt'`), as the CLI warns about them.
fn warn_inapplicable(py: Python<'_>, request: &Request) -> PyResult<()> {
    for i in request.inapplicable() {
        let keyword = match i.option {
            RequestOption::Laplacian => "laplacian",
            RequestOption::ArapEnergy => "arap_energy",
            RequestOption::Iterations => "iterations",
            RequestOption::Tolerance => "tolerance",
            RequestOption::ArapInit => "arap_init",
            RequestOption::Weight => "weight",
            RequestOption::Qr => "qr",
            RequestOption::Condition => "condition",
        };
        let note = i.note.map(|n| format!(" ({n})")).unwrap_or_default();
        warn::<PyRuntimeWarning>(
            py,
            &format!(
                "{keyword}= applies to {}='{}' only; ignored with {}='{}'{note}",
                i.applies_to.0, i.applies_to.1, i.chosen.0, i.chosen.1
            ),
        )?;
    }
    Ok(())
}

/// [`warn_inapplicable`] of the solve options alone (`Deformer`,
/// `solve_lse`: the weight and the QR back end).
fn warn_solve_inapplicable(py: Python<'_>, options: &DeformOptions, qr: bool) -> PyResult<()> {
    let request = Request {
        options: options.clone(),
        given: Given {
            qr,
            ..Given::default()
        },
        ..Request::default()
    };
    warn_inapplicable(py, &request)
}

/// Deforms the mesh `(V, F)` under `constraints`: set-up, precompute and
/// solve in one call (with `energy="arap"`, the ARAP iterations). Returns
/// `(U, report)`.
#[pyfunction]
#[pyo3(signature = (V, F, constraints, laplacian=None, method=None, qr=None, factor=None, weight=None, refine=None, energy=None, arap_energy=None, iterations=None, tolerance=None, arap_init=None, memory_limit=None, out_of_core=None, spd=None, threads=None, ordering=None))]
#[allow(non_snake_case, clippy::too_many_arguments)]
fn deform<'py>(
    py: Python<'py>,
    V: &Bound<'py, PyAny>,
    F: &Bound<'py, PyAny>,
    constraints: &Bound<'py, PyAny>,
    laplacian: Option<&str>,
    method: Option<&str>,
    qr: Option<&str>,
    factor: Option<&Bound<'py, PyAny>>,
    weight: Option<f64>,
    refine: Option<&Bound<'py, PyAny>>,
    energy: Option<&str>,
    arap_energy: Option<&str>,
    iterations: Option<usize>,
    tolerance: Option<f64>,
    arap_init: Option<&str>,
    memory_limit: Option<&Bound<'py, PyAny>>,
    out_of_core: Option<&Bound<'py, PyAny>>,
    spd: Option<&str>,
    threads: Option<&Bound<'py, PyAny>>,
    ordering: Option<&Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    guarded(|| {
        let kind = laplacian_kind(laplacian)?;
        let (options, objects) = Keywords {
            method,
            qr,
            factor: Factor { factor, spd },
            weight,
            refine,
            memory_limit,
            held: Held { threads, ordering },
            out_of_core,
        }
        .options()?;
        let keywords = EnergyKeywords {
            energy,
            arap_energy,
            iterations,
            tolerance,
            arap_init,
        };
        let given = Given {
            laplacian: laplacian.is_some(),
            qr: qr.is_some(),
            ..Given::default()
        };
        let options = DeformOptions {
            laplacian: kind,
            ..options
        };
        let request = keywords.request(options, given)?;
        warn_inapplicable(py, &request)?;
        let budget = request.options.solve.resources.budget;
        let mesh = mesh(py, V, F, budget)?;
        let set = constraints_for(constraints, &mesh, budget)?;
        let outcome = released(py, move || {
            let outcome = request::deform(mesh, set, &request)?;
            Ok((outcome.positions, outcome.report))
        });
        let (positions, report) = objects.explain(py, outcome)?;
        Ok((
            convert::positions_to_numpy(py, &positions).into_any(),
            report_with_warnings(py, &report)?,
        ))
    })
}

/// A list keyword of words (`methods=["penalty", "kkt"]`), each parsed by
/// [`word`]; `None` when absent.
fn words<T>(keyword: &str, list: Option<Vec<String>>) -> PyResult<Option<Vec<T>>>
where
    T: std::str::FromStr<Err = crate::error::ParseWordError>,
{
    list.map(|l| l.iter().map(|w| word(keyword, w)).collect())
        .transpose()
}

/// Runs the library's comparison ([`crate::compare`]) of every
/// configuration on the mesh `(V, F)` under `constraints` against the
/// refined null-space reference: the rows of `lse-deform compare --json`,
/// as a list of dicts. A reference forward error above 1e-12 of the
/// diagonal is a `RuntimeWarning`, as the CLI warns.
#[pyfunction]
#[pyo3(name = "compare", signature = (V, F, constraints, laplacian=None, methods=None, qr=None, factor=None, weights=None, refine=None, repeat=None, condition=None, spd=None, memory_limit=None, threads=None, ordering=None))]
#[allow(non_snake_case, clippy::too_many_arguments)]
fn compare_rows<'py>(
    py: Python<'py>,
    V: &Bound<'py, PyAny>,
    F: &Bound<'py, PyAny>,
    constraints: &Bound<'py, PyAny>,
    laplacian: Option<&str>,
    methods: Option<Vec<String>>,
    qr: Option<Vec<String>>,
    factor: Option<Vec<Bound<'py, PyAny>>>,
    weights: Option<Vec<f64>>,
    refine: Option<&Bound<'py, PyAny>>,
    repeat: Option<usize>,
    condition: Option<bool>,
    spd: Option<Vec<String>>,
    memory_limit: Option<&Bound<'py, PyAny>>,
    threads: Option<&Bound<'py, PyAny>>,
    ordering: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    guarded(|| {
        let kind = laplacian_kind(laplacian)?;
        let defaults = CompareOptions::default();
        let mut objects = Objects::default();
        let factors = factor_list(factor, spd, &mut objects)?;
        let resources = Held { threads, ordering }.resources(parse_memory_limit(memory_limit)?)?;
        let options = CompareOptions {
            methods: words("methods", methods)?.unwrap_or(defaults.methods),
            qrs: words("qr", qr)?,
            spds: factors,
            weights: weights.unwrap_or(defaults.weights),
            refine: parse_refine(refine)?.or(defaults.refine),
            repeat: repeat.unwrap_or(defaults.repeat),
            condition: condition.unwrap_or(defaults.condition),
            resources,
        };
        // Fail before any work when the filters leave nothing to run.
        let configs = options
            .configurations()
            .map_err(|e| input(format!("methods=/qr=/factor=/weights=: {e}")))?;
        let configs: Vec<Configuration> = configs.into_iter().map(Configuration::new).collect();
        let budget = options.resources.budget;
        let mesh = mesh(py, V, F, budget)?;
        let set = constraints_for(constraints, &mesh, budget)?;
        let outcome = released(py, move || {
            let mut deformer =
                compare::reference_deformer(mesh, kind, set, options.resources.budget)?;
            compare::compare_configurations(&mut deformer, &configs, &options, &mut |_| {})
        });
        let (reference, rows) = objects.explain(py, outcome)?;
        if let Some(e) = reference.forward_error_estimate.filter(|&e| e > 1e-12) {
            warn::<PyRuntimeWarning>(
                py,
                &format!(
                    "the reference solution (nullspace-qr, refined) has an estimated forward error of {e:.1e}: differences below it are not resolved"
                ),
            )?;
        }
        convert::json_value(py, &rows)
    })
}

/// `compare`'s `factor=` list (or `spd=`, its old name, words only):
/// words of the catalogue and back-end objects ([`own_backend`]), the
/// objects added to `objects`; `None` when neither is given.
fn factor_list(
    factor: Option<Vec<Bound<'_, PyAny>>>,
    spd: Option<Vec<String>>,
    objects: &mut Objects,
) -> PyResult<Option<Vec<SpdChoice>>> {
    let Some(factor) = factor else {
        return Ok(
            words::<SpdKind>("factor", spd)?.map(|k| k.into_iter().map(Into::into).collect())
        );
    };
    let as_words: Option<Vec<String>> = factor.iter().map(|f| f.extract().ok()).collect();
    if let Some(w) = as_words {
        let given = Factor {
            factor: Some(w),
            spd,
        }
        .given()?;
        return Ok(
            words::<SpdKind>("factor", given)?.map(|k| k.into_iter().map(Into::into).collect())
        );
    }
    if spd.is_some() {
        return Err(input(
            "factor= (with objects) and spd= (its old name) were both given: give one",
        ));
    }
    // Each object once, and each object's name once: two rows under one
    // label could not be told apart (and one object's rows would share
    // its state).
    let mut seen: Vec<(usize, *mut pyo3::ffi::PyObject, String)> = Vec::new();
    let mut choices = Vec::with_capacity(factor.len());
    for (i, f) in factor.iter().enumerate() {
        if let Ok(w) = f.extract::<String>() {
            choices.push(word::<SpdKind>("factor", &w)?.into());
            continue;
        }
        if let Some((j, _, _)) = seen.iter().find(|(_, p, _)| *p == f.as_ptr()) {
            return Err(input(format!(
                "factor=[{i}] is the object of factor=[{j}] again: give each back-end object once (its rows would share one label)"
            )));
        }
        let choice = own_choice(f, "factor", objects)?;
        let name = choice.name().to_string();
        if let Some((j, _, _)) = seen.iter().find(|(_, _, n)| *n == name) {
            return Err(input(format!(
                "factor=[{i}]'s name '{name}' is the name of factor=[{j}]: give each back-end object a name of its own (the name labels its rows)"
            )));
        }
        seen.push((i, f.as_ptr(), name));
        choices.push(choice);
    }
    Ok(Some(choices))
}

/// The Laplacian of `(V, F)` as a `scipy.sparse.csc_matrix` (n × n; the
/// crate's sign convention: `L_ii = Σ_j w_ij`, `L_ij = −w_ij`, `δ = L V`).
#[pyfunction]
#[pyo3(name = "laplacian", signature = (V, F, kind=None))]
#[allow(non_snake_case)]
fn laplacian_matrix<'py>(
    py: Python<'py>,
    V: &Bound<'py, PyAny>,
    F: &Bound<'py, PyAny>,
    kind: Option<&str>,
) -> PyResult<Bound<'py, PyAny>> {
    guarded(|| {
        let kind = laplacian_kind(kind)?;
        let mesh = mesh(py, V, F, environment_budget()?)?;
        let l = released(py, move || Ok(laplacian::laplacian(&mesh, kind)?))?;
        convert::csc_to_scipy(py, &l)
    })
}

/// Solves `min ‖A X − C‖ subject to B X = D` for sparse `A` (l × n) and
/// `B` (m × n) and dense `C` (l × k) and `D` (m × k); returns `(X, report)`.
#[pyfunction]
#[pyo3(signature = (A, C, B, D, method=None, qr=None, factor=None, weight=None, refine=None, memory_limit=None, out_of_core=None, spd=None, threads=None, ordering=None))]
#[allow(non_snake_case, clippy::too_many_arguments)]
fn solve_lse<'py>(
    py: Python<'py>,
    A: &Bound<'py, PyAny>,
    C: &Bound<'py, PyAny>,
    B: &Bound<'py, PyAny>,
    D: &Bound<'py, PyAny>,
    method: Option<&str>,
    qr: Option<&str>,
    factor: Option<&Bound<'py, PyAny>>,
    weight: Option<f64>,
    refine: Option<&Bound<'py, PyAny>>,
    memory_limit: Option<&Bound<'py, PyAny>>,
    out_of_core: Option<&Bound<'py, PyAny>>,
    spd: Option<&str>,
    threads: Option<&Bound<'py, PyAny>>,
    ordering: Option<&Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    guarded(|| {
        let (options, objects) = Keywords {
            method,
            qr,
            factor: Factor { factor, spd },
            weight,
            refine,
            memory_limit,
            held: Held { threads, ordering },
            out_of_core,
        }
        .options()?;
        warn_solve_inapplicable(py, &options, qr.is_some())?;
        let m = options.solve;
        let budget = m.resources.budget;
        let a = convert::sparse(A, "A", budget)?;
        let b = convert::sparse(B, "B", budget)?;
        let (c, one_d) = convert::dense(C, "C", None, true, budget)?;
        let (d, _) = convert::dense(D, "D", None, true, budget)?;
        let outcome = released(py, move || {
            let problem = LseProblem::from_parts(a.as_ref(), c.as_ref(), b.as_ref(), d.as_ref())?;
            let mut solver = LseSolver::new(problem, &m)?;
            let x = solver.solve()?;
            Ok((x, solver.report().clone()))
        });
        let (x, report) = objects.explain(py, outcome)?;
        Ok((
            convert::matrix_to_numpy(py, x.as_ref(), one_d),
            report_with_warnings(py, &report)?,
        ))
    })
}

#[pymethods]
impl PyDeformer {
    /// Set-up: validates the mesh and constraints, builds the Laplacian and
    /// the system. Options as for `deform`.
    #[new]
    #[pyo3(signature = (V, F, constraints, laplacian=None, method=None, qr=None, factor=None, weight=None, refine=None, memory_limit=None, out_of_core=None, spd=None, threads=None, ordering=None))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        V: &Bound<'_, PyAny>,
        F: &Bound<'_, PyAny>,
        constraints: &Bound<'_, PyAny>,
        laplacian: Option<&str>,
        method: Option<&str>,
        qr: Option<&str>,
        factor: Option<&Bound<'_, PyAny>>,
        weight: Option<f64>,
        refine: Option<&Bound<'_, PyAny>>,
        memory_limit: Option<&Bound<'_, PyAny>>,
        out_of_core: Option<&Bound<'_, PyAny>>,
        spd: Option<&str>,
        threads: Option<&Bound<'_, PyAny>>,
        ordering: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyDeformer> {
        guarded(|| {
            let kind = laplacian_kind(laplacian)?;
            let (options, objects) = Keywords {
                method,
                qr,
                factor: Factor { factor, spd },
                weight,
                refine,
                memory_limit,
                held: Held { threads, ordering },
                out_of_core,
            }
            .options()?;
            warn_solve_inapplicable(py, &options, qr.is_some())?;
            let options = options.solve;
            let mesh = mesh(py, V, F, options.resources.budget)?;
            let set = constraints_for(constraints, &mesh, options.resources.budget)?;
            let stage = released(py, move || {
                UnitScaled::new(&mesh, &set)?;
                Ok(Stage::SetUp {
                    mesh,
                    kind,
                    constraints: set,
                })
            })?;
            Ok(PyDeformer {
                budget: options.resources.budget,
                state: Mutex::new(DeformerState {
                    stage,
                    options,
                    changes: Changes::default(),
                }),
                objects,
                owner: Default::default(),
            })
        })
    }

    /// Precompute: factors the system (GIL released).
    fn precompute(&self, py: Python<'_>) -> PyResult<()> {
        self.with_state(py, |s| {
            s.changes.reconfigured("precompute()");
            s.precompute()
        })
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
            let indices = convert::indices(indices, "indices", self.budget)?;
            let targets = convert::rows3(targets, "targets", self.budget)?;
            if indices.len() != targets.len() {
                return Err(input(format!(
                    "{} indices but {} targets (one row of targets per index)",
                    indices.len(),
                    targets.len()
                )));
            }
            let updates: Vec<(usize, [f64; 3])> = indices.into_iter().zip(targets).collect();
            self.with_state(py, move |s| {
                s.changes.reconfigured("set_targets()");
                s.deformer("set_targets()")?.set_targets(&updates)
            })
        })
    }

    /// Applies the affine map `M` (3 × 4 `[R | t]`, or 4 × 4 with last row
    /// `[0, 0, 0, 1]` within 1e-12) to the rest targets of group `name`: positions, edge
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
        self.with_state(py, move |s| s.group(&name))
    }

    /// Solve: the deformed positions (n × 3) for the current targets,
    /// reusing the factorisation (GIL released). Call `precompute()` first.
    /// `refine` (as for the constructor; None: the Deformer's own) applies
    /// to this call only; `refine="off"` still computes one correction for
    /// the forward-error estimate. `estimate=False` (with refinement off
    /// only) skips it and the diagnostics: the cheap frame (basis.rs).
    #[pyo3(signature = (refine=None, estimate=true))]
    fn solve<'py>(
        &self,
        py: Python<'py>,
        refine: Option<&Bound<'py, PyAny>>,
        estimate: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        guarded(|| {
            let refine = parse_refine(refine)?;
            let (positions, warnings) =
                self.with_state(py, move |s| basis::solve_frame(s, refine, estimate))?;
            for w in &warnings {
                warn::<PyRuntimeWarning>(py, &w.message)?;
            }
            Ok(convert::positions_to_numpy(py, &positions).into_any())
        })
    }

    /// The affine response basis of the constraint groups `groups` (a
    /// list of names) on this deformer's factor: a `HandleBasis` (basis.rs).
    fn basis(slf: &Bound<'_, Self>, groups: &Bound<'_, PyAny>) -> PyResult<basis::PyHandleBasis> {
        guarded(|| basis::build(slf, groups))
    }

    /// The report of the last precompute and solve, a dict with the keys
    /// of the CLI's JSON report.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        guarded(|| {
            let report = self.with_state(py, |s| Ok(s.deformer("report")?.report().clone()))?;
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
        let affine = basis::affine(M, "M")?;
        let name = name.to_string();
        self.with_state(py, move |s| {
            let deformer = s.deformer("transform_group()")?;
            if !deformer.constraints().group(&name).is_empty() {
                s.changes.transformed(&name);
            }
            s.deformer("transform_group()")?
                .transform_group(&name, &affine)
        })
    }
}

/// The native module `lse_deform._native`; the package `lse_deform`
/// re-exports it.
#[pymodule]
#[pyo3(name = "_native")]
pub(crate) fn native_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    // Under an address-space limit, one malloc arena from now on, as the
    // command-line tool does at start (`limits::cap_allocator_arenas`):
    // the threads this module starts then reserve no arena of their own.
    crate::limits::cap_allocator_arenas();
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("NumericalError", py.get_type::<NumericalError>())?;
    m.add("InputTypeError", input_type_error_class(py)?)?;
    m.add("TooLargeError", too_large_error_class(py)?)?;
    m.add_class::<PyDeformer>()?;
    m.add_class::<basis::PyHandleBasis>()?;
    m.add_function(wrap_pyfunction!(compare_rows, m)?)?;
    m.add_function(wrap_pyfunction!(deform, m)?)?;
    m.add_function(wrap_pyfunction!(laplacian_matrix, m)?)?;
    m.add_function(wrap_pyfunction!(solve_lse, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
