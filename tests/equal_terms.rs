//! One ordering and one thread count for every back end
//! (docs/equal-terms.md): a held AMD permutation gives the back ends that
//! count the exact fill the same factor, whose size is checked against a
//! fill count computed here by eliminating the graph by hand; a given
//! permutation is followed and changes no solution; a wrong one is a typed
//! refusal; a back end from outside factors the permuted matrix; the
//! report states the ordering and the threads.

use std::collections::BTreeSet;
use std::sync::Arc;

use faer::sparse::SymbolicSparseColMatRef;
use lse_deform::backend::BackendName;
use lse_deform::backend::ordering::FactorPlan;
use lse_deform::backend::spd::{FaerLlt, SpdBackend, SpdKind, SpdSymbolic};
use lse_deform::error::{Error, NumericalError, ProblemError};
use lse_deform::formulation::{Chosen, FormulationChoice};
use lse_deform::resources::{FillOrdering, Resources, Threads};
use lse_deform::scene::FixedAndHandle;
use lse_deform::solver::LseSolver;
use lse_deform::testing::{random_lses, random_surface};
use lse_deform::{Deformer, LaplacianKind, Method, SolveOptions, formulation::NullSpaceQr};
use proptest::prelude::*;

fn held(ordering: FillOrdering, threads: usize) -> Resources {
    Resources {
        ordering,
        threads: Threads::count(threads).unwrap(),
        ..Resources::default()
    }
}

fn deformer() -> Deformer {
    let mesh = random_surface(18, 14, 7);
    let set = FixedAndHandle::paper_default(&mesh)
        .constraints(&mesh)
        .unwrap();
    Deformer::new(
        mesh,
        LaplacianKind::Cotangent,
        set,
        &lse_deform::SolveOptions::default(),
    )
    .unwrap()
}

/// Penalty with `spd`: the matrix factored is `tril(AᵀA + w²BᵀB)` over
/// every vertex (no unknown leaves the system), so its pattern is known
/// from `A` and `B` alone.
fn penalty(spd: SpdKind) -> SolveOptions {
    SolveOptions::new(FormulationChoice {
        spd: spd.into(),
        weight: Some(1e3),
        ..FormulationChoice::new(Method::Penalty)
    })
}

/// The strictly lower pattern of `AᵀA + BᵀB` as adjacency sets.
fn normal_graph(d: &Deformer) -> Vec<BTreeSet<usize>> {
    let n = d.problem().n();
    // The columns of each row of A and of B.
    let a = d.problem().a().as_ref();
    let mut rows: Vec<Vec<usize>> = vec![Vec::new(); a.nrows()];
    for j in 0..a.ncols() {
        for &r in a.symbolic().row_idx_of_col_raw(j) {
            rows[r].push(j);
        }
    }
    let b = d.problem().b().as_ref();
    rows.extend((0..b.nrows()).map(|r| b.symbolic().col_idx_of_row_raw(r).to_vec()));
    let mut adjacent = vec![BTreeSet::new(); n];
    for cols in &rows {
        for &i in cols {
            for &j in cols {
                if i != j {
                    adjacent[i].insert(j);
                }
            }
        }
    }
    adjacent
}

/// Entries of `L` (diagonal included) when the graph is eliminated in
/// `order`: eliminating a vertex joins its remaining neighbours into a
/// clique, and its column holds them (symbolic Gaussian elimination,
/// written out; no library's symbolic analysis is used).
fn fill_by_elimination(mut graph: Vec<BTreeSet<usize>>, order: &[usize]) -> usize {
    let mut total = 0;
    for &v in order {
        let neighbours: Vec<usize> = graph[v].iter().copied().collect();
        total += 1 + neighbours.len();
        for &a in &neighbours {
            graph[a].remove(&v);
            for &b in &neighbours {
                if a != b {
                    graph[a].insert(b);
                }
            }
        }
        graph[v].clear();
    }
    total
}

/// The exact-fill back ends of this build.
fn exact_fill_backends() -> Vec<SpdKind> {
    let mut kinds = vec![SpdKind::FaerSimplicial, SpdKind::Nalgebra];
    if SpdKind::Cholmod.in_this_build() {
        kinds.push(SpdKind::Cholmod);
    }
    kinds
}

