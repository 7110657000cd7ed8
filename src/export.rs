//! Matrix Market export of a problem and of the matrix a formulation
//! factored, for MATLAB (`mmread`) and SciPy (`scipy.io.mmread`).
//!
//! Files written by [`export_problem`] into a directory:
//!
//! | file | content | format |
//! |---|---|---|
//! | `A.mtx` | `A = [L; w·B_soft]` (l × n) | `coordinate real general` |
//! | `C.mtx` | `C = [δ; w·D_soft]` (l × 3) | `array real general` |
//! | `B.mtx` | `B`, hard constraints in priority order (m × n) | `coordinate real general` |
//! | `D.mtx` | `D` (m × 3) | `array real general` |
//! | `factored.mtx` | [`Prepared::factored_matrix`], both triangles | `coordinate real general` |
//! | `meta.json` | [`export_meta`]: method, back ends, weight, Laplacian, KKT multiplier scale, the unknown order of `factored.mtx`, and what `solve` needs to treat the files as the mesh problem they came from (Laplacian rows, length scale) | JSON |
//!
//! The writers and the reader are in [`crate::mtx`] (values in shortest
//! round-trip form, so a file read back gives the same `f64` bit for bit);
//! `lse-deform solve` reads a directory written here and solves it.
//!
//! The factored matrix is written in full (both triangles, `general`) rather
//! than as a `symmetric` lower triangle: every reader then gets the matrix
//! itself, with no convention on which triangle is stored. Its unknown
//! order is the formulation's own (see [`Prepared::factored_matrix`]); for
//! KKT the multiplier rows are scaled by [`crate::Report::kkt_multiplier_scale`].

use std::path::{Path, PathBuf};

use faer::MatRef;
use faer::sparse::SparseColMatRef;

use crate::choice::Method;
use crate::error::{Error, MatrixFileError};
use crate::formulation::Prepared;
use crate::interop::faer_rows_to_sprs;
use crate::mtx::write_sprs;
pub use crate::mtx::{read_dense, read_sparse, write_dense, write_sparse};
use crate::problem::LseProblem;

/// The paths [`export_problem`] wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExportedFiles {
    /// `A.mtx`.
    pub a: PathBuf,
    /// `C.mtx`.
    pub c: PathBuf,
    /// `B.mtx`.
    pub b: PathBuf,
    /// `D.mtx`.
    pub d: PathBuf,
    /// `factored.mtx`, if a prepared system with a factored matrix was
    /// given.
    pub factored: Option<PathBuf>,
}

/// Creates the directory `dir` (and its parents) if missing. A `dir` that
/// exists and is not a directory (a file, a device such as `/dev/full`) is
/// an error that says so, where the system's own would say "File exists".
pub fn create_output_dir(dir: &Path) -> Result<(), Error> {
    if let Ok(m) = std::fs::metadata(dir)
        && !m.is_dir()
    {
        let what = if m.is_file() {
            "a regular file"
        } else {
            "a device, FIFO or socket"
        };
        let e = std::io::Error::new(
            std::io::ErrorKind::NotADirectory,
            format!("exists and is {what}, not a directory (the export is a directory of files)"),
        );
        return Err(Error::io(dir, e));
    }
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))
}

/// Writes `A`, `C`, `B`, `D` of `problem` and, if given, the matrix
/// `prepared` factored, into `dir` (created if missing,
/// [`create_output_dir`]). Existing files of the same names are
/// overwritten.
pub fn export_problem(
    dir: &Path,
    problem: &LseProblem,
    prepared: Option<&dyn Prepared>,
) -> Result<ExportedFiles, Error> {
    create_output_dir(dir)?;
    let files = ExportedFiles {
        a: dir.join("A.mtx"),
        c: dir.join("C.mtx"),
        b: dir.join("B.mtx"),
        d: dir.join("D.mtx"),
        factored: None,
    };
    write_sparse(&files.a, problem.a().as_ref())?;
    write_dense(&files.c, problem.c().as_ref())?;
    write_sprs(&files.b, &faer_rows_to_sprs(problem.b().as_ref()))?;
    write_dense(&files.d, problem.d().as_ref())?;
    let factored = match prepared.and_then(|p| p.factored_matrix()) {
        Some(k) => {
            let path = dir.join("factored.mtx");
            write_sparse(&path, k.as_ref())?;
            Some(path)
        }
        None => None,
    };
    Ok(ExportedFiles { factored, ..files })
}

