//! Python's frames that cost less than a refined, diagnosed solve:
//! `Deformer.basis(groups)`, the class `HandleBasis` (the library's
//! [`HandleBasis`], docs/handles.md) for affine drags of groups, and the
//! body of `Deformer.solve(refine=..., estimate=...)` ([`solve_frame`]) for
//! a solve without refinement and diagnostics.
//!
//! **When a basis is stale.** `evaluate(T)` promises what, for every group
//! `g` of the basis, `transform_group(g, T.get(g, identity))` followed by
//! `solve()` returns — with every other constraint at the target it had
//! when the basis was built. The basis holds `X₀` (the other constraints'
//! targets then) and the `R_g` (the groups' rest targets then) on the
//! factor then, refined with the refinement then. So it is stale after
//! anything that changes one of those: `precompute()` (a new factor, its
//! options and refinement; also when it fails: then there is no factor),
//! `set_targets()` of any constraint (it moves current and rest targets,
//! inside a basis group or outside it), and `transform_group()` of a group
//! outside the basis. `transform_group()` of a group of the basis is not a
//! change for it: evaluate ignores where transform_group last put its
//! groups (a group missing from the dict is at its rest pose). Every
//! mutating entry point of the Python `Deformer` records itself in
//! [`Changes`](super::state::Changes) under the Deformer's lock, whether it succeeds or not (a
//! transform_group only when the group exists), and `evaluate` checks the
//! record under the same lock before reading the basis; a per-call
//! `solve(refine=...)` changes nothing that stays. Conservative: a
//! set_targets to the same values, or a group transformed and put back,
//! still makes the basis refuse.

use numpy::{PyArray2, PyArrayDescrMethods, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyMapping, PyString};

use super::convert;
use super::errors::{guarded, input, released, to_py, type_error};
use super::state::{DeformerState, PyDeformer, Stamp};
use crate::deform::Affine;
use crate::error::{Error, ProblemError};
use crate::formulation::Refine;
use crate::handle::HandleBasis;

/// The identity: the transform of a group the dict leaves out.
const IDENTITY: Affine = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
];

/// How far each entry of a 4 × 4 map's last row may be from
/// `[0, 0, 0, 1]`: a product of a few rigid maps composed in `f64` is
/// off by a few ulps (1e-16), a projective map by far more.
pub(super) const HOMOGENEOUS_TOLERANCE: f64 = 1e-12;

/// From this many vertices on, `evaluate` releases the GIL (below it,
/// releasing and taking it back costs about as much as the evaluation).
const RELEASE_GIL_VERTICES: usize = 4096;

