//! numpy / scipy.sparse / Python objects → the library's types and back.
//!
//! Arrays are read through `numpy.asarray` and the numpy crate's strided
//! views (`as_array`), element by element, so C-ordered, Fortran-ordered,
//! non-contiguous and negatively strided arrays all read the same; nothing
//! here assumes a memory order. Dtypes: real arrays accept float, int and
//! uint kinds (converted to float64), index arrays int and uint kinds;
//! anything else is an `InputTypeError` (a `TypeError`) naming the
//! argument and its dtype.
//!
//! Memory: an array's shape can promise far more than its storage (a
//! broadcast `numpy.broadcast_to(x, (2**31, 3))` holds three numbers), so
//! every buffer made here from a shape is checked against the memory budget
//! ([`crate::limits`]) and allocated by `try_reserve` before it is filled:
//! too large is a `TooLargeError` naming the array and the bytes, never an
//! abort or a panic.

use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, MatRef};
use numpy::ndarray::Array2;
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArrayDescrMethods, PyArrayMethods, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use serde_json::Value;

use super::errors::{allocation_failed, input, type_error};
use crate::constraints::{ConstraintSet, parse_constraints, read_constraints_file};
use crate::error::{MeshError, ProblemError};
use crate::limits::MemoryBudget;
use crate::report::Report;

/// Which dtypes an array may have.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    /// float, int or uint; read as float64.
    Real,
    /// int or uint; read as int64 / uint64.
    Index,
}

/// `numpy.asarray(obj)` with its dtype checked against `kind` and converted
/// to float64 (real), int64 or uint64 (indices).
fn numeric_array<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    kind: Kind,
) -> PyResult<Bound<'py, PyUntypedArray>> {
    let py = obj.py();
    let np = py.import("numpy")?;
    let array = np
        .call_method1("asarray", (obj,))
        .map_err(|e| type_error(format!("{name} is not an array: {e}")))?;
    let array = array
        .cast_into::<PyUntypedArray>()
        .map_err(|_| type_error(format!("{name} is not an array")))?;
    let dtype = array.dtype();
    let target = match (dtype.kind(), kind) {
        (b'f', Kind::Real) | (b'i', Kind::Real) | (b'u', Kind::Real) => "float64",
        (b'i', Kind::Index) => "int64",
        (b'u', Kind::Index) => "uint64",
        _ => {
            let wanted = match kind {
                Kind::Real => "real numbers (float64; float, int and uint dtypes are converted)",
                Kind::Index => "integer indices (int64; other integer dtypes are converted)",
            };
            return Err(type_error(format!(
                "{name} must hold {wanted}, got dtype {}",
                dtype.str()?
            )));
        }
    };
    let kwargs = PyDict::new(py);
    kwargs.set_item("copy", false)?;
    array
        .call_method("astype", (target,), Some(&kwargs))?
        .cast_into::<PyUntypedArray>()
        .map_err(|_| type_error(format!("{name}: astype did not return an array")))
}

/// The shape of `array` as (rows, columns): 2-D as it is, 1-D as one
/// column when `column_ok`; `columns` (if given) must match.
fn shape_2d(
    array: &Bound<'_, PyUntypedArray>,
    name: &str,
    columns: Option<usize>,
    column_ok: bool,
) -> PyResult<(usize, usize)> {
    let shape = array.shape();
    let (rows, cols) = match shape {
        [r, c] => (*r, *c),
        [r] if column_ok => (*r, 1),
        _ => {
            let expected = match columns {
                Some(c) => format!("an n × {c} array"),
                None => "a 2-D array".to_string(),
            };
            return Err(input(format!(
                "{name} must be {expected}, got shape {shape:?}"
            )));
        }
    };
    if let Some(c) = columns
        && cols != c
    {
        return Err(input(format!(
            "{name} must be an n × {c} array, got shape {shape:?}"
        )));
    }
    Ok((rows, cols))
}

/// `items` items of `bytes_each` bytes, saturating.
fn bytes_of(items: usize, bytes_each: usize) -> u64 {
    (items as u64).saturating_mul(bytes_each as u64)
}

