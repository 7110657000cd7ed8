//! The editing state of `lse-deform edit`: the mesh, the constraints as
//! uploaded, the settings, and the engine they were precomputed into. No
//! numerics here: it calls [`Deformer`], [`HandleBasis`] and
//! [`ArapDeformer`] and keeps their results.

use std::collections::BTreeMap;
use std::time::Instant;

use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use crate::arap::ArapDeformer;
use crate::choice::{Energy, Method, deserialize_word};
use crate::constraints::ConstraintSet;
use crate::deform::{Affine, Deformer, GroupTargets};
use crate::error::{Error, ProblemError};
use crate::formulation::Refine;
use crate::handle::HandleBasis;
use crate::laplacian::LaplacianKind;
use crate::mesh::Mesh;
use crate::options::{
    DeformOptions, INTERACTIVE_ARAP_ITERATIONS_PER_FRAME, SUGGESTED_PENALTY_WEIGHT,
};
use crate::request::{self, Factored, Request};
use crate::resources::{OrderingWord, Threads};
use crate::solver::SolveOptions;

/// The group that never moves in a drag: left out of the response basis
/// (moving it falls back to full solves).
pub const FIXED_GROUP: &str = "fixed";

/// The most movable groups (other than [`FIXED_GROUP`]) the response basis
/// takes: each adds four solved columns of `n` numbers, built at every
/// change and read at every frame (past a few dozen groups a frame costs
/// more than a full solve). More is refused with
/// [`ProblemError::TooLarge`] before any work, as is a basis beyond the
/// memory budget ([`HandleBasis::estimated_bytes`]).
pub const MAX_BASIS_GROUPS: usize = 256;

/// The switches of the page, typed; read and written as the CLI's words.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Settings {
    /// uniform, cotan, cotan-symmetric or intrinsic-delaunay.
    #[serde(deserialize_with = "deserialize_word")]
    pub laplacian: LaplacianKind,
    /// nullspace-qr, penalty, kkt or eliminate.
    #[serde(deserialize_with = "deserialize_word")]
    pub method: Method,
    /// The penalty weight.
    pub weight: f64,
    /// off, auto or a step count.
    #[serde(deserialize_with = "deserialize_word")]
    pub refine: Refine,
    /// laplacian or arap.
    #[serde(deserialize_with = "deserialize_word")]
    pub energy: Energy,
    /// ARAP iterations per frame during a drag.
    pub arap_iterations_per_frame: usize,
    /// The factorisation's fill-reducing ordering: own, amd, metis or
    /// natural (docs/equal-terms.md §2); own when not given.
    #[serde(default = "own_ordering", deserialize_with = "deserialize_word")]
    pub ordering: OrderingWord,
    /// The factorisation's threads: own, or a count (a JSON number, or
    /// the count as a word); own when not given.
    #[serde(
        default,
        deserialize_with = "deserialize_threads",
        serialize_with = "serialize_threads"
    )]
    pub threads: Threads,
}

/// [`Settings::ordering`] when not given.
fn own_ordering() -> OrderingWord {
    OrderingWord::Own
}

/// [`Settings::threads`] from `"own"`, a count as a word, or a number.
fn deserialize_threads<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Threads, D::Error> {
    match Value::deserialize(d)? {
        Value::String(word) => word.parse().map_err(serde::de::Error::custom),
        Value::Number(n) => n
            .as_u64()
            .and_then(|n| usize::try_from(n).ok())
            .and_then(Threads::count)
            .ok_or_else(|| {
                serde::de::Error::custom(format!(
                    "threads: expected own or a positive count up to {}, got {n}",
                    crate::resources::MAX_THREADS
                ))
            }),
        other => Err(serde::de::Error::custom(format!(
            "threads: expected own or a positive count, got {other}"
        ))),
    }
}

/// [`Settings::threads`] as the page shows it: `"own"` or the count.
fn serialize_threads<S: serde::Serializer>(threads: &Threads, s: S) -> Result<S::Ok, S::Error> {
    match threads.requested() {
        Some(n) => s.serialize_u64(n as u64),
        None => s.serialize_str("own"),
    }
}

