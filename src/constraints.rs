//! Constraints (paper eq. 3–6) and their JSON file format (DESIGN.md §3).
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
//! ([`MeshSignature`], written by [`crate::scene`]);
//! [`ConstraintSet::mesh_mismatch`] compares it with the mesh at hand.

use std::collections::HashMap;
use std::path::Path;

use serde::Deserialize;
use serde_json::{Map, Value};

use crate::error::{ConstraintError, Error};
use crate::mesh::{Mesh, MeshSignature};

/// The geometric content of a constraint.
#[derive(Debug, Clone, PartialEq)]
pub enum ConstraintKind {
    /// `p_vertex = target` (eq. 3).
    Position {
        /// The vertex.
        vertex: usize,
        /// Its target position.
        target: [f64; 3],
    },
    /// `t p_i + (1−t) p_j = target` (eq. 4).
    Edge {
        /// `[i, j]`.
        vertices: [usize; 2],
        /// Weight of `p_i`.
        t: f64,
        /// Target of the point on the edge.
        target: [f64; 3],
    },
    /// `s p_i + t p_j + (1−s−t) p_k = target` (eq. 5).
    Face {
        /// `[i, j, k]`.
        vertices: [usize; 3],
        /// `[s, t]`.
        barycentric: [f64; 2],
        /// Target of the point on the face.
        target: [f64; 3],
    },
    /// `p_i − p_j = vector` (eq. 6).
    Relative {
        /// `[i, j]`.
        vertices: [usize; 2],
        /// The prescribed difference.
        vector: [f64; 3],
    },
}

/// One constraint: its kind, whether it is hard (`weight == None`) or
/// soft with a weight `w > 0`, and the named group it belongs to, if any.
///
/// ```
/// use lse_deform::Constraint;
/// let fixed = Constraint::position(0, [0.0, 0.0, 0.0]);
/// let handle = Constraint::position(7, [1.0, 2.0, 3.0]).in_group("handle");
/// let soft = Constraint::edge([3, 4], 0.25, [0.0, 1.0, 0.0]).with_weight(10.0);
/// assert!(fixed.is_hard() && !soft.is_hard());
/// assert_eq!(handle.group.as_deref(), Some("handle"));
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Constraint {
    /// What is constrained.
    pub kind: ConstraintKind,
    /// `None` for a hard constraint, `Some(w)` (finite, > 0) for a soft one.
    pub weight: Option<f64>,
    /// The named group (a handle, a fixed region) the constraint belongs
    /// to: groups are moved together
    /// ([`crate::Deformer::transform_group`]). `"group"` in the JSON format.
    pub group: Option<String>,
}

/// A sparse constraint row: up to three `(vertex, coefficient)` pairs.
/// Zero coefficients (an edge with `t = 1`) are dropped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    entries: [(usize, f64); 3],
    len: usize,
}

impl Row {
    fn new(pairs: &[(usize, f64)]) -> Row {
        let mut entries = [(0, 0.0); 3];
        let mut len = 0;
        for &(v, a) in pairs {
            if a != 0.0 {
                entries[len] = (v, a);
                len += 1;
            }
        }
        Row { entries, len }
    }

    /// The nonzero `(vertex, coefficient)` pairs.
    pub fn entries(&self) -> &[(usize, f64)] {
        &self.entries[..self.len]
    }

    /// `Σ_k a_k X[v_k]` for a position array.
    pub fn apply(&self, x: &[[f64; 3]]) -> [f64; 3] {
        let mut s = [0.0; 3];
        for &(v, a) in self.entries() {
            for k in 0..3 {
                s[k] += a * x[v][k];
            }
        }
        s
    }

    /// Euclidean norm of the coefficient vector.
    pub fn norm(&self) -> f64 {
        self.entries().iter().map(|e| e.1 * e.1).sum::<f64>().sqrt()
    }
}

