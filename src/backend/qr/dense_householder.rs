//! The paper's QR (§3.3) on independent blocks: Householder reflections per
//! block of `Bᵀ`, processing the block's constraints in list order and
//! skipping dependent ones.
//!
//! **Blocks.** Constraints that share no unknown are independent: the
//! connected components of the constraint–unknown graph split `Bᵀ` into
//! blocks after a permutation, `Q = blockdiag(Q_c, I)`, and rank and
//! conflicts are decided per block with the priority order kept inside each.
//! A lone position constraint is a 1 × 1 block, so for "fix a region, drag a
//! handle" `A Q2` is simply `A` without the fixed columns.
//!
//! **Per block** (`n_c` unknowns, `m_c` constraints) the block of `Bᵀ` is a
//! dense `n_c × m_c` matrix. Column `j` has the earlier reflectors applied; if
//! the norm of its part below the current rank `k` is `≤ η ‖b_j‖` it is
//! skipped, otherwise a Householder reflector `H_k = I − τ v vᵀ` (`v_k = 1`)
//! maps that part to `β e_k` and `R[0..=k, k]` is stored. `Q_c = H_0 ⋯ H_{r−1}`
//! is never formed: the reflectors are applied to operands.
//!
//! **Free directions** `z` are numbered by walking the unknowns in order: an
//! unconstrained unknown is its own free direction (`Q = I` there); a block
//! contributes its `n_c − r_c` directions `Q_c e_t, t ≥ r_c`, at the position
//! of its smallest unknown. This keeps the mesh ordering's locality.
//!
//! Cost: `O(m_c r_c n_c)` per block. Large blocks (thousands of mutually
//! linked relative constraints) make this cubic — the paper's Fig. 9.

use faer::sparse::{SparseColMat, SparseColMatRef, SparseRowMatRef, SymbolicSparseColMat};
use faer::{Mat, MatMut, MatRef};

use super::distinct_rows::factor_distinct_rows;
use super::graph_rows::factor_graph_rows;
use super::{ConstraintQr, QrBackend, RankTolerance};
use crate::error::{Error, ProblemError};
use crate::limits::MemoryBudget;

/// Per-block dense Householder QR with the paper's column skipping.
#[derive(Debug, Clone, Copy, Default)]
pub struct DenseHouseholder;

impl QrBackend for DenseHouseholder {
    fn name(&self) -> crate::backend::BackendName {
        super::QrKind::DenseHouseholder.name().into()
    }

    fn factor_with(
        &self,
        b: SparseRowMatRef<'_, usize, f64>,
        tolerance: RankTolerance,
        resources: &crate::resources::Resources,
    ) -> Result<Box<dyn ConstraintQr>, Error> {
        let budget = resources.budget;
        factor_distinct_rows(b, |b| {
            factor_graph_rows(b, |b| {
                Ok(Box::new(BlockHouseholderQr::new(b, tolerance, budget)?)
                    as Box<dyn ConstraintQr>)
            })
        })
    }
}

/// One independent block of `Bᵀ` and its factorisation.
#[derive(Debug, Clone)]
struct Block {
    /// Unknowns of the block, increasing (local row `t` ↔ `verts[t]`).
    verts: Vec<usize>,
    /// Householder vectors, `n_c × r`; column `k` is zero above row `k` and
    /// 1 on it.
    v: Mat<f64>,
    tau: Vec<f64>,
    /// `R1`, `r × r` upper triangular (kept constraints only).
    r1: Mat<f64>,
    /// The kept rows of `B`, in rank order.
    kept: Vec<usize>,
    /// Offsets of the block's part of `y` and of `z`.
    y_offset: usize,
    z_offset: usize,
}

impl Block {
    fn rank(&self) -> usize {
        self.tau.len()
    }

    /// `u ← H_k u` for the column range of `u` (local rows).
    fn reflect(&self, k: usize, mut u: MatMut<'_, f64>) {
        let n_c = self.verts.len();
        for c in 0..u.ncols() {
            let mut s = 0.0;
            for t in k..n_c {
                s += self.v[(t, k)] * u[(t, c)];
            }
            s *= self.tau[k];
            if s != 0.0 {
                for t in k..n_c {
                    u[(t, c)] -= s * self.v[(t, k)];
                }
            }
        }
    }
}

