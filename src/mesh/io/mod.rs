//! Mesh file I/O: OBJ, PLY (ASCII and binary), OFF; optionally gzip-compressed.
//! Vertex order is always kept as in the file.
//!
//! # Reading
//!
//! [`read_mesh`] picks the format from the extension (`.obj`, `.ply`, `.off`,
//! each optionally followed by `.gz`); whether the data is gzip-compressed is
//! decided by its first two bytes (`1f 8b`), so a mislabelled file still
//! reads (with a note). [`read_mesh_bytes`] does the same on bytes in memory.
//! Every reader:
//! - keeps the file's vertex order and 0-based numbering (OBJ's 1-based and
//!   relative indices are resolved);
//! - fan-triangulates polygons `(v0, v1, …, vk)` into
//!   `(v0, v1, v2), (v0, v2, v3), …, (v0, v(k−1), vk)` and says so in
//!   [`LoadedMesh::notes`]; polygons with fewer than 3 vertices are an error;
//! - builds the mesh with [`Mesh::new`], so every invariant of
//!   [`super`] is checked; errors naming a vertex or face carry the file line
//!   when the format is line-based (see [`MeshError`]);
//! - never panics and never allocates from a count in the file that the
//!   file's size cannot back (PLY and OFF headers are checked against the
//!   bytes that follow them before any payload is read).
//!
//! Why hand-written parsers for OBJ and OFF: `tobj` reorders vertices by
//! first use and drops unreferenced ones (the crate's constraints refer to
//! vertices by file index, so the order must be kept exactly), and
//! `obj-rs`/`off-rs` parse `f32` (we need the file's `f64` values bit for
//! bit). PLY uses `ply-rs-bw` for the header and element decoding.
//!
//! ## OBJ
//! Records `v x y z [w …]` (anything after `z`, e.g. `w` or vertex colours,
//! is ignored) and `f` with index forms `i`, `i/j`, `i//k`, `i/j/k`; indices
//! are 1-based, negative indices count back from the last vertex defined so
//! far (`-1` is the latest). `vn vt vp g o s usemtl mtllib l`, comments
//! (`#` to end of line), blank lines and unknown record types are ignored
//! (unknown ones are listed in a note). One record per line (no `\`
//! continuation lines).
//!
//! ## PLY
//! ASCII, binary little- and big-endian. Needs an element `vertex` with
//! scalar properties `x`, `y`, `z` (any numeric type; converted exactly to
//! `f64`) and an element `face` with a list property `vertex_indices` (or
//! `vertex_index`) of any integer types. Other elements and properties are
//! skipped. Bytes after the last element (other than whitespace) are an
//! error: they mean the header's counts do not match the data.
//!
//! ## OFF
//! An optional header line `OFF` (also `COFF`, `NOFF`, `CNOFF`, `STOFF`, …;
//! counts may follow on the same line), then a line `V F [E]`, `V` vertex
//! lines `x y z […]` (extra values such as colours or normals ignored) and
//! `F` face lines `k i0 … i(k−1) […]` (0-based indices; trailing colour
//! values ignored). `#` starts a comment; blank lines are skipped. One vertex
//! or face per line. Binary OFF and 4D/nD OFF are refused.
//!
//! # Writing
//!
//! [`write_mesh`] picks the format from the extension (`.gz` compresses).
//! Writers keep vertex and face order, and write coordinates so that reading
//! back gives bit-identical `f64` values: OBJ, OFF and ASCII PLY use Rust's
//! shortest round-trip decimal formatting (`{}`), binary PLY writes the
//! IEEE-754 doubles themselves.

mod obj;
mod off;
mod ply;

use std::fs::File;
use std::io::{self, BufRead, BufReader, Write};
use std::path::Path;

use flate2::Compression;
use flate2::read::MultiGzDecoder;
use flate2::write::GzEncoder;

use super::Mesh;
use crate::error::{Error, MeshError};
use crate::limits::{self, MemoryBudget};

use obj::read_obj;
pub use obj::write_obj;
use off::read_off;
pub use off::write_off;
use ply::read_ply;
pub use ply::{PlyEncoding, write_ply};

/// A supported mesh file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ.
    Obj,
    /// Stanford PLY.
    Ply,
    /// Object File Format.
    Off,
}

