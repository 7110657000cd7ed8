//! The library's entry point for a whole deformation: a mesh, its
//! constraints and a [`Request`] (the typed options of
//! [`crate::options`], with which of them were given) in; the positions
//! with their report out ([`deform`]), or the precomputed engine for a
//! caller that keeps solving ([`prepare`]).
//!
//! This is the one place that
//! - picks the energy: the Laplacian one ([`Deformer`]) or ARAP
//!   ([`ArapDeformer`]: new → precompute → initialise → iterations);
//! - lists the options given that the chosen energy or method does not use
//!   ([`Request::inapplicable`], typed: each door words them its own way);
//! - checks the options before any work, without building a back end
//!   ([`Request::validate`]);
//! - applies `strict` ([`Outcome::verdict`]): a conflicting hard
//!   constraint is a [`ConstraintError::Conflicting`], an estimated forward
//!   error above [`FORWARD_ERROR_WARNING`] a [`NumericalError::LostAccuracy`].
//!
//! The CLI, Python and the editor translate their words into a
//! [`Request`] and call this module; none holds these decisions.

use crate::arap::ArapDeformer;
use crate::choice::{Energy, Method};
use crate::constraints::ConstraintSet;
use crate::deform::Deformer;
use crate::error::{ConstraintError, Error, NumericalError};
use crate::formulation::FORWARD_ERROR_WARNING;
use crate::mesh::Mesh;
use crate::options::{ArapOptions, DeformOptions};
use crate::report::{ArapReport, Report, WarningSubject};

/// An option of a request, for the list of those that do not apply.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RequestOption {
    /// The Laplacian's weights (the Laplacian energy only).
    Laplacian,
    /// The ARAP energy (ARAP only).
    ArapEnergy,
    /// The ARAP iterations (ARAP only).
    Iterations,
    /// The ARAP stop tolerance (ARAP only).
    Tolerance,
    /// The ARAP initial guess (ARAP only).
    ArapInit,
    /// The penalty weight (the penalty method only).
    Weight,
    /// The QR back end (the null-space method only).
    Qr,
    /// The condition estimate (the Laplacian energy only: ARAP's matrix
    /// is the cotangent Laplacian's, estimated with `--energy laplacian`).
    Condition,
}

/// Which options a door was given (a default is not "given"): what
/// [`Request::inapplicable`] reads. The penalty weight is given when
/// `solve.formulation.weight` is `Some`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Given {
    /// The Laplacian's weights.
    pub laplacian: bool,
    /// The ARAP energy.
    pub arap_energy: bool,
    /// The ARAP iterations.
    pub iterations: bool,
    /// The ARAP tolerance.
    pub tolerance: bool,
    /// The ARAP initial guess.
    pub arap_init: bool,
    /// The QR back end.
    pub qr: bool,
}

/// An option given that the request does not use: it is ignored, and the
/// door says so in its own words (`--weight applies to --method penalty
/// only; ignored with --method kkt`, `weight= applies to method='penalty'
/// only; …`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Inapplicable {
    /// The option.
    pub option: RequestOption,
    /// The option and value it applies to (`("method", "penalty")`).
    pub applies_to: (&'static str, &'static str),
    /// The option and value chosen instead (`("method", "kkt")`).
    pub chosen: (&'static str, String),
    /// What the chosen value uses instead, when it says more
    /// (`cotangent weights`).
    pub note: Option<&'static str>,
}

/// What a deformation is asked to do.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Request {
    /// The energy, Laplacian, formulation, resources and strictness.
    pub options: DeformOptions,
    /// The ARAP iterations (used with [`Energy::Arap`]).
    pub arap: ArapOptions,
    /// Which options were given.
    pub given: Given,
    /// Estimate the condition number of the factored matrix (Lanczos)
    /// before the solve (the Laplacian energy; the report's
    /// `condition_estimate`).
    pub condition: bool,
}