/// Refuses `bytes` for `what` (named only on failure) beyond the memory
/// budget: a `TooLargeError`.
fn check_budget(what: &impl Fn() -> String, bytes: u64, budget: MemoryBudget) -> PyResult<()> {
    budget
        .check(bytes, || format!("{} would need", what()))
        .map_err(|detail| super::errors::to_py(ProblemError::TooLarge { detail }.into()))
}

/// An empty vector with room for `n` items, checked against the budget and
/// reserved with `try_reserve_exact`: a `TooLargeError` instead of an abort.
fn vec_for<T>(n: usize, budget: MemoryBudget, what: impl Fn() -> String) -> PyResult<Vec<T>> {
    let bytes = bytes_of(n, std::mem::size_of::<T>());
    check_budget(&what, bytes, budget)?;
    let mut v = Vec::new();
    v.try_reserve_exact(n)
        .map_err(|e| allocation_failed(&what(), bytes, e))?;
    Ok(v)
}

/// `Mat::from_fn` that checks the budget and reserves with faer's
/// `try_reserve` first (`Mat::from_fn` panics when its allocation fails).
fn mat_from_fn(
    rows: usize,
    cols: usize,
    budget: MemoryBudget,
    what: impl Fn() -> String,
    f: impl FnMut(usize, usize) -> f64,
) -> PyResult<Mat<f64>> {
    let bytes = bytes_of(rows, 8).saturating_mul(cols as u64);
    check_budget(&what, bytes, budget)?;
    let mut m = Mat::new();
    m.try_reserve(rows, cols)
        .map_err(|e| allocation_failed(&what(), bytes, format!("{e:?}")))?;
    m.resize_with(rows, cols, f);
    Ok(m)
}

/// A real array as an owned matrix (1-D arrays as one column when
/// `column_ok`); the flag says whether it was 1-D.
pub(crate) fn dense(
    obj: &Bound<'_, PyAny>,
    name: &str,
    columns: Option<usize>,
    column_ok: bool,
    budget: MemoryBudget,
) -> PyResult<(Mat<f64>, bool)> {
    let array = numeric_array(obj, name, Kind::Real)?;
    let (rows, cols) = shape_2d(&array, name, columns, column_ok)?;
    let what = || format!("the {rows} × {cols} array {name}");
    let one_d = array.ndim() == 1;
    if one_d {
        let typed = array.cast::<PyArray1<f64>>()?.readonly();
        let view = typed.as_array();
        Ok((mat_from_fn(rows, 1, budget, what, |i, _| view[i])?, true))
    } else {
        let typed = array.cast::<PyArray2<f64>>()?.readonly();
        let view = typed.as_array();
        Ok((
            mat_from_fn(rows, cols, budget, what, |i, j| view[[i, j]])?,
            false,
        ))
    }
}

/// An n × 3 real array as rows (read straight from the array: no
/// intermediate matrix).
pub(crate) fn rows3(
    obj: &Bound<'_, PyAny>,
    name: &str,
    budget: MemoryBudget,
) -> PyResult<Vec<[f64; 3]>> {
    let array = numeric_array(obj, name, Kind::Real)?;
    let (rows, _) = shape_2d(&array, name, Some(3), false)?;
    let typed = array.cast::<PyArray2<f64>>()?.readonly();
    let view = typed.as_array();
    let mut out = vec_for(rows, budget, || format!("the {rows} × 3 array {name}"))?;
    out.extend((0..rows).map(|i| [view[[i, 0]], view[[i, 1]], view[[i, 2]]]));
    Ok(out)
}

/// An integer array as int64 or uint64 (numpy's conversion, no copy when
/// it is one already) with its (rows, columns) shape.
fn index_array<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    columns: Option<usize>,
    column_ok: bool,
) -> PyResult<(Bound<'py, PyUntypedArray>, (usize, usize))> {
    let array = numeric_array(obj, name, Kind::Index)?;
    let shape = shape_2d(&array, name, columns, column_ok)?;
    Ok((array, shape))
}