impl MeshFormat {
    /// The format named by a path's extension, case-insensitively, and
    /// whether the extension says gzip (`.obj.gz` gives `(Obj, true)`).
    pub fn from_path(path: &Path) -> Result<(MeshFormat, bool), MeshError> {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        let (stem, gzip) = match name.strip_suffix(".gz") {
            Some(stem) => (stem, true),
            None => (name.as_str(), false),
        };
        let format = if stem.ends_with(".obj") {
            MeshFormat::Obj
        } else if stem.ends_with(".ply") {
            MeshFormat::Ply
        } else if stem.ends_with(".off") {
            MeshFormat::Off
        } else {
            let extension = match stem.rfind('.') {
                Some(i) => stem[i..].to_string(),
                None => String::from("(none)"),
            };
            let extension = if gzip {
                format!("{extension}.gz")
            } else {
                extension
            };
            return Err(MeshError::UnsupportedFormat { extension });
        };
        Ok((format, gzip))
    }

    /// The format's name as used in error messages: `"OBJ"`, `"PLY"`,
    /// `"OFF"`.
    pub fn name(self) -> &'static str {
        match self {
            MeshFormat::Obj => "OBJ",
            MeshFormat::Ply => "PLY",
            MeshFormat::Off => "OFF",
        }
    }
}

/// A mesh read from a file, with notes on what the reader did (e.g. polygons
/// fan-triangulated).
#[derive(Debug, Clone)]
pub struct LoadedMesh {
    /// The mesh.
    pub mesh: Mesh,
    /// Human-readable notes for the user (one sentence each, no trailing
    /// newline); empty when the file was read exactly as a triangle mesh.
    pub notes: Vec<String>,
}

/// Failure inside a reader: bad data, or the underlying reader failed
/// (I/O error, corrupt gzip stream).
enum ReadError {
    Mesh(MeshError),
    Io(io::Error),
}

impl From<MeshError> for ReadError {
    fn from(e: MeshError) -> Self {
        ReadError::Mesh(e)
    }
}

impl From<io::Error> for ReadError {
    fn from(e: io::Error) -> Self {
        ReadError::Io(e)
    }
}

const GZIP_MAGIC: [u8; 2] = [0x1f, 0x8b];

/// [`read_mesh`] within the budget of `resources` ([`crate::limits`]): a regular file whose
/// size (× [`limits::GZIP_EXPANSION`] when compressed) would need more is
/// refused before it is read; whatever the source (a pipe, a device,
/// gzip-compressed data), at most `budget / `[`limits::MESH_BYTES_PER_FILE_BYTE`]
/// bytes are read (after decompression), and data that goes on beyond is
/// refused ([`MeshError::TooLarge`], naming the budget and the bytes read),
/// never parsed as the mesh its first part may be; the mesh assembled is
/// checked as it grows.
pub fn read_mesh(path: &Path, budget: MemoryBudget) -> Result<LoadedMesh, Error> {
    let (format, gzip_ext) = MeshFormat::from_path(path)?;
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    // Only a regular file's length is the number of bytes it will deliver
    // (a pipe reports 0).
    let size = file
        .metadata()
        .ok()
        .filter(|m| m.is_file())
        .map(|m| m.len());
    let mut reader = BufReader::with_capacity(1 << 16, file);
    let head = reader.fill_buf().map_err(|e| Error::io(path, e))?;
    let gzip = head.starts_with(&GZIP_MAGIC);
    if let Some(size) = size {
        let expansion = if gzip { limits::GZIP_EXPANSION } else { 1 };
        let estimate = size
            .saturating_mul(expansion)
            .saturating_mul(limits::MESH_BYTES_PER_FILE_BYTE);
        budget
            .check(estimate, || {
                format!(
                    "{} ({}{}) would need",
                    path.display(),
                    limits::format_bytes(size),
                    if gzip { ", gzip-compressed" } else { "" }
                )
            })
            .map_err(|detail| MeshError::TooLarge {
                what: "mesh file",
                detail,
            })?;
    }
    let name = path.display().to_string();
    let result = if gzip {
        let decoder = BufReader::with_capacity(1 << 16, MultiGzDecoder::new(reader));
        read_capped(decoder, format, None, budget, &name, true)
    } else {
        read_capped(reader, format, size, budget, &name, false)
    };
    match result {
        Ok(mut loaded) => {
            if gzip != gzip_ext {
                loaded.notes.insert(
                    0,
                    if gzip {
                        "the file is gzip-compressed although its name does not end in .gz"
                            .to_string()
                    } else {
                        "the file is not gzip-compressed although its name ends in .gz; read it as plain text".to_string()
                    },
                );
            }
            Ok(loaded)
        }
        Err(ReadError::Mesh(e)) => Err(Error::Mesh(e)),
        Err(ReadError::Io(e)) if gzip => Err(Error::io(
            path,
            io::Error::new(
                e.kind(),
                format!("reading gzip-compressed data: {e} (the file may be truncated or corrupt)"),
            ),
        )),
        Err(ReadError::Io(e)) => Err(Error::io(path, e)),
    }
}

