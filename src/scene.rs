//! Ready-made constraint scenes of the kind the paper evaluates: a fixed
//! region and a dragged handle.

use crate::constraints::{Constraint, ConstraintKind, ConstraintSet};
use crate::error::{Error, ProblemError};
use crate::mesh::{Mesh, MeshSignature};

/// The group of a scene's fixed region.
pub const FIXED_GROUP: &str = "fixed";
/// The group of a scene's handle.
pub const HANDLE_GROUP: &str = "handle";

/// A coordinate axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    /// The first coordinate.
    X,
    /// The second coordinate.
    Y,
    /// The third coordinate.
    Z,
}

impl Axis {
    /// The three axes, in coordinate order.
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

    /// The coordinate index: 0, 1 or 2.
    pub fn index(self) -> usize {
        self as usize
    }

    /// The axis's name: `x`, `y` or `z`.
    pub fn name(self) -> &'static str {
        ["x", "y", "z"][self.index()]
    }
}

/// An axis with a direction, as written `x`, `+y` or `-z` (the minus:
/// descending, see [`FixedAndHandle::descending`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AxisDirection {
    /// The axis.
    pub axis: Axis,
    /// `true` for `-x`, `-y` or `-z`.
    pub descending: bool,
}

/// A string that names no [`AxisDirection`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParseAxisError {
    /// The string, as given.
    pub value: String,
}

impl std::fmt::Display for ParseAxisError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "'{}' is not an axis: expected x, y, z, -x, -y or -z",
            self.value
        )
    }
}

impl std::error::Error for ParseAxisError {}

impl std::str::FromStr for AxisDirection {
    type Err = ParseAxisError;

    /// `x`, `y`, `z`, optionally after `+` or `-` (lower case only).
    fn from_str(s: &str) -> Result<AxisDirection, ParseAxisError> {
        let (descending, name) = match s.strip_prefix('-') {
            Some(rest) => (true, rest),
            None => (false, s.strip_prefix('+').unwrap_or(s)),
        };
        let axis = match name {
            "x" => Axis::X,
            "y" => Axis::Y,
            "z" => Axis::Z,
            _ => {
                return Err(ParseAxisError {
                    value: s.to_string(),
                });
            }
        };
        Ok(AxisDirection { axis, descending })
    }
}

/// "Fix the bottom, drag the top": the `fixed_fraction` of vertices lowest
/// along `axis` are held in place (hard), and the `handle_fraction` of
/// vertices closest to the highest vertex along `axis` (excluding fixed ones)
/// are moved rigidly by `offset` (hard, or soft with `handle_weight`).
#[derive(Debug, Clone, PartialEq)]
pub struct FixedAndHandle {
    /// Coordinate axis that orders "bottom" to "top".
    pub axis: Axis,
    /// `true`: "bottom" is the high end of `axis` (the fixed region at the
    /// largest coordinates, the handle at the smallest): a mesh modelled
    /// upside down, or the other end of a long one.
    pub descending: bool,
    /// Fraction of vertices fixed, in `[0, 1]`.
    pub fixed_fraction: f64,
    /// Fraction of vertices in the handle, in `[0, 1]`.
    pub handle_fraction: f64,
    /// Displacement of the handle.
    pub offset: [f64; 3],
    /// `None` for a hard handle, `Some(w)` for a soft one.
    pub handle_weight: Option<f64>,
}

impl FixedAndHandle {
    /// The default scene of the paper's experiments: 20 % fixed, 2 % handle
    /// on the longest axis, moved by 15 % of the bounding-box diagonal
    /// perpendicular to it.
    pub fn paper_default(mesh: &Mesh) -> FixedAndHandle {
        let (lo, hi) = mesh.bounding_box();
        let ext = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
        let axis = Axis::ALL
            .into_iter()
            .max_by(|&a, &b| ext[a.index()].total_cmp(&ext[b.index()]))
            .unwrap_or(Axis::Y);
        FixedAndHandle {
            axis,
            descending: false,
            fixed_fraction: 0.2,
            handle_fraction: 0.02,
            offset: FixedAndHandle::default_offset(mesh, axis),
            handle_weight: None,
        }
    }