impl ConstraintKind {
    /// The name used in the JSON file.
    pub fn name(&self) -> &'static str {
        match self {
            ConstraintKind::Position { .. } => "position",
            ConstraintKind::Edge { .. } => "edge",
            ConstraintKind::Face { .. } => "face",
            ConstraintKind::Relative { .. } => "relative",
        }
    }

    /// The vertices involved.
    pub fn vertices(&self) -> &[usize] {
        match self {
            ConstraintKind::Position { vertex, .. } => std::slice::from_ref(vertex),
            ConstraintKind::Edge { vertices, .. } => vertices,
            ConstraintKind::Face { vertices, .. } => vertices,
            ConstraintKind::Relative { vertices, .. } => vertices,
        }
    }

    /// The row of coefficients.
    pub fn row(&self) -> Row {
        match *self {
            ConstraintKind::Position { vertex, .. } => Row::new(&[(vertex, 1.0)]),
            ConstraintKind::Edge { vertices, t, .. } => {
                Row::new(&[(vertices[0], t), (vertices[1], 1.0 - t)])
            }
            ConstraintKind::Face {
                vertices,
                barycentric: [s, t],
                ..
            } => Row::new(&[
                (vertices[0], s),
                (vertices[1], t),
                (vertices[2], 1.0 - s - t),
            ]),
            ConstraintKind::Relative { vertices, .. } => {
                Row::new(&[(vertices[0], 1.0), (vertices[1], -1.0)])
            }
        }
    }

    /// The right-hand side (target or vector).
    pub fn rhs(&self) -> [f64; 3] {
        match *self {
            ConstraintKind::Position { target, .. }
            | ConstraintKind::Edge { target, .. }
            | ConstraintKind::Face { target, .. } => target,
            ConstraintKind::Relative { vector, .. } => vector,
        }
    }

    /// Replaces the right-hand side (target or vector), keeping the row.
    pub fn set_rhs(&mut self, value: [f64; 3]) {
        match self {
            ConstraintKind::Position { target, .. }
            | ConstraintKind::Edge { target, .. }
            | ConstraintKind::Face { target, .. } => *target = value,
            ConstraintKind::Relative { vector, .. } => *vector = value,
        }
    }

    /// `true` if the row's coefficients sum to a nonzero value, i.e. the
    /// constraint pins the translation of the vertices' component
    /// (position, edge and face do; relative does not).
    pub fn pins_translation(&self) -> bool {
        !matches!(self, ConstraintKind::Relative { .. })
    }
}

impl Constraint {
    /// A hard constraint.
    pub fn hard(kind: ConstraintKind) -> Constraint {
        Constraint {
            kind,
            weight: None,
            group: None,
        }
    }

    /// A soft constraint of weight `w`.
    pub fn soft(kind: ConstraintKind, w: f64) -> Constraint {
        Constraint {
            kind,
            weight: Some(w),
            group: None,
        }
    }

    /// Hard `p_vertex = target` (eq. 3).
    pub fn position(vertex: usize, target: [f64; 3]) -> Constraint {
        Constraint::hard(ConstraintKind::Position { vertex, target })
    }

    /// Hard `t p_i + (1−t) p_j = target` (eq. 4), `vertices = [i, j]`.
    pub fn edge(vertices: [usize; 2], t: f64, target: [f64; 3]) -> Constraint {
        Constraint::hard(ConstraintKind::Edge {
            vertices,
            t,
            target,
        })
    }

    /// Hard `s p_i + t p_j + (1−s−t) p_k = target` (eq. 5),
    /// `vertices = [i, j, k]`, `barycentric = [s, t]`.
    pub fn face(vertices: [usize; 3], barycentric: [f64; 2], target: [f64; 3]) -> Constraint {
        Constraint::hard(ConstraintKind::Face {
            vertices,
            barycentric,
            target,
        })
    }

    /// Hard `p_i − p_j = vector` (eq. 6), `vertices = [i, j]`.
    pub fn relative(vertices: [usize; 2], vector: [f64; 3]) -> Constraint {
        Constraint::hard(ConstraintKind::Relative { vertices, vector })
    }