/// The file [`export_meta`] writes.
pub const META_FILE: &str = "meta.json";

/// Writes `meta.json` into `dir`: how the exported problem was set up and
/// factored, from the `report` of its precompute:
///
/// - `method`, `qr_backend`, `factor_backend` (and `spd_backend`, its
///   deprecated alias kept for one release), `penalty_weight`,
///   `laplacian`, `kkt_multiplier_scale` (null where they do not apply);
/// - `factored_unknowns`: the unknown order of `factored.mtx` in words, and
///   for elimination `factored_unknown_list`, the unknowns (vertices) in
///   that order;
/// - `unknowns` (n), `rhs_columns` (k), `laplacian_rows` (the rows of `A`
///   that are the Laplacian, before the soft rows), `length_scale` (the
///   unit of the conflict tolerance), `length_unit` (the mesh length the
///   problem's lengths are divided by: `X` times it is the deformed
///   positions, see [`crate::Deformer`]), `soft_weight_scale` (the factor
///   `length_unitᵃ` the soft rows of `A` and `C` carry on top of their
///   weights, docs/units.md §3), `constraint_of_b_row`,
///   `constraint_of_soft_row` and `soft_weight_of_row` (the constraint
///   index of each row of `B` and of each soft row of `A`, and the soft
///   weight as given);
/// - `fingerprint`: [`system_fingerprint`] of the `A`, `C`, `B`, `D`
///   written beside it and of the `laplacian_rows`, `length_scale` and
///   `length_unit` above ([`MetaUnits`]): what `solve` uses of the file.
///
/// `lse-deform solve` reads `laplacian_rows` and `length_scale` back
/// ([`LseProblem::with_laplacian_rows`], [`LseProblem::with_length_scale`]),
/// so that the files solve to the same positions and the same report as
/// the mesh problem; it first checks the file against the matrices
/// ([`check_meta`]).
pub fn export_meta(
    dir: &Path,
    problem: &LseProblem,
    report: &crate::Report,
) -> Result<PathBuf, Error> {
    let n = problem.n();
    let (order, list): (String, Option<Vec<usize>>) = match report.method {
        Method::NullSpaceQr => (
            format!(
                "the free directions z of X = Q[y; z] ({} of them: unknowns minus the rank of B), in the QR back end's order",
                n - report.rank.unwrap_or(0)
            ),
            None,
        ),
        Method::Penalty => (format!("the unknowns 0..{n} (vertices for a mesh)"), None),
        Method::Eliminate => {
            let mut fixed = vec![false; n];
            for &j in problem.b().symbolic().col_idx() {
                fixed[j] = true;
            }
            (
                "the unknowns not fixed by a hard row, increasing (factored_unknown_list)".into(),
                Some((0..n).filter(|&j| !fixed[j]).collect()),
            )
        }
        Method::Kkt => (
            format!(
                "the unknowns 0..{n}, then the multipliers of the {} rows of B divided by kkt_multiplier_scale (rows and columns n.. scaled by it)",
                problem.b().nrows()
            ),
            None,
        ),
    };
    let meta = serde_json::json!({
        "format": "lse-deform export-system",
        "method": report.method,
        "qr_backend": report.qr_backend,
        "spd_backend": report.factor_backend,
        "factor_backend": report.factor_backend,
        "penalty_weight": report.penalty_weight(),
        "laplacian": report.energy,
        "kkt_multiplier_scale": report.kkt_multiplier_scale(),
        "factored_unknowns": order,
        "factored_unknown_list": list,
        "unknowns": n,
        "rhs_columns": problem.n_rhs(),
        "laplacian_rows": problem.n_laplacian_rows(),
        "length_scale": problem.length_scale(),
        "length_unit": report.length_unit,
        "constraint_of_b_row": problem.hard_constraints(),
        "soft_weight_scale": report.soft_weight_scale,
        "constraint_of_soft_row": problem.soft_constraints().iter().map(|s| s.index).collect::<Vec<_>>(),
        "soft_weight_of_row": problem.soft_constraints().iter().map(|s| s.weight).collect::<Vec<_>>(),
        "fingerprint": problem_fingerprint(problem, &MetaUnits {
            laplacian_rows: problem.n_laplacian_rows(),
            length_scale: read_back(problem.length_scale()),
            length_unit: read_back(report.length_unit),
        }),
    });
    let path = dir.join(META_FILE);
    let text = serde_json::to_string_pretty(&meta).map_err(|e| Error::io(&path, e.into()))?;
    crate::atomic::write_bytes(&path, (text + "\n").as_bytes()).map_err(|e| Error::io(&path, e))?;
    Ok(path)
}

