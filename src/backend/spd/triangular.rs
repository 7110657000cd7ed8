//! Triangular solves `L Lᵀ x = b` with a faer Cholesky factor, written for
//! the few-right-hand-side case of mesh deformation (three coordinates).
//!
//! faer's own solve handles any number of right-hand sides through generic
//! dense kernels per supernode; with three columns and the many small
//! supernodes of a surface mesh's normal matrix its per-supernode overhead
//! dominates. Here:
//!
//! - every supernode's block (`c` diagonal rows then `p` pattern rows, `c`
//!   columns) is stored **row-major** ([`SupernodalRows`], transposed once
//!   after the numeric factorisation), so a row of `L` restricted to a
//!   supernode is contiguous;
//! - the right-hand sides are interleaved (`w[K i + k]`) so that each
//!   pattern row's `K` values are one cache line;
//! - forward, supernode `s` with columns `[f, f + c)` and pattern rows `P`:
//!   `x_s ← L_ss⁻¹ w_s` (row-oriented), then for every `r ∈ P`:
//!   `w_r −= L_{r,s} · x_s` — `K` dot products of length `c`;
//! - backward, supernodes in reverse: `a = Σ_{r∈P} L_{r,s}ᵀ w_r` — `K` axpys
//!   of length `c` per row — then `x_s ← L_ss⁻ᵀ (w_s − a)`.
//!
//! Every entry of `L` is read once per direction and used for all `K`
//! coordinates, and the inner loops run over contiguous rows of length `c`
//! (SIMD-friendly). A simplicial factor is solved column by column.

use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};

/// Lanes of the hand-unrolled reductions (one AVX2 vector of `f64`).
const LANES: usize = 4;

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
            for j in 0..c {
                for i in 0..rows {
                    block[i * c + j] = tmp[j * rows + i];
                }
            }
        }
    }
}

/// `L Lᵀ w = w` in place, `w` interleaved with `K` values per unknown, in
/// the factor's (permuted) ordering. Supernodal values must be in the
/// [`SupernodalRows`] layout; `scratch` is resized as needed and reused.
pub(super) fn solve_interleaved<const K: usize>(
    symbolic: &SymbolicCholesky<usize>,
    values: &[f64],
    w: &mut [f64],
    scratch: &mut Vec<f64>,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports the features the variant is compiled for.
        unsafe { solve_interleaved_avx2::<K>(symbolic, values, w, scratch) };
        return;
    }
    solve_interleaved_body::<K>(symbolic, values, w, scratch);
}

/// [`solve_interleaved`] compiled for AVX2 + FMA (the default x86-64
/// target has only SSE2; the kernels are the same source).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn solve_interleaved_avx2<const K: usize>(
    symbolic: &SymbolicCholesky<usize>,
    values: &[f64],
    w: &mut [f64],
    scratch: &mut Vec<f64>,
) {
    solve_interleaved_body::<K>(symbolic, values, w, scratch);
}