    /// The same constraint made soft with weight `w` (checked when it is
    /// added to a [`ConstraintSet`]).
    pub fn with_weight(mut self, w: f64) -> Constraint {
        self.weight = Some(w);
        self
    }

    /// The same constraint in the named group.
    pub fn in_group(mut self, name: impl Into<String>) -> Constraint {
        self.group = Some(name.into());
        self
    }

    /// `true` for hard constraints.
    pub fn is_hard(&self) -> bool {
        self.weight.is_none()
    }
}

/// An ordered list of constraints. The order is the priority of hard
/// constraints: of two conflicting ones the earlier is kept.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ConstraintSet {
    constraints: Vec<Constraint>,
    /// The mesh the constraints were made for, when known.
    mesh: Option<MeshSignature>,
    /// Each group's name and members (increasing), in order of first
    /// appearance: derived from `constraints` by [`ConstraintSet::from_vec`]
    /// and [`ConstraintSet::push`], the only ways a constraint enters (a
    /// constraint's group cannot change inside the set), so that a drag's
    /// [`ConstraintSet::group`] does not scan every constraint per frame.
    groups: Vec<(String, Vec<usize>)>,
    /// The position of each group in `groups`, by name: adding a
    /// constraint and looking a group up take constant time, not a scan of
    /// the groups (10⁵ distinct groups took 22 s that way).
    group_index: HashMap<String, usize>,
}

impl ConstraintSet {
    /// An empty set.
    pub fn new() -> ConstraintSet {
        ConstraintSet::default()
    }

    /// Wraps a list, checking each constraint's own values (finite numbers,
    /// valid weights, no vertex repeated within a constraint). Vertex ranges
    /// are checked against a mesh by [`ConstraintSet::check_vertices`].
    pub fn from_vec(constraints: Vec<Constraint>) -> Result<ConstraintSet, ConstraintError> {
        let mut set = ConstraintSet::new();
        set.constraints.reserve(constraints.len());
        for c in constraints {
            set.push(c)?;
        }
        Ok(set)
    }

    /// Hard position constraints `p_{vertices[i]} = targets[i]`, constraint
    /// `i` for pair `i`: libigl's position-only form of
    /// `min_quad_with_fixed` (known indices `b`, their values `bc`). The
    /// lengths must agree; values are checked as by [`ConstraintSet::push`],
    /// vertex ranges later by [`ConstraintSet::check_vertices`].
    ///
    /// ```
    /// use lse_deform::ConstraintSet;
    /// let set = ConstraintSet::positions(&[3, 7], &[[0.0; 3], [1.0, 2.0, 3.0]]).unwrap();
    /// assert_eq!((set.len(), set.n_hard()), (2, 2));
    /// assert_eq!(set[1].kind.vertices(), &[7]);
    /// assert!(ConstraintSet::positions(&[3], &[]).is_err());
    /// ```
    pub fn positions(
        vertices: &[usize],
        targets: &[[f64; 3]],
    ) -> Result<ConstraintSet, ConstraintError> {
        if vertices.len() != targets.len() {
            return Err(ConstraintError::Shape {
                message: format!(
                    "{} vertices but {} targets: position constraints need one target per vertex",
                    vertices.len(),
                    targets.len()
                ),
            });
        }
        ConstraintSet::from_vec(
            vertices
                .iter()
                .zip(targets)
                .map(|(&v, &p)| Constraint::position(v, p))
                .collect(),
        )
    }

    /// The mesh the constraints were made for (the file's `"mesh"` object),
    /// if recorded.
    pub fn mesh(&self) -> Option<&MeshSignature> {
        self.mesh.as_ref()
    }

    /// Records (or forgets) the mesh the constraints were made for; written
    /// by [`ConstraintSet::to_json`].
    pub fn set_mesh(&mut self, mesh: Option<MeshSignature>) {
        self.mesh = mesh;
    }

