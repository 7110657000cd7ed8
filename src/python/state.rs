//! What a Python `Deformer` is: the class [`PyDeformer`], its state behind
//! the lock ([`DeformerState`]: the set-up or the factored library
//! [`Deformer`], the solve options, and the [`Changes`] a `HandleBasis`
//! must know of) and the GIL-released access to it. The leaf of `python`
//! that the class's methods (`mod.rs`) and the basis (`basis.rs`) share.

use std::collections::HashMap;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

use super::errors::{input, released};
use super::own_backend::{Objects, this_thread};
use crate::constraints::ConstraintSet;
use crate::error::{Error, ProblemError};
use crate::laplacian::LaplacianKind;
use crate::limits::MemoryBudget;
use crate::mesh::Mesh;
use crate::{Deformer, SolveOptions};

/// When a basis was built, in [`Changes`]' clocks.
#[derive(Debug, Clone, Copy)]
pub(super) struct Stamp {
    epoch: u64,
    clock: u64,
}

/// The changes of a Python `Deformer` a basis must know of (module
/// documentation): an epoch that every reconfiguration advances, and per
/// group the time of its last `transform_group` on a clock of their own.
#[derive(Debug, Default)]
pub(super) struct Changes {
    epoch: u64,
    /// The call that advanced the epoch last.
    last: &'static str,
    clock: u64,
    moved: HashMap<String, u64>,
}

impl Changes {
    /// `call` (a `precompute()` or `set_targets()`) is about to change
    /// the factor or targets: every basis built before is stale.
    pub(super) fn reconfigured(&mut self, call: &'static str) {
        self.epoch += 1;
        self.last = call;
    }

    /// `transform_group(group, …)` is about to move `group`'s targets: a
    /// basis built before is stale unless `group` is one of its groups.
    pub(super) fn transformed(&mut self, group: &str) {
        self.clock += 1;
        match self.moved.get_mut(group) {
            Some(t) => *t = self.clock,
            None => {
                self.moved.insert(group.to_string(), self.clock);
            }
        }
    }

    pub(super) fn stamp(&self) -> Stamp {
        Stamp {
            epoch: self.epoch,
            clock: self.clock,
        }
    }

    /// What changed since `stamp` for a basis of `groups`, if anything.
    pub(super) fn since(&self, stamp: Stamp, groups: &[String]) -> Option<String> {
        if self.epoch != stamp.epoch {
            return Some(format!("{} was called since", self.last));
        }
        if self.clock == stamp.clock {
            return None;
        }
        self.moved
            .iter()
            .filter(|&(g, &t)| t > stamp.clock && !groups.contains(g))
            .map(|(g, _)| g)
            .min()
            .map(|g| format!("transform_group('{g}') moved a group outside the basis since"))
    }
}

/// What a `Deformer` holds behind its lock.
pub(super) struct DeformerState {
    pub(super) stage: Stage,
    pub(super) options: SolveOptions,
    /// What a `HandleBasis` of this deformer must know (basis.rs).
    pub(super) changes: Changes,
}

/// A Python `Deformer` before and after its first `precompute()`: the
/// library's [`Deformer`] is made factored, so the door keeps the set-up
/// until then.
pub(super) enum Stage {
    /// Checked, not yet factored.
    SetUp {
        mesh: Mesh,
        kind: LaplacianKind,
        constraints: ConstraintSet,
    },
    /// Factored.
    Factored(Box<Deformer>),
}

impl DeformerState {
    /// The factored deformer, or an error saying that `call` needs
    /// `precompute()` first.
    pub(super) fn deformer(&mut self, call: &str) -> Result<&mut Deformer, Error> {
        match &mut self.stage {
            Stage::Factored(d) => Ok(d),
            Stage::SetUp { .. } => Err(ProblemError::InvalidArgument {
                message: format!("{call} needs a factorisation: call precompute() first"),
            }
            .into()),
        }
    }

    /// `precompute()`: the first factors the set-up, later ones refactor
    /// (on error the previous factorisation stays).
    pub(super) fn precompute(&mut self) -> Result<(), Error> {
        match &mut self.stage {
            Stage::Factored(d) => d.refactor(&self.options),
            Stage::SetUp {
                mesh,
                kind,
                constraints,
            } => {
                let d = Deformer::new(mesh.clone(), *kind, constraints.clone(), &self.options)?;
                self.stage = Stage::Factored(Box::new(d));
                Ok(())
            }
        }
    }

    /// The constraint indices of group `name`.
    pub(super) fn group(&self, name: &str) -> Result<Vec<usize>, Error> {
        match &self.stage {
            Stage::Factored(d) => d.group_members(name),
            Stage::SetUp { constraints, .. } => match constraints.group(name) {
                [] => Err(ProblemError::BadUpdate {
                    message: format!("there is no constraint group '{name}'"),
                }
                .into()),
                members => Ok(members.to_vec()),
            },
        }
    }
}

/// A mesh with constraints, deformed again and again: `precompute()` once,
/// then `set_targets` / `transform_group` and `solve()` per frame, reusing
/// the factorisation.
#[pyclass(name = "Deformer", module = "lse_deform", subclass)]
pub(super) struct PyDeformer {
    pub(super) state: Mutex<DeformerState>,
    /// The memory budget of `memory_limit=`, for the arrays later calls
    /// convert (the solve options in the state hold it too).
    pub(super) budget: MemoryBudget,
    /// The back-end objects of `factor=`, to explain errors.
    pub(super) objects: Objects,
    /// The thread inside a call on this Deformer ([`this_thread`]; 0:
    /// none), which a back-end object's method may call back.
    pub(super) owner: AtomicU64,
}

/// Clears [`PyDeformer::owner`] when the call holding the lock ends.
struct Owned<'a>(&'a AtomicU64);

impl Drop for Owned<'_> {
    fn drop(&mut self) {
        self.0.store(0, Ordering::Release);
    }
}

impl PyDeformer {
    /// Runs `f` on the state with the GIL released.
    ///
    /// Errors: `InputError` for a call from inside a call on this
    /// Deformer on the same thread (a back-end object's method that calls
    /// it back): the state's lock is this thread's already, and waiting
    /// for it would never end.
    pub(super) fn with_state<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut DeformerState) -> Result<T, Error> + Send,
    ) -> PyResult<T> {
        let me = this_thread();
        if self.owner.load(Ordering::Acquire) == me {
            return Err(input(
                "this Deformer was called back from inside one of its own calls (a back-end object's method called it while the Deformer was calling the object): its calls are serialised and do not nest",
            ));
        }
        let (state, owner) = (&self.state, &self.owner);
        let result = released(py, move || match state.lock() {
            Ok(mut guard) => {
                owner.store(me, Ordering::Release);
                let _owned = Owned(owner);
                f(&mut guard).map(Ok)
            }
            Err(_) => Ok(Err(())),
        });
        let result = self.objects.explain(py, result)?;
        result.map_err(|()| {
            PyRuntimeError::new_err(
                "this Deformer is unusable after an internal error in an earlier call",
            )
        })
    }
}
