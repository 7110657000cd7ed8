//! Triangular solves `L Lᵀ x = b` with a faer Cholesky factor, written for
//! the few-right-hand-side case of mesh deformation (three coordinates).
//!
//! faer's own solve handles any number of right-hand sides through generic
//! dense kernels per supernode; with three columns and the many small
//! supernodes of a surface mesh's normal matrix its per-supernode overhead
//! dominates. Here:
//!
//! - the right-hand sides are solved in groups of [`LANES`] = 4 columns,
//!   stored as one [`Lane`] per unknown (`w[i] = [b_i0, b_i1, b_i2, b_i3]`,
//!   unused columns zero): the three coordinates of a mesh plus one zero,
//!   i.e. one AVX2 register and half a cache line per unknown. Every entry
//!   of `L` is then one broadcast and one lane-wise multiply–add, with no
//!   horizontal reductions;
//! - every supernode's block (`c` diagonal rows then `p` pattern rows, `c`
//!   columns) is stored **row-major** ([`SupernodalRows`], transposed once
//!   after the numeric factorisation), so a row of `L` restricted to a
//!   supernode is contiguous;
//! - forward, supernode `s` with columns `[f, f + c)` and pattern rows `P`:
//!   `x_s ← L_ss⁻¹ w_s` (row-oriented, `x_s` kept in place in `w[f..f+c]`),
//!   then `w_r −= L_{r,s} x_s` for every `r ∈ P`, four rows at a time so
//!   that each `x_j` loaded serves four rows;
//! - backward, supernodes in reverse: `a = Σ_{r∈P} L_{r,s}ᵀ w_r`, four
//!   pattern rows per pass over an accumulator of `c` lanes (in L1), then
//!   `x_s ← L_ss⁻ᵀ (w_s − a)` by blocks of eight columns from the last,
//!   each block's sums over the rows below it held in registers.
//!
//! Every entry of `L` is read once per direction and used for all columns
//! of a group, and every accumulation runs over at least four independent
//! chains, so the solve is bound by reading `L` (twice) rather than by
//! arithmetic latency. A simplicial factor is solved column by column with
//! the same lanes.
//!
//! The same kernels are instantiated for wide groups of [`WIDE_LANES`] = 8
//! columns on AVX-512 registers ([`wide_passes`]: the seven columns of a
//! response basis read `L` once instead of twice), and the supernodal
//! passes run over any ascending set of supernodes ([`Passes`]), which is
//! what the solve on two threads along the elimination tree
//! ([`super::tree_split`]) needs.

use std::ops::Range;

use faer::sparse::linalg::cholesky::supernodal::{SupernodalLltRef, SymbolicSupernodalCholesky};
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};

/// How far ahead (in values, 16 KiB) the backward solve requests the blocks
/// it will read next. Measured when it was introduced (a local harness,
/// median of 61 solves) on the Bunny's reduced normal matrix
/// (3.3 M factor entries): without it the backward solve took 4.6 ms
/// against the forward's 2.7 ms; with 0, 1024, 2048, 4096 and 8192 values
/// ahead 3.5, 3.2, 3.2, 3.4 and 3.4 ms.
const PREFETCH_AHEAD: usize = 2048;

/// Right-hand-side columns solved together.
pub(super) const LANES: usize = 4;

/// The values of one unknown in the (up to) [`LANES`] right-hand sides of
/// a group.
pub(super) type Lane = [f64; LANES];

/// A supernodal factor's values with every supernode block row-major.
///
/// Invariant: for supernode `s` with `c` columns and `p` pattern rows, the
/// values `val_ptr[s] .. val_ptr[s+1]` hold the `(c + p) × c` block row by
/// row: rows `0..c` the diagonal block (lower triangle meaningful), rows
/// `c..c+p` the pattern rows in the order of the symbolic pattern.
pub(super) struct SupernodalRows;

