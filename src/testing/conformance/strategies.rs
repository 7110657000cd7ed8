//! Cases several kits draw: meshes with constraints, and grid matrices.

use faer::sparse::{SparseColMat, Triplet};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::laplacian::LaplacianKind;
use crate::testing::{ConstraintMix, constraint_mixes, laplacian_kinds};

// ---------------------------------------------------------------------------
// Cases: meshes with constraints, and matrices.

/// [`constraint_mixes`] with a Laplacian kind.
pub(super) fn mixes() -> impl Strategy<Value = (ConstraintMix, LaplacianKind)> {
    (constraint_mixes(), laplacian_kinds())
}

/// A grid matrix: `side × side` unknowns, values drawn from `seed`.
#[derive(Clone, Debug)]
pub struct GridCase {
    /// Unknowns per side.
    pub side: usize,
    /// The seed of the values.
    pub seed: u64,
}

/// Grids of 2–8 unknowns a side.
pub(super) fn grids() -> impl Strategy<Value = GridCase> {
    (2usize..9, any::<u64>()).prop_map(|(side, seed)| GridCase { side, seed })
}

/// The lower triangle of `L + s I`, `L` the Laplacian of a `side × side`
/// grid with edge weights in `[0.5, 1.5)` and `s` in `[0.01, 1)`, both
/// drawn from `seed`: symmetric positive definite, its pattern fixed by
/// `side` alone. Public so that a back end's own tests can use the kit's
/// matrices.
pub fn grid_lower(side: usize, seed: u64) -> SparseColMat<usize, f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = side * side;
    let shift = rng.random_range(0.01..1.0);
    let mut diagonal = vec![shift; n];
    let mut triplets = Vec::new();
    for a in 0..n {
        let (i, j) = (a / side, a % side);
        let right = (j + 1 < side).then_some(a + 1);
        let below = (i + 1 < side).then_some(a + side);
        for b in [right, below].into_iter().flatten() {
            let w = rng.random_range(0.5..1.5);
            triplets.push(Triplet::new(b, a, -w));
            diagonal[a] += w;
            diagonal[b] += w;
        }
    }
    triplets.extend(
        diagonal
            .iter()
            .enumerate()
            .map(|(a, &d)| Triplet::new(a, a, d)),
    );
    SparseColMat::try_new_from_triplets(n, n, &triplets).expect("a grid's triplets are in range")
}
