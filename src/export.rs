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

use crate::choice::Method;
use crate::error::Error;
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

/// Writes `A`, `C`, `B`, `D` of `problem` and, if given, the matrix
/// `prepared` factored, into `dir` (created if missing). Existing files of
/// the same names are overwritten.
pub fn export_problem(
    dir: &Path,
    problem: &LseProblem,
    prepared: Option<&dyn Prepared>,
) -> Result<ExportedFiles, Error> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
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
/// - `method`, `qr_backend`, `spd_backend`, `penalty_weight`, `laplacian`,
///   `kkt_multiplier_scale` (null where they do not apply);
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
///   weight as given).
///
/// `lse-deform solve` reads `laplacian_rows` and `length_scale` back
/// ([`LseProblem::with_laplacian_rows`], [`LseProblem::with_length_scale`]),
/// so that the files solve to the same positions and the same report as
/// the mesh problem.
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
        "spd_backend": report.spd_backend,
        "penalty_weight": report.penalty_weight,
        "laplacian": report.laplacian,
        "kkt_multiplier_scale": report.kkt_multiplier_scale,
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
    });
    let path = dir.join(META_FILE);
    let text = serde_json::to_string_pretty(&meta).map_err(|e| Error::io(&path, e.into()))?;
    crate::atomic::write_bytes(&path, (text + "\n").as_bytes()).map_err(|e| Error::io(&path, e))?;
    Ok(path)
}

/// What `lse-deform solve` takes from a `meta.json`: the Laplacian rows and
/// the length scale (either may be absent).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ProblemMeta {
    /// `laplacian_rows`.
    pub laplacian_rows: Option<usize>,
    /// `length_scale`.
    pub length_scale: Option<f64>,
    /// `length_unit`: reports of the solve give lengths times it, as the
    /// mesh problem's report does.
    pub length_unit: Option<f64>,
}

/// Reads the fields of [`ProblemMeta`] from a `meta.json`; a file that is
/// not JSON, or a field of the wrong type, is an error naming the file.
pub fn read_meta(path: &Path) -> Result<ProblemMeta, Error> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let bad = |message: String| -> Error {
        crate::error::MatrixFileError {
            path: path.to_path_buf(),
            line: None,
            message,
        }
        .into()
    };
    let value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| bad(format!("not JSON: {e}")))?;
    let mut meta = ProblemMeta::default();
    match value.get("laplacian_rows") {
        None | Some(serde_json::Value::Null) => {}
        Some(v) => {
            meta.laplacian_rows = Some(
                v.as_u64()
                    .and_then(|u| usize::try_from(u).ok())
                    .ok_or_else(|| bad("'laplacian_rows' must be a non-negative integer".into()))?,
            )
        }
    }
    for (key, field) in [
        ("length_scale", &mut meta.length_scale),
        ("length_unit", &mut meta.length_unit),
    ] {
        match value.get(key) {
            None | Some(serde_json::Value::Null) => {}
            Some(v) => {
                *field = Some(
                    v.as_f64()
                        .filter(|s| s.is_finite() && *s > 0.0)
                        .ok_or_else(|| bad(format!("'{key}' must be a finite number > 0")))?,
                )
            }
        }
    }
    Ok(meta)
}