impl Default for Settings {
    /// The library's defaults ([`DeformOptions::default`]); the fields the
    /// page always shows a value for take the library's suggestions: the
    /// penalty weight [`SUGGESTED_PENALTY_WEIGHT`], the refinement
    /// [`Refine::default`] (what the default method resolves `None` to) and
    /// [`INTERACTIVE_ARAP_ITERATIONS_PER_FRAME`].
    fn default() -> Self {
        let d = DeformOptions::default();
        Settings {
            laplacian: d.laplacian,
            method: d.solve.formulation.method,
            weight: d
                .solve
                .formulation
                .weight
                .unwrap_or(SUGGESTED_PENALTY_WEIGHT),
            refine: d.solve.refine.unwrap_or_default(),
            energy: d.energy,
            arap_iterations_per_frame: INTERACTIVE_ARAP_ITERATIONS_PER_FRAME,
            ordering: OrderingWord::Own,
            threads: d.solve.resources.threads,
        }
    }
}

fn invalid(message: String) -> Error {
    ProblemError::InvalidArgument { message }.into()
}

impl Settings {
    /// The options over [`DeformOptions::default`]: the energy, the
    /// Laplacian, the formulation of `method` with the default back ends
    /// (and `weight` for the penalty method), checked; the refinement.
    pub fn options(&self) -> Result<DeformOptions, Error> {
        let mut options = DeformOptions {
            energy: self.energy,
            laplacian: self.laplacian,
            ..DeformOptions::default()
        };
        options.solve.formulation.method = self.method;
        options.solve.formulation.weight = Some(self.weight);
        options
            .solve
            .formulation
            .validate(&options.solve.factor_storage)?;
        options.solve.refine = Some(self.refine);
        options.solve.resources.ordering = self.ordering.into();
        options.solve.resources.threads = self.threads;
        Ok(options)
    }

    /// These settings with `fields` replaced (any of the fields above; an
    /// unknown field, a wrong type or an unknown word is an error naming
    /// it).
    pub fn with(&self, fields: serde_json::Map<String, Value>) -> Result<Settings, Error> {
        let mut current = serde_json::to_value(self).unwrap_or(Value::Null);
        for (k, v) in fields {
            current[k] = v;
        }
        serde_json::from_value(current).map_err(|e| invalid(format!("settings: {e}")))
    }

    /// Checks what the types do not: the formulation can be built, the
    /// ordering is in this build, and the iteration count.
    pub fn check(&self) -> Result<(), Error> {
        let options = self.options()?;
        // Kept while there are no constraints: refused now, not at the
        // first change that factors.
        options.solve.resources.ordering.check_in_build()?;
        // Checked whatever the method: a weight kept for a later switch to
        // `penalty` must already be one.
        if !(self.weight.is_finite() && self.weight > 0.0) {
            return Err(invalid(format!(
                "weight {} must be a finite positive number",
                self.weight
            )));
        }
        if !(1..=100).contains(&self.arap_iterations_per_frame) {
            return Err(invalid(format!(
                "arap_iterations_per_frame {} must be in 1..=100",
                self.arap_iterations_per_frame
            )));
        }
        Ok(())
    }
}

/// What the constraints were precomputed into.
pub enum Engine {
    /// Laplacian editing: the deformer (targets, full solves) and the
    /// response basis of the groups other than [`FIXED_GROUP`].
    Linear {
        /// The deformer.
        deformer: Box<Deformer>,
        /// `None` when there is no movable group.
        basis: Option<HandleBasis>,
        /// A group outside the basis moved: frames are full solves.
        basis_stale: bool,
    },
    /// ARAP: the groups' targets, moved as [`Deformer::transform_group`]
    /// moves them.
    Arap {
        /// Targets of the groups.
        targets: GroupTargets,
        /// The iterations.
        arap: Box<ArapDeformer>,
    },
}

/// A precomputed engine with its first positions and report.
pub struct Built {
    /// The engine.
    pub engine: Engine,
    /// Positions at rest targets.
    pub positions: Vec<[f64; 3]>,
    /// The report of the first positions (their diagnostics).
    pub report: Value,
    /// Seconds of each phase.
    pub timings: Value,
}