/// The 3 × 4 `[R | t]` of `obj`: a 3 × 4 array, or a 4 × 4 one whose last
/// row is `[0, 0, 0, 1]` within [`HOMOGENEOUS_TOLERANCE`]; errors name
/// the argument `name`.
pub(super) fn affine(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Affine> {
    let budget = crate::limits::MemoryBudget::from_environment()
        .map_err(|e| super::errors::to_py(e.into()))?;
    let (m, _) = convert::dense(obj, name, Some(4), false, budget)?;
    let homogeneous = m.nrows() == 4
        && (0..4).all(|j| (m[(3, j)] - [0.0, 0.0, 0.0, 1.0][j]).abs() <= HOMOGENEOUS_TOLERANCE);
    if !(m.nrows() == 3 || homogeneous) {
        return Err(input(format!(
            "{name} must be 3 × 4 [R | t] or 4 × 4 with last row [0, 0, 0, 1] (within {HOMOGENEOUS_TOLERANCE:e}), got {} × 4{}",
            m.nrows(),
            if m.nrows() == 4 {
                " with another last row"
            } else {
                ""
            }
        )));
    }
    Ok([0, 1, 2].map(|r| [0, 1, 2, 3].map(|c| m[(r, c)])))
}

/// The affine response of some constraint groups of a Deformer:
/// positions for any affine maps of the groups without a solve.
///
/// `evaluate(transforms, out=None)` takes a dict from group name to a 3 x 4
/// `[R | t]` or 4 x 4 affine map (last row `[0, 0, 0, 1]` within 1e-12)
/// and returns the (n, 3) float64 positions that
/// `transform_group(g, transforms.get(g, identity))` for every group `g`
/// of the basis followed by `solve()` would return (to the forward error
/// of the two, both refined): a group left out of the dict is at its rest
/// pose, not where `transform_group` last put it, and every constraint
/// outside the groups keeps the target it had when the basis was built.
/// A frame costs one read of the basis (`bytes`), no solve.
///
/// The basis refuses (InputError) once the Deformer has changed in a way
/// that would change that answer: `precompute()`, `set_targets()` of any
/// constraint, or `transform_group()` of a group outside the basis (any
/// call, even one that changes nothing in the end). `transform_group()`
/// of a group of the basis does not make it stale. Build a new basis then.
#[pyclass(name = "HandleBasis", module = "lse_deform", frozen)]
pub(super) struct PyHandleBasis {
    basis: HandleBasis,
    deformer: Py<PyDeformer>,
    stamp: Stamp,
}

/// `Deformer.basis(groups)`: the library's [`HandleBasis::new`] on the
/// deformer's factor, with its refinement and memory budget, under its
/// lock (GIL released).
pub(super) fn build(
    deformer: &Bound<'_, PyDeformer>,
    groups: &Bound<'_, PyAny>,
) -> PyResult<PyHandleBasis> {
    let py = deformer.py();
    let expected = "groups must be a list of group names (str), e.g. basis([\"handle\"])";
    if groups.is_instance_of::<PyString>() {
        return Err(type_error(format!("{expected}, not a str")));
    }
    let names: Vec<String> = groups
        .extract()
        .map_err(|_| type_error(format!("{expected}, got {}", type_name(groups))))?;
    let (basis, stamp) = deformer.borrow().with_state(py, move |s| {
        let stamp = s.changes.stamp();
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        Ok((HandleBasis::new(s.deformer("basis()")?, &names)?, stamp))
    })?;
    Ok(PyHandleBasis {
        basis,
        deformer: deformer.clone().unbind(),
        stamp,
    })
}

#[pymethods]
impl PyHandleBasis {
    /// The positions (n, 3) for the affine maps `transforms` (a dict from
    /// group name to a 3 x 4 or 4 x 4 map; a group left out stays at its
    /// rest pose), written into `out` when given (a writable C-contiguous
    /// float64 array of shape (n, 3), which is returned). See the class.
    #[pyo3(signature = (transforms, out=None))]
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        transforms: &Bound<'py, PyAny>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        guarded(|| {
            let m = self.transforms(transforms)?;
            let out = output(py, out, self.basis.n_vertices())?;
            self.check_current(py)?;
            self.check_maps(py, &m)?;
            let mut guard = out
                .try_readwrite()
                .map_err(|e| input(format!("out is not writable: {e}")))?;
            let flat = guard
                .as_slice_mut()
                .map_err(|e| input(format!("out: {e}")))?;
            let (rows, _) = flat.as_chunks_mut::<3>();
            if rows.len() >= RELEASE_GIL_VERTICES {
                released(py, || self.basis.evaluate(&m, rows))?;
            } else {
                self.basis.evaluate(&m, rows).map_err(to_py)?;
            }
            drop(guard);
            Ok(out.into_any())
        })
    }

    /// The group names, in the order they were given.
    #[getter]
    fn groups(&self) -> Vec<String> {
        self.basis.groups().to_vec()
    }

    /// The bytes of the basis: what one evaluation reads.
    #[getter]
    fn bytes(&self) -> usize {
        self.basis.bytes()
    }

    /// Seconds the basis took to build (the solves of its 3 + 4G columns
    /// and their refinement).
    #[getter]
    fn build_time_s(&self) -> f64 {
        self.basis.build_time_s()
    }

    /// The forward-error estimate of the basis relative to the length
    /// scale: the largest over its 3 + 4G refined columns (the library's
    /// `HandleBasis::forward_error_estimate`). Positions combine the
    /// columns with the maps' entries as weights.
    #[getter]
    fn forward_error_estimate(&self) -> f64 {
        self.basis.forward_error_estimate()
    }

    fn __repr__(&self) -> String {
        format!(
            "HandleBasis(groups={:?}, vertices={}, bytes={})",
            self.basis.groups(),
            self.basis.n_vertices(),
            self.basis.bytes()
        )
    }
}

impl PyHandleBasis {
    /// The maps of `obj` (a dict) in the order of the basis's groups, the
    /// identity for a group it leaves out.
    fn transforms(&self, obj: &Bound<'_, PyAny>) -> PyResult<Vec<Affine>> {
        let groups = self.basis.groups();
        let expected = || {
            type_error(format!(
                "transforms must be a mapping (a dict) from group name to a 3 × 4 or 4 × 4 affine map, got {}",
                type_name(obj)
            ))
        };
        // Any mapping (collections.abc.Mapping: a dict, a MappingProxyType).
        let items = match obj.cast::<PyDict>() {
            Ok(dict) => dict.items(),
            Err(_) => obj.cast::<PyMapping>().map_err(|_| expected())?.items()?,
        };
        let mut m = vec![IDENTITY; groups.len()];
        for item in items.iter() {
            let (key, value): (Bound<'_, PyAny>, Bound<'_, PyAny>) = item.extract()?;
            let name: String = key.extract().map_err(|_| {
                type_error(format!(
                    "transforms: the keys are group names (str), got {}",
                    type_name(&key)
                ))
            })?;
            let g = groups.iter().position(|x| *x == name).ok_or_else(|| {
                input(format!(
                    "transforms: group '{name}' is not in this basis (its groups: {})",
                    groups.join(", ")
                ))
            })?;
            m[g] = affine(&value, &format!("transforms['{name}']"))?;
        }
        Ok(m)
    }

