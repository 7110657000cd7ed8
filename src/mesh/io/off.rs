//! OFF: the reader and the writer (what is accepted: see the parent
//! module's documentation).

use std::io::{self, BufRead, Write};

use super::shared::{
    Builder, LineReader, LoadedMesh, ReadError, check_declared_counts, parse_error, parse_f64,
    parse_i64, show, strip_comment, tokens,
};
use crate::error::MeshError;
use crate::limits::MemoryBudget;
use crate::mesh::Mesh;

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

/// Reads an OFF file: the header ([`read_off_header`]), the counts
/// ([`parse_off_counts`]) checked against the budget and the file size
/// ([`off_reserve_cap`]), then exactly that many vertex lines
/// ([`parse_off_vertex`]) and face lines ([`parse_off_face`]), and nothing
/// after them but comments and blank lines.
pub(super) fn read_off<R: BufRead>(
    reader: R,
    size: Option<u64>,
    budget: MemoryBudget,
) -> Result<LoadedMesh, ReadError> {
    let mut notes = Vec::new();
    let mut lines = LineReader::new(reader, F);
    let (counts, counts_line) = read_off_header(&mut lines, &mut notes)?;
    let (n_vertices, n_faces) = parse_off_counts(&counts, counts_line)?;
    check_declared_counts(n_vertices, n_faces, budget)?;
    let reserve_cap = off_reserve_cap(n_vertices, n_faces, size, counts_line)?;
    let mut b = Builder::within(budget);
    b.positions.reserve(n_vertices.min(reserve_cap));
    b.vertex_lines.reserve(n_vertices.min(reserve_cap));
    for v in 0..n_vertices {
        let Some((line, text)) = next_content(&mut lines)? else {
            return Err(truncated(lines.line, v, n_vertices, "vertices", counts_line).into());
        };
        b.vertex(parse_off_vertex(text, v, line)?, Some(line))?;
    }
    b.faces.reserve(n_faces.min(reserve_cap));
    b.face_lines.reserve(n_faces.min(reserve_cap));
    let mut poly = Vec::new();
    for f in 0..n_faces {
        let Some((line, text)) = next_content(&mut lines)? else {
            return Err(truncated(lines.line, f, n_faces, "faces", counts_line).into());
        };
        parse_off_face(
            text,
            f,
            line,
            |index, corner| b.resolve(index, corner, Some(line)),
            &mut poly,
        )?;
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

/// The format name in OFF errors.
const F: &str = "OFF";

/// No vertices and no faces: a file that ends before its counts.
fn empty() -> MeshError {
    MeshError::Empty {
        vertices: 0,
        faces: 0,
    }
}

/// The error for a file that ends (at `line`, the last line read) after
/// `done` of the `declared` vertices or faces (`what`) of the counts line.
fn truncated(
    line: usize,
    done: usize,
    declared: usize,
    what: &str,
    counts_line: usize,
) -> MeshError {
    MeshError::Parse {
        format: F,
        line: Some(line),
        message: format!(
            "the file ends after {done} of the {declared} {what} declared at line {counts_line} (truncated file or wrong count)"
        ),
    }
}

/// Reads the header: the optional `OFF` keyword line (checked by
/// [`check_off_keyword`]) and the counts, on the same line after it or on
/// the next line with content. Returns the counts tokens and their line
/// number. A first token that is an integer means there is no keyword
/// (accepted, with a note): that line holds the counts.
fn read_off_header<R: BufRead>(
    lines: &mut LineReader<R>,
    notes: &mut Vec<String>,
) -> Result<(Vec<Vec<u8>>, usize), ReadError> {
    let Some((first_line, text)) = next_content(lines)? else {
        return Err(empty().into());
    };
    let first: Vec<Vec<u8>> = tokens(text).map(<[u8]>::to_vec).collect();
    let first_tok = first.first().map(Vec::as_slice).unwrap_or_default();
    if parse_i64(first_tok).is_some() {
        notes.push(
            "the OFF file has no 'OFF' header line; read the counts from its first line"
                .to_string(),
        );
        return Ok((first, first_line));
    }
    check_off_keyword(&first, first_line)?;
    if first.len() > 1 {
        return Ok((first[1..].to_vec(), first_line));
    }
    let Some((l, text)) = next_content(lines)? else {
        return Err(empty().into());
    };
    Ok((tokens(text).map(<[u8]>::to_vec).collect(), l))
}

/// Checks the keyword line's tokens (`first`, at `line`): the keyword ends in
/// `OFF` (any case), its prefix is made of the 3D variants' letters `S`,
/// `T`, `C`, `N` (not `4` or `n`: 4D and n-dimensional OFF), and the
/// next token is not `BINARY`.
fn check_off_keyword(first: &[Vec<u8>], line: usize) -> Result<(), MeshError> {
    let first_tok = first.first().map(Vec::as_slice).unwrap_or_default();
    let header_ok =
        first_tok.len() >= 3 && first_tok[first_tok.len() - 3..].eq_ignore_ascii_case(b"OFF");
    let prefix = &first_tok[..first_tok.len().saturating_sub(3)];
    if !header_ok {
        return Err(parse_error(
            F,
            line,
            format!(
                "expected the header 'OFF' (or COFF, NOFF, …), found '{}'",
                show(first_tok)
            ),
        ));
    }
    if prefix.contains(&b'4') || prefix.contains(&b'n') {
        return Err(parse_error(
            F,
            line,
            format!(
                "'{}' (4D or n-dimensional OFF) is not supported; only 3D OFF is",
                show(first_tok)
            ),
        ));
    }
    if !prefix
        .iter()
        .all(|c| matches!(c, b'S' | b'T' | b'C' | b'N'))
    {
        return Err(parse_error(
            F,
            line,
            format!(
                "unknown OFF header '{}' (expected OFF, COFF, NOFF, CNOFF, STOFF, …)",
                show(first_tok)
            ),
        ));
    }
    if first
        .get(1)
        .is_some_and(|t| t.eq_ignore_ascii_case(b"BINARY"))
    {
        return Err(parse_error(
            F,
            line,
            "binary OFF is not supported; convert it to ASCII OFF, PLY or OBJ",
        ));
    }
    Ok(())
}

/// Parses the counts line's tokens (at `line`): the vertex and the face
/// count, non-negative integers, both non-zero (else [`MeshError::Empty`]);
/// the edge count, optional, is ignored.
fn parse_off_counts(counts: &[Vec<u8>], line: usize) -> Result<(usize, usize), MeshError> {
    let count = |k: usize, what: &str| -> Result<usize, MeshError> {
        let tok = counts.get(k).ok_or_else(|| {
            parse_error(
                F,
                line,
                format!("expected the counts line 'vertices faces edges', but the {what} count is missing"),
            )
        })?;
        std::str::from_utf8(tok)
            .ok()
            .and_then(|s| s.parse::<usize>().ok())
            .ok_or_else(|| {
                parse_error(
                    F,
                    line,
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
        });
    }
    Ok((n_vertices, n_faces))
}

/// How many vertices or faces to reserve up front. For a file of known
/// `size`, the declared counts must fit: every vertex line needs at least
/// [`OFF_MIN_VERTEX_BYTES`] and every face line [`OFF_MIN_FACE_BYTES`]
/// (one byte of slack: a missing final newline), else the counts are
/// refused at `counts_line` before anything is allocated; the cap is then
/// `size / 6`. Of unknown size, [`MAX_BLIND_RESERVE`].
fn off_reserve_cap(
    n_vertices: usize,
    n_faces: usize,
    size: Option<u64>,
    counts_line: usize,
) -> Result<usize, MeshError> {
    let needed = n_vertices as u128 * OFF_MIN_VERTEX_BYTES + n_faces as u128 * OFF_MIN_FACE_BYTES;
    match size {
        Some(size) => {
            if needed > u128::from(size) + 1 {
                return Err(parse_error(
                    F,
                    counts_line,
                    format!(
                        "the header declares {n_vertices} vertices and {n_faces} faces, which need at least {needed} bytes, but the whole file has only {size} bytes (wrong counts or truncated file)"
                    ),
                ));
            }
            Ok(usize::try_from(size / 6).unwrap_or(usize::MAX))
        }
        None => Ok(MAX_BLIND_RESERVE),
    }
}

/// Parses vertex `v`'s line (`text`, at `line`): three coordinates; values
/// after them (a colour, a normal) are ignored.
fn parse_off_vertex(text: &[u8], v: usize, line: usize) -> Result<[f64; 3], MeshError> {
    let mut it = tokens(text);
    let mut p = [0.0; 3];
    for (k, c) in p.iter_mut().enumerate() {
        let Some(tok) = it.next() else {
            return Err(parse_error(
                F,
                line,
                format!("expected 3 coordinates for vertex {v}, found {k}"),
            ));
        };
        *c = parse_f64(tok)
            .ok_or_else(|| parse_error(F, line, format!("invalid number '{}'", show(tok))))?;
    }
    Ok(p)
}

/// Parses face `f`'s line (`text`, at `line`): a vertex count `k`, then
/// `k` 0-based indices, each mapped by `resolve(index, corner)` (the
/// builder's range check) as it is read, into `poly`; values after them (a
/// colour) are ignored.
fn parse_off_face(
    text: &[u8],
    f: usize,
    line: usize,
    mut resolve: impl FnMut(i64, usize) -> Result<usize, MeshError>,
    poly: &mut Vec<usize>,
) -> Result<(), MeshError> {
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
            ));
        };
        let index = parse_i64(tok)
            .ok_or_else(|| parse_error(F, line, format!("invalid face index '{}'", show(tok))))?;
        poly.push(resolve(index, corner)?);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::io::shared::unwrap_io;

    /// Reads `text` as a file of known size (the size check applies).
    fn off(text: &str) -> Result<LoadedMesh, MeshError> {
        unwrap_io(read_off(
            text.as_bytes(),
            Some(text.len() as u64),
            MemoryBudget::unlimited(),
        ))
    }

    fn parse_error_at(line: usize, message: &str) -> MeshError {
        MeshError::Parse {
            format: "OFF",
            line: Some(line),
            message: message.into(),
        }
    }

    const BODY: &str = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";

    #[test]
    fn header_and_counts_on_one_line_or_after_comments() {
        let expected = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        for head in [
            "# made by hand\n\nOFF # header\n# counts next\n3 1 0\n",
            "off 3 1\n",
            "STOFF\n3 1 0\n",
            "CNOFF\n3 1 0\n",
        ] {
            let loaded = off(&format!("{head}{BODY}")).unwrap();
            assert_eq!(loaded.mesh.positions(), &expected, "{head:?}");
            assert_eq!(loaded.mesh.faces(), &[[0, 1, 2]], "{head:?}");
            assert_eq!(loaded.notes, Vec::<String>::new(), "{head:?}");
        }
    }

    #[test]
    fn crlf_and_a_missing_final_newline_read_without_a_note() {
        let loaded = off("OFF\r\n3 1 0\r\n0 0 0\r\n1 0 0\r\n0 1 0\r\n3 0 1 2").unwrap();
        assert_eq!(loaded.mesh.faces(), &[[0, 1, 2]]);
        assert_eq!(loaded.notes, Vec::<String>::new());
    }

    #[test]
    fn counts_line_errors() {
        assert_eq!(
            off("OFF\n3\n").unwrap_err(),
            parse_error_at(
                2,
                "expected the counts line 'vertices faces edges', but the face count is missing"
            )
        );
        assert_eq!(
            off("OFF\n-3 1 0\n").unwrap_err(),
            parse_error_at(
                2,
                "invalid vertex count '-3' (expected a non-negative integer)"
            )
        );
        assert_eq!(
            off("OFF 3 1.0 0\n").unwrap_err(),
            parse_error_at(
                1,
                "invalid face count '1.0' (expected a non-negative integer)"
            )
        );
        // Without a header the first line is the counts line.
        assert_eq!(
            off("3 0 0\n0 0 0\n").unwrap_err(),
            MeshError::Empty {
                vertices: 3,
                faces: 0
            }
        );
        assert_eq!(
            off("OFF\n# nothing else\n").unwrap_err(),
            MeshError::Empty {
                vertices: 0,
                faces: 0
            }
        );
    }

    #[test]
    fn counts_beyond_the_file_size_are_refused_before_reading() {
        // 3 vertices and 9 faces need at least 3·6 + 9·8 = 90 bytes; the
        // file has 36.
        let text = format!("OFF\n3 9 0\n{BODY}");
        assert_eq!(text.len(), 36);
        assert_eq!(
            off(&text).unwrap_err(),
            parse_error_at(
                2,
                "the header declares 3 vertices and 9 faces, which need at least 90 bytes, but the whole file has only 36 bytes (wrong counts or truncated file)"
            )
        );
        // Of unknown size (a gzip stream), the same file is read until it
        // ends, and the error is where it ends.
        match read_off(text.as_bytes(), None, MemoryBudget::unlimited()) {
            Err(ReadError::Mesh(e)) => assert_eq!(
                e,
                parse_error_at(
                    6,
                    "the file ends after 1 of the 9 faces declared at line 2 (truncated file or wrong count)"
                )
            ),
            Err(ReadError::Io(e)) => panic!("{e}"),
            Ok(loaded) => panic!("{loaded:?}"),
        }
    }

    #[test]
    fn more_faces_than_declared_is_an_error_at_the_first_extra_line() {
        let text = format!("OFF\n3 1 0\n{BODY}\n# trailing comment\n3 0 2 1\n");
        assert_eq!(
            off(&text).unwrap_err(),
            parse_error_at(
                9,
                "unexpected data after the last of the 1 faces declared at line 2 (wrong counts in the header?)"
            )
        );
    }

    #[test]
    fn vertex_and_face_line_errors() {
        let with_face = |face: &str| off(&format!("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n{face}\n"));
        assert_eq!(
            with_face("3 0 1").unwrap_err(),
            parse_error_at(6, "face 0 declares 3 vertices but only 2 indices follow")
        );
        assert_eq!(
            with_face("x 0 1 2").unwrap_err(),
            parse_error_at(6, "invalid vertex count 'x' at the start of a face line")
        );
        assert_eq!(
            with_face("3 0 1 2.0").unwrap_err(),
            parse_error_at(6, "invalid face index '2.0'")
        );
        assert_eq!(
            with_face("2 0 1").unwrap_err(),
            MeshError::BadFaceSize {
                face: 0,
                sides: 2,
                line: Some(6)
            }
        );
        // OFF indices are 0-based and never relative.
        assert_eq!(
            with_face("3 0 -1 2").unwrap_err(),
            MeshError::IndexOutOfRange {
                face: 0,
                index: -1,
                vertex_count: 3,
                line: Some(6)
            }
        );
        assert_eq!(
            with_face("3 0 1 3").unwrap_err(),
            MeshError::IndexOutOfRange {
                face: 0,
                index: 3,
                vertex_count: 3,
                line: Some(6)
            }
        );
        // Extra values after the k indices (a face colour) are ignored.
        assert_eq!(
            with_face("3 2 1 0 0.5 0.5 0.5").unwrap().mesh.faces(),
            &[[2, 1, 0]]
        );
        assert_eq!(
            off("OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2\n").unwrap_err(),
            parse_error_at(4, "expected 3 coordinates for vertex 1, found 2")
        );
    }

    fn toks(text: &str) -> Vec<Vec<u8>> {
        tokens(text.as_bytes()).map(<[u8]>::to_vec).collect()
    }

    #[test]
    fn keyword_check_alone() {
        for ok in ["OFF", "off", "COFF", "STCNOFF", "OFF 3 1 0"] {
            assert_eq!(check_off_keyword(&toks(ok), 4), Ok(()), "{ok}");
        }
        assert_eq!(
            check_off_keyword(&toks("PLY"), 4),
            Err(parse_error_at(
                4,
                "expected the header 'OFF' (or COFF, NOFF, …), found 'PLY'"
            ))
        );
        assert_eq!(
            check_off_keyword(&toks("4OFF"), 1),
            Err(parse_error_at(
                1,
                "'4OFF' (4D or n-dimensional OFF) is not supported; only 3D OFF is"
            ))
        );
        assert_eq!(
            check_off_keyword(&toks("XOFF"), 1),
            Err(parse_error_at(
                1,
                "unknown OFF header 'XOFF' (expected OFF, COFF, NOFF, CNOFF, STOFF, …)"
            ))
        );
        assert_eq!(
            check_off_keyword(&toks("OFF binary"), 2),
            Err(parse_error_at(
                2,
                "binary OFF is not supported; convert it to ASCII OFF, PLY or OBJ"
            ))
        );
    }

    #[test]
    fn header_reader_alone_finds_the_counts_and_their_line() {
        let header = |text: &str| {
            let mut lines = LineReader::new(text.as_bytes(), F);
            let mut notes = Vec::new();
            match read_off_header(&mut lines, &mut notes) {
                Ok((counts, line)) => Ok((counts, line, notes)),
                Err(ReadError::Mesh(e)) => Err(e),
                Err(ReadError::Io(e)) => panic!("{e}"),
            }
        };
        assert_eq!(header("OFF 5 6 7\n").unwrap(), (toks("5 6 7"), 1, vec![]));
        assert_eq!(
            header("# c\nNOFF\n\n8 9\n").unwrap(),
            (toks("8 9"), 4, vec![])
        );
        let (counts, line, notes) = header("\n3 1 0\n").unwrap();
        assert_eq!((counts, line), (toks("3 1 0"), 2));
        assert_eq!(
            notes,
            ["the OFF file has no 'OFF' header line; read the counts from its first line"]
        );
        assert_eq!(
            header("OFF\n").unwrap_err(),
            MeshError::Empty {
                vertices: 0,
                faces: 0
            }
        );
    }

    #[test]
    fn counts_parser_alone() {
        assert_eq!(parse_off_counts(&toks("3 1"), 7), Ok((3, 1)));
        assert_eq!(parse_off_counts(&toks("12 20 30"), 7), Ok((12, 20)));
        assert_eq!(
            parse_off_counts(&toks("0 4 0"), 7),
            Err(MeshError::Empty {
                vertices: 0,
                faces: 4
            })
        );
        assert_eq!(
            parse_off_counts(&toks("3 x"), 7),
            Err(parse_error_at(
                7,
                "invalid face count 'x' (expected a non-negative integer)"
            ))
        );
    }

    #[test]
    fn size_check_alone() {
        // 2 vertices and 1 face need 2·6 + 8 = 20 bytes: 19 (a missing final
        // newline) still fits, 18 does not.
        assert_eq!(off_reserve_cap(2, 1, Some(19), 3), Ok(3));
        assert_eq!(
            off_reserve_cap(2, 1, Some(18), 3),
            Err(parse_error_at(
                3,
                "the header declares 2 vertices and 1 faces, which need at least 20 bytes, but the whole file has only 18 bytes (wrong counts or truncated file)"
            ))
        );
        assert_eq!(
            off_reserve_cap(usize::MAX, 1, None, 3),
            Ok(MAX_BLIND_RESERVE)
        );
    }

    #[test]
    fn vertex_line_parser_alone() {
        assert_eq!(
            parse_off_vertex(b"1 -2.5 3e2 0.5 0.5", 0, 1),
            Ok([1.0, -2.5, 300.0])
        );
        assert_eq!(
            parse_off_vertex(b"1 nope 3", 4, 9),
            Err(parse_error_at(9, "invalid number 'nope'"))
        );
        assert_eq!(
            parse_off_vertex(b"1", 4, 9),
            Err(parse_error_at(
                9,
                "expected 3 coordinates for vertex 4, found 1"
            ))
        );
    }

    #[test]
    fn face_line_parser_alone_resolves_each_index_as_it_reads_it() {
        let mut poly = Vec::new();
        let shift = |index: i64, _corner: usize| Ok(index as usize + 10);
        parse_off_face(b"4 0 1 2 3 0.5", 0, 1, shift, &mut poly).unwrap();
        assert_eq!(poly, [10, 11, 12, 13]);
        // The resolver's error comes before a later bad token.
        let refuse = |index: i64, corner: usize| {
            Err(MeshError::IndexOutOfRange {
                face: corner,
                index,
                vertex_count: 0,
                line: None,
            })
        };
        assert_eq!(
            parse_off_face(b"3 7 x 2", 0, 1, refuse, &mut poly),
            Err(MeshError::IndexOutOfRange {
                face: 0,
                index: 7,
                vertex_count: 0,
                line: None
            })
        );
        assert_eq!(
            parse_off_face(b"3 0 1", 5, 2, shift, &mut poly),
            Err(parse_error_at(
                2,
                "face 5 declares 3 vertices but only 2 indices follow"
            ))
        );
    }

    fn awkward_triangle() -> Mesh {
        Mesh::new(
            vec![
                [-0.0, 0.1, 1e21],
                [1.0, 0.30000000000000004, -3.0],
                [1e-7, 0.0, 123456789.0],
            ],
            vec![[2, 0, 1]],
        )
        .unwrap()
    }

    #[test]
    fn writer_text_is_zero_based_with_an_edge_count_of_zero() {
        let mut out = Vec::new();
        write_off(&awkward_triangle(), &mut out).unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "OFF\n3 1 0\n\
             -0 0.1 1000000000000000000000\n\
             1 0.30000000000000004 -3\n\
             0.0000001 0 123456789\n\
             3 2 0 1\n"
        );
    }

    #[test]
    fn write_then_read_is_bit_identical() {
        let mut out = Vec::new();
        write_off(&awkward_triangle(), &mut out).unwrap();
        let back = unwrap_io(read_off(
            &out[..],
            Some(out.len() as u64),
            MemoryBudget::unlimited(),
        ))
        .unwrap();
        assert_eq!(back.notes, Vec::<String>::new());
        assert_eq!(back.mesh.faces(), &[[2, 0, 1]]);
        let bits: Vec<[u64; 3]> = back
            .mesh
            .positions()
            .iter()
            .map(|p| p.map(f64::to_bits))
            .collect();
        let expected: Vec<[u64; 3]> = [
            [-0.0, 0.1, 1e21],
            [1.0, 0.30000000000000004, -3.0],
            [1e-7, 0.0, 123456789.0],
        ]
        .iter()
        .map(|p| p.map(f64::to_bits))
        .collect();
        assert_eq!(bits, expected);
    }
}