/// What free direction `z_k` is.
#[derive(Debug, Clone, Copy)]
enum FreeSlot {
    /// An unconstrained unknown.
    Unknown(usize),
    /// Direction `Q_c e_t` of block `c`, `t ≥ r_c`.
    Block { block: usize, t: usize },
}

/// The factorisation produced by [`DenseHouseholder`].
#[derive(Debug, Clone)]
pub struct BlockHouseholderQr {
    n: usize,
    blocks: Vec<Block>,
    free: Vec<FreeSlot>,
    kept: Vec<usize>,
    skipped: Vec<usize>,
}

impl BlockHouseholderQr {
    /// Factors `Bᵀ` block by block.
    ///
    /// Errors: [`ProblemError::TooLarge`] when the dense blocks would not fit
    /// in the solve's memory `budget` ([`crate::limits`]): a block of `k` unknowns and
    /// `m` constraints stores `Bᵀ` and its reflectors densely
    /// (`8(k m + k min(k, m) + min(k, m)²)` bytes) and makes a dense block of
    /// at least `(k − min(k, m))²` entries in the normal matrix (16 bytes
    /// each with its index). Checked before anything is allocated.
    ///
    /// Phases: the blocks ([`partition_blocks`]), the size check, each
    /// block's dense `Bᵀ` ([`dense_block`]) and its factorisation
    /// ([`factor_block`]), then the free directions ([`free_directions`]).
    pub fn new(
        b: SparseRowMatRef<'_, usize, f64>,
        tolerance: RankTolerance,
        budget: MemoryBudget,
    ) -> Result<Self, ProblemError> {
        let n = b.ncols();
        let Partition {
            touched,
            block_of,
            block_verts,
            block_rows,
            mut skipped,
        } = partition_blocks(b);
        check_block_sizes(&block_verts, &block_rows, budget)?;
        let mut local = vec![usize::MAX; n];
        let mut blocks = Vec::with_capacity(block_verts.len());
        let mut y_offset = 0;
        for (verts, rows) in block_verts.into_iter().zip(block_rows) {
            let bt = dense_block(b, &verts, &rows, &mut local);
            let block = factor_block(verts, &rows, bt, tolerance, y_offset, &mut skipped);
            y_offset += block.rank();
            blocks.push(block);
        }
        skipped.sort_unstable();
        let free = free_directions(n - y_offset, &touched, &block_of, &mut blocks);
        let kept = blocks.iter().flat_map(|b| b.kept.iter().copied()).collect();
        Ok(BlockHouseholderQr {
            n,
            blocks,
            free,
            kept,
            skipped,
        })
    }
}

/// The independent blocks of `B`: unknowns linked by a constraint, by
/// union–find.
#[derive(Debug, PartialEq)]
struct Partition {
    /// Whether an unknown appears in some constraint.
    touched: Vec<bool>,
    /// The block of each touched unknown (`usize::MAX`: untouched).
    block_of: Vec<usize>,
    /// Each block's unknowns, increasing; blocks numbered by their smallest.
    block_verts: Vec<Vec<usize>>,
    /// Each block's constraints, increasing.
    block_rows: Vec<Vec<usize>>,
    /// Empty constraints (dependent on anything).
    skipped: Vec<usize>,
}

