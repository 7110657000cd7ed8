//! Triangle quality: angles and aspect ratios.
//!
//! The definitions match the statistics table of the test-mesh README
//! (`../shared/meshes/README.md`):
//!
//! - angles are the interior angles of each triangle, in degrees, computed
//!   as `atan2(|u × v|, u · v)` for the two edge vectors `u`, `v` leaving the
//!   corner (accurate also for angles near 0° and 180°, unlike `acos`);
//! - the aspect ratio of a triangle is `(ℓ_max / h_min) · √3/2`, with `ℓ_max`
//!   its longest edge and `h_min = 2·area / ℓ_max` its shortest altitude; it
//!   is 1 for an equilateral triangle and grows without bound for slivers
//!   (`√3` for a right isosceles triangle);
//! - the edge-length ratio is the longest edge length divided by the
//!   shortest, over the whole mesh: a measure of non-uniformity.

use super::Mesh;

/// Triangle quality summary of a mesh. Every field is finite for a
/// [`Mesh`] without faces of zero area (see [`Mesh::degenerate_face`]);
/// such a face has an infinite (or, with coincident corners, NaN) aspect
/// ratio.
#[derive(Debug, Clone, PartialEq)]
pub struct Quality {
    /// Smallest interior angle over all triangles, in degrees (`0 <` this
    /// `≤ 60`).
    pub min_angle_deg: f64,
    /// A face where the smallest angle occurs (the first one).
    pub min_angle_face: usize,
    /// Largest interior angle over all triangles, in degrees (`60 ≤` this
    /// `< 180`).
    pub max_angle_deg: f64,
    /// A face where the largest angle occurs (the first one).
    pub max_angle_face: usize,
    /// Largest aspect ratio `(ℓ_max / h_min)·√3/2` (see the module
    /// documentation); `≥ 1`.
    pub max_aspect_ratio: f64,
    /// A face where the largest aspect ratio occurs (the first one).
    pub max_aspect_ratio_face: usize,
    /// Percentage (0–100) of triangles whose smallest angle is below 10°.
    pub percent_below_10_deg: f64,
    /// Number of triangles whose smallest angle is below 1°.
    pub count_below_1_deg: usize,
    /// Longest edge length divided by shortest edge length over the mesh.
    pub edge_length_ratio: f64,
    /// Length of the longest edge.
    pub longest_edge: f64,
    /// Length of the shortest edge.
    pub shortest_edge: f64,
}

/// Angles (degrees) and aspect ratio of one triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleQuality {
    /// Interior angles in degrees at the three corners, in face order.
    pub angles_deg: [f64; 3],
    /// `(ℓ_max / h_min)·√3/2`.
    pub aspect_ratio: f64,
    /// Shortest edge length.
    pub shortest_edge: f64,
    /// Longest edge length.
    pub longest_edge: f64,
}

