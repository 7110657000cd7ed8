//! OBJ: the reader and the writer (what is accepted: see the parent
//! module's documentation).

use std::io::{self, BufRead, Write};

use super::shared::{
    Builder, LineReader, LoadedMesh, ReadError, parse_error, parse_f64, parse_i64, show,
    strip_comment, tokens,
};
use crate::error::MeshError;
use crate::limits::MemoryBudget;
use crate::mesh::Mesh;

/// Reads an OBJ file line by line: `v` lines ([`parse_obj_vertex`]), `f`
/// lines ([`parse_obj_face`]), known records without geometry skipped, and
/// other records counted ([`Unknown`]) for a note ([`obj_notes`]).
pub(super) fn read_obj<R: BufRead>(
    reader: R,
    budget: MemoryBudget,
) -> Result<LoadedMesh, ReadError> {
    let mut lines = LineReader::new(reader, F);
    let mut b = Builder::within(budget);
    let mut poly: Vec<usize> = Vec::new();
    let mut unknown = Unknown::default();
    while let Some((line, text)) = lines.next_line()? {
        let mut it = tokens(strip_comment(text));
        let Some(keyword) = it.next() else { continue };
        match keyword {
            b"v" => b.vertex(parse_obj_vertex(it, line)?, Some(line))?,
            b"f" => {
                let defined = b.positions.len();
                parse_obj_face(
                    it,
                    line,
                    defined,
                    |index, corner| b.resolve(index, corner, Some(line)),
                    &mut poly,
                )?;
                b.polygon(&poly, Some(line))?;
            }
            b"vn" | b"vt" | b"vp" | b"g" | b"o" | b"s" | b"usemtl" | b"mtllib" | b"l" => {}
            other => unknown.record(other, line),
        }
    }
    let notes = obj_notes(&unknown, lines.missing_final_newline, lines.line);
    Ok(b.finish(F, notes)?)
}

/// The format name in OBJ errors.
const F: &str = "OBJ";

/// Parses the rest of a `v` line (`it`, after the keyword, at `line`):
/// three coordinates; more (a `w`, or vertex colours) are ignored.
fn parse_obj_vertex<'a>(
    mut it: impl Iterator<Item = &'a [u8]>,
    line: usize,
) -> Result<[f64; 3], MeshError> {
    let mut p = [0.0; 3];
    for (k, c) in p.iter_mut().enumerate() {
        let Some(tok) = it.next() else {
            return Err(parse_error(
                F,
                line,
                format!("expected 3 coordinates after 'v', found {k}"),
            ));
        };
        *c = parse_f64(tok)
            .ok_or_else(|| parse_error(F, line, format!("invalid number '{}'", show(tok))))?;
    }
    Ok(p)
}

/// Parses the rest of an `f` line (`it`, after the keyword, at `line`) into
/// `poly`: each corner `v`, `v/vt`, `v//vn` or `v/vt/vn` keeps its vertex
/// index, made 0-based by [`obj_index`] (`defined` vertices so far) and
/// mapped by `resolve(index, corner)` (the builder's check) as it is read.
fn parse_obj_face<'a>(
    it: impl Iterator<Item = &'a [u8]>,
    line: usize,
    defined: usize,
    mut resolve: impl FnMut(i64, usize) -> Result<usize, MeshError>,
    poly: &mut Vec<usize>,
) -> Result<(), MeshError> {
    poly.clear();
    for (corner, tok) in it.enumerate() {
        let head = tok.split(|&c| c == b'/').next().unwrap_or_default();
        let index = parse_i64(head)
            .ok_or_else(|| parse_error(F, line, format!("invalid face index '{}'", show(tok))))?;
        poly.push(resolve(obj_index(index, defined, line)?, corner)?);
    }
    Ok(())
}

/// An OBJ vertex index made 0-based: `i > 0` is 1-based, `i < 0` relative
/// (`-1` is the last of the `defined` vertices so far; the sum saturates,
/// and a result below 0 is left for the builder to refuse), `0` an error.
fn obj_index(index: i64, defined: usize, line: usize) -> Result<i64, MeshError> {
    match index {
        0 => Err(parse_error(
            F,
            line,
            "face index 0 is invalid (OBJ indices start at 1)",
        )),
        i if i > 0 => Ok(i - 1),
        i => Ok(i64::try_from(defined).unwrap_or(i64::MAX).saturating_add(i)),
    }
}

/// Lines of record types the reader does not know: how many, and the
/// first three distinct keywords with their lines, for the note.
#[derive(Debug, Default, PartialEq)]
struct Unknown {
    count: usize,
    examples: Vec<(String, usize)>,
}

impl Unknown {
    fn record(&mut self, keyword: &[u8], line: usize) {
        self.count += 1;
        if self.examples.len() < 3 && !self.examples.iter().any(|(k, _)| k.as_bytes() == keyword) {
            self.examples.push((show(keyword), line));
        }
    }
}

/// The reader's notes: the unknown records, if any, and a missing final
/// newline (the last line, `last_line`, may have been cut off).
fn obj_notes(unknown: &Unknown, missing_final_newline: bool, last_line: usize) -> Vec<String> {
    let mut notes = Vec::new();
    if unknown.count > 0 {
        let examples: Vec<String> = unknown
            .examples
            .iter()
            .map(|(k, l)| format!("'{k}' at line {l}"))
            .collect();
        notes.push(format!(
            "ignored {} OBJ line(s) of unsupported record types (e.g. {})",
            unknown.count,
            examples.join(", ")
        ));
    }
    if missing_final_newline {
        notes.push(format!(
            "the OBJ file does not end with a newline: if it was cut off, line {last_line} may be incomplete"
        ));
    }
    notes
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
mod tests;
