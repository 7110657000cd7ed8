//! Ready-made constraint scenes of the kind the paper evaluates: a fixed
//! region and a dragged handle.

use crate::constraints::{Constraint, ConstraintKind, ConstraintSet};
use crate::error::{Error, ProblemError};
use crate::mesh::Mesh;

/// "Fix the bottom, drag the top": the `fixed_fraction` of vertices lowest
/// along `axis` are held in place (hard), and the `handle_fraction` of
/// vertices closest to the highest vertex along `axis` (excluding fixed ones)
/// are moved rigidly by `offset` (hard, or soft with `handle_weight`).
#[derive(Debug, Clone, PartialEq)]
pub struct FixedAndHandle {
    /// Coordinate axis (0 = x, 1 = y, 2 = z) that orders "bottom" to "top".
    pub axis: usize,
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
        let axis = (0..3)
            .max_by(|&a, &b| ext[a].total_cmp(&ext[b]))
            .unwrap_or(1);
        let mut offset = [0.0; 3];
        offset[(axis + 1) % 3] = 0.15 * mesh.bbox_diagonal();
        FixedAndHandle {
            axis,
            fixed_fraction: 0.2,
            handle_fraction: 0.02,
            offset,
            handle_weight: None,
        }
    }

    /// The vertices of the fixed region and of the handle.
    pub fn regions(&self, mesh: &Mesh) -> Result<(Vec<usize>, Vec<usize>), Error> {
        let bad = |message: String| -> Error { ProblemError::InvalidArgument { message }.into() };
        if self.axis > 2 {
            return Err(bad(format!("axis {} is not 0, 1 or 2", self.axis)));
        }
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
        order.sort_by(|&a, &b| p[a][self.axis].total_cmp(&p[b][self.axis]).then(a.cmp(&b)));
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

    /// The constraints: fixed vertices first (highest priority), then the
    /// handle.
    pub fn constraints(&self, mesh: &Mesh) -> Result<ConstraintSet, Error> {
        let (fixed, handle) = self.regions(mesh)?;
        let p = mesh.positions();
        let mut list = Vec::with_capacity(fixed.len() + handle.len());
        for v in fixed {
            list.push(Constraint::hard(ConstraintKind::Position {
                vertex: v,
                target: p[v],
            }));
        }
        for v in handle {
            let target = [0, 1, 2].map(|k| p[v][k] + self.offset[k]);
            let kind = ConstraintKind::Position { vertex: v, target };
            list.push(Constraint {
                kind,
                weight: self.handle_weight,
            });
        }
        Ok(ConstraintSet::from_vec(list)?)
    }
}