/// Angles, aspect ratio and edge lengths of the triangle `abc`. For a
/// degenerate triangle the aspect ratio is infinite (or NaN for coincident
/// points).
pub fn triangle_quality(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> TriangleQuality {
    let corners = [a, b, c];
    let mut angles_deg = [0.0; 3];
    let mut len_sq = [0.0; 3];
    for k in 0..3 {
        let p = corners[k];
        let u = sub(corners[(k + 1) % 3], p);
        let v = sub(corners[(k + 2) % 3], p);
        angles_deg[k] = norm_sq(cross(u, v)).sqrt().atan2(dot(u, v)).to_degrees();
        // Edge opposite corner k+2, i.e. edge (k, k+1).
        len_sq[k] = norm_sq(u);
    }
    let (mut imax, mut imin) = (0, 0);
    for k in 1..3 {
        if len_sq[k] > len_sq[imax] {
            imax = k;
        }
        if len_sq[k] < len_sq[imin] {
            imin = k;
        }
    }
    // Twice the area from the two edges adjacent to the longest one (they
    // meet at the corner opposite it): the most accurate cross product.
    let opposite = (imax + 2) % 3;
    let p = corners[opposite];
    let twice_area = norm_sq(cross(
        sub(corners[(opposite + 1) % 3], p),
        sub(corners[(opposite + 2) % 3], p),
    ))
    .sqrt();
    let aspect_ratio = len_sq[imax] / twice_area * (3f64.sqrt() / 2.0);
    TriangleQuality {
        angles_deg,
        aspect_ratio,
        shortest_edge: len_sq[imin].sqrt(),
        longest_edge: len_sq[imax].sqrt(),
    }
}

impl Quality {
    /// Computes the summary in one pass over the faces (`O(F)`).
    pub fn of(mesh: &Mesh) -> Quality {
        let p = mesh.positions();
        let mut q = Quality {
            min_angle_deg: f64::INFINITY,
            min_angle_face: 0,
            max_angle_deg: f64::NEG_INFINITY,
            max_angle_face: 0,
            max_aspect_ratio: f64::NEG_INFINITY,
            max_aspect_ratio_face: 0,
            percent_below_10_deg: 0.0,
            count_below_1_deg: 0,
            edge_length_ratio: 0.0,
            longest_edge: f64::NEG_INFINITY,
            shortest_edge: f64::INFINITY,
        };
        let mut below_10 = 0usize;
        for (f, &[i, j, k]) in mesh.faces().iter().enumerate() {
            let t = triangle_quality(p[i], p[j], p[k]);
            let lo = t.angles_deg.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = t
                .angles_deg
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max);
            if lo < q.min_angle_deg {
                q.min_angle_deg = lo;
                q.min_angle_face = f;
            }
            if hi > q.max_angle_deg {
                q.max_angle_deg = hi;
                q.max_angle_face = f;
            }
            if t.aspect_ratio > q.max_aspect_ratio {
                q.max_aspect_ratio = t.aspect_ratio;
                q.max_aspect_ratio_face = f;
            }
            if lo < 10.0 {
                below_10 += 1;
            }
            if lo < 1.0 {
                q.count_below_1_deg += 1;
            }
            q.longest_edge = q.longest_edge.max(t.longest_edge);
            q.shortest_edge = q.shortest_edge.min(t.shortest_edge);
        }
        // A valid mesh has at least one face.
        q.percent_below_10_deg = 100.0 * below_10 as f64 / mesh.n_faces().max(1) as f64;
        q.edge_length_ratio = q.longest_edge / q.shortest_edge;
        q
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn norm_sq(a: [f64; 3]) -> f64 {
    a[0] * a[0] + a[1] * a[1] + a[2] * a[2]
}

/// The largest absolute component of `vectors`.
fn max_abs(vectors: &[[f64; 3]]) -> f64 {
    vectors.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()))
}

/// The edge vectors `b − a`, `c − a`, `c − b` of the triangle `abc`, and
/// the factor `h` they are to be multiplied by: 1, or 2 when a difference
/// overflows (corners more than `f64::MAX` apart in a coordinate) and the
/// vectors are those of the halved corners, `b/2 − a/2`, … (halving is
/// exact for normal numbers: only the overflow is avoided).
fn edge_vectors(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> ([[f64; 3]; 3], f64) {
    let plain = [sub(b, a), sub(c, a), sub(c, b)];
    if plain.iter().flatten().all(|v| v.is_finite()) {
        return (plain, 1.0);
    }
    let half = |p: [f64; 3]| p.map(|x| 0.5 * x);
    let (a, b, c) = (half(a), half(b), half(c));
    ([sub(b, a), sub(c, a), sub(c, b)], 2.0)
}

/// `2^round(log2 x)` for a finite `x > 0` (at most `2^1023`, the largest
/// power of two a double holds), else 1: the exact unit that normalises a
/// length of size `x` to `[0.7, 1.4]` (to `[0.7, 2]` above `2^1023`).
pub(crate) fn power_of_two_unit(x: f64) -> f64 {
    if x > 0.0 && x.is_finite() {
        2f64.powi((x.log2().round() as i32).min(f64::MAX_EXP - 1))
    } else {
        1.0
    }
}

/// `‖v‖₂` without overflow or underflow of the squares.
fn norm(v: [f64; 3]) -> f64 {
    let m = max_abs(&[v]);
    if m == 0.0 {
        return 0.0;
    }
    m * norm_sq(v.map(|x| x / m)).sqrt()
}

/// A triangle's area against its size ([`triangle_size`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleSize {
    /// `2·area > 64 ε ℓ²` (ℓ the longest edge; the rounding error of the
    /// cross product is a few `ε ℓ²`): the area is clearly not zero.
    pub clearly_positive: bool,
    /// The area (infinite when beyond the largest double).
    pub area: f64,
    /// The longest edge ℓ (infinite when beyond the largest double).
    pub longest_edge: f64,
    /// `2·area / ℓ²`, which does not depend on the unit (0 for collinear
    /// corners; `≤ √3/2`, the equilateral triangle's).
    pub relative_area: f64,
}