/// `x` as [`read_meta`] will read it from the JSON `export_meta` writes:
/// serde_json's reader is not correctly rounded in every case, so the
/// fingerprint is made of the value read back, bit for bit.
fn read_back(x: f64) -> f64 {
    serde_json::to_string(&x)
        .ok()
        .and_then(|text| serde_json::from_str(&text).ok())
        .unwrap_or(x)
}

/// What `lse-deform solve` takes from a `meta.json`: the Laplacian rows and
/// the length scale, and what it checks the matrices against (any may be
/// absent).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ProblemMeta {
    /// `laplacian_rows`.
    pub laplacian_rows: Option<usize>,
    /// `length_scale`.
    pub length_scale: Option<f64>,
    /// `length_unit`: reports of the solve give lengths times it, as the
    /// mesh problem's report does.
    pub length_unit: Option<f64>,
    /// `unknowns` (the columns of `A` and `B`).
    pub unknowns: Option<usize>,
    /// `rhs_columns` (the columns of `C` and `D`).
    pub rhs_columns: Option<usize>,
    /// The length of `constraint_of_b_row` (the rows of `B`).
    pub hard_rows: Option<usize>,
    /// The length of `constraint_of_soft_row` (the rows of `A` after the
    /// Laplacian).
    pub soft_rows: Option<usize>,
    /// `fingerprint` ([`system_fingerprint`]).
    pub fingerprint: Option<String>,
}

/// What `solve` takes from a `meta.json` besides checks, covered by its
/// fingerprint ([`system_fingerprint`]) with the matrices.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MetaUnits {
    /// `laplacian_rows`.
    pub laplacian_rows: usize,
    /// `length_scale`, the unit of the conflict tolerance.
    pub length_scale: f64,
    /// `length_unit`, the mesh length the problem's lengths are divided by.
    pub length_unit: f64,
}

impl ProblemMeta {
    /// The [`MetaUnits`] of this file, `None` when one is missing.
    pub fn units(&self) -> Option<MetaUnits> {
        Some(MetaUnits {
            laplacian_rows: self.laplacian_rows?,
            length_scale: self.length_scale?,
            length_unit: self.length_unit?,
        })
    }
}

/// The prefix of a [`system_fingerprint`].
const FINGERPRINT_PREFIX: &str = "fnv1a64-v2:";

/// The top-level object of a JSON text, a key repeated in it refused (a
/// reader that keeps the last value would use a value the file's
/// fingerprint may not have been made with).
struct UniqueKeys(serde_json::Map<String, serde_json::Value>);

impl<'de> serde::Deserialize<'de> for UniqueKeys {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<UniqueKeys, D::Error> {
        d.deserialize_any(UniqueKeysVisitor)
    }
}

/// The visitor of [`UniqueKeys`].
struct UniqueKeysVisitor;

impl<'de> serde::de::Visitor<'de> for UniqueKeysVisitor {
    type Value = UniqueKeys;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("a JSON object, as export-system writes")
    }

    fn visit_map<M: serde::de::MapAccess<'de>>(self, mut map: M) -> Result<UniqueKeys, M::Error> {
        let mut out = serde_json::Map::new();
        while let Some(key) = map.next_key::<String>()? {
            if out.contains_key(&key) {
                return Err(serde::de::Error::custom(format!(
                    "the key '{key}' appears twice"
                )));
            }
            let value = map.next_value()?;
            out.insert(key, value);
        }
        Ok(UniqueKeys(out))
    }
}

