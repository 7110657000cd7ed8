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
//! Lines end at `\n`, `\r\n` or a lone `\r`; a leading UTF-8 byte-order
//! mark is skipped. Everything else is checked and refused with a
//! [`MatrixFileError`] naming the file and the 1-based line: a bad header,
//! missing or extra numbers, indices out of range, non-finite values
//! (NaN, `inf`), more or fewer entries than the size line announces,
//! non-UTF-8 text. Duplicate coordinate entries are summed (the convention
//! of MATLAB and SciPy). Sizes are checked against the memory budget
//! ([`crate::limits`]) before anything is allocated for them, and what is
//! read is bounded whatever the source (a stream such as `/dev/zero` is
//! refused, not read to exhaustion): a line is at most [`MAX_LINE_BYTES`],
//! the file at most 256 bytes per announced value besides 16 MiB of header
//! and comments. [`read_system`] reads the four files of `solve`, checking
//! their headers together (shapes, entries, memory) before any entry. The
//! reader never panics, whatever the bytes.
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
use crate::limits::MemoryBudget;

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
    pub(crate) fn into_sparse(self) -> SparseColMat<usize, f64> {
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
    pub(crate) fn into_dense(self, path: &Path) -> Result<Mat<f64>, Error> {
        self.into_dense_budgeted(path, MemoryBudget::default())
    }

    /// [`MatrixFile::into_dense`] within `budget`.
    fn into_dense_budgeted(self, path: &Path, budget: MemoryBudget) -> Result<Mat<f64>, Error> {
        match self {
            MatrixFile::Dense(m) => Ok(m),
            MatrixFile::Sparse(m) => {
                check_memory(
                    path,
                    (m.nrows() as u64)
                        .saturating_mul(m.ncols() as u64)
                        .saturating_mul(8),
                    budget,
                )?;
                Ok(m.to_dense())
            }
        }
    }
}

fn check_memory(path: &Path, bytes: u64, budget: MemoryBudget) -> Result<(), Error> {
    budget
        .check(bytes, || format!("the matrix of {}", path.display()))
        .map_err(|detail| ProblemError::TooLarge { detail }.into())
}

/// Format, field and symmetry of a header.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Symmetry {
    General,
    Symmetric,
    Skew,
}

/// What a Matrix Market file's first lines (header and size line) say,
/// before any entry is read: enough to check shapes and memory first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MatrixHeader {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// `coordinate`: the entries its size line announces; `array`: `None`.
    pub entries: Option<usize>,
    /// `symmetric` or `skew-symmetric`: each entry off the diagonal stands
    /// for two.
    pub symmetric: bool,
}

impl MatrixHeader {
    /// The most nonzeros the matrix can have: the announced entries (twice
    /// for a symmetric file), or rows × cols for an array.
    pub(crate) fn max_nonzeros(&self) -> u64 {
        match self.entries {
            Some(e) if self.symmetric => (e as u64).saturating_mul(2),
            Some(e) => e as u64,
            None => (self.rows as u64).saturating_mul(self.cols as u64),
        }
    }

    /// Bytes of reading the file into the form it has: the entries and
    /// their compressed copy ([`BYTES_PER_SPARSE_ENTRY`] each) and the
    /// column pointers, or the dense array.
    fn read_bytes(&self) -> u64 {
        match self.entries {
            Some(_) => self
                .max_nonzeros()
                .saturating_mul(BYTES_PER_SPARSE_ENTRY)
                .saturating_add((self.cols as u64).saturating_add(1).saturating_mul(8)),
            None => self.dense_bytes(),
        }
    }

    /// Bytes of the matrix as a dense one.
    fn dense_bytes(&self) -> u64 {
        (self.rows as u64)
            .saturating_mul(self.cols as u64)
            .saturating_mul(8)
    }
}

/// A file whose header and size line have been read; the entries next.
struct Opened<'p, R: BufRead> {
    lines: Lines<'p, R>,
    header: MatrixHeader,
    pattern: bool,
    symmetry: Symmetry,
    size_line: usize,
}