    /// The default handle offset for `axis`: 15 % of the bounding-box
    /// diagonal along the next axis (x → y → z → x), perpendicular to it.
    pub fn default_offset(mesh: &Mesh, axis: Axis) -> [f64; 3] {
        let mut offset = [0.0; 3];
        offset[(axis.index() + 1) % 3] = 0.15 * mesh.bbox_diagonal();
        offset
    }

    /// How high `p` is, bottom to top: its coordinate along the axis,
    /// negated when [`FixedAndHandle::descending`].
    pub(crate) fn height(&self, p: [f64; 3]) -> f64 {
        if self.descending {
            -p[self.axis.index()]
        } else {
            p[self.axis.index()]
        }
    }

    /// The vertices of the fixed region and of the handle.
    pub fn regions(&self, mesh: &Mesh) -> Result<(Vec<usize>, Vec<usize>), Error> {
        let bad = |message: String| -> Error { ProblemError::InvalidArgument { message }.into() };
        for (name, f) in [
            ("fixed", self.fixed_fraction),
            ("handle", self.handle_fraction),
        ] {
            if !(0.0..=1.0).contains(&f) {
                return Err(bad(format!("{name} fraction {f} is not in [0, 1]")));
            }
        }
        let p = mesh.positions();
        let n = mesh.n_vertices();
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| {
            self.height(p[a])
                .total_cmp(&self.height(p[b]))
                .then(a.cmp(&b))
        });
        let n_fixed = ((self.fixed_fraction * n as f64).round() as usize).min(n);
        let mut fixed: Vec<usize> = order[..n_fixed].to_vec();
        fixed.sort_unstable();
        let mut is_fixed = vec![false; n];
        for &v in &fixed {
            is_fixed[v] = true;
        }
        let top = p[order[n - 1]];
        let d2 = |v: usize| (0..3).map(|k| (p[v][k] - top[k]).powi(2)).sum::<f64>();
        let mut near: Vec<usize> = (0..n).filter(|&v| !is_fixed[v]).collect();
        near.sort_by(|&a, &b| d2(a).total_cmp(&d2(b)).then(a.cmp(&b)));
        let n_handle = ((self.handle_fraction * n as f64).round() as usize).min(near.len());
        let mut handle = near[..n_handle].to_vec();
        handle.sort_unstable();
        Ok((fixed, handle))
    }

    /// The constraints: fixed vertices first (highest priority, group
    /// [`FIXED_GROUP`]), then the handle (group [`HANDLE_GROUP`]), so that a
    /// scene file can be dragged as it is (`Deformer::transform_group`, the
    /// editor's `POST /api/transform`, Python's `transform_group`) and
    /// `render` colours its regions.
    pub fn constraints(&self, mesh: &Mesh) -> Result<ConstraintSet, Error> {
        let (fixed, handle) = self.regions(mesh)?;
        let p = mesh.positions();
        let mut list = Vec::with_capacity(fixed.len() + handle.len());
        for v in fixed {
            list.push(
                Constraint::hard(ConstraintKind::Position {
                    vertex: v,
                    target: p[v],
                })
                .in_group(FIXED_GROUP),
            );
        }
        for v in handle {
            let target = [0, 1, 2].map(|k| p[v][k] + self.offset[k]);
            let kind = ConstraintKind::Position { vertex: v, target };
            list.push(Constraint {
                kind,
                weight: self.handle_weight,
                group: Some(HANDLE_GROUP.into()),
            });
        }
        let mut set = ConstraintSet::from_vec(list)?;
        set.set_mesh(Some(MeshSignature::of(mesh)));
        Ok(set)
    }
}

