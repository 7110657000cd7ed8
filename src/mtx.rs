//! Matrix Market files (`.mtx`): the reader behind `lse-deform solve` and
//! the writers behind `export-system` — what MATLAB's `mmread`/`mmwrite`
//! and SciPy's `scipy.io.mmread`/`mmwrite` exchange.
//!
//! **Reader** ([`read_matrix`]). Accepts the header
//! `%%MatrixMarket matrix FORMAT FIELD SYMMETRY` (case-insensitive) with
//! - `FORMAT` `coordinate` (sparse: `rows cols entries`, then one
//!   `row col [value]` line per entry, 1-based) or `array` (dense:
//!   `rows cols`, then the values column by column);
//! - `FIELD` `real`, `double` or `integer` (`pattern`: coordinate only,
//!   every value 1); `complex` is refused;
//! - `SYMMETRY` `general`, `symmetric` (the lower triangle is stored; the
//!   upper is its mirror) or `skew-symmetric` (mirror negated, no diagonal);
//!   for `array` only `general`.
//!
//! Comment (`%`) and blank lines are skipped anywhere after the header.
//! Everything else is checked and refused with a
//! [`MatrixFileError`] naming the file and the 1-based line: a bad header,
//! missing or extra numbers, indices out of range, non-finite values
//! (NaN, `inf`), more or fewer entries than the size line announces,
//! non-UTF-8 text. Duplicate coordinate entries are summed (the convention
//! of MATLAB and SciPy). Sizes are checked against the memory budget
//! ([`crate::limits`]) before anything is allocated for them. The reader
//! never panics, whatever the bytes.
//!
//! **Writers.** Sparse matrices go through `sprs`'s Matrix Market writer
//! (`sprs::io::write_matrix_market_to_bufwrite`, into a buffer we flush
//! ourselves so that no error is lost), which prints values with Rust's
//! shortest round-trip decimal representation, so a file read back gives
//! the same `f64` bit for bit. Dense matrices ([`write_dense`]) are written
//! in the `array` format (what makes `mmread` return a dense array),
//! column-major, with the same round-trip formatting (`{:e}`).

use std::fs::File;
use std::io::{BufRead, BufReader, Write};
use std::path::Path;

use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat, Triplet};
use faer::{Mat, MatRef};

use crate::error::{Error, MatrixFileError, ProblemError};
use crate::interop::faer_to_sprs;

/// A matrix read from a Matrix Market file, in the form the file has.
#[derive(Debug, Clone)]
pub enum MatrixFile {
    /// A `coordinate` file.
    Sparse(SparseColMat<usize, f64>),
    /// An `array` file.
    Dense(Mat<f64>),
}

/// Bytes per stored entry while reading a coordinate file: the triplet
/// (two indices and a value) and the compressed copy built from it.
const BYTES_PER_SPARSE_ENTRY: u64 = 48;

impl MatrixFile {
    /// `(rows, cols)`.
    pub fn shape(&self) -> (usize, usize) {
        match self {
            MatrixFile::Sparse(m) => (m.nrows(), m.ncols()),
            MatrixFile::Dense(m) => (m.nrows(), m.ncols()),
        }
    }

    /// The matrix as a sparse one (a dense file's zeros are not stored).
    pub fn into_sparse(self) -> SparseColMat<usize, f64> {
        match self {
            MatrixFile::Sparse(m) => m,
            MatrixFile::Dense(m) => {
                let mut col_ptr = vec![0usize];
                let (mut rows, mut vals) = (Vec::new(), Vec::new());
                for j in 0..m.ncols() {
                    for i in 0..m.nrows() {
                        if m[(i, j)] != 0.0 {
                            rows.push(i);
                            vals.push(m[(i, j)]);
                        }
                    }
                    col_ptr.push(rows.len());
                }
                SparseColMat::new(
                    SymbolicSparseColMat::new_checked(m.nrows(), m.ncols(), col_ptr, None, rows),
                    vals,
                )
            }
        }
    }