#[test]
fn one_amd_permutation_gives_the_exact_fill_back_ends_the_fill_counted_by_hand() {
    let mut d = deformer();
    let graph = normal_graph(&d);
    // The permutation every back end is given: the plan's AMD of the
    // matrix's pattern (the same pattern, lower triangle).
    let lower = {
        let n = d.problem().n();
        let mut col_ptr = vec![0usize];
        let mut rows = Vec::new();
        for (j, adjacent) in graph.iter().enumerate() {
            rows.push(j);
            rows.extend(adjacent.iter().copied().filter(|&i| i > j));
            col_ptr.push(rows.len());
        }
        faer::sparse::SymbolicSparseColMat::new_checked(n, n, col_ptr, None, rows)
    };
    let plan = FactorPlan::new(
        &FillOrdering::Amd,
        Threads::Own,
        lower.as_ref(),
        &|k| k,
        lower.ncols(),
    )
    .unwrap();
    let by_hand = fill_by_elimination(graph, plan.permutation.as_deref().unwrap());

    let reference = {
        d.refactor(&SolveOptions::default()).unwrap();
        d.solve().unwrap().positions
    };
    let diagonal = d.mesh().bbox_diagonal();
    for kind in exact_fill_backends() {
        let options = SolveOptions {
            resources: held(FillOrdering::Amd, 1),
            ..penalty(kind)
        };
        d.refactor(&options).unwrap();
        let solution = d.solve().unwrap();
        let r = &solution.report;
        assert_eq!(r.nnz.factor, Some(by_hand), "{kind}");
        assert_eq!(r.ordering.as_deref(), Some("amd"), "{kind}");
        assert_eq!(r.threads, Some(1), "{kind}");
        assert!(r.timings_s.ordering > 0.0, "{kind}");
        // Penalty at w = 1e3 is near the constrained solution, not on it:
        // its own ordering gives the same numbers to rounding.
        let own = {
            d.refactor(&penalty(kind)).unwrap();
            d.solve().unwrap()
        };
        assert!(own.report.ordering.as_deref().unwrap().starts_with("own ("));
        let apart = max_distance(&own.positions, &solution.positions);
        assert!(apart <= 1e-9 * diagonal, "{kind}: {apart:e}");
        assert!(max_distance(&reference, &solution.positions) < 1e-2 * diagonal);
    }
}

fn max_distance(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (0..3).map(|c| (p[c] - q[c]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max)
}

#[test]
fn a_given_order_is_followed_and_changes_no_solution_of_any_method() {
    let mut d = deformer();
    let n = d.problem().n();
    let diagonal = d.mesh().bbox_diagonal();
    let reversed: Arc<[usize]> = (0..n).rev().collect::<Vec<_>>().into();
    for method in Method::ALL {
        let choice = FormulationChoice {
            weight: (method == Method::Penalty).then_some(1e3),
            ..FormulationChoice::new(method)
        };
        let own = SolveOptions::new(choice.clone());
        d.refactor(&own).unwrap();
        let expected = d.solve().unwrap().positions;
        for ordering in [
            FillOrdering::Given(reversed.clone()),
            FillOrdering::Natural,
            FillOrdering::Amd,
        ] {
            let word = ordering.name();
            let options = SolveOptions {
                resources: held(ordering, 2),
                ..own.clone()
            };
            d.refactor(&options).unwrap();
            let solution = d.solve().unwrap();
            let used = solution.report.ordering.clone().unwrap();
            let expected_word = match method {
                Method::Kkt => format!("{word} (kkt)"),
                _ => word.to_string(),
            };
            assert_eq!(used, expected_word, "{method}");
            let apart = max_distance(&expected, &solution.positions);
            assert!(apart <= 1e-9 * diagonal, "{method} {word}: {apart:e}");
        }
    }
}

#[test]
fn natural_order_fills_more_than_amd_on_a_surface() {
    let mut d = deformer();
    let mut nnz = |ordering| {
        let options = SolveOptions {
            resources: held(ordering, 1),
            ..penalty(SpdKind::FaerSimplicial)
        };
        d.refactor(&options).unwrap();
        d.report().nnz.factor.unwrap()
    };
    let (natural, amd) = (nnz(FillOrdering::Natural), nnz(FillOrdering::Amd));
    assert!(natural > amd, "natural {natural}, amd {amd}");
}

#[test]
fn a_given_order_that_is_not_a_permutation_is_refused_typed() {
    let mut d = deformer();
    let n = d.problem().n();
    let mut repeated: Vec<usize> = (0..n).collect();
    repeated[1] = 0;
    for (order, expected) in [
        (vec![0usize; 3], "entries"),
        (repeated, "not a permutation"),
    ] {
        let options = SolveOptions {
            resources: held(FillOrdering::Given(order.into()), 1),
            ..SolveOptions::default()
        };
        match d.refactor(&options) {
            Err(Error::Problem(ProblemError::InvalidArgument { message })) => {
                assert!(message.contains(expected), "{message}");
            }
            other => panic!("expected InvalidArgument, got {other:?}"),
        }
    }
    if !SpdKind::Cholmod.in_this_build() {
        let options = SolveOptions {
            resources: held(FillOrdering::Metis, 1),
            ..SolveOptions::default()
        };
        match d.refactor(&options) {
            Err(Error::Problem(ProblemError::InvalidArgument { message })) => {
                assert!(message.contains("not in this build"), "{message}");
            }
            other => panic!("expected InvalidArgument, got {other:?}"),
        }
    }
}

#[test]
fn threads_are_what_each_back_end_used() {
    let mut d = deformer();
    for (kind, asked, used) in [
        (SpdKind::FaerSupernodal, 1, 1),
        (SpdKind::FaerSupernodal, 2, 2),
        (SpdKind::Nalgebra, 2, 1),
    ] {
        let options = SolveOptions {
            resources: Resources {
                threads: Threads::count(asked).unwrap(),
                ..Resources::default()
            },
            ..penalty(kind)
        };
        d.refactor(&options).unwrap();
        assert_eq!(d.report().threads, Some(used), "{kind} asked {asked}");
        assert!(d.report().ordering.as_deref().unwrap().starts_with("own ("));
    }
    // Own threads: faer's small factor runs on one (below its 50 M-value
    // threshold).
    d.refactor(&penalty(SpdKind::FaerAuto)).unwrap();
    assert_eq!(d.report().threads, Some(1));
    assert_eq!(d.report().ordering.as_deref(), Some("own (amd)"));
}

/// A back end from outside with no ordering of its own: faer's simplicial
/// Cholesky told to keep the natural order.
struct NoOrdering;

impl SpdBackend for NoOrdering {
    fn name(&self) -> BackendName {
        "no-ordering".into()
    }

    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        let plan = FactorPlan::new(
            &FillOrdering::Natural,
            Threads::Own,
            lower,
            &|k| k,
            lower.ncols(),
        )
        .map_err(|e| NumericalError::Backend {
            backend: "no-ordering".into(),
            message: e.to_string(),
        })?;
        FaerLlt::simplicial().analyze_planned(lower, &plan)
    }
}

