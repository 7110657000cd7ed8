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

/// Area of the triangle `abc` (NaN if a coordinate is NaN).
pub fn triangle_area(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    0.5 * norm_sq(cross(sub(b, a), sub(c, a))).sqrt()
}

/// Squared length of the longest edge of `abc`.
pub fn longest_edge_sq(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    norm_sq(sub(b, a))
        .max(norm_sq(sub(c, b)))
        .max(norm_sq(sub(a, c)))
}

/// The power of two `2^e` nearest to the largest coordinate difference of
/// `abc` (1 if the three points coincide). Dividing the edge vectors by it
/// is exact and brings them to unit size, so that areas and squared lengths
/// neither overflow (coordinates of 1e200) nor underflow (1e-200).
fn edge_unit(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let m = sub(b, a)
        .iter()
        .chain(sub(c, a).iter())
        .chain(sub(c, b).iter())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    power_of_two_unit(m)
}

/// `2^round(log2 x)` for a finite `x > 0`, else 1: the exact unit that
/// normalises a length of size `x` to `[0.7, 1.4]`.
pub fn power_of_two_unit(x: f64) -> f64 {
    if x > 0.0 && x.is_finite() {
        2f64.powi(x.log2().round() as i32)
    } else {
        1.0
    }
}

/// Whether the triangle `abc` has clearly non-zero area, `|e1 × e2| > 64 ε
/// ℓ²` (ℓ the longest edge; the rounding error of the cross product is a
/// few `ε ℓ²`), and its area. Scale-invariant: the test runs on the edge
/// vectors divided by an exact power of two ([`power_of_two_unit`]), so it
/// decides the same for a mesh in any unit from 1e-300 to 1e300.
pub fn area_is_clearly_positive(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> (bool, f64) {
    let u = edge_unit(a, b, c);
    let (e1, e2, e3) = (sub(b, a), sub(c, a), sub(c, b));
    let scale = |e: [f64; 3]| [e[0] / u, e[1] / u, e[2] / u];
    let (e1, e2, e3) = (scale(e1), scale(e2), scale(e3));
    let twice_area = norm_sq(cross(e1, e2)).sqrt();
    let l2 = norm_sq(e1).max(norm_sq(e2)).max(norm_sq(e3));
    // Written so that a NaN area also counts as degenerate.
    let clearly_positive = twice_area > 64.0 * f64::EPSILON * l2;
    (clearly_positive, 0.5 * twice_area * u * u)
}

/// `‖a − b‖₂` without overflow or underflow of the squares (scaled by the
/// largest coordinate difference).
pub fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = sub(a, b);
    let m = d.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if m == 0.0 || !m.is_finite() {
        return m;
    }
    m * norm_sq([d[0] / m, d[1] / m, d[2] / m]).sqrt()
}