impl SupernodalRows {
    /// Transposes faer's column-major supernode blocks in `values` to the
    /// row-major layout, in place (one temporary of the largest block).
    pub(super) fn transpose_in_place(symbolic: &SymbolicCholesky<usize>, values: &mut [f64]) {
        let SymbolicCholeskyRaw::Supernodal(s) = symbolic.raw() else {
            return;
        };
        let begin = s.supernode_begin();
        let end = s.supernode_end();
        let val_ptr = s.col_ptr_for_val();
        let mut tmp: Vec<f64> = Vec::new();
        for sn in 0..s.n_supernodes() {
            let c = end[sn] - begin[sn];
            let block = &mut values[val_ptr[sn]..val_ptr[sn + 1]];
            let rows = block.len() / c.max(1);
            tmp.clear();
            tmp.extend_from_slice(block);
            // 8 × 8 tiles: a tile's reads (8 columns of tmp) and writes (8
            // rows of the block) stay within 16 cache lines, instead of one
            // line per element for blocks larger than the cache.
            for i0 in (0..rows).step_by(8) {
                let i1 = (i0 + 8).min(rows);
                for j0 in (0..c).step_by(8) {
                    let j1 = (j0 + 8).min(c);
                    for i in i0..i1 {
                        for j in j0..j1 {
                            block[i * c + j] = tmp[j * rows + i];
                        }
                    }
                }
            }
        }
    }
}

/// The diagonal of `L` in permuted order (faer's column-major values).
pub(super) fn factor_diagonal(symbolic: &SymbolicCholesky<usize>, values: &[f64]) -> Vec<f64> {
    let n = symbolic.nrows();
    let mut diag = vec![0.0; n];
    match symbolic.raw() {
        SymbolicCholeskyRaw::Simplicial(s) => {
            let col_ptr = s.col_ptr();
            for (j, d) in diag.iter_mut().enumerate() {
                *d = values[col_ptr[j]];
            }
        }
        SymbolicCholeskyRaw::Supernodal(s) => {
            let l = SupernodalLltRef::new(s, values);
            for k in 0..s.n_supernodes() {
                let node = l.supernode(k);
                let (start, m) = (node.start(), node.val());
                for t in 0..m.ncols() {
                    diag[start + t] = m[(t, t)];
                }
            }
        }
    }
    diag
}

/// Lane-wise arithmetic on one unknown's group of right-hand sides: the
/// kernels below are written once over this trait and instantiated with
/// explicit AVX2 + FMA vectors where the CPU has them ([`Avx2`]) and with
/// plain arrays elsewhere. (Written over plain `[f64; 4]` alone, LLVM
/// re-vectorises the loops *across* unknowns, transposing lanes and
/// spilling registers: half the speed.)
trait LaneOps<const W: usize>: Copy {
    fn zero() -> Self;
    fn load(lane: &[f64; W]) -> Self;
    fn store(self, lane: &mut [f64; W]);
    /// `self + v x`.
    fn add_mul(self, v: f64, x: Self) -> Self;
    /// `self − v x`.
    fn sub_mul(self, v: f64, x: Self) -> Self;
    fn add(self, other: Self) -> Self;
    fn sub(self, other: Self) -> Self;
    fn scale(self, s: f64) -> Self;
    /// Hints that `values` will be read soon (no effect where unsupported).
    fn prefetch(values: &[f64]);
}

/// Portable lanes (separate multiply and add).
impl<const W: usize> LaneOps<W> for [f64; W] {
    #[inline(always)]
    fn zero() -> Self {
        [0.0; W]
    }
    #[inline(always)]
    fn load(lane: &[f64; W]) -> Self {
        *lane
    }
    #[inline(always)]
    fn store(self, lane: &mut [f64; W]) {
        *lane = self;
    }
    #[inline(always)]
    fn add_mul(self, v: f64, x: Self) -> Self {
        std::array::from_fn(|q| self[q] + v * x[q])
    }
    #[inline(always)]
    fn sub_mul(self, v: f64, x: Self) -> Self {
        std::array::from_fn(|q| self[q] - v * x[q])
    }
    #[inline(always)]
    fn add(self, other: Self) -> Self {
        std::array::from_fn(|q| self[q] + other[q])
    }
    #[inline(always)]
    fn sub(self, other: Self) -> Self {
        std::array::from_fn(|q| self[q] - other[q])
    }
    #[inline(always)]
    fn scale(self, s: f64) -> Self {
        std::array::from_fn(|q| self[q] * s)
    }
    #[inline(always)]
    fn prefetch(_: &[f64]) {}
}