    /// The matrix as a dense one; a sparse file is expanded after a check of
    /// `rows × cols × 8` bytes against the memory budget.
    pub fn into_dense(self, path: &Path) -> Result<Mat<f64>, Error> {
        match self {
            MatrixFile::Dense(m) => Ok(m),
            MatrixFile::Sparse(m) => {
                check_memory(
                    path,
                    (m.nrows() as u64)
                        .saturating_mul(m.ncols() as u64)
                        .saturating_mul(8),
                )?;
                Ok(m.to_dense())
            }
        }
    }
}

fn check_memory(path: &Path, bytes: u64) -> Result<(), Error> {
    crate::limits::check(bytes, || format!("the matrix of {}", path.display()))
        .map_err(|detail| ProblemError::TooLarge { detail }.into())
}

/// Format, field and symmetry of a header.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Symmetry {
    General,
    Symmetric,
    Skew,
}

/// Reads a Matrix Market file (see the module documentation).
pub fn read_matrix(path: &Path) -> Result<MatrixFile, Error> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    read_matrix_from(BufReader::new(file), path)
}

/// [`read_matrix`] from any reader; `path` names it in errors.
pub fn read_matrix_from(reader: impl BufRead, path: &Path) -> Result<MatrixFile, Error> {
    let mut lines = Lines {
        inner: reader.lines(),
        number: 0,
        path,
    };
    let err = |line: Option<usize>, message: String| -> Error {
        MatrixFileError {
            path: path.to_path_buf(),
            line,
            message,
        }
        .into()
    };
    let header = lines.next_raw()?.ok_or_else(|| {
        err(
            None,
            "empty file (expected the header '%%MatrixMarket matrix …')".into(),
        )
    })?;
    let lower = header.to_ascii_lowercase();
    let fields: Vec<&str> = lower.split_whitespace().collect();
    if fields.len() != 5 || fields[0] != "%%matrixmarket" || fields[1] != "matrix" {
        return Err(err(
            Some(1),
            format!(
                "expected the header '%%MatrixMarket matrix FORMAT FIELD SYMMETRY', found '{}'",
                truncate(&header)
            ),
        ));
    }
    let sparse = match fields[2] {
        "coordinate" => true,
        "array" => false,
        other => {
            return Err(err(
                Some(1),
                format!("format '{other}': expected coordinate or array"),
            ));
        }
    };
    let pattern = match fields[3] {
        "real" | "double" | "integer" => false,
        "pattern" if sparse => true,
        "pattern" => {
            return Err(err(
                Some(1),
                "field 'pattern' needs the coordinate format".into(),
            ));
        }
        "complex" => {
            return Err(err(
                Some(1),
                "complex matrices are not supported (real, integer or pattern only)".into(),
            ));
        }
        other => {
            return Err(err(
                Some(1),
                format!("field '{other}': expected real, integer or pattern"),
            ));
        }
    };
    let symmetry = match fields[4] {
        "general" => Symmetry::General,
        "symmetric" if sparse => Symmetry::Symmetric,
        "skew-symmetric" if sparse => Symmetry::Skew,
        "symmetric" | "skew-symmetric" | "hermitian" if !sparse => {
            return Err(err(
                Some(1),
                format!(
                    "{} arrays are not supported (write the full matrix as 'array real general')",
                    fields[4]
                ),
            ));
        }
        other => {
            return Err(err(
                Some(1),
                format!("symmetry '{other}': expected general, symmetric or skew-symmetric"),
            ));
        }
    };
    let (size_line, size) = lines
        .next_data()?
        .ok_or_else(|| err(None, "no size line".into()))?;
    let dims = parse_counts(&size).ok_or_else(|| {
        err(
            Some(size_line),
            format!(
                "expected the size line '{}', found '{}'",
                if sparse {
                    "rows cols entries"
                } else {
                    "rows cols"
                },
                truncate(&size)
            ),
        )
    })?;
    if dims.len() != if sparse { 3 } else { 2 } {
        return Err(err(
            Some(size_line),
            format!(
                "expected {} numbers on the size line, found {}",
                if sparse { 3 } else { 2 },
                dims.len()
            ),
        ));
    }
    let (rows, cols) = (dims[0], dims[1]);
    if symmetry != Symmetry::General && rows != cols {
        return Err(err(
            Some(size_line),
            format!(
                "a {} matrix must be square, this one is {rows} × {cols}",
                fields[4]
            ),
        ));
    }
    if sparse {
        read_coordinate(
            &mut lines, rows, cols, dims[2], pattern, symmetry, size_line,
        )
    } else {
        read_array(&mut lines, rows, cols, size_line)
    }
}

