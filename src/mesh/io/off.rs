//! OFF (Object File Format): the header, counts, vertex lines and face
//! lines, with the declared counts checked against the input size.

use std::io::{self, BufRead, Write};

use super::{
    Builder, LineReader, LoadedMesh, ReadError, check_declared_counts, parse_error, parse_f64,
    parse_i64, show, strip_comment, tokens,
};
use crate::error::MeshError;
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

pub(super) fn read_off<R: BufRead>(reader: R, size: Option<u64>) -> Result<LoadedMesh, ReadError> {
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
    use super::super::{MeshFormat, read_mesh_bytes};
    use super::*;

    fn read(text: &str) -> Result<LoadedMesh, MeshError> {
        read_mesh_bytes(text.as_bytes(), MeshFormat::Off)
    }

    #[test]
    fn comments_blank_lines_and_polygons_are_read() {
        let m = read("OFF\n# a square\n\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0 # last\n4 0 1 2 3\n")
            .unwrap()
            .mesh;
        assert_eq!(m.n_vertices(), 4);
        assert_eq!(m.faces(), &[[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn counts_beyond_the_data_and_bad_indices_are_refused() {
        assert!(read("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").is_err());
        assert!(read("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n").is_err());
        assert!(read("OFF\n-3 1 0\n").is_err());
    }

    #[test]
    fn written_files_read_back_bit_for_bit() {
        let p = vec![
            [0.1, -2.5e-300, 1e300],
            [1.0 / 3.0, 0.0, -0.0],
            [7.0, 8.0, 9.0],
        ];
        let mesh = Mesh::new(p.clone(), vec![[0, 1, 2]]).unwrap();
        let mut bytes = Vec::new();
        write_off(&mesh, &mut bytes).unwrap();
        let back = read_mesh_bytes(&bytes, MeshFormat::Off).unwrap().mesh;
        assert_eq!(back.positions(), &p[..]);
        assert_eq!(back.faces(), mesh.faces());
    }
}