/// One 256-bit AVX register per lane, fused multiply–adds.
///
/// Only constructed inside [`solve_lanes_avx2`] and the passes of
/// [`passes`], which run only after the CPU was found to support AVX2 and
/// FMA; every method is inlined there.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Avx2(std::arch::x86_64::__m256d);

/// Right-hand-side columns of a wide group ([`wide_passes`]).
pub(super) const WIDE_LANES: usize = 8;

/// The values of one unknown in a wide group.
pub(super) type WideLane = [f64; WIDE_LANES];

/// One 512-bit AVX-512 register per wide lane, fused multiply–adds.
///
/// Only constructed inside the passes of [`wide_passes`], which run only
/// after the CPU was found to support AVX-512F; every method is inlined
/// there.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Avx512(std::arch::x86_64::__m512d);

/// [`LaneOps`] for a vector type (a one-field tuple struct constructed only
/// where its instructions are available) from its intrinsics: set-zero,
/// load, store, broadcast, `a·b + c`, `−a·b + c`, add, subtract, multiply.
#[cfg(target_arch = "x86_64")]
macro_rules! vector_lanes {
    ($ty:ident, $w:expr, $zero:ident, $load:ident, $store:ident, $set1:ident,
     $fmadd:ident, $fnmadd:ident, $add:ident, $sub:ident, $mul:ident) => {
        impl LaneOps<{ $w }> for $ty {
            // SAFETY (every method): the type is only constructed where
            // the CPU has its instructions (see the type).
            #[inline(always)]
            fn zero() -> Self {
                unsafe { $ty(std::arch::x86_64::$zero()) }
            }
            #[inline(always)]
            fn load(lane: &[f64; $w]) -> Self {
                unsafe { $ty(std::arch::x86_64::$load(lane.as_ptr())) }
            }
            #[inline(always)]
            fn store(self, lane: &mut [f64; $w]) {
                unsafe { std::arch::x86_64::$store(lane.as_mut_ptr(), self.0) }
            }
            #[inline(always)]
            fn add_mul(self, v: f64, x: Self) -> Self {
                use std::arch::x86_64::{$fmadd, $set1};
                unsafe { $ty($fmadd($set1(v), x.0, self.0)) }
            }
            #[inline(always)]
            fn sub_mul(self, v: f64, x: Self) -> Self {
                use std::arch::x86_64::{$fnmadd, $set1};
                unsafe { $ty($fnmadd($set1(v), x.0, self.0)) }
            }
            #[inline(always)]
            fn add(self, other: Self) -> Self {
                unsafe { $ty(std::arch::x86_64::$add(self.0, other.0)) }
            }
            #[inline(always)]
            fn sub(self, other: Self) -> Self {
                unsafe { $ty(std::arch::x86_64::$sub(self.0, other.0)) }
            }
            #[inline(always)]
            fn scale(self, s: f64) -> Self {
                use std::arch::x86_64::{$mul, $set1};
                unsafe { $ty($mul(self.0, $set1(s))) }
            }
            #[inline(always)]
            fn prefetch(values: &[f64]) {
                use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
                for line in values.chunks(8) {
                    unsafe { _mm_prefetch::<_MM_HINT_T0>(line.as_ptr().cast()) };
                }
            }
        }
    };
}