/// Set-up, precompute, response basis and the first positions of
/// `constraints` on `mesh` with `settings` (the basis at the identity, with
/// their diagnostics; a solve when nothing but `fixed` is grouped); `stage`
/// is told each phase's name. The library's request layer
/// ([`crate::request::prepare`]) picks the energy and runs its set-up and
/// precompute (ARAP's initial guess included).
pub fn build(
    mesh: &Mesh,
    constraints: &ConstraintSet,
    settings: &Settings,
    stage: &dyn Fn(&str),
) -> Result<Built, Error> {
    settings.check()?;
    let t0 = Instant::now();
    let options = settings.options()?;
    let request = Request {
        options: DeformOptions {
            solve: SolveOptions {
                // ARAP refines with the formulation's default, as it
                // always has.
                refine: match options.energy {
                    Energy::Arap => None,
                    Energy::Laplacian => options.solve.refine,
                },
                ..options.solve.clone()
            },
            ..options.clone()
        },
        ..Request::default()
    };
    stage(match options.energy {
        Energy::Arap => "set-up and ARAP precompute",
        Energy::Laplacian => "set-up and precompute (factorisation)",
    });
    match request::prepare(mesh.clone(), constraints.clone(), &request)? {
        Factored::Arap(arap) => build_arap(*arap, settings, t0),
        Factored::Linear(deformer) => build_linear(*deformer, &options, t0, stage),
    }
}

/// [`build`] for ARAP (precomputed and initialised by the request layer):
/// `arap_iterations_per_frame` iterations; `targets` computes the groups'
/// targets.
fn build_arap(mut arap: ArapDeformer, settings: &Settings, t0: Instant) -> Result<Built, Error> {
    let targets = GroupTargets::new(arap.constraints().clone(), arap.length_unit());
    arap.iterate(settings.arap_iterations_per_frame)?;
    let report = arap.finish()?;
    let timings = json!({
        "setup_s": report.timings_s.setup,
        "precompute_s": report.timings_s.precompute(),
        "ready_s": t0.elapsed().as_secs_f64(),
    });
    let report = serde_json::to_value(report).unwrap_or(Value::Null);
    let positions = arap.positions();
    Ok(Built {
        engine: Engine::Arap {
            targets,
            arap: Box::new(arap),
        },
        positions,
        report,
        timings,
    })
}

/// [`build`] for the Laplacian energy (precomputed by the request layer):
/// the response basis of the movable groups and the first positions.
fn build_linear(
    mut deformer: Deformer,
    options: &DeformOptions,
    t0: Instant,
    stage: &dyn Fn(&str),
) -> Result<Built, Error> {
    let groups = deformer.constraints().group_names();
    let movable: Vec<String> = groups
        .into_iter()
        .filter(|g| *g != FIXED_GROUP)
        .map(str::to_string)
        .collect();
    let movable: Vec<&str> = movable.iter().map(String::as_str).collect();
    check_basis_size(&deformer, movable.len(), options.solve.resources.budget)?;
    let (setup_s, precompute_s) = {
        let t = &deformer.report().timings_s;
        (t.setup, t.precompute())
    };
    stage("response basis");
    let t = Instant::now();
    let basis = if movable.is_empty() {
        None
    } else {
        Some(HandleBasis::new(&mut deformer, &movable)?)
    };
    let basis_s = t.elapsed().as_secs_f64();
    let (positions, report) = first_positions(&mut deformer, basis.as_ref(), stage)?;
    Ok(Built {
        engine: Engine::Linear {
            deformer: Box::new(deformer),
            basis,
            basis_stale: false,
        },
        positions,
        report: serde_json::to_value(&report).unwrap_or(Value::Null),
        timings: json!({
            "setup_s": setup_s,
            "precompute_s": precompute_s,
            "basis_s": basis_s,
            "ready_s": t0.elapsed().as_secs_f64(),
        }),
    })
}

/// The positions with every group at rest, and their report: the basis at
/// the identity (to its forward error, which the report then carries), or
/// a solve when there is no basis.
fn first_positions(
    deformer: &mut Deformer,
    basis: Option<&HandleBasis>,
    stage: &dyn Fn(&str),
) -> Result<(Vec<[f64; 3]>, crate::report::Report), Error> {
    match basis {
        Some(b) => {
            stage("diagnostics");
            let mut positions = vec![[0.0; 3]; deformer.mesh().n_vertices()];
            b.evaluate(&vec![IDENTITY; b.groups().len()], &mut positions)?;
            let u = deformer.length_unit();
            let x = faer::Mat::from_fn(positions.len(), 3, |i, c| positions[i][c] / u);
            Ok((
                positions,
                deformer.solver_mut().diagnose(x.as_ref()).clone(),
            ))
        }
        None => {
            stage("first solve");
            let solution = deformer.solve()?;
            Ok((solution.positions, solution.report))
        }
    }
}