/// Partitions `b`'s unknowns and constraints into independent blocks (see
/// [`Partition`]).
fn partition_blocks(b: SparseRowMatRef<'_, usize, f64>) -> Partition {
    let (m, n) = (b.nrows(), b.ncols());
    let row_ptr = b.symbolic().row_ptr();
    let col_idx = b.symbolic().col_idx();
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    let mut touched = vec![false; n];
    for i in 0..m {
        let cols = &col_idx[row_ptr[i]..row_ptr[i + 1]];
        for &c in cols {
            touched[c] = true;
        }
        if let Some((&first, rest)) = cols.split_first() {
            for &c in rest {
                let (ra, rb) = (find(&mut parent, first), find(&mut parent, c));
                if ra != rb {
                    parent[ra.max(rb)] = ra.min(rb);
                }
            }
        }
    }
    // Blocks numbered by their smallest unknown; unknowns sorted.
    let mut block_of_root = vec![usize::MAX; n];
    let mut block_verts: Vec<Vec<usize>> = Vec::new();
    let mut block_of = vec![usize::MAX; n];
    for v in 0..n {
        if touched[v] {
            let r = find(&mut parent, v);
            if block_of_root[r] == usize::MAX {
                block_of_root[r] = block_verts.len();
                block_verts.push(Vec::new());
            }
            block_of[v] = block_of_root[r];
            block_verts[block_of_root[r]].push(v);
        }
    }
    let mut block_rows: Vec<Vec<usize>> = vec![Vec::new(); block_verts.len()];
    let mut skipped = Vec::new();
    for i in 0..m {
        match col_idx[row_ptr[i]..row_ptr[i + 1]].first() {
            Some(&c) => block_rows[block_of[c]].push(i),
            None => skipped.push(i), // an empty row is dependent on anything
        }
    }
    Partition {
        touched,
        block_of,
        block_verts,
        block_rows,
        skipped,
    }
}

/// The block's `Bᵀ`, dense: `verts.len() × rows.len()`, duplicate entries
/// summed in storage order. `local` (length `n`) is scratch: it maps the
/// block's unknowns to their positions.
fn dense_block(
    b: SparseRowMatRef<'_, usize, f64>,
    verts: &[usize],
    rows: &[usize],
    local: &mut [usize],
) -> Mat<f64> {
    let row_ptr = b.symbolic().row_ptr();
    let col_idx = b.symbolic().col_idx();
    let vals = b.val();
    for (t, &v) in verts.iter().enumerate() {
        local[v] = t;
    }
    let mut bt = Mat::<f64>::zeros(verts.len(), rows.len());
    for (j, &i) in rows.iter().enumerate() {
        for p in row_ptr[i]..row_ptr[i + 1] {
            bt[(local[col_idx[p]], j)] += vals[p];
        }
    }
    bt
}

/// Householder QR of a block's `Bᵀ` (`bt`), column by column in priority
/// order: each column is reflected by the reflectors so far; its
/// remainder below them, `rest`, makes it independent when
/// `rest > η ‖b_j‖₂` ([`RankTolerance`]), and then a new reflector
/// `v = [1; x/(α − β)]`, `τ = (β − α)/β`, `β = −sign(α) rest` (LAPACK's
/// `dlarfg`) zeroes it below the diagonal. Dependent columns go to
/// `skipped`.
fn factor_block(
    verts: Vec<usize>,
    rows: &[usize],
    mut bt: Mat<f64>,
    tolerance: RankTolerance,
    y_offset: usize,
    skipped: &mut Vec<usize>,
) -> Block {
    let n_c = verts.len();
    let mut block = Block {
        verts,
        v: Mat::zeros(n_c, n_c.min(rows.len())),
        tau: Vec::new(),
        r1: Mat::zeros(n_c.min(rows.len()), n_c.min(rows.len())),
        kept: Vec::new(),
        y_offset,
        z_offset: 0,
    };
    for (j, &i) in rows.iter().enumerate() {
        let k = block.rank();
        let col_norm = (0..n_c).map(|t| bt[(t, j)].powi(2)).sum::<f64>().sqrt();
        for h in 0..k {
            block.reflect(h, bt.as_mut().subcols_mut(j, 1));
        }
        let rest = (k..n_c).map(|t| bt[(t, j)].powi(2)).sum::<f64>().sqrt();
        // NaN-safe: a NaN remainder counts as dependent.
        let independent = rest > tolerance.relative * col_norm;
        if k == n_c || !independent {
            skipped.push(i);
            continue;
        }
        let alpha = bt[(k, j)];
        let beta = -rest.copysign(alpha);
        let scale = 1.0 / (alpha - beta);
        block.v[(k, k)] = 1.0;
        for t in k + 1..n_c {
            block.v[(t, k)] = bt[(t, j)] * scale;
        }
        block.tau.push((beta - alpha) / beta);
        for h in 0..k {
            block.r1[(h, k)] = bt[(h, j)];
        }
        block.r1[(k, k)] = beta;
        block.kept.push(i);
    }
    let r = block.rank();
    block.v = block.v.subcols(0, r).to_owned();
    block.r1 = block.r1.submatrix(0, 0, r, r).to_owned();
    block
}