#[cfg(target_arch = "x86_64")]
vector_lanes!(
    Avx2,
    LANES,
    _mm256_setzero_pd,
    _mm256_loadu_pd,
    _mm256_storeu_pd,
    _mm256_set1_pd,
    _mm256_fmadd_pd,
    _mm256_fnmadd_pd,
    _mm256_add_pd,
    _mm256_sub_pd,
    _mm256_mul_pd
);

#[cfg(target_arch = "x86_64")]
vector_lanes!(
    Avx512,
    WIDE_LANES,
    _mm512_setzero_pd,
    _mm512_loadu_pd,
    _mm512_storeu_pd,
    _mm512_set1_pd,
    _mm512_fmadd_pd,
    _mm512_fnmadd_pd,
    _mm512_add_pd,
    _mm512_sub_pd,
    _mm512_mul_pd
);

/// Whether the wide passes ([`wide_passes`]) run on vector registers as
/// wide as their lanes (AVX-512F). Elsewhere a wide group costs about twice
/// a group of [`LANES`] and two such groups on two threads are faster.
pub(super) fn wide_lanes_native() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// `L Lᵀ w = w` in place for one group of right-hand sides, `w[i]` the
/// lane of unknown `i` in the factor's (permuted) ordering. Supernodal
/// values must be in the [`SupernodalRows`] layout; `inv_diag[i] = 1 / L_ii`
/// (multiplications instead of divisions on the critical path). `scratch`
/// is resized as needed and reused.
pub(super) fn solve_lanes(
    symbolic: &SymbolicCholesky<usize>,
    values: &[f64],
    inv_diag: &[f64],
    w: &mut [Lane],
    scratch: &mut Vec<Lane>,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports the features the variant is compiled for.
        unsafe { solve_lanes_avx2(symbolic, values, inv_diag, w, scratch) };
        return;
    }
    solve_lanes_body::<LANES, Lane>(symbolic, values, inv_diag, w, scratch);
}

/// [`solve_lanes`] with [`Avx2`] lanes, compiled for AVX2 + FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn solve_lanes_avx2(
    symbolic: &SymbolicCholesky<usize>,
    values: &[f64],
    inv_diag: &[f64],
    w: &mut [Lane],
    scratch: &mut Vec<Lane>,
) {
    solve_lanes_body::<LANES, Avx2>(symbolic, values, inv_diag, w, scratch);
}

#[inline(always)]
fn solve_lanes_body<const W: usize, V: LaneOps<W>>(
    symbolic: &SymbolicCholesky<usize>,
    values: &[f64],
    inv_diag: &[f64],
    w: &mut [[f64; W]],
    scratch: &mut Vec<[f64; W]>,
) {
    match symbolic.raw() {
        SymbolicCholeskyRaw::Supernodal(s) => {
            let every = 0..s.n_supernodes();
            let all = std::slice::from_ref(&every);
            forward_pass::<W, V>(s, values, inv_diag, all, w);
            backward_pass::<W, V>(s, values, inv_diag, all, w, scratch);
        }
        SymbolicCholeskyRaw::Simplicial(s) => {
            let col_ptr = s.col_ptr();
            let rows = s.row_idx();
            let n = s.nrows();
            for j in 0..n {
                // Diagonal first (sorted rows, lower triangle).
                let (a, b) = (col_ptr[j], col_ptr[j + 1]);
                let xj = V::load(&w[j]).scale(inv_diag[j]);
                xj.store(&mut w[j]);
                for (&r, &v) in rows[a + 1..b].iter().zip(&values[a + 1..b]) {
                    V::load(&w[r]).sub_mul(v, xj).store(&mut w[r]);
                }
            }
            for j in (0..n).rev() {
                let (a, b) = (col_ptr[j], col_ptr[j + 1]);
                let mut acc = V::load(&w[j]);
                for (&r, &v) in rows[a + 1..b].iter().zip(&values[a + 1..b]) {
                    acc = acc.sub_mul(v, V::load(&w[r]));
                }
                acc.scale(inv_diag[j]).store(&mut w[j]);
            }
        }
    }
}

