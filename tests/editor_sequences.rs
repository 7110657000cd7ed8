//! Sequences of editor requests, some of them concurrent, against a model
//! of the session: what the constraints, the settings and the group
//! transforms must be after each step, and therefore what every answer's
//! status, `/api/report`'s settings and generation, `/api/constraints` and
//! the f64 positions must be. The positions are checked against the
//! library's own full solve of the model's state (a fresh `Deformer`, no
//! basis), so a lost update, a transform applied to stale constraints or a
//! basis that drifted from the solve all show.
//!
//! The requests go through the whole service in process
//! ([`InProcessEditor`]): token, `Host` check, body reading, JSON errors.
#![cfg(feature = "editor")]

use std::collections::BTreeMap;

use lse_deform::constraints::{Constraint, ConstraintKind, ConstraintSet, parse_constraints};
use lse_deform::deform::{Affine, Deformer};
use lse_deform::editor::EditOptions;
use lse_deform::editor::in_process::{Body, InProcessEditor, http};
use lse_deform::formulation::{FormulationChoice, Refine};
use lse_deform::laplacian::LaplacianKind;
use lse_deform::mesh::{Mesh, generate};
use proptest::prelude::*;
use serde_json::{Value, json};

const NX: usize = 5;

fn mesh() -> Mesh {
    generate::grid(NX, NX).unwrap()
}

/// The constraint files a sequence uploads.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Scene {
    /// Bottom row "fixed", top row "handle".
    Rows,
    /// Bottom row "fixed", top corners "left" and "right", a soft centre.
    Corners,
    /// No constraints: the mesh at rest.
    Empty,
}

fn constraints(scene: Scene) -> ConstraintSet {
    let m = mesh();
    let p = m.positions();
    let top = NX * (NX + 1);
    let mut pins: Vec<(usize, &str)> = (0..=NX).map(|v| (v, "fixed")).collect();
    match scene {
        Scene::Rows => pins.extend((0..=NX).map(|v| (top + v, "handle"))),
        Scene::Corners => pins.extend([(top, "left"), (top + NX, "right")]),
        Scene::Empty => pins.clear(),
    }
    let mut cs = ConstraintSet::new();
    for (vertex, group) in pins {
        let mut c = Constraint::hard(ConstraintKind::Position {
            vertex,
            target: p[vertex],
        });
        c.group = Some(group.into());
        cs.push(c).unwrap();
    }
    if scene == Scene::Corners {
        let centre = (NX / 2) * (NX + 1) + NX / 2;
        let mut c = Constraint::soft(
            ConstraintKind::Position {
                vertex: centre,
                target: [p[centre][0], p[centre][1], 0.3],
            },
            2.0,
        );
        c.group = Some("soft".into());
        cs.push(c).unwrap();
    }
    cs
}

