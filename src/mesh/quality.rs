//! Triangle quality: angles and aspect ratios.

use super::Mesh;

/// Triangle quality summary of a mesh.
#[derive(Debug, Clone)]
pub struct Quality {}

impl Quality {
    /// Computes the summary.
    pub fn of(mesh: &Mesh) -> Quality {
        let _ = mesh;
        Quality {}
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
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