/// The forward solve `w ← L⁻¹ w` restricted to the supernodes in `ranges`
/// (ascending): each supernode's own rows are solved and its updates
/// subtracted from its pattern rows.
#[inline(always)]
fn forward_pass<const W: usize, V: LaneOps<W>>(
    s: &SymbolicSupernodalCholesky<usize>,
    values: &[f64],
    inv_diag: &[f64],
    ranges: &[Range<usize>],
    w: &mut [[f64; W]],
) {
    let (begin, end) = (s.supernode_begin(), s.supernode_end());
    let (rows, row_ptr, val_ptr) = (s.row_idx(), s.col_ptr_for_row_idx(), s.col_ptr_for_val());
    for sn in ranges.iter().flat_map(|r| r.clone()) {
        let (f, c) = (begin[sn], end[sn] - begin[sn]);
        let pattern = &rows[row_ptr[sn]..row_ptr[sn + 1]];
        let l = &values[val_ptr[sn]..val_ptr[sn + 1]];
        forward_supernode::<W, V>(l, f, c, pattern, inv_diag, w);
    }
}

/// The backward solve `w ← L⁻ᵀ w` restricted to the supernodes in `ranges`
/// (visited from the last to the first), reading the rows below them
/// (their ancestors') as already solved.
#[inline(always)]
fn backward_pass<const W: usize, V: LaneOps<W>>(
    s: &SymbolicSupernodalCholesky<usize>,
    values: &[f64],
    inv_diag: &[f64],
    ranges: &[Range<usize>],
    w: &mut [[f64; W]],
    scratch: &mut Vec<[f64; W]>,
) {
    let (begin, end) = (s.supernode_begin(), s.supernode_end());
    let (rows, row_ptr, val_ptr) = (s.row_idx(), s.col_ptr_for_row_idx(), s.col_ptr_for_val());
    let widest = (0..s.n_supernodes())
        .map(|k| end[k] - begin[k])
        .max()
        .unwrap_or(0);
    if scratch.len() < widest {
        scratch.resize(widest, [0.0; W]);
    }
    for range in ranges.iter().rev() {
        // The blocks are visited from the last to the first: the hardware
        // prefetcher follows ascending streams only, so the values ahead
        // are requested explicitly, PREFETCH_AHEAD values below the
        // current block (within the range: the values of a range of
        // supernodes are contiguous).
        let mut requested = val_ptr[range.end];
        for sn in range.clone().rev() {
            let (f, c) = (begin[sn], end[sn] - begin[sn]);
            let pattern = &rows[row_ptr[sn]..row_ptr[sn + 1]];
            let l = &values[val_ptr[sn]..val_ptr[sn + 1]];
            let from = val_ptr[sn]
                .saturating_sub(PREFETCH_AHEAD)
                .max(val_ptr[range.start]);
            if from < requested {
                V::prefetch(&values[from..requested]);
                requested = from;
            }
            backward_supernode::<W, V>(l, f, c, pattern, inv_diag, w, scratch);
        }
    }
}

/// A forward pass ([`Passes::forward`]).
type ForwardPass<const W: usize> =
    unsafe fn(&SymbolicSupernodalCholesky<usize>, &[f64], &[f64], &[Range<usize>], &mut [[f64; W]]);

/// A backward pass ([`Passes::backward`]).
type BackwardPass<const W: usize> = unsafe fn(
    &SymbolicSupernodalCholesky<usize>,
    &[f64],
    &[f64],
    &[Range<usize>],
    &mut [[f64; W]],
    &mut Vec<[f64; W]>,
);

/// The supernodal forward and backward passes for lanes of `W` columns,
/// compiled for the vectors this CPU has ([`passes`], [`wide_passes`]):
/// what a solve split over the elimination tree
/// ([`super::tree_split::TreeSplit`]) runs on each part.
#[derive(Clone, Copy)]
pub(super) struct Passes<const W: usize> {
    /// Invariant: only functions whose target features the CPU has.
    forward: ForwardPass<W>,
    backward: BackwardPass<W>,
}