/// Reads a Matrix Market file (see the module documentation).
pub(crate) fn read_matrix(path: &Path) -> Result<MatrixFile, Error> {
    let file = crate::input::open_input(path).map_err(|e| Error::io(path, e))?;
    read_matrix_from(BufReader::new(file), path)
}

/// [`read_matrix`] from any reader; `path` names it in errors.
pub fn read_matrix_from(reader: impl BufRead, path: &Path) -> Result<MatrixFile, Error> {
    open(reader, path)?.read_entries(MemoryBudget::default())
}

/// Reads the header and the size line: the banner ([`parse_banner`]) and
/// the sizes ([`parse_size_line`]); then allows the rest of the file the
/// bytes its entries may take.
fn open<R: BufRead>(reader: R, path: &Path) -> Result<Opened<'_, R>, Error> {
    let mut lines = Lines::new(reader, path);
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
    let banner = parse_banner(&header).map_err(|m| err(Some(1), m))?;
    let (size_line, size) = lines
        .next_data()?
        .ok_or_else(|| err(None, "no size line".into()))?;
    let header = parse_size_line(&size, &banner).map_err(|m| err(Some(size_line), m))?;
    // The rest of the file may hold this many bytes: the entries' lines (a
    // stream that goes on beyond is refused, not read to exhaustion).
    let values = header.entries.map_or(header.max_nonzeros(), |e| e as u64);
    lines.allow(values.saturating_mul(MAX_BYTES_PER_VALUE));
    Ok(Opened {
        lines,
        header,
        pattern: banner.pattern,
        symmetry: banner.symmetry,
        size_line,
    })
}

/// What the header line `%%MatrixMarket matrix FORMAT FIELD SYMMETRY`
/// says (words case-insensitive).
#[derive(Debug, PartialEq)]
struct Banner {
    /// `coordinate` (else `array`).
    sparse: bool,
    /// Field `pattern`: entries without values.
    pattern: bool,
    symmetry: Symmetry,
    /// The symmetry word as written (lower case), for messages.
    symmetry_word: String,
}

/// Parses the header line (a leading byte-order mark, which Windows
/// editors write, ignored). Supported: coordinate or array; real, double,
/// integer or (coordinate only) pattern; general, or (coordinate only)
/// symmetric or skew-symmetric. The error is the message for line 1.
fn parse_banner(header: &str) -> Result<Banner, String> {
    let header = header.strip_prefix('\u{feff}').unwrap_or(header);
    let lower = header.to_ascii_lowercase();
    let fields: Vec<&str> = lower.split_whitespace().collect();
    if fields.len() != 5 || fields[0] != "%%matrixmarket" || fields[1] != "matrix" {
        return Err(format!(
            "expected the header '%%MatrixMarket matrix FORMAT FIELD SYMMETRY', found '{}'",
            crate::error::excerpt(header)
        ));
    }
    let sparse = match fields[2] {
        "coordinate" => true,
        "array" => false,
        other => return Err(format!("format '{other}': expected coordinate or array")),
    };
    let pattern = match fields[3] {
        "real" | "double" | "integer" => false,
        "pattern" if sparse => true,
        "pattern" => return Err("field 'pattern' needs the coordinate format".into()),
        "complex" => {
            return Err(
                "complex matrices are not supported (real, integer or pattern only)".into(),
            );
        }
        other => {
            return Err(format!(
                "field '{other}': expected real, integer or pattern"
            ));
        }
    };
    let symmetry = match fields[4] {
        "general" => Symmetry::General,
        "symmetric" if sparse => Symmetry::Symmetric,
        "skew-symmetric" if sparse => Symmetry::Skew,
        "symmetric" | "skew-symmetric" | "hermitian" if !sparse => {
            return Err(format!(
                "{} arrays are not supported (write the full matrix as 'array real general')",
                fields[4]
            ));
        }
        other => {
            return Err(format!(
                "symmetry '{other}': expected general, symmetric or skew-symmetric"
            ));
        }
    };
    Ok(Banner {
        sparse,
        pattern,
        symmetry,
        symmetry_word: fields[4].to_string(),
    })
}