/// `f(k, v)` for the entries of an [`index_array`] in row-major order (`k`
/// the entry's place in that order), widened to `i128` so that int64 and
/// uint64 read alike; stops at `f`'s first error. Reads the array in place:
/// no copy of the entries is made here (the caller keeps what it needs).
fn for_each_index(
    array: &Bound<'_, PyUntypedArray>,
    mut f: impl FnMut(usize, i128) -> PyResult<()>,
) -> PyResult<()> {
    let unsigned = array.dtype().kind() == b'u';
    macro_rules! read {
        ($t:ty) => {{
            if array.ndim() == 1 {
                let typed = array.cast::<PyArray1<$t>>()?.readonly();
                for (k, &v) in typed.as_array().iter().enumerate() {
                    f(k, v as i128)?;
                }
            } else {
                let typed = array.cast::<PyArray2<$t>>()?.readonly();
                // `iter` walks in logical (row-major) order whatever the
                // memory order.
                for (k, &v) in typed.as_array().iter().enumerate() {
                    f(k, v as i128)?;
                }
            }
        }};
    }
    if unsigned {
        read!(u64)
    } else {
        read!(i64)
    }
    Ok(())
}

/// A non-negative index as `usize`, or `None`.
fn as_index(v: i128) -> Option<usize> {
    usize::try_from(v).ok()
}

/// `F` (m × 3 vertex indices) as faces; a negative index is the mesh
/// layer's [`MeshError::IndexOutOfRange`], ranges are checked by
/// [`crate::Mesh::new`].
pub(crate) fn faces(
    obj: &Bound<'_, PyAny>,
    n_vertices: usize,
    budget: MemoryBudget,
) -> PyResult<Vec<[usize; 3]>> {
    let (array, (rows, _)) = index_array(obj, "F", Some(3), false)?;
    let mut faces = vec_for(rows, budget, || format!("the {rows} faces of F"))?;
    let mut f = [0usize; 3];
    for_each_index(&array, |k, v| {
        let (face, corner) = (k / 3, k % 3);
        f[corner] = as_index(v).ok_or_else(|| {
            super::errors::to_py(
                MeshError::IndexOutOfRange {
                    face,
                    index: i64::try_from(v).unwrap_or(i64::MIN),
                    vertex_count: n_vertices,
                    line: None,
                }
                .into(),
            )
        })?;
        if corner == 2 {
            faces.push(f);
        }
        Ok(())
    })?;
    Ok(faces)
}

/// A 1-D (or k × 1) array of non-negative indices.
pub(crate) fn indices(
    obj: &Bound<'_, PyAny>,
    name: &str,
    budget: MemoryBudget,
) -> PyResult<Vec<usize>> {
    indices_with_copies(obj, name, budget, 1)
}

/// `ordering=`'s sequence of indices as the shared permutation
/// [`FillOrdering::Given`](crate::resources::FillOrdering) holds: the
/// vector [`indices`] reads and the shared copy made of it exist at once,
/// so the budget counts both (8 bytes per entry each).
pub(crate) fn ordering(
    obj: &Bound<'_, PyAny>,
    budget: MemoryBudget,
) -> PyResult<std::sync::Arc<[usize]>> {
    Ok(indices_with_copies(obj, "ordering", budget, 2)?.into())
}

/// [`indices`], with room for `copies` copies of the result counted
/// against the budget (those the caller makes while this one lives).
fn indices_with_copies(
    obj: &Bound<'_, PyAny>,
    name: &str,
    budget: MemoryBudget,
    copies: usize,
) -> PyResult<Vec<usize>> {
    let (array, (rows, cols)) = index_array(obj, name, None, true)?;
    if cols != 1 {
        return Err(input(format!(
            "{name} must be a 1-D array of indices (or k × 1), got {cols} columns"
        )));
    }
    let what = || match copies {
        1 => format!("the {rows} indices of {name}"),
        c => format!("the {rows} indices of {name} ({c} copies at once)"),
    };
    check_budget(
        &what,
        bytes_of(rows, 8).saturating_mul(copies as u64),
        budget,
    )?;
    let mut out = vec_for(rows, budget, what)?;
    for_each_index(&array, |i, v| {
        out.push(as_index(v).ok_or_else(|| {
            input(format!(
                "{name}[{i}] = {v} is not an index (indices are 0-based and ≥ 0)"
            ))
        })?);
        Ok(())
    })?;
    Ok(out)
}