/// A scene that mixes all four constraint kinds on top of a
/// [`FixedAndHandle`] scene, for checking rank detection and comparing
/// formulations on more than positions:
///
/// - `relative`: a patch of `relative + 1` free vertices around the middle of
///   the axis, its breadth-first spanning tree's edges constrained to keep
///   their original difference vectors (independent: a tree);
/// - `edges`: mesh edges near 70 % of the axis, both ends free and unused,
///   whose midpoint (`t = ½`) is moved by half the handle offset;
/// - `faces`: faces near 70 % of the axis, all corners free and unused,
///   whose centroid is moved by half the handle offset;
/// - optionally a duplicate of the first fixed constraint (redundant) and a
///   contradiction of the second (the same vertex sent 10 % of the diagonal
///   away: conflicting), appended last so that the originals win.
#[derive(Debug, Clone, PartialEq)]
pub struct MixedScene {
    /// The fixed region and handle.
    pub base: FixedAndHandle,
    /// Number of relative constraints.
    pub relative: usize,
    /// Number of on-edge constraints.
    pub edges: usize,
    /// Number of on-face constraints.
    pub faces: usize,
    /// Append a duplicate of the first fixed constraint.
    pub duplicate: bool,
    /// Append a constraint contradicting the second fixed constraint.
    pub conflict: bool,
}

impl MixedScene {
    /// The constraints, in priority order: fixed, handle, relative
    /// ([`relative_tree`]), edge ([`edge_midpoints`]), face
    /// ([`face_centroids`]), then the duplicate and the conflict
    /// ([`MixedScene::redundant_tail`]).
    pub fn constraints(&self, mesh: &Mesh) -> Result<ConstraintSet, Error> {
        let base = self.base.constraints(mesh)?;
        let (fixed, handle) = self.base.regions(mesh)?;
        let n = mesh.n_vertices();
        let mut used = vec![false; n];
        for &v in fixed.iter().chain(&handle) {
            used[v] = true;
        }
        let p = mesh.positions();
        let mut order: Vec<usize> = (0..n).collect();
        let base_scene = &self.base;
        order.sort_by(|&a, &b| {
            base_scene
                .height(p[a])
                .total_cmp(&base_scene.height(p[b]))
                .then(a.cmp(&b))
        });
        let mut list: Vec<Constraint> = base.as_slice().to_vec();
        if self.relative > 0 {
            list.extend(relative_tree(mesh, &order, self.relative, &mut used));
        }
        // Edges and faces near 70 % of the axis, on unused vertices.
        let half = [0, 1, 2].map(|k| 0.5 * self.base.offset[k]);
        let near = from_fraction(&order, 0.7);
        list.extend(edge_midpoints(mesh, &near, self.edges, half, &mut used));
        if self.faces > 0 {
            list.extend(face_centroids(mesh, &near, self.faces, half, &mut used));
        }
        list.extend(self.redundant_tail(mesh, base.as_slice()));
        let mut set = ConstraintSet::from_vec(list)?;
        set.set_mesh(Some(MeshSignature::of(mesh)));
        Ok(set)
    }

    /// The optional last constraints: a duplicate of the first base
    /// constraint, and the second one with its right-hand side moved by 10 %
    /// of the bounding-box diagonal along x (a conflict).
    fn redundant_tail(&self, mesh: &Mesh, base: &[Constraint]) -> Vec<Constraint> {
        let mut tail = Vec::new();
        if self.duplicate
            && let Some(first) = base.first()
        {
            tail.push(first.clone());
        }
        if self.conflict
            && let Some(second) = base.get(1)
        {
            let mut c = second.clone();
            let r = c.kind.rhs();
            let d = 0.1 * mesh.bbox_diagonal();
            c.kind.set_rhs([r[0] + d, r[1], r[2]]);
            tail.push(c);
        }
        tail
    }
}

/// `order` (vertices bottom to top) rotated to start at the fraction
/// `frac` of it, then going back down from there: every vertex once,
/// nearest that height first (upward before downward).
fn from_fraction(order: &[usize], frac: f64) -> Vec<usize> {
    let n = order.len();
    let start = ((frac * n as f64) as usize).min(n - 1);
    order[start..]
        .iter()
        .chain(order[..start].iter().rev())
        .copied()
        .collect()
}