/// Reads the fields of [`ProblemMeta`] from a `meta.json`. An error naming
/// the file: a file that is not JSON, not an object, with a key repeated,
/// a field of the wrong type, or without a `fingerprint` of this version
/// ([`system_fingerprint`]) or one of the [`MetaUnits`] it covers — such a
/// file cannot be checked against the matrices, and the message says to
/// export the system again.
pub fn read_meta(path: &Path) -> Result<ProblemMeta, Error> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let bad = |message: String| -> Error { meta_error(path, message) };
    let UniqueKeys(value) = serde_json::from_str(&text).map_err(|e| {
        bad(match e.classify() {
            serde_json::error::Category::Data => e.to_string(),
            _ => format!("not JSON: {e}"),
        })
    })?;
    let present = |key: &str| value.get(key).filter(|v| !v.is_null());
    let count = |key: &str| -> Result<Option<usize>, Error> {
        present(key)
            .map(|v| {
                v.as_u64()
                    .and_then(|u| usize::try_from(u).ok())
                    .ok_or_else(|| bad(format!("'{key}' must be a non-negative integer")))
            })
            .transpose()
    };
    let length = |key: &str| -> Result<Option<usize>, Error> {
        present(key)
            .map(|v| {
                v.as_array()
                    .map(Vec::len)
                    .ok_or_else(|| bad(format!("'{key}' must be an array")))
            })
            .transpose()
    };
    let positive = |key: &str| -> Result<Option<f64>, Error> {
        present(key)
            .map(|v| {
                v.as_f64()
                    .filter(|s| s.is_finite() && *s > 0.0)
                    .ok_or_else(|| bad(format!("'{key}' must be a finite number > 0")))
            })
            .transpose()
    };
    let again = "export the system again (lse-deform export-system) so that it can be checked";
    let fingerprint = match present("fingerprint").map(serde_json::Value::as_str) {
        None => {
            return Err(bad(format!(
                "has no 'fingerprint': nothing in it can be verified against the matrices; {again}"
            )));
        }
        Some(None) => return Err(bad("'fingerprint' must be a string".into())),
        Some(Some(f)) if !f.starts_with(FINGERPRINT_PREFIX) => {
            return Err(bad(format!(
                "its fingerprint '{f}' is not of this version ({FINGERPRINT_PREFIX}…, which also covers laplacian_rows, length_scale and length_unit); {again}"
            )));
        }
        Some(Some(f)) => f.to_string(),
    };
    let meta = ProblemMeta {
        laplacian_rows: count("laplacian_rows")?,
        length_scale: positive("length_scale")?,
        length_unit: positive("length_unit")?,
        unknowns: count("unknowns")?,
        rhs_columns: count("rhs_columns")?,
        hard_rows: length("constraint_of_b_row")?,
        soft_rows: length("constraint_of_soft_row")?,
        fingerprint: Some(fingerprint),
    };
    for (key, given) in [
        ("laplacian_rows", meta.laplacian_rows.is_some()),
        ("length_scale", meta.length_scale.is_some()),
        ("length_unit", meta.length_unit.is_some()),
    ] {
        if !given {
            return Err(bad(format!(
                "has no '{key}', which its fingerprint covers; {again}"
            )));
        }
    }
    Ok(meta)
}

/// An error about the `meta.json` at `path`.
fn meta_error(path: &Path, message: String) -> Error {
    MatrixFileError {
        path: path.to_path_buf(),
        line: None,
        message,
    }
    .into()
}