/// Parses the size line `size` under `banner`: `rows cols entries`
/// (coordinate) or `rows cols` (array); a symmetric matrix must be square.
/// The error is the message for the size line.
fn parse_size_line(size: &str, banner: &Banner) -> Result<MatrixHeader, String> {
    let sparse = banner.sparse;
    let dims = parse_counts(size).ok_or_else(|| {
        format!(
            "expected the size line '{}', found '{}'",
            if sparse {
                "rows cols entries"
            } else {
                "rows cols"
            },
            crate::error::excerpt(size)
        )
    })?;
    if dims.len() != if sparse { 3 } else { 2 } {
        return Err(format!(
            "expected {} numbers on the size line, found {}",
            if sparse { 3 } else { 2 },
            dims.len()
        ));
    }
    let (rows, cols) = (dims[0], dims[1]);
    if banner.symmetry != Symmetry::General && rows != cols {
        return Err(format!(
            "a {} matrix must be square, this one is {rows} × {cols}",
            banner.symmetry_word
        ));
    }
    Ok(MatrixHeader {
        rows,
        cols,
        entries: sparse.then(|| dims[2]),
        symmetric: banner.symmetry != Symmetry::General,
    })
}

impl<R: BufRead> Opened<'_, R> {
    /// Reads the entries (after checking their memory against `budget`).
    fn read_entries(mut self, budget: MemoryBudget) -> Result<MatrixFile, Error> {
        let MatrixHeader {
            rows,
            cols,
            entries,
            ..
        } = self.header;
        match entries {
            Some(entries) => read_coordinate(
                &mut self.lines,
                rows,
                cols,
                entries,
                self.pattern,
                self.symmetry,
                self.size_line,
                budget,
            ),
            None => read_array(&mut self.lines, rows, cols, self.size_line, budget),
        }
    }
}

/// `A`, `C`, `B`, `D` of `min ‖AX − C‖ s.t. BX = D`.
pub type SystemMatrices = (
    SparseColMat<usize, f64>,
    Mat<f64>,
    SparseColMat<usize, f64>,
    Mat<f64>,
);

/// [`read_system`] within the budget of `resources`.
pub fn read_system(
    a: &Path,
    c: &Path,
    b: &Path,
    d: &Path,
    budget: MemoryBudget,
) -> Result<SystemMatrices, Error> {
    fn open_file(path: &Path) -> Result<Opened<'_, BufReader<File>>, Error> {
        let file = crate::input::open_input(path).map_err(|e| Error::io(path, e))?;
        open(BufReader::new(file), path)
    }
    let (fa, fc, fb, fd) = (open_file(a)?, open_file(c)?, open_file(b)?, open_file(d)?);
    let (ha, hc, hb, hd) = (fa.header, fc.header, fb.header, fd.header);
    crate::problem::check_part_shapes(
        (ha.rows, ha.cols),
        (hc.rows, hc.cols),
        (hb.rows, hb.cols),
        (hd.rows, hd.cols),
    )?;
    let n = ha.cols as u64;
    let entries = ha.max_nonzeros().saturating_add(hb.max_nonzeros());
    if entries < n {
        return Err(ProblemError::Dimensions {
            message: format!(
                "A and B hold at most {entries} entries together (their size lines), fewer than the {n} unknowns: some unknown appears in no row of A or B, so the problem has no unique solution"
            ),
        }
        .into());
    }
    if hb.max_nonzeros() < hb.rows as u64 {
        return Err(ProblemError::Dimensions {
            message: format!(
                "B has {} rows but holds at most {} entries (its size line): some row of B has no entry, a constraint that says nothing about X",
                hb.rows,
                hb.max_nonzeros()
            ),
        }
        .into());
    }
    // Reading A and B (an array file converted keeps its nonzeros), and C
    // and D as read and as dense matrices.
    let sparse = |h: &MatrixHeader| {
        h.read_bytes().saturating_add(if h.entries.is_none() {
            h.max_nonzeros().saturating_mul(16)
        } else {
            0
        })
    };
    let dense = |h: &MatrixHeader| {
        h.dense_bytes().saturating_add(if h.entries.is_some() {
            h.read_bytes()
        } else {
            0
        })
    };
    let total = sparse(&ha)
        .saturating_add(sparse(&hb))
        .saturating_add(dense(&hc))
        .saturating_add(dense(&hd));
    budget
        .check(total, || {
            format!(
                "reading A ({} × {}), C ({} × {}), B ({} × {}) and D ({} × {}) would need",
                ha.rows, ha.cols, hc.rows, hc.cols, hb.rows, hb.cols, hd.rows, hd.cols
            )
        })
        .map_err(|detail| Error::from(ProblemError::TooLarge { detail }))?;
    let ma = fa.read_entries(budget)?.into_sparse();
    let mc = fc.read_entries(budget)?.into_dense_budgeted(c, budget)?;
    let mb = fb.read_entries(budget)?.into_sparse();
    let md = fd.read_entries(budget)?.into_dense_budgeted(d, budget)?;
    Ok((ma, mc, mb, md))
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
    budget: MemoryBudget,
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
        budget,
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
        let (i, j, value) = parse_entry(&text, pattern, rows, cols).map_err(&bad)?;
        push_entry(&mut triplets, i, j, value, symmetry).map_err(&bad)?;
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