/// Reads a mesh of `format` from `reader`, at most the bytes whose
/// estimate fits `budget`: data that reaches the cap is refused whatever
/// its first part parses as (a mesh cut short at a line or a face can be
/// a valid smaller mesh). `name` names the source in the refusal;
/// `decompressed` says the bytes counted are gzip's output.
fn read_capped<R: BufRead>(
    reader: R,
    format: MeshFormat,
    size: Option<u64>,
    budget: MemoryBudget,
    name: &str,
    decompressed: bool,
) -> Result<LoadedMesh, ReadError> {
    let cap = budget.limit() / limits::MESH_BYTES_PER_FILE_BYTE;
    let mut capped = io::Read::take(reader, cap.saturating_add(1));
    let result = read_from(&mut capped, format, size, budget);
    if capped.limit() > 0 {
        return result;
    }
    let after = if decompressed {
        " after decompression"
    } else {
        ""
    };
    Err(MeshError::TooLarge {
        what: "mesh file",
        detail: limits::beyond_the_cap(
            budget,
            name,
            cap,
            after,
            limits::MESH_BYTES_PER_FILE_BYTE,
            "mesh",
        ),
    }
    .into())
}

/// [`read_mesh_bytes`] within the budget of `resources`: what is
/// decompressed is capped as [`read_mesh`] caps a stream, and refused
/// beyond the cap.
pub fn read_mesh_bytes(
    bytes: &[u8],
    format: MeshFormat,
    budget: MemoryBudget,
) -> Result<LoadedMesh, MeshError> {
    let name = "the data";
    let result = if bytes.starts_with(&GZIP_MAGIC) {
        let decoder = BufReader::new(MultiGzDecoder::new(bytes));
        read_capped(decoder, format, None, budget, name, true)
    } else {
        read_capped(
            bytes,
            format,
            u64::try_from(bytes.len()).ok(),
            budget,
            name,
            false,
        )
    };
    result.map_err(|e| match e {
        ReadError::Mesh(e) => e,
        ReadError::Io(e) => MeshError::Parse {
            format: format.name(),
            line: None,
            message: format!("could not read the data: {e}"),
        },
    })
}

/// Dispatches on the format; `size` is the number of bytes `reader` will
/// deliver, when known (not for gzip).
fn read_from<R: BufRead>(
    mut reader: R,
    format: MeshFormat,
    size: Option<u64>,
    budget: MemoryBudget,
) -> Result<LoadedMesh, ReadError> {
    match format {
        MeshFormat::Obj => read_obj(reader, budget),
        MeshFormat::Off => read_off(reader, size, budget),
        MeshFormat::Ply => {
            let head = reader.fill_buf()?;
            let n = head.len().min(3);
            if head[..n] != b"ply"[..n] {
                // Not a PLY file: the parser's message on what has arrived,
                // without reading the rest of the stream (which may not end).
                return read_ply(head, budget);
            }
            let mut bytes = Vec::new();
            reader.read_to_end(&mut bytes)?;
            read_ply(&bytes, budget)
        }
    }
}

// ---------------------------------------------------------------------------
// Shared helpers

/// The longest line the text readers read: a stream without line breaks
/// (`/dev/zero`) is refused here instead of read into memory to
/// exhaustion. (A polygon of a million vertices fits.)
pub const MAX_LINE_BYTES: usize = 16 << 20;

/// A line-by-line reader over bytes: lines without their `\n` / `\r\n`,
/// numbered from 1, each at most [`MAX_LINE_BYTES`].
struct LineReader<R> {
    reader: R,
    format: &'static str,
    buf: Vec<u8>,
    line: usize,
    missing_final_newline: bool,
}

impl<R: BufRead> LineReader<R> {
    fn new(reader: R, format: &'static str) -> Self {
        LineReader {
            reader,
            format,
            buf: Vec::new(),
            line: 0,
            missing_final_newline: false,
        }
    }

