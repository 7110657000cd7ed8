//! Procedurally generated meshes, for use without any mesh file.
//!
//! Every generator is deterministic (randomness, where used, comes from a
//! `ChaCha8Rng` seeded with the given seed), returns a mesh that passed
//! [`Mesh::new`] validation, orients faces counter-clockwise seen from
//! outside (spheres) or from `+z` (planar and height-field meshes), and
//! refuses parameters that are out of range or would produce more than
//! [`MAX_VERTICES`] vertices with [`MeshError::BadParameter`].
//!
//! | kind | vertices | faces | topology |
//! |---|---|---|---|
//! | [`icosphere`]`(k)` | `10·4^k + 2` | `20·4^k` | closed, genus 0 |
//! | [`bumpy_sphere`]`(k, …)` | `10·4^k + 2` | `20·4^k` | closed, genus 0 |
//! | [`grid`]`(nx, ny)` | `(nx+1)(ny+1)` | `2·nx·ny` | disk (1 boundary loop) |
//! | [`unsymmetric_grid`]`(n)` | `n(n+1) + (2n+1)²` | `10n² + n` | disk |
//! | [`sliver_mesh`]`(n, seed)` | `(n+1)² + ⌊n²/10⌋` | `2n² + 2⌊n²/10⌋` | disk |

use std::collections::HashMap;
use std::fmt;
use std::str::FromStr;

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::Mesh;
use crate::error::MeshError;

/// Largest vertex count any generator produces (about 1.2 GB of positions
/// and faces); larger requests are refused.
pub const MAX_VERTICES: usize = 50_000_000;

/// Largest number of icosphere subdivisions (`10·4^11 + 2 ≈ 42M` vertices).
pub const MAX_SUBDIVISIONS: u32 = 11;

fn bad(name: &'static str, message: impl Into<String>) -> MeshError {
    MeshError::BadParameter {
        name,
        message: message.into(),
    }
}

/// Vertex count of an icosphere with `k` subdivisions: `10·4^k + 2`.
pub(crate) fn icosphere_vertex_count(k: u32) -> Option<usize> {
    4usize.checked_pow(k)?.checked_mul(10)?.checked_add(2)
}

/// The unit icosphere: a regular icosahedron whose triangles are split
/// `subdivisions` times into four at the edge midpoints, every new vertex
/// projected onto the unit sphere. `10·4^k + 2` vertices, `20·4^k` faces,
/// closed, genus 0, outward (counter-clockwise) orientation. Subdivision 0 is
/// the icosahedron itself; at most [`MAX_SUBDIVISIONS`].
pub fn icosphere(subdivisions: u32) -> Result<Mesh, MeshError> {
    let (positions, faces) = icosphere_raw(subdivisions)?;
    Mesh::new(positions, faces)
}

type Raw = (Vec<[f64; 3]>, Vec<[usize; 3]>);

fn icosphere_raw(subdivisions: u32) -> Result<Raw, MeshError> {
    if subdivisions > MAX_SUBDIVISIONS {
        return Err(bad(
            "subdivisions",
            format!(
                "{subdivisions} is more than the maximum {MAX_SUBDIVISIONS} ({} vertices)",
                icosphere_vertex_count(MAX_SUBDIVISIONS).unwrap_or(usize::MAX)
            ),
        ));
    }
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut positions: Vec<[f64; 3]> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|&p| normalize(p))
    .collect();
    let mut faces: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let final_count = icosphere_vertex_count(subdivisions).unwrap_or(usize::MAX);
    positions.reserve(final_count.saturating_sub(positions.len()));
    for _ in 0..subdivisions {
        let mut midpoint: HashMap<(usize, usize), usize> =
            HashMap::with_capacity(faces.len() * 3 / 2);
        let mut next = Vec::with_capacity(faces.len() * 4);
        for &[a, b, c] in &faces {
            let mut mid = |i: usize, j: usize| -> usize {
                *midpoint.entry((i.min(j), i.max(j))).or_insert_with(|| {
                    let (p, q) = (positions[i], positions[j]);
                    positions.push(normalize([p[0] + q[0], p[1] + q[1], p[2] + q[2]]));
                    positions.len() - 1
                })
            };
            let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
            next.push([a, ab, ca]);
            next.push([b, bc, ab]);
            next.push([c, ca, bc]);
            next.push([ab, bc, ca]);
        }
        faces = next;
    }
    Ok((positions, faces))
}