    /// `None` when no mesh is recorded or the recorded one matches `mesh`
    /// (counts and [fingerprint](crate::mesh::fingerprint)); otherwise a
    /// sentence saying what differs (for a warning or, strictly, a
    /// [`ConstraintError::MeshMismatch`]).
    pub fn mesh_mismatch(&self, mesh: &Mesh) -> Option<String> {
        self.mesh.as_ref().and_then(|sig| sig.mismatch(mesh))
    }

    /// Appends a constraint, checking its values; returns its index (the
    /// index [`crate::Deformer::set_target`] and the report use).
    pub fn push(&mut self, c: Constraint) -> Result<usize, ConstraintError> {
        let index = self.constraints.len();
        check_values(index, &c)?;
        self.add_to_group(index, &c);
        self.constraints.push(c);
        Ok(index)
    }

    /// Records constraint `index` (`c`) as a member of its group, if any.
    fn add_to_group(&mut self, index: usize, c: &Constraint) {
        let Some(name) = c.group.as_deref() else {
            return;
        };
        match self.group_index.get(name) {
            Some(&g) => self.groups[g].1.push(index),
            None => {
                self.group_index.insert(name.to_string(), self.groups.len());
                self.groups.push((name.to_string(), vec![index]));
            }
        }
    }

    /// The indices of the constraints in group `name`, increasing (empty if
    /// there is no such group).
    pub fn group(&self, name: &str) -> &[usize] {
        self.group_index
            .get(name)
            .map_or(&[], |&g| self.groups[g].1.as_slice())
    }

    /// The group names, each once, in order of first appearance.
    pub fn group_names(&self) -> Vec<&str> {
        self.groups.iter().map(|(g, _)| g.as_str()).collect()
    }

    /// The constraints in priority order.
    pub fn as_slice(&self) -> &[Constraint] {
        &self.constraints
    }

    /// Number of constraints.
    pub fn len(&self) -> usize {
        self.constraints.len()
    }

    /// `true` if there are none.
    pub fn is_empty(&self) -> bool {
        self.constraints.is_empty()
    }

    /// Sets the target (or relative vector) of constraint `index`.
    pub fn set_rhs(&mut self, index: usize, value: [f64; 3]) -> Result<(), ConstraintError> {
        if value.iter().any(|v| !v.is_finite()) {
            return Err(ConstraintError::NonFinite {
                index,
                field: "target",
            });
        }
        match self.constraints.get_mut(index) {
            Some(c) => {
                c.kind.set_rhs(value);
                Ok(())
            }
            None => Err(ConstraintError::Shape {
                message: format!(
                    "constraint {index} does not exist (there are {})",
                    self.constraints.len()
                ),
            }),
        }
    }

    /// Checks that every vertex is `< n_vertices`.
    pub fn check_vertices(&self, n_vertices: usize) -> Result<(), ConstraintError> {
        for (index, c) in self.constraints.iter().enumerate() {
            for &v in c.kind.vertices() {
                if v >= n_vertices {
                    return Err(ConstraintError::VertexOutOfRange {
                        index,
                        vertex: v as u64,
                        vertex_count: n_vertices,
                    });
                }
            }
        }
        Ok(())
    }

    /// Number of hard constraints.
    pub fn n_hard(&self) -> usize {
        self.constraints.iter().filter(|c| c.is_hard()).count()
    }

    /// Serialises to the JSON file format.
    pub fn to_json(&self) -> String {
        let items: Vec<Value> = self.constraints.iter().map(constraint_to_json).collect();
        let mut s = String::from("{");
        if let Some(mesh) = &self.mesh {
            s.push_str("\"mesh\": ");
            s.push_str(&serde_json::to_string(mesh).unwrap_or_else(|_| "null".into()));
            s.push_str(",\n ");
        }
        s.push_str("\"constraints\": [\n");
        for (k, item) in items.iter().enumerate() {
            s.push_str("  ");
            s.push_str(&item.to_string());
            if k + 1 < items.len() {
                s.push(',');
            }
            s.push('\n');
        }
        s.push_str("]}\n");
        s
    }
}

