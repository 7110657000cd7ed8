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
mod shared;

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
use shared::ReadError;
pub use shared::{LoadedMesh, MAX_LINE_BYTES, MeshFormat};

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
    let file = crate::input::open_input(path).map_err(|e| Error::io(path, e))?;
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

#[cfg(test)]
mod tests {
    use super::shared::{Builder, LineReader, show, strip_comment, tokens};
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