fn normalize(p: [f64; 3]) -> [f64; 3] {
    let n = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    [p[0] / n, p[1] / n, p[2] / n]
}

/// An icosphere whose vertices are moved radially to
/// `r(p) = 1 + amplitude · f(p)`, with the smooth bump function
/// `f(p) = (1/m) Σ_j cos(ω_j (d_j · p) + φ_j)`, `m = bumps`: a sum of plane
/// waves restricted to the sphere (like low-order spherical harmonics), with
/// unit directions `d_j`, frequencies `ω_j ∈ [2, 5)` and phases `φ_j` drawn
/// from a `ChaCha8Rng` seeded with `0`. Since `|f| ≤ 1`, `r ≥ 1 − amplitude
/// > 0`. Same counts and topology as [`icosphere`].
///
/// Requires `0 ≤ amplitude < 1` and `1 ≤ bumps ≤ 64`.
pub fn bumpy_sphere(subdivisions: u32, amplitude: f64, bumps: usize) -> Result<Mesh, MeshError> {
    bumpy_sphere_seeded(subdivisions, amplitude, bumps, 0)
}

/// [`bumpy_sphere`] with the random directions, frequencies and phases drawn
/// from a `ChaCha8Rng` seeded with `seed`.
pub fn bumpy_sphere_seeded(
    subdivisions: u32,
    amplitude: f64,
    bumps: usize,
    seed: u64,
) -> Result<Mesh, MeshError> {
    if !(0.0..1.0).contains(&amplitude) {
        return Err(bad(
            "amplitude",
            format!("{amplitude} is not in [0, 1) (the radius 1 + amplitude·f must stay positive)"),
        ));
    }
    if !(1..=64).contains(&bumps) {
        return Err(bad("bumps", format!("{bumps} is not in 1..=64")));
    }
    let (mut positions, faces) = icosphere_raw(subdivisions)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let waves: Vec<([f64; 3], f64, f64)> = (0..bumps)
        .map(|_| {
            // Uniform direction on the sphere.
            let z: f64 = rng.random_range(-1.0..1.0);
            let phi: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            let s = (1.0 - z * z).sqrt();
            let d = [s * phi.cos(), s * phi.sin(), z];
            let omega: f64 = rng.random_range(2.0..5.0);
            let phase: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            (d, omega, phase)
        })
        .collect();
    for p in &mut positions {
        let f: f64 = waves
            .iter()
            .map(|(d, w, ph)| (w * (d[0] * p[0] + d[1] * p[1] + d[2] * p[2]) + ph).cos())
            .sum::<f64>()
            / bumps as f64;
        let r = 1.0 + amplitude * f;
        *p = [p[0] * r, p[1] * r, p[2] * r];
    }
    Mesh::new(positions, faces)
}

fn check_vertex_count(name: &'static str, count: Option<usize>) -> Result<usize, MeshError> {
    match count {
        Some(c) if c <= MAX_VERTICES => Ok(c),
        _ => Err(bad(
            name,
            format!("the mesh would have more than {MAX_VERTICES} vertices"),
        )),
    }
}

