//! The catalogue of bad inputs: one case per input class that users of
//! Laplacian-deformation code run into. Each case checks the error's
//! *kind* (its enum variant) and that its message names the offending
//! element: the line, face, vertex or constraint.
//!
//! The mesh and constraint cases run through the library. The problem and
//! numerical cases run through `Deformer`. The last test runs the binary:
//! exit codes 2 and 3, one line, no backtrace, and `--verbose`.

use std::io::Write;
use std::process::{Command, Output};

use proptest::prelude::Strategy;

use lse_deform::constraints::parse_constraints;
use lse_deform::error::{ConstraintError, Error, MeshError, NumericalError, ProblemError};
use lse_deform::mesh::{MeshFormat, generate, read_mesh_bytes};
use lse_deform::{
    Constraint, ConstraintSet, Deformer, LaplacianKind, Mesh, Method, QrKind,
    constraints::ConstraintKind, formulation::Formulation, formulation::FormulationChoice,
    formulation::Kkt, formulation::NullSpaceQr, formulation::Penalty,
};

// ---------------------------------------------------------------------------
// Meshes

fn mesh_err(text: &[u8], format: MeshFormat) -> MeshError {
    match read_mesh_bytes(text, format, lse_deform::limits::MemoryBudget::default()) {
        Ok(m) => panic!(
            "expected an error, got a mesh of {} vertices",
            m.mesh.n_vertices()
        ),
        Err(e) => e,
    }
}

/// Asserts that `e` is the expected variant and that its message contains
/// every word in `words`.
macro_rules! expect {
    ($e:expr, $pat:pat, $($word:expr),+) => {{
        let e = $e;
        assert!(matches!(e, $pat), "wrong kind: {e:?}");
        let msg = e.to_string();
        $(assert!(msg.contains($word), "expected {:?} in: {msg}", $word);)+
        msg
    }};
}

const TETRA_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
const TETRA_OFF: &str =
    "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
const TETRA_PLY: &str = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";

/// The null-space method with QR back end `qr` and the default SPD back end.
fn nullspace_qr_with(qr: QrKind) -> Box<dyn Formulation> {
    let choice = FormulationChoice {
        qr: qr.into(),
        ..FormulationChoice::new(Method::NullSpaceQr)
    };
    choice.build().unwrap()
}

#[test]
fn the_valid_files_of_this_catalogue_load() {
    // Otherwise the cases below would test nothing but typos.
    for (text, format) in [
        (TETRA_OBJ, MeshFormat::Obj),
        (TETRA_OFF, MeshFormat::Off),
        (TETRA_PLY, MeshFormat::Ply),
    ] {
        let m = read_mesh_bytes(
            text.as_bytes(),
            format,
            lse_deform::limits::MemoryBudget::default(),
        )
        .unwrap()
        .mesh;
        assert_eq!((m.n_vertices(), m.faces().len()), (4, 4));
    }
}

#[test]
fn empty_files() {
    for format in [MeshFormat::Obj, MeshFormat::Off, MeshFormat::Ply] {
        let e = mesh_err(b"", format);
        assert!(
            matches!(e, MeshError::Empty { .. } | MeshError::Parse { .. }),
            "{format:?}: {e:?}"
        );
    }
    expect!(
        mesh_err(b"", MeshFormat::Obj),
        MeshError::Empty {
            vertices: 0,
            faces: 0
        },
        "empty mesh"
    );
}

#[test]
fn truncated_files_name_the_line() {
    // OBJ cut inside the last vertex line (line 4: "v 0 0").
    let cut = &TETRA_OBJ[..TETRA_OBJ.find("v 0 0 1").unwrap() + 5];
    let e = mesh_err(cut.as_bytes(), MeshFormat::Obj);
    expect!(
        e,
        MeshError::Parse { line: Some(4), .. },
        "line 4",
        "coordinates"
    );
    // OFF cut after two faces: the header promised four.
    let cut = &TETRA_OFF[..TETRA_OFF.find("3 0 3 2").unwrap()];
    expect!(
        mesh_err(cut.as_bytes(), MeshFormat::Off),
        MeshError::Parse { .. },
        "OFF"
    );
    // ASCII PLY cut inside the face list.
    let cut = &TETRA_PLY[..TETRA_PLY.find("3 0 3 2").unwrap()];
    expect!(
        mesh_err(cut.as_bytes(), MeshFormat::Ply),
        MeshError::Parse { .. },
        "PLY"
    );
}