    /// The next line and its 1-based number, `None` at the end.
    fn next_line(&mut self) -> Result<Option<(usize, &[u8])>, ReadError> {
        self.buf.clear();
        let limit = MAX_LINE_BYTES as u64 + 1;
        if io::Read::take(&mut self.reader, limit).read_until(b'\n', &mut self.buf)? == 0 {
            return Ok(None);
        }
        self.line += 1;
        if self.buf.len() > MAX_LINE_BYTES {
            return Err(MeshError::Parse {
                format: self.format,
                line: Some(self.line),
                message: format!(
                    "the line is longer than {} (not a text {} file?)",
                    limits::format_bytes(MAX_LINE_BYTES as u64),
                    self.format
                ),
            }
            .into());
        }
        if self.buf.last() == Some(&b'\n') {
            self.buf.pop();
        } else {
            self.missing_final_newline = true;
        }
        if self.buf.last() == Some(&b'\r') {
            self.buf.pop();
        }
        Ok(Some((self.line, &self.buf)))
    }
}

/// The part of a line before a `#` comment.
fn strip_comment(line: &[u8]) -> &[u8] {
    match line.iter().position(|&b| b == b'#') {
        Some(i) => &line[..i],
        None => line,
    }
}

/// Whitespace-separated tokens of a line.
fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| b.is_ascii_whitespace())
        .filter(|t| !t.is_empty())
}

/// A token for an error message: lossy UTF-8, at most 40 characters.
fn show(token: &[u8]) -> String {
    let s = String::from_utf8_lossy(token);
    if s.chars().count() > 40 {
        format!("{}…", s.chars().take(40).collect::<String>())
    } else {
        s.into_owned()
    }
}

fn parse_f64(token: &[u8]) -> Option<f64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

fn parse_i64(token: &[u8]) -> Option<i64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

fn parse_error(format: &'static str, line: usize, message: impl Into<String>) -> MeshError {
    MeshError::Parse {
        format,
        line: Some(line),
        message: message.into(),
    }
}

/// Positions and triangles being assembled by a reader, with the source line
/// of every vertex and triangle (empty for binary formats) so that
/// validation errors can name the line, within a memory budget.
#[derive(Default)]
struct Builder {
    positions: Vec<[f64; 3]>,
    faces: Vec<[usize; 3]>,
    vertex_lines: Vec<usize>,
    face_lines: Vec<usize>,
    polygons_split: usize,
    triangles_from_polygons: usize,
    budget: MemoryBudget,
}

impl Builder {
    /// An empty mesh to assemble within `budget`.
    fn within(budget: MemoryBudget) -> Builder {
        Builder {
            budget,
            ..Builder::default()
        }
    }

    /// Makes room for `vertices` more vertices and `faces` more triangles,
    /// refusing it when the lists' estimate ([`limits::MESH_BYTES_PER_VERTEX`],
    /// [`limits::MESH_BYTES_PER_FACE`]) at the capacity they then have
    /// exceeds the budget, or when the allocator cannot give that capacity
    /// (under an address-space limit): a list that is full doubles, as a
    /// `Vec` would, so that it is the capacity, up to twice the length,
    /// that the memory holds. A polygon of short indices (`f 1 2 3 4 …`)
    /// is 2 bytes a triangle in the file and 32 in memory, beyond what the
    /// cap on the bytes read bounds.
    fn make_room(&mut self, vertices: usize, faces: usize) -> Result<(), MeshError> {
        let v = self.positions.len() + vertices;
        let f = self.faces.len() + faces;
        let (v_cap, f_cap) = (grown(&self.positions, v), grown(&self.faces, f));
        let estimate = (v_cap as u64)
            .saturating_mul(limits::MESH_BYTES_PER_VERTEX)
            .saturating_add((f_cap as u64).saturating_mul(limits::MESH_BYTES_PER_FACE));
        let what = || format!("the {v} vertices and {f} triangles read so far");
        let too_large = |detail| MeshError::TooLarge {
            what: "mesh",
            detail,
        };
        self.budget
            .check(estimate, || {
                format!("{} (room for {v_cap} and {f_cap}) would need", what())
            })
            .map_err(too_large)?;
        let lines = |lines: &Vec<usize>, cap| if lines.is_empty() { 0 } else { cap };
        let (v_lines, f_lines) = (
            lines(&self.vertex_lines, v_cap),
            lines(&self.face_lines, f_cap),
        );
        reserve_to(&mut self.positions, v_cap)
            .and_then(|()| reserve_to(&mut self.vertex_lines, v_lines))
            .and_then(|()| reserve_to(&mut self.faces, f_cap))
            .and_then(|()| reserve_to(&mut self.face_lines, f_lines))
            .map_err(|e| {
                too_large(format!(
                    "{} could not be given room for {v_cap} and {f_cap} ({}; about {} in all, within the memory budget of {} but not what the system allows)",
                    what(),
                    e,
                    limits::format_bytes(estimate),
                    limits::format_bytes(self.budget.limit()),
                ))
            })
    }