impl std::ops::Index<usize> for ConstraintSet {
    type Output = Constraint;
    fn index(&self, i: usize) -> &Constraint {
        &self.constraints[i]
    }
}

fn check_values(index: usize, c: &Constraint) -> Result<(), ConstraintError> {
    let verts = c.kind.vertices();
    for a in 0..verts.len() {
        for b in a + 1..verts.len() {
            if verts[a] == verts[b] {
                return Err(ConstraintError::RepeatedVertex {
                    index,
                    vertex: verts[a],
                });
            }
        }
    }
    let finite3 = |v: &[f64; 3]| v.iter().all(|x| x.is_finite());
    match &c.kind {
        ConstraintKind::Position { target, .. } if !finite3(target) => {
            return Err(ConstraintError::NonFinite {
                index,
                field: "target",
            });
        }
        ConstraintKind::Edge { t, target, .. } => {
            if !t.is_finite() {
                return Err(ConstraintError::NonFinite { index, field: "t" });
            }
            if !finite3(target) {
                return Err(ConstraintError::NonFinite {
                    index,
                    field: "target",
                });
            }
        }
        ConstraintKind::Face {
            barycentric,
            target,
            ..
        } => {
            if !barycentric.iter().all(|x| x.is_finite()) {
                return Err(ConstraintError::NonFinite {
                    index,
                    field: "barycentric",
                });
            }
            if !finite3(target) {
                return Err(ConstraintError::NonFinite {
                    index,
                    field: "target",
                });
            }
        }
        ConstraintKind::Relative { vector, .. } if !finite3(vector) => {
            return Err(ConstraintError::NonFinite {
                index,
                field: "vector",
            });
        }
        _ => {}
    }
    if let Some(w) = c.weight
        && !(w.is_finite() && w > 0.0)
    {
        return Err(ConstraintError::InvalidWeight { index, weight: w });
    }
    Ok(())
}

/// Reads a constraints file and checks its vertices against a mesh of
/// `n_vertices` vertices.
pub fn read_constraints(path: &Path, n_vertices: usize) -> Result<ConstraintSet, Error> {
    let set = read_constraints_file(path)?;
    set.check_vertices(n_vertices)?;
    Ok(set)
}

/// Reads a constraints file without checking vertex ranges (so that a
/// caller can first compare the file's `"mesh"` with the mesh at hand; see
/// [`ConstraintSet::mesh_mismatch`], then [`ConstraintSet::check_vertices`]).
pub fn read_constraints_file(path: &Path) -> Result<ConstraintSet, Error> {
    if let Ok(meta) = std::fs::metadata(path).map(|m| m.len()) {
        let estimate = meta.saturating_mul(crate::limits::CONSTRAINT_BYTES_PER_FILE_BYTE);
        crate::limits::check(estimate, || {
            format!(
                "{} ({}) would need",
                path.display(),
                crate::limits::format_bytes(meta)
            )
        })
        .map_err(|detail| ConstraintError::TooLarge { detail })?;
    }
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    Ok(parse_constraints(&text)?)
}

