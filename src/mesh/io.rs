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

use std::fs::File;
use std::io::{self, BufRead, BufReader, Write};
use std::path::Path;

use flate2::Compression;
use flate2::read::MultiGzDecoder;
use flate2::write::GzEncoder;
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    ElementDef, Encoding, PropertyAccess, PropertyAccessResult, PropertyType, ScalarType,
};

use super::Mesh;
use crate::error::{Error, MeshError};
use crate::limits;

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

/// Encoding of a written PLY file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlyEncoding {
    /// `format ascii 1.0`, coordinates in shortest round-trip decimal.
    Ascii,
    /// `format binary_little_endian 1.0` (the default of [`write_mesh`]).
    BinaryLittleEndian,
    /// `format binary_big_endian 1.0`.
    BinaryBigEndian,
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

/// Reads a mesh, choosing the format from the extension (`.obj`, `.ply`,
/// `.off`, each optionally followed by `.gz`; gzip is detected from the
/// content). See the module documentation for what each reader accepts.
pub fn read_mesh(path: &Path) -> Result<LoadedMesh, Error> {
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
        limits::check(estimate, || {
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
    // Whatever the source (a pipe, a device, a gzip bomb), no more is read
    // than the memory budget allows for a file.
    let cap = limits::memory_budget() / limits::MESH_BYTES_PER_FILE_BYTE;
    let (result, beyond_cap) = if gzip {
        let decoder = BufReader::with_capacity(1 << 16, MultiGzDecoder::new(reader));
        let mut capped = io::Read::take(decoder, cap + 1);
        (read_from(&mut capped, format, None), capped.limit() == 0)
    } else {
        let mut capped = io::Read::take(reader, cap + 1);
        (read_from(&mut capped, format, size), capped.limit() == 0)
    };
    if beyond_cap && result.is_err() {
        let detail = limits::check(
            (cap + 1).saturating_mul(limits::MESH_BYTES_PER_FILE_BYTE),
            || {
                format!(
                    "{} (more than {}{}) would need",
                    path.display(),
                    limits::format_bytes(cap),
                    if gzip { " decompressed" } else { "" }
                )
            },
        )
        .err()
        .unwrap_or_else(|| format!("{} delivered more than {cap} bytes", path.display()));
        return Err(MeshError::TooLarge {
            what: "mesh file",
            detail,
        }
        .into());
    }
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

/// Reads a mesh of the given format from bytes in memory (gzip-compressed
/// data, recognised by its magic number, is decompressed first). Never
/// panics, whatever the bytes.
pub fn read_mesh_bytes(bytes: &[u8], format: MeshFormat) -> Result<LoadedMesh, MeshError> {
    let result = if bytes.starts_with(&GZIP_MAGIC) {
        read_from(BufReader::new(MultiGzDecoder::new(bytes)), format, None)
    } else {
        read_from(bytes, format, u64::try_from(bytes.len()).ok())
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
) -> Result<LoadedMesh, ReadError> {
    match format {
        MeshFormat::Obj => read_obj(reader),
        MeshFormat::Off => read_off(reader, size),
        MeshFormat::Ply => {
            let head = reader.fill_buf()?;
            let n = head.len().min(3);
            if head[..n] != b"ply"[..n] {
                // Not a PLY file: the parser's message on what has arrived,
                // without reading the rest of the stream (which may not end).
                return read_ply(head);
            }
            let mut bytes = Vec::new();
            reader.read_to_end(&mut bytes)?;
            read_ply(&bytes)
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
/// validation errors can name the line.
#[derive(Default)]
struct Builder {
    positions: Vec<[f64; 3]>,
    faces: Vec<[usize; 3]>,
    vertex_lines: Vec<usize>,
    face_lines: Vec<usize>,
    polygons_split: usize,
    triangles_from_polygons: usize,
}

impl Builder {
    /// Adds a vertex, refusing non-finite coordinates.
    fn vertex(&mut self, p: [f64; 3], line: Option<usize>) -> Result<(), MeshError> {
        if let Some(&value) = p.iter().find(|c| !c.is_finite()) {
            return Err(MeshError::NonFiniteCoordinate {
                vertex: self.positions.len(),
                value,
                line,
            });
        }
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

// ---------------------------------------------------------------------------
// OBJ

fn read_obj<R: BufRead>(reader: R) -> Result<LoadedMesh, ReadError> {
    const F: &str = "OBJ";
    let mut lines = LineReader::new(reader, F);
    let mut b = Builder::default();
    let mut poly: Vec<usize> = Vec::new();
    let mut unknown: Vec<(String, usize)> = Vec::new();
    let mut n_unknown = 0usize;
    while let Some((line, text)) = lines.next_line()? {
        let mut it = tokens(strip_comment(text));
        let Some(keyword) = it.next() else { continue };
        match keyword {
            b"v" => {
                let mut p = [0.0; 3];
                for (k, c) in p.iter_mut().enumerate() {
                    let Some(tok) = it.next() else {
                        return Err(parse_error(
                            F,
                            line,
                            format!("expected 3 coordinates after 'v', found {k}"),
                        )
                        .into());
                    };
                    *c = parse_f64(tok).ok_or_else(|| {
                        parse_error(F, line, format!("invalid number '{}'", show(tok)))
                    })?;
                }
                b.vertex(p, Some(line))?;
            }
            b"f" => {
                poly.clear();
                for (corner, tok) in it.enumerate() {
                    let head = tok.split(|&c| c == b'/').next().unwrap_or_default();
                    let index = parse_i64(head).ok_or_else(|| {
                        parse_error(F, line, format!("invalid face index '{}'", show(tok)))
                    })?;
                    let resolved = match index {
                        0 => {
                            return Err(parse_error(
                                F,
                                line,
                                "face index 0 is invalid (OBJ indices start at 1)",
                            )
                            .into());
                        }
                        i if i > 0 => i - 1,
                        // Relative: -1 is the last vertex defined so far.
                        i => i64::try_from(b.positions.len())
                            .unwrap_or(i64::MAX)
                            .saturating_add(i),
                    };
                    poly.push(b.resolve(resolved, corner, Some(line))?);
                }
                b.polygon(&poly, Some(line))?;
            }
            b"vn" | b"vt" | b"vp" | b"g" | b"o" | b"s" | b"usemtl" | b"mtllib" | b"l" => {}
            other => {
                n_unknown += 1;
                if unknown.len() < 3 && !unknown.iter().any(|(k, _)| k.as_bytes() == other) {
                    unknown.push((show(other), line));
                }
            }
        }
    }
    let mut notes = Vec::new();
    if n_unknown > 0 {
        let examples: Vec<String> = unknown
            .iter()
            .map(|(k, l)| format!("'{k}' at line {l}"))
            .collect();
        notes.push(format!(
            "ignored {n_unknown} OBJ line(s) of unsupported record types (e.g. {})",
            examples.join(", ")
        ));
    }
    if lines.missing_final_newline {
        notes.push(format!(
            "the OBJ file does not end with a newline: if it was cut off, line {} may be incomplete",
            lines.line
        ));
    }
    Ok(b.finish(F, notes)?)
}

// ---------------------------------------------------------------------------
// OFF

/// Bytes needed at least by one OFF vertex line (`"0 0 0\n"`) and one face
/// line (`"3 0 1 2\n"`).
const OFF_MIN_VERTEX_BYTES: u128 = 6;
const OFF_MIN_FACE_BYTES: u128 = 8;

/// Without a known size, never reserve more than this many elements up
/// front (vectors still grow as data arrives).
const MAX_BLIND_RESERVE: usize = 1 << 20;

/// The next line with content (comments stripped), or a parse error saying
/// what was expected.
fn next_content<R: BufRead>(
    lines: &mut LineReader<R>,
) -> Result<Option<(usize, &[u8])>, ReadError> {
    loop {
        // Two-step to satisfy the borrow checker: test, then re-borrow.
        let has_content = match lines.next_line()? {
            None => return Ok(None),
            Some((_, text)) => tokens(strip_comment(text)).next().is_some(),
        };
        if has_content {
            let line = lines.line;
            return Ok(Some((line, strip_comment(&lines.buf))));
        }
    }
}

fn read_off<R: BufRead>(reader: R, size: Option<u64>) -> Result<LoadedMesh, ReadError> {
    const F: &str = "OFF";
    let mut notes = Vec::new();
    let mut lines = LineReader::new(reader, F);
    let Some((first_line, text)) = next_content(&mut lines)? else {
        return Err(MeshError::Empty {
            vertices: 0,
            faces: 0,
        }
        .into());
    };
    let first: Vec<Vec<u8>> = tokens(text).map(<[u8]>::to_vec).collect();
    let first_tok = first.first().map(Vec::as_slice).unwrap_or_default();
    let (counts, counts_line): (Vec<Vec<u8>>, usize) = if parse_i64(first_tok).is_some() {
        notes.push(
            "the OFF file has no 'OFF' header line; read the counts from its first line"
                .to_string(),
        );
        (first, first_line)
    } else {
        let header_ok =
            first_tok.len() >= 3 && first_tok[first_tok.len() - 3..].eq_ignore_ascii_case(b"OFF");
        let prefix = &first_tok[..first_tok.len().saturating_sub(3)];
        if !header_ok {
            return Err(parse_error(
                F,
                first_line,
                format!(
                    "expected the header 'OFF' (or COFF, NOFF, …), found '{}'",
                    show(first_tok)
                ),
            )
            .into());
        }
        if prefix.contains(&b'4') || prefix.contains(&b'n') {
            return Err(parse_error(
                F,
                first_line,
                format!(
                    "'{}' (4D or n-dimensional OFF) is not supported; only 3D OFF is",
                    show(first_tok)
                ),
            )
            .into());
        }
        if !prefix
            .iter()
            .all(|c| matches!(c, b'S' | b'T' | b'C' | b'N'))
        {
            return Err(parse_error(
                F,
                first_line,
                format!(
                    "unknown OFF header '{}' (expected OFF, COFF, NOFF, CNOFF, STOFF, …)",
                    show(first_tok)
                ),
            )
            .into());
        }
        if first
            .get(1)
            .is_some_and(|t| t.eq_ignore_ascii_case(b"BINARY"))
        {
            return Err(parse_error(
                F,
                first_line,
                "binary OFF is not supported; convert it to ASCII OFF, PLY or OBJ",
            )
            .into());
        }
        if first.len() > 1 {
            (first[1..].to_vec(), first_line)
        } else {
            let Some((l, text)) = next_content(&mut lines)? else {
                return Err(MeshError::Empty {
                    vertices: 0,
                    faces: 0,
                }
                .into());
            };
            (tokens(text).map(<[u8]>::to_vec).collect(), l)
        }
    };
    let count = |k: usize, what: &str| -> Result<usize, MeshError> {
        let tok = counts.get(k).ok_or_else(|| {
            parse_error(
                F,
                counts_line,
                format!("expected the counts line 'vertices faces edges', but the {what} count is missing"),
            )
        })?;
        std::str::from_utf8(tok)
            .ok()
            .and_then(|s| s.parse::<usize>().ok())
            .ok_or_else(|| {
                parse_error(
                    F,
                    counts_line,
                    format!(
                        "invalid {what} count '{}' (expected a non-negative integer)",
                        show(tok)
                    ),
                )
            })
    };
    let n_vertices = count(0, "vertex")?;
    let n_faces = count(1, "face")?;
    if n_vertices == 0 || n_faces == 0 {
        return Err(MeshError::Empty {
            vertices: n_vertices,
            faces: n_faces,
        }
        .into());
    }
    check_declared_counts(n_vertices, n_faces)?;
    let needed = n_vertices as u128 * OFF_MIN_VERTEX_BYTES + n_faces as u128 * OFF_MIN_FACE_BYTES;
    let reserve_cap = match size {
        Some(size) => {
            if needed > u128::from(size) + 1 {
                return Err(parse_error(
                    F,
                    counts_line,
                    format!(
                        "the header declares {n_vertices} vertices and {n_faces} faces, which need at least {needed} bytes, but the whole file has only {size} bytes (wrong counts or truncated file)"
                    ),
                )
                .into());
            }
            usize::try_from(size / 6).unwrap_or(usize::MAX)
        }
        None => MAX_BLIND_RESERVE,
    };
    let mut b = Builder::default();
    b.positions.reserve(n_vertices.min(reserve_cap));
    b.vertex_lines.reserve(n_vertices.min(reserve_cap));
    for v in 0..n_vertices {
        let Some((line, text)) = next_content(&mut lines)? else {
            return Err(MeshError::Parse {
                format: F,
                line: Some(lines.line),
                message: format!(
                    "the file ends after {v} of the {n_vertices} vertices declared at line {counts_line} (truncated file or wrong count)"
                ),
            }
            .into());
        };
        let mut it = tokens(text);
        let mut p = [0.0; 3];
        for (k, c) in p.iter_mut().enumerate() {
            let Some(tok) = it.next() else {
                return Err(parse_error(
                    F,
                    line,
                    format!("expected 3 coordinates for vertex {v}, found {k}"),
                )
                .into());
            };
            *c = parse_f64(tok)
                .ok_or_else(|| parse_error(F, line, format!("invalid number '{}'", show(tok))))?;
        }
        b.vertex(p, Some(line))?;
    }
    b.faces.reserve(n_faces.min(reserve_cap));
    b.face_lines.reserve(n_faces.min(reserve_cap));
    let mut poly = Vec::new();
    for f in 0..n_faces {
        let Some((line, text)) = next_content(&mut lines)? else {
            return Err(MeshError::Parse {
                format: F,
                line: Some(lines.line),
                message: format!(
                    "the file ends after {f} of the {n_faces} faces declared at line {counts_line} (truncated file or wrong count)"
                ),
            }
            .into());
        };
        let mut it = tokens(text);
        let k_tok = it.next().unwrap_or_default();
        let k = std::str::from_utf8(k_tok)
            .ok()
            .and_then(|s| s.parse::<usize>().ok())
            .ok_or_else(|| {
                parse_error(
                    F,
                    line,
                    format!(
                        "invalid vertex count '{}' at the start of a face line",
                        show(k_tok)
                    ),
                )
            })?;
        poly.clear();
        for corner in 0..k {
            let Some(tok) = it.next() else {
                return Err(parse_error(
                    F,
                    line,
                    format!("face {f} declares {k} vertices but only {corner} indices follow"),
                )
                .into());
            };
            let index = parse_i64(tok).ok_or_else(|| {
                parse_error(F, line, format!("invalid face index '{}'", show(tok)))
            })?;
            poly.push(b.resolve(index, corner, Some(line))?);
        }
        b.polygon(&poly, Some(line))?;
    }
    if let Some((line, _)) = next_content(&mut lines)? {
        return Err(parse_error(
            F,
            line,
            format!(
                "unexpected data after the last of the {n_faces} faces declared at line {counts_line} (wrong counts in the header?)"
            ),
        )
        .into());
    }
    Ok(b.finish(F, notes)?)
}

// ---------------------------------------------------------------------------
// PLY

/// Face-index list of a PLY element, in the file's integer type.
enum IndexList {
    I8(Vec<i8>),
    U8(Vec<u8>),
    I16(Vec<i16>),
    U16(Vec<u16>),
    I32(Vec<i32>),
    U32(Vec<u32>),
}

impl IndexList {
    fn to_i64(&self) -> Vec<i64> {
        match self {
            IndexList::I8(v) => v.iter().map(|&x| i64::from(x)).collect(),
            IndexList::U8(v) => v.iter().map(|&x| i64::from(x)).collect(),
            IndexList::I16(v) => v.iter().map(|&x| i64::from(x)).collect(),
            IndexList::U16(v) => v.iter().map(|&x| i64::from(x)).collect(),
            IndexList::I32(v) => v.iter().map(|&x| i64::from(x)).collect(),
            IndexList::U32(v) => v.iter().map(|&x| i64::from(x)).collect(),
        }
    }
}

/// One decoded PLY element: the properties we use, the rest ignored.
struct PlyElement {
    xyz: [f64; 3],
    indices: Option<IndexList>,
}

fn xyz_slot(name: &str) -> Option<usize> {
    match name {
        "x" => Some(0),
        "y" => Some(1),
        "z" => Some(2),
        _ => None,
    }
}

fn is_index_list(name: &str) -> bool {
    name == "vertex_indices" || name == "vertex_index"
}

impl PlyElement {
    fn scalar(&mut self, name: &str, value: f64) -> PropertyAccessResult {
        match xyz_slot(name) {
            Some(k) => {
                self.xyz[k] = value;
                PropertyAccessResult::Set
            }
            None => PropertyAccessResult::Ignored,
        }
    }

    fn list(&mut self, name: &str, list: IndexList) -> PropertyAccessResult {
        if is_index_list(name) {
            self.indices = Some(list);
            PropertyAccessResult::Set
        } else {
            PropertyAccessResult::Ignored
        }
    }
}

impl PropertyAccess for PlyElement {
    fn new() -> Self {
        PlyElement {
            xyz: [0.0; 3],
            indices: None,
        }
    }
    fn set_char(&mut self, name: &str, v: i8) -> PropertyAccessResult {
        self.scalar(name, f64::from(v))
    }
    fn set_uchar(&mut self, name: &str, v: u8) -> PropertyAccessResult {
        self.scalar(name, f64::from(v))
    }
    fn set_short(&mut self, name: &str, v: i16) -> PropertyAccessResult {
        self.scalar(name, f64::from(v))
    }
    fn set_ushort(&mut self, name: &str, v: u16) -> PropertyAccessResult {
        self.scalar(name, f64::from(v))
    }
    fn set_int(&mut self, name: &str, v: i32) -> PropertyAccessResult {
        self.scalar(name, f64::from(v))
    }
    fn set_uint(&mut self, name: &str, v: u32) -> PropertyAccessResult {
        self.scalar(name, f64::from(v))
    }
    fn set_float(&mut self, name: &str, v: f32) -> PropertyAccessResult {
        self.scalar(name, f64::from(v))
    }
    fn set_double(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        self.scalar(name, v)
    }
    fn set_list_char(&mut self, name: &str, v: Vec<i8>) -> PropertyAccessResult {
        self.list(name, IndexList::I8(v))
    }
    fn set_list_uchar(&mut self, name: &str, v: Vec<u8>) -> PropertyAccessResult {
        self.list(name, IndexList::U8(v))
    }
    fn set_list_short(&mut self, name: &str, v: Vec<i16>) -> PropertyAccessResult {
        self.list(name, IndexList::I16(v))
    }
    fn set_list_ushort(&mut self, name: &str, v: Vec<u16>) -> PropertyAccessResult {
        self.list(name, IndexList::U16(v))
    }
    fn set_list_int(&mut self, name: &str, v: Vec<i32>) -> PropertyAccessResult {
        self.list(name, IndexList::I32(v))
    }
    fn set_list_uint(&mut self, name: &str, v: Vec<u32>) -> PropertyAccessResult {
        self.list(name, IndexList::U32(v))
    }
}

fn scalar_size(t: &ScalarType) -> u128 {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

fn is_integer(t: &ScalarType) -> bool {
    !matches!(t, ScalarType::Float | ScalarType::Double)
}

/// Least number of payload bytes one element can take: binary, the scalar
/// sizes plus the count of each list (lists may be empty); ASCII, one
/// character and one separator per property. At least 1 either way. In a
/// binary file the vertex index list of a face counts with three items: a
/// face with fewer vertices is refused anyway, so this stays a lower bound
/// for every file the reader accepts, and a header that overstates its
/// vertex count is caught here instead of face bytes being misread as
/// coordinates. (In ASCII a short face is reported with its line instead.)
fn min_element_bytes(name: &str, def: &ElementDef, encoding: Encoding) -> u128 {
    let is_face_indices = |prop: &str| name == "face" && is_index_list(prop);
    let n: u128 = match encoding {
        Encoding::Ascii => 2 * def.properties.len() as u128,
        Encoding::BinaryLittleEndian | Encoding::BinaryBigEndian => def
            .properties
            .iter()
            .map(|(prop, p)| match &p.data_type {
                PropertyType::Scalar(t) => scalar_size(t),
                PropertyType::List(count, item) if is_face_indices(prop) => {
                    scalar_size(count) + 3 * scalar_size(item)
                }
                PropertyType::List(count, _) => scalar_size(count),
            })
            .sum(),
    };
    n.max(1)
}

/// The message of a `ply-rs-bw` error, without its line prefix.
fn ply_message(e: &ply_rs_bw::parser::ParseError) -> String {
    match ply_error(e) {
        MeshError::Parse { message, .. } => message,
        other => other.to_string(),
    }
}

/// A `ply-rs-bw` error as a [`MeshError`]: its line kept, its message made
/// single-line and bounded in length.
fn ply_error(e: &ply_rs_bw::parser::ParseError) -> MeshError {
    let mut message = e.to_string();
    if let Some(l) = e.line() {
        let prefix = format!("Line {l}: ");
        if let Some(rest) = message.strip_prefix(&prefix) {
            message = rest.to_string();
        }
    }
    let mut message = message.replace("\n\t", "; ").replace('\n', " ");
    if message.chars().count() > 300 {
        message = format!("{}…", message.chars().take(300).collect::<String>());
    }
    MeshError::Parse {
        format: "PLY",
        line: e.line(),
        message,
    }
}

fn ply_header_error(line: Option<usize>, message: impl Into<String>) -> MeshError {
    MeshError::Parse {
        format: "PLY",
        line,
        message: message.into(),
    }
}

/// Refuses a header whose counts would not fit in the memory budget
/// ([`crate::limits`]), before anything is reserved.
fn check_declared_counts(n_vertices: usize, n_faces: usize) -> Result<(), MeshError> {
    let estimate = (n_vertices as u64)
        .saturating_mul(limits::MESH_BYTES_PER_VERTEX)
        .saturating_add((n_faces as u64).saturating_mul(limits::MESH_BYTES_PER_FACE));
    limits::check(estimate, || {
        format!("the header's {n_vertices} vertices and {n_faces} faces would need")
    })
    .map_err(|detail| MeshError::TooLarge {
        what: "mesh",
        detail,
    })
}

fn read_ply(bytes: &[u8]) -> Result<LoadedMesh, ReadError> {
    const F: &str = "PLY";
    let parser = Parser::<PlyElement>::new();
    let mut reader = Reader::new(bytes);
    let header = parser.read_header(&mut reader).map_err(|e| ply_error(&e))?;
    let mut payload: &[u8] = reader.into_inner();
    let header_bytes = bytes.get(..bytes.len() - payload.len()).unwrap_or_default();
    let header_lines = header_bytes.iter().filter(|&&c| c == b'\n').count();
    // 1-based header line declaring each element, for messages.
    let element_line = |name: &str| -> Option<usize> {
        header_bytes
            .split(|&c| c == b'\n')
            .position(|l| {
                let mut t = tokens(l);
                t.next() == Some(b"element") && t.next() == Some(name.as_bytes())
            })
            .map(|i| i + 1)
    };

    // The header must describe a triangle mesh we can read.
    let vertex_def = header
        .elements
        .get("vertex")
        .ok_or_else(|| ply_header_error(None, "the header declares no 'vertex' element"))?;
    for name in ["x", "y", "z"] {
        match vertex_def.properties.get(name).map(|p| &p.data_type) {
            Some(PropertyType::Scalar(_)) => {}
            Some(PropertyType::List(..)) => {
                return Err(ply_header_error(
                    element_line("vertex"),
                    format!("vertex property '{name}' is a list; expected a number"),
                )
                .into());
            }
            None => {
                return Err(ply_header_error(
                    element_line("vertex"),
                    format!("the 'vertex' element has no property '{name}'"),
                )
                .into());
            }
        }
    }
    let Some(face_def) = header.elements.get("face") else {
        let hint = if header.elements.contains_key("tristrips") {
            " (triangle strips, element 'tristrips', are not supported: convert them to faces)"
        } else {
            " (a point cloud has no triangles to deform)"
        };
        return Err(
            ply_header_error(None, format!("the header declares no 'face' element{hint}")).into(),
        );
    };
    let index_prop = face_def
        .properties
        .iter()
        .find(|(name, _)| is_index_list(name))
        .map(|(_, p)| p);
    match index_prop.map(|p| &p.data_type) {
        Some(PropertyType::List(count, item)) if is_integer(count) && is_integer(item) => {}
        Some(t) => {
            return Err(ply_header_error(
                element_line("face"),
                format!(
                    "face property 'vertex_indices' has type {t:?}; expected a list of integers"
                ),
            )
            .into());
        }
        None => {
            return Err(ply_header_error(
                element_line("face"),
                "the 'face' element has no list property 'vertex_indices' (or 'vertex_index')",
            )
            .into());
        }
    }

    // The declared counts must fit in the bytes that follow the header.
    let mut needed: u128 = 0;
    let mut declared: Vec<String> = Vec::new();
    for (name, def) in &header.elements {
        needed = needed
            .saturating_add(def.count as u128 * min_element_bytes(name, def, header.encoding));
        declared.push(format!("{} '{name}'", def.count));
        let slack = u128::from(header.encoding == Encoding::Ascii);
        if needed > payload.len() as u128 + slack {
            return Err(ply_header_error(
                element_line(name),
                format!(
                    "the header declares {} elements, which need at least {needed} bytes, but only {} bytes follow the header (wrong count or truncated file)",
                    declared.join(" and "),
                    payload.len()
                ),
            )
            .into());
        }
    }

    check_declared_counts(vertex_def.count, face_def.count)?;
    let mut b = Builder::default();
    b.positions.reserve(vertex_def.count);
    let ascii = header.encoding == Encoding::Ascii;
    let mut line = header_lines;
    let mut deferred: Option<MeshError> = None;
    for (name, def) in &header.elements {
        let is_vertex = name == "vertex";
        let is_face = name == "face";
        for i in 0..def.count {
            let element = match header.encoding {
                Encoding::Ascii => {
                    if payload.is_empty() {
                        return Err(ply_header_error(
                            Some(line),
                            format!(
                                "the data ends after {i} of the {} '{name}' elements (the header's counts do not match the data, or the file is truncated)",
                                def.count
                            ),
                        )
                        .into());
                    }
                    let end = payload
                        .iter()
                        .position(|&c| c == b'\n')
                        .map_or(payload.len(), |p| p + 1);
                    let (text, rest) = payload.split_at(end);
                    payload = rest;
                    line += 1;
                    let text = std::str::from_utf8(text).map_err(|_| {
                        ply_header_error(Some(line), "the line is not valid text (UTF-8)")
                    })?;
                    parser
                        .read_ascii_element(text, def)
                        .map_err(|e| ply_header_error(Some(line), ply_message(&e)))?
                }
                Encoding::BinaryLittleEndian | Encoding::BinaryBigEndian => {
                    let r = if header.encoding == Encoding::BinaryLittleEndian {
                        parser.read_little_endian_element(&mut payload, def)
                    } else {
                        parser.read_big_endian_element(&mut payload, def)
                    };
                    r.map_err(|e| {
                        if e.kind() == io::ErrorKind::UnexpectedEof {
                            ply_header_error(
                                None,
                                format!(
                                    "the data ends inside '{name}' element {i} of {} (the header's counts do not match the data, or the file is truncated)",
                                    def.count
                                ),
                            )
                        } else {
                            ply_header_error(
                                None,
                                format!("'{name}' element {i}: {}", ply_message(&e)),
                            )
                        }
                    })?
                }
            };
            let here = ascii.then_some(line);
            let result = if is_vertex {
                b.vertex(element.xyz, here)
            } else if is_face {
                let indices = element
                    .indices
                    .as_ref()
                    .map(IndexList::to_i64)
                    .unwrap_or_default();
                indices
                    .iter()
                    .enumerate()
                    .map(|(corner, &index)| b.resolve(index, corner, here))
                    .collect::<Result<Vec<usize>, MeshError>>()
                    .and_then(|poly| b.polygon(&poly, here))
            } else {
                Ok(())
            };
            if let Err(e) = result {
                // Report it only once the data proved structurally sound: if
                // the counts do not match the data, a garbage value here is a
                // symptom, and the mismatch is the error to report.
                deferred.get_or_insert(e);
            }
        }
    }
    if let Some(p) = payload.iter().position(|c| !c.is_ascii_whitespace()) {
        let extra = payload.len() - p;
        return Err(ply_header_error(
            ascii.then_some(line + 1),
            format!(
                "{extra} bytes of data follow the last element (the header's element counts do not match the data)"
            ),
        )
        .into());
    }
    if let Some(e) = deferred {
        return Err(e.into());
    }
    Ok(b.finish(F, Vec::new())?)
}

// ---------------------------------------------------------------------------
// Writers

/// Checks, before any work, that [`write_mesh`] will be able to write
/// `path`: the extension names a format it writes and the file can be opened
/// for writing (the directory exists, permissions allow it). See
/// [`check_writable`].
pub fn check_mesh_output(path: &Path) -> Result<(), Error> {
    MeshFormat::from_path(path)?;
    check_writable(path)
}

/// Checks that `path` can be opened for writing, without changing it: an
/// existing file is opened for writing and left as it is (no truncation), a
/// missing one is created and removed again. Lets a command refuse a
/// misspelt directory or a read-only location before a long computation
/// instead of after it.
pub fn check_writable(path: &Path) -> Result<(), Error> {
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
    Ok(())
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

/// Writes ASCII OBJ: a comment line, `v x y z` per vertex (shortest
/// round-trip decimals) and `f a b c` per face (1-based). Pass a buffered
/// writer for speed.
pub fn write_obj<W: Write>(mesh: &Mesh, mut w: W) -> io::Result<()> {
    writeln!(
        w,
        "# written by lse-deform: {} vertices, {} faces",
        mesh.n_vertices(),
        mesh.n_faces()
    )?;
    for p in mesh.positions() {
        writeln!(w, "v {} {} {}", p[0], p[1], p[2])?;
    }
    for f in mesh.faces() {
        writeln!(w, "f {} {} {}", f[0] + 1, f[1] + 1, f[2] + 1)?;
    }
    Ok(())
}

/// Writes ASCII OFF: `OFF`, `V F 0` (the edge count is optional in OFF and
/// written as 0), `x y z` per vertex (shortest round-trip decimals) and
/// `3 a b c` per face (0-based). Pass a buffered writer for speed.
pub fn write_off<W: Write>(mesh: &Mesh, mut w: W) -> io::Result<()> {
    writeln!(w, "OFF")?;
    writeln!(w, "{} {} 0", mesh.n_vertices(), mesh.n_faces())?;
    for p in mesh.positions() {
        writeln!(w, "{} {} {}", p[0], p[1], p[2])?;
    }
    for f in mesh.faces() {
        writeln!(w, "3 {} {} {}", f[0], f[1], f[2])?;
    }
    Ok(())
}

/// Writes PLY with `property double x, y, z` and
/// `property list uchar int vertex_indices`. Fails with
/// `io::ErrorKind::InvalidInput` if a vertex index does not fit in a 32-bit
/// signed `int`. Pass a buffered writer for speed.
pub fn write_ply<W: Write>(mesh: &Mesh, mut w: W, encoding: PlyEncoding) -> io::Result<()> {
    if i32::try_from(mesh.n_vertices()).is_err() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{} vertices: PLY 'int' vertex indices cannot address more than {} vertices",
                mesh.n_vertices(),
                i32::MAX
            ),
        ));
    }
    let format = match encoding {
        PlyEncoding::Ascii => "ascii",
        PlyEncoding::BinaryLittleEndian => "binary_little_endian",
        PlyEncoding::BinaryBigEndian => "binary_big_endian",
    };
    write!(
        w,
        "ply\nformat {format} 1.0\ncomment written by lse-deform\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.n_vertices(),
        mesh.n_faces()
    )?;
    // Indices are < n_vertices ≤ i32::MAX (checked above).
    let idx = |i: usize| i32::try_from(i).unwrap_or(i32::MAX);
    match encoding {
        PlyEncoding::Ascii => {
            for p in mesh.positions() {
                writeln!(w, "{} {} {}", p[0], p[1], p[2])?;
            }
            for f in mesh.faces() {
                writeln!(w, "3 {} {} {}", f[0], f[1], f[2])?;
            }
        }
        PlyEncoding::BinaryLittleEndian | PlyEncoding::BinaryBigEndian => {
            let le = encoding == PlyEncoding::BinaryLittleEndian;
            let f64_bytes = |x: f64| if le { x.to_le_bytes() } else { x.to_be_bytes() };
            let i32_bytes = |x: i32| if le { x.to_le_bytes() } else { x.to_be_bytes() };
            for p in mesh.positions() {
                for &c in p {
                    w.write_all(&f64_bytes(c))?;
                }
            }
            for f in mesh.faces() {
                w.write_all(&[3])?;
                for &i in f {
                    w.write_all(&i32_bytes(idx(i)))?;
                }
            }
        }
    }
    Ok(())
}