fn truncate(s: &str) -> String {
    match s.char_indices().nth(80) {
        Some((i, _)) => format!("{}…", &s[..i]),
        None => s.to_string(),
    }
}

/// Non-negative integers separated by whitespace, or `None`.
fn parse_counts(s: &str) -> Option<Vec<usize>> {
    s.split_whitespace()
        .map(|t| t.parse::<usize>().ok())
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn read_coordinate(
    lines: &mut Lines<'_, impl BufRead>,
    rows: usize,
    cols: usize,
    entries: usize,
    pattern: bool,
    symmetry: Symmetry,
    size_line: usize,
) -> Result<MatrixFile, Error> {
    let path = lines.path;
    // A symmetric or skew-symmetric file stores each off-diagonal entry
    // once and its mirror is added: up to twice the announced count, which
    // may be anything up to 2⁶⁴ − 1 (saturating: the budget refuses it).
    let stored = if symmetry == Symmetry::General {
        entries as u64
    } else {
        (entries as u64).saturating_mul(2)
    };
    check_memory(
        path,
        stored
            .saturating_mul(BYTES_PER_SPARSE_ENTRY)
            .saturating_add((cols as u64).saturating_mul(8)),
    )?;
    let mut triplets = Vec::with_capacity(stored.min(1 << 20) as usize);
    let mut count = 0usize;
    while let Some((line, text)) = lines.next_data()? {
        let bad = |message: String| -> Error { lines.error(Some(line), message) };
        if count == entries {
            return Err(bad(format!(
                "more entries than the {entries} the size line (line {size_line}) announces"
            )));
        }
        let tokens: Vec<&str> = text.split_whitespace().collect();
        let expected = if pattern { 2 } else { 3 };
        if tokens.len() != expected {
            return Err(bad(format!(
                "expected '{}', found {} item(s): '{}'",
                if pattern { "row col" } else { "row col value" },
                tokens.len(),
                truncate(&text)
            )));
        }
        let index = |t: &str, what: &str, max: usize| -> Result<usize, Error> {
            match t.parse::<usize>() {
                Ok(i) if (1..=max).contains(&i) => Ok(i - 1),
                _ => Err(lines.error(
                    Some(line),
                    format!("{what} index '{}' is not in 1..={max}", truncate(t)),
                )),
            }
        };
        let (i, j) = (
            index(tokens[0], "row", rows)?,
            index(tokens[1], "column", cols)?,
        );
        let value = if pattern {
            1.0
        } else {
            parse_value(tokens[2]).map_err(&bad)?
        };
        match symmetry {
            Symmetry::General => triplets.push(Triplet::new(i, j, value)),
            Symmetry::Symmetric | Symmetry::Skew => {
                if i < j {
                    return Err(bad(format!(
                        "entry ({}, {}) is above the diagonal: a {} file stores the lower triangle",
                        i + 1,
                        j + 1,
                        if symmetry == Symmetry::Skew {
                            "skew-symmetric"
                        } else {
                            "symmetric"
                        }
                    )));
                }
                if i == j && symmetry == Symmetry::Skew {
                    return Err(bad(format!(
                        "diagonal entry ({0}, {0}) in a skew-symmetric file (its diagonal is zero)",
                        i + 1
                    )));
                }
                triplets.push(Triplet::new(i, j, value));
                if i != j {
                    let mirror = if symmetry == Symmetry::Skew {
                        -value
                    } else {
                        value
                    };
                    triplets.push(Triplet::new(j, i, mirror));
                }
            }
        }
        count += 1;
    }
    if count != entries {
        return Err(lines.error(
            None,
            format!("{count} entries, but the size line (line {size_line}) announces {entries}"),
        ));
    }
    SparseColMat::try_new_from_triplets(rows, cols, &triplets)
        .map(MatrixFile::Sparse)
        .map_err(|e| lines.error(None, format!("cannot build the matrix: {e:?}")))
}

fn read_array(
    lines: &mut Lines<'_, impl BufRead>,
    rows: usize,
    cols: usize,
    size_line: usize,
) -> Result<MatrixFile, Error> {
    let path = lines.path;
    let total = (rows as u64).saturating_mul(cols as u64);
    check_memory(path, total.saturating_mul(8))?;
    let total = usize::try_from(total)
        .map_err(|_| lines.error(Some(size_line), "rows × cols overflows".into()))?;
    let mut values = Vec::with_capacity(total.min(1 << 24));
    while let Some((line, text)) = lines.next_data()? {
        for token in text.split_whitespace() {
            if values.len() == total {
                return Err(lines.error(
                    Some(line),
                    format!("more values than rows × cols = {total} (size line {size_line})"),
                ));
            }
            values.push(parse_value(token).map_err(|m| lines.error(Some(line), m))?);
        }
    }
    if values.len() != total {
        return Err(lines.error(
            None,
            format!(
                "{} values for a {rows} × {cols} matrix (expected {total})",
                values.len()
            ),
        ));
    }
    Ok(MatrixFile::Dense(Mat::from_fn(rows, cols, |i, j| {
        values[j * rows + i]
    })))
}

fn parse_value(t: &str) -> Result<f64, String> {
    match t.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(format!("value '{}' is not finite", truncate(t))),
        Err(_) => Err(format!("'{}' is not a number", truncate(t))),
    }
}