/// The constraints argument: a list of dicts in the JSON format (or a
/// dict with a `"constraints"` list), a path (`str` or `os.PathLike`) to
/// a constraints file, or libigl's position-only pair `(b, bc)`.
/// Returns the set and, for a file, the file's `"mesh"` record check is
/// left to the caller.
pub(crate) fn constraints(obj: &Bound<'_, PyAny>, budget: MemoryBudget) -> PyResult<ConstraintSet> {
    let py = obj.py();
    if obj.is_instance_of::<PyString>() || obj.hasattr("__fspath__")? {
        let path: String = py
            .import("os")?
            .call_method1("fspath", (obj,))?
            .extract()
            .map_err(|_| type_error("a constraints path must be a str or an os.PathLike of str"))?;
        return read_constraints_file(path.as_ref(), budget).map_err(super::errors::to_py);
    }
    if let Some((b, bc)) = libigl_pair(obj)? {
        let vertices = indices(&b, "b", budget)?;
        let targets = rows3(&bc, "bc", budget)?;
        return ConstraintSet::positions(&vertices, &targets)
            .map_err(|e| super::errors::to_py(e.into()));
    }
    let root = if obj.is_instance_of::<PyDict>() {
        to_json(obj, "constraints", 0)?
    } else if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        let list = to_json(obj, "constraints", 0)?;
        Value::Object([("constraints".to_string(), list)].into_iter().collect())
    } else {
        return Err(type_error(format!(
            "constraints must be a list of dicts (the JSON format), a path to a constraints file, or a pair (b, bc) of vertex indices and n × 3 targets; got {}",
            obj.get_type().name()?
        )));
    };
    parse_constraints(&root.to_string()).map_err(|e| super::errors::to_py(e.into()))
}

/// `Some((b, bc))` when `obj` is a 2-tuple or 2-list whose items are not
/// dicts: libigl's form.
fn libigl_pair<'py>(
    obj: &Bound<'py, PyAny>,
) -> PyResult<Option<(Bound<'py, PyAny>, Bound<'py, PyAny>)>> {
    if !(obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>()) || obj.len()? != 2 {
        return Ok(None);
    }
    let (first, second) = (obj.get_item(0)?, obj.get_item(1)?);
    if first.is_instance_of::<PyDict>() || second.is_instance_of::<PyDict>() {
        return Ok(None);
    }
    Ok(Some((first, second)))
}

/// Deepest nesting of a constraints object (the format needs 3; a
/// self-containing list must not overflow the stack).
const MAX_JSON_DEPTH: usize = 32;

