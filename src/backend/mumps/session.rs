//! One analysed matrix on rank 0 and the factorisations made from it.
//!
//! MUMPS keeps one numeric factor per instance, while the SPD and `LDLᵀ`
//! seams let one symbolic analysis hand out several factors (a weight
//! sweep). A [`Session`] is the instance with the analysed pattern; each
//! [`Factorisation`] keeps its own values and the generation of the factor
//! it made. A solve whose factor has since been replaced by another
//! factorisation of the same session factors its values again first
//! (`JOB = 2`, no new analysis), so every solve uses its own matrix.

use std::sync::{Arc, Mutex, MutexGuard};

use faer::MatMut;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

use super::driver::Driver;
use super::instance::{Failure, Params};
use super::shared::{MumpsFacts, failure_message, numerical};
use crate::error::NumericalError;

/// The lower triangle of a symmetric matrix as MUMPS's centralised
/// assembled input: 1-based row and column indices, and where each entry's
/// value sits in the caller's CSC values.
pub(crate) struct Assembled {
    pub n: usize,
    irn: Vec<i32>,
    jcn: Vec<i32>,
    positions: Vec<usize>,
}

impl Assembled {
    /// The entries with row ≥ column of `lower`.
    pub(crate) fn from_lower(
        lower: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Assembled, NumericalError> {
        let n = lower.ncols();
        if n >= i32::MAX as usize {
            return Err(numerical(Failure::Rank(format!(
                "{n} unknowns exceed MUMPS's 32-bit indices"
            ))));
        }
        let (mut irn, mut jcn, mut positions) = (Vec::new(), Vec::new(), Vec::new());
        for j in 0..n {
            for q in lower.col_range(j) {
                let r = lower.row_idx()[q];
                if r >= j {
                    irn.push(r as i32 + 1);
                    jcn.push(j as i32 + 1);
                    positions.push(q);
                }
            }
        }
        Ok(Assembled {
            n,
            irn,
            jcn,
            positions,
        })
    }

    /// The values of `lower` (same pattern) in this entry order.
    pub fn values(&self, lower: SparseColMatRef<'_, usize, f64>) -> Vec<f64> {
        self.positions.iter().map(|&q| lower.val()[q]).collect()
    }
}

/// The pivots as a back end that judges them itself reports them
/// (MUMPS's null-pivot detection): the unknowns whose pivots it found null
/// (0-based, original order) and the number of negative pivots.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct DetectedPivots {
    /// Unknowns with a null pivot.
    pub null: Vec<usize>,
    /// When `null` is not empty: the unknowns still null when the matrix is
    /// factored again with a threshold at the level of rounding (a pivot in
    /// `null` but not here was small but sound, as on sliver-heavy meshes).
    pub null_at_rounding: Vec<usize>,
    /// How many pivots were negative (the inertia's negative count).
    pub negative: usize,
}

/// An analysed instance and the generation of its current numeric factor.
pub(crate) struct Session {
    pub driver: Driver,
    matrix: Assembled,
    /// `PERM_IN` (1-based positions in the pivot order), when the caller
    /// fixes the order.
    perm_in: Vec<i32>,
    /// The values of the current factor (MUMPS reads them at `JOB = 2`).
    values: Vec<f64>,
    generation: u64,
    /// `CNTL` entries every factorisation sets (the null-pivot threshold
    /// of a second look).
    factorisation_cntl: Vec<(usize, f64)>,
}

/// Workspace failures MUMPS asks to retry with a larger `ICNTL(14)`
/// (user's guide, §8: −8, −9, −11, −14, −15, −17, −20).
const WORKSPACE_ERRORS: [i32; 7] = [-8, -9, -11, -14, -15, -17, -20];