/// Refuses a response basis of more than [`MAX_BASIS_GROUPS`] groups, or
/// one beyond the memory budget, before the precompute.
fn check_basis_size(
    deformer: &Deformer,
    groups: usize,
    budget: crate::limits::MemoryBudget,
) -> Result<(), Error> {
    let problem = deformer.problem();
    let (n, l, m) = (problem.n(), problem.c().nrows(), problem.d().nrows());
    if groups > MAX_BASIS_GROUPS {
        let bytes = HandleBasis::estimated_bytes(n, l, m, groups);
        return Err(ProblemError::TooLarge {
            detail: format!(
                "{groups} movable constraint groups, more than the {MAX_BASIS_GROUPS} the editor's response basis takes (each adds 4 solved columns of {n} numbers, read at every frame; about {} here): give fewer distinct group names",
                crate::limits::format_bytes(bytes)
            ),
        }
        .into());
    }
    HandleBasis::check_memory(n, l, m, groups, budget)
}

/// How a frame was computed.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum FramePath {
    /// `X₀ + Σ R_g M_gᵀ`.
    Basis,
    /// A solve with the existing factor.
    FullSolve,
    /// ARAP iterations warm-started from the last frame.
    Arap,
}

/// Why a frame was refused.
#[derive(Debug)]
pub enum FrameError {
    /// The library's refusal (no such group, no constraints yet, a failed
    /// solve).
    Engine(Error),
    /// The transform would put a target of the group beyond the range of
    /// f32, the format positions are sent in (and so would put the
    /// positions there); nothing changed.
    NotRepresentable(String),
}

impl From<Error> for FrameError {
    fn from(e: Error) -> Self {
        FrameError::Engine(e)
    }
}

impl std::fmt::Display for FrameError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FrameError::Engine(e) => e.fmt(f),
            FrameError::NotRepresentable(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for FrameError {}

/// Checks that the targets of group `name` in `constraints` (as a
/// transform by `m` set them) are finite in f32; if not, calls `revert`
/// (which moves the group back) and says why.
fn targets_in_f32(
    constraints: &ConstraintSet,
    name: &str,
    m: &Affine,
    revert: impl FnOnce() -> Result<(), Error>,
) -> Result<(), FrameError> {
    let far = constraints
        .group(name)
        .iter()
        .map(|&i| (i, constraints[i].kind.rhs()))
        .find(|(_, t)| t.iter().any(|&v| !(v as f32).is_finite()));
    if let Some((index, target)) = far {
        revert()?;
        return Err(FrameError::NotRepresentable(format!(
            "transform of group '{name}' by {m:?}: constraint {index}'s target would be {target:?}, beyond the range of f32 (±3.4e38) in which positions are sent; nothing changed"
        )));
    }
    Ok(())
}

/// The editing state.
pub struct Session {
    /// The mesh as loaded.
    pub mesh: Mesh,
    /// The constraints as uploaded (rest targets).
    pub constraints: ConstraintSet,
    /// The switches.
    pub settings: Settings,
    /// `None` until constraints pin every component.
    pub engine: Option<Engine>,
    /// The current positions.
    pub positions: Vec<[f64; 3]>,
    /// The current transform of each moved group.
    pub transforms: BTreeMap<String, Affine>,
    /// The report of the last precompute, with the editor's timings.
    pub report: Value,
    /// Seconds of the last frames' compute (most recent last, ≤ 1000).
    pub frame_times_s: Vec<f64>,
    /// Counts every change of constraints or settings.
    pub generation: u64,
}

/// The identity transform.
pub const IDENTITY: Affine = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
];

impl Session {
    /// A session on `mesh` with no engine yet.
    pub fn new(mesh: Mesh) -> Session {
        let positions = mesh.positions().to_vec();
        Session {
            mesh,
            constraints: ConstraintSet::new(),
            settings: Settings::default(),
            engine: None,
            positions,
            transforms: BTreeMap::new(),
            report: Value::Null,
            frame_times_s: Vec::new(),
            generation: 0,
        }
    }