/// Lines with their 1-based numbers; I/O and UTF-8 errors become errors
/// naming the line.
struct Lines<'p, R: BufRead> {
    inner: std::io::Lines<R>,
    number: usize,
    path: &'p Path,
}

impl<R: BufRead> Lines<'_, R> {
    fn error(&self, line: Option<usize>, message: String) -> Error {
        MatrixFileError {
            path: self.path.to_path_buf(),
            line,
            message,
        }
        .into()
    }

    fn next_raw(&mut self) -> Result<Option<String>, Error> {
        match self.inner.next() {
            None => Ok(None),
            Some(Ok(s)) => {
                self.number += 1;
                Ok(Some(s))
            }
            Some(Err(e)) => {
                self.number += 1;
                Err(self.error(Some(self.number), format!("cannot read the line: {e}")))
            }
        }
    }

    /// The next line that is neither blank nor a comment, trimmed.
    fn next_data(&mut self) -> Result<Option<(usize, String)>, Error> {
        while let Some(s) = self.next_raw()? {
            let t = s.trim();
            if !t.is_empty() && !t.starts_with('%') {
                return Ok(Some((self.number, t.to_string())));
            }
        }
        Ok(None)
    }
}

/// Reads a file that must hold a sparse matrix (an `array` file is
/// converted).
pub fn read_sparse(path: &Path) -> Result<SparseColMat<usize, f64>, Error> {
    Ok(read_matrix(path)?.into_sparse())
}

/// Reads a file that must hold a dense matrix (a `coordinate` file is
/// expanded).
pub fn read_dense(path: &Path) -> Result<Mat<f64>, Error> {
    read_matrix(path)?.into_dense(path)
}