/// Checks a `meta.json` (read from `path`) against the matrices it is to
/// describe, as read from their files: the counts it records (unknowns,
/// right-hand sides, rows of `B`, Laplacian and soft rows of `A`) and its
/// [`system_fingerprint`] of the matrices and its [`MetaUnits`]. A
/// meta.json left from another export, or edited, would otherwise change
/// the Laplacian rows, the length scale of the conflict test or the length
/// unit of the report without a word; any difference, and a file without
/// a fingerprint or units, is an error naming the file and what differs.
pub fn check_meta(
    meta: &ProblemMeta,
    path: &Path,
    a: SparseColMatRef<'_, usize, f64>,
    c: MatRef<'_, f64>,
    b: SparseColMatRef<'_, usize, f64>,
    d: MatRef<'_, f64>,
) -> Result<(), Error> {
    let counts = [
        ("unknowns", meta.unknowns, a.ncols(), "the columns of A"),
        (
            "rhs_columns",
            meta.rhs_columns,
            c.ncols(),
            "the columns of C",
        ),
        (
            "constraint_of_b_row",
            meta.hard_rows,
            b.nrows(),
            "the rows of B",
        ),
        (
            "laplacian_rows + constraint_of_soft_row",
            meta.laplacian_rows
                .and_then(|l| meta.soft_rows.map(|s| l.saturating_add(s))),
            a.nrows(),
            "the rows of A",
        ),
    ];
    for (key, recorded, actual, what) in counts {
        if let Some(recorded) = recorded
            && recorded != actual
        {
            return Err(meta_error(
                path,
                format!(
                    "written for another system: its {key} is {recorded}, {what} are {actual} (a meta.json left from another export?)"
                ),
            ));
        }
    }
    if let Some(rows) = meta.laplacian_rows
        && rows > a.nrows()
    {
        return Err(meta_error(
            path,
            format!(
                "laplacian_rows is {rows}, more than the {} rows of A",
                a.nrows()
            ),
        ));
    }
    let (Some(recorded), Some(units)) = (&meta.fingerprint, meta.units()) else {
        return Err(meta_error(
            path,
            "has no fingerprint, or not the units it covers: export the system again".into(),
        ));
    };
    let actual = system_fingerprint(a, c, b, d, &units);
    if *recorded != actual {
        return Err(meta_error(
            path,
            format!(
                "written for other matrices or units: its fingerprint is {recorded}, the matrices read with its laplacian_rows, length_scale and length_unit have {actual} (a meta.json left from another export, or the matrices or the file changed since)"
            ),
        ));
    }
    Ok(())
}

/// Applies a checked `meta.json` ([`check_meta`]) to `problem`, built by
/// [`LseProblem::from_parts`] from the same matrices: its Laplacian rows
/// and its length scale.
///
/// The length scale `s` is the unit of the conflict test: a skipped hard
/// row with a residual above `CONFLICT_RELATIVE_TOLERANCE · s` (`1e-8 s`,
/// [`crate::report::CONFLICT_RELATIVE_TOLERANCE`]) conflicts, below it is
/// redundant. The targets of `B` imply a size `s₀` of `X`
/// ([`LseProblem::length_scale`] of `from_parts`). A tolerance above `s₀`
/// would call every conflict between the targets redundant, and one below
/// their rounding, `ε s₀`, would call every redundant row conflicting; so
/// `s` must lie in `[ε s₀ / 1e-8, s₀ / 1e-8]`, else it is refused (an
/// error naming the file). An export of a mesh has `s` the bounding-box
/// diagonal and `s₀` the size of the constrained positions, well inside.
pub fn apply_meta(
    meta: &ProblemMeta,
    path: &Path,
    mut problem: LseProblem,
) -> Result<LseProblem, Error> {
    if let Some(rows) = meta.laplacian_rows {
        problem = problem.with_laplacian_rows(rows);
    }
    if let Some(scale) = meta.length_scale {
        let s0 = problem.length_scale();
        let tolerance = crate::report::CONFLICT_RELATIVE_TOLERANCE;
        let (low, high) = (f64::EPSILON * s0 / tolerance, s0 / tolerance);
        if !(low..=high).contains(&scale) {
            return Err(meta_error(
                path,
                format!(
                    "length_scale {scale:e} is implausible for these matrices: the targets of B imply a size of X of {s0:.3e}, and the conflict tolerance ({tolerance:e} of the length scale) must lie between their rounding and their size, so the length scale in [{low:.3e}, {high:.3e}]"
                ),
            ));
        }
        problem = problem.with_length_scale(scale);
    }
    Ok(problem)
}

