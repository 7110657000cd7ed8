//! What the readers share: the formats ([`MeshFormat`]), what a read gives
//! ([`LoadedMesh`]) and the plumbing of every reader (lines, tokens, the
//! mesh assembled within the budget, the errors). A leaf of
//! [`crate::mesh::io`], which re-exports the public items and dispatches to
//! the readers and writers: the readers import it, it imports none of
//! them.

use std::io::{self, BufRead};
use std::path::Path;

use crate::error::MeshError;
use crate::limits::{self, MemoryBudget};
use crate::mesh::Mesh;

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
    pub(crate) fn from_path(path: &Path) -> Result<(MeshFormat, bool), MeshError> {
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
pub(super) enum ReadError {
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

/// The longest line the text readers read: a stream without line breaks
/// (`/dev/zero`) is refused here instead of read into memory to
/// exhaustion. (A polygon of a million vertices fits.)
pub const MAX_LINE_BYTES: usize = 16 << 20;

/// A line-by-line reader over bytes: lines without their `\n` / `\r\n`,
/// numbered from 1, each at most [`MAX_LINE_BYTES`].
pub(super) struct LineReader<R> {
    pub(super) reader: R,
    pub(super) format: &'static str,
    pub(super) buf: Vec<u8>,
    pub(super) line: usize,
    pub(super) missing_final_newline: bool,
}

impl<R: BufRead> LineReader<R> {
    pub(super) fn new(reader: R, format: &'static str) -> Self {
        LineReader {
            reader,
            format,
            buf: Vec::new(),
            line: 0,
            missing_final_newline: false,
        }
    }

    /// The next line and its 1-based number, `None` at the end.
    pub(super) fn next_line(&mut self) -> Result<Option<(usize, &[u8])>, ReadError> {
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
pub(super) fn strip_comment(line: &[u8]) -> &[u8] {
    match line.iter().position(|&b| b == b'#') {
        Some(i) => &line[..i],
        None => line,
    }
}

/// Whitespace-separated tokens of a line.
pub(super) fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| b.is_ascii_whitespace())
        .filter(|t| !t.is_empty())
}

/// A token for an error message: lossy UTF-8, at most 40 characters.
pub(super) fn show(token: &[u8]) -> String {
    let s = String::from_utf8_lossy(token);
    if s.chars().count() > 40 {
        format!("{}…", s.chars().take(40).collect::<String>())
    } else {
        s.into_owned()
    }
}

pub(super) fn parse_f64(token: &[u8]) -> Option<f64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

pub(super) fn parse_i64(token: &[u8]) -> Option<i64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

pub(super) fn parse_error(
    format: &'static str,
    line: usize,
    message: impl Into<String>,
) -> MeshError {
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
pub(super) struct Builder {
    pub(super) positions: Vec<[f64; 3]>,
    pub(super) faces: Vec<[usize; 3]>,
    pub(super) vertex_lines: Vec<usize>,
    pub(super) face_lines: Vec<usize>,
    pub(super) polygons_split: usize,
    pub(super) triangles_from_polygons: usize,
    pub(super) budget: MemoryBudget,
}

impl Builder {
    /// An empty mesh to assemble within `budget`.
    pub(super) fn within(budget: MemoryBudget) -> Builder {
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
    pub(super) fn make_room(&mut self, vertices: usize, faces: usize) -> Result<(), MeshError> {
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
    pub(super) fn vertex(&mut self, p: [f64; 3], line: Option<usize>) -> Result<(), MeshError> {
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
    pub(super) fn resolve(
        &self,
        index: i64,
        corner: usize,
        line: Option<usize>,
    ) -> Result<usize, MeshError> {
        usize::try_from(index).map_err(|_| MeshError::IndexOutOfRange {
            face: self.faces.len() + corner.saturating_sub(2),
            index,
            vertex_count: self.positions.len(),
            line,
        })
    }

    /// Adds a polygon (0-based indices), fan-triangulated.
    pub(super) fn polygon(&mut self, poly: &[usize], line: Option<usize>) -> Result<(), MeshError> {
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
    pub(super) fn finish(
        self,
        format: &'static str,
        mut notes: Vec<String>,
    ) -> Result<LoadedMesh, MeshError> {
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
pub(super) fn check_declared_counts(
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

/// A reader's result with I/O failures turned into a panic: the unit tests
/// read from memory, where only [`ReadError::Mesh`] can occur.
#[cfg(test)]
pub(super) fn unwrap_io(result: Result<LoadedMesh, ReadError>) -> Result<LoadedMesh, MeshError> {
    match result {
        Ok(loaded) => Ok(loaded),
        Err(ReadError::Mesh(e)) => Err(e),
        Err(ReadError::Io(e)) => panic!("unexpected I/O error: {e}"),
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::MeshFormat;
    use crate::error::MeshError;

    #[test]
    fn format_from_path() {
        let f = |p: &str| MeshFormat::from_path(Path::new(p));
        assert_eq!(f("a/b/c.obj").unwrap(), (MeshFormat::Obj, false));
        assert_eq!(f("c.PLY").unwrap(), (MeshFormat::Ply, false));
        assert_eq!(f("c.off.gz").unwrap(), (MeshFormat::Off, true));
        assert_eq!(f("x.y.Obj.GZ").unwrap(), (MeshFormat::Obj, true));
        assert_eq!(
            f("mesh.stl").unwrap_err(),
            MeshError::UnsupportedFormat {
                extension: ".stl".into()
            }
        );
        assert_eq!(
            f("mesh.stl.gz").unwrap_err(),
            MeshError::UnsupportedFormat {
                extension: ".stl.gz".into()
            }
        );
        assert!(matches!(
            f("noextension").unwrap_err(),
            MeshError::UnsupportedFormat { .. }
        ));
    }
}