/// Parses the JSON constraint format (vertex ranges are not checked here;
/// see [`ConstraintSet::check_vertices`]).
///
/// A leading UTF-8 byte-order mark (which Windows editors write) is skipped;
/// JSON itself (RFC 8259 §8.1) forbids it but allows parsers to ignore it.
pub fn parse_constraints(text: &str) -> Result<ConstraintSet, ConstraintError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let root: Value = serde_json::from_str(text).map_err(|e| {
        // serde_json's message ends in " at line L column C", which the
        // error's own fields already carry.
        let full = e.to_string();
        let suffix = format!(" at line {} column {}", e.line(), e.column());
        ConstraintError::Json {
            line: e.line(),
            column: e.column(),
            message: full.strip_suffix(&suffix).unwrap_or(&full).to_string(),
        }
    })?;
    let mesh = match root.get("mesh") {
        None | Some(Value::Null) => None,
        Some(v) => Some(
            MeshSignature::deserialize(v).map_err(|e| ConstraintError::Shape {
                message: format!(
                    "'mesh' must be {{\"vertices\": n, \"faces\": m, \"fingerprint\": \"…\"}}: {e}"
                ),
            })?,
        ),
    };
    let list = match &root {
        Value::Object(map) => match map.get("constraints") {
            Some(Value::Array(list)) => list,
            Some(_) => {
                return Err(ConstraintError::Shape {
                    message: "'constraints' must be an array".into(),
                });
            }
            None => {
                return Err(ConstraintError::Shape {
                    message: "the top level must be an object with a 'constraints' array".into(),
                });
            }
        },
        _ => {
            return Err(ConstraintError::Shape {
                message: "the top level must be an object with a 'constraints' array".into(),
            });
        }
    };
    let mut set = ConstraintSet::new();
    set.constraints.reserve(list.len());
    for (index, item) in list.iter().enumerate() {
        set.push(parse_one(index, item)?)?;
    }
    set.mesh = mesh;
    Ok(set)
}

fn parse_one(index: usize, item: &Value) -> Result<Constraint, ConstraintError> {
    let map = item.as_object().ok_or_else(|| ConstraintError::BadField {
        index,
        field: "constraint",
        problem: "must be a JSON object".into(),
    })?;
    let ty = match map.get("type") {
        Some(Value::String(s)) => s.as_str(),
        Some(_) => {
            return Err(ConstraintError::BadField {
                index,
                field: "type",
                problem: "must be a string".into(),
            });
        }
        None => {
            return Err(ConstraintError::BadField {
                index,
                field: "type",
                problem: "is missing".into(),
            });
        }
    };
    let f = Fields { index, map };
    let (kind, allowed): (ConstraintKind, &[&str]) = match ty {
        "position" => (
            ConstraintKind::Position {
                vertex: f.vertex("vertex")?,
                target: f.vec3("target")?,
            },
            &["vertex", "target"],
        ),
        "edge" => (
            ConstraintKind::Edge {
                vertices: f.vertices::<2>()?,
                t: f.number("t")?,
                target: f.vec3("target")?,
            },
            &["vertices", "t", "target"],
        ),
        "face" => (
            ConstraintKind::Face {
                vertices: f.vertices::<3>()?,
                barycentric: f.numbers::<2>("barycentric")?,
                target: f.vec3("target")?,
            },
            &["vertices", "barycentric", "target"],
        ),
        "relative" => (
            ConstraintKind::Relative {
                vertices: f.vertices::<2>()?,
                vector: f.vec3("vector")?,
            },
            &["vertices", "vector"],
        ),
        other => {
            return Err(ConstraintError::UnknownType {
                index,
                found: other.to_string(),
            });
        }
    };
    for key in map.keys() {
        let known = matches!(
            key.as_str(),
            "type" | "weight" | "group" | "name" | "comment"
        ) || allowed.contains(&key.as_str());
        if !known {
            return Err(ConstraintError::UnknownField {
                index,
                field: key.clone(),
                kind: ty.to_string(),
                allowed: format!("type, {}, weight, group, name, comment", allowed.join(", ")),
            });
        }
    }
    let weight = match map.get("weight") {
        None => None,
        Some(v) => Some(json_number(v).ok_or_else(|| ConstraintError::BadField {
            index,
            field: "weight",
            problem: "must be a number".into(),
        })?),
    };
    let group = match map.get("group") {
        None => None,
        Some(Value::String(name)) => Some(name.clone()),
        Some(_) => {
            return Err(ConstraintError::BadField {
                index,
                field: "group",
                problem: "must be a string (the group's name)".into(),
            });
        }
    };
    Ok(Constraint {
        kind,
        weight,
        group,
    })
}