    /// Adds a vertex, refusing non-finite coordinates.
    fn vertex(&mut self, p: [f64; 3], line: Option<usize>) -> Result<(), MeshError> {
        if let Some(&value) = p.iter().find(|c| !c.is_finite()) {
            return Err(MeshError::NonFiniteCoordinate {
                vertex: self.positions.len(),
                value,
                line,
            });
        }
        self.make_room(1, 0)?;
        self.positions.push(p);
        if let Some(l) = line {
            self.vertex_lines.push(l);
        }
        Ok(())
    }

    /// Resolves one polygon corner given as a 0-based (possibly negative)
    /// index; `corner` is its position in the polygon (for the face index of
    /// the error).
    fn resolve(&self, index: i64, corner: usize, line: Option<usize>) -> Result<usize, MeshError> {
        usize::try_from(index).map_err(|_| MeshError::IndexOutOfRange {
            face: self.faces.len() + corner.saturating_sub(2),
            index,
            vertex_count: self.positions.len(),
            line,
        })
    }

    /// Adds a polygon (0-based indices), fan-triangulated.
    fn polygon(&mut self, poly: &[usize], line: Option<usize>) -> Result<(), MeshError> {
        if poly.len() < 3 {
            return Err(MeshError::BadFaceSize {
                face: self.faces.len(),
                sides: poly.len(),
                line,
            });
        }
        self.make_room(0, poly.len() - 2)?;
        if poly.len() > 3 {
            self.polygons_split += 1;
            self.triangles_from_polygons += poly.len() - 2;
        }
        for k in 1..poly.len() - 1 {
            self.faces.push([poly[0], poly[k], poly[k + 1]]);
            if let Some(l) = line {
                self.face_lines.push(l);
            }
        }
        Ok(())
    }

    /// Validates and returns the mesh, attaching lines to errors.
    fn finish(self, format: &'static str, mut notes: Vec<String>) -> Result<LoadedMesh, MeshError> {
        let Builder {
            positions,
            faces,
            vertex_lines,
            face_lines,
            polygons_split,
            triangles_from_polygons,
            budget: _,
        } = self;
        if polygons_split > 0 {
            notes.push(format!(
                "{polygons_split} {format} polygon(s) with more than 3 vertices were fan-triangulated into {triangles_from_polygons} triangles"
            ));
        }
        match Mesh::new(positions, faces) {
            Ok(mesh) => Ok(LoadedMesh { mesh, notes }),
            Err(e) => {
                if let Some(v) = e.located_vertex() {
                    Err(e.with_line(vertex_lines.get(v).copied()))
                } else if let Some(f) = e.located_face() {
                    Err(e.with_line(face_lines.get(f).copied()))
                } else {
                    Err(e)
                }
            }
        }
    }
}

/// The capacity `list` has once it holds `len` items: its own when that
/// suffices, else twice it (at least `len`, at least 4), as `Vec` grows.
fn grown<T>(list: &Vec<T>, len: usize) -> usize {
    if len <= list.capacity() {
        list.capacity()
    } else {
        len.max(list.capacity().saturating_mul(2)).max(4)
    }
}

/// Reserves `list` up to a capacity of `cap` (no change when it has that),
/// reporting an allocation failure instead of aborting.
fn reserve_to<T>(list: &mut Vec<T>, cap: usize) -> Result<(), std::collections::TryReserveError> {
    list.try_reserve_exact(cap.saturating_sub(list.len()))
}

