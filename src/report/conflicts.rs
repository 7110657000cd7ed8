//! Warnings for the conflicting hard constraints of a report: which
//! constraint was dropped, by how much the solution misses it, and which
//! earlier constraints it contradicts, where a small search finds them.
//!
//! A skipped row `b_k` of `B` is (to the rank tolerance) a combination
//! `Σ α_s b_s` of earlier kept rows. The rows with `α_s ≠ 0` are the
//! constraints it conflicts with. They are found locally: start from the
//! kept rows before `k` that share an unknown with `b_k`, solve the small
//! dense least-squares problem `min ‖Σ α_s b_s − b_k‖`, and while the
//! remainder is not negligible widen the set by the kept rows sharing an
//! unknown with it (a chain of relative constraints, a face built from
//! edges). A search that grows past [`MAX_ROWS`] rows or
//! [`MAX_ROUNDS`] rounds gives up: the warning then says "earlier
//! constraints" without naming them.

use std::collections::HashMap;

use faer::Mat;
use faer::linalg::solvers::SolveLstsq;

use super::{Warning, WarningKind, WarningSubject};
use crate::problem::{LseProblem, RowPlace};

/// How many conflicting constraints the warnings name one by one; the rest
/// are counted in one more warning (all are in
/// [`Report::conflicting`](crate::report::Report::conflicting)).
pub const CONFLICT_WARNINGS_SHOWN: usize = 10;

/// The most kept rows a search for the sources of a conflict looks at.
const MAX_ROWS: usize = 200;

/// The most times a search widens its set of rows.
const MAX_ROUNDS: usize = 32;

/// A combination of kept rows whose remainder is at most this times
/// `‖b_k‖` explains row `k`: three times the rank tolerance `η = 1e-10`
/// below which row `k` was skipped (sparse Givens may skip a remainder of
/// up to `√k η` spread over `k` entries), and well below the remainder of
/// a kept row (it was kept because it exceeds `η`), so that a nearly
/// parallel kept row does not stand in for the one row `k` repeats.
const EXPLAINED: f64 = 3e-10;

/// A kept row whose share `|α_s| ‖b_s‖` of the combination is below this
/// times `‖b_k‖` is dropped at once (if the rest still explain row `k`);
/// the others are dropped one at a time while they can be.
const NEGLIGIBLE_SHARE: f64 = 1e-12;

/// The most rows dropped one at a time (each a least-squares solve).
const MAX_PRUNED: usize = 24;

/// The sources of the conflicting constraints of one factorisation, found
/// on demand and kept (they depend only on `B` and the skipped rows, not
/// on the right-hand sides, so a drag loop does not search again).
#[derive(Debug, Clone, Default)]
pub struct ConflictSources {
    skipped: Vec<usize>,
    /// Unknown → the kept rows touching it (increasing), built on first use.
    touching: Option<HashMap<usize, Vec<usize>>>,
    found: HashMap<usize, Option<Vec<usize>>>,
}

impl ConflictSources {
    /// For a factorisation that skipped the rows `skipped` of `B`.
    pub fn new(skipped: &[usize]) -> ConflictSources {
        ConflictSources {
            skipped: skipped.to_vec(),
            touching: None,
            found: HashMap::new(),
        }
    }

    /// The earlier kept constraints that hard constraint `index` is a
    /// combination of (constraint indices, increasing), or `None` when the
    /// search gives up or `index` is not a hard constraint.
    pub fn of(&mut self, problem: &LseProblem, index: usize) -> Option<&[usize]> {
        if !self.found.contains_key(&index) {
            let found = match problem.place(index) {
                Some(RowPlace::Hard(k)) if k < problem.b().nrows() => {
                    let skipped = &self.skipped;
                    let touching = self
                        .touching
                        .get_or_insert_with(|| kept_rows_by_unknown(problem, skipped));
                    search(problem, touching, k)
                }
                _ => None,
            };
            self.found.insert(index, found);
        }
        self.found.get(&index).and_then(|s| s.as_deref())
    }
}

