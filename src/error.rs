//! Typed errors.
//!
//! Every failure the library can meet on user input or in the numerics is a
//! variant here that names *what* is wrong and *where* (file line, face,
//! vertex, constraint index, pivot). The library never panics on user input
//! and never returns non-finite positions: a solve that would produce them
//! returns a [`NumericalError`] instead.
//!
//! Errors fall into two classes, which the CLI maps to exit codes:
//! bad input ([`Error::is_input_error`], exit code 2) and numerical failure
//! (exit code 3).

use std::path::PathBuf;

use thiserror::Error;

/// Any error of the crate.
#[derive(Debug, Error)]
pub enum Error {
    /// The mesh file or mesh data is invalid.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// The constraints file or a constraint is invalid.
    #[error(transparent)]
    Constraint(#[from] ConstraintError),
    /// Mesh and constraints are valid on their own but do not form a
    /// solvable problem (detected before any factorisation).
    #[error(transparent)]
    Problem(#[from] ProblemError),
    /// A factorisation or solve failed numerically. A back end's
    /// [`NumericalError::OutOfMemory`] never lands here: `From` makes it
    /// [`ProblemError::TooLarge`], a refusal for size.
    #[error(transparent)]
    Numerical(NumericalError),
    /// A Matrix Market file is invalid.
    #[error(transparent)]
    MatrixFile(#[from] MatrixFileError),
    /// `LSE_MEMORY_LIMIT` is set to something that is not a size
    /// ([`crate::limits::MemoryBudget::from_environment`]).
    #[error(transparent)]
    MemoryLimit(#[from] crate::limits::MemoryLimitError),
    /// The caller's interruption hook asked the call to stop
    /// ([`crate::interrupt`]; the Python module's hook when Ctrl-C is
    /// pressed). Nothing is wrong with the input.
    #[error("interrupted")]
    Interrupted,
    /// Reading or writing a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
}

impl Error {
    /// `true` for errors caused by the input (mesh, constraints, files),
    /// `false` for numerical failures and an interruption.
    pub(crate) fn is_input_error(&self) -> bool {
        !matches!(self, Error::Numerical(_) | Error::Interrupted)
    }

    /// The process exit code the CLI uses for this error: 2 for bad input,
    /// 3 for numerical failure, 130 (128 + SIGINT, the shell's convention)
    /// for an interruption.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Interrupted => 130,
            e if e.is_input_error() => 2,
            _ => 3,
        }
    }

    /// Wraps an I/O error with the path it happened on.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}

/// Result type of the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// An invalid mesh file or invalid mesh data. Indices are 0-based unless the
/// message says "line", which is 1-based as in an editor.
///
/// Variants that name a vertex or a face carry `line: Option<usize>`: `None`
/// when the error comes from [`Mesh::new`](crate::mesh::Mesh::new) on
/// in-memory data, `Some(l)` when a file reader could locate the element in a
/// line-based file (OBJ, OFF, ASCII PLY). For a face, `face` is always the
/// index in the *triangle* list (after fan-triangulating polygons), and `line`
/// is the line of the polygon it came from; the message shows both.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MeshError {
    /// The file could not be parsed.
    #[error("{format} parse error{}: {message}", line.map(|l| format!(" at line {l}")).unwrap_or_default())]
    Parse {
        /// File format ("OBJ", "PLY", "OFF").
        format: &'static str,
        /// 1-based line of the problem, where the format has lines.
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },
    /// The file extension names no supported format.
    #[error("unsupported mesh format '{extension}' (expected .obj, .ply or .off, optionally .gz)")]
    UnsupportedFormat {
        /// The extension found.
        extension: String,
    },
    /// The mesh has no vertices or no faces.
    #[error("empty mesh: {vertices} vertices and {faces} faces (need at least one triangle)")]
    Empty {
        /// Vertex count.
        vertices: usize,
        /// Face count.
        faces: usize,
    },
    /// A coordinate is NaN or infinite.
    #[error("vertex {vertex}{} has a non-finite coordinate {value}", at_line(line))]
    NonFiniteCoordinate {
        /// Vertex index.
        vertex: usize,
        /// The offending value.
        value: f64,
        /// 1-based file line of the vertex, if read from a line-based file.
        line: Option<usize>,
    },
    /// A face refers to a vertex that does not exist.
    #[error(
        "face {face}{} refers to vertex {index} (0-based), but the mesh has {vertex_count} vertices",
        at_line(line)
    )]
    IndexOutOfRange {
        /// Face index.
        face: usize,
        /// The index as resolved to 0-based (may be negative if the file's
        /// index was, e.g. an OBJ relative index reaching before the first
        /// vertex).
        index: i64,
        /// Number of vertices (for an OBJ relative index: the number defined
        /// up to that line).
        vertex_count: usize,
        /// 1-based file line of the face, if read from a line-based file.
        line: Option<usize>,
    },
    /// A face has fewer than three vertices or is not a triangle where the
    /// format requires triangles.
    #[error(
        "face {face}{} has {sides} vertices; only polygons with at least 3 are allowed",
        at_line(line)
    )]
    BadFaceSize {
        /// Face index (in the triangle list, i.e. the index the face would
        /// have had).
        face: usize,
        /// Its number of vertices.
        sides: usize,
        /// 1-based file line of the face, if read from a line-based file.
        line: Option<usize>,
    },
    /// A face uses the same vertex twice.
    #[error(
        "face {face}{} uses vertex {vertex} twice (a degenerate face)",
        at_line(line)
    )]
    RepeatedVertex {
        /// Face index.
        face: usize,
        /// The repeated vertex.
        vertex: usize,
        /// 1-based file line of the face, if read from a line-based file.
        line: Option<usize>,
    },
    /// A face has (numerically) zero area: twice its area is at most
    /// `64 ε` times its longest edge squared
    /// ([`crate::mesh::quality::TriangleSize`]).
    #[error(
        "face {face}{} (vertices {vertices:?}) has zero area for its size (area {}, longest edge {}: twice the area over the longest edge squared is {relative_area:.1e}, not above 64ε = 1.4e-14): its angles and cotangent weights are undefined, so no cotangent Laplacian can be built on this rest shape (the uniform Laplacian needs no angles)",
        at_line(line),
        show_magnitude(*area),
        show_magnitude(*longest_edge)
    )]
    DegenerateFace {
        /// Face index.
        face: usize,
        /// Its vertices.
        vertices: [usize; 3],
        /// Its area (infinite when beyond the largest double).
        area: f64,
        /// Its longest edge (infinite when beyond the largest double).
        longest_edge: f64,
        /// Twice its area over its longest edge squared (unit-free).
        relative_area: f64,
        /// 1-based file line of the face, if read from a line-based file.
        line: Option<usize>,
    },
    /// Two faces use the same three vertices.
    #[error(
        "face {face}{} repeats face {first} (same vertices {vertices:?})",
        at_line(line)
    )]
    DuplicateFace {
        /// The later face.
        face: usize,
        /// The earlier face with the same vertices.
        first: usize,
        /// The shared vertices.
        vertices: [usize; 3],
        /// 1-based file line of the later face, if read from a line-based
        /// file.
        line: Option<usize>,
    },
    /// A vertex is used by no face.
    #[error(
        "vertex {vertex}{} is used by no face ({count} unreferenced vertices in all): it has no Laplacian row, which makes the system singular; remove unreferenced vertices from the mesh (renumbering the faces and constraints) before deforming it",
        at_line(line)
    )]
    UnreferencedVertex {
        /// The first unreferenced vertex.
        vertex: usize,
        /// How many there are.
        count: usize,
        /// 1-based file line of that vertex, if read from a line-based file.
        line: Option<usize>,
    },
    /// A generator parameter is out of its range.
    #[error("invalid parameter {name}: {message}")]
    BadParameter {
        /// The parameter.
        name: &'static str,
        /// What is wrong.
        message: String,
    },
    /// An operation that needs an oriented 2-manifold met something else.
    #[error("not an oriented manifold at edge ({}, {}): {reason}", edge[0], edge[1])]
    NotManifold {
        /// The edge's vertices.
        edge: [usize; 2],
        /// What is wrong there.
        reason: String,
    },
    /// The file is larger than the configured limit.
    #[error("{what} too large: {detail}")]
    TooLarge {
        /// What is too large.
        what: &'static str,
        /// The estimate and the limit.
        detail: String,
    },
}