/// Up to `count` hard relative constraints on the breadth-first spanning
/// tree over unused vertices, from the first unused vertex of
/// [`from_fraction`]`(order, ½)`: each tree edge `u − v` keeps its rest
/// difference `p_u − p_v` (a tree: independent). Marks its vertices used.
fn relative_tree(mesh: &Mesh, order: &[usize], count: usize, used: &mut [bool]) -> Vec<Constraint> {
    let mut list = Vec::new();
    let Some(seed) = from_fraction(order, 0.5).into_iter().find(|&v| !used[v]) else {
        return list;
    };
    let p = mesh.positions();
    let (offsets, neighbours) = crate::mesh::topology::vertex_neighbors(mesh);
    let mut queue = std::collections::VecDeque::from([seed]);
    used[seed] = true;
    while let Some(v) = queue.pop_front() {
        for &u in &neighbours[offsets[v]..offsets[v + 1]] {
            if list.len() == count {
                break;
            }
            if !used[u] {
                used[u] = true;
                queue.push_back(u);
                let vector = [0, 1, 2].map(|k| p[u][k] - p[v][k]);
                list.push(Constraint::hard(ConstraintKind::Relative {
                    vertices: [u, v],
                    vector,
                }));
            }
        }
        if list.len() == count {
            break;
        }
    }
    list
}

/// Up to `count` hard on-edge constraints: for each unused vertex `v` of
/// `near` in turn, its first unused neighbour `u`; the edge midpoint
/// (`t = ½`) moved by `half`. Marks both ends used.
fn edge_midpoints(
    mesh: &Mesh,
    near: &[usize],
    count: usize,
    half: [f64; 3],
    used: &mut [bool],
) -> Vec<Constraint> {
    if count == 0 {
        return Vec::new();
    }
    let p = mesh.positions();
    let (offsets, neighbours) = crate::mesh::topology::vertex_neighbors(mesh);
    let mut list = Vec::new();
    for &v in near {
        if list.len() == count {
            break;
        }
        if used[v] {
            continue;
        }
        if let Some(&u) = neighbours[offsets[v]..offsets[v + 1]]
            .iter()
            .find(|&&u| !used[u])
        {
            used[v] = true;
            used[u] = true;
            let target = [0, 1, 2].map(|k| 0.5 * (p[v][k] + p[u][k]) + half[k]);
            list.push(Constraint::hard(ConstraintKind::Edge {
                vertices: [v, u],
                t: 0.5,
                target,
            }));
        }
    }
    list
}

/// Up to `count` hard on-face constraints: faces with no used corner, by
/// their earliest corner in `near` (stable), each centroid moved by
/// `half`. Marks their corners used.
fn face_centroids(
    mesh: &Mesh,
    near: &[usize],
    count: usize,
    half: [f64; 3],
    used: &mut [bool],
) -> Vec<Constraint> {
    let p = mesh.positions();
    let mut rank = vec![usize::MAX; mesh.n_vertices()];
    for (r, &v) in near.iter().enumerate() {
        rank[v] = r;
    }
    let mut faces: Vec<&[usize; 3]> = mesh.faces().iter().collect();
    faces.sort_by_key(|f| f.iter().map(|&v| rank[v]).min().unwrap_or(usize::MAX));
    let mut list = Vec::new();
    for f in faces {
        if list.len() == count {
            break;
        }
        if f.iter().any(|&v| used[v]) {
            continue;
        }
        for &v in f {
            used[v] = true;
        }
        let third = 1.0 / 3.0;
        let target = [0, 1, 2].map(|k| third * (p[f[0]][k] + p[f[1]][k] + p[f[2]][k]) + half[k]);
        list.push(Constraint::hard(ConstraintKind::Face {
            vertices: *f,
            barycentric: [third, third],
            target,
        }));
    }
    list
}