impl Request {
    /// The options given that this request does not use, in a fixed order
    /// (the ARAP options, the Laplacian, the condition estimate, the
    /// weight, the QR back end).
    pub fn inapplicable(&self) -> Vec<Inapplicable> {
        let o = &self.options;
        let g = &self.given;
        let mut out = Vec::new();
        if o.energy != Energy::Arap {
            for (option, given) in [
                (RequestOption::ArapEnergy, g.arap_energy),
                (RequestOption::Iterations, g.iterations),
                (RequestOption::Tolerance, g.tolerance),
                (RequestOption::ArapInit, g.arap_init),
            ] {
                if given {
                    out.push(Inapplicable {
                        option,
                        applies_to: ("energy", "arap"),
                        chosen: ("energy", o.energy.to_string()),
                        note: None,
                    });
                }
            }
        } else {
            if g.laplacian {
                out.push(Inapplicable {
                    option: RequestOption::Laplacian,
                    applies_to: ("energy", "laplacian"),
                    chosen: ("energy", Energy::Arap.to_string()),
                    note: Some("cotangent weights"),
                });
            }
            if self.condition {
                out.push(Inapplicable {
                    option: RequestOption::Condition,
                    applies_to: ("energy", "laplacian"),
                    chosen: ("energy", Energy::Arap.to_string()),
                    note: None,
                });
            }
        }
        let method = o.solve.formulation.method;
        if o.solve.formulation.weight.is_some() && method != Method::Penalty {
            out.push(Inapplicable {
                option: RequestOption::Weight,
                applies_to: ("method", "penalty"),
                chosen: ("method", method.to_string()),
                note: None,
            });
        }
        if g.qr && method != Method::NullSpaceQr {
            out.push(Inapplicable {
                option: RequestOption::Qr,
                applies_to: ("method", "nullspace-qr"),
                chosen: ("method", method.to_string()),
                note: None,
            });
        }
        out
    }

    /// Checks the options before any work, without building a back end:
    /// the formulation's ([`crate::formulation::FormulationChoice::validate`]).
    pub fn validate(&self) -> Result<(), Error> {
        let solve = &self.options.solve;
        solve.formulation.validate(&solve.factor_storage)?;
        Ok(())
    }
}

/// A precomputed deformation: the Laplacian energy's deformer, or ARAP's
/// (initialised, before its iterations).
pub enum Factored {
    /// The Laplacian energy.
    Linear(Box<Deformer>),
    /// ARAP.
    Arap(Box<ArapDeformer>),
}

/// What [`deform`] computed.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The rest mesh.
    pub mesh: Mesh,
    /// The deformed positions, in the mesh's units.
    pub positions: Vec<[f64; 3]>,
    /// The report.
    pub report: Report,
    /// ARAP's iterations (with [`Energy::Arap`]).
    pub arap: Option<ArapReport>,
    /// Whether the request was strict.
    strict: bool,
}

/// Set-up and precompute of `request` on `mesh` with `constraints` (for
/// ARAP also its initial guess), after [`Request::validate`].
pub(crate) fn prepare(
    mesh: Mesh,
    constraints: ConstraintSet,
    request: &Request,
) -> Result<Factored, Error> {
    request.validate()?;
    let o = &request.options;
    match o.energy {
        Energy::Arap => {
            let mut arap = ArapDeformer::new(mesh, constraints, request.arap.energy, &o.solve)?;
            arap.initialize(request.arap.init)?;
            Ok(Factored::Arap(Box::new(arap)))
        }
        Energy::Laplacian => {
            let deformer = Deformer::new(mesh, o.laplacian, constraints, &o.solve)?;
            Ok(Factored::Linear(Box::new(deformer)))
        }
    }
}