#[test]
fn a_back_end_from_outside_factors_the_permuted_matrix() {
    let mut d = deformer();
    let diagonal = d.mesh().bbox_diagonal();
    d.refactor(&SolveOptions::default()).unwrap();
    let expected = d.solve().unwrap().positions;
    let amd = held(FillOrdering::Amd, 1);
    let faer = SolveOptions {
        resources: amd.clone(),
        ..SolveOptions::new(FormulationChoice {
            spd: SpdKind::FaerSimplicial.into(),
            ..FormulationChoice::new(Method::NullSpaceQr)
        })
    };
    d.refactor(&faer).unwrap();
    let faer_nnz = d.report().nnz.factor;
    let outside = SolveOptions {
        resources: amd,
        ..SolveOptions::new(FormulationChoice {
            spd: Chosen::Own(Arc::new(NoOrdering)),
            ..FormulationChoice::new(Method::NullSpaceQr)
        })
    };
    d.refactor(&outside).unwrap();
    let solution = d.solve().unwrap();
    assert_eq!(
        solution.report.ordering.as_deref(),
        Some("amd (applied to the matrix)")
    );
    // The outside back end keeps the order it is handed: the permuted
    // matrix has the fill of the AMD permutation.
    assert_eq!(solution.report.nnz.factor, faer_nnz);
    let apart = max_distance(&expected, &solution.positions);
    assert!(apart <= 1e-9 * diagonal, "{apart:e}");
    // Without a held ordering it analyses the matrix as given.
    d.refactor(&SolveOptions::new(FormulationChoice {
        spd: Chosen::Own(Arc::new(NoOrdering)),
        ..FormulationChoice::new(Method::NullSpaceQr)
    }))
    .unwrap();
    assert!(d.report().nnz.factor > faer_nnz);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// On random LSE problems, a random given order (and AMD, natural)
    /// gives the null-space method's and KKT's solutions of the default to
    /// rounding.
    #[test]
    fn held_orderings_agree_with_the_default(lse in random_lses(), seed in any::<u64>()) {
        let n = lse.problem.n();
        let mut order: Vec<usize> = (0..n).collect();
        let mut state = seed | 1;
        for i in (1..n).rev() {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            order.swap(i, (state % (i as u64 + 1)) as usize);
        }
        let mut solver = LseSolver::with_formulation(lse.problem.clone(), &NullSpaceQr::default(), &lse_deform::resources::Resources::default()).unwrap();
        let expected = solver.solve().unwrap();
        let scale = expected.norm_max().max(1.0);
        for ordering in [FillOrdering::Given(order.into()), FillOrdering::Amd, FillOrdering::Natural] {
            let word = ordering.name();
            let resources = held(ordering, 1);
            solver.refactor_with(&NullSpaceQr::default(), &resources).unwrap();
            let x = solver.solve().unwrap();
            let apart = (&x - &expected).norm_max();
            prop_assert!(apart <= 1e-9 * scale, "{}: {:e}", word, apart);
            prop_assert_eq!(solver.report().ordering.as_deref(), Some(word));
        }
    }
}