impl<const W: usize> Passes<W> {
    /// [`forward_pass`] over `ranges`.
    pub(super) fn forward(
        &self,
        s: &SymbolicSupernodalCholesky<usize>,
        values: &[f64],
        inv_diag: &[f64],
        ranges: &[Range<usize>],
        w: &mut [[f64; W]],
    ) {
        // SAFETY: the CPU has the pass's target features (invariant).
        unsafe { (self.forward)(s, values, inv_diag, ranges, w) }
    }

    /// [`backward_pass`] over `ranges`.
    pub(super) fn backward(
        &self,
        s: &SymbolicSupernodalCholesky<usize>,
        values: &[f64],
        inv_diag: &[f64],
        ranges: &[Range<usize>],
        w: &mut [[f64; W]],
        scratch: &mut Vec<[f64; W]>,
    ) {
        // SAFETY: the CPU has the pass's target features (invariant).
        unsafe { (self.backward)(s, values, inv_diag, ranges, w, scratch) }
    }
}

/// [`Passes`] over lanes of `$w` columns with the vector type `$v`,
/// compiled for the target features `$features` (which the caller has
/// checked the CPU has).
#[cfg(target_arch = "x86_64")]
macro_rules! compiled_passes {
    ($w:expr, $v:ty, $features:literal) => {{
        #[target_feature(enable = $features)]
        unsafe fn forward(
            s: &SymbolicSupernodalCholesky<usize>,
            values: &[f64],
            inv_diag: &[f64],
            ranges: &[Range<usize>],
            w: &mut [[f64; $w]],
        ) {
            forward_pass::<{ $w }, $v>(s, values, inv_diag, ranges, w);
        }
        #[target_feature(enable = $features)]
        unsafe fn backward(
            s: &SymbolicSupernodalCholesky<usize>,
            values: &[f64],
            inv_diag: &[f64],
            ranges: &[Range<usize>],
            w: &mut [[f64; $w]],
            scratch: &mut Vec<[f64; $w]>,
        ) {
            backward_pass::<{ $w }, $v>(s, values, inv_diag, ranges, w, scratch);
        }
        Passes { forward, backward }
    }};
}

/// The passes for groups of [`LANES`] columns.
pub(super) fn passes() -> Passes<LANES> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        return compiled_passes!(LANES, Avx2, "avx2,fma");
    }
    Passes {
        forward: forward_pass::<LANES, Lane>,
        backward: backward_pass::<LANES, Lane>,
    }
}

/// The passes for groups of [`WIDE_LANES`] columns.
pub(super) fn wide_passes() -> Passes<WIDE_LANES> {
    #[cfg(target_arch = "x86_64")]
    if wide_lanes_native() {
        return compiled_passes!(WIDE_LANES, Avx512, "avx512f");
    }
    Passes {
        forward: forward_pass::<WIDE_LANES, WideLane>,
        backward: backward_pass::<WIDE_LANES, WideLane>,
    }
}

/// `Σ_j row[j] x[j]` with four independent partial sums (so that the
/// multiply–adds overlap instead of waiting on each other).
#[inline(always)]
fn dot_lanes<const W: usize, V: LaneOps<W>>(row: &[f64], x: &[[f64; W]]) -> V {
    let mut s = [V::zero(); 4];
    let mut rc = row.chunks_exact(4);
    let mut xc = x.chunks_exact(4);
    for (r, xs) in (&mut rc).zip(&mut xc) {
        for u in 0..4 {
            s[u] = s[u].add_mul(r[u], V::load(&xs[u]));
        }
    }
    for (&v, xj) in rc.remainder().iter().zip(xc.remainder()) {
        s[0] = s[0].add_mul(v, V::load(xj));
    }
    s[0].add(s[1]).add(s[2].add(s[3]))
}