/// The warning of conflicting constraint `index`, its sentence made from
/// its data: "constraint I conflicts with constraint(s) … and was dropped
/// (residual R)", "earlier constraints" when `with` is empty.
pub(crate) fn conflict_warning(index: usize, with: Vec<usize>, residual: f64) -> Warning {
    let named = match with.as_slice() {
        [] => "earlier constraints".to_string(),
        [one] => format!("constraint {one}"),
        list => format!("constraints {}", name_list(list)),
    };
    Warning::new(
        WarningKind::ConflictingConstraint,
        format!(
            "constraint {index} conflicts with {named} and was dropped (residual {residual:.3e})"
        ),
    )
    .about(WarningSubject::ConflictingConstraint {
        index,
        with,
        residual,
    })
}

/// `a, b, c` for up to eight indices, then `… (N in all)`.
fn name_list(list: &[usize]) -> String {
    const SHOWN: usize = 8;
    let mut s = list
        .iter()
        .take(SHOWN)
        .map(|i| i.to_string())
        .collect::<Vec<_>>()
        .join(", ");
    if list.len() > SHOWN {
        s.push_str(&format!(", … ({} in all)", list.len()));
    }
    s
}

/// Unknown → the rows of `B` not in `skipped` that touch it, increasing.
fn kept_rows_by_unknown(problem: &LseProblem, skipped: &[usize]) -> HashMap<usize, Vec<usize>> {
    let b = problem.b();
    let mut is_skipped = vec![false; b.nrows()];
    for &s in skipped {
        if let Some(flag) = is_skipped.get_mut(s) {
            *flag = true;
        }
    }
    let mut touching: HashMap<usize, Vec<usize>> = HashMap::new();
    for r in (0..b.nrows()).filter(|&r| !is_skipped[r]) {
        for &j in &b.symbolic().col_idx()[b.symbolic().row_range(r)] {
            touching.entry(j).or_default().push(r);
        }
    }
    touching
}

/// The constraint indices of the kept rows before `k` that row `k` of `B`
/// is a combination of, or `None` (see the module documentation).
/// `touching` maps each unknown to the kept rows touching it.
fn search(
    problem: &LseProblem,
    touching: &HashMap<usize, Vec<usize>>,
    k: usize,
) -> Option<Vec<usize>> {
    let b = problem.b();
    let row = |r: usize| {
        let range = b.symbolic().row_range(r);
        (
            &b.symbolic().col_idx()[range.clone()],
            &b.val()[range.clone()],
        )
    };
    let (cols_k, vals_k) = row(k);
    let norm_k = vals_k.iter().map(|v| v * v).sum::<f64>().sqrt();
    if norm_k == 0.0 {
        return None;
    }
    let mut rows: Vec<usize> = Vec::new();
    let mut frontier: Vec<usize> = cols_k.to_vec();
    let mut seen_cols: Vec<usize> = Vec::new();
    for _ in 0..MAX_ROUNDS {
        let before = rows.len();
        for j in std::mem::take(&mut frontier) {
            if seen_cols.contains(&j) {
                continue;
            }
            seen_cols.push(j);
            let earlier = touching.get(&j).map(Vec::as_slice).unwrap_or(&[]);
            for &r in earlier.iter().take_while(|&&r| r < k) {
                if !rows.contains(&r) {
                    rows.push(r);
                }
            }
            if rows.len() > MAX_ROWS {
                return None;
            }
        }
        if rows.len() == before {
            return None;
        }
        rows.sort_unstable();
        // Every unknown of the rows and of row k.
        let mut cols: Vec<usize> = cols_k.to_vec();
        for &r in &rows {
            cols.extend_from_slice(row(r).0);
        }
        cols.sort_unstable();
        cols.dedup();
        if cols.len() < rows.len() {
            return None;
        }
        let at = |j: usize| cols.binary_search(&j).expect("collected above");
        let mut basis = Mat::<f64>::zeros(cols.len(), rows.len());
        for (s, &r) in rows.iter().enumerate() {
            let (c, v) = row(r);
            for (&j, &x) in c.iter().zip(v) {
                basis[(at(j), s)] += x;
            }
        }
        let mut target = Mat::<f64>::zeros(cols.len(), 1);
        for (&j, &x) in cols_k.iter().zip(vals_k) {
            target[(at(j), 0)] += x;
        }
        if let Some(named) = explain(&basis, &target, norm_k, |s| row(rows[s]).1) {
            let hard = problem.hard_constraints();
            let mut named: Vec<usize> = named.into_iter().map(|s| hard[rows[s]]).collect();
            named.sort_unstable();
            return Some(named);
        }
        for &r in &rows {
            frontier.extend(row(r).0.iter().copied().filter(|j| !seen_cols.contains(j)));
        }
    }
    None
}

