//! Shared helpers of the timing studies (precompute breakdown, relative
//! constraints, scaling, drag): the phases of the paper's Fig. 8, the back
//! ends of this build, the penalty weight, and table and link cells.

use lse_deform::resources::{FillOrdering, Resources, Threads};
use std::sync::Arc;

use lse_deform::backend::qr::QrKind;
use lse_deform::backend::spd::{SpdBackend, SpdKind};
use lse_deform::constraints::ConstraintSet;
use lse_deform::report::Timings;
use lse_deform::{
    Deformer, LaplacianKind, Mesh, formulation::Formulation, formulation::NullSpaceQr,
};

use crate::harness::context::AnyError;
use crate::harness::plot::Drawn;

/// The phases of the paper's Fig. 8 (plus set-up), bottom of a stack first.
/// Every stacked-bar figure of the timing experiments passes this list, so a
/// phase keeps its colour across figures.
pub const PHASES: [&str; 7] = [
    "set-up",
    "QR",
    "preparation",
    "normal matrix",
    "ordering",
    "symbolic",
    "numeric",
];

/// The values of [`PHASES`] of a report's timings (seconds).
pub fn phase_values(t: &Timings) -> Vec<f64> {
    vec![
        t.setup,
        t.qr,
        t.preparation,
        t.normal_matrix,
        t.ordering,
        t.symbolic,
        t.numeric,
    ]
}

/// The CSV columns of [`phase_cells`].
pub const PHASE_COLUMNS: [&str; 6] = [
    "qr_s",
    "preparation_s",
    "normal_matrix_s",
    "ordering_s",
    "symbolic_s",
    "numeric_s",
];

/// CSV cells (`{:.6e}`, empty without timings) of the phases after the
/// set-up: QR, preparation, normal matrix, ordering (one held equal,
/// computed apart), symbolic, numeric.
pub fn phase_cells(t: Option<&Timings>) -> [String; 6] {
    let v = t.map(phase_values);
    [1, 2, 3, 4, 5, 6].map(|i| {
        v.as_ref()
            .map(|v| format!("{:.6e}", v[i]))
            .unwrap_or_default()
    })
}

/// [`phase_values`] without the set-up (the precompute phases only; zero in
/// the set-up slot so that colours still match [`PHASES`]).
pub fn precompute_phase_values(t: &Timings) -> Vec<f64> {
    let mut v = phase_values(t);
    v[0] = 0.0;
    v
}

/// The SPD back ends of this build (CHOLMOD only with `--features
/// suitesparse`, MUMPS only with `--features mumps`), in the library's
/// order. With MUMPS in the build it also starts MPI (once, as one rank in
/// this process), so that MPI's start-up is not timed as part of a study's
/// first MUMPS analysis.
pub fn spd_backends() -> Vec<&'static str> {
    start_mpi();
    SpdKind::available()
        .into_iter()
        .map(SpdKind::name)
        .collect()
}

/// Starts MPI as one rank in this process if MUMPS is in the build (a no-op
/// after the first call, and without the feature).
pub fn start_mpi() {
    #[cfg(feature = "mumps")]
    let _ = lse_deform::backend::mumps::ranks();
}

/// The SPD back end called `name` (one of [`spd_backends`]).
pub fn spd_backend(name: &str) -> Result<Arc<dyn SpdBackend>, AnyError> {
    Ok(name.parse::<SpdKind>()?.backend()?)
}

/// The QR back ends of this build (SPQR only with `--features suitesparse`).
pub fn qr_backends() -> Vec<&'static str> {
    QrKind::available().into_iter().map(QrKind::name).collect()
}

/// The null-space method with the library's default QR back end and the
/// SPD back end `spd` (the default QR is whatever `NullSpaceQr::default()`
/// uses, so a change of the default is picked up).
pub fn null_space_with_spd(spd_name: &str) -> Result<NullSpaceQr, AnyError> {
    Ok(NullSpaceQr {
        spd: spd_backend(spd_name)?,
        ..NullSpaceQr::default()
    })
}

/// The penalty weight of the timing experiments: relative, so that a
/// former hard row outweighs the heaviest Laplacian column by this factor on
/// every mesh (the library's penalty weight is relative to `A`'s largest
/// column norm, see `lse_deform::formulation::Penalty`).
pub const PENALTY_RELATIVE_WEIGHT: f64 = 100.0;