/// The free directions (`n_free` of them) in unknown order: an untouched
/// unknown, or at a block's smallest unknown the block's `Q_c e_t` for
/// `t ≥ rank` (setting the block's `z_offset`).
fn free_directions(
    n_free: usize,
    touched: &[bool],
    block_of: &[usize],
    blocks: &mut [Block],
) -> Vec<FreeSlot> {
    let mut free = Vec::with_capacity(n_free);
    for v in 0..touched.len() {
        if !touched[v] {
            free.push(FreeSlot::Unknown(v));
        } else {
            let c = block_of[v];
            if blocks[c].verts[0] == v {
                blocks[c].z_offset = free.len();
                for t in blocks[c].rank()..blocks[c].verts.len() {
                    free.push(FreeSlot::Block { block: c, t });
                }
            }
        }
    }
    free
}

impl ConstraintQr for BlockHouseholderQr {
    fn n(&self) -> usize {
        self.n
    }

    fn rank(&self) -> usize {
        self.kept.len()
    }

    fn kept(&self) -> &[usize] {
        &self.kept
    }

    fn skipped(&self) -> &[usize] {
        &self.skipped
    }

    fn solve_r1t(&self, d: MatRef<'_, f64>, mut y: MatMut<'_, f64>) {
        for b in &self.blocks {
            // R1ᵀ is lower triangular: forward substitution.
            for c in 0..d.ncols() {
                for k in 0..b.rank() {
                    let mut s = d[(b.kept[k], c)];
                    for h in 0..k {
                        s -= b.r1[(h, k)] * y[(b.y_offset + h, c)];
                    }
                    y[(b.y_offset + k, c)] = s / b.r1[(k, k)];
                }
            }
        }
    }

    fn apply_q(&self, y: MatRef<'_, f64>, z: MatRef<'_, f64>, mut x: MatMut<'_, f64>) {
        let ncols = x.ncols();
        for (k, slot) in self.free.iter().enumerate() {
            if let FreeSlot::Unknown(v) = *slot {
                for c in 0..ncols {
                    x[(v, c)] = z[(k, c)];
                }
            }
        }
        for b in &self.blocks {
            let (n_c, r) = (b.verts.len(), b.rank());
            let mut u = Mat::<f64>::zeros(n_c, ncols);
            for c in 0..ncols {
                for t in 0..r {
                    u[(t, c)] = y[(b.y_offset + t, c)];
                }
                for t in r..n_c {
                    u[(t, c)] = z[(b.z_offset + t - r, c)];
                }
            }
            for k in (0..r).rev() {
                b.reflect(k, u.as_mut());
            }
            for (t, &v) in b.verts.iter().enumerate() {
                for c in 0..ncols {
                    x[(v, c)] = u[(t, c)];
                }
            }
        }
    }

    fn apply_qt(&self, x: MatRef<'_, f64>, mut y: MatMut<'_, f64>, mut z: MatMut<'_, f64>) {
        let ncols = x.ncols();
        for (k, slot) in self.free.iter().enumerate() {
            if let FreeSlot::Unknown(v) = *slot {
                for c in 0..ncols {
                    z[(k, c)] = x[(v, c)];
                }
            }
        }
        for b in &self.blocks {
            let (n_c, r) = (b.verts.len(), b.rank());
            let mut u = Mat::<f64>::zeros(n_c, ncols);
            for (t, &v) in b.verts.iter().enumerate() {
                for c in 0..ncols {
                    u[(t, c)] = x[(v, c)];
                }
            }
            for k in 0..r {
                b.reflect(k, u.as_mut());
            }
            for c in 0..ncols {
                for t in 0..r {
                    y[(b.y_offset + t, c)] = u[(t, c)];
                }
                for t in r..n_c {
                    z[(b.z_offset + t - r, c)] = u[(t, c)];
                }
            }
        }
    }