/// `min ‖basis α − target‖` over the columns `keep` of `basis`: `α` and the
/// remainder.
fn least_squares(basis: &Mat<f64>, target: &Mat<f64>, keep: &[usize]) -> (Mat<f64>, f64) {
    let sub = Mat::from_fn(basis.nrows(), keep.len(), |i, s| basis[(i, keep[s])]);
    let alpha = sub.col_piv_qr().solve_lstsq(target);
    let remainder = (&sub * &alpha - target).norm_l2();
    (
        alpha,
        if remainder.is_finite() {
            remainder
        } else {
            f64::INFINITY
        },
    )
}

/// The smallest set of columns of `basis` (kept rows of `B`) found greedily
/// whose combination is within [`EXPLAINED`]` × norm` of `target`, or
/// `None` if all of them together are not. Columns are dropped from the
/// least share `|α_s| ‖b_s‖` up while the rest still explain the target:
/// the solution of nearly parallel kept rows carries rounding of order
/// `ε/ρ` in every coefficient, which must not name a row that plays no
/// part (a repeat of one of two nearly parallel rows names that one).
fn explain<'a>(
    basis: &Mat<f64>,
    target: &Mat<f64>,
    norm: f64,
    row_values: impl Fn(usize) -> &'a [f64],
) -> Option<Vec<usize>> {
    let bound = EXPLAINED * norm;
    let row_norm = |s: usize| row_values(s).iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut keep: Vec<usize> = (0..basis.ncols()).collect();
    let (mut alpha, remainder) = least_squares(basis, target, &keep);
    if remainder > bound {
        return None;
    }
    let share =
        |alpha: &Mat<f64>, keep: &[usize], t: usize| alpha[(t, 0)].abs() * row_norm(keep[t]);
    // Rows with no part at all (beyond rounding) go at once.
    let significant: Vec<usize> = (0..keep.len())
        .filter(|&t| share(&alpha, &keep, t) > NEGLIGIBLE_SHARE * norm)
        .map(|t| keep[t])
        .collect();
    if significant.len() < keep.len() {
        let (a, r) = least_squares(basis, target, &significant);
        if r <= bound {
            keep = significant;
            alpha = a;
        }
    }
    // Then one at a time, least share first.
    if keep.len() <= MAX_PRUNED {
        'prune: loop {
            let mut order: Vec<usize> = (0..keep.len()).collect();
            order.sort_by(|&s, &t| share(&alpha, &keep, s).total_cmp(&share(&alpha, &keep, t)));
            for t in order {
                let fewer: Vec<usize> = keep.iter().copied().filter(|&c| c != keep[t]).collect();
                if fewer.is_empty() {
                    break;
                }
                let (a, r) = least_squares(basis, target, &fewer);
                if r <= bound {
                    keep = fewer;
                    alpha = a;
                    continue 'prune;
                }
            }
            break;
        }
    }
    Some(keep)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sentence is made from the data the warning carries, so code
    /// that acts on the warning reads the data, never the sentence.
    #[test]
    fn a_conflict_warning_carries_what_its_sentence_says() {
        let w = conflict_warning(7, vec![0, 4], 1.5e-3);
        assert_eq!(w.kind, WarningKind::ConflictingConstraint);
        assert_eq!(
            w.message,
            "constraint 7 conflicts with constraints 0, 4 and was dropped (residual 1.500e-3)"
        );
        assert_eq!(
            w.subject,
            Some(WarningSubject::ConflictingConstraint {
                index: 7,
                with: vec![0, 4],
                residual: 1.5e-3
            })
        );
        let alone = conflict_warning(3, Vec::new(), 2.0);
        assert!(alone.message.contains("conflicts with earlier constraints"));
        assert_eq!(
            conflict_warning(3, vec![1], 2.0).message,
            "constraint 3 conflicts with constraint 1 and was dropped (residual 2.000e0)"
        );
    }
}