/// Writes a sparse matrix as `%%MatrixMarket matrix coordinate real
/// general` (1-based indices, shortest round-trip values) with `sprs`.
pub fn write_sparse(path: &Path, m: SparseColMatRef<'_, usize, f64>) -> Result<(), Error> {
    write_sprs(path, &faer_to_sprs(m))
}

/// `sprs`'s writer into our own buffered file, written atomically
/// ([`crate::atomic`]; the buffer is flushed there, so an error on the last
/// block — a full disk — is not lost, as it would be in
/// `sprs::io::write_matrix_market`, which drops its `BufWriter` unflushed).
pub(crate) fn write_sprs(path: &Path, m: &sprs::CsMat<f64>) -> Result<(), Error> {
    crate::atomic::write(path, |w| sprs::io::write_matrix_market_to_bufwrite(w, m))
        .map_err(|e| Error::io(path, e))
}

/// Writes a dense matrix as `%%MatrixMarket matrix array real general`:
/// the dimensions, then every entry in column-major order, one per line,
/// in Rust's shortest round-trip exponent notation. Atomically
/// ([`crate::atomic`]): on an error a previous file is left as it was.
pub fn write_dense(path: &Path, m: MatRef<'_, f64>) -> Result<(), Error> {
    crate::atomic::write(path, |w| {
        writeln!(w, "%%MatrixMarket matrix array real general")?;
        writeln!(w, "% written by lse-deform")?;
        writeln!(w, "{} {}", m.nrows(), m.ncols())?;
        for j in 0..m.ncols() {
            for i in 0..m.nrows() {
                writeln!(w, "{:e}", m[(i, j)])?;
            }
        }
        Ok(())
    })
    .map_err(|e| Error::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<MatrixFile, Error> {
        read_matrix_from(text.as_bytes(), Path::new("m.mtx"))
    }

    fn line_of(e: Error) -> Option<usize> {
        match e {
            Error::MatrixFile(f) => f.line,
            other => panic!("not a matrix file error: {other}"),
        }
    }

    #[test]
    fn reads_coordinate_symmetric_skew_pattern_and_array() {
        let m = read("%%MatrixMarket matrix coordinate real general\n% c\n\n2 3 3\n1 1 2.5\n2 3 -1\n1 1 0.5\n").unwrap().into_sparse().to_dense();
        assert_eq!((m[(0, 0)], m[(1, 2)], m[(0, 1)]), (3.0, -1.0, 0.0));
        let s = read("%%MatrixMarket matrix coordinate real symmetric\n2 2 2\n1 1 4\n2 1 1\n")
            .unwrap()
            .into_sparse()
            .to_dense();
        assert_eq!((s[(0, 1)], s[(1, 0)], s[(0, 0)]), (1.0, 1.0, 4.0));
        let k = read("%%MatrixMarket matrix coordinate integer skew-symmetric\n2 2 1\n2 1 3\n")
            .unwrap()
            .into_sparse()
            .to_dense();
        assert_eq!((k[(1, 0)], k[(0, 1)]), (3.0, -3.0));
        let p = read("%%MatrixMarket matrix coordinate pattern general\n2 2 1\n2 2\n")
            .unwrap()
            .into_sparse()
            .to_dense();
        assert_eq!(p[(1, 1)], 1.0);
        let d = read("%%matrixmarket MATRIX array real general\n2 2\n1\n2\n3 4\n")
            .unwrap()
            .into_dense(Path::new("m"))
            .unwrap();
        assert_eq!(
            (d[(0, 0)], d[(1, 0)], d[(0, 1)], d[(1, 1)]),
            (1.0, 2.0, 3.0, 4.0)
        );
    }

    #[test]
    fn refuses_bad_files_naming_the_line() {
        let cases: &[(&str, Option<usize>)] = &[
            ("", None),
            (
                "%%MatrixMarket matrix coordinate complex general\n1 1 1\n1 1 1 0\n",
                Some(1),
            ),
            ("%%MatrixMarket tensor coordinate real general\n", Some(1)),
            (
                "%%MatrixMarket matrix coordinate real general\n2 2\n",
                Some(2),
            ),
            (
                "%%MatrixMarket matrix coordinate real general\n2 2 1\n3 1 1.0\n",
                Some(3),
            ),
            (
                "%%MatrixMarket matrix coordinate real general\n2 2 1\n0 1 1.0\n",
                Some(3),
            ),
            (
                "%%MatrixMarket matrix coordinate real general\n2 2 1\n1 1 nan\n",
                Some(3),
            ),
            (
                "%%MatrixMarket matrix coordinate real general\n2 2 1\n1 1 1e999\n",
                Some(3),
            ),
            (
                "%%MatrixMarket matrix coordinate real general\n2 2 1\n1 1\n",
                Some(3),
            ),
            (
                "%%MatrixMarket matrix coordinate real general\n2 2 1\n1 1 1 1\n",
                Some(3),
            ),
            (
                "%%MatrixMarket matrix coordinate real general\n2 2 1\n1 1 1\n2 2 2\n",
                Some(4),
            ),
            (
                "%%MatrixMarket matrix coordinate real general\n2 2 2\n1 1 1\n",
                None,
            ),
            (
                "%%MatrixMarket matrix coordinate real symmetric\n2 2 1\n1 2 1\n",
                Some(3),
            ),
            (
                "%%MatrixMarket matrix coordinate real symmetric\n2 3 0\n",
                Some(2),
            ),
            (
                "%%MatrixMarket matrix array real general\n2 1\n1\n2\n3\n",
                Some(5),
            ),
            ("%%MatrixMarket matrix array real general\n2 1\n1\n", None),
            (
                "%%MatrixMarket matrix array real general\n2 1\nx\n2\n",
                Some(3),
            ),
            ("%%MatrixMarket matrix array real symmetric\n2 2\n", Some(1)),
            (
                "%%MatrixMarket matrix coordinate real general\n-2 2 1\n",
                Some(2),
            ),
        ];
        for (text, line) in cases {
            let e = read(text).unwrap_err();
            let message = e.to_string();
            assert!(message.starts_with("m.mtx"), "{message}");
            assert_eq!(line_of(e), *line, "{text:?}: {message}");
        }
        // Not UTF-8.
        let e = read_matrix_from(
            &b"%%MatrixMarket matrix array real general\n1 1\n\xff\n"[..],
            Path::new("m"),
        )
        .unwrap_err();
        assert_eq!(line_of(e), Some(3));
    }

    #[test]
    fn a_size_beyond_the_memory_budget_is_refused_before_allocating() {
        let e =
            read("%%MatrixMarket matrix array real general\n4000000000 4000000000\n").unwrap_err();
        assert!(
            matches!(e, Error::Problem(ProblemError::TooLarge { .. })),
            "{e}"
        );
        let e = read("%%MatrixMarket matrix coordinate real general\n1 1 18446744073709551615\n")
            .unwrap_err();
        assert!(
            matches!(e, Error::Problem(ProblemError::TooLarge { .. })),
            "{e}"
        );
        // A symmetric or skew header announcing more than 2⁶³ entries: the
        // doubled count overflowed (a panic in debug builds) before the
        // budget could refuse it.
        for symmetry in ["symmetric", "skew-symmetric"] {
            for entries in ["9223372036854775808", "18446744073709551615"] {
                let text =
                    format!("%%MatrixMarket matrix coordinate real {symmetry}\n2 2 {entries}\n");
                let e = read(&text).unwrap_err();
                assert!(
                    matches!(e, Error::Problem(ProblemError::TooLarge { .. })),
                    "{symmetry}, {entries}: {e}"
                );
            }
        }
    }
}
