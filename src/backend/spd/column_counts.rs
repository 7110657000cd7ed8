//! The column counts of a Cholesky factor from the pattern of the matrix
//! alone, before the factor exists: what a back end that cannot bound its
//! own symbolic phase (nalgebra's builds the whole pattern of `L`) is
//! sized by before the budget admits it. A leaf: it imports no back end.

/// The number of entries of each column of the Cholesky factor `L` (the
/// diagonal included) of a symmetric matrix with the full (both
/// triangles), sorted, square CSC pattern `col_ptr`/`rows` in which every
/// diagonal entry is present: `nnz(L) = Σ` of them, before `L` exists.
///
/// Gilbert, Ng and Peyton's algorithm ("An efficient algorithm to compute
/// row and column counts for sparse Cholesky factorization", SIAM J.
/// Matrix Anal. Appl. 15 (1994); CSparse's `cs_counts`, Davis, *Direct
/// Methods for Sparse Linear Systems*, §4.5): the elimination tree by
/// Liu's algorithm with path compression, its postorder, then for each
/// column `j` in postorder and each `i > j` of its pattern, whether `j` is
/// a leaf of row `i`'s subtree, found with the first descendants and a
/// disjoint-set forest of least common ancestors. Entry `L_ij` is nonzero
/// exactly when `j` lies in that subtree, so the counts are exact (no
/// numerical cancellation is assumed, as in every symbolic factorisation,
/// nalgebra's included). Time `O(nnz(A) α(n))`, memory `O(n)` besides
/// the counts.
pub(crate) fn factor_column_counts(col_ptr: &[usize], rows: &[usize]) -> Vec<usize> {
    const NONE: usize = usize::MAX;
    let n = col_ptr.len().saturating_sub(1);
    let column = |j: usize| rows[col_ptr[j]..col_ptr[j + 1]].iter().copied();
    let parent = elimination_tree(n, column);
    let post = postorder(&parent);
    // first[j]: the first postorder index of j's subtree; delta[j] ends
    // as j's count minus its children's.
    let mut first = vec![NONE; n];
    let mut delta = vec![0isize; n];
    for (k, &j) in post.iter().enumerate() {
        delta[j] = isize::from(first[j] == NONE);
        let mut a = j;
        while a != NONE && first[a] == NONE {
            first[a] = k;
            a = parent[a];
        }
    }
    let mut max_first = vec![NONE; n];
    let mut prev_leaf = vec![NONE; n];
    let mut ancestor: Vec<usize> = (0..n).collect();
    for &j in &post {
        if parent[j] != NONE {
            delta[parent[j]] -= 1;
        }
        for i in column(j).filter(|&i| i > j) {
            // Is j a leaf of row i's subtree (its first descendant past
            // the last leaf seen)?
            if max_first[i] != NONE && first[j] <= max_first[i] {
                continue;
            }
            max_first[i] = first[j];
            let previous = std::mem::replace(&mut prev_leaf[i], j);
            delta[j] += 1;
            if previous != NONE {
                // Not the first leaf: the least common ancestor of the
                // previous leaf and j is counted twice.
                let mut q = previous;
                while q != ancestor[q] {
                    q = ancestor[q];
                }
                let mut s = previous;
                while s != q {
                    let up = ancestor[s];
                    ancestor[s] = q;
                    s = up;
                }
                delta[q] -= 1;
            }
        }
        if parent[j] != NONE {
            ancestor[j] = parent[j];
        }
    }
    // Children come before parents (parent[j] > j).
    for j in 0..n {
        if parent[j] != NONE {
            delta[parent[j]] += delta[j];
        }
    }
    delta.into_iter().map(|d| d.max(0).unsigned_abs()).collect()
}

/// The elimination tree of a symmetric matrix of dimension `n` whose
/// column `k` has rows `column(k)` (Liu's algorithm with path
/// compression, reading the entries above the diagonal): `parent[j]`, or
/// `usize::MAX` for a root.
fn elimination_tree<I: Iterator<Item = usize>>(
    n: usize,
    column: impl Fn(usize) -> I,
) -> Vec<usize> {
    const NONE: usize = usize::MAX;
    let mut parent = vec![NONE; n];
    let mut ancestor = vec![NONE; n];
    for k in 0..n {
        for mut i in column(k) {
            while i != NONE && i < k {
                let next = ancestor[i];
                ancestor[i] = k;
                if next == NONE {
                    parent[i] = k;
                }
                i = next;
            }
        }
    }
    parent
}

/// A postorder of the forest `parent` (`usize::MAX` for a root): every
/// node after its descendants, each subtree contiguous.
fn postorder(parent: &[usize]) -> Vec<usize> {
    const NONE: usize = usize::MAX;
    let n = parent.len();
    let mut head = vec![NONE; n];
    let mut next = vec![NONE; n];
    for j in (0..n).rev() {
        if parent[j] != NONE {
            next[j] = head[parent[j]];
            head[parent[j]] = j;
        }
    }
    let mut post = Vec::with_capacity(n);
    let mut stack = Vec::new();
    for root in (0..n).filter(|&j| parent[j] == NONE) {
        stack.push(root);
        while let Some(&p) = stack.last() {
            let child = head[p];
            if child == NONE {
                stack.pop();
                post.push(p);
            } else {
                head[p] = next[child];
                stack.push(child);
            }
        }
    }
    post
}