    fn mul_a_q2(&self, a: SparseColMatRef<'_, usize, f64>) -> SparseColMat<usize, f64> {
        let l = a.nrows();
        let (a_ptr, a_rows, a_val) = (a.symbolic().col_ptr(), a.symbolic().row_idx(), a.val());
        let mut col_ptr = Vec::with_capacity(self.free.len() + 1);
        col_ptr.push(0usize);
        let mut row_idx = Vec::with_capacity(a_rows.len());
        let mut values = Vec::with_capacity(a_rows.len());
        let mut row_pos = vec![usize::MAX; l];
        for slot in &self.free {
            match *slot {
                FreeSlot::Unknown(v) => {
                    let range = a_ptr[v]..a_ptr[v + 1];
                    row_idx.extend_from_slice(&a_rows[range.clone()]);
                    values.extend_from_slice(&a_val[range]);
                    col_ptr.push(row_idx.len());
                }
                FreeSlot::Block { block, t } => {
                    let b = &self.blocks[block];
                    if t != b.rank() {
                        continue; // the whole block is emitted at its first slot
                    }
                    // Rows of A touching the block, sorted.
                    let mut rows: Vec<usize> = Vec::new();
                    for &v in &b.verts {
                        for &i in &a_rows[a_ptr[v]..a_ptr[v + 1]] {
                            if row_pos[i] == usize::MAX {
                                row_pos[i] = 0;
                                rows.push(i);
                            }
                        }
                    }
                    rows.sort_unstable();
                    for (p, &i) in rows.iter().enumerate() {
                        row_pos[i] = p;
                    }
                    // M = A[rows, verts], then M ← M H_0 ⋯ H_{r−1}.
                    let n_c = b.verts.len();
                    let mut mt = Mat::<f64>::zeros(n_c, rows.len()); // Mᵀ, so H acts on columns
                    for (t, &v) in b.verts.iter().enumerate() {
                        for p in a_ptr[v]..a_ptr[v + 1] {
                            mt[(t, row_pos[a_rows[p]])] = a_val[p];
                        }
                    }
                    for k in 0..b.rank() {
                        // (M H)ᵀ = H Mᵀ.
                        b.reflect(k, mt.as_mut());
                    }
                    for t in b.rank()..n_c {
                        for (p, &i) in rows.iter().enumerate() {
                            row_idx.push(i);
                            values.push(mt[(t, p)]);
                        }
                        col_ptr.push(row_idx.len());
                    }
                    for &i in &rows {
                        row_pos[i] = usize::MAX;
                    }
                }
            }
        }
        let ncols = col_ptr.len() - 1;
        // Rows of every column are sorted (A's are; block rows were sorted)
        // and unique; `new_checked` verifies it in O(nnz).
        let symbolic = SymbolicSparseColMat::new_checked(l, ncols, col_ptr, None, row_idx);
        SparseColMat::new(symbolic, values)
    }

    fn free_unknown(&self, k: usize) -> usize {
        match self.free.get(k) {
            Some(FreeSlot::Unknown(v)) => *v,
            Some(FreeSlot::Block { block, t }) => self.blocks[*block].verts[*t],
            None => k,
        }
    }

    fn storage_nnz(&self) -> usize {
        self.blocks
            .iter()
            .map(|b| b.verts.len() * b.rank() + b.rank() * (b.rank() + 1) / 2)
            .sum()
    }
}

