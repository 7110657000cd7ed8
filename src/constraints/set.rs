//! The constraints themselves: [`ConstraintKind`] (the four kinds of
//! row), [`Constraint`] (a kind, an optional soft weight and group) and
//! [`ConstraintSet`] (the checked list, with its mesh signature): the leaf
//! of `constraints` that the parser and the readers build.

use std::collections::HashMap;

use serde_json::Value;

use crate::error::ConstraintError;
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

    /// Euclidean norm of the coefficient vector, without overflow (an
    /// edge with `t = 1e308` has coefficients near ±1e308, whose squares
    /// are not doubles).
    pub fn norm(&self) -> f64 {
        self.entries().iter().fold(0.0, |n, e| n.hypot(e.1))
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
    pub(crate) fn pins_translation(&self) -> bool {
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
    pub(super) mesh: Option<MeshSignature>,
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
    pub(crate) fn set_mesh(&mut self, mesh: Option<MeshSignature>) {
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
