//! OBJ: the reader and the writer (what is accepted: see the parent
//! module's documentation).

use std::io::{self, BufRead, Write};

use super::{
    Builder, LineReader, LoadedMesh, ReadError, parse_error, parse_f64, parse_i64, show,
    strip_comment, tokens,
};
use crate::limits::MemoryBudget;
use crate::mesh::Mesh;

pub(super) fn read_obj<R: BufRead>(
    reader: R,
    budget: MemoryBudget,
) -> Result<LoadedMesh, ReadError> {
    const F: &str = "OBJ";
    let mut lines = LineReader::new(reader, F);
    let mut b = Builder::within(budget);
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

#[cfg(test)]
mod tests {
    use std::io::Write as _;

    use flate2::Compression;
    use flate2::write::GzEncoder;

    use super::*;
    use crate::error::MeshError;
    use crate::mesh::io::{MeshFormat, read_mesh_bytes, unwrap_io};

    fn obj(text: &str) -> Result<LoadedMesh, MeshError> {
        unwrap_io(read_obj(text.as_bytes(), MemoryBudget::unlimited()))
    }

    fn parse_error_at(line: usize, message: &str) -> MeshError {
        MeshError::Parse {
            format: "OBJ",
            line: Some(line),
            message: message.into(),
        }
    }

    const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

    #[test]
    fn crlf_tabs_blank_lines_and_comments_glued_to_tokens() {
        let text =
            "v 0 0 0\r\nv\t1\t0\t0\r\n#full line\r\n\r\n   \r\nv 0 1 0#glued\r\nf 1 2 3#glued\r\n";
        let loaded = obj(text).unwrap();
        assert_eq!(
            loaded.mesh.positions(),
            &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
        );
        assert_eq!(loaded.mesh.faces(), &[[0, 1, 2]]);
        assert_eq!(loaded.notes, Vec::<String>::new());
    }

    #[test]
    fn number_forms_and_bad_vertex_lines() {
        let text = "v +1 -2.5e1 .5\nv 5. 0 0\nv 0 1E2 0\nf 1 2 3\n";
        assert_eq!(
            obj(text).unwrap().mesh.positions(),
            &[[1.0, -25.0, 0.5], [5.0, 0.0, 0.0], [0.0, 100.0, 0.0]]
        );
        assert_eq!(
            obj("v 1 2\n").unwrap_err(),
            parse_error_at(1, "expected 3 coordinates after 'v', found 2")
        );
        assert_eq!(
            obj("v 0 0 0\nv 1,5 0 0\n").unwrap_err(),
            parse_error_at(2, "invalid number '1,5'")
        );
        assert_eq!(
            obj("v 0 0 0\nv 0 0 -inf\n").unwrap_err(),
            MeshError::NonFiniteCoordinate {
                vertex: 1,
                value: f64::NEG_INFINITY,
                line: Some(2),
            }
        );
    }

    #[test]
    fn texture_and_normal_indices_are_not_read() {
        // Only the part before the first '/' is parsed: a texture index of
        // 999 or a normal index 'abc' is not checked.
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/999/abc 2/x 3//\n";
        assert_eq!(obj(text).unwrap().mesh.faces(), &[[0, 1, 2]]);
        assert_eq!(
            obj("v 0 0 0\nf /1/1 1 1\n").unwrap_err(),
            parse_error_at(2, "invalid face index '/1/1'")
        );
    }

    #[test]
    fn relative_indices_count_back_from_the_vertices_read_so_far() {
        // After 3 vertices, -3 -2 -1 are 0 1 2; after 4, -3 is 1, -1 is 3,
        // -2 is 2; absolute and relative indices mix in one face.
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 1 1 0\nf -3 -1 3\n";
        assert_eq!(obj(text).unwrap().mesh.faces(), &[[0, 1, 2], [1, 3, 2]]);
    }

    #[test]
    fn out_of_range_indices_name_the_face_and_the_line() {
        // A relative index before the first vertex: 4 − 9 = −5, in corner 4
        // of a pentagon after one face, i.e. in its third triangle (face 3).
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 1 2 3 4 -9\n";
        assert_eq!(
            obj(text).unwrap_err(),
            MeshError::IndexOutOfRange {
                face: 3,
                index: -5,
                vertex_count: 4,
                line: Some(6),
            }
        );
        // Too large an absolute index is caught when the mesh is built, with
        // the line of its face (0-based index 3 of 3 vertices).
        assert_eq!(
            obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").unwrap_err(),
            MeshError::IndexOutOfRange {
                face: 0,
                index: 3,
                vertex_count: 3,
                line: Some(4),
            }
        );
        assert_eq!(
            obj("v 0 0 0\nf 1 2 99999999999999999999\n").unwrap_err(),
            parse_error_at(2, "invalid face index '99999999999999999999'")
        );
        assert_eq!(
            obj("v 0 0 0\nf\n").unwrap_err(),
            MeshError::BadFaceSize {
                face: 0,
                sides: 0,
                line: Some(2),
            }
        );
    }

    #[test]
    fn polygons_are_fanned_from_their_first_vertex_with_a_note() {
        // A unit square (1 2 3 4) and a pentagon (2 5 6 7 3) sharing the
        // edge 2–3.
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2.5 0.5 0\nv 2 1 0\n\
                    f 1 2 3 4\nf 2 5 6 7 3\n";
        let loaded = obj(text).unwrap();
        assert_eq!(
            loaded.mesh.faces(),
            &[[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 6], [1, 6, 2]]
        );
        assert_eq!(
            loaded.notes,
            vec![
                "2 OBJ polygon(s) with more than 3 vertices were fan-triangulated into 5 triangles"
                    .to_string()
            ]
        );
    }

    #[test]
    fn unknown_records_are_counted_and_three_kinds_named() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\ncurv 1\ncurv 2\nvn 0 0 1\nparm u 0\nl 1 2\ndeg 3\nbmat u\nf 1 2 3\n";
        assert_eq!(
            obj(text).unwrap().notes,
            vec![
                "ignored 5 OBJ line(s) of unsupported record types (e.g. 'curv' at line 4, 'parm' at line 7, 'deg' at line 9)"
                    .to_string()
            ]
        );
    }

    #[test]
    fn missing_final_newline_note_names_the_last_line() {
        let note = |l: usize| {
            format!(
                "the OBJ file does not end with a newline: if it was cut off, line {l} may be incomplete"
            )
        };
        assert_eq!(obj(TRIANGLE.trim_end()).unwrap().notes, vec![note(4)]);
        assert_eq!(
            obj(&format!("{TRIANGLE}# end")).unwrap().notes,
            vec![note(5)]
        );
    }

    #[test]
    fn gzip_including_several_members_is_read_by_content() {
        let gz = |part: &str| {
            let mut e = GzEncoder::new(Vec::new(), Compression::default());
            e.write_all(part.as_bytes()).unwrap();
            e.finish().unwrap()
        };
        let expected_positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let one = read_mesh_bytes(&gz(TRIANGLE), MeshFormat::Obj).unwrap();
        assert_eq!(one.mesh.positions(), &expected_positions);
        assert_eq!(one.mesh.faces(), &[[0, 1, 2]]);
        // Two concatenated gzip members (as `cat a.gz b.gz` makes) are one
        // stream; the cut falls inside a line.
        let mut two = gz("v 0 0 0\nv 1 0 ");
        two.extend(gz("0\nv 0 1 0\nf 1 2 3\n"));
        let two = read_mesh_bytes(&two, MeshFormat::Obj).unwrap();
        assert_eq!(two.mesh.positions(), &expected_positions);
        assert_eq!(two.mesh.faces(), &[[0, 1, 2]]);
        // A gzip stream cut short is a parse error, not a shorter mesh.
        let whole = gz(TRIANGLE);
        let cut = &whole[..whole.len() - 8];
        assert!(matches!(
            read_mesh_bytes(cut, MeshFormat::Obj),
            Err(MeshError::Parse {
                format: "OBJ",
                line: None,
                ..
            })
        ));
    }

    fn awkward_triangle() -> Mesh {
        Mesh::new(
            vec![
                [0.1, -0.0, 1e21],
                [1.0, 0.30000000000000004, -3.0],
                [1e-7, 0.0, 123456789.0],
            ],
            vec![[0, 1, 2]],
        )
        .unwrap()
    }

    #[test]
    fn writer_text_is_one_based_shortest_round_trip_decimal() {
        let mut out = Vec::new();
        write_obj(&awkward_triangle(), &mut out).unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "# written by lse-deform: 3 vertices, 1 faces\n\
             v 0.1 -0 1000000000000000000000\n\
             v 1 0.30000000000000004 -3\n\
             v 0.0000001 0 123456789\n\
             f 1 2 3\n"
        );
    }

    #[test]
    fn write_then_read_is_bit_identical() {
        let mut out = Vec::new();
        write_obj(&awkward_triangle(), &mut out).unwrap();
        let back = unwrap_io(read_obj(&out[..], MemoryBudget::unlimited())).unwrap();
        assert_eq!(back.notes, Vec::<String>::new());
        assert_eq!(back.mesh.faces(), &[[0, 1, 2]]);
        let bits: Vec<[u64; 3]> = back
            .mesh
            .positions()
            .iter()
            .map(|p| p.map(f64::to_bits))
            .collect();
        // -0.0 keeps its sign bit; 0.1 + 0.2 keeps its last ulp.
        let expected: Vec<[u64; 3]> = [
            [0.1, -0.0, 1e21],
            [1.0, 0.30000000000000004, -3.0],
            [1e-7, 0.0, 123456789.0],
        ]
        .iter()
        .map(|p| p.map(f64::to_bits))
        .collect();
        assert_eq!(bits, expected);
        assert_eq!(bits[0][1], 1 << 63);
    }
}