/// Many constraints through one vertex, appended to a [`FixedAndHandle`]
/// scene: the legal but unkind inputs whose cost must stay proportional to
/// their size.
///
/// The *hub* is the free vertex (neither fixed nor in the handle) nearest to
/// the middle of the axis; `count` constraints follow the base scene:
/// - `partners == 0`: `p_hub = p_hub⁰` (its rest position), `count` times —
///   one position constraint repeated;
/// - `partners = P > 0`: `p_hub − p_v = p_hub⁰ − p_v⁰` for `v` cycling over
///   the `P` free vertices nearest the hub, `count` relative constraints
///   all sharing the hub.
///
/// Every `conflict_every`-th copy after the first round (`k ≥ max(P, 1)`,
/// `k % conflict_every == 0`; `0` for none) has its target or vector moved by
/// 1 % of the bounding-box diagonal along x. So in exact terms: the first
/// round is independent of the base and of each other (rank `+ max(P, 1)`),
/// the later unmoved copies are redundant and the moved ones conflicting —
/// see [`CrowdedScene::expected`].
#[derive(Debug, Clone, PartialEq)]
pub struct CrowdedScene {
    /// The fixed region and handle.
    pub base: FixedAndHandle,
    /// `0`: a repeated position constraint; `P > 0`: relative constraints
    /// from the hub to `P` vertices in turn.
    pub partners: usize,
    /// Number of crowded constraints.
    pub count: usize,
    /// Every this many-th later copy conflicts (`0`: none).
    pub conflict_every: usize,
}

impl CrowdedScene {
    fn copy_conflicts(&self, k: usize) -> bool {
        self.conflict_every > 0
            && k >= self.partners.max(1)
            && k.is_multiple_of(self.conflict_every)
    }

    /// The constraints: the base scene's, then the crowded ones.
    pub fn constraints(&self, mesh: &Mesh) -> Result<ConstraintSet, Error> {
        let base = self.base.constraints(mesh)?;
        let (fixed, handle) = self.base.regions(mesh)?;
        let p = mesh.positions();
        let n = mesh.n_vertices();
        let mut used = vec![false; n];
        for &v in fixed.iter().chain(&handle) {
            used[v] = true;
        }
        let (lo, hi) = mesh.bounding_box();
        let axis = self.base.axis.index();
        let mid = 0.5 * (lo[axis] + hi[axis]);
        let mut free: Vec<usize> = (0..n).filter(|&v| !used[v]).collect();
        free.sort_by(|&a, &b| {
            (p[a][axis] - mid)
                .abs()
                .total_cmp(&(p[b][axis] - mid).abs())
                .then(a.cmp(&b))
        });
        let bad = |message: String| -> Error { ProblemError::InvalidArgument { message }.into() };
        let Some((&hub, rest)) = free.split_first() else {
            return Err(bad("no free vertex for the hub".into()));
        };
        let d2 = |v: usize| (0..3).map(|k| (p[v][k] - p[hub][k]).powi(2)).sum::<f64>();
        let mut partners = rest.to_vec();
        partners.sort_by(|&a, &b| d2(a).total_cmp(&d2(b)).then(a.cmp(&b)));
        if partners.len() < self.partners {
            return Err(bad(format!(
                "{} partners asked for, {} free vertices",
                self.partners,
                partners.len()
            )));
        }
        partners.truncate(self.partners);
        let shift = 0.01 * mesh.bbox_diagonal();
        let mut list = base.as_slice().to_vec();
        list.reserve(self.count);
        for k in 0..self.count {
            let mut kind = if self.partners == 0 {
                ConstraintKind::Position {
                    vertex: hub,
                    target: p[hub],
                }
            } else {
                let v = partners[k % self.partners];
                ConstraintKind::Relative {
                    vertices: [hub, v],
                    vector: [0, 1, 2].map(|c| p[hub][c] - p[v][c]),
                }
            };
            if self.copy_conflicts(k) {
                let r = kind.rhs();
                kind.set_rhs([r[0] + shift, r[1], r[2]]);
            }
            list.push(Constraint::hard(kind));
        }
        let mut set = ConstraintSet::from_vec(list)?;
        set.set_mesh(Some(MeshSignature::of(mesh)));
        Ok(set)
    }

