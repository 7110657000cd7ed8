//! The `lse-deform` binary as a user runs it.

use std::path::Path;
use std::process::{Command, Output};

use lse_deform::mesh::read_mesh;

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lse-deform"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn p(dir: &Path, name: &str) -> String {
    dir.join(name).to_string_lossy().into_owned()
}

#[test]
fn generate_scene_deform_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = p(dir.path(), "grid.obj");
    let o = run(&["generate", "grid", "--vertices", "900", "-o", &mesh]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = p(dir.path(), "scene.json");
    let o = run(&[
        "scene",
        &mesh,
        "--relative",
        "5",
        "--edges",
        "3",
        "--faces",
        "3",
        "--duplicate",
        "--conflict",
        "-o",
        &scene,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = p(dir.path(), "out.ply");
    let report = p(dir.path(), "report.json");
    let o = run(&[
        "deform", &mesh, "-c", &scene, "-o", &out, "--report", &report,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let deformed = read_mesh(Path::new(&out)).unwrap().mesh;
    let original = read_mesh(Path::new(&mesh)).unwrap().mesh;
    assert_eq!(deformed.n_vertices(), original.n_vertices());
    assert_eq!(deformed.faces(), original.faces());

    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    for key in [
        "vertices",
        "rank",
        "redundant",
        "conflicting",
        "max_constraint_residual",
        "timings_s",
        "nnz",
    ] {
        assert!(r.get(key).is_some(), "report lacks {key}");
    }
    for phase in [
        "setup",
        "qr",
        "preparation",
        "normal_matrix",
        "symbolic",
        "numeric",
        "solve",
    ] {
        assert!(r["timings_s"][phase].as_f64().unwrap() >= 0.0);
    }
    let n_constraints =
        lse_deform::constraints::parse_constraints(&std::fs::read_to_string(&scene).unwrap())
            .unwrap()
            .len();
    // The duplicate and the conflict are the last two constraints.
    assert_eq!(r["redundant"], serde_json::json!([n_constraints - 2]));
    assert_eq!(
        r["conflicting"][0]["index"],
        serde_json::json!(n_constraints - 1)
    );
    assert!(stderr(&o).contains(&format!(
        "warning: constraint {} conflicts",
        n_constraints - 1
    )));
    assert_eq!(r["rank"], serde_json::json!(n_constraints - 2));
    assert!(r["max_constraint_residual"].as_f64().unwrap() < 1e-12);
}

/// Each bad input gives exit code 2 and one line naming the problem.
#[test]
fn bad_inputs_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| {
        let path = p(dir.path(), name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let good = write(
        "two.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 0 0\nv 6 0 0\nv 5 1 0\nf 1 2 3\nf 4 5 6\n",
    );
    let pin_both = write(
        "pin.json",
        r#"{"constraints":[{"type":"position","vertex":0,"target":[0,0,0]},{"type":"position","vertex":3,"target":[5,0,0]}]}"#,
    );
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec![write("trunc.obj", "v 0 0 0\nv 1 0 0\nv 0 1\n")],
            "line 3",
        ),
        (
            vec![write("oob.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")],
            "face 0 (line 4) refers to vertex 3",
        ),
        (
            vec![write("nan.obj", "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n")],
            "vertex 1 (line 2) has a non-finite coordinate",
        ),
        (
            vec![
                good.clone(),
                write(
                    "big.json",
                    r#"{"constraints":[{"type":"position","vertex":1000000000,"target":[0,0,0]}]}"#,
                ),
            ],
            "constraint 0: vertex 1000000000 is out of range",
        ),
        (
            vec![
                good.clone(),
                write(
                    "neg.json",
                    r#"{"constraints":[{"type":"position","vertex":0,"target":[0,0,0],"weight":-1}]}"#,
                ),
            ],
            "constraint 0: weight -1 is invalid",
        ),
        (
            vec![
                good.clone(),
                write(
                    "one.json",
                    r#"{"constraints":[{"type":"position","vertex":0,"target":[0,0,0]}]}"#,
                ),
            ],
            "mesh component 1 (3 vertices, e.g. vertex 3) is not pinned",
        ),
        (
            vec![
                good.clone(),
                write("bad.json", r#"{"constraints":[{"type":"position""#),
            ],
            "malformed JSON at line 1",
        ),
    ];
    for (files, expected) in cases {
        let mut args = vec!["deform".to_string(), files[0].clone()];
        args.push("-c".into());
        args.push(files.get(1).cloned().unwrap_or_else(|| pin_both.clone()));
        args.push("-o".into());
        args.push(p(dir.path(), "out.obj"));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = run(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(expected), "expected '{expected}' in: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    // The good mesh with both components pinned works.
    let o = run(&[
        "deform",
        &good,
        "-c",
        &pin_both,
        "-o",
        &p(dir.path(), "ok.obj"),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A 900-vertex grid, a scene with every constraint kind (and a duplicate
/// and a conflict) for it, in `dir`: `(mesh path, scene path)`.
fn grid_and_scene(dir: &Path) -> (String, String) {
    let mesh = p(dir, "grid.obj");
    let o = run(&["generate", "grid", "--vertices", "900", "-o", &mesh]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = p(dir, "scene.json");
    let o = run(&[
        "scene",
        &mesh,
        "--relative",
        "5",
        "--edges",
        "3",
        "--faces",
        "3",
        "--duplicate",
        "--conflict",
        "-o",
        &scene,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    (mesh, scene)
}

/// The written mesh holds the kept hard constraints: every row `b·X = d`
/// of the scene, evaluated on the positions read back from the output
/// file (binary PLY keeps the doubles exactly), except the conflicting one
/// the report names.
#[test]
fn the_written_mesh_meets_the_targets() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let out = p(dir.path(), "out.ply");
    let report = p(dir.path(), "report.json");
    let o = run(&[
        "deform", &mesh, "-c", &scene, "-o", &out, "--report", &report,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let x = read_mesh(Path::new(&out)).unwrap().mesh;
    let original = read_mesh(Path::new(&mesh)).unwrap().mesh;
    let set = lse_deform::constraints::parse_constraints(&std::fs::read_to_string(&scene).unwrap())
        .unwrap();
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let conflicting = r["conflicting"][0]["index"].as_u64().unwrap() as usize;
    let scale = original.bbox_diagonal();
    let mut moved = 0;
    for (i, c) in set.as_slice().iter().enumerate() {
        let got = c.kind.row().apply(x.positions());
        let want = c.kind.rhs();
        let err = (0..3).map(|k| (got[k] - want[k]).abs()).fold(0.0, f64::max);
        if i == conflicting {
            assert!(err > 1e-3 * scale, "constraint {i} should be violated");
        } else {
            assert!(err <= 1e-10 * scale, "constraint {i}: |b·X − d| = {err:e}");
        }
        let before = c.kind.row().apply(original.positions());
        if (0..3).any(|k| (before[k] - want[k]).abs() > 1e-3 * scale) {
            moved += 1;
        }
    }
    assert!(
        moved > 0,
        "the scene moves something: the check is not vacuous"
    );
}

/// Every error class through the binary, with its exit code and a one-line
/// message naming the problem.
#[test]
fn exit_codes_of_every_error_class() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let out = p(dir.path(), "out.obj");
    let missing_dir = p(dir.path(), "no-such-dir/out.obj");
    let missing_report = p(dir.path(), "no-such-dir/report.json");
    // A file where the export directory should be: it cannot be created.
    let blocker = p(dir.path(), "blocker");
    std::fs::write(&blocker, "x").unwrap();
    let deform = |extra: &[&str]| -> Vec<String> {
        let mut v: Vec<String> = ["deform", &mesh, "-c", &scene]
            .iter()
            .map(|s| s.to_string())
            .collect();
        v.extend(extra.iter().map(|s| s.to_string()));
        v
    };
    let cases: Vec<(Vec<String>, i32, &str)> = vec![
        (deform(&["-o", &out, "--method", "nullspace"]), 2, "unknown"),
        (deform(&["-o", &out, "--qr", "givens"]), 2, "givens"),
        (deform(&["-o", &out, "--spd", "llt"]), 2, "llt"),
        // Missing arguments (clap's usage errors are exit code 2 too).
        (deform(&[]), 2, "--output"),
        (vec!["deform".into()], 2, "required"),
        (vec!["generate".into(), "grid".into()], 2, "--output"),
        // Unwritable or unsupported outputs, refused before any work.
        (deform(&["-o", &missing_dir]), 2, "no-such-dir"),
        (deform(&["-o", &p(dir.path(), "out.stl")]), 2, ".stl"),
        (
            deform(&["-o", &out, "--report", &missing_report]),
            2,
            "report.json",
        ),
        (
            vec![
                "export-system".into(),
                mesh.clone(),
                "-c".into(),
                scene.clone(),
                "-o".into(),
                format!("{blocker}/sub"),
            ],
            2,
            "blocker",
        ),
        // Numerical: the scene's duplicate makes the KKT matrix singular.
        (deform(&["-o", &out, "--method", "kkt"]), 3, "singular"),
    ];
    for (args, code, word) in &cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = run(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(*code), "{args:?}: {err}");
        assert!(err.contains(word), "{args:?}: expected '{word}' in {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    assert!(!Path::new(&out).exists(), "no output on failure");
}

/// A null-space solve whose result would not be finite (targets near the
/// largest double: their differences overflow) is a numerical error with
/// exit code 3, and no mesh is written.
#[test]
fn a_null_space_numerical_failure_exits_3() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = p(dir.path(), "grid.obj");
    let o = run(&["generate", "grid", "--vertices", "100", "-o", &mesh]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = p(dir.path(), "huge.json");
    std::fs::write(
        &scene,
        r#"{"constraints": [
            {"type": "position", "vertex": 0, "target": [1.7e308, 0, 0]},
            {"type": "position", "vertex": 99, "target": [-1.7e308, 0, 0]}
        ]}"#,
    )
    .unwrap();
    let out = p(dir.path(), "out.obj");
    let o = run(&["deform", &mesh, "-c", &scene, "-o", &out]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.starts_with("error: "), "{err}");
    assert!(!Path::new(&out).exists());
}

/// Outputs are checked before the input is even read: a missing input with
/// an unwritable output reports the output.
#[test]
fn outputs_are_checked_first() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(&[
        "deform",
        &p(dir.path(), "missing.obj"),
        "-c",
        &p(dir.path(), "missing.json"),
        "-o",
        &p(dir.path(), "x.stl"),
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        err.contains(".stl") && !err.contains("missing.obj"),
        "{err}"
    );
    // An existing output file is checked without being changed.
    let existing = p(dir.path(), "keep.obj");
    std::fs::write(&existing, "keep me").unwrap();
    let o = run(&[
        "deform",
        &p(dir.path(), "missing.obj"),
        "-c",
        &p(dir.path(), "missing.json"),
        "-o",
        &existing,
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("missing.obj"));
    assert_eq!(std::fs::read_to_string(&existing).unwrap(), "keep me");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "nothing left behind"
    );
}

#[test]
fn generate_says_which_vertex_count_it_produced() {
    let dir = tempfile::tempdir().unwrap();
    let out = p(dir.path(), "s.obj");
    let o = run(&["generate", "icosphere", "--vertices", "1000", "-o", &out]);
    assert!(o.status.success());
    // Icospheres have 10·4^k + 2 vertices: 642 and 2562 around 1000.
    let err = stderr(&o);
    assert!(err.contains("642 vertices"), "{err}");
    assert!(
        err.contains("1000 vertices asked for") && err.contains("2562"),
        "{err}"
    );
    let o = run(&["generate", "icosphere", "--vertices", "642", "-o", &out]);
    assert!(!stderr(&o).contains("asked for"), "{}", stderr(&o));
}

/// `scene` records the mesh; `deform` on another mesh with the same vertex
/// count warns, and with `--strict` refuses (exit 2).
#[test]
fn a_scene_for_another_mesh_warns_or_with_strict_fails() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    // The same grid, bent: same counts and faces, other positions.
    let grid = read_mesh(Path::new(&mesh)).unwrap().mesh;
    let bent: Vec<[f64; 3]> = grid
        .positions()
        .iter()
        .map(|q| [q[0], q[1], q[2] + 0.2 * q[0] * q[0]])
        .collect();
    let other = p(dir.path(), "other.obj");
    lse_deform::mesh::write_mesh(&grid.with_positions(bent).unwrap(), Path::new(&other)).unwrap();
    let out = p(dir.path(), "out.obj");
    let o = run(&["deform", &mesh, "-c", &scene, "-o", &out]);
    assert!(!stderr(&o).contains("made for"), "{}", stderr(&o));
    let o = run(&["deform", &other, "-c", &scene, "-o", &out]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("warning:") && err.contains("fingerprint"),
        "{err}"
    );
    std::fs::remove_file(&out).unwrap();
    let o = run(&["deform", &other, "-c", &scene, "-o", &out, "--strict"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.starts_with("error: ") && err.contains("fingerprint"),
        "{err}"
    );
    assert!(!Path::new(&out).exists());
}

/// A constraints file saved with a UTF-8 byte-order mark deforms.
#[test]
fn a_constraints_file_with_a_bom_works() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let text = std::fs::read_to_string(&scene).unwrap();
    let bom = p(dir.path(), "bom.json");
    std::fs::write(&bom, format!("\u{feff}{text}")).unwrap();
    let o = run(&["deform", &mesh, "-c", &bom, "-o", &p(dir.path(), "o.obj")]);
    assert!(o.status.success(), "{}", stderr(&o));
}