    /// Installs a built engine for `constraints` and `settings`.
    pub(crate) fn install(&mut self, constraints: ConstraintSet, settings: Settings, built: Built) {
        self.constraints = constraints;
        self.settings = settings;
        self.engine = Some(built.engine);
        self.positions = built.positions;
        self.transforms.clear();
        self.frame_times_s.clear();
        let mut report = built.report;
        if let Value::Object(map) = &mut report {
            map.insert("editor".into(), json!({"timings_s": built.timings}));
        }
        self.report = report;
        self.generation += 1;
    }

    /// Back to no constraints: the mesh at rest.
    pub(crate) fn clear(&mut self) {
        self.constraints = ConstraintSet::new();
        self.engine = None;
        self.positions = self.mesh.positions().to_vec();
        self.transforms.clear();
        self.frame_times_s.clear();
        self.report = Value::Null;
        self.generation += 1;
    }

    /// Moves group `name` by `m` (applied to its rest targets) and
    /// recomputes the positions: by the response basis when it covers the
    /// group, else a full solve, or ARAP iterations. Returns the path taken
    /// and its seconds. A transform that would put a target of the group
    /// beyond f32 is refused ([`FrameError::NotRepresentable`]) and changes
    /// nothing.
    pub(crate) fn transform(
        &mut self,
        name: &str,
        m: &Affine,
    ) -> Result<(FramePath, f64), FrameError> {
        let iterations = self.settings.arap_iterations_per_frame;
        let engine = self.engine.as_mut().ok_or_else(|| {
            Error::from(ProblemError::BadUpdate {
                message: "no constraints yet: PUT /api/constraints first".into(),
            })
        })?;
        let t = Instant::now();
        let previous = self.transforms.get(name).copied().unwrap_or(IDENTITY);
        let path = match engine {
            Engine::Linear {
                deformer,
                basis,
                basis_stale,
            } => {
                deformer.transform_group(name, m)?;
                let constraints = deformer.constraints().clone();
                targets_in_f32(&constraints, name, m, || {
                    deformer.transform_group(name, &previous)
                })?;
                // X₀ holds the other groups at rest: the basis is valid
                // while every group outside it is at the identity.
                let in_basis = |g: &str| {
                    basis
                        .as_ref()
                        .is_some_and(|b| b.groups().iter().any(|h| h == g))
                };
                *basis_stale = self
                    .transforms
                    .iter()
                    .filter(|(g, _)| g.as_str() != name)
                    .map(|(g, t)| (g.as_str(), t))
                    .chain(std::iter::once((name, m)))
                    .any(|(g, t)| !in_basis(g) && *t != IDENTITY);
                match basis {
                    Some(b) if !*basis_stale => {
                        let ms: Vec<Affine> = b
                            .groups()
                            .iter()
                            .map(|g| {
                                if g == name {
                                    *m
                                } else {
                                    self.transforms.get(g).copied().unwrap_or(IDENTITY)
                                }
                            })
                            .collect();
                        b.evaluate(&ms, &mut self.positions)?;
                        FramePath::Basis
                    }
                    _ => {
                        self.positions = deformer.solve()?.positions;
                        FramePath::FullSolve
                    }
                }
            }
            Engine::Arap { targets, arap } => {
                targets.transform_group(name, m)?;
                let constraints = targets.constraints().clone();
                targets_in_f32(&constraints, name, m, || {
                    targets.transform_group(name, &previous).map(|_| ())
                })?;
                for i in targets.group_members(name)? {
                    arap.set_target(i, targets.constraints()[i].kind.rhs())?;
                }
                arap.iterate(iterations)?;
                self.positions = arap.positions();
                FramePath::Arap
            }
        };
        let seconds = t.elapsed().as_secs_f64();
        self.transforms.insert(name.to_string(), *m);
        if self.frame_times_s.len() >= 1000 {
            self.frame_times_s.remove(0);
        }
        self.frame_times_s.push(seconds);
        Ok((path, seconds))
    }