/// A Python object as JSON: dicts with string keys, lists, tuples, numpy
/// arrays and scalars (through `tolist`), str, bool, int and finite floats.
/// `path` names the place in errors (`constraints[3]['target'][1]`).
fn to_json(obj: &Bound<'_, PyAny>, path: &str, depth: usize) -> PyResult<Value> {
    if depth > MAX_JSON_DEPTH {
        return Err(input(format!(
            "{path}: nested deeper than {MAX_JSON_DEPTH} levels"
        )));
    }
    if let Ok(b) = obj.cast::<PyBool>() {
        return Ok(Value::Bool(b.is_true()));
    }
    if obj.is_instance_of::<PyInt>() {
        if let Ok(v) = obj.extract::<i64>() {
            return Ok(Value::from(v));
        }
        if let Ok(v) = obj.extract::<u64>() {
            return Ok(Value::from(v));
        }
        return Err(input(format!("{path}: the integer {obj} is out of range")));
    }
    if obj.is_instance_of::<PyFloat>() {
        let v: f64 = obj.extract()?;
        return serde_json::Number::from_f64(v)
            .map(Value::Number)
            .ok_or_else(|| input(format!("{path} = {v} is not finite")));
    }
    if obj.is_instance_of::<PyString>() {
        return Ok(Value::String(obj.extract()?));
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        let mut map = serde_json::Map::new();
        for (k, v) in d.iter() {
            let key: String = k
                .extract()
                .map_err(|_| type_error(format!("{path}: keys must be strings, got {k}")))?;
            let value = to_json(&v, &format!("{path}['{key}']"), depth + 1)?;
            map.insert(key, value);
        }
        return Ok(Value::Object(map));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        let mut items = Vec::new();
        for (i, item) in obj.try_iter()?.enumerate() {
            items.push(to_json(&item?, &format!("{path}[{i}]"), depth + 1)?);
        }
        return Ok(Value::Array(items));
    }
    if obj.hasattr("tolist")? {
        // numpy arrays and scalars: their Python equivalents.
        let plain = obj.call_method0("tolist")?;
        if !plain.is(obj) {
            return to_json(&plain, path, depth + 1);
        }
    }
    Err(type_error(format!(
        "{path}: a {} cannot be part of a constraint (expected dict, list, str, number or bool)",
        obj.get_type().name()?
    )))
}

/// Refuses a matrix whose index arrays alone would exceed the memory
/// budget ([`crate::limits`]) — a shape of 10¹⁸ columns must be an error,
/// not an allocation failure.
fn check_size(
    name: &str,
    (rows, cols): (usize, usize),
    entries: usize,
    budget: MemoryBudget,
) -> PyResult<()> {
    let bytes = (rows as u64)
        .saturating_add(cols as u64)
        .saturating_add(1)
        .saturating_mul(8)
        .saturating_add((entries as u64).saturating_mul(24));
    budget
        .check(bytes, || {
            format!("the {rows} × {cols} matrix {name} would need")
        })
        .map_err(|detail| super::errors::to_py(ProblemError::TooLarge { detail }.into()))
}

/// A sparse matrix from `scipy.sparse` (CSC and CSR read directly, COO
/// directly, other formats through `tocoo()`) or a dense 2-D array, as a
/// faer CSC matrix (duplicates summed). Index arrays are checked (pointer
/// monotonicity and range, row and column ranges) before use.
pub(crate) fn sparse(
    obj: &Bound<'_, PyAny>,
    name: &str,
    budget: MemoryBudget,
) -> PyResult<SparseColMat<usize, f64>> {
    let py = obj.py();
    let scipy_sparse = py.import("scipy.sparse")?;
    if !scipy_sparse.call_method1("issparse", (obj,))?.is_truthy()? {
        let (m, _) = dense(obj, name, None, false, budget)?;
        let nonzeros = (0..m.ncols())
            .map(|j| (0..m.nrows()).filter(|&i| m[(i, j)] != 0.0).count())
            .sum::<usize>();
        check_size(name, (m.nrows(), m.ncols()), nonzeros, budget)?;
        let mut triplets = vec_for(nonzeros, budget, || {
            format!("the {nonzeros} nonzeros of the dense array {name}")
        })?;
        for j in 0..m.ncols() {
            for i in 0..m.nrows() {
                if m[(i, j)] != 0.0 {
                    triplets.push(Triplet::new(i, j, m[(i, j)]));
                }
            }
        }
        return from_triplets(name, m.nrows(), m.ncols(), &triplets, budget);
    }
    let (rows, cols): (usize, usize) = obj.getattr("shape")?.extract().map_err(|_| {
        input(format!(
            "{name}.shape is not a pair of non-negative integers"
        ))
    })?;
    let format: String = obj.getattr("format")?.extract()?;
    let coo;
    let (obj, format) = match format.as_str() {
        "csc" | "csr" | "coo" => (obj, format),
        _ => {
            coo = obj.call_method0("tocoo")?;
            (&coo, "coo".to_string())
        }
    };
    let data = dense(
        &obj.getattr("data")?,
        &format!("{name}.data"),
        None,
        true,
        budget,
    )?
    .0;
    check_size(name, (rows, cols), data.nrows(), budget)?;
    let mut values = vec_for(data.nrows(), budget, || {
        format!("the {} entries of {name}", data.nrows())
    })?;
    values.extend((0..data.nrows()).map(|i| data[(i, 0)]));
    let triplets = match format.as_str() {
        "coo" => {
            let r = indices(&obj.getattr("row")?, &format!("{name}.row"), budget)?;
            let c = indices(&obj.getattr("col")?, &format!("{name}.col"), budget)?;
            if r.len() != values.len() || c.len() != values.len() {
                return Err(input(format!(
                    "{name}: row, col and data of a COO matrix must have one length, got {}, {} and {}",
                    r.len(),
                    c.len(),
                    values.len()
                )));
            }
            check_range(name, "row", &r, rows)?;
            check_range(name, "column", &c, cols)?;
            let mut triplets = vec_for(values.len(), budget, || {
                format!("the {} entries of {name}", values.len())
            })?;
            triplets.extend((0..values.len()).map(|k| Triplet::new(r[k], c[k], values[k])));
            triplets
        }
        by_rows => {
            let by_rows = by_rows == "csr";
            let (major, minor) = if by_rows { (rows, cols) } else { (cols, rows) };
            let ptr = indices(&obj.getattr("indptr")?, &format!("{name}.indptr"), budget)?;
            let idx = indices(&obj.getattr("indices")?, &format!("{name}.indices"), budget)?;
            compressed_triplets(name, (major, minor), &ptr, &idx, &values, by_rows, budget)?
        }
    };
    from_triplets(name, rows, cols, &triplets, budget)
}