/// Refuses a header whose counts would not fit in the memory budget
/// ([`crate::limits`]), before anything is reserved.
fn check_declared_counts(
    n_vertices: usize,
    n_faces: usize,
    budget: MemoryBudget,
) -> Result<(), MeshError> {
    let estimate = (n_vertices as u64)
        .saturating_mul(limits::MESH_BYTES_PER_VERTEX)
        .saturating_add((n_faces as u64).saturating_mul(limits::MESH_BYTES_PER_FACE));
    budget
        .check(estimate, || {
            format!("the header's {n_vertices} vertices and {n_faces} faces would need")
        })
        .map_err(|detail| MeshError::TooLarge {
            what: "mesh",
            detail,
        })
}

// ---------------------------------------------------------------------------
// Writers

/// Checks, before any work, that [`write_mesh`] will be able to write
/// `path`: the extension names a format it writes and the file can be opened
/// for writing (the directory exists, permissions allow it). See
/// [`check_writable`], whose notes it returns.
pub fn check_mesh_output(path: &Path) -> Result<Vec<String>, Error> {
    MeshFormat::from_path(path)?;
    check_writable(path)
}

/// Checks that `path` can be opened for writing, without changing it: an
/// existing file is opened for writing and left as it is (no truncation), a
/// missing one is created and removed again. Lets a command refuse a
/// misspelt directory or a read-only location before a long computation
/// instead of after it. A FIFO is checked and readied by
/// [`crate::atomic::prepare`] (refused without a reader, kept open for the
/// write with one), which also finishes an interrupted set of renames
/// `path` belongs to: the notes returned say so.
pub fn check_writable(path: &Path) -> Result<Vec<String>, Error> {
    let notes = crate::atomic::prepare(path).map_err(|e| Error::io(path, e))?;
    #[cfg(unix)]
    {
        // Opened by `prepare` already; another open and close here would
        // end its reader's input.
        use std::os::unix::fs::FileTypeExt;
        if std::fs::metadata(path).is_ok_and(|m| m.file_type().is_fifo()) {
            return Ok(notes);
        }
    }
    let existed = path.symlink_metadata().is_ok();
    std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(false)
        .open(path)
        .map_err(|e| Error::io(path, e))?;
    if !existed {
        std::fs::remove_file(path).map_err(|e| Error::io(path, e))?;
    }
    Ok(notes)
}

/// Writes a mesh, choosing the format from the extension: `.obj`, `.off`,
/// `.ply` (binary little-endian, double coordinates), each optionally
/// followed by `.gz` (gzip-compressed). Atomically ([`crate::atomic`]): on
/// an error (a full disk) a previous file at `path` is left as it was.
pub fn write_mesh(mesh: &Mesh, path: &Path) -> Result<(), Error> {
    let (format, gzip) = MeshFormat::from_path(path)?;
    crate::atomic::write(path, |out| {
        if gzip {
            let mut gz = GzEncoder::new(out, Compression::default());
            write_format(mesh, &mut gz, format).and_then(|()| gz.finish().map(|_| ()))
        } else {
            write_format(mesh, out, format)
        }
    })
    .map_err(|e| Error::io(path, e))
}

fn write_format<W: Write>(mesh: &Mesh, w: W, format: MeshFormat) -> io::Result<()> {
    match format {
        MeshFormat::Obj => write_obj(mesh, w),
        MeshFormat::Off => write_off(mesh, w),
        MeshFormat::Ply => write_ply(mesh, w, PlyEncoding::BinaryLittleEndian),
    }
}

