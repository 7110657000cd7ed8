//! The Givens merge-and-rotate kernel shared by the sparse QR paths.
//!
//! Two sorted sparse vectors `x` and `y` (index lists strictly increasing)
//! are merged by index and rotated entry by entry:
//! `u = c x + s y`, `v = −s x + c y`, a missing entry counting as `0`.
//! Exact zeros of `u` and `v` are dropped; no other entry is, and every
//! surviving entry is computed by exactly the two products and one sum above,
//! so the result is bit-identical to rotating the dense vectors.

/// A sorted sparse vector borrowed as (indices, values).
pub(super) type SparseRef<'a> = (&'a [usize], &'a [f64]);

/// A sparse vector being built, as (indices, values).
pub(super) type SparseOut<'a> = (&'a mut Vec<usize>, &'a mut Vec<f64>);

/// Appends the nonzero entries of `c x + s y` to `u` and of `−s x + c y` to
/// `v`, in increasing index order. Entries already in `u` and `v` are kept,
/// so a caller may push leading entries first; they must have smaller
/// indices than any of `x` or `y` for the outputs to stay sorted.
pub(super) fn rotate_merge(x: SparseRef, y: SparseRef, c: f64, s: f64, u: SparseOut, v: SparseOut) {
    let ((xi, xv), (yi, yv)) = (x, y);
    let (mut i, mut k) = (0, 0);
    while i < xi.len() || k < yi.len() {
        let ri = xi.get(i).copied().unwrap_or(usize::MAX);
        let rk = yi.get(k).copied().unwrap_or(usize::MAX);
        let (idx, a, b) = if ri < rk {
            i += 1;
            (ri, xv[i - 1], 0.0)
        } else if rk < ri {
            k += 1;
            (rk, 0.0, yv[k - 1])
        } else {
            i += 1;
            k += 1;
            (ri, xv[i - 1], yv[k - 1])
        };
        let p = c * a + s * b;
        let q = -s * a + c * b;
        if p != 0.0 {
            u.0.push(idx);
            u.1.push(p);
        }
        if q != 0.0 {
            v.0.push(idx);
            v.1.push(q);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merges_disjoint_and_shared_indices_and_drops_exact_zeros() {
        // x = [1 at 0, 2 at 2], y = [3 at 1, 2 at 2]; c = s = 1 (not a true
        // rotation, but the kernel is linear, which is what is checked).
        let (x_i, x_v) = (vec![0, 2], vec![1.0, 2.0]);
        let (y_i, y_v) = (vec![1, 2], vec![3.0, 2.0]);
        let (mut ui, mut uv, mut vi, mut vv) = (vec![], vec![], vec![], vec![]);
        rotate_merge(
            (&x_i, &x_v),
            (&y_i, &y_v),
            1.0,
            1.0,
            (&mut ui, &mut uv),
            (&mut vi, &mut vv),
        );
        // u = x + y = [1, 3, 4]; v = y − x = [−1, 3, 0] with the 0 dropped.
        assert_eq!((ui, uv), (vec![0, 1, 2], vec![1.0, 3.0, 4.0]));
        assert_eq!((vi, vv), (vec![0, 1], vec![-1.0, 3.0]));
    }
}