/// Reads a JSON number, accepting the strings "NaN", "inf", "-inf" so that
/// non-finite values written by other programs are reported as non-finite
/// rather than as a type error.
fn json_number(v: &Value) -> Option<f64> {
    match v {
        Value::Number(n) => n.as_f64(),
        Value::String(s) => match s.to_ascii_lowercase().as_str() {
            "nan" => Some(f64::NAN),
            "inf" | "infinity" | "+inf" => Some(f64::INFINITY),
            "-inf" | "-infinity" => Some(f64::NEG_INFINITY),
            _ => None,
        },
        _ => None,
    }
}

struct Fields<'a> {
    index: usize,
    map: &'a Map<String, Value>,
}

impl Fields<'_> {
    fn get(&self, field: &'static str) -> Result<&Value, ConstraintError> {
        self.map
            .get(field)
            .ok_or_else(|| ConstraintError::BadField {
                index: self.index,
                field,
                problem: "is missing".into(),
            })
    }

    fn number(&self, field: &'static str) -> Result<f64, ConstraintError> {
        json_number(self.get(field)?).ok_or_else(|| ConstraintError::BadField {
            index: self.index,
            field,
            problem: "must be a number".into(),
        })
    }

    fn numbers<const K: usize>(&self, field: &'static str) -> Result<[f64; K], ConstraintError> {
        let bad = || ConstraintError::BadField {
            index: self.index,
            field,
            problem: format!("must be an array of {K} numbers"),
        };
        let arr = self.get(field)?.as_array().ok_or_else(bad)?;
        if arr.len() != K {
            return Err(bad());
        }
        let mut out = [0.0; K];
        for (o, v) in out.iter_mut().zip(arr) {
            *o = json_number(v).ok_or_else(bad)?;
        }
        Ok(out)
    }

    fn vec3(&self, field: &'static str) -> Result<[f64; 3], ConstraintError> {
        self.numbers::<3>(field)
    }

    fn vertex_value(&self, field: &'static str, v: &Value) -> Result<usize, ConstraintError> {
        let bad = || ConstraintError::BadField {
            index: self.index,
            field,
            problem: "must hold non-negative integer vertex indices".into(),
        };
        let u = v.as_u64().ok_or_else(bad)?;
        // An index too large for this platform is out of range of any mesh.
        usize::try_from(u).map_err(|_| ConstraintError::VertexOutOfRange {
            index: self.index,
            vertex: u,
            vertex_count: 0,
        })
    }

    fn vertex(&self, field: &'static str) -> Result<usize, ConstraintError> {
        self.vertex_value(field, self.get(field)?)
    }

    fn vertices<const K: usize>(&self) -> Result<[usize; K], ConstraintError> {
        let field = "vertices";
        let arr = self
            .get(field)?
            .as_array()
            .filter(|a| a.len() == K)
            .ok_or_else(|| ConstraintError::BadField {
                index: self.index,
                field,
                problem: format!("must be an array of {K} vertex indices"),
            })?;
        let mut out = [0usize; K];
        for (o, v) in out.iter_mut().zip(arr) {
            *o = self.vertex_value(field, v)?;
        }
        Ok(out)
    }
}

fn constraint_to_json(c: &Constraint) -> Value {
    use serde_json::json;
    let mut v = match &c.kind {
        ConstraintKind::Position { vertex, target } => {
            json!({"type": "position", "vertex": vertex, "target": target})
        }
        ConstraintKind::Edge {
            vertices,
            t,
            target,
        } => json!({"type": "edge", "vertices": vertices, "t": t, "target": target}),
        ConstraintKind::Face {
            vertices,
            barycentric,
            target,
        } => {
            json!({"type": "face", "vertices": vertices, "barycentric": barycentric, "target": target})
        }
        ConstraintKind::Relative { vertices, vector } => {
            json!({"type": "relative", "vertices": vertices, "vector": vector})
        }
    };
    if let (Some(w), Some(map)) = (c.weight, v.as_object_mut()) {
        map.insert("weight".into(), json!(w));
    }
    if let (Some(name), Some(map)) = (&c.group, v.as_object_mut()) {
        map.insert("group".into(), json!(name));
    }
    v
}