/// At most the first 80 characters of `text` (from a user's file), with
/// `…` where it was cut: what an error quotes of an input, so that a
/// 20 MB word makes a one-line message, not a 20 MB one.
pub(crate) fn excerpt(text: &str) -> String {
    match text.char_indices().nth(80) {
        Some((i, _)) => format!("{}…", &text[..i]),
        None => text.to_string(),
    }
}

/// A length or an area for a message: `{:e}`, or "beyond the largest
/// double" when it is infinite.
fn show_magnitude(x: f64) -> String {
    if x.is_infinite() {
        "beyond the largest double (1.8e308)".into()
    } else {
        format!("{x:.3e}")
    }
}

/// `" (line N)"`, or nothing.
fn at_line(line: &Option<usize>) -> String {
    line.map(|l| format!(" (line {l})")).unwrap_or_default()
}

impl MeshError {
    /// The 1-based file line the error refers to, if known.
    pub fn line(&self) -> Option<usize> {
        match self {
            MeshError::Parse { line, .. }
            | MeshError::NonFiniteCoordinate { line, .. }
            | MeshError::IndexOutOfRange { line, .. }
            | MeshError::BadFaceSize { line, .. }
            | MeshError::RepeatedVertex { line, .. }
            | MeshError::DegenerateFace { line, .. }
            | MeshError::DuplicateFace { line, .. }
            | MeshError::UnreferencedVertex { line, .. } => *line,
            MeshError::UnsupportedFormat { .. }
            | MeshError::Empty { .. }
            | MeshError::BadParameter { .. }
            | MeshError::NotManifold { .. }
            | MeshError::TooLarge { .. } => None,
        }
    }

