//! One triangle's corner quantities (dot products, squared edge lengths,
//! area), from positions or from squared edge lengths alone: what the
//! cotangent weights and the mixed areas of [`super`] and the intrinsic
//! triangulation of `intrinsic_delaunay` are computed from.

/// The corners of one triangle: for corner `k` the dot product of its two
/// edge vectors, the squared length of the opposite edge (`len_sq[k]` is the
/// edge between corners `k+1` and `k+2`) and twice the area.
#[derive(Debug, Clone, Copy)]
pub(super) struct Triangle {
    pub(super) dot: [f64; 3],
    pub(super) len_sq: [f64; 3],
    pub(super) double_area: f64,
    pub(super) area: f64,
}

impl Triangle {
    pub(super) fn new(x: [[f64; 3]; 3]) -> Triangle {
        let e = |a: usize, b: usize| [x[b][0] - x[a][0], x[b][1] - x[a][1], x[b][2] - x[a][2]];
        let dot3 = |u: [f64; 3], v: [f64; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
        let mut dot = [0.0; 3];
        let mut len_sq = [0.0; 3];
        for k in 0..3 {
            let (a, b) = ((k + 1) % 3, (k + 2) % 3);
            dot[k] = dot3(e(k, a), e(k, b));
            let opp = e(a, b);
            len_sq[k] = dot3(opp, opp);
        }
        let (u, v) = (e(0, 1), e(0, 2));
        let c = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        let double_area = dot3(c, c).sqrt();
        Triangle {
            dot,
            len_sq,
            double_area,
            area: double_area / 2.0,
        }
    }

    /// The same quantities from the squared edge lengths alone (`len_sq[k]`
    /// opposite corner `k`), as an intrinsic triangulation knows them:
    /// `u·v = (|u|² + |v|² − |u − v|²)/2` and Heron's formula in Kahan's
    /// cancellation-free ordering for the area.
    pub(super) fn from_len_sq(len_sq: [f64; 3]) -> Triangle {
        let mut dot = [0.0; 3];
        for k in 0..3 {
            dot[k] = 0.5 * (len_sq[(k + 1) % 3] + len_sq[(k + 2) % 3] - len_sq[k]);
        }
        let mut l = len_sq.map(f64::sqrt);
        l.sort_by(|x, y| y.total_cmp(x));
        let [a, b, c] = l;
        let q = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c));
        let area = 0.25 * q.max(0.0).sqrt();
        Triangle {
            dot,
            len_sq,
            double_area: 2.0 * area,
            area,
        }
    }

    /// Cotangent of the angle at corner `k`: `(u·v)/|u×v|`.
    pub(super) fn cot(&self, k: usize) -> f64 {
        self.dot[k] / self.double_area
    }
}