/// A settings field the page may change, and its value.
#[derive(Debug, Clone, PartialEq)]
enum Field {
    Laplacian(&'static str),
    Method(&'static str),
    Weight(f64),
    Refine(&'static str),
}

impl Field {
    fn key(&self) -> &'static str {
        match self {
            Field::Laplacian(_) => "laplacian",
            Field::Method(_) => "method",
            Field::Weight(_) => "weight",
            Field::Refine(_) => "refine",
        }
    }

    fn body(&self) -> Value {
        match self {
            Field::Laplacian(w) | Field::Method(w) | Field::Refine(w) => json!({self.key(): w}),
            Field::Weight(w) => json!({"weight": w}),
        }
    }
}

/// One request.
#[derive(Debug, Clone)]
enum Op {
    PutConstraints(Scene),
    /// A constraints body the server must refuse (400), changing nothing.
    PutBadConstraints(&'static str),
    PutSettings(Field),
    /// A settings body the server must refuse (400), changing nothing.
    PutBadSettings(Value),
    Transform(&'static str, Affine),
    /// A transform that would put targets beyond f32 (422).
    TransformBeyondF32(&'static str),
}

/// What the session must hold.
#[derive(Debug, Clone)]
struct Model {
    scene: Scene,
    laplacian: &'static str,
    method: &'static str,
    weight: f64,
    refine: &'static str,
    transforms: BTreeMap<&'static str, Affine>,
    generation: u64,
}

impl Model {
    fn new() -> Model {
        Model {
            scene: Scene::Empty,
            laplacian: "cotan",
            method: "nullspace-qr",
            weight: 1e3,
            refine: "auto",
            transforms: BTreeMap::new(),
            generation: 0,
        }
    }

    fn groups(&self) -> &'static [&'static str] {
        match self.scene {
            Scene::Rows => &["fixed", "handle"],
            Scene::Corners => &["fixed", "left", "right", "soft"],
            Scene::Empty => &[],
        }
    }

    /// Applies `op`; the status it must get.
    fn apply(&mut self, op: &Op) -> u16 {
        match op {
            Op::PutConstraints(scene) => {
                self.scene = *scene;
                self.changed()
            }
            Op::PutSettings(field) => {
                match *field {
                    Field::Laplacian(w) => self.laplacian = w,
                    Field::Method(w) => self.method = w,
                    Field::Weight(w) => self.weight = w,
                    Field::Refine(w) => self.refine = w,
                }
                self.changed()
            }
            Op::PutBadConstraints(_) | Op::PutBadSettings(_) => 400,
            Op::Transform(group, m) => {
                if !self.groups().contains(group) {
                    return 400;
                }
                self.transforms.insert(group, *m);
                200
            }
            Op::TransformBeyondF32(group) => {
                if self.groups().contains(group) {
                    422
                } else {
                    400
                }
            }
        }
    }

    fn changed(&mut self) -> u16 {
        self.transforms.clear();
        self.generation += 1;
        200
    }

    /// The library's full solve of this state (no basis).
    fn positions(&self) -> Vec<[f64; 3]> {
        let cs = constraints(self.scene);
        if cs.is_empty() {
            return mesh().positions().to_vec();
        }
        let laplacian: LaplacianKind = self.laplacian.parse().unwrap();
        let mut deformer =
            Deformer::new(mesh(), laplacian, cs, &lse_deform::SolveOptions::default()).unwrap();
        deformer
            .solver_mut()
            .set_refine(Some(self.refine.parse::<Refine>().unwrap()));
        let choice = FormulationChoice {
            weight: Some(self.weight),
            ..FormulationChoice::new(self.method.parse().unwrap())
        };
        deformer
            .refactor_with(
                choice.build().unwrap().as_ref(),
                &lse_deform::resources::Resources::default(),
            )
            .unwrap();
        for (group, m) in &self.transforms {
            deformer.transform_group(group, m).unwrap();
        }
        deformer.solve().unwrap().positions
    }
}

fn body(op: &Op) -> (&'static str, &'static str, Vec<u8>) {
    let json = |v: Value| serde_json::to_vec(&v).unwrap();
    match op {
        Op::PutConstraints(s) => ("PUT", "/api/constraints", constraints(*s).to_json().into()),
        Op::PutBadConstraints(text) => ("PUT", "/api/constraints", text.as_bytes().to_vec()),
        Op::PutSettings(f) => ("PUT", "/api/settings", json(f.body())),
        Op::PutBadSettings(v) => ("PUT", "/api/settings", json(v.clone())),
        Op::Transform(g, m) => (
            "POST",
            "/api/transform",
            json(json!({"group": g, "matrix": m})),
        ),
        Op::TransformBeyondF32(g) => {
            let m = [
                [1.0, 0.0, 0.0, 1e39],
                [0.0, 1.0, 0.0, 0.0],
                [0.0, 0.0, 1.0, 0.0],
            ];
            (
                "POST",
                "/api/transform",
                json(json!({"group": g, "matrix": m})),
            )
        }
    }
}

fn send(editor: &InProcessEditor, op: &Op) -> (u16, Value) {
    let (method, path, bytes) = body(op);
    let a = editor.answer(editor.request(method, path, bytes));
    let v: Value = serde_json::from_slice(&a.body).unwrap_or(Value::Null);
    (a.status.as_u16(), v)
}

/// The session matches `model`: settings, generation, constraints and the
/// positions (to 1e-9 of the grid's unit size).
fn check(editor: &InProcessEditor, model: &Model) {
    let r = editor.answer(editor.request("GET", "/api/report", ""));
    assert_eq!(r.status, 200);
    let report: Value = serde_json::from_slice(&r.body).unwrap();
    let settings = &report["editor"]["settings"];
    assert_eq!(settings["laplacian"], model.laplacian, "{report}");
    assert_eq!(settings["method"], model.method, "{report}");
    assert_eq!(settings["weight"], model.weight, "{report}");
    assert_eq!(settings["refine"], model.refine, "{report}");
    assert_eq!(report["editor"]["generation"], model.generation, "{report}");

    let c = editor.answer(editor.request("GET", "/api/constraints", ""));
    let served = parse_constraints(std::str::from_utf8(&c.body).unwrap()).unwrap();
    assert_eq!(served.to_json(), constraints(model.scene).to_json());

    let p = editor.answer(editor.request("GET", "/api/positions?format=f64", ""));
    assert_eq!(p.status, 200);
    let got: Vec<f64> = p
        .body
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
        .collect();
    let want = model.positions();
    assert_eq!(got.len(), 3 * want.len());
    let worst = want
        .iter()
        .flatten()
        .zip(&got)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        worst <= 1e-9,
        "positions differ by {worst:e} from the model's solve: {model:?}"
    );
}

fn affine() -> impl Strategy<Value = Affine> {
    (-0.8f64..0.8, -0.5f64..0.5, -0.5f64..0.5, -0.5f64..0.5).prop_map(|(a, x, y, z)| {
        let (c, s) = (a.cos(), a.sin());
        [[c, -s, 0.0, x], [s, c, 0.0, y], [0.0, 0.0, 1.0, z]]
    })
}

fn field() -> impl Strategy<Value = Field> {
    prop_oneof![
        prop::sample::select(vec!["uniform", "cotan", "cotan-symmetric"])
            .prop_map(Field::Laplacian),
        prop::sample::select(vec!["nullspace-qr", "kkt", "eliminate", "penalty"])
            .prop_map(Field::Method),
        prop::sample::select(vec![10.0, 1e3, 1e5]).prop_map(Field::Weight),
        prop::sample::select(vec!["off", "auto", "2"]).prop_map(Field::Refine),
    ]
}

const GROUPS: &[&str] = &["fixed", "handle", "left", "right", "soft", "nobody"];

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        2 => prop::sample::select(vec![Scene::Rows, Scene::Corners, Scene::Empty])
            .prop_map(Op::PutConstraints),
        1 => prop::sample::select(vec![
            "{\"constraints\": [",
            "{\"constraints\": [{\"type\": \"position\", \"vertex\": 100000, \"target\": [0, 0, 0]}]}",
            "[1, 2, 3]",
        ])
        .prop_map(Op::PutBadConstraints),
        3 => field().prop_map(Op::PutSettings),
        1 => prop::sample::select(vec![
            json!({"method": "magic"}),
            json!({"weight": -1.0}),
            json!({"colour": 1}),
            json!({"laplacian": 3}),
            json!({"refine": "sometimes"}),
        ])
        .prop_map(Op::PutBadSettings),
        5 => (prop::sample::select(GROUPS.to_vec()), affine())
            .prop_map(|(g, m)| Op::Transform(g, m)),
        1 => prop::sample::select(GROUPS.to_vec()).prop_map(Op::TransformBeyondF32),
    ]
}

/// A step: one request, or several sent at once whose result does not
/// depend on their order (settings changes of distinct fields, transforms
/// of distinct groups).
#[derive(Debug, Clone)]
enum Step {
    One(Op),
    Together(Vec<Op>),
}

fn step() -> impl Strategy<Value = Step> {
    prop_oneof![
        3 => op().prop_map(Step::One),
        1 => prop::collection::vec(field(), 2..=4).prop_map(|fields| {
            let mut seen = Vec::new();
            Step::Together(
                fields
                    .into_iter()
                    .filter(|f| {
                        let new = !seen.contains(&f.key());
                        seen.push(f.key());
                        new
                    })
                    .map(Op::PutSettings)
                    .collect(),
            )
        }),
        1 => prop::collection::vec(affine(), 2..=3).prop_map(|ms| {
            Step::Together(
                ["left", "right", "handle"]
                    .into_iter()
                    .zip(ms)
                    .map(|(g, m)| Op::Transform(g, m))
                    .collect(),
            )
        }),
    ]
}

fn run(editor: &InProcessEditor, model: &mut Model, step: &Step) {
    match step {
        Step::One(op) => {
            let want = model.apply(op);
            let (status, answer) = send(editor, op);
            assert_eq!(status, want, "{op:?}: {answer}");
            if status >= 400 {
                assert!(
                    answer["error"].is_string() && answer["kind"].is_string(),
                    "{answer}"
                );
            }
        }
        Step::Together(ops) => {
            let statuses: Vec<(u16, Value)> = std::thread::scope(|s| {
                let handles: Vec<_> = ops.iter().map(|op| s.spawn(|| send(editor, op))).collect();
                handles.into_iter().map(|h| h.join().unwrap()).collect()
            });
            for (op, (status, answer)) in ops.iter().zip(statuses) {
                let want = model.apply(op);
                assert_eq!(
                    status, want,
                    "{op:?} (sent together with {ops:?}): {answer}"
                );
            }
        }
    }
    check(editor, model);
}

fn editor() -> InProcessEditor {
    let options = EditOptions {
        mesh: "grid.obj".into(),
        constraints: None,
        host: "127.0.0.1".into(),
        port: 0,
        max_body_bytes: 1 << 20,
        token: None,
        body_timeout: std::time::Duration::from_secs(10),
        idle_timeout: std::time::Duration::from_secs(10),
    };
    InProcessEditor::new(mesh(), None, &options, "a".repeat(32)).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn request_sequences_follow_the_session_model(steps in prop::collection::vec(step(), 1..10)) {
        let editor = editor();
        let mut model = Model::new();
        check(&editor, &model);
        for step in &steps {
            run(&editor, &mut model, step);
        }
    }
}

/// Fixed case: two settings changes sent at once both take effect (the
/// read-modify-write of each is serialised); before, one was lost.
#[test]
fn concurrent_settings_changes_are_both_applied_in_process() {
    let editor = editor();
    let mut model = Model::new();
    run(
        &editor,
        &mut model,
        &Step::One(Op::PutConstraints(Scene::Rows)),
    );
    for _ in 0..5 {
        let together = Step::Together(vec![
            Op::PutSettings(Field::Method(if model.method == "kkt" {
                "eliminate"
            } else {
                "kkt"
            })),
            Op::PutSettings(Field::Laplacian(if model.laplacian == "uniform" {
                "cotan"
            } else {
                "uniform"
            })),
        ]);
        run(&editor, &mut model, &together);
    }
}

/// Without the token, or under a foreign `Host`, nothing is answered but
/// the refusal, and the session is unchanged.
#[test]
fn the_in_process_service_keeps_the_guard() {
    let editor = editor();
    let body = constraints(Scene::Rows).to_json();
    let no_token = axum_request(
        "PUT",
        "/api/constraints",
        &body,
        &[("host", "127.0.0.1:8765")],
    );
    assert_eq!(editor.answer(no_token).status, 401);
    let foreign = axum_request(
        "PUT",
        "/api/constraints",
        &body,
        &[
            ("host", "evil.example:8765"),
            ("authorization", &format!("Bearer {}", editor.token())),
        ],
    );
    assert_eq!(editor.answer(foreign).status, 403);
    check(&editor, &Model::new());
}

fn axum_request(
    method: &str,
    path: &str,
    body: &str,
    headers: &[(&str, &str)],
) -> http::Request<Body> {
    let mut r = http::Request::builder()
        .method(method)
        .uri(path)
        .header("content-type", "application/json");
    for (k, v) in headers {
        r = r.header(*k, *v);
    }
    r.body(body.to_string().into()).unwrap()
}