/// A reader's result with I/O failures turned into a panic: the unit tests
/// read from memory, where only [`ReadError::Mesh`] can occur.
#[cfg(test)]
fn unwrap_io(result: Result<LoadedMesh, ReadError>) -> Result<LoadedMesh, MeshError> {
    match result {
        Ok(loaded) => Ok(loaded),
        Err(ReadError::Mesh(e)) => Err(e),
        Err(ReadError::Io(e)) => panic!("unexpected I/O error: {e}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every line of `bytes` as (number, text), and whether the last line
    /// lacked its newline.
    fn all_lines(bytes: &[u8]) -> (Vec<(usize, Vec<u8>)>, bool) {
        let mut lines = LineReader::new(bytes, "OBJ");
        let mut out = Vec::new();
        while let Ok(Some((n, text))) = lines.next_line() {
            out.push((n, text.to_vec()));
        }
        (out, lines.missing_final_newline)
    }

    #[test]
    fn line_reader_strips_one_lf_or_crlf_and_numbers_from_one() {
        let (lines, missing) = all_lines(b"a\r\nb\n\nc\r\r\n d ");
        let expected: Vec<(usize, Vec<u8>)> = vec![
            (1, b"a".to_vec()),
            (2, b"b".to_vec()),
            (3, b"".to_vec()),
            (4, b"c\r".to_vec()),
            (5, b" d ".to_vec()),
        ];
        assert_eq!(lines, expected);
        assert!(missing);
        let (lines, missing) = all_lines(b"x\n");
        assert_eq!(lines, vec![(1, b"x".to_vec())]);
        assert!(!missing);
    }

    #[test]
    fn line_reader_refuses_a_line_longer_than_the_limit() {
        let endless = io::BufReader::new(io::repeat(b'x'));
        let mut lines = LineReader::new(endless, "OFF");
        match lines.next_line() {
            Err(ReadError::Mesh(e)) => assert_eq!(
                e,
                MeshError::Parse {
                    format: "OFF",
                    line: Some(1),
                    message: "the line is longer than 16.0 MiB (not a text OFF file?)".into(),
                }
            ),
            Err(ReadError::Io(e)) => panic!("{e}"),
            Ok(line) => panic!("read {:?}", line.map(|(n, t)| (n, t.len()))),
        }
        // The limit counts the line break: MAX_LINE_BYTES bytes with it, or
        // at the end of the data without it, are a line; one more is not.
        let mut bytes = vec![b'y'; MAX_LINE_BYTES - 1];
        bytes.push(b'\n');
        let mut lines = LineReader::new(&bytes[..], "OFF");
        assert!(matches!(lines.next_line(), Ok(Some((1, t))) if t.len() == MAX_LINE_BYTES - 1));
        let bytes = vec![b'y'; MAX_LINE_BYTES];
        let mut lines = LineReader::new(&bytes[..], "OFF");
        assert!(matches!(lines.next_line(), Ok(Some((1, t))) if t.len() == MAX_LINE_BYTES));
        let mut bytes = vec![b'y'; MAX_LINE_BYTES];
        bytes.push(b'\n');
        let mut lines = LineReader::new(&bytes[..], "OFF");
        assert!(matches!(
            lines.next_line(),
            Err(ReadError::Mesh(MeshError::Parse { line: Some(1), .. }))
        ));
    }

    #[test]
    fn comments_tokens_and_shown_tokens() {
        assert_eq!(strip_comment(b"v 1 2 3 # note # more"), b"v 1 2 3 ");
        assert_eq!(strip_comment(b"#only"), b"");
        let t: Vec<&[u8]> = tokens(b"\t f  1/2/3\x0b 4 ").collect();
        assert_eq!(t, vec![&b"f"[..], b"1/2/3\x0b", b"4"]);
        assert_eq!(show(b"abc"), "abc");
        let long = [b'z'; 41];
        assert_eq!(show(&long), format!("{}…", "z".repeat(40)));
        assert_eq!(show(b"\xff1"), "\u{fffd}1");
    }

    #[test]
    fn builder_fans_polygons_and_numbers_a_bad_corner_by_its_triangle() {
        let mut b = Builder::default();
        b.polygon(&[7, 8, 9], Some(1)).unwrap();
        b.polygon(&[0, 1, 2, 3, 4], Some(2)).unwrap();
        assert_eq!(b.faces, vec![[7, 8, 9], [0, 1, 2], [0, 2, 3], [0, 3, 4]]);
        assert_eq!(b.face_lines, vec![1, 2, 2, 2]);
        assert_eq!((b.polygons_split, b.triangles_from_polygons), (1, 3));
        // With 4 faces so far, corner 4 of the next polygon would land in
        // its third triangle: face 4 + 2 = 6. Corners 0..=2 land in the first.
        assert_eq!(
            b.resolve(-2, 4, Some(3)),
            Err(MeshError::IndexOutOfRange {
                face: 6,
                index: -2,
                vertex_count: 0,
                line: Some(3),
            })
        );
        assert!(matches!(
            b.resolve(-1, 1, None),
            Err(MeshError::IndexOutOfRange { face: 4, .. })
        ));
        assert_eq!(b.resolve(5, 0, None), Ok(5));
        assert_eq!(
            b.polygon(&[1, 2], Some(9)),
            Err(MeshError::BadFaceSize {
                face: 4,
                sides: 2,
                line: Some(9),
            })
        );
    }
}