/// The unit square `[0,1]²` in the plane `z = 0`, as an `nx × ny` grid of
/// cells: vertex `(i, j)` (`0 ≤ i ≤ nx`, `0 ≤ j ≤ ny`) is at
/// `(i/nx, j/ny, 0)` with index `j·(nx+1) + i`, and every cell is split into
/// two triangles by the same diagonal, from `(i, j)` to `(i+1, j+1)`.
/// `(nx+1)(ny+1)` vertices, `2·nx·ny` faces, one boundary loop, oriented
/// counter-clockwise seen from `+z`. Requires `nx, ny ≥ 1`.
pub fn grid(nx: usize, ny: usize) -> Result<Mesh, MeshError> {
    if nx == 0 || ny == 0 {
        return Err(bad(
            "nx, ny",
            format!("a grid needs at least 1 × 1 cells, got {nx} × {ny}"),
        ));
    }
    let nv = check_vertex_count(
        "nx, ny",
        nx.checked_add(1)
            .and_then(|w| w.checked_mul(ny.checked_add(1)?)),
    )?;
    let mut positions = Vec::with_capacity(nv);
    for j in 0..=ny {
        let y = j as f64 / ny as f64;
        for i in 0..=nx {
            positions.push([i as f64 / nx as f64, y, 0.0]);
        }
    }
    let mut faces = Vec::with_capacity(2 * nx * ny);
    let w = nx + 1;
    for j in 0..ny {
        for i in 0..nx {
            let v00 = j * w + i;
            let (v10, v01, v11) = (v00 + 1, v00 + w, v00 + w + 1);
            faces.push([v00, v10, v11]);
            faces.push([v00, v11, v01]);
        }
    }
    Mesh::new(positions, faces)
}

/// Vertex count of [`unsymmetric_grid`]`(n)`: `n(n+1) + (2n+1)²`.
pub(crate) fn unsymmetric_grid_vertex_count(n: usize) -> Option<usize> {
    let right = n.checked_mul(2)?.checked_add(1)?;
    n.checked_mul(n + 1)?.checked_add(right.checked_mul(right)?)
}

/// An unsymmetric planar grid in the spirit of Fig. 1 of Masuda et al.
/// (2006) (our reconstruction, not the paper's exact mesh): the unit
/// square `[0,1]²` (in `z = 0`) whose left half `x ≤ ½` is an `n × n` grid
/// of coarse cells (`1/(2n) × 1/n`, diagonal from lower left to upper right)
/// and whose right half is a `2n × 2n` grid of cells half as large in each
/// direction with the *other* diagonal (lower right to upper left). The
/// halves meet conformingly at `x = ½`: each coarse cell touching it is split
/// into three triangles by the midpoint of its right edge.
///
/// The domain is mirror-symmetric about `x = ½`, the mesh is not, so a
/// Laplacian with uniform (graph) weights, which sees only connectivity,
/// deforms it asymmetrically under mirror-symmetric constraints, while
/// cotangent weights, which approximate the continuous Laplacian, stay much
/// closer to symmetric. Measured with this crate's LSE deformer (boundary
/// fixed, the interior vertices on the line `y = ½` lifted by 0.3, `n = 4`
/// and `8`): `max |z(x, y) − z(1−x, y)|` is about 0.05 with uniform weights
/// and about 0.013 with cotangent weights. (A single handle vertex on the
/// seam is not a good demonstration: there both are visibly asymmetric.)
///
/// `n(n+1) + (2n+1)²` vertices, `10n² + n` faces, one boundary loop.
/// Requires `n ≥ 1`.
///
/// Vertex numbering: left-half vertex in row `j` (`y = j/n`) and column
/// `i < n` (`x = i/(2n)`) is `j·n + i`; right-half vertex in row `r`
/// (`y = r/(2n)`) and column `c ≤ 2n` (`x = ½ + c/(4n)`) is
/// `n(n+1) + r(2n+1) + c`.
pub fn unsymmetric_grid(n: usize) -> Result<Mesh, MeshError> {
    if n == 0 {
        return Err(bad("n", "an unsymmetric grid needs n ≥ 1"));
    }
    let nv = check_vertex_count("n", unsymmetric_grid_vertex_count(n))?;
    let nf = n
        .checked_mul(n)
        .and_then(|x| x.checked_mul(10))
        .and_then(|x| x.checked_add(n))
        .unwrap_or(usize::MAX);
    let mut positions = Vec::with_capacity(nv);
    let left = |j: usize, i: usize| j * n + i;
    let base = n * (n + 1);
    let m = 2 * n;
    let right = |r: usize, c: usize| base + r * (m + 1) + c;
    for j in 0..=n {
        for i in 0..n {
            positions.push([i as f64 / (2 * n) as f64, j as f64 / n as f64, 0.0]);
        }
    }
    for r in 0..=m {
        for c in 0..=m {
            positions.push([0.5 + c as f64 / (4 * n) as f64, r as f64 / m as f64, 0.0]);
        }
    }
    let mut faces = Vec::with_capacity(nf);
    // Left half: coarse cells; the column at x = 1/2 is shared with the
    // right half (row j there is right-half row 2j, column 0).
    let left_or_seam = |j: usize, i: usize| {
        if i == n { right(2 * j, 0) } else { left(j, i) }
    };
    for j in 0..n {
        for i in 0..n {
            let a = left_or_seam(j, i);
            let b = left_or_seam(j, i + 1);
            let c = left_or_seam(j + 1, i + 1);
            let d = left_or_seam(j + 1, i);
            if i + 1 < n {
                faces.push([a, b, c]);
                faces.push([a, c, d]);
            } else {
                let mid = right(2 * j + 1, 0);
                faces.push([a, b, mid]);
                faces.push([a, mid, d]);
                faces.push([d, mid, c]);
            }
        }
    }
    // Right half: fine cells with the other diagonal (b to d).
    for r in 0..m {
        for c in 0..m {
            let a = right(r, c);
            let b = right(r, c + 1);
            let cc = right(r + 1, c + 1);
            let d = right(r + 1, c);
            faces.push([a, b, d]);
            faces.push([b, cc, d]);
        }
    }
    Mesh::new(positions, faces)
}