/// Parses a coordinate entry line: `row col value` (`row col` for a
/// pattern, value 1), indices 1-based within `rows` and `cols`, returned
/// 0-based. The error is the message for the line.
fn parse_entry(
    text: &str,
    pattern: bool,
    rows: usize,
    cols: usize,
) -> Result<(usize, usize, f64), String> {
    let tokens: Vec<&str> = text.split_whitespace().collect();
    let expected = if pattern { 2 } else { 3 };
    if tokens.len() != expected {
        return Err(format!(
            "expected '{}', found {} item(s): '{}'",
            if pattern { "row col" } else { "row col value" },
            tokens.len(),
            crate::error::excerpt(text)
        ));
    }
    let index = |t: &str, what: &str, max: usize| -> Result<usize, String> {
        match t.parse::<usize>() {
            Ok(i) if (1..=max).contains(&i) => Ok(i - 1),
            _ => Err(format!(
                "{what} index '{}' is not in 1..={max}",
                crate::error::excerpt(t)
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
        parse_value(tokens[2])?
    };
    Ok((i, j, value))
}

/// Adds entry `(i, j)` (0-based) to `triplets`: as it is in a general
/// file; in a symmetric or skew-symmetric one it must be on or below the
/// diagonal (not on it when skew) and its mirror `(j, i)` is added too,
/// negated when skew. The error is the message for the line.
fn push_entry(
    triplets: &mut Vec<Triplet<usize, usize, f64>>,
    i: usize,
    j: usize,
    value: f64,
    symmetry: Symmetry,
) -> Result<(), String> {
    match symmetry {
        Symmetry::General => triplets.push(Triplet::new(i, j, value)),
        Symmetry::Symmetric | Symmetry::Skew => {
            if i < j {
                return Err(format!(
                    "entry ({}, {}) is above the diagonal: a {} file stores the lower triangle",
                    i + 1,
                    j + 1,
                    if symmetry == Symmetry::Skew {
                        "skew-symmetric"
                    } else {
                        "symmetric"
                    }
                ));
            }
            if i == j && symmetry == Symmetry::Skew {
                return Err(format!(
                    "diagonal entry ({0}, {0}) in a skew-symmetric file (its diagonal is zero)",
                    i + 1
                ));
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
    Ok(())
}

fn read_array(
    lines: &mut Lines<'_, impl BufRead>,
    rows: usize,
    cols: usize,
    size_line: usize,
    budget: MemoryBudget,
) -> Result<MatrixFile, Error> {
    let path = lines.path;
    let total = (rows as u64).saturating_mul(cols as u64);
    check_memory(path, total.saturating_mul(8), budget)?;
    // An empty array may still announce a huge dimension (0 × 10¹²): no
    // dimension may exceed what the budget holds, or every loop over the
    // columns of the empty matrix runs for hours.
    check_memory(path, (rows.max(cols) as u64).saturating_mul(8), budget)?;
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
        Ok(_) => Err(format!(
            "value '{}' is not finite",
            crate::error::excerpt(t)
        )),
        Err(_) => Err(format!("'{}' is not a number", crate::error::excerpt(t))),
    }
}

/// The longest line read: an entry's line is a few dozen bytes, and a
/// stream without line breaks (`/dev/zero`) is refused here instead of
/// being read into memory to exhaustion.
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// Bytes a file may hold besides its entries' lines (header, size line,
/// comments).
const HEADER_BYTES: u64 = 16 << 20;

/// Bytes a file may hold per value its size line announces (an entry's
/// line is at most about 60).
const MAX_BYTES_PER_VALUE: u64 = 256;

/// Lines with their 1-based numbers; I/O and UTF-8 errors become errors
/// naming the line. A line ends at `\n`, `\r\n` or a lone `\r` (classic
/// Mac OS); lines are at most [`MAX_LINE_BYTES`], and the file at most the
/// bytes [`Lines::allow`] granted.
struct Lines<'p, R: BufRead> {
    inner: R,
    number: usize,
    path: &'p Path,
    /// The last line ended in `\r`: a `\n` next belongs to it.
    after_cr: bool,
    /// Bytes that may still be read.
    remaining: u64,
    line: Vec<u8>,
}

impl<'p, R: BufRead> Lines<'p, R> {
    fn new(inner: R, path: &'p Path) -> Self {
        Lines {
            inner,
            number: 0,
            path,
            after_cr: false,
            remaining: HEADER_BYTES,
            line: Vec::new(),
        }
    }

    /// Lets `bytes` more be read.
    fn allow(&mut self, bytes: u64) {
        self.remaining = self.remaining.saturating_add(bytes);
    }

    fn error(&self, line: Option<usize>, message: String) -> Error {
        MatrixFileError {
            path: self.path.to_path_buf(),
            line,
            message,
        }
        .into()
    }

    fn next_raw(&mut self) -> Result<Option<String>, Error> {
        self.line.clear();
        let mut read_any = false;
        loop {
            let available = match self.inner.fill_buf() {
                Ok(b) => b,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    return Err(
                        self.error(Some(self.number + 1), format!("cannot read the line: {e}"))
                    );
                }
            };
            if available.is_empty() {
                break;
            }
            if self.after_cr {
                self.after_cr = false;
                if available[0] == b'\n' {
                    self.inner.consume(1);
                    continue;
                }
            }
            read_any = true;
            let end = available.iter().position(|&b| b == b'\n' || b == b'\r');
            let take = end.unwrap_or(available.len());
            if self.line.len() + take > MAX_LINE_BYTES {
                return Err(self.error(
                    Some(self.number + 1),
                    format!(
                        "the line is longer than {MAX_LINE_BYTES} bytes (not a Matrix Market file?)"
                    ),
                ));
            }
            let consumed = take + usize::from(end.is_some());
            if consumed as u64 > self.remaining {
                return Err(self.error(
                    Some(self.number + 1),
                    format!(
                        "the file goes on beyond the size its size line allows ({MAX_BYTES_PER_VALUE} bytes per entry and {} for the header and comments)",
                        crate::limits::format_bytes(HEADER_BYTES)
                    ),
                ));
            }
            self.remaining -= consumed as u64;
            self.line.extend_from_slice(&available[..take]);
            if let Some(i) = end {
                self.after_cr = available[i] == b'\r';
                self.inner.consume(consumed);
                break;
            }
            self.inner.consume(consumed);
        }
        if !read_any {
            return Ok(None);
        }
        self.number += 1;
        match std::str::from_utf8(&self.line) {
            Ok(s) => Ok(Some(s.to_string())),
            Err(_) => Err(self.error(
                Some(self.number),
                "cannot read the line: stream did not contain valid UTF-8".into(),
            )),
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

    fn banner(sparse: bool, pattern: bool, symmetry: Symmetry, word: &str) -> Banner {
        Banner {
            sparse,
            pattern,
            symmetry,
            symmetry_word: word.into(),
        }
    }

    #[test]
    fn banner_parser_alone() {
        assert_eq!(
            parse_banner("\u{feff}%%MatrixMarket Matrix Coordinate Pattern Symmetric"),
            Ok(banner(true, true, Symmetry::Symmetric, "symmetric"))
        );
        assert_eq!(
            parse_banner("%%MatrixMarket matrix array real general"),
            Ok(banner(false, false, Symmetry::General, "general"))
        );
        assert_eq!(
            parse_banner("%%MatrixMarket matrix array pattern general"),
            Err("field 'pattern' needs the coordinate format".into())
        );
        assert_eq!(
            parse_banner("%%MatrixMarket matrix array real hermitian"),
            Err("hermitian arrays are not supported (write the full matrix as 'array real general')".into())
        );
        assert_eq!(
            parse_banner("%%MatrixMarket matrix coordinate real upper"),
            Err("symmetry 'upper': expected general, symmetric or skew-symmetric".into())
        );
        assert_eq!(
            parse_banner("%%MatrixMarket vector coordinate real general"),
            Err("expected the header '%%MatrixMarket matrix FORMAT FIELD SYMMETRY', found '%%MatrixMarket vector coordinate real general'".into())
        );
    }

    #[test]
    fn size_line_parser_alone() {
        let coordinate = banner(true, false, Symmetry::General, "general");
        assert_eq!(
            parse_size_line("3 4 5", &coordinate),
            Ok(MatrixHeader {
                rows: 3,
                cols: 4,
                entries: Some(5),
                symmetric: false
            })
        );
        assert_eq!(
            parse_size_line("3 4", &coordinate),
            Err("expected 3 numbers on the size line, found 2".into())
        );
        let skew = banner(true, false, Symmetry::Skew, "skew-symmetric");
        assert_eq!(
            parse_size_line("3 4 1", &skew),
            Err("a skew-symmetric matrix must be square, this one is 3 × 4".into())
        );
        let array = banner(false, false, Symmetry::General, "general");
        assert_eq!(
            parse_size_line("2 x", &array),
            Err("expected the size line 'rows cols', found '2 x'".into())
        );
    }

    #[test]
    fn entry_line_parser_alone() {
        assert_eq!(parse_entry("2 3 -1.5", false, 2, 3), Ok((1, 2, -1.5)));
        assert_eq!(parse_entry(" 1  1 ", true, 2, 3), Ok((0, 0, 1.0)));
        assert_eq!(
            parse_entry("3 1 1.0", false, 2, 3),
            Err("row index '3' is not in 1..=2".into())
        );
        assert_eq!(
            parse_entry("1 0 1.0", false, 2, 3),
            Err("column index '0' is not in 1..=3".into())
        );
        assert_eq!(
            parse_entry("1 1", false, 2, 3),
            Err("expected 'row col value', found 2 item(s): '1 1'".into())
        );
    }

    #[test]
    fn entries_are_mirrored_by_symmetry() {
        let pairs = |t: &[Triplet<usize, usize, f64>]| -> Vec<(usize, usize, f64)> {
            t.iter().map(|t| (t.row, t.col, t.val)).collect()
        };
        let mut t = Vec::new();
        push_entry(&mut t, 0, 1, 2.0, Symmetry::General).unwrap();
        push_entry(&mut t, 2, 0, 3.0, Symmetry::Symmetric).unwrap();
        push_entry(&mut t, 1, 1, 4.0, Symmetry::Symmetric).unwrap();
        push_entry(&mut t, 2, 1, 5.0, Symmetry::Skew).unwrap();
        assert_eq!(
            pairs(&t),
            [
                (0, 1, 2.0),
                (2, 0, 3.0),
                (0, 2, 3.0),
                (1, 1, 4.0),
                (2, 1, 5.0),
                (1, 2, -5.0)
            ]
        );
        assert_eq!(
            push_entry(&mut t, 0, 1, 1.0, Symmetry::Symmetric),
            Err(
                "entry (1, 2) is above the diagonal: a symmetric file stores the lower triangle"
                    .into()
            )
        );
        assert_eq!(
            push_entry(&mut t, 1, 1, 1.0, Symmetry::Skew),
            Err("diagonal entry (2, 2) in a skew-symmetric file (its diagonal is zero)".into())
        );
    }

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
            let shown = e.to_string();
            assert!(shown.starts_with("m.mtx"), "{shown}");
            assert_eq!(line_of(e), *line, "{text:?}: {shown}");
        }
        // Not UTF-8.
        let e = read_matrix_from(
            &b"%%MatrixMarket matrix array real general\n1 1\n\xff\n"[..],
            Path::new("m"),
        )
        .unwrap_err();
        assert_eq!(line_of(e), Some(3));
    }

    /// A byte-order mark (as Windows editors write, and as a constraints
    /// file may start) is skipped; lines may end in `\r\n` or a lone `\r`
    /// (which used to make the whole file its "header").
    /// Found by the fuzz target: an empty array announcing 10¹² columns
    /// was accepted, and every loop over its columns ran for hours.
    #[test]
    fn an_empty_array_with_a_huge_dimension_is_refused() {
        for header in ["0 1000000000000", "1000000000000 0"] {
            let text = format!("%%MatrixMarket matrix array real general\n{header}\n");
            let Err(e) = read(&text) else {
                panic!("{header} was accepted")
            };
            assert!(e.to_string().contains("m.mtx"), "{e}");
        }
    }

    #[test]
    fn byte_order_marks_and_every_line_ending_are_read() {
        let lf = "%%MatrixMarket matrix coordinate real general\n% c\n2 3 2\n1 1 2.5\n2 3 -1\n";
        let expected = read(lf).unwrap().into_sparse().to_dense();
        for text in [
            format!("\u{feff}{lf}"),
            lf.replace('\n', "\r\n"),
            lf.replace('\n', "\r"),
            format!("\u{feff}{}", lf.replace('\n', "\r")),
            lf.trim_end().to_string(),
        ] {
            let m = read(&text)
                .unwrap_or_else(|e| panic!("{text:?}: {e}"))
                .into_sparse()
                .to_dense();
            assert_eq!(m, expected, "{text:?}");
        }
        // Line numbers count `\r` line ends too.
        let e =
            read("%%MatrixMarket matrix coordinate real general\r2 2 1\r\r3 1 1\r").unwrap_err();
        assert_eq!(line_of(e), Some(4));
        // A header that is not one is shown as its first line only.
        let e = read("%%MatrixMarket matrix coordinate real\r2 2 1\r1 1 1\r").unwrap_err();
        let message = e.to_string();
        assert!(
            message.ends_with("found '%%MatrixMarket matrix coordinate real'"),
            "{message}"
        );
    }

    /// An endless stream is refused early, whatever it holds: one endless
    /// line, endless comment lines, endless blank lines after the entries.
    #[test]
    fn endless_streams_are_refused_at_a_size_bound() {
        use std::io::Read;
        let path = Path::new("stream");
        let e = read_matrix_from(BufReader::new(std::io::repeat(0)), path).unwrap_err();
        assert!(
            e.to_string().contains("line 1: the line is longer than"),
            "{e}"
        );
        let comments = b"%%MatrixMarket matrix coordinate real general\n"
            .chain(std::io::repeat(b'%').take(10))
            .chain(&b"\n"[..])
            .chain(std::io::repeat(b'\n'));
        let e = read_matrix_from(BufReader::new(comments), path).unwrap_err();
        assert!(
            e.to_string()
                .contains("beyond the size its size line allows"),
            "{e}"
        );
        let entries = b"%%MatrixMarket matrix coordinate real general\n2 2 1\n1 1 1\n"
            .chain(std::io::repeat(b'\n'));
        let e = read_matrix_from(BufReader::new(entries), path).unwrap_err();
        assert!(
            e.to_string()
                .contains("beyond the size its size line allows"),
            "{e}"
        );
    }

    /// `read_system` compares the four headers before reading entries: a
    /// file whose entries could not even be read is not read when the
    /// headers already say the problem is refused.
    #[test]
    fn read_system_checks_the_headers_together_first() {
        let dir = tempfile::tempdir().unwrap();
        let write = |name: &str, text: &str| {
            let p = dir.path().join(name);
            std::fs::write(&p, text).unwrap();
            p
        };
        let one_row = "%%MatrixMarket matrix array real general\n1 3\n0\n0\n0\n";
        let garbage = "x y z\n";
        let a = write(
            "A.mtx",
            &format!("%%MatrixMarket matrix coordinate real general\n1 300000000 1\n{garbage}"),
        );
        let b = write(
            "B.mtx",
            &format!("%%MatrixMarket matrix coordinate real general\n1 300000000 1\n{garbage}"),
        );
        let (c, d) = (write("C.mtx", one_row), write("D.mtx", one_row));
        let e = read_system(&a, &c, &b, &d, MemoryBudget::default()).unwrap_err();
        assert!(
            matches!(e, Error::Problem(ProblemError::Dimensions { .. })),
            "{e}"
        );
        assert!(
            e.to_string().contains("fewer than the 300000000 unknowns"),
            "{e}"
        );
        // A row of B without an entry.
        let a2 = write(
            "A2.mtx",
            "%%MatrixMarket matrix coordinate real general\n2 2 2\n1 1 1\n2 2 1\n",
        );
        let b2 = write(
            "B2.mtx",
            &format!("%%MatrixMarket matrix coordinate real general\n2 2 1\n{garbage}"),
        );
        let d2 = write("D2.mtx", "%%MatrixMarket matrix array real general\n2 3\n");
        let c2 = write(
            "C2.mtx",
            "%%MatrixMarket matrix coordinate real general\n2 3 1\n1 1 1\n",
        );
        let e = read_system(&a2, &c2, &b2, &d2, MemoryBudget::default()).unwrap_err();
        assert!(e.to_string().contains("some row of B has no entry"), "{e}");
        // Shapes, before C's one entry is expanded into 3·10⁸ rows.
        let b3 = write(
            "B3.mtx",
            "%%MatrixMarket matrix coordinate real general\n1 2 1\n1 1 1\n",
        );
        let c3 = write(
            "C3.mtx",
            &format!("%%MatrixMarket matrix coordinate real general\n300000000 3 1\n{garbage}"),
        );
        let e = read_system(&a2, &c3, &b3, &d, MemoryBudget::default()).unwrap_err();
        assert!(
            e.to_string().contains("C must have as many rows as A"),
            "{e}"
        );
        // B with no rows is a problem without hard constraints.
        let b0 = write(
            "B0.mtx",
            "%%MatrixMarket matrix coordinate real general\n0 2 0\n",
        );
        let d0 = write("D0.mtx", "%%MatrixMarket matrix array real general\n0 3\n");
        let c4 = write(
            "C4.mtx",
            "%%MatrixMarket matrix array real general\n2 3\n1\n2\n3\n4\n5\n6\n",
        );
        let (ma, mc, mb, md) = read_system(&a2, &c4, &b0, &d0, MemoryBudget::default()).unwrap();
        assert_eq!(
            (ma.nrows(), mc.ncols(), mb.nrows(), md.nrows()),
            (2, 3, 0, 0)
        );
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