/// The index of the run with the median total of `totals` (the lower
/// median for an even count).
pub fn median_index(totals: &[f64]) -> usize {
    let mut order: Vec<usize> = (0..totals.len()).collect();
    order.sort_by(|&a, &b| totals[a].total_cmp(&totals[b]));
    order[(order.len().saturating_sub(1)) / 2]
}

/// Set-up (a fresh [`Deformer`]) and precompute of `formulation` under
/// `resources` (threads and ordering held, or each back end's own); the
/// report carries both times and the ordering and threads used.
pub fn setup_and_precompute(
    mesh: &Mesh,
    constraints: &ConstraintSet,
    formulation: &dyn Formulation,
    resources: &Resources,
) -> Result<Deformer, AnyError> {
    let deformer = Deformer::with_formulation(
        mesh.clone(),
        LaplacianKind::Cotangent,
        constraints.clone(),
        formulation,
        resources,
    )?;
    Ok(deformer)
}

/// What a timing row held equal across back ends: nothing (each back
/// end's own ordering and threads), or one AMD permutation and one thread.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Terms {
    /// Each back end's own ordering and threads.
    #[serde(rename = "own")]
    Own,
    /// One AMD permutation of the matrix factored, given to every back
    /// end, and one thread.
    #[serde(rename = "amd, 1 thread")]
    AmdOneThread,
}

impl Terms {
    /// Both, own first.
    pub const ALL: [Terms; 2] = [Terms::Own, Terms::AmdOneThread];

    /// The column word.
    pub fn word(self) -> &'static str {
        match self {
            Terms::Own => "own",
            Terms::AmdOneThread => "amd, 1 thread",
        }
    }

    /// The resources of these terms (default budget).
    pub fn resources(self) -> Resources {
        match self {
            Terms::Own => Resources::default(),
            Terms::AmdOneThread => Resources {
                ordering: FillOrdering::Amd,
                threads: Threads::count(1).unwrap_or_default(),
                ..Resources::default()
            },
        }
    }
}

/// Prints the notes of a drawn figure (skipped points) on stderr.
pub fn note_drawn(drawn: &Drawn, notes: &mut Vec<String>) {
    for n in &drawn.notes {
        eprintln!("  plot note: {n}");
        notes.push(format!("plot: {n}"));
    }
}

/// The file name of `path` (for README links relative to `results/`).
pub fn link(dir: &str, stem: &str) -> String {
    format!("[![{stem}]({dir}/{stem}.png)]({dir}/{stem}.svg)")
}

/// Shortens an error message for a table cell.
pub fn short_error(e: &str) -> String {
    let one_line = e.replace('\n', " ").replace('|', "/");
    if one_line.chars().count() > 110 {
        format!("{}…", one_line.chars().take(110).collect::<String>())
    } else {
        one_line
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_index_picks_the_middle_run() {
        assert_eq!(median_index(&[3.0, 1.0, 2.0]), 2);
        assert_eq!(median_index(&[5.0]), 0);
        // Lower median for an even count.
        assert_eq!(median_index(&[4.0, 1.0, 3.0, 2.0]), 3);
    }

    #[test]
    fn backends_of_the_build_are_listed() {
        let spds = spd_backends();
        assert!(spds.contains(&"faer-auto"));
        assert_eq!(spds.contains(&"cholmod"), cfg!(feature = "suitesparse"));
        assert_eq!(spds.contains(&"mumps"), cfg!(feature = "mumps"));
        let qrs = qr_backends();
        assert!(qrs.contains(&"dense-householder"));
        assert_eq!(qrs.contains(&"spqr"), cfg!(feature = "suitesparse"));
    }

    #[test]
    fn phases_sum_to_setup_plus_precompute() {
        let t = Timings {
            setup: 1.0,
            qr: 2.0,
            preparation: 3.0,
            normal_matrix: 4.0,
            ordering: 0.25,
            symbolic: 5.0,
            numeric: 6.0,
            solve: 7.0,
            refine: 0.5,
            diagnostics: 8.0,
        };
        let v = phase_values(&t);
        assert_eq!(v.len(), PHASES.len());
        assert_eq!(v.iter().sum::<f64>(), t.setup + t.precompute());
        assert_eq!(precompute_phase_values(&t)[0], 0.0);
    }
}