/// One supernode of the forward solve (`l` row-major, `c` columns).
#[inline(always)]
fn forward_supernode<const W: usize, V: LaneOps<W>>(
    l: &[f64],
    f: usize,
    c: usize,
    pattern: &[usize],
    inv_diag: &[f64],
    w: &mut [[f64; W]],
) {
    // x_s ← L_ss⁻¹ w_s, row by row: x_i = (w_i − Σ_{j<i} L_ij x_j) / L_ii,
    // in place in w[f..f+c].
    for i in 0..c {
        let row = &l[i * c..i * c + i];
        let s = dot_lanes::<W, V>(row, &w[f..f + i]);
        V::load(&w[f + i])
            .sub(s)
            .scale(inv_diag[f + i])
            .store(&mut w[f + i]);
    }
    let (head, tail) = w.split_at_mut(f + c);
    let xs: &[[f64; W]] = &head[f..];
    // Pattern rows lie after the supernode in the ordering: all in `tail`.
    let off = l.get(c * c..).unwrap_or(&[]);
    let mut rows4 = pattern.chunks_exact(4);
    let mut vals4 = off.chunks_exact(4 * c.max(1));
    for (r, v) in (&mut rows4).zip(&mut vals4) {
        // Four rows at once, two partial sums each (even and odd j).
        let (v0, v1, v2, v3) = (&v[..c], &v[c..2 * c], &v[2 * c..3 * c], &v[3 * c..]);
        let mut s = [V::zero(); 8];
        let mut j = 0;
        while j + 1 < c {
            let (xa, xb) = (V::load(&xs[j]), V::load(&xs[j + 1]));
            s[0] = s[0].add_mul(v0[j], xa);
            s[1] = s[1].add_mul(v1[j], xa);
            s[2] = s[2].add_mul(v2[j], xa);
            s[3] = s[3].add_mul(v3[j], xa);
            s[4] = s[4].add_mul(v0[j + 1], xb);
            s[5] = s[5].add_mul(v1[j + 1], xb);
            s[6] = s[6].add_mul(v2[j + 1], xb);
            s[7] = s[7].add_mul(v3[j + 1], xb);
            j += 2;
        }
        if j < c {
            let xa = V::load(&xs[j]);
            s[0] = s[0].add_mul(v0[j], xa);
            s[1] = s[1].add_mul(v1[j], xa);
            s[2] = s[2].add_mul(v2[j], xa);
            s[3] = s[3].add_mul(v3[j], xa);
        }
        for u in 0..4 {
            let t = &mut tail[r[u] - f - c];
            V::load(t).sub(s[u].add(s[u + 4])).store(t);
        }
    }
    for (&r, v) in rows4
        .remainder()
        .iter()
        .zip(vals4.remainder().chunks_exact(c.max(1)))
    {
        let t = &mut tail[r - f - c];
        V::load(t).sub(dot_lanes::<W, V>(v, xs)).store(t);
    }
}

/// `Σ_t rows[t·c + j0 + q] x[t]` for `q < M` and `t < x.len()`: `M`
/// columns of a row-major block (row stride `c`) against one lane per row,
/// the `M` sums held in registers across all rows.
#[inline(always)]
fn column_sums<const W: usize, V: LaneOps<W>, const M: usize>(
    rows: &[f64],
    c: usize,
    j0: usize,
    x: &[[f64; W]],
) -> [V; M] {
    let mut acc = [V::zero(); M];
    for (t, xt) in x.iter().enumerate() {
        let xt = V::load(xt);
        let v = &rows[t * c + j0..t * c + j0 + M];
        for q in 0..M {
            acc[q] = acc[q].add_mul(v[q], xt);
        }
    }
    acc
}

