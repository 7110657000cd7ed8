//! A mesh's signature: vertex count, face count and a fingerprint of its
//! connectivity and (rounded) positions, so that a constraints file can say
//! which mesh it was made for.
//!
//! **Fingerprint** (`"fnv1a64-v1:" + 16 hex digits`): the 64-bit FNV-1a hash
//! (offset basis `0xcbf29ce484222325`, prime `0x100000001b3`) of these bytes,
//! every integer little-endian:
//! 1. the tag `lse-deform mesh v1`;
//! 2. the vertex count and the face count (`u64` each);
//! 3. every face's three vertex indices, in file order (`u64` each);
//! 4. the quantum exponent `e = ⌊log₂ diag⌋ − 20` (`i64`), with `diag` the
//!    bounding-box diagonal;
//! 5. every coordinate rounded to a multiple of `2^e`:
//!    `round(x / 2^e)` (`i64`), vertex by vertex, x, y, z.
//!
//! So two meshes have the same fingerprint when they have the same faces in
//! the same order and positions equal to about `2⁻²⁰ ≈ 10⁻⁶` of their size —
//! the same mesh written as OBJ with shortest decimals, as a `float` PLY or
//! as a `double` PLY agrees; a deformed copy, a remeshed or reordered mesh
//! does not. The quantum is a power of two (so dividing by it is exact) and
//! depends on the diagonal only through its binary exponent (so rounding the
//! file's numbers does not change the quantum, except when the diagonal sits
//! within rounding of a power of two). Like any rounding, a coordinate within
//! rounding noise of a half-quantum can still round differently: a mismatch
//! is therefore a warning by default (`deform --strict` makes it an error).

use serde::{Deserialize, Serialize};

use super::Mesh;

/// Which mesh something was made for: the counts and the
/// [fingerprint](self).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSignature {
    /// Number of vertices.
    pub vertices: usize,
    /// Number of (triangle) faces.
    pub faces: usize,
    /// `"fnv1a64-v1:…"`, see the module documentation.
    pub fingerprint: String,
}

/// Binary exponent of the rounding quantum relative to the diagonal
/// (`2⁻²⁰ ≈ 1e-6`): above `float` rounding (`2⁻²⁴` relative), far below any
/// deliberate change of shape.
const QUANTUM_BITS_BELOW_DIAGONAL: i64 = 20;

/// 64-bit FNV-1a (Fowler–Noll–Vo): a fingerprint against mix-ups, not a
/// cryptographic hash.
pub(crate) struct Fnv1a(pub(crate) u64);

impl Fnv1a {
    pub(crate) fn new() -> Fnv1a {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }

    pub(crate) fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
}

impl MeshSignature {
    /// The signature of `mesh` (one pass over faces and positions).
    pub fn of(mesh: &Mesh) -> MeshSignature {
        MeshSignature {
            vertices: mesh.n_vertices(),
            faces: mesh.n_faces(),
            fingerprint: fingerprint(mesh),
        }
    }

    /// `None` when `self` (what a file says) describes `mesh`, otherwise a
    /// sentence saying what differs.
    pub(crate) fn mismatch(&self, mesh: &Mesh) -> Option<String> {
        let actual = MeshSignature::of(mesh);
        if *self == actual {
            return None;
        }
        if (self.vertices, self.faces) != (actual.vertices, actual.faces) {
            return Some(format!(
                "made for a mesh of {} vertices and {} faces, this one has {} and {}",
                self.vertices, self.faces, actual.vertices, actual.faces
            ));
        }
        Some(format!(
            "made for a mesh with the same counts but fingerprint {}, this one has {} (other connectivity or positions)",
            self.fingerprint, actual.fingerprint
        ))
    }
}

/// The fingerprint of the module documentation.
pub fn fingerprint(mesh: &Mesh) -> String {
    let mut h = Fnv1a::new();
    h.bytes(b"lse-deform mesh v1");
    h.bytes(&(mesh.n_vertices() as u64).to_le_bytes());
    h.bytes(&(mesh.n_faces() as u64).to_le_bytes());
    for f in mesh.faces() {
        for &v in f {
            h.bytes(&(v as u64).to_le_bytes());
        }
    }
    let diagonal = mesh.bbox_diagonal();
    let e = if diagonal > 0.0 && diagonal.is_finite() {
        diagonal.log2().floor() as i64 - QUANTUM_BITS_BELOW_DIAGONAL
    } else {
        0
    };
    h.bytes(&e.to_le_bytes());
    // Multiplying by 2^-e is exact (a power of two built from its bits).
    let scale = pow2(-e);
    for p in mesh.positions() {
        for &x in p {
            h.bytes(&((x * scale).round() as i64).to_le_bytes());
        }
    }
    format!("fnv1a64-v1:{:016x}", h.0)
}

/// `2^k` for `k` in the normal range of `f64`, saturating outside it.
fn pow2(k: i64) -> f64 {
    let k = k.clamp(-1022, 1023);
    f64::from_bits(((k + 1023) as u64) << 52)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn triangle(scale: f64) -> Mesh {
        Mesh::new(
            vec![[0.0, 0.0, 0.0], [scale, 0.0, 0.0], [0.0, scale, 0.0]],
            vec![[0, 1, 2]],
        )
        .unwrap()
    }

    #[test]
    fn fnv1a_matches_the_published_vectors() {
        // From the FNV reference test suite (Fowler, Noll, Vo).
        let mut h = Fnv1a::new();
        h.bytes(b"");
        assert_eq!(h.0, 0xcbf29ce484222325);
        let mut h = Fnv1a::new();
        h.bytes(b"a");
        assert_eq!(h.0, 0xaf63dc4c8601ec8c);
        let mut h = Fnv1a::new();
        h.bytes(b"foobar");
        assert_eq!(h.0, 0x85944171f73967e8);
    }

    #[test]
    fn pow2_is_exact() {
        assert_eq!(pow2(0), 1.0);
        assert_eq!(pow2(3), 8.0);
        assert_eq!(pow2(-20), 1.0 / 1048576.0);
    }

    #[test]
    fn float_rounding_keeps_the_fingerprint_and_a_move_changes_it() {
        let m = triangle(1.0);
        // diag = √2 → e = 0 − 20; a float32 round trip of 0.1-ish values
        // moves them by ~1e-9, far below the 2^-20 quantum.
        let f32ed: Vec<[f64; 3]> = m
            .positions()
            .iter()
            .map(|p| p.map(|x| (x + 0.1) as f32 as f64 - 0.1))
            .collect();
        let near = m.with_positions(f32ed).unwrap();
        assert_eq!(fingerprint(&m), fingerprint(&near));
        let moved = m
            .with_positions(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.01]])
            .unwrap();
        assert_ne!(fingerprint(&m), fingerprint(&moved));
        let sig = MeshSignature::of(&m);
        assert_eq!(sig.mismatch(&m), None);
        assert!(sig.mismatch(&moved).unwrap().contains("fingerprint"));
    }

    #[test]
    fn connectivity_is_part_of_it() {
        let p = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let a = Mesh::new(p.clone(), vec![[0, 1, 2]]).unwrap();
        let b = Mesh::new(p, vec![[0, 2, 1]]).unwrap();
        assert_ne!(fingerprint(&a), fingerprint(&b));
        assert!(fingerprint(&a).starts_with("fnv1a64-v1:"));
        assert_eq!(fingerprint(&a).len(), "fnv1a64-v1:".len() + 16);
    }
}