/// Vertex count of [`sliver_mesh`]`(n, _)`: `(n+1)² + ⌊n²/10⌋`.
pub(crate) fn sliver_vertex_count(n: usize) -> Option<usize> {
    let sq = n.checked_add(1)?.checked_mul(n + 1)?;
    sq.checked_add(n.checked_mul(n)? / 10)
}

/// The sliver mesh of Fig. 2 of Masuda et al. (2006): a curved height field
/// over `[0,1]²` full of long, thin triangles, on which cotangent weights
/// become huge or negative.
///
/// Construction (all random choices from a `ChaCha8Rng` seeded with `seed`):
/// - an `n × n` grid of cells whose column widths and row heights are
///   regular except for about a quarter of them, chosen at random, which are
///   squeezed by a factor between 1/1000 and 1/100; every cell is split by
///   a diagonal, so a squeezed column or row gives *needles* (min angle
///   `≈ atan(factor)`, well below 1°; aspect ratio in the hundreds);
/// - `⌊n²/10⌋` randomly chosen unsqueezed cells get an extra vertex just
///   inside the midpoint of their bottom edge (offset by 1/300 of the
///   cell height), and are split into four triangles around it; the one on
///   the bottom edge is a *cap* with an angle near 180°;
/// - heights `z = 0.25 · sin(πx) · sin(πy) + 0.1 · x·y` (cap vertices take
///   the mean height of their edge's ends, so the cap stays flat).
///
/// `(n+1)² + ⌊n²/10⌋` vertices, `2n² + 2⌊n²/10⌋` faces, one boundary
/// loop. The result is a valid [`Mesh`] (no face is degenerate in the sense
/// of the module invariants). Requires `n ≥ 2`.
pub fn sliver_mesh(n: usize, seed: u64) -> Result<Mesh, MeshError> {
    if n < 2 {
        return Err(bad("n", format!("a sliver mesh needs n ≥ 2, got {n}")));
    }
    let nv = check_vertex_count("n", sliver_vertex_count(n))?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let spacing = |rng: &mut ChaCha8Rng| -> Vec<f64> {
        let gaps: Vec<f64> = (0..n)
            .map(|_| {
                if rng.random_bool(0.25) {
                    10f64.powf(rng.random_range(-3.0..-2.0))
                } else {
                    1.0
                }
            })
            .collect();
        let total: f64 = gaps.iter().sum();
        let mut x = Vec::with_capacity(n + 1);
        let mut acc = 0.0;
        x.push(0.0);
        for g in &gaps {
            acc += g;
            x.push(acc / total);
        }
        x
    };
    let xs = spacing(&mut rng);
    let ys = spacing(&mut rng);
    let height = |x: f64, y: f64| {
        0.25 * (std::f64::consts::PI * x).sin() * (std::f64::consts::PI * y).sin() + 0.1 * x * y
    };
    let w = n + 1;
    let mut positions = Vec::with_capacity(nv);
    for &y in &ys {
        for &x in &xs {
            positions.push([x, y, height(x, y)]);
        }
    }
    // Candidate cap cells: cells in an unsqueezed column and row, so that the
    // cap (not the squeeze) sets their shape.
    let is_wide = |v: &[f64], i: usize| v[i + 1] - v[i] > 0.5 / n as f64;
    let mut candidates: Vec<usize> = (0..n * n)
        .filter(|&c| is_wide(&xs, c % n) && is_wide(&ys, c / n))
        .collect();
    candidates.shuffle(&mut rng);
    let mut n_caps = n * n / 10;
    if candidates.len() < n_caps {
        // Too few regular cells (tiny n): fall back to any cells.
        candidates = (0..n * n).collect();
        candidates.shuffle(&mut rng);
        n_caps = n_caps.min(candidates.len());
    }
    let mut cap = vec![false; n * n];
    for &c in &candidates[..n_caps] {
        cap[c] = true;
    }
    let mut faces = Vec::with_capacity(2 * n * n + 2 * n_caps);
    for j in 0..n {
        for i in 0..n {
            let a = j * w + i;
            let (b, c, d) = (a + 1, a + w + 1, a + w);
            if cap[j * n + i] {
                let (pa, pb) = (positions[a], positions[b]);
                let h = ys[j + 1] - ys[j];
                let p = [
                    0.5 * (pa[0] + pb[0]),
                    0.5 * (pa[1] + pb[1]) + h / 300.0,
                    0.5 * (pa[2] + pb[2]),
                ];
                positions.push(p);
                let m = positions.len() - 1;
                faces.push([a, b, m]);
                faces.push([b, c, m]);
                faces.push([c, d, m]);
                faces.push([d, a, m]);
            } else if rng.random_bool(0.5) {
                faces.push([a, b, c]);
                faces.push([a, c, d]);
            } else {
                faces.push([a, b, d]);
                faces.push([b, c, d]);
            }
        }
    }
    Mesh::new(positions, faces)
}