    /// The vertex an error is about, if it names one (used by file readers
    /// to attach the vertex's line).
    pub(crate) fn located_vertex(&self) -> Option<usize> {
        match self {
            MeshError::NonFiniteCoordinate { vertex, .. }
            | MeshError::UnreferencedVertex { vertex, .. } => Some(*vertex),
            _ => None,
        }
    }

    /// The face (index in the triangle list) an error is about, if it names
    /// one (used by file readers to attach the face's line).
    pub(crate) fn located_face(&self) -> Option<usize> {
        match self {
            MeshError::IndexOutOfRange { face, .. }
            | MeshError::BadFaceSize { face, .. }
            | MeshError::RepeatedVertex { face, .. }
            | MeshError::DegenerateFace { face, .. }
            | MeshError::DuplicateFace { face, .. } => Some(*face),
            _ => None,
        }
    }

    /// Sets the `line` of a vertex- or face-located error that has none yet;
    /// other errors are returned unchanged.
    pub(crate) fn with_line(mut self, new_line: Option<usize>) -> Self {
        match &mut self {
            MeshError::NonFiniteCoordinate { line, .. }
            | MeshError::IndexOutOfRange { line, .. }
            | MeshError::BadFaceSize { line, .. }
            | MeshError::RepeatedVertex { line, .. }
            | MeshError::DegenerateFace { line, .. }
            | MeshError::DuplicateFace { line, .. }
            | MeshError::UnreferencedVertex { line, .. }
                if line.is_none() =>
            {
                *line = new_line;
            }
            _ => {}
        }
        self
    }
}