impl Session {
    /// `JOB = 1` on `matrix` with `params` (and `perm_in` when not empty).
    pub(crate) fn analyse(
        mut driver: Driver,
        matrix: Assembled,
        perm_in: Vec<i32>,
        params: &Params,
    ) -> Result<Session, Failure> {
        let (irn, jcn) = (matrix.irn.as_ptr(), matrix.jcn.as_ptr());
        let perm = perm_in.as_ptr();
        let (n, nnz, has_perm) = (matrix.n, matrix.irn.len(), !perm_in.is_empty());
        driver.job(1, params, |s| {
            s.n = n as i32;
            s.nnz = nnz as i64;
            s.irn = irn.cast_mut();
            s.jcn = jcn.cast_mut();
            if has_perm {
                s.perm_in = perm.cast_mut();
            }
        })?;
        Ok(Session {
            driver,
            matrix,
            perm_in,
            values: Vec::new(),
            generation: 0,
            factorisation_cntl: Vec::new(),
        })
    }

    /// `JOB = 2` on `values`, retried with twice the workspace relaxation
    /// (`ICNTL(14)`) while MUMPS says its workspace was too small, at most
    /// three times; returns the new generation.
    fn factorise(&mut self, values: &[f64]) -> Result<u64, Failure> {
        self.values = values.to_vec();
        let mut relaxation = self.driver.struc().0.icntl[13].max(20);
        for attempt in 0.. {
            let (irn, jcn, a) = (
                self.matrix.irn.as_ptr(),
                self.matrix.jcn.as_ptr(),
                self.values.as_ptr(),
            );
            let perm = self.perm_in.as_ptr();
            let has_perm = !self.perm_in.is_empty();
            let params = Params {
                icntl: vec![(14, relaxation)],
                cntl: self.factorisation_cntl.clone(),
            };
            let outcome = self.driver.job(2, &params, |s| {
                s.irn = irn.cast_mut();
                s.jcn = jcn.cast_mut();
                s.a = a.cast_mut();
                if has_perm {
                    s.perm_in = perm.cast_mut();
                }
            });
            match outcome {
                Err(Failure::Mumps { infog1, .. })
                    if WORKSPACE_ERRORS.contains(&infog1) && attempt < 3 =>
                {
                    relaxation *= 2;
                }
                Err(e) => {
                    self.generation += 1;
                    return Err(e);
                }
                Ok(()) => break,
            }
        }
        self.generation += 1;
        Ok(self.generation)
    }

    /// `JOB = 3` on `rhs` (column-major, `n × nrhs`): the solution replaces
    /// it.
    fn solve(&mut self, rhs: &mut [f64], nrhs: usize) -> Result<(), Failure> {
        let n = self.matrix.n;
        let ptr = rhs.as_mut_ptr();
        let a = self.values.as_ptr();
        self.driver.job(3, &Params::default(), |s| {
            s.rhs = ptr;
            s.nrhs = nrhs as i32;
            s.lrhs = n as i32;
            s.a = a.cast_mut();
        })
    }

    /// Sets `CNTL` entries for the factorisations from now on.
    pub(crate) fn set_factorisation_cntl(&mut self, cntl: Vec<(usize, f64)>) {
        self.factorisation_cntl = cntl;
    }

    /// The null pivots (`PIVNUL_LIST`, 0-based) and the number of negative
    /// pivots (`INFOG(12)`) of the current factor.
    pub(crate) fn detected_pivots(&self) -> DetectedPivots {
        let struc = self.driver.struc();
        let count = struc.infog(28).max(0) as usize;
        let list = struc.0.pivnul_list;
        let null = if list.is_null() {
            Vec::new()
        } else {
            // SAFETY: with ICNTL(24) = 1, MUMPS allocates PIVNUL_LIST on
            // the host with at least INFOG(28) entries (1-based indices).
            unsafe { std::slice::from_raw_parts(list, count) }
                .iter()
                .map(|&i| (i - 1).max(0) as usize)
                .collect()
        };
        DetectedPivots {
            null,
            null_at_rounding: Vec::new(),
            negative: struc.infog(12).max(0) as usize,
        }
    }

    /// What the report says of the current factor.
    pub fn facts(&self) -> MumpsFacts {
        let figures = self.driver.figures();
        MumpsFacts {
            ranks: figures.len(),
            factor_entries_per_rank: figures.iter().map(|f| f.factor_entries).collect(),
            peak_bytes_per_rank: figures.iter().map(|f| f.peak_bytes).collect(),
            ordering: ordering_name(self.driver.struc().infog(7)).to_string(),
            out_of_core: self.driver.out_of_core(),
        }
    }
}