/// Columns `[j0, j0 + M)` of the backward solve of one supernode's diagonal
/// block, once the pattern rows are subtracted and the columns after the
/// block are solved: `v = w_B − L_{D,B}ᵀ x_D` (`D` the supernode's own rows
/// after the block), then `x_B = L_BB⁻ᵀ v` by the small `M × M` triangle.
#[inline(always)]
fn backward_block<const W: usize, V: LaneOps<W>, const M: usize>(
    l: &[f64],
    f: usize,
    c: usize,
    j0: usize,
    inv_diag: &[f64],
    w: &mut [[f64; W]],
) {
    let j1 = j0 + M;
    let below = column_sums::<W, V, M>(&l[j1 * c..c * c], c, j0, &w[f + j1..f + c]);
    let mut v = [V::zero(); M];
    for q in 0..M {
        v[q] = V::load(&w[f + j0 + q]).sub(below[q]);
    }
    for i in (0..M).rev() {
        let mut x = v[i];
        for j in i + 1..M {
            x = x.sub_mul(l[(j0 + j) * c + j0 + i], v[j]);
        }
        v[i] = x.scale(inv_diag[f + j0 + i]);
    }
    for q in 0..M {
        v[q].store(&mut w[f + j0 + q]);
    }
}

/// One supernode of the backward solve (`l` row-major, `c` columns).
///
/// First `w_s −= L_{P,s}ᵀ w_P`: the pattern rows four at a time, each
/// group read front to back (contiguous rows, which the hardware
/// prefetcher streams), accumulated into `acc` (`c` lanes, in L1). Then the
/// diagonal block by blocks of eight columns from the last to the first,
/// the first block holding the `c mod 8` leftover columns.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn backward_supernode<const W: usize, V: LaneOps<W>>(
    l: &[f64],
    f: usize,
    c: usize,
    pattern: &[usize],
    inv_diag: &[f64],
    w: &mut [[f64; W]],
    acc: &mut [[f64; W]],
) {
    if !pattern.is_empty() {
        let acc = &mut acc[..c];
        acc.fill([0.0; W]);
        let off = &l[c * c..];
        let mut rows4 = pattern.chunks_exact(4);
        let mut vals4 = off.chunks_exact(4 * c);
        for (r, v) in (&mut rows4).zip(&mut vals4) {
            let (wa, wb) = (V::load(&w[r[0]]), V::load(&w[r[1]]));
            let (wc, wd) = (V::load(&w[r[2]]), V::load(&w[r[3]]));
            let (v0, v1, v2, v3) = (&v[..c], &v[c..2 * c], &v[2 * c..3 * c], &v[3 * c..]);
            for (j, a) in acc.iter_mut().enumerate() {
                let x = V::load(a).add_mul(v0[j], wa).add_mul(v1[j], wb);
                x.add_mul(v2[j], wc).add_mul(v3[j], wd).store(a);
            }
        }
        for (&r, v) in rows4
            .remainder()
            .iter()
            .zip(vals4.remainder().chunks_exact(c))
        {
            let wr = V::load(&w[r]);
            for (a, &vj) in acc.iter_mut().zip(v) {
                V::load(a).add_mul(vj, wr).store(a);
            }
        }
        for (x, a) in w[f..f + c].iter_mut().zip(acc.iter()) {
            V::load(x).sub(V::load(a)).store(x);
        }
    }
    let mut j0 = c;
    while j0 >= 8 {
        j0 -= 8;
        backward_block::<W, V, 8>(l, f, c, j0, inv_diag, w);
    }
    match c % 8 {
        1 => backward_block::<W, V, 1>(l, f, c, 0, inv_diag, w),
        2 => backward_block::<W, V, 2>(l, f, c, 0, inv_diag, w),
        3 => backward_block::<W, V, 3>(l, f, c, 0, inv_diag, w),
        4 => backward_block::<W, V, 4>(l, f, c, 0, inv_diag, w),
        5 => backward_block::<W, V, 5>(l, f, c, 0, inv_diag, w),
        6 => backward_block::<W, V, 6>(l, f, c, 0, inv_diag, w),
        7 => backward_block::<W, V, 7>(l, f, c, 0, inv_diag, w),
        _ => {}
    }
}

#[cfg(test)]
mod tests;