/// The whole deformation: [`prepare`], then the solve (or ARAP's
/// iterations). Strictness is not an error here: [`Outcome::verdict`]
/// says, so that a door can show the report first.
pub fn deform(mesh: Mesh, constraints: ConstraintSet, request: &Request) -> Result<Outcome, Error> {
    let strict = request.options.strict;
    match prepare(mesh, constraints, request)? {
        Factored::Linear(mut deformer) => {
            if request.condition {
                deformer.solver_mut().estimate_condition()?;
            }
            let solution = deformer.solve()?;
            Ok(Outcome {
                mesh: deformer.mesh().clone(),
                positions: solution.positions,
                report: solution.report,
                arap: None,
                strict,
            })
        }
        Factored::Arap(mut arap) => {
            let history = arap.run(request.arap.iterations, request.arap.tolerance)?;
            Ok(Outcome {
                mesh: arap.mesh().clone(),
                positions: arap.positions(),
                report: arap.report().clone(),
                arap: Some(history),
                strict,
            })
        }
    }
}

impl Outcome {
    /// With a strict request: a conflicting hard constraint is an error
    /// ([`ConstraintError::Conflicting`], naming the first), and then, for
    /// the Laplacian energy, an estimated forward error above
    /// [`FORWARD_ERROR_WARNING`] (or not a number) is one
    /// ([`NumericalError::LostAccuracy`]). ARAP's estimate is of its last
    /// global step, not of the ARAP solution, so only its conflicts count.
    /// `Ok` otherwise, and always without `strict`.
    pub fn verdict(&self) -> Result<(), Error> {
        match (self.strict, &self.arap) {
            (false, _) => Ok(()),
            (true, Some(_)) => strict_conflicts(&self.report),
            (true, None) => strict_verdict(&self.report),
        }
    }
}

/// [`Outcome::verdict`] of a strict request's `report` (also for the
/// `solve` command's general problems).
pub(crate) fn strict_verdict(report: &Report) -> Result<(), Error> {
    strict_conflicts(report)?;
    let estimate = report.forward_error_estimate.unwrap_or(0.0);
    if estimate.is_nan() || estimate > FORWARD_ERROR_WARNING {
        return Err(NumericalError::LostAccuracy {
            matrix: format!("{} (strict)", report.method),
            estimate,
            tolerance: FORWARD_ERROR_WARNING,
            advice: crate::solver::lost_accuracy_advice(report.method, report.refinement.as_ref()),
        }
        .into());
    }
    Ok(())
}

/// A strict request's conflicts: the first conflicting hard constraint
/// (with the count of the others) as [`ConstraintError::Conflicting`].
pub(crate) fn strict_conflicts(report: &Report) -> Result<(), Error> {
    if let Some(first) = report.conflicting.first() {
        let count = report.conflicting.len();
        let sentence = report
            .warnings
            .iter()
            .find(|w| {
                matches!(
                    w.subject,
                    Some(WarningSubject::ConflictingConstraint { index, .. }) if index == first.index
                )
            })
            .map(|w| w.message.clone())
            .unwrap_or_else(|| {
                format!(
                    "constraint {} conflicts with earlier constraints (residual {:.3e})",
                    first.index, first.residual
                )
            });
        let detail = if count > 1 {
            format!("{sentence}; and {} more", count - 1)
        } else {
            sentence
        };
        return Err(ConstraintError::Conflicting { count, detail }.into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_given_options_that_do_not_apply_are_listed() {
        let mut r = Request::default();
        assert!(r.inapplicable().is_empty());
        r.given = Given {
            laplacian: true,
            iterations: true,
            qr: true,
            ..Given::default()
        };
        // Laplacian energy, null-space method: the iterations do not apply.
        let listed: Vec<RequestOption> = r.inapplicable().iter().map(|i| i.option).collect();
        assert_eq!(listed, vec![RequestOption::Iterations]);
        r.options.energy = Energy::Arap;
        r.options.solve.formulation.method = Method::Kkt;
        r.options.solve.formulation.weight = Some(1.0);
        let listed: Vec<RequestOption> = r.inapplicable().iter().map(|i| i.option).collect();
        assert_eq!(
            listed,
            vec![
                RequestOption::Laplacian,
                RequestOption::Weight,
                RequestOption::Qr
            ]
        );
        assert_eq!(r.inapplicable()[1].chosen, ("method", "kkt".to_string()));
    }
}