/// Every index `< bound`, or an error naming the first that is not.
fn check_range(name: &str, what: &str, idx: &[usize], bound: usize) -> PyResult<()> {
    match idx.iter().position(|&i| i >= bound) {
        Some(k) => Err(input(format!(
            "{name}: entry {k} has {what} index {} but the matrix has {bound} {what}s",
            idx[k]
        ))),
        None => Ok(()),
    }
}

/// The triplets of compressed arrays (CSC, or CSR when `by_rows`), checked.
fn compressed_triplets(
    name: &str,
    (major, minor): (usize, usize),
    ptr: &[usize],
    idx: &[usize],
    values: &[f64],
    by_rows: bool,
    budget: MemoryBudget,
) -> PyResult<Vec<Triplet<usize, usize, f64>>> {
    let (major_name, minor_name) = if by_rows {
        ("row", "column")
    } else {
        ("column", "row")
    };
    if ptr.len() != major + 1 || idx.len() != values.len() {
        return Err(input(format!(
            "{name}: indptr must have {} entries ({major} {major_name}s + 1) and indices as many as data, got {}, {} and {}",
            major + 1,
            ptr.len(),
            idx.len(),
            values.len()
        )));
    }
    if let Some(k) = (0..major).find(|&k| ptr[k] > ptr[k + 1]) {
        return Err(input(format!(
            "{name}: indptr decreases at {major_name} {k} ({} > {})",
            ptr[k],
            ptr[k + 1]
        )));
    }
    if ptr[0] != 0 || ptr[major] > idx.len() {
        return Err(input(format!(
            "{name}: indptr must start at 0 and end at most at the {} stored entries, got {} .. {}",
            idx.len(),
            ptr[0],
            ptr[major]
        )));
    }
    check_range(name, minor_name, &idx[..ptr[major]], minor)?;
    let mut triplets = vec_for(ptr[major], budget, || {
        format!("the {} entries of {name}", ptr[major])
    })?;
    for k in 0..major {
        for p in ptr[k]..ptr[k + 1] {
            let (i, j) = if by_rows { (k, idx[p]) } else { (idx[p], k) };
            triplets.push(Triplet::new(i, j, values[p]));
        }
    }
    Ok(triplets)
}

