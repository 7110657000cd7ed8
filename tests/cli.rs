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