/// An invalid constraints file or constraint. `index` is the 0-based position
/// of the constraint in the file's `constraints` array.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ConstraintError {
    /// The file is not valid JSON or not of the expected shape.
    #[error("constraints file: malformed JSON at line {line}, column {column}: {message}")]
    Json {
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What the parser said.
        message: String,
    },
    /// A key appears twice in one JSON object of the file, at any depth
    /// (a reader of JSON objects keeps one of the two values, silently).
    #[error("constraints file, line {line}: key '{key}' appears twice in one object {place}")]
    DuplicateKey {
        /// The key.
        key: String,
        /// 1-based line of its second appearance.
        line: usize,
        /// Where the object is: "at the top level", "in constraint 3",
        /// "in 'mesh'".
        place: String,
    },
    /// The top level is not an object with a `constraints` array.
    #[error("constraints file: {message}")]
    Shape {
        /// What is wrong.
        message: String,
    },
    /// `type` is not one of position, edge, face, relative.
    #[error(
        "constraint {index}: unknown type '{found}' (expected position, edge, face or relative)"
    )]
    UnknownType {
        /// Constraint index.
        index: usize,
        /// The type found.
        found: String,
    },
    /// A required field is missing or has the wrong JSON type.
    #[error("constraint {index}: field '{field}' {problem}")]
    BadField {
        /// Constraint index.
        index: usize,
        /// The field.
        field: &'static str,
        /// "is missing", "must be an array of 3 numbers", ...
        problem: String,
    },
    /// A field that the constraint's type does not have (a typo such as
    /// "wieght" must not silently turn a soft constraint into a hard one).
    #[error(
        "constraint {index}: unknown field '{field}' for a {kind} constraint (allowed: {allowed})"
    )]
    UnknownField {
        /// Constraint index.
        index: usize,
        /// The field found.
        field: String,
        /// The constraint's type.
        kind: String,
        /// The allowed fields.
        allowed: String,
    },
    /// A vertex index is not in the mesh.
    #[error(
        "constraint {index}: vertex {vertex} is out of range (the mesh has {vertex_count} vertices)"
    )]
    VertexOutOfRange {
        /// Constraint index.
        index: usize,
        /// The vertex.
        vertex: u64,
        /// Number of vertices.
        vertex_count: usize,
    },
    /// The same vertex appears twice in one constraint.
    #[error("constraint {index}: vertex {vertex} appears twice")]
    RepeatedVertex {
        /// Constraint index.
        index: usize,
        /// The vertex.
        vertex: usize,
    },
    /// A number is NaN or infinite.
    #[error("constraint {index}: '{field}' is not finite")]
    NonFinite {
        /// Constraint index.
        index: usize,
        /// The field.
        field: &'static str,
    },
    /// A weight is zero, negative, NaN or infinite.
    #[error("constraint {index}: weight {weight} is invalid (must be finite and > 0)")]
    InvalidWeight {
        /// Constraint index.
        index: usize,
        /// The weight.
        weight: f64,
    },
    /// The file holds more constraints than the configured limit.
    #[error("constraints file too large: {detail}")]
    TooLarge {
        /// The estimate and the limit.
        detail: String,
    },
    /// The file's `"mesh"` object names another mesh (an error only when
    /// asked to be strict; otherwise a warning).
    #[error("constraints file was {detail}")]
    MeshMismatch {
        /// What differs (counts or fingerprint).
        detail: String,
    },
    /// Hard constraints contradict earlier ones and were dropped (an error
    /// only when asked to be strict; otherwise warnings).
    #[error("{count} conflicting hard constraint(s), and --strict makes that an error: {detail}")]
    Conflicting {
        /// How many were dropped.
        count: usize,
        /// The first conflict: index, the constraints it contradicts,
        /// residual.
        detail: String,
    },
}

/// An invalid Matrix Market file (`crate::mtx`): the file, the 1-based
/// line where known, and what is wrong there.
#[derive(Debug, Error, Clone, PartialEq)]
#[error("{}{}: {message}", path.display(), line.map(|l| format!(", line {l}")).unwrap_or_default())]
pub struct MatrixFileError {
    /// The file.
    pub path: PathBuf,
    /// 1-based line, if the problem is on one line.
    pub line: Option<usize>,
    /// What is wrong.
    pub message: String,
}