/// See [`BlockHouseholderQr::new`]: the dense storage of every block and the
/// dense blocks they put in the normal matrix, against the memory budget.
fn check_block_sizes(
    verts: &[Vec<usize>],
    rows: &[Vec<usize>],
    budget: MemoryBudget,
) -> Result<(), ProblemError> {
    let (mut bytes, mut largest) = (0u64, (0u64, 0u64));
    for (v, r) in verts.iter().zip(rows) {
        let (k, m) = (v.len() as u64, r.len() as u64);
        let min = k.min(m);
        let dense = k
            .saturating_mul(m)
            .saturating_add(k.saturating_mul(min))
            .saturating_add(min.saturating_mul(min))
            .saturating_mul(8);
        let normal = (k - min).saturating_mul(k - min).saturating_mul(16);
        bytes = bytes.saturating_add(dense).saturating_add(normal);
        if k > largest.0 {
            largest = (k, m);
        }
    }
    budget.check(bytes, || {
        format!(
            "the dense Householder blocks of Bᵀ (largest: {} unknowns linked by {} constraints; try the sparse-givens QR back end) would need",
            largest.0, largest.1
        )
    })
    .map_err(|detail| ProblemError::TooLarge { detail })
}

#[cfg(test)]
mod phase_tests {
    use faer::sparse::{SparseRowMat, Triplet};

    use super::*;

    fn rows(m: usize, n: usize, t: &[(usize, usize, f64)]) -> SparseRowMat<usize, f64> {
        let t: Vec<_> = t.iter().map(|&(i, j, v)| Triplet::new(i, j, v)).collect();
        SparseRowMat::try_new_from_triplets(m, n, &t).unwrap()
    }

    #[test]
    fn partition_links_unknowns_sharing_a_constraint() {
        // Constraint 0 on u0, u1; 1 on u3; 2 empty; 3 on u1, u4 (joins
        // block 0); u2 untouched.
        let b = rows(
            4,
            5,
            &[
                (0, 0, 1.0),
                (0, 1, 1.0),
                (1, 3, 2.0),
                (3, 1, 1.0),
                (3, 4, 1.0),
            ],
        );
        let m = usize::MAX;
        assert_eq!(
            partition_blocks(b.as_ref()),
            Partition {
                touched: vec![true, true, false, true, true],
                block_of: vec![0, 0, m, 1, 0],
                block_verts: vec![vec![0, 1, 4], vec![3]],
                block_rows: vec![vec![0, 3], vec![1]],
                skipped: vec![2],
            }
        );
        let mut local = vec![m; 5];
        let bt = dense_block(b.as_ref(), &[0, 1, 4], &[0, 3], &mut local);
        assert_eq!(bt, faer::mat![[1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
        assert_eq!(local, [0, 1, m, m, 2]);
    }

    #[test]
    fn block_factor_is_dlarfg_and_skips_a_multiple() {
        // Bᵀ = [3 6; 4 8]: column 1 is twice column 0.
        let bt = faer::mat![[3.0, 6.0], [4.0, 8.0]];
        let mut skipped = Vec::new();
        let block = factor_block(
            vec![0, 1],
            &[10, 11],
            bt,
            RankTolerance::default(),
            7,
            &mut skipped,
        );
        // α = 3, ‖x‖ = 5: β = −5, v = [1, 4/(3 + 5)], τ = (−5 − 3)/−5.
        assert_eq!(block.tau, [1.6]);
        assert_eq!(block.v, faer::mat![[1.0], [0.5]]);
        assert_eq!(block.r1, faer::mat![[-5.0]]);
        assert_eq!((block.kept, block.y_offset), (vec![10], 7));
        assert_eq!(skipped, [11]);
    }

    #[test]
    fn free_directions_follow_unknown_order() {
        let block = |verts: Vec<usize>, rank: usize| Block {
            verts,
            v: Mat::zeros(0, 0),
            tau: vec![1.0; rank],
            r1: Mat::zeros(0, 0),
            kept: Vec::new(),
            y_offset: 0,
            z_offset: 0,
        };
        let mut blocks = vec![block(vec![0, 1], 1), block(vec![3], 1)];
        let m = usize::MAX;
        let free = free_directions(2, &[true, true, false, true], &[0, 0, m, 1], &mut blocks);
        assert_eq!(
            format!("{free:?}"),
            "[Block { block: 0, t: 1 }, Unknown(2)]"
        );
        assert_eq!((blocks[0].z_offset, blocks[1].z_offset), (0, 2));
    }
}