    /// The checks of `transform_group` on each map of `m` (a matrix whose
    /// targets overflow is refused here as there), without moving anything.
    fn check_maps(&self, py: Python<'_>, m: &[Affine]) -> PyResult<()> {
        let groups = self.basis.groups();
        self.deformer.bind(py).borrow().with_state(py, move |s| {
            for (name, map) in groups.iter().zip(m) {
                s.deformer("evaluate()")?.check_transform(name, map)?;
            }
            Ok(())
        })
    }

    /// An `InputError` when the Deformer changed since the basis was built
    /// (module documentation).
    fn check_current(&self, py: Python<'_>) -> PyResult<()> {
        let stamp = self.stamp;
        let groups = self.basis.groups();
        let change = self
            .deformer
            .bind(py)
            .borrow()
            .with_state(py, move |s| Ok(s.changes.since(stamp, groups)))?;
        match change {
            None => Ok(()),
            Some(what) => Err(input(format!(
                "this basis was built for an earlier configuration of the Deformer: {what}; build a new one with Deformer.basis({groups:?})"
            ))),
        }
    }
}

/// The array `evaluate` writes: `out` when given (checked: a float64
/// array of shape (n, 3), C-contiguous), else a new one.
fn output<'py>(
    py: Python<'py>,
    out: Option<&Bound<'py, PyAny>>,
    n: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let Some(out) = out.filter(|o| !o.is_none()) else {
        let zeros = py.import("numpy")?.call_method1("zeros", ((n, 3),))?;
        return Ok(zeros.cast_into::<PyArray2<f64>>()?);
    };
    let expected = format!("out must be a C-contiguous float64 numpy array of shape ({n}, 3)");
    let array = out
        .cast::<PyUntypedArray>()
        .map_err(|_| type_error(format!("{expected}, got {}", type_name(out))))?;
    if !array.dtype().is_equiv_to(&numpy::dtype::<f64>(py)) {
        return Err(type_error(format!(
            "{expected}, got dtype {}",
            array.dtype().str()?
        )));
    }
    if array.shape() != [n, 3] {
        return Err(input(format!("{expected}, got shape {:?}", array.shape())));
    }
    if !array.is_c_contiguous() {
        return Err(input(format!(
            "{expected}, got one that is not C-contiguous (numpy.ascontiguousarray makes one)"
        )));
    }
    Ok(out.cast::<PyArray2<f64>>()?.clone())
}

pub(super) fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "an object".into())
}

/// The body of `Deformer.solve(refine, estimate)`: the positions and the
/// report's warnings. `refine` (else the Deformer's own) is this call's
/// refinement only. `estimate=False` is the cheap frame, the library's
/// [`crate::Deformer::solve_undiagnosed`]: no correction at all (with
/// `refine='off'` a solve still computes one, not applied, for the
/// forward-error estimate) and no diagnostics (the report then says
/// "not computed": no estimate, no refinement, no residuals). With
/// refinement on it is refused: a refined solve's estimate is its last
/// correction, which it computes anyway.
pub(super) fn solve_frame(
    s: &mut DeformerState,
    refine: Option<Refine>,
    estimate: bool,
) -> Result<(Vec<[f64; 3]>, Vec<crate::report::Warning>), Error> {
    let default_refine = s.options.refine;
    let deformer = s.deformer("solve()")?;
    let mode = refine.unwrap_or_else(|| deformer.solver().refine_mode());
    if !estimate && mode != Refine::EstimateOnly {
        return Err(ProblemError::InvalidArgument {
            message: format!(
                "estimate=False applies to refine='off' only: a refined solve (refine='{mode}') computes its forward-error estimate anyway, from its last correction; pass refine='off' with estimate=False"
            ),
        }
        .into());
    }
    if refine.is_some() {
        deformer.solver_mut().set_refine(refine);
    }
    let result = if estimate {
        deformer
            .solve()
            .map(|solution| (solution.positions, solution.report.warnings))
    } else {
        deformer.solve_undiagnosed().map(|p| (p, Vec::new()))
    };
    if refine.is_some() {
        deformer.solver_mut().set_refine(default_refine);
    }
    result
}