    /// More ARAP iterations at the current targets (converging after a
    /// drag stops); nothing for the Laplacian energy.
    pub(crate) fn iterate(&mut self, n: usize) -> Result<usize, Error> {
        if let Some(Engine::Arap { arap, .. }) = &mut self.engine {
            arap.iterate(n)?;
            self.positions = arap.positions();
            return Ok(n);
        }
        Ok(0)
    }

    /// The report with the current residuals (Laplacian: diagnosed at the
    /// current targets) and the editor's frame statistics.
    pub(crate) fn report(&mut self) -> Value {
        let mut report = self.report.clone();
        let fresh = match &mut self.engine {
            Some(Engine::Linear { deformer, .. }) => {
                let u = deformer.length_unit();
                let x =
                    faer::Mat::from_fn(self.positions.len(), 3, |i, c| self.positions[i][c] / u);
                serde_json::to_value(deformer.solver_mut().diagnose(x.as_ref())).ok()
            }
            Some(Engine::Arap { arap, .. }) => arap
                .finish()
                .ok()
                .and_then(|r| serde_json::to_value(r).ok()),
            None => None,
        };
        let editor = report.get("editor").cloned();
        if let Some(fresh) = fresh {
            report = fresh;
        }
        let mut times = self.frame_times_s.clone();
        times.sort_by(f64::total_cmp);
        let median = times.get(times.len() / 2).copied();
        let basis = match &self.engine {
            Some(Engine::Linear {
                basis: Some(b),
                basis_stale,
                ..
            }) => {
                json!({"groups": b.groups(), "bytes": b.bytes(), "build_s": b.build_time_s(), "forward_error_estimate": b.forward_error_estimate(), "stale": basis_stale})
            }
            _ => Value::Null,
        };
        if let Value::Object(map) = &mut report {
            let mut e = editor.filter(Value::is_object).unwrap_or_else(|| json!({}));
            e["frames"] = json!(self.frame_times_s.len());
            e["frame_median_s"] = json!(median);
            e["basis"] = basis;
            e["settings"] = serde_json::to_value(&self.settings).unwrap_or(Value::Null);
            e["generation"] = json!(self.generation);
            map.insert("editor".into(), e);
        } else {
            report = json!({"editor": {"settings": self.settings, "generation": self.generation}, "note": "no constraints yet"});
        }
        report
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The page's settings without a change are the library's defaults;
    /// only the values the page must always show are filled in (the
    /// penalty weight, the refinement the default method resolves to).
    #[test]
    fn default_settings_are_the_library_defaults() {
        let mut expected = DeformOptions::default();
        expected.solve.formulation.weight = Some(SUGGESTED_PENALTY_WEIGHT);
        expected.solve.refine = Some(Refine::Auto);
        assert_eq!(Settings::default().options().unwrap(), expected);
        assert_eq!(Settings::default().arap_iterations_per_frame, 2);
    }

    /// Ordering and threads: absent means own; a word or a number is
    /// read into the options; a count out of range and an unknown word
    /// are refused naming the field; what is written reads back.
    #[test]
    fn ordering_and_threads_settings_reach_the_options() {
        let fields = |v: Value| v.as_object().unwrap().clone();
        let d = Settings::default();
        let own = d.with(fields(json!({}))).unwrap();
        assert_eq!(own.options().unwrap().solve.resources, Default::default());
        let held = d
            .with(fields(json!({"ordering": "amd", "threads": 1})))
            .unwrap();
        let resources = held.options().unwrap().solve.resources;
        assert_eq!(resources.ordering, crate::resources::FillOrdering::Amd);
        assert_eq!(resources.threads, Threads::count(1).unwrap());
        assert_eq!(
            d.with(fields(json!({"threads": "2"}))).unwrap().threads,
            Threads::count(2).unwrap()
        );
        let written = serde_json::to_value(&held).unwrap();
        assert_eq!(written["threads"], 1);
        assert_eq!(written["ordering"], "amd");
        for bad in [
            json!({"threads": 0}),
            json!({"threads": 100000}),
            json!({"threads": -1}),
            json!({"threads": [1]}),
            json!({"ordering": "colamd"}),
        ] {
            let e = d.with(fields(bad.clone())).unwrap_err().to_string();
            let field = bad.as_object().unwrap().keys().next().unwrap().clone();
            assert!(e.contains(&field), "{bad}: {e}");
        }
    }
}