fn from_triplets(
    name: &str,
    rows: usize,
    cols: usize,
    triplets: &[Triplet<usize, usize, f64>],
    budget: MemoryBudget,
) -> PyResult<SparseColMat<usize, f64>> {
    check_size(name, (rows, cols), triplets.len(), budget)?;
    SparseColMat::try_new_from_triplets(rows, cols, triplets)
        .map_err(|e| input(format!("{name}: not a valid sparse matrix ({e:?})")))
}

/// Positions as an n × 3 float64 array (C order).
pub(crate) fn positions_to_numpy<'py>(
    py: Python<'py>,
    positions: &[[f64; 3]],
) -> Bound<'py, PyArray2<f64>> {
    let flat: Vec<f64> = positions.iter().flatten().copied().collect();
    Array2::from_shape_vec((positions.len(), 3), flat)
        .unwrap_or_else(|_| Array2::zeros((0, 3)))
        .into_pyarray(py)
}

/// A matrix as a float64 array (C order); one column as a 1-D array when
/// `one_d`.
pub(crate) fn matrix_to_numpy<'py>(
    py: Python<'py>,
    m: MatRef<'_, f64>,
    one_d: bool,
) -> Bound<'py, PyAny> {
    if one_d {
        let column: Vec<f64> = (0..m.nrows()).map(|i| m[(i, 0)]).collect();
        return column.into_pyarray(py).into_any();
    }
    Array2::from_shape_fn((m.nrows(), m.ncols()), |(i, j)| m[(i, j)])
        .into_pyarray(py)
        .into_any()
}

/// A faer CSC matrix as `scipy.sparse.csc_matrix` (sorted row indices).
pub(crate) fn csc_to_scipy<'py>(
    py: Python<'py>,
    m: &SparseColMat<usize, f64>,
) -> PyResult<Bound<'py, PyAny>> {
    let (mut ptr, mut idx, mut val) = (vec![0usize], Vec::new(), Vec::new());
    for j in 0..m.ncols() {
        let range = m.symbolic().col_range(j);
        let mut column: Vec<(usize, f64)> = m.symbolic().row_idx()[range.clone()]
            .iter()
            .copied()
            .zip(m.val()[range].iter().copied())
            .collect();
        column.sort_by_key(|e| e.0);
        for (i, v) in column {
            idx.push(i);
            val.push(v);
        }
        ptr.push(idx.len());
    }
    csc_parts_to_scipy(py, (m.nrows(), m.ncols()), &ptr, &idx, val)
}

/// Compressed columns (`col_ptr`, `row_idx` as they are: the caller
/// sorts) with `values` as a `scipy.sparse.csc_matrix` of `shape`.
pub(crate) fn csc_parts_to_scipy<'py>(
    py: Python<'py>,
    shape: (usize, usize),
    col_ptr: &[usize],
    row_idx: &[usize],
    values: Vec<f64>,
) -> PyResult<Bound<'py, PyAny>> {
    let as_i64 = |v: &[usize]| v.iter().map(|&i| i as i64).collect::<Vec<i64>>();
    let arrays = (
        values.into_pyarray(py),
        as_i64(row_idx).into_pyarray(py),
        as_i64(col_ptr).into_pyarray(py),
    );
    let kwargs = PyDict::new(py);
    kwargs.set_item("shape", shape)?;
    py.import("scipy.sparse")?
        .call_method("csc_matrix", (arrays,), Some(&kwargs))
}

/// The report as a plain dict with the keys of the CLI's JSON report.
pub(crate) fn report_dict<'py>(py: Python<'py>, report: &Report) -> PyResult<Bound<'py, PyAny>> {
    json_value(py, report)
}

/// A serialisable value as the Python value of its JSON (dicts, lists,
/// numbers, strings, `None`): the keys and words of the CLI's JSON.
pub(crate) fn json_value<'py>(
    py: Python<'py>,
    value: &impl serde::Serialize,
) -> PyResult<Bound<'py, PyAny>> {
    let json = serde_json::to_string(value)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (json,))
}