/// The fingerprint of `A`, `C`, `B` and `D` of `min ‖AX − C‖ s.t. BX = D`
/// as written to (and read back from) Matrix Market files, and of the
/// [`MetaUnits`] `solve` reads beside them: 64-bit FNV-1a over each
/// matrix's shape and its nonzero entries `(row, column, bits of the
/// value)` in row-major order (stored zeros and the order of a file's
/// entries do not count; the writers give every value in shortest
/// round-trip form, so a value read back has the same bits), then the
/// Laplacian rows and the bits of the length scale and of the length unit.
/// `"fnv1a64-v2:"` and 16 hexadecimal digits. (`v1`, written before,
/// covered the matrices only.) A check against mix-ups and edits, not a
/// cryptographic signature.
pub fn system_fingerprint(
    a: SparseColMatRef<'_, usize, f64>,
    c: MatRef<'_, f64>,
    b: SparseColMatRef<'_, usize, f64>,
    d: MatRef<'_, f64>,
    units: &MetaUnits,
) -> String {
    let entries = |m: SparseColMatRef<'_, usize, f64>| -> Vec<(usize, usize, f64)> {
        m.triplet_iter().map(|t| (t.row, t.col, *t.val)).collect()
    };
    fingerprint(
        [
            ((a.nrows(), a.ncols()), entries(a)),
            ((b.nrows(), b.ncols()), entries(b)),
        ],
        [c, d],
        units,
    )
}

/// [`system_fingerprint`] of the matrices [`export_problem`] writes for
/// `problem` (`B` is held by rows) and `units`.
fn problem_fingerprint(problem: &LseProblem, units: &MetaUnits) -> String {
    let (a, b) = (problem.a().as_ref(), problem.b().as_ref());
    let b_entries = b.triplet_iter().map(|t| (t.row, t.col, *t.val)).collect();
    fingerprint(
        [
            (
                (a.nrows(), a.ncols()),
                a.triplet_iter().map(|t| (t.row, t.col, *t.val)).collect(),
            ),
            ((b.nrows(), b.ncols()), b_entries),
        ],
        [problem.c().as_ref(), problem.d().as_ref()],
        units,
    )
}

/// A sparse matrix as its shape and its `(row, column, value)` entries.
type SparseEntries = ((usize, usize), Vec<(usize, usize, f64)>);

/// The hash of [`system_fingerprint`]: the sparse `A` and `B` as shapes
/// and entries, then the dense `C` and `D`, then `units`.
fn fingerprint(
    sparse: [SparseEntries; 2],
    dense: [MatRef<'_, f64>; 2],
    units: &MetaUnits,
) -> String {
    let mut h = crate::mesh::fingerprint::Fnv1a::new();
    h.bytes(b"lse-deform system v2");
    for (shape, entries) in sparse {
        hash_entries(&mut h, shape, entries);
    }
    for m in dense {
        let entries = (0..m.ncols())
            .flat_map(|j| (0..m.nrows()).map(move |i| (i, j, m[(i, j)])))
            .collect();
        hash_entries(&mut h, (m.nrows(), m.ncols()), entries);
    }
    h.bytes(&(units.laplacian_rows as u64).to_le_bytes());
    h.bytes(&units.length_scale.to_bits().to_le_bytes());
    h.bytes(&units.length_unit.to_bits().to_le_bytes());
    format!("{FINGERPRINT_PREFIX}{:016x}", h.0)
}

/// Feeds a matrix's shape and its nonzero entries, sorted by row and then
/// column, into `h`.
fn hash_entries(
    h: &mut crate::mesh::fingerprint::Fnv1a,
    (rows, cols): (usize, usize),
    mut entries: Vec<(usize, usize, f64)>,
) {
    entries.retain(|e| e.2 != 0.0);
    entries.sort_unstable_by_key(|e| (e.0, e.1));
    for x in [rows, cols, entries.len()] {
        h.bytes(&(x as u64).to_le_bytes());
    }
    for (i, j, v) in entries {
        h.bytes(&(i as u64).to_le_bytes());
        h.bytes(&(j as u64).to_le_bytes());
        h.bytes(&v.to_bits().to_le_bytes());
    }
}
