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
//!
//! **Writers.** Sparse matrices go through `sprs`'s Matrix Market writer
//! (`sprs::io::write_matrix_market_to_bufwrite`, into a buffer we flush
//! ourselves so that no error is lost), which reports I/O failures as errors
//! (nalgebra-sparse's file writer `expect`s its final flush, i.e. panics on
//! a full disk) and prints values with Rust's shortest round-trip decimal
//! representation, so a file read back gives the same `f64` bit for bit.
//! Neither crate writes the dense `array` format, which is what makes
//! `mmread` return a dense array for `C` and `D`; a twenty-line writer
//! ([`write_dense`]) does, column-major as the format requires, with the
//! same round-trip formatting (`{:e}`). [`read_dense`] and [`read_sparse`]
//! read the files back.
//!
//! The factored matrix is written in full (both triangles, `general`) rather
//! than as a `symmetric` lower triangle: every reader then gets the matrix
//! itself, with no convention on which triangle is stored. Its unknown
//! order is the formulation's own (see [`Prepared::factored_matrix`]); for
//! KKT the multiplier rows are scaled by [`crate::Report::kkt_multiplier_scale`].

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

use faer::sparse::{SparseColMat, SparseColMatRef};
use faer::{Mat, MatRef};

use crate::error::Error;
use crate::formulation::Prepared;
use crate::interop::{faer_rows_to_sprs, faer_to_sprs, sprs_to_faer};
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

fn invalid(path: &Path, message: impl Into<String>) -> Error {
    Error::io(
        path,
        std::io::Error::new(std::io::ErrorKind::InvalidData, message.into()),
    )
}

fn sprs_error(path: &Path, e: sprs::io::IoError) -> Error {
    match e {
        sprs::io::IoError::Io(source) => Error::io(path, source),
        other => invalid(path, format!("Matrix Market: {other}")),
    }
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

/// Writes a sparse matrix as `%%MatrixMarket matrix coordinate real
/// general` (1-based indices, shortest round-trip values) with `sprs`.
pub fn write_sparse(path: &Path, m: SparseColMatRef<'_, usize, f64>) -> Result<(), Error> {
    write_sprs(path, &faer_to_sprs(m))
}

/// `sprs`'s writer into our own buffered file, flushed explicitly:
/// `sprs::io::write_matrix_market` drops its `BufWriter` without flushing,
/// which would lose an error on the last block (a full disk).
fn write_sprs(path: &Path, m: &sprs::CsMat<f64>) -> Result<(), Error> {
    let file = File::create(path).map_err(|e| Error::io(path, e))?;
    let mut w = BufWriter::new(file);
    sprs::io::write_matrix_market_to_bufwrite(&mut w, m).map_err(|e| Error::io(path, e))?;
    w.flush().map_err(|e| Error::io(path, e))
}

/// Reads a `coordinate` Matrix Market file (real; `general` or
/// `symmetric`, as `sprs` supports) into a faer CSC matrix; duplicate
/// entries are summed.
pub fn read_sparse(path: &Path) -> Result<SparseColMat<usize, f64>, Error> {
    let tri =
        sprs::io::read_matrix_market::<f64, usize, _>(path).map_err(|e| sprs_error(path, e))?;
    let csc: sprs::CsMat<f64> = tri.to_csc();
    Ok(sprs_to_faer(csc.view()))
}

/// Writes a dense matrix as `%%MatrixMarket matrix array real general`:
/// the dimensions, then every entry in column-major order, one per line,
/// in Rust's shortest round-trip exponent notation.
pub fn write_dense(path: &Path, m: MatRef<'_, f64>) -> Result<(), Error> {
    let file = File::create(path).map_err(|e| Error::io(path, e))?;
    let mut w = BufWriter::new(file);
    let io = |e| Error::io(path, e);
    writeln!(w, "%%MatrixMarket matrix array real general").map_err(io)?;
    writeln!(w, "% written by lse-deform").map_err(io)?;
    writeln!(w, "{} {}", m.nrows(), m.ncols()).map_err(io)?;
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            writeln!(w, "{:e}", m[(i, j)]).map_err(io)?;
        }
    }
    w.flush().map_err(io)
}

/// Reads an `array real general` Matrix Market file (as written by
/// [`write_dense`], or by SciPy's `mmwrite` for a dense array).
pub fn read_dense(path: &Path) -> Result<Mat<f64>, Error> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let mut lines = BufReader::new(file).lines().enumerate();
    let (_, header) = lines.next().ok_or_else(|| invalid(path, "empty file"))?;
    let header = header.map_err(|e| Error::io(path, e))?.to_ascii_lowercase();
    let fields: Vec<&str> = header.split_whitespace().collect();
    if fields.len() != 5
        || fields[0] != "%%matrixmarket"
        || fields[1] != "matrix"
        || fields[2] != "array"
        || fields[3] != "real"
        || fields[4] != "general"
    {
        return Err(invalid(
            path,
            format!(
                "line 1: expected '%%MatrixMarket matrix array real general', found '{header}'"
            ),
        ));
    }
    let mut size: Option<(usize, usize)> = None;
    let mut values = Vec::new();
    for (number, line) in lines {
        let line = line.map_err(|e| Error::io(path, e))?;
        let text = line.trim();
        if text.is_empty() || text.starts_with('%') {
            continue;
        }
        let bad = |what: &str| invalid(path, format!("line {}: {what}: '{text}'", number + 1));
        match size {
            None => {
                let dims: Vec<usize> = text
                    .split_whitespace()
                    .map(|t| t.parse::<usize>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| bad("expected the dimensions 'rows cols'"))?;
                if dims.len() != 2 {
                    return Err(bad("expected the dimensions 'rows cols'"));
                }
                let total = dims[0]
                    .checked_mul(dims[1])
                    .ok_or_else(|| bad("dimensions overflow"))?;
                values.reserve(total.min(1 << 24));
                size = Some((dims[0], dims[1]));
            }
            Some((r, c)) => {
                if values.len() == r * c {
                    return Err(bad("more values than rows × cols"));
                }
                let v: f64 = text.parse().map_err(|_| bad("expected one real value"))?;
                values.push(v);
            }
        }
    }
    let (r, c) = size.ok_or_else(|| invalid(path, "no dimension line"))?;
    if values.len() != r * c {
        return Err(invalid(
            path,
            format!("{} values for a {r} × {c} matrix", values.len()),
        ));
    }
    Ok(Mat::from_fn(r, c, |i, j| values[j * r + i]))
}