/// Mesh and constraints that are each valid but do not define a unique
/// solution. Detected before any factorisation.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ProblemError {
    /// No constraints at all.
    #[error(
        "no constraints: a Laplacian deformation needs at least one constraint that fixes a position"
    )]
    NoConstraints,
    /// A mesh component is free to translate.
    #[error(
        "mesh component {component} ({vertices} vertices, e.g. vertex {example_vertex}) is not pinned: no position, edge or face constraint touches it (relative constraints alone leave it free to translate), so the system is singular; add a constraint on it"
    )]
    UnpinnedComponent {
        /// Component index (components numbered by their smallest vertex).
        component: usize,
        /// Its vertex count.
        vertices: usize,
        /// One of its vertices.
        example_vertex: usize,
    },
    /// A method got constraints it does not support.
    #[error("{method} does not support constraint {index} ({kind}): {reason}")]
    Unsupported {
        /// The method.
        method: String,
        /// Constraint index.
        index: usize,
        /// Its kind.
        kind: &'static str,
        /// Why.
        reason: &'static str,
    },
    /// The system would be too large to factor within the configured limits.
    #[error("system too large: {detail}")]
    TooLarge {
        /// The estimate and the limit.
        detail: String,
    },
    /// The matrices given to
    /// [`LseProblem::from_parts`](crate::problem::LseProblem::from_parts)
    /// do not fit together (or one is empty).
    #[error("problem matrices: {message}")]
    Dimensions {
        /// Which sizes disagree.
        message: String,
    },
    /// An entry of `A`, `B`, `C` or `D` is NaN or infinite.
    #[error(
        "problem matrices: {matrix}[{row}, {col}] = {value} is not finite (0-based row and column)"
    )]
    NonFiniteEntry {
        /// `"A"`, `"B"`, `"C"` or `"D"`.
        matrix: &'static str,
        /// 0-based row.
        row: usize,
        /// 0-based column.
        col: usize,
        /// The value.
        value: f64,
    },
    /// A row of `B` has no nonzero coefficient (stored zeros do not count):
    /// the constraint `0 = d` says nothing about `X`.
    #[error(
        "row {row} of B has no nonzero entry: the constraint 0·X = D[{row}, :] says nothing about X; remove it"
    )]
    EmptyConstraintRow {
        /// 0-based row of `B`.
        row: usize,
    },
    /// An unknown appears in no row of `A` or `B` (both columns empty), so
    /// it is free and the problem has no unique solution.
    #[error(
        "unknown {unknown} (row {unknown} of X) appears in no row of A or B (column {unknown} of both is empty): it is free, so the problem has no unique solution"
    )]
    UnusedUnknown {
        /// 0-based unknown (column of `A` and `B`).
        unknown: usize,
    },
    /// An argument (a fraction, an axis, a method option) is out of range.
    #[error("invalid argument: {message}")]
    InvalidArgument {
        /// What is wrong.
        message: String,
    },
    /// A solve option that cannot be used as given (a penalty without a
    /// weight, an SPD back end the KKT method cannot use). Front doors name
    /// `option` by their own flag or keyword.
    #[error("invalid {}: {message}", option.describe())]
    InvalidOption {
        /// The option at fault.
        option: SolveOption,
        /// What is wrong, in the library's terms.
        message: String,
    },
    /// A target update refers to a constraint that does not exist or has the
    /// wrong kind.
    #[error("target update: {message}")]
    BadUpdate {
        /// What is wrong.
        message: String,
    },
}

impl ProblemError {
    /// [`ProblemError::TooLarge`] for an allocation of about `bytes` for
    /// `what` that the allocator refused, naming the address-space limit
    /// (`RLIMIT_AS`) and what the process has mapped when there is one:
    /// what an allocation that scales with the input returns instead of
    /// aborting (it is made with `try_reserve`, or through a faer
    /// constructor that reports `OutOfMemory`).
    pub(crate) fn allocation_failed(what: &str, bytes: u64) -> ProblemError {
        ProblemError::TooLarge {
            detail: format!(
                "{what}: allocating about {} failed{}",
                crate::limits::format_bytes(bytes),
                address_space_context()
            ),
        }
    }

    /// The error of a faer sparse constructor (`try_new_from_triplets`,
    /// `try_new_from_nonnegative_triplets`, …) building `what` of about
    /// `bytes`: an allocation failure (`OutOfMemory`) is
    /// [`ProblemError::allocation_failed`]; an index overflow or an entry
    /// out of bounds is [`ProblemError::Dimensions`].
    pub(crate) fn from_creation(
        what: &str,
        bytes: u64,
        e: faer::sparse::CreationError,
    ) -> ProblemError {
        use faer::sparse::{CreationError, FaerError};
        match e {
            CreationError::Generic(FaerError::OutOfMemory) => {
                ProblemError::allocation_failed(what, bytes)
            }
            other => ProblemError::Dimensions {
                message: format!("{what}: {other:?}"),
            },
        }
    }
}