#[inline(always)]
fn solve_interleaved_body<const K: usize>(
    symbolic: &SymbolicCholesky<usize>,
    values: &[f64],
    w: &mut [f64],
    scratch: &mut Vec<f64>,
) {
    match symbolic.raw() {
        SymbolicCholeskyRaw::Supernodal(s) => {
            let begin = s.supernode_begin();
            let end = s.supernode_end();
            let rows = s.row_idx();
            let row_ptr = s.col_ptr_for_row_idx();
            let val_ptr = s.col_ptr_for_val();
            let n_super = s.n_supernodes();
            let max_c = (0..n_super).map(|k| end[k] - begin[k]).max().unwrap_or(0);
            // x_s de-interleaved (K × c, padded) and the backward sums.
            let stride = max_c.div_ceil(LANES) * LANES;
            if scratch.len() < 2 * K * stride {
                scratch.resize(2 * K * stride, 0.0);
            }
            let (xs, acc) = scratch.split_at_mut(K * stride);
            for sn in 0..n_super {
                let (f, c) = (begin[sn], end[sn] - begin[sn]);
                let pattern = &rows[row_ptr[sn]..row_ptr[sn + 1]];
                let l = &values[val_ptr[sn]..val_ptr[sn + 1]];
                forward_supernode::<K>(l, f, c, pattern, w, xs, stride);
            }
            for sn in (0..n_super).rev() {
                let (f, c) = (begin[sn], end[sn] - begin[sn]);
                let pattern = &rows[row_ptr[sn]..row_ptr[sn + 1]];
                let l = &values[val_ptr[sn]..val_ptr[sn + 1]];
                backward_supernode::<K>(l, f, c, pattern, w, xs, acc, stride);
            }
        }
        SymbolicCholeskyRaw::Simplicial(s) => {
            let col_ptr = s.col_ptr();
            let rows = s.row_idx();
            let n = s.nrows();
            for j in 0..n {
                let (a, b) = (col_ptr[j], col_ptr[j + 1]);
                // Diagonal first (sorted rows, lower triangle).
                let mut xj = load::<K>(w, j);
                let inv = 1.0 / values[a];
                for v in xj.iter_mut() {
                    *v *= inv;
                }
                store::<K>(w, j, xj);
                for (&r, &v) in rows[a + 1..b].iter().zip(&values[a + 1..b]) {
                    let mut xr = load::<K>(w, r);
                    for k in 0..K {
                        xr[k] -= v * xj[k];
                    }
                    store::<K>(w, r, xr);
                }
            }
            for j in (0..n).rev() {
                let (a, b) = (col_ptr[j], col_ptr[j + 1]);
                let mut acc = load::<K>(w, j);
                for (&r, &v) in rows[a + 1..b].iter().zip(&values[a + 1..b]) {
                    let xr = load::<K>(w, r);
                    for k in 0..K {
                        acc[k] -= v * xr[k];
                    }
                }
                let inv = 1.0 / values[a];
                for v in acc.iter_mut() {
                    *v *= inv;
                }
                store::<K>(w, j, acc);
            }
        }
    }
}

#[inline(always)]
fn load<const K: usize>(w: &[f64], i: usize) -> [f64; K] {
    let mut x = [0.0; K];
    x.copy_from_slice(&w[K * i..K * i + K]);
    x
}

#[inline(always)]
fn store<const K: usize>(w: &mut [f64], i: usize, x: [f64; K]) {
    w[K * i..K * i + K].copy_from_slice(&x);
}

