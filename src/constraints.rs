//! Constraints (paper eq. 3–6) (docs/formulations.md §1) and their JSON file format (README,
//! "Constraint files").
//!
//! Every constraint is one scalar linear row `Σ_k a_k p_{v_k} = u` shared by
//! the x, y and z coordinates (a 3-vector right-hand side):
//!
//! | kind | row | right-hand side |
//! |---|---|---|
//! | position | `p_i` | target `u` |
//! | edge | `t p_i + (1−t) p_j` | target `u` |
//! | face | `s p_i + t p_j + (1−s−t) p_k` | target `u` |
//! | relative | `p_i − p_j` | vector `v` |
//!
//! A constraint is *hard* (held exactly) unless it has a `weight` `w > 0`,
//! in which case it is *soft*: the row and right-hand side are multiplied by
//! `w` and appended to the least-squares system, i.e. it adds
//! `w² ‖row·P − u‖²` to the energy.
//!
//! The coefficients of position, edge and face rows sum to 1 (they pin the
//! translation of the component they are on); a relative row sums to 0 (it
//! does not). No row of these four kinds can be all zero.
//!
//! The JSON format:
//! ```json
//! {"constraints": [
//!   {"type": "position", "vertex": 12, "target": [0.1, 0.2, 0.3]},
//!   {"type": "edge", "vertices": [4, 5], "t": 0.3, "target": [0, 0, 1]},
//!   {"type": "face", "vertices": [1, 2, 3], "barycentric": [0.2, 0.3], "target": [0, 1, 0]},
//!   {"type": "relative", "vertices": [7, 9], "vector": [0, 0, 0.5]},
//!   {"type": "position", "vertex": 40, "target": [1, 1, 1], "weight": 10.0}
//! ]}
//! ```
//! A constraint may name a group, `"group": "handle"`: the constraints of a
//! group move together ([`crate::Deformer::transform_group`],
//! [`crate::Deformer::set_group_targets`]).
//!
//! Unknown fields are an error (a misspelt `"wieght"` must not silently
//! make a soft constraint hard), except `"name"` and `"comment"`, which are
//! free text and ignored.
//!
//! An optional top-level `"mesh": {"vertices": n, "faces": m, "fingerprint":
//! "…"}` names the mesh the constraints were made for
//! ([`MeshSignature`](crate::mesh::MeshSignature), written by [`crate::scene`]);
//! [`ConstraintSet::mesh_mismatch`] compares it with the mesh at hand.

use std::path::Path;

use crate::error::{ConstraintError, Error};

mod parse;
mod set;

pub use set::{Constraint, ConstraintKind, ConstraintSet, Row};

/// Reads a constraints file and checks its vertices against a mesh of
/// `n_vertices` vertices.
pub fn read_constraints(path: &Path, n_vertices: usize) -> Result<ConstraintSet, Error> {
    let set = read_constraints_file(path, crate::limits::MemoryBudget::default())?;
    set.check_vertices(n_vertices)?;
    Ok(set)
}

/// Reads a constraints file within `budget`.
///
/// The file is parsed as it is read, never held whole: a regular file's
/// size is checked against the budget first
/// ([`crate::limits::CONSTRAINT_BYTES_PER_FILE_BYTE`] per byte), and a
/// stream (a pipe, a device) is read up to the size that estimate allows;
/// one that reaches it is refused ([`ConstraintError::TooLarge`], naming
/// the budget and the bytes read), whatever its first part parses as.
pub fn read_constraints_file(
    path: &Path,
    budget: crate::limits::MemoryBudget,
) -> Result<ConstraintSet, Error> {
    use std::io::{BufRead, BufReader, Read};
    let io = |e| Error::io(path, e);
    let file = crate::input::open_input(path).map_err(io)?;
    let per_byte = crate::limits::CONSTRAINT_BYTES_PER_FILE_BYTE;
    let name = path.display().to_string();
    let cap = crate::limits::file_read_cap(&file, &name, budget, per_byte)
        .map_err(|detail| ConstraintError::TooLarge { detail })?;
    let mut reader = BufReader::with_capacity(1 << 16, file.take(cap.saturating_add(1)));
    if reader.fill_buf().map_err(io)?.starts_with(BOM) {
        reader.consume(BOM.len());
    }
    let mut de = serde_json::Deserializer::from_reader(&mut reader);
    let result = parse::parse(&mut de);
    drop(de);
    if reader.get_ref().limit() == 0 {
        // The stream went on past the cap: refused, parsed or not.
        let detail = crate::limits::beyond_the_cap(budget, &name, cap, "", per_byte, "parsing");
        return Err(ConstraintError::TooLarge { detail }.into());
    }
    match result {
        Ok(set) => Ok(set),
        Err(parse::Failure::Constraint(e)) => Err(e.into()),
        Err(parse::Failure::Json(e)) if e.is_io() => Err(io(e.into())),
        Err(parse::Failure::Json(e)) => Err(parse::json_error(&e).into()),
    }
}

/// The UTF-8 byte-order mark.
const BOM: &[u8] = "\u{feff}".as_bytes();

/// Parses the JSON constraint format (vertex ranges are not checked here;
/// see [`ConstraintSet::check_vertices`]).
///
/// A leading UTF-8 byte-order mark (which Windows editors write) is skipped;
/// JSON itself (RFC 8259 §8.1) forbids it but allows parsers to ignore it.
///
/// The text is read in one pass straight into the constraints (never as a
/// JSON document tree): parsing needs about the memory of the constraints
/// themselves besides the text. Constraints are checked as they are read:
/// the first invalid one is reported, with its index, even if the text
/// after it is not JSON.
pub fn parse_constraints(text: &str) -> Result<ConstraintSet, ConstraintError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut de = serde_json::Deserializer::from_str(text);
    parse::parse(&mut de).map_err(|e| match e {
        parse::Failure::Constraint(e) => e,
        parse::Failure::Json(e) => parse::json_error(&e),
    })
}