/// The kinds of generated mesh, by their command-line names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum GeneratedKind {
    /// `icosphere`: [`icosphere`].
    Icosphere,
    /// `bumpy-sphere`: [`bumpy_sphere_seeded`] with amplitude 0.15 and 6
    /// bumps.
    BumpySphere,
    /// `grid`: a square [`grid`] `n × n`.
    Grid,
    /// `unsymmetric-grid`: [`unsymmetric_grid`].
    UnsymmetricGrid,
    /// `sliver`: [`sliver_mesh`].
    Sliver,
}

impl GeneratedKind {
    /// All kinds, in the order of the module table.
    pub const ALL: [GeneratedKind; 5] = [
        GeneratedKind::Icosphere,
        GeneratedKind::BumpySphere,
        GeneratedKind::Grid,
        GeneratedKind::UnsymmetricGrid,
        GeneratedKind::Sliver,
    ];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            GeneratedKind::Icosphere => "icosphere",
            GeneratedKind::BumpySphere => "bumpy-sphere",
            GeneratedKind::Grid => "grid",
            GeneratedKind::UnsymmetricGrid => "unsymmetric-grid",
            GeneratedKind::Sliver => "sliver",
        }
    }

    /// Vertex count for size parameter `size` (see [`generate`]), `None` on
    /// overflow.
    pub fn vertex_count(self, size: usize) -> Option<usize> {
        match self {
            GeneratedKind::Icosphere | GeneratedKind::BumpySphere => {
                icosphere_vertex_count(u32::try_from(size).ok()?)
            }
            GeneratedKind::Grid => size.checked_add(1)?.checked_mul(size + 1),
            GeneratedKind::UnsymmetricGrid => unsymmetric_grid_vertex_count(size),
            GeneratedKind::Sliver => sliver_vertex_count(size),
        }
    }

    /// Smallest valid size parameter (0 subdivisions, 1 cell, or `n = 2`
    /// for the sliver mesh).
    pub fn min_size(self) -> usize {
        match self {
            GeneratedKind::Icosphere | GeneratedKind::BumpySphere => 0,
            GeneratedKind::Grid | GeneratedKind::UnsymmetricGrid => 1,
            GeneratedKind::Sliver => 2,
        }
    }
}