/// The ordering `INFOG(7)` names after a sequential analysis (user's
/// guide, §6.2).
pub(crate) fn ordering_name(infog7: i32) -> &'static str {
    match infog7 {
        0 => "amd",
        1 => "given",
        2 => "amf",
        3 => "scotch",
        4 => "pord",
        5 => "metis",
        6 => "qamd",
        _ => "unknown",
    }
}

/// A session shared by the symbolic analysis and its factors.
pub(crate) type Shared = Arc<Mutex<Session>>;

/// Locks a session (poison ignored: a panic aborts every rank anyway).
pub(crate) fn lock(shared: &Shared) -> MutexGuard<'_, Session> {
    shared.lock().unwrap_or_else(|e| e.into_inner())
}

/// One numeric factorisation of a session's pattern.
pub(crate) struct Factorisation {
    pub shared: Shared,
    generation: u64,
    values: Vec<f64>,
    pub n: usize,
    /// Entries of the factor over all ranks (`INFOG(29)`).
    pub entries: u64,
    pub facts: MumpsFacts,
    /// Solves that had to factor the values again.
    pub refactorizations: usize,
}

impl Factorisation {
    /// Factors `lower` (the analysed pattern).
    pub fn new(
        shared: &Shared,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Factorisation, Failure> {
        let mut session = lock(shared);
        let values = session.matrix.values(lower);
        let generation = session.factorise(&values)?;
        Ok(Factorisation {
            shared: Arc::clone(shared),
            generation,
            n: session.matrix.n,
            entries: crate::backend::mumps::ffi::count(session.driver.struc().infog(29)),
            facts: session.facts(),
            values,
            refactorizations: 0,
        })
    }

    /// Solves in place for every column of `rhs`, factoring this
    /// factorisation's values again first when another factorisation of
    /// the session replaced them ([`Factorisation::refactorizations`]
    /// counts it).
    ///
    /// Errors: [`NumericalError::OutOfMemory`] when MUMPS could not
    /// allocate its workspace; else [`NumericalError::Backend`] with
    /// MUMPS's code, naming the out-of-core directory when the factor is
    /// kept there (a file of the factor that cannot be read).
    pub fn solve_in_place(&mut self, mut rhs: MatMut<'_, f64>) -> Result<(), NumericalError> {
        let (n, k) = (rhs.nrows(), rhs.ncols());
        let mut dense: Vec<f64> = (0..k)
            .flat_map(|c| (0..n).map(move |i| (i, c)))
            .map(|(i, c)| rhs[(i, c)])
            .collect();
        let mut session = lock(&self.shared);
        let mut outcome = Ok(());
        if session.generation != self.generation {
            self.refactorizations += 1;
            outcome = session.factorise(&self.values).map(|g| self.generation = g);
        }
        if outcome.is_ok() && n > 0 && k > 0 {
            outcome = session.solve(&mut dense, k);
        }
        if let Err(failure) = outcome {
            return Err(solve_error(failure, session.driver.scratch_directory()));
        }
        for c in 0..k {
            for i in 0..n {
                rhs[(i, c)] = dense[c * n + i];
            }
        }
        Ok(())
    }
}

/// A failed solve as the seams' error: MUMPS's words and code, and the
/// out-of-core directory it was reading from.
fn solve_error(failure: Failure, scratch: Option<&std::path::Path>) -> NumericalError {
    if let Some(what) = super::shared::allocation_refused(&failure) {
        return NumericalError::out_of_memory(super::shared::NAME, &what);
    }
    let message = failure_message(failure);
    let message = match scratch {
        Some(dir) => format!(
            "solving with the out-of-core factor in {}: {message}",
            dir.display()
        ),
        None => format!("solving with the factor: {message}"),
    };
    NumericalError::Backend {
        backend: super::shared::NAME.into(),
        message,
    }
}