/// `" under the address-space limit (RLIMIT_AS) of …, with … mapped"`
/// when the process has such a limit, else empty: what explains an
/// allocation the allocator refused.
fn address_space_context() -> String {
    use crate::limits::{address_space_limit, format_bytes, mapped_bytes};
    match address_space_limit() {
        Some(limit) => format!(
            " under the address-space limit (RLIMIT_AS) of {}, with {} mapped",
            format_bytes(limit),
            format_bytes(mapped_bytes().unwrap_or(0))
        ),
        None => String::new(),
    }
}

impl NumericalError {
    /// [`NumericalError::OutOfMemory`]: `backend` could not allocate
    /// `what`.
    pub(crate) fn out_of_memory(backend: &str, what: &str) -> NumericalError {
        NumericalError::OutOfMemory {
            backend: backend.into(),
            what: what.into(),
        }
    }

    /// The error of a faer routine of `backend` building `what`: faer's
    /// `OutOfMemory` is [`NumericalError::OutOfMemory`], an index overflow
    /// is [`NumericalError::Backend`].
    pub(crate) fn from_faer(
        backend: &str,
        what: &str,
        e: faer::sparse::FaerError,
    ) -> NumericalError {
        match e {
            faer::sparse::FaerError::OutOfMemory => NumericalError::out_of_memory(backend, what),
            other => NumericalError::Backend {
                backend: backend.into(),
                message: format!("{what}: {other:?}"),
            },
        }
    }
}

impl From<NumericalError> for Error {
    /// [`Error::Numerical`], except [`NumericalError::OutOfMemory`], which
    /// is [`ProblemError::TooLarge`]: a back end that could not allocate
    /// has met a limit, not a numerical failure.
    fn from(e: NumericalError) -> Error {
        match e {
            NumericalError::OutOfMemory { backend, what } => {
                Error::Problem(ProblemError::TooLarge {
                    detail: format!(
                        "{backend}: allocating {what} failed{}",
                        address_space_context()
                    ),
                })
            }
            other => Error::Numerical(other),
        }
    }
}

/// The options of a solve, for errors that name the one at fault
/// ([`ProblemError::InvalidOption`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolveOption {
    /// The formulation.
    Method,
    /// The QR back end.
    Qr,
    /// The SPD back end.
    Spd,
    /// The penalty weight.
    Weight,
    /// The refinement mode.
    Refine,
}

impl SolveOption {
    /// The option in words.
    pub(crate) fn describe(self) -> &'static str {
        match self {
            SolveOption::Method => "method",
            SolveOption::Qr => "QR back end",
            SolveOption::Spd => "SPD back end",
            SolveOption::Weight => "penalty weight",
            SolveOption::Refine => "refinement",
        }
    }
}

/// A word that names none of the values of a typed choice (a method, a
/// back end, a Laplacian, a refinement mode, ...): the one parse error of
/// every configuration word, listing the accepted words.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
#[error("unknown {what} '{word}' (expected one of: {})", .expected.join(", "))]
pub struct ParseWordError {
    /// What the word should have named (`"method"`, `"SPD back end"`).
    pub what: &'static str,
    /// The word given.
    pub word: String,
    /// The accepted words (of this build), in the order they are listed.
    pub expected: Vec<&'static str>,
}

impl From<ParseWordError> for ProblemError {
    fn from(e: ParseWordError) -> Self {
        ProblemError::InvalidArgument {
            message: e.to_string(),
        }
    }
}

impl From<ParseWordError> for Error {
    fn from(e: ParseWordError) -> Self {
        Error::Problem(e.into())
    }
}