impl crate::choice::Word for GeneratedKind {
    const WHAT: &'static str = "mesh kind";
    fn all() -> &'static [Self] {
        &GeneratedKind::ALL
    }
    fn name(self) -> &'static str {
        GeneratedKind::name(self)
    }
}

impl FromStr for GeneratedKind {
    type Err = crate::error::ParseWordError;

    /// Parses a command-line name (case-insensitive; `_` accepted for `-`).
    ///
    /// Errors: [`ParseWordError`](crate::error::ParseWordError) listing the
    /// kinds.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let norm = s.trim().to_ascii_lowercase().replace('_', "-");
        <GeneratedKind as crate::choice::Word>::parse_word(&norm).map_err(|e| {
            crate::error::ParseWordError {
                word: s.to_string(),
                ..e
            }
        })
    }
}

impl fmt::Display for GeneratedKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Generates a mesh of the given kind with its single size parameter:
/// subdivisions for the spheres, cells per side for the grids (`grid(size,
/// size)`), `n` for the unsymmetric grid and the sliver mesh. `seed` drives
/// the random parts (bumps, slivers) and is ignored by the others.
pub fn generate(kind: GeneratedKind, size: usize, seed: u64) -> Result<Mesh, MeshError> {
    let subdivisions =
        || u32::try_from(size).map_err(|_| bad("subdivisions", format!("{size} is too large")));
    match kind {
        GeneratedKind::Icosphere => icosphere(subdivisions()?),
        GeneratedKind::BumpySphere => bumpy_sphere_seeded(subdivisions()?, 0.15, 6, seed),
        GeneratedKind::Grid => grid(size, size),
        GeneratedKind::UnsymmetricGrid => unsymmetric_grid(size),
        GeneratedKind::Sliver => sliver_mesh(size, seed),
    }
}

/// The size parameter of `kind` whose vertex count is closest to
/// `target_vertices` (ties go to the smaller mesh), among sizes producing at
/// most [`MAX_VERTICES`] vertices.
pub fn size_for_vertices(kind: GeneratedKind, target_vertices: usize) -> Result<usize, MeshError> {
    if target_vertices > MAX_VERTICES {
        return Err(bad(
            "vertices",
            format!("{target_vertices} is more than the maximum {MAX_VERTICES}"),
        ));
    }
    // Vertex counts grow monotonically with size: find the first size with
    // count ≥ target, then compare it with its predecessor.
    let count = |s: usize| kind.vertex_count(s).unwrap_or(usize::MAX);
    let lo = kind.min_size();
    let mut hi = lo;
    while count(hi) < target_vertices {
        hi = hi * 2 + 1;
    }
    let mut l = lo;
    while l < hi {
        let mid = l + (hi - l) / 2;
        if count(mid) < target_vertices {
            l = mid + 1;
        } else {
            hi = mid;
        }
    }
    let mut best = l;
    if l > lo && target_vertices - count(l - 1) <= count(l) - target_vertices {
        best = l - 1;
    }
    if count(best) > MAX_VERTICES {
        best -= 1;
    }
    Ok(best)
}

/// A mesh of the given kind whose vertex count is as close as possible to
/// `target_vertices` (see [`size_for_vertices`]), for scaling experiments.
/// A 1M-vertex grid takes a fraction of a second in release builds.
pub fn with_about_vertices(
    kind: GeneratedKind,
    target_vertices: usize,
    seed: u64,
) -> Result<Mesh, MeshError> {
    generate(kind, size_for_vertices(kind, target_vertices)?, seed)
}