    /// `(rank added, redundant, conflicting)` of the crowded constraints,
    /// as indices into [`CrowdedScene::constraints`] (which start at
    /// `base_len`, the base scene's constraint count).
    pub fn expected(&self, base_len: usize) -> (usize, Vec<usize>, Vec<usize>) {
        let first_round = self.partners.max(1).min(self.count);
        let later = first_round..self.count;
        let redundant = later
            .clone()
            .filter(|&k| !self.copy_conflicts(k))
            .map(|k| base_len + k)
            .collect();
        let conflicting = later
            .filter(|&k| self.copy_conflicts(k))
            .map(|k| base_len + k)
            .collect();
        (first_round, redundant, conflicting)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit square `0 (0,0) – 1 (1,0) – 2 (1,1) – 3 (0,1)`, two triangles.
    fn square() -> Mesh {
        Mesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .unwrap()
    }

    #[test]
    fn axis_directions_parse_and_a_bad_one_is_named() {
        let parse = |s: &str| s.parse::<AxisDirection>();
        let dir = |axis, descending| Ok(AxisDirection { axis, descending });
        assert_eq!(parse("x"), dir(Axis::X, false));
        assert_eq!(parse("+y"), dir(Axis::Y, false));
        assert_eq!(parse("-z"), dir(Axis::Z, true));
        for bad in ["w", "X", "", "--x", "xy"] {
            assert_eq!(
                parse(bad),
                Err(ParseAxisError {
                    value: bad.to_string()
                })
            );
        }
        assert_eq!(
            parse("up").unwrap_err().to_string(),
            "'up' is not an axis: expected x, y, z, -x, -y or -z"
        );
        assert_eq!(Axis::ALL.map(Axis::index), [0, 1, 2]);
        assert_eq!(Axis::ALL.map(Axis::name), ["x", "y", "z"]);
    }

    #[test]
    fn from_fraction_goes_up_then_back_down() {
        assert_eq!(from_fraction(&[5, 6, 7, 8, 9], 0.5), [7, 8, 9, 6, 5]);
        assert_eq!(from_fraction(&[5, 6, 7, 8, 9], 0.7), [8, 9, 7, 6, 5]);
        assert_eq!(from_fraction(&[5, 6, 7, 8, 9], 1.0), [9, 8, 7, 6, 5]);
    }

    #[test]
    fn relative_tree_starts_at_the_middle_and_keeps_rest_differences() {
        let mut used = [true, false, false, false];
        let list = relative_tree(&square(), &[0, 1, 2, 3], 1, &mut used);
        // Seed 2 (the middle of the order); its unused neighbours 1, 3.
        assert_eq!(
            list,
            [Constraint::hard(ConstraintKind::Relative {
                vertices: [1, 2],
                vector: [0.0, -1.0, 0.0],
            })]
        );
        assert_eq!(used, [true, true, true, false]);
    }

    #[test]
    fn edge_midpoints_take_the_first_unused_neighbour() {
        let mut used = [false, false, true, false];
        let list = edge_midpoints(&square(), &[2, 3, 1, 0], 2, [0.0, 0.0, 1.0], &mut used);
        // 2 is used; 3 pairs with 0; 1's neighbours 0 and 2 are used.
        assert_eq!(
            list,
            [Constraint::hard(ConstraintKind::Edge {
                vertices: [3, 0],
                t: 0.5,
                target: [0.0, 0.5, 1.0],
            })]
        );
        assert_eq!(used, [true, false, true, true]);
    }

    #[test]
    fn face_centroids_take_free_faces_nearest_first() {
        let mut used = [false; 4];
        let list = face_centroids(&square(), &[2, 3, 1, 0], 2, [0.0, 0.0, 1.0], &mut used);
        // Both faces touch vertex 2 (rank 0): the first wins, the second
        // then shares its corners.
        assert_eq!(
            list,
            [Constraint::hard(ConstraintKind::Face {
                vertices: [0, 1, 2],
                barycentric: [1.0 / 3.0, 1.0 / 3.0],
                target: [2.0 / 3.0, 1.0 / 3.0, 1.0],
            })]
        );
        assert_eq!(used, [true, true, true, false]);
    }
}