/// `Σ_j a[j] x[j]` with `LANES` independent partial sums (so the compiler
/// can vectorise the reduction); `a` and `x` have equal length.
#[inline(always)]
fn dot(a: &[f64], x: &[f64]) -> f64 {
    let mut s = [0.0; LANES];
    let mut ca = a.chunks_exact(LANES);
    let mut cx = x.chunks_exact(LANES);
    for (pa, px) in (&mut ca).zip(&mut cx) {
        for q in 0..LANES {
            s[q] += pa[q] * px[q];
        }
    }
    let mut tail = 0.0;
    for (u, v) in ca.remainder().iter().zip(cx.remainder()) {
        tail += u * v;
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

/// `[Σ_j a[j] x_k[j]]_k` for the `K` vectors `x_k = xs[k·stride ..][..len]`,
/// reading `a` once, with `LANES` partial sums per vector.
#[inline(always)]
fn dot_k<const K: usize>(a: &[f64], xs: &[f64], stride: usize) -> [f64; K] {
    let len = a.len();
    let mut s = [[0.0; LANES]; K];
    let full = len / LANES * LANES;
    let mut j = 0;
    while j < full {
        let pa = &a[j..j + LANES];
        for k in 0..K {
            let px = &xs[k * stride + j..k * stride + j + LANES];
            for q in 0..LANES {
                s[k][q] += pa[q] * px[q];
            }
        }
        j += LANES;
    }
    let mut out = [0.0; K];
    for k in 0..K {
        let mut tail = 0.0;
        for jj in full..len {
            tail += a[jj] * xs[k * stride + jj];
        }
        out[k] = (s[k][0] + s[k][1]) + (s[k][2] + s[k][3]) + tail;
    }
    out
}

/// `y_k += α_k a` for the `K` vectors `y_k = ys[k·stride ..][..a.len()]`,
/// reading `a` once.
#[inline(always)]
fn axpy_k<const K: usize>(alpha: [f64; K], a: &[f64], ys: &mut [f64], stride: usize) {
    let len = a.len();
    for (j, &av) in a.iter().enumerate().take(len) {
        for k in 0..K {
            ys[k * stride + j] += alpha[k] * av;
        }
    }
}

/// `y += α a` over equal-length slices.
#[inline(always)]
fn axpy(alpha: f64, a: &[f64], y: &mut [f64]) {
    for (yv, &av) in y.iter_mut().zip(a) {
        *yv += alpha * av;
    }
}

/// One supernode of the forward solve (`l` row-major, `c` columns).
#[inline(always)]
fn forward_supernode<const K: usize>(
    l: &[f64],
    f: usize,
    c: usize,
    pattern: &[usize],
    w: &mut [f64],
    xs: &mut [f64],
    stride: usize,
) {
    // x_s ← L_ss⁻¹ w_s, row by row: x_i = (w_i − Σ_{j<i} L_ij x_j) / L_ii.
    for i in 0..c {
        let row = &l[i * c..i * c + i + 1];
        let wi = load::<K>(w, f + i);
        for k in 0..K {
            let xk = &mut xs[k * stride..k * stride + c];
            let s = dot(&row[..i], &xk[..i]);
            xk[i] = (wi[k] - s) / row[i];
        }
    }
    for i in 0..c {
        let mut xi = [0.0; K];
        for k in 0..K {
            xi[k] = xs[k * stride + i];
        }
        store::<K>(w, f + i, xi);
    }
    // w_r −= L_{r,s} · x_s for every pattern row.
    for (t, &r) in pattern.iter().enumerate() {
        let row = &l[(c + t) * c..(c + t + 1) * c];
        let mut wr = load::<K>(w, r);
        let d = dot_k::<K>(row, xs, stride);
        for k in 0..K {
            wr[k] -= d[k];
        }
        store::<K>(w, r, wr);
    }
}

/// One supernode of the backward solve (`l` row-major, `c` columns).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn backward_supernode<const K: usize>(
    l: &[f64],
    f: usize,
    c: usize,
    pattern: &[usize],
    w: &mut [f64],
    xs: &mut [f64],
    acc: &mut [f64],
    stride: usize,
) {
    for k in 0..K {
        acc[k * stride..k * stride + c].fill(0.0);
    }
    // a = Σ_{r∈P} L_{r,s}ᵀ w_r.
    for (t, &r) in pattern.iter().enumerate() {
        let row = &l[(c + t) * c..(c + t + 1) * c];
        let wr = load::<K>(w, r);
        axpy_k::<K>(wr, row, acc, stride);
    }
    for i in 0..c {
        let wi = load::<K>(w, f + i);
        for k in 0..K {
            xs[k * stride + i] = wi[k] - acc[k * stride + i];
        }
    }
    // x_s ← L_ss⁻ᵀ x_s: for i = c−1 … 0, x_i /= L_ii, then x_j −= L_ij x_i
    // for j < i (row i of L_ss is contiguous).
    for i in (0..c).rev() {
        let row = &l[i * c..i * c + i + 1];
        for k in 0..K {
            let xk = &mut xs[k * stride..k * stride + c];
            xk[i] /= row[i];
            let xi = xk[i];
            axpy(-xi, &row[..i], &mut xk[..i]);
        }
    }
    for i in 0..c {
        let mut xi = [0.0; K];
        for k in 0..K {
            xi[k] = xs[k * stride + i];
        }
        store::<K>(w, f + i, xi);
    }
}