/// A numerical failure. Never silently compromised: the solve stops here.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum NumericalError {
    /// Cholesky met a pivot that is not positive.
    #[error(
        "{matrix} is not numerically positive definite: the pivot of unknown {unknown}{} is not positive{}",
        vertex.map(|v| format!(" (vertex {v})")).unwrap_or_default(),
        pivot.map(|p| format!(" ({p:e})")).unwrap_or_default()
    )]
    NotPositiveDefinite {
        /// Which matrix.
        matrix: String,
        /// Unknown index in the original (unpermuted) ordering of that matrix.
        unknown: usize,
        /// The mesh vertex of that unknown, if it corresponds to one.
        vertex: Option<usize>,
        /// The pivot value (≤ 0, or NaN), where the back end reports it.
        pivot: Option<f64>,
    },
    /// Cholesky completed but a pivot lost all its significant digits.
    #[error(
        "{matrix}: factorisation broke down at unknown {unknown}{}: pivot/diagonal = {ratio:e} is below the breakdown threshold {threshold:e} (all significant digits cancelled)",
        vertex.map(|v| format!(" (vertex {v})")).unwrap_or_default()
    )]
    Breakdown {
        /// Which matrix.
        matrix: String,
        /// Unknown index in the original ordering.
        unknown: usize,
        /// The mesh vertex of that unknown, if any.
        vertex: Option<usize>,
        /// `L_kk² / A_kk`.
        ratio: f64,
        /// The threshold it fell below.
        threshold: f64,
    },
    /// A symmetric indefinite (KKT) system is singular.
    #[error("{matrix} is singular: {detail}")]
    Singular {
        /// Which matrix.
        matrix: String,
        /// Where and why.
        detail: String,
    },
    /// A solve's verification failed: the computed solution does not solve
    /// the factored system to the required backward error, even after
    /// iterative refinement.
    #[error(
        "{matrix}: the solution failed its residual check: normwise backward error {backward_error:e} exceeds {tolerance:e} after iterative refinement (the factorisation lost too many digits)"
    )]
    InaccurateSolution {
        /// Which matrix.
        matrix: String,
        /// `‖K y − b‖∞ / (‖K‖∞ ‖y‖∞ + ‖b‖∞)` after refinement.
        backward_error: f64,
        /// The largest accepted value.
        tolerance: f64,
    },
    /// The solution's estimated forward error exceeds what the caller
    /// accepts (the CLI's `--strict`), although the factorisation
    /// completed: an ill-conditioned system, or a penalty weight too small
    /// to hold the hard constraints.
    #[error(
        "{matrix}: the solution's estimated forward error {estimate:.2e} (relative to the length scale) exceeds {tolerance:.0e} ({advice})"
    )]
    LostAccuracy {
        /// Which matrix.
        matrix: String,
        /// The forward error estimate.
        estimate: f64,
        /// The largest accepted value.
        tolerance: f64,
        /// What could lower the error, for the method and refinement in
        /// use ([`crate::solver::lost_accuracy_advice`]).
        advice: String,
    },
    /// The matrix a formulation factored for a general problem (one built
    /// by [`LseProblem::from_parts`](crate::problem::LseProblem::from_parts))
    /// is singular: an unknown of `X` is not determined by `A` together with
    /// the kept rows of `B`. (For meshes the same situation is an unpinned
    /// component, diagnosed before factorising.)
    #[error(
        "{matrix} is singular: unknown {unknown} (row {unknown} of X) is free — A together with the kept rows of B does not determine it ({detail})"
    )]
    FreeUnknown {
        /// Which matrix.
        matrix: String,
        /// 0-based unknown of `X` named by the failing pivot.
        unknown: usize,
        /// What the factorisation saw.
        detail: String,
    },
    /// A target (or relative vector) is so large against the mesh's length
    /// unit that the problem cannot be represented in double precision.
    #[error(
        "constraint {index}: its target {value:e} is {ratio:e} times the mesh's length unit (mean edge length {unit:e}), beyond the range of double precision"
    )]
    TargetOutOfRange {
        /// Constraint index.
        index: usize,
        /// The largest coordinate of the target.
        value: f64,
        /// The mesh's length unit.
        unit: f64,
        /// `value / unit` (infinite).
        ratio: f64,
    },
    /// A soft weight times the power of the length unit that keeps the
    /// documented energy (`w ℓᵃ`, [`crate::problem::SoftWeightScale`]) is
    /// not a finite positive double.
    #[error(
        "constraint {index}: its soft weight {weight:e} times the mesh's length unit {length:e} to the power {power} (which keeps the energy in the mesh's units) is beyond the range of double precision"
    )]
    SoftWeightOutOfRange {
        /// Constraint index.
        index: usize,
        /// The weight as given.
        weight: f64,
        /// The length unit `ℓ`.
        length: f64,
        /// The power `a`.
        power: i32,
    },
    /// A soft weight whose row weight `w ℓᵃ` (the weight in the problem's
    /// units, [`crate::problem::SoftWeightScale`]) has a square beyond
    /// double precision. Every formulation forms normal equations (`AᵀA`,
    /// or `(AQ2)ᵀ(AQ2)` for the null-space method), whose diagonal at the
    /// row's unknowns holds `(w ℓᵃ b_i)²` with coefficients `|b_i| ≤ 1`
    /// for positions, relative vectors and edge and face points inside
    /// their element: beyond `(w ℓᵃ)² = ∞`, i.e. `w ℓᵃ > √(f64::MAX) ≈
    /// 1.34e154`, the factorisation would meet an infinite entry and fail
    /// late as "not positive definite". Refused at assembly, as a weight
    /// whose product underflows to zero is
    /// ([`NumericalError::SoftWeightOutOfRange`]).
    #[error(
        "constraint {index}: its soft weight {weight:e} is too large: times the mesh's length unit to the power {power} (which keeps the energy in the mesh's units) it is {row_weight:e}, above √(largest double) ≈ 1.34e154, so its square in the normal equations overflows"
    )]
    SoftWeightTooLarge {
        /// Constraint index.
        index: usize,
        /// The weight as given.
        weight: f64,
        /// `w ℓᵃ`.
        row_weight: f64,
        /// The power `a` of the length unit.
        power: i32,
    },
    /// The solve produced a non-finite value.
    #[error(
        "solve produced a non-finite value in row {vertex} of X (for a mesh, the position of vertex {vertex})"
    )]
    NonFiniteSolution {
        /// The first row of `X` (vertex, for a mesh) with a non-finite
        /// entry.
        vertex: usize,
    },
    /// The ARAP objective is not finite in the mesh's units: the squared
    /// lengths of the deformation overflow double precision (a target far
    /// outside the mesh), or a NaN entered them.
    #[error(
        "ARAP: the energy {} is {value:e}, not finite: the squared lengths of the deformation are beyond the range of double precision (is a target far outside the mesh?)",
        if *iteration == 0 { "of the initial guess".to_string() } else { format!("after iteration {iteration}") }
    )]
    NonFiniteEnergy {
        /// The iteration (0: the initial guess).
        iteration: usize,
        /// The energy (infinite or NaN).
        value: f64,
    },
    /// A back end could not allocate what it needs (faer's `OutOfMemory`,
    /// a workspace the allocator refused under an address-space limit).
    /// Not a numerical failure: as an [`Error`] it is
    /// [`ProblemError::TooLarge`] (the CLI's exit code 2, Python's
    /// `TooLargeError`), like every refusal for size.
    #[error("{backend}: allocating {what} failed")]
    OutOfMemory {
        /// The back end.
        backend: String,
        /// What it was allocating.
        what: String,
    },
    /// A back end reported an error.
    #[error("{backend}: {message}")]
    Backend {
        /// The back end.
        backend: String,
        /// Its message.
        message: String,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A back end's allocation failure reaches every door as a refusal for
    /// size (exit code 2), and every other numerical error as one (exit
    /// code 3): the conversion `?` applies at each seam.
    #[test]
    fn a_back_ends_out_of_memory_is_a_refusal_for_size() {
        let oom: Error = NumericalError::out_of_memory("faer-auto", "the workspace").into();
        match &oom {
            Error::Problem(ProblemError::TooLarge { detail }) => {
                assert!(
                    detail.starts_with("faer-auto: allocating the workspace failed"),
                    "{detail}"
                );
            }
            other => panic!("expected TooLarge, got {other:?}"),
        }
        assert_eq!(oom.exit_code(), 2);
        let from_faer = |e| Error::from(NumericalError::from_faer("faer-auto", "the factor", e));
        let overflow = from_faer(faer::sparse::FaerError::IndexOverflow);
        assert!(
            matches!(overflow, Error::Numerical(NumericalError::Backend { .. })),
            "{overflow:?}"
        );
        assert_eq!(overflow.exit_code(), 3);
        let oom_faer = from_faer(faer::sparse::FaerError::OutOfMemory);
        assert_eq!(oom_faer.exit_code(), 2, "{oom_faer}");
    }
}