#[test]
fn binary_ply_with_a_wrong_element_count() {
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
    for v in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]] {
        for c in v {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    bytes.push(3);
    for i in [0i32, 1, 2] {
        bytes.extend_from_slice(&i.to_le_bytes());
    }
    // The header declares 5 vertices (60 bytes) + 1 face (13 bytes); 49 follow.
    let msg = expect!(
        mesh_err(&bytes, MeshFormat::Ply),
        MeshError::Parse { line: Some(3), .. },
        "5 'vertex'"
    );
    assert!(msg.contains("line 3"), "{msg}");
}

#[test]
fn polygons_are_fan_triangulated_with_a_note() {
    let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
    let loaded = read_mesh_bytes(
        quad.as_bytes(),
        MeshFormat::Obj,
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap();
    assert_eq!(loaded.mesh.faces(), &[[0, 1, 2], [0, 2, 3]]);
    assert!(
        loaded.notes.iter().any(|n| n.contains("triangulated")),
        "{:?}",
        loaded.notes
    );
    // A "face" of two vertices is refused.
    let e = mesh_err(
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2\n",
        MeshFormat::Obj,
    );
    expect!(
        e,
        MeshError::BadFaceSize {
            face: 1,
            sides: 2,
            line: Some(5)
        },
        "face 1",
        "line 5"
    );
}

#[test]
fn face_indices_out_of_range_negative_or_repeated() {
    let e = mesh_err(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", MeshFormat::Obj);
    expect!(
        e,
        MeshError::IndexOutOfRange {
            face: 0,
            index: 3,
            ..
        },
        "face 0",
        "line 4",
        "vertex 3"
    );
    // OBJ negative indices are relative (-1 = the last vertex), so only one
    // that reaches before the first vertex is out of range.
    let ok = read_mesh_bytes(
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n",
        MeshFormat::Obj,
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap();
    assert_eq!(ok.mesh.faces(), &[[0, 1, 2]]);
    let e = mesh_err(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 -2 -1\n", MeshFormat::Obj);
    expect!(
        e,
        MeshError::IndexOutOfRange { face: 0, .. } | MeshError::Parse { .. },
        "line 4"
    );
    // OFF has no relative indices: a negative one is an error.
    let off = b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n";
    expect!(
        mesh_err(off, MeshFormat::Off),
        MeshError::IndexOutOfRange { .. } | MeshError::Parse { .. },
        "line 6"
    );
    let e = mesh_err(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 2\n", MeshFormat::Obj);
    expect!(
        e,
        MeshError::RepeatedVertex {
            face: 0,
            vertex: 1,
            line: Some(4)
        },
        "face 0",
        "vertex 1"
    );
}

#[test]
fn non_finite_coordinates() {
    for (text, word) in [("nan", "NaN"), ("inf", "inf"), ("-inf", "-inf")] {
        let obj = format!("v 0 0 0\nv 1 {text} 0\nv 0 1 0\nf 1 2 3\n");
        let e = mesh_err(obj.as_bytes(), MeshFormat::Obj);
        expect!(
            e,
            MeshError::NonFiniteCoordinate {
                vertex: 1,
                line: Some(2),
                ..
            },
            "vertex 1",
            "line 2",
            word
        );
    }
    // The same through the constructor (no file line).
    let e = Mesh::new(
        vec![[0.0; 3], [1.0, 0.0, f64::NAN], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2]],
    )
    .unwrap_err();
    expect!(
        e,
        MeshError::NonFiniteCoordinate {
            vertex: 1,
            line: None,
            ..
        },
        "vertex 1"
    );
}

#[test]
fn zero_area_and_duplicate_faces() {
    // Three collinear points: read (what a deformation that collapses a
    // face writes must read back) with a warning naming the face; the
    // cotangent Laplacians refuse it as a rest shape, the uniform one not.
    let loaded = read_mesh_bytes(
        b"v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 4\nf 1 3 2\n",
        MeshFormat::Obj,
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap();
    let warnings: Vec<String> = loaded
        .mesh
        .warnings()
        .iter()
        .map(|w| w.to_string())
        .collect();
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("face 1") && w.contains("zero area")),
        "{warnings:?}"
    );
    for kind in [
        LaplacianKind::Cotangent,
        LaplacianKind::CotangentSymmetric,
        LaplacianKind::IntrinsicDelaunay,
    ] {
        let e = lse_deform::laplacian::laplacian(&loaded.mesh, kind).unwrap_err();
        expect!(
            e,
            MeshError::DegenerateFace { face: 1, .. },
            "face 1",
            "zero area",
            "cotangent"
        );
    }
    assert!(lse_deform::laplacian::laplacian(&loaded.mesh, LaplacianKind::Uniform).is_ok());
    // The same triangle twice, in another rotation.
    let e = mesh_err(
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 2 3 1\n",
        MeshFormat::Obj,
    );
    expect!(
        e,
        MeshError::DuplicateFace {
            face: 1,
            first: 0,
            line: Some(5),
            ..
        },
        "face 1",
        "face 0"
    );
}

#[test]
fn non_manifold_edges_are_accepted_with_a_warning_and_deform() {
    // Three triangles on edge (0, 1): not a manifold.
    let obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n";
    let loaded = read_mesh_bytes(
        obj,
        MeshFormat::Obj,
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap();
    assert_eq!(
        lse_deform::mesh::Topology::of(&loaded.mesh).n_non_manifold_edges,
        1
    );
    let warnings: Vec<String> = loaded
        .mesh
        .warnings()
        .iter()
        .map(|w| w.to_string())
        .collect();
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("(0, 1)") || w.contains("0 and 1") || w.contains("[0, 1]")),
        "{warnings:?}"
    );
    let cs = ConstraintSet::from_vec(
        (0..4)
            .map(|v| {
                Constraint::hard(ConstraintKind::Position {
                    vertex: v,
                    target: [v as f64, 0.0, 0.0],
                })
            })
            .collect(),
    )
    .unwrap();
    let mut d = Deformer::with_formulation(
        loaded.mesh,
        LaplacianKind::Cotangent,
        cs,
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    let s = d.solve().unwrap();
    assert!(s.positions.iter().flatten().all(|c| c.is_finite()));
    assert_eq!(
        messages(&s.report.warnings),
        warnings,
        "the report repeats the warning"
    );
}

#[test]
fn unreferenced_vertices_say_why_and_how_to_fix() {
    let e = mesh_err(
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nf 1 2 3\n",
        MeshFormat::Obj,
    );
    expect!(
        e,
        MeshError::UnreferencedVertex {
            vertex: 3,
            count: 1,
            line: Some(4)
        },
        "vertex 3",
        "singular",
        "remove"
    );
}

// ---------------------------------------------------------------------------
// Problems that are valid piece by piece but have no unique solution

fn pos(vertex: usize, target: [f64; 3]) -> Constraint {
    Constraint::hard(ConstraintKind::Position { vertex, target })
}

fn set(cs: Vec<Constraint>) -> ConstraintSet {
    ConstraintSet::from_vec(cs).unwrap()
}

#[test]
fn a_component_no_constraint_pins_is_named() {
    let obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 0 0\nv 6 0 0\nv 5 1 0\nf 1 2 3\nf 4 5 6\n";
    let mesh = read_mesh_bytes(
        obj,
        MeshFormat::Obj,
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap()
    .mesh;
    // A relative constraint on the second triangle does not pin it.
    let rel = Constraint::hard(ConstraintKind::Relative {
        vertices: [3, 4],
        vector: [1.0, 0.0, 0.0],
    });
    let cs = set(vec![pos(0, [0.0; 3]), rel]);
    let e = Deformer::new(
        mesh,
        LaplacianKind::Cotangent,
        cs,
        &lse_deform::SolveOptions::default(),
    )
    .err()
    .unwrap();
    expect!(
        e,
        Error::Problem(ProblemError::UnpinnedComponent {
            component: 1,
            vertices: 3,
            ..
        }),
        "component 1",
        "vertex 3"
    );
}

#[test]
fn no_constraints_and_relative_constraints_alone() {
    let mesh = generate::grid(4, 4).unwrap();
    let e = Deformer::new(
        mesh.clone(),
        LaplacianKind::Uniform,
        ConstraintSet::new(),
        &lse_deform::SolveOptions::default(),
    )
    .err()
    .unwrap();
    expect!(
        e,
        Error::Problem(ProblemError::NoConstraints),
        "no constraints"
    );
    let rel = Constraint::hard(ConstraintKind::Relative {
        vertices: [0, 1],
        vector: [1.0, 0.0, 0.0],
    });
    let e = Deformer::new(
        mesh,
        LaplacianKind::Uniform,
        set(vec![rel]),
        &lse_deform::SolveOptions::default(),
    )
    .err()
    .unwrap();
    expect!(
        e,
        Error::Problem(ProblemError::UnpinnedComponent { .. }),
        "relative constraints alone"
    );
}

// ---------------------------------------------------------------------------
// Constraint files

fn constraint_err(json: &str, n_vertices: usize) -> ConstraintError {
    match parse_constraints(json).and_then(|s| s.check_vertices(n_vertices).map(|_| s)) {
        Ok(s) => panic!("expected an error, got {} constraints", s.len()),
        Err(e) => e,
    }
}

fn one(c: &str) -> String {
    format!(r#"{{"constraints": [{{"type": "position", "vertex": 0, "target": [0, 0, 0]}}, {c}]}}"#)
}

#[test]
fn malformed_json_names_line_and_column() {
    let e = constraint_err("{\"constraints\": [\n  {\"type\": \"position\",, }\n]}", 10);
    expect!(e, ConstraintError::Json { line: 2, .. }, "line 2", "column");
    expect!(
        constraint_err("[]", 10),
        ConstraintError::Shape { .. },
        "constraints"
    );
}

/// A key repeated in one object, at any depth, is refused with the key
/// and the line of its second appearance (a reader that keeps the last
/// value would move vertex 3000's constraint to vertex 5, silently).
#[test]
fn a_repeated_key_at_any_depth_is_refused_with_its_line() {
    let cases: [(&str, &str, usize, &str); 8] = [
        (
            "{\"constraints\": [\n {\"type\": \"position\",\n  \"vertex\": 3000,\n  \"vertex\": 5, \"target\": [0, 0, 0]}\n]}",
            "vertex",
            4,
            "in constraint 0",
        ),
        (
            "{\"constraints\": [{\"type\": \"position\", \"vertex\": 1, \"target\": [0, 0, 0]},\n{\"type\": \"position\", \"vertex\": 2, \"target\": [0, 0, 0],\n \"comment\": \"a\", \"comment\": \"b\"}]}",
            "comment",
            3,
            "in constraint 1",
        ),
        (
            "{\"constraints\": [{\"type\": \"position\", \"vertex\": 1, \"target\": [0, 0, 0],\n \"weight\": 1, \"weight\": 2}]}",
            "weight",
            2,
            "in constraint 0",
        ),
        (
            "{\"constraints\": [{\"type\": \"position\", \"vertex\": 1, \"target\": [0, 0, 0],\n \"extra\": {\"a\": 1,\n \"a\": 2}}]}",
            "a",
            3,
            "in constraint 0",
        ),
        (
            "{\"constraints\": [], \"constraints\": []}",
            "constraints",
            1,
            "at the top level",
        ),
        (
            "{\"note\": 1,\n\"constraints\": [],\n\"note\": 2}",
            "note",
            3,
            "at the top level",
        ),
        (
            "{\"constraints\": [], \"about\": [{\"x\": 1, \"y\": 2},\n {\"x\": 1, \"x\": 2}]}",
            "x",
            2,
            "at the top level",
        ),
        (
            "{\"mesh\": {\"vertices\": 4,\n \"faces\": 2, \"vertices\": 4, \"fingerprint\": \"f\"}, \"constraints\": []}",
            "vertices",
            2,
            "in 'mesh'",
        ),
    ];
    for (json, key, line, place) in cases {
        let e = constraint_err(json, 10_000);
        assert!(
            matches!(&e, ConstraintError::DuplicateKey { key: k, line: l, .. } if k == key && *l == line),
            "{json}: {e:?}"
        );
        let message = e.to_string();
        for word in [
            format!("'{key}'"),
            format!("line {line}"),
            place.to_string(),
        ] {
            assert!(message.contains(&word), "{word} in: {message}");
        }
    }
    // Equal keys in different objects are not repeated keys.
    let ok = "{\"constraints\": [{\"type\": \"position\", \"vertex\": 1, \"target\": [0, 0, 0], \"comment\": {\"a\": {\"a\": 1}}},\n{\"type\": \"position\", \"vertex\": 2, \"target\": [0, 0, 0], \"comment\": [{\"a\": 1}, {\"a\": 2}]}], \"a\": {\"constraints\": 1}}";
    assert_eq!(parse_constraints(ok).unwrap().len(), 2);
    // A file read from disk says the same.
    let dir = std::env::temp_dir().join(format!("lse-duplicate-key-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("c.json");
    std::fs::write(&path, cases[0].0).unwrap();
    let e = lse_deform::constraints::read_constraints_file(
        &path,
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap_err();
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(
        matches!(
            &e,
            Error::Constraint(ConstraintError::DuplicateKey { line: 4, .. })
        ),
        "{e:?}"
    );
}

#[test]
fn each_bad_constraint_names_its_index() {
    let cases: &[(&str, &str)] = &[
        (
            r#"{"type": "spring", "vertex": 1, "target": [0,0,0]}"#,
            "unknown type 'spring'",
        ),
        (r#"{"type": "position", "target": [0,0,0]}"#, "'vertex'"),
        (r#"{"type": "position", "vertex": 1}"#, "'target'"),
        (
            r#"{"type": "position", "vertex": 1, "target": [0,0]}"#,
            "'target'",
        ),
        (
            r#"{"type": "position", "vertex": 1, "target": [0,0,0], "wieght": 2}"#,
            "unknown field 'wieght'",
        ),
        (
            r#"{"type": "position", "vertex": 1000000000, "target": [0,0,0]}"#,
            "vertex 1000000000 is out of range",
        ),
        (
            r#"{"type": "position", "vertex": -1, "target": [0,0,0]}"#,
            "'vertex'",
        ),
        (
            r#"{"type": "edge", "vertices": [2, 2], "t": 0.5, "target": [0,0,0]}"#,
            "vertex 2 appears twice",
        ),
        (
            r#"{"type": "edge", "vertices": [1, 2], "t": "nan", "target": [0,0,0]}"#,
            "'t' is not finite",
        ),
        (
            r#"{"type": "face", "vertices": [1, 2, 3], "barycentric": ["inf", 0.2], "target": [0,0,0]}"#,
            "'barycentric' is not finite",
        ),
        (
            r#"{"type": "position", "vertex": 1, "target": [0,"nan",0]}"#,
            "'target' is not finite",
        ),
        (
            r#"{"type": "position", "vertex": 1, "target": [0,0,0], "weight": 0}"#,
            "weight 0 is invalid",
        ),
        (
            r#"{"type": "position", "vertex": 1, "target": [0,0,0], "weight": -1}"#,
            "weight -1 is invalid",
        ),
        (
            r#"{"type": "position", "vertex": 1, "target": [0,0,0], "weight": "nan"}"#,
            "weight NaN is invalid",
        ),
        (
            r#"{"type": "position", "vertex": 1, "target": [0,0,0], "weight": "inf"}"#,
            "weight inf is invalid",
        ),
    ];
    for (c, words) in cases {
        let e = constraint_err(&one(c), 10);
        let msg = e.to_string();
        assert!(msg.contains("constraint 1"), "{c}: {msg}");
        assert!(msg.contains(words), "{c}: expected {words:?} in: {msg}");
        assert!(
            !matches!(
                e,
                ConstraintError::Json { .. } | ConstraintError::Shape { .. }
            ),
            "{c}: {e:?}"
        );
    }
    expect!(
        constraint_err(&one(cases[0].0), 10),
        ConstraintError::UnknownType { index: 1, .. },
        "spring"
    );
    expect!(
        constraint_err(&one(cases[5].0), 10),
        ConstraintError::VertexOutOfRange {
            index: 1,
            vertex: 1_000_000_000,
            vertex_count: 10
        },
        "10 vertices"
    );
    expect!(
        constraint_err(&one(cases[7].0), 10),
        ConstraintError::RepeatedVertex {
            index: 1,
            vertex: 2
        },
        "twice"
    );
    expect!(
        constraint_err(&one(cases[8].0), 10),
        ConstraintError::NonFinite {
            index: 1,
            field: "t"
        },
        "'t'"
    );
    expect!(
        constraint_err(&one(cases[12].0), 10),
        ConstraintError::InvalidWeight { index: 1, .. },
        "-1"
    );
    // JSON itself has no infinity: serde_json refuses an overflowing literal
    // where it stands.
    let e = constraint_err(
        &one(r#"{"type": "edge", "vertices": [1, 2], "t": 1e999, "target": [0,0,0]}"#),
        10,
    );
    expect!(
        e,
        ConstraintError::Json { line: 1, .. },
        "out of range",
        "column"
    );
}

#[test]
fn no_constraint_row_is_all_zero() {
    // The extreme parameters leave one coefficient 1 on one vertex: the
    // format cannot express an all-zero row (src/constraints.rs).
    let kinds = [
        ConstraintKind::Edge {
            vertices: [1, 2],
            t: 0.0,
            target: [0.0; 3],
        },
        ConstraintKind::Edge {
            vertices: [1, 2],
            t: 1.0,
            target: [0.0; 3],
        },
        ConstraintKind::Face {
            vertices: [1, 2, 3],
            barycentric: [0.0, 0.0],
            target: [0.0; 3],
        },
        ConstraintKind::Face {
            vertices: [1, 2, 3],
            barycentric: [1.0, 0.0],
            target: [0.0; 3],
        },
    ];
    for k in kinds {
        let row = k.row();
        assert_eq!(row.entries().len(), 1, "{k:?}");
        assert_eq!(row.entries()[0].1, 1.0, "{k:?}");
    }
}

#[test]
fn target_updates_are_checked_and_change_nothing_when_refused() {
    let mesh = generate::grid(2, 2).unwrap();
    let cs = set(vec![pos(0, [0.0; 3]), pos(8, [1.0, 1.0, 0.3])]);
    let mut d = Deformer::with_formulation(
        mesh,
        LaplacianKind::Cotangent,
        cs,
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    expect!(
        d.set_target(1, [0.0, f64::NAN, 0.0]).unwrap_err(),
        Error::Constraint(ConstraintError::NonFinite {
            index: 1,
            field: "target"
        }),
        "constraint 1: 'target' is not finite"
    );
    expect!(
        d.set_target(2, [0.0; 3]).unwrap_err(),
        Error::Problem(ProblemError::BadUpdate { .. }),
        "constraint 2 does not exist (there are 2)"
    );
    // The refused updates changed nothing.
    let s = d.solve().unwrap();
    assert_eq!(s.positions[8], [1.0, 1.0, 0.3]);
}

/// A finite target too large for the problem's unit (the mesh's mean edge
/// length, below 1: the largest double divided by it overflows) is named
/// for what it is, not as "not finite", by the update as by set-up.
#[test]
fn a_target_too_large_for_the_mesh_units_says_so() {
    let mesh = generate::grid(2, 2).unwrap();
    let cs = set(vec![pos(0, [0.0; 3]), pos(8, [1.0, 1.0, 0.3])]);
    let mut d = Deformer::new(
        mesh.clone(),
        LaplacianKind::Cotangent,
        cs,
        &lse_deform::SolveOptions::default(),
    )
    .unwrap();
    assert!(d.length_unit() < 1.0);
    d.refactor_with(
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    let huge = [f64::MAX, 0.0, 0.0];
    for e in [
        d.set_target(1, huge).unwrap_err(),
        d.set_targets(&[(0, [0.0; 3]), (1, huge)]).unwrap_err(),
        Deformer::new(
            mesh,
            LaplacianKind::Cotangent,
            set(vec![pos(0, [0.0; 3]), pos(8, huge)]),
            &lse_deform::SolveOptions::default(),
        )
        .err()
        .unwrap(),
    ] {
        let msg = expect!(
            e,
            Error::Numerical(NumericalError::TargetOutOfRange { index: 1, .. }),
            "constraint 1",
            "1.7976931348623157e308",
            "length unit"
        );
        assert!(!msg.contains("not finite"), "{msg}");
    }
    let s = d.solve().unwrap();
    assert_eq!(
        s.positions[8],
        [1.0, 1.0, 0.3],
        "the refused updates changed nothing"
    );
}

/// A soft weight whose square overflows in the normal equations is
/// refused at set-up (as one whose product with the unit underflows is),
/// by every formulation alike, instead of failing in the factorisation as
/// "not positive definite".
#[test]
fn a_soft_weight_too_large_is_refused_up_front() {
    let mesh = generate::grid(8, 8).unwrap();
    let soft = |w: f64| {
        let mut s = vec![pos(0, [0.0; 3]), pos(80, [1.0, 1.0, 0.3])];
        s.push(Constraint::soft(
            ConstraintKind::Position {
                vertex: 40,
                target: [0.5, 0.5, 0.2],
            },
            w,
        ));
        set(s)
    };
    for kind in [LaplacianKind::Cotangent, LaplacianKind::Uniform] {
        let unit_power = kind.inverse_length_power();
        let unit = Deformer::new(
            mesh.clone(),
            kind,
            soft(1.0),
            &lse_deform::SolveOptions::default(),
        )
        .unwrap()
        .length_unit();
        // The row weight is w ℓᵃ: refused above √(f64::MAX) ≈ 1.34e154.
        let scale = unit.powi(unit_power);
        for w in [1e308, 1e200 / scale, 1.35e154 / scale] {
            let e = Deformer::new(
                mesh.clone(),
                kind,
                soft(w),
                &lse_deform::SolveOptions::default(),
            )
            .err()
            .unwrap();
            let msg = expect!(
                e,
                Error::Numerical(NumericalError::SoftWeightTooLarge { index: 2, .. }),
                "constraint 2",
                "too large",
                "1.34e154"
            );
            assert!(!msg.contains("positive definite"), "{msg}");
        }
        // Below the bound: accepted at set-up (whether a factorisation
        // then keeps its digits is the solve's business), and a large
        // weight that does keep them holds the soft target.
        assert!(
            Deformer::new(
                mesh.clone(),
                kind,
                soft(1.3e154 / scale),
                &lse_deform::SolveOptions::default()
            )
            .is_ok()
        );
        let mut d = Deformer::with_formulation(
            mesh.clone(),
            kind,
            soft(1e100 / scale),
            &NullSpaceQr::default(),
            &lse_deform::resources::Resources::default(),
        )
        .unwrap();
        let x = d.solve().unwrap().positions[40];
        assert!((x[2] - 0.2).abs() < 1e-6, "{kind:?}: {x:?}");
    }
}

// ---------------------------------------------------------------------------
// Numerical trouble

/// A 20 × 20 grid with its left column fixed, its right column moved and
/// relative constraints between neighbours in the middle row.
fn grid_scene(relative: bool) -> (Mesh, ConstraintSet) {
    let mesh = generate::grid(20, 20).unwrap();
    let mut cs = Vec::new();
    for j in 0..20 {
        cs.push(pos(20 * j, mesh.positions()[20 * j]));
        let p = mesh.positions()[20 * j + 19];
        cs.push(pos(20 * j + 19, [p[0], p[1], p[2] + 0.3]));
    }
    if relative {
        for i in 5..15 {
            let (a, b) = (200 + i, 200 + i + 1);
            let (pa, pb) = (mesh.positions()[a], mesh.positions()[b]);
            cs.push(Constraint::hard(ConstraintKind::Relative {
                vertices: [a, b],
                vector: [pa[0] - pb[0], pa[1] - pb[1], pa[2] - pb[2]],
            }));
        }
    }
    (mesh, set(cs))
}

#[test]
fn conflicting_hard_constraints_are_reported_not_an_error() {
    let (mesh, base) = grid_scene(false);
    let mut cs = base.as_slice().to_vec();
    let n = cs.len();
    cs.push(pos(0, [0.0, 0.0, 1.0])); // conflicts with constraint 0
    cs.push(cs[1].clone()); // repeats constraint 1: redundant
    let mut d = Deformer::with_formulation(
        mesh,
        LaplacianKind::Cotangent,
        set(cs),
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    let s = d.solve().unwrap();
    assert_eq!(s.report.redundant, vec![n + 1]);
    assert_eq!(s.report.conflicting.len(), 1);
    assert_eq!(s.report.conflicting[0].index, n);
    // The earlier constraint wins and holds exactly: vertex 0 stays put.
    assert!((s.report.conflicting[0].residual - 1.0).abs() < 1e-12);
    assert_eq!(s.positions[0], [0.0, 0.0, 0.0]);
    // Never silent: a warning names it, the constraint it contradicts and
    // the residual.
    assert_eq!(
        messages(&s.report.warnings),
        vec![format!(
            "constraint {n} conflicts with constraint 0 and was dropped (residual 1.000e0)"
        )]
    );
}

/// Fifteen conflicts: the first ten warnings name theirs one by one (with
/// the earlier constraint each contradicts, here an edge through two kept
/// positions), one more counts the rest; the ARAP deformer warns alike.
#[test]
fn many_conflicts_are_warned_one_by_one_then_counted() {
    let (mesh, base) = grid_scene(false);
    let mut cs = base.as_slice().to_vec();
    let first = cs.len();
    for j in 0..15 {
        // Vertex 20 j is fixed by constraint 2 j, vertex 20 (j + 1) by
        // 2 (j + 1): the midpoint of the edge between them, 0.1 too high.
        let (a, b) = (20 * j, 20 * (j + 1));
        let (pa, pb) = (mesh.positions()[a], mesh.positions()[b]);
        let mid = [0, 1, 2].map(|k| 0.5 * (pa[k] + pb[k]));
        cs.push(Constraint::hard(ConstraintKind::Edge {
            vertices: [a, b],
            t: 0.5,
            target: [mid[0], mid[1], mid[2] + 0.1],
        }));
    }
    let check = |warnings: &[lse_deform::report::Warning], what: &str| {
        for j in 0..10 {
            let expected = format!(
                "constraint {} conflicts with constraints {}, {} and was dropped (residual 1.000e-1)",
                first + j,
                2 * j,
                2 * (j + 1)
            );
            assert!(
                warnings.iter().any(|w| w.message == expected),
                "{what}: no '{expected}' in {warnings:?}"
            );
        }
        assert!(
            warnings.iter().any(|w| w
                .message
                .starts_with("… and 5 more conflicting constraints were dropped (15 in all")),
            "{what}: {warnings:?}"
        );
        assert_eq!(
            warnings
                .iter()
                .filter(|w| w.message.contains(" conflicts with "))
                .count(),
            10,
            "{what}: {warnings:?}"
        );
    };
    let mut d = Deformer::with_formulation(
        mesh.clone(),
        LaplacianKind::Cotangent,
        set(cs.clone()),
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    let s = d.solve().unwrap();
    assert_eq!(s.report.conflicting.len(), 15);
    check(&s.report.warnings, "laplacian");
    // A second solve does not repeat them.
    let again = d.solve().unwrap();
    assert_eq!(again.report.warnings, s.report.warnings);
    let mut arap = lse_deform::arap::ArapDeformer::with_formulation(
        mesh,
        set(cs),
        lse_deform::arap::ArapEnergy::SpokesAndRims,
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    arap.initialize(lse_deform::arap::ArapInit::Linear).unwrap();
    arap.run(2, 0.0).unwrap();
    check(&arap.report().warnings, "arap");
    arap.run(1, 0.0).unwrap();
    check(&arap.report().warnings, "arap, run again");
}

#[test]
fn a_penalty_weight_too_large_is_a_breakdown_not_garbage() {
    // A relative constraint puts w²[1 −1; −1 1] on two unknowns; eliminating
    // the first cancels the second pivot to rounding once w² ≫ 1/ε.
    let (mesh, cs) = grid_scene(true);
    let mut d = Deformer::with_formulation(
        mesh,
        LaplacianKind::Uniform,
        cs,
        &Penalty::new(1e4),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    assert!(d.solve().is_ok(), "a moderate weight works");
    for w in [1e10, 1e12, 1e14] {
        let e = match d
            .refactor_with(
                &Penalty::new(w),
                &lse_deform::resources::Resources::default(),
            )
            .and_then(|_| d.solve())
        {
            Ok(s) => panic!(
                "w = {w:e}: expected a numerical error, got {:?}",
                &s.positions[..2]
            ),
            Err(e) => e,
        };
        let msg = expect!(
            e,
            Error::Numerical(
                NumericalError::Breakdown { .. }
                    | NumericalError::NotPositiveDefinite { .. }
                    | NumericalError::LostAccuracy { .. }
            ),
            "AᵀA + w²BᵀB"
        );
        assert!(msg.contains("vertex") || msg.contains("accuracy"), "{msg}");
    }
}

#[test]
fn a_redundant_constraint_makes_kkt_singular_and_says_which() {
    let (mesh, base) = grid_scene(false);
    let mut cs = base.as_slice().to_vec();
    let n = cs.len();
    cs.push(cs[3].clone());
    let mut d = Deformer::new(
        mesh,
        LaplacianKind::Cotangent,
        set(cs),
        &lse_deform::SolveOptions::default(),
    )
    .unwrap();
    let e = d
        .refactor_with(
            &Kkt::default(),
            &lse_deform::resources::Resources::default(),
        )
        .and_then(|_| d.solve().map(|_| ()))
        .unwrap_err();
    expect!(
        e,
        Error::Numerical(NumericalError::Singular { .. }),
        "KKT",
        &format!("constraint {n}")
    );
}

#[test]
fn sliver_meshes_solve_exactly_or_fail_with_a_reason() {
    let mesh = generate::sliver_mesh(20, 7).unwrap();
    let cs = lse_deform::scene::FixedAndHandle::paper_default(&mesh)
        .constraints(&mesh)
        .unwrap();
    let diag = mesh.bbox_diagonal();
    for kind in [LaplacianKind::Cotangent, LaplacianKind::Uniform] {
        let mut d = Deformer::new(
            mesh.clone(),
            kind,
            cs.clone(),
            &lse_deform::SolveOptions::default(),
        )
        .unwrap();
        match d
            .refactor_with(
                &NullSpaceQr::default(),
                &lse_deform::resources::Resources::default(),
            )
            .and_then(|_| d.solve())
        {
            Ok(s) => {
                assert!(s.positions.iter().flatten().all(|c| c.is_finite()));
                assert!(s.report.max_constraint_residual <= 1e-13 * diag, "{kind:?}");
            }
            Err(e) => assert!(matches!(e, Error::Numerical(_)), "{kind:?}: {e}"),
        }
    }
}

// ---------------------------------------------------------------------------
// Crowded constraints: many constraints through one vertex. The cost must
// stay proportional to the input (full counts in benches/performance.rs,
// group t8_crowded); here the answers are checked on smaller counts.

/// Runs a [`CrowdedScene`] on every QR back end and checks the rank, the
/// redundant and the conflicting sets against [`CrowdedScene::expected`]
/// (derived from how the scene is built, not from a solver), the conflict
/// residuals (the 1 % shift) and that the kept constraints hold.
fn check_crowded(partners: usize, count: usize) {
    use lse_deform::scene::{CrowdedScene, FixedAndHandle};
    let mesh = generate::grid(20, 20).unwrap();
    let scene = CrowdedScene {
        base: FixedAndHandle::paper_default(&mesh),
        partners,
        count,
        conflict_every: 7,
    };
    let cs = scene.constraints(&mesh).unwrap();
    let base_len = cs.len() - count;
    let (added, redundant, conflicting) = scene.expected(base_len);
    assert!(!redundant.is_empty() && !conflicting.is_empty());
    let shift = 0.01 * mesh.bbox_diagonal();
    let mut d = Deformer::new(
        mesh,
        LaplacianKind::Cotangent,
        cs,
        &lse_deform::SolveOptions::default(),
    )
    .unwrap();
    for qr in QrKind::available() {
        let f = nullspace_qr_with(qr);
        d.refactor_with(f.as_ref(), &lse_deform::resources::Resources::default())
            .unwrap();
        let s = d.solve().unwrap();
        let r = &s.report;
        // The base scene's position constraints are on distinct vertices.
        assert_eq!(r.rank, Some(base_len + added), "{qr}");
        assert_eq!(r.redundant, redundant, "{qr}");
        let found: Vec<usize> = r.conflicting.iter().map(|c| c.index).collect();
        assert_eq!(found, conflicting, "{qr}");
        for c in &r.conflicting {
            assert!((c.residual - shift).abs() < 1e-9 * shift, "{qr}: {c:?}");
        }
        assert!(r.max_constraint_residual < 1e-12, "{qr}: {r:?}");
    }
}

#[test]
fn one_position_constraint_repeated_thousands_of_times() {
    check_crowded(0, 5_000);
}

#[test]
fn thousands_of_relative_constraints_through_one_hub() {
    check_crowded(40, 5_000);
}

#[test]
fn a_byte_order_mark_is_not_malformed_json() {
    let text = format!(
        "\u{feff}{}",
        one(r#"{"type": "position", "vertex": 1, "target": [0,0,0]}"#)
    );
    let set = parse_constraints(&text).unwrap();
    assert_eq!(set.len(), 2);
    assert_eq!(set[1], pos(1, [0.0, 0.0, 0.0]));
    // Only one mark, and only at the start.
    let twice = format!("\u{feff}{text}");
    expect!(
        constraint_err(&twice, 4),
        ConstraintError::Json {
            line: 1,
            column: 1,
            ..
        },
        "line 1"
    );
}

#[test]
fn a_constraints_file_knows_its_mesh() {
    use lse_deform::scene::FixedAndHandle;
    let mesh = generate::grid(10, 10).unwrap();
    let cs = FixedAndHandle::paper_default(&mesh)
        .constraints(&mesh)
        .unwrap();
    let back = parse_constraints(&cs.to_json()).unwrap();
    // (Targets can differ in the last bit: serde_json parses decimals
    // without `float_roundtrip`.)
    assert_eq!(back.mesh(), cs.mesh(), "the mesh object survives the file");
    assert_eq!(back.len(), cs.len());
    assert_eq!(back.mesh().unwrap().vertices, 121);
    assert_eq!(back.mesh_mismatch(&mesh), None);
    // Same counts, other positions: the fingerprint says so.
    let moved: Vec<[f64; 3]> = mesh
        .positions()
        .iter()
        .map(|p| [p[0], p[1], p[2] + 0.01 * p[0]])
        .collect();
    let other = mesh.with_positions(moved).unwrap();
    let msg = back.mesh_mismatch(&other).unwrap();
    assert!(msg.contains("fingerprint"), "{msg}");
    // Other counts.
    let small = generate::grid(5, 5).unwrap();
    let msg = back.mesh_mismatch(&small).unwrap();
    assert!(msg.contains("121 vertices") && msg.contains("36"), "{msg}");
    // A malformed mesh object is a shape error naming the field.
    let bad = r#"{"mesh": {"vertices": 3, "faces": 1}, "constraints": []}"#;
    expect!(
        constraint_err(bad, 3),
        ConstraintError::Shape { .. },
        "'mesh'",
        "fingerprint"
    );
    let extra = r#"{"mesh": {"vertices": 3, "faces": 1, "fingerprint": "x", "colour": 1}, "constraints": []}"#;
    expect!(
        constraint_err(extra, 3),
        ConstraintError::Shape { .. },
        "colour"
    );
}

// ---------------------------------------------------------------------------
// The binary: exit codes and one-line messages

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lse-deform"))
        .args(args)
        .output()
        .expect("the binary runs")
}

#[test]
fn the_cli_exits_2_on_bad_input_and_3_on_numerical_failure_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = |n: &str| dir.path().join(n).to_string_lossy().into_owned();
    let write = |n: &str, text: &str| {
        std::fs::File::create(path(n))
            .unwrap()
            .write_all(text.as_bytes())
            .unwrap()
    };

    let (mesh, cs) = grid_scene(true);
    let mut obj = String::new();
    for p in mesh.positions() {
        obj.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
    }
    for f in mesh.faces() {
        obj.push_str(&format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1));
    }
    write("grid.obj", &obj);
    write("scene.json", &cs.to_json());
    write("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    write(
        "bad.json",
        &one(r#"{"type": "position", "vertex": 1, "target": [0,0,0], "weight": -1}"#),
    );
    let out = path("out.obj");

    let cases: &[(&[&str], i32, &str)] = &[
        (&["info", &path("bad.obj")], 2, "face 0 (line 4)"),
        (
            &[
                "deform",
                &path("grid.obj"),
                "-c",
                &path("bad.json"),
                "-o",
                &out,
            ],
            2,
            "constraint 1",
        ),
        (
            &[
                "deform",
                &path("missing.obj"),
                "-c",
                &path("scene.json"),
                "-o",
                &out,
            ],
            2,
            "missing.obj",
        ),
        (
            &[
                "deform",
                &path("grid.obj"),
                "-c",
                &path("scene.json"),
                "-o",
                &out,
                "--method",
                "penalty",
                "--weight",
                "1e12",
            ],
            3,
            "vertex",
        ),
    ];
    for (args, code, word) in cases {
        let o = run(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(*code), "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        assert!(
            err.starts_with("error: ") && err.contains(word),
            "{args:?}: {err}"
        );
        assert!(
            !err.contains("panicked") && !err.contains("backtrace"),
            "{err}"
        );
    }
    assert!(!std::path::Path::new(&out).exists(), "no output on failure");

    // --verbose adds the chain of causes to a file error.
    let o = run(&[
        "--verbose",
        "deform",
        &path("missing.obj"),
        "-c",
        &path("scene.json"),
        "-o",
        &out,
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2));
    assert!(err.lines().count() >= 2, "{err}");
}

// ---------------------------------------------------------------------------
// The constraint parser never panics (the mesh readers' counterpart is in
// tests/mesh_io.rs; coverage-guided fuzzing of both is in fuzz/).

const VALID_CONSTRAINTS: &str = r#"{"constraints": [
  {"type": "position", "vertex": 12, "target": [0.1, 0.2, 0.3]},
  {"type": "edge", "vertices": [4, 5], "t": 0.3, "target": [0, 0, 1]},
  {"type": "face", "vertices": [1, 2, 3], "barycentric": [0.2, 0.3], "target": [0, 1, 0]},
  {"type": "relative", "vertices": [7, 9], "vector": [0, 0, 0.5], "name": "keep"},
  {"type": "position", "vertex": 40, "target": [1, 1, 1], "weight": 10.0}
]}"#;

/// Whatever the text, parsing gives a set or an error; a set that comes back
/// has finite coefficients and targets and valid weights.
fn check_constraints_no_panic(text: &str) {
    if let Ok(set) = parse_constraints(text) {
        for c in set.as_slice() {
            assert!(c.kind.row().entries().iter().all(|&(_, v)| v.is_finite()));
            assert!(c.kind.rhs().iter().all(|v| v.is_finite()));
            assert!(c.weight.is_none_or(|w| w.is_finite() && w > 0.0));
        }
        let _ = set.check_vertices(20);
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(512))]

    #[test]
    fn constraint_parser_never_panics_on_arbitrary_text(bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..512)) {
        check_constraints_no_panic(&String::from_utf8_lossy(&bytes));
    }

    #[test]
    fn constraint_parser_never_panics_on_mutated_files(
        edits in proptest::collection::vec((proptest::prelude::any::<usize>(), 0u8..4, proptest::prelude::any::<usize>()), 1..8),
    ) {
        // Mutations that keep the text JSON-like: replace, insert or delete
        // a character, or truncate.
        const ALPHABET: &[u8] = b"0123456789-.eE+ ,:[]{}\"ntfalsrue";
        let mut bytes = VALID_CONSTRAINTS.as_bytes().to_vec();
        for (at, op, c) in edits {
            if bytes.is_empty() {
                break;
            }
            let at = at % bytes.len();
            let ch = ALPHABET[c % ALPHABET.len()];
            match op {
                0 => bytes[at] = ch,
                1 => bytes.insert(at, ch),
                2 => { bytes.remove(at); }
                _ => bytes.truncate(at),
            }
        }
        check_constraints_no_panic(&String::from_utf8_lossy(&bytes));
    }

    #[test]
    fn constraint_parser_checks_structured_values(
        vertex in proptest::prop_oneof![
            proptest::prelude::Just("1e300".to_string()),
            proptest::prelude::Just("-3".to_string()),
            proptest::prelude::Just("2.5".to_string()),
            proptest::prelude::Just("18446744073709551616".to_string()),
            proptest::prelude::Just("\"7\"".to_string()),
            (0u64..40).prop_map(|v| v.to_string()),
        ],
        number in proptest::prop_oneof![
            proptest::prelude::Just("\"nan\"".to_string()),
            proptest::prelude::Just("\"-inf\"".to_string()),
            proptest::prelude::Just("null".to_string()),
            proptest::prelude::Just("[]".to_string()),
            (-1e6f64..1e6).prop_map(|v| format!("{v}")),
        ],
        weight in proptest::option::of(-2.0f64..2.0),
    ) {
        let w = weight.map(|w| format!(r#", "weight": {w}"#)).unwrap_or_default();
        let text = format!(
            r#"{{"constraints": [{{"type": "edge", "vertices": [{vertex}, 3], "t": {number}, "target": [0, {number}, 0]{w}}}]}}"#
        );
        check_constraints_no_panic(&text);
        if let Ok(set) = parse_constraints(&text).and_then(|s| s.check_vertices(20).map(|_| s)) {
            for c in set.as_slice() {
                assert!(c.kind.vertices().iter().all(|&v| v < 20));
            }
        }
    }
}

/// The sentences of `warnings`, in order (what the report's `"warnings"`
/// holds).
fn messages(warnings: &[lse_deform::report::Warning]) -> Vec<String> {
    warnings.iter().map(|w| w.message.clone()).collect()
}
