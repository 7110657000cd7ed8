//! Wavefront OBJ: `v` and `f` lines (polygons fan-triangulated, `f v/t/n`
//! index forms, negative indices relative), other keywords counted and
//! noted.

use std::io::{self, BufRead, Write};

use super::{
    Builder, LineReader, LoadedMesh, ReadError, parse_error, parse_f64, parse_i64, show,
    strip_comment, tokens,
};
use crate::mesh::Mesh;

pub(super) fn read_obj<R: BufRead>(reader: R) -> Result<LoadedMesh, ReadError> {
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
    use super::super::{MeshFormat, read_mesh_bytes};
    use super::*;
    use crate::error::MeshError;

    fn read(text: &str) -> Result<LoadedMesh, MeshError> {
        read_mesh_bytes(text.as_bytes(), MeshFormat::Obj)
    }

    #[test]
    fn polygons_are_fanned_and_index_forms_and_negative_indices_resolve() {
        let m =
            read("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nf 1/1/1 2//2 3/3 4\nf -4 -3 -1\n")
                .unwrap()
                .mesh;
        assert_eq!(m.n_vertices(), 4);
        assert_eq!(m.faces(), &[[0, 1, 2], [0, 2, 3], [0, 1, 3]]);
    }

    #[test]
    fn index_zero_and_out_of_range_indices_are_refused_with_their_line() {
        let zero = read("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n").unwrap_err();
        assert!(zero.to_string().contains("index 0"), "{zero}");
        let far = read("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").unwrap_err();
        assert!(far.to_string().contains("line 4"), "{far}");
        let short = read("v 0 0\n").unwrap_err();
        assert!(short.to_string().contains("found 2"), "{short}");
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
        write_obj(&mesh, &mut bytes).unwrap();
        let back = read_mesh_bytes(&bytes, MeshFormat::Obj).unwrap().mesh;
        assert_eq!(back.positions(), &p[..]);
        assert_eq!(back.faces(), mesh.faces());
    }
}