/// Whether the triangle `abc` has clearly non-zero area,
/// `2·area > 64 ε ℓ²` ([`TriangleSize`]), with its area and longest edge.
///
/// Scale-invariant and free of overflow and underflow for any finite
/// corners: each edge vector is divided by an exact power of two that
/// brings it to unit size ([`power_of_two_unit`]) before the cross
/// product, so `2·area / ℓ² = |ê₁ × ê₂| (u₁/u)(u₂/u) / ℓ̂²` (`u` the unit of
/// the longest coordinate difference) is computed alike for a mesh in any
/// unit, and a sliver of edges 1 and 1e308 has its area (5e307), not the
/// 0 of a cross product of unit-scaled edges that underflows.
pub(crate) fn triangle_size(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> TriangleSize {
    let ([e1, e2, e3], h) = edge_vectors(a, b, c);
    let u = power_of_two_unit(max_abs(&[e1, e2, e3]));
    let l2 = [e1, e2, e3]
        .map(|e| norm_sq(e.map(|x| x / u)))
        .into_iter()
        .fold(0.0, f64::max);
    let (u1, u2) = (
        power_of_two_unit(max_abs(&[e1])),
        power_of_two_unit(max_abs(&[e2])),
    );
    let twice = norm(cross(e1.map(|x| x / u1), e2.map(|x| x / u2)));
    let relative_area = if l2 > 0.0 {
        twice * (u1 / u) * (u2 / u) / l2
    } else {
        0.0
    };
    TriangleSize {
        // Written so that a NaN counts as degenerate.
        clearly_positive: relative_area > 64.0 * f64::EPSILON,
        area: 0.5 * twice * u1 * u2 * h * h,
        longest_edge: l2.sqrt() * u * h,
        relative_area,
    }
}

/// Whether the triangle `abc` has clearly non-zero area, and its area
/// ([`triangle_size`]).
pub(crate) fn area_is_clearly_positive(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> (bool, f64) {
    let size = triangle_size(a, b, c);
    (size.clearly_positive, size.area)
}

/// `‖a − b‖₂` without overflow or underflow of the squares (scaled by the
/// largest coordinate difference).
pub(crate) fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = sub(a, b);
    let m = d.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if m == 0.0 || !m.is_finite() {
        return m;
    }
    m * norm_sq([d[0] / m, d[1] / m, d[2] / m]).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangle_size_is_free_of_overflow_and_underflow() {
        let s = triangle_size([0.0; 3], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]);
        assert!(s.clearly_positive);
        assert_eq!((s.area, s.relative_area), (2.0, 0.5));
        assert_eq!(s.longest_edge, 8f64.sqrt());
        // The same triangle at 2^1000 times the size: the same decision
        // and relative area, the area beyond the largest double.
        let k = 2f64.powi(1000);
        let big = triangle_size([0.0; 3], [2.0 * k, 0.0, 0.0], [0.0, 2.0 * k, 0.0]);
        assert!((big.relative_area - 0.5).abs() < 1e-15);
        assert!(big.area.is_infinite());
        // Collinear: zero.
        let flat = triangle_size([0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]);
        assert!(!flat.clearly_positive);
        assert_eq!((flat.area, flat.relative_area), (0.0, 0.0));
        // Corners 3e308 apart: edges of the halved corners, doubled.
        let v = 1.5e308;
        let wide = triangle_size([-v, 0.0, 0.0], [v, 0.0, 0.0], [0.0, v, 0.0]);
        assert!(wide.clearly_positive);
        assert!(wide.area.is_infinite() && wide.longest_edge.is_infinite());
        assert!((wide.relative_area - 0.5).abs() < 1e-15);
        assert_eq!(power_of_two_unit(f64::MAX), 2f64.powi(1023));
    }
}
