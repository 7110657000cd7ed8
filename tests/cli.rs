//! The `lse-deform` binary as a user runs it.

use std::path::Path;

use lse_deform::mesh::read_mesh;

mod common;
use common::{grid_and_default_scene, path_in, run, stderr};

#[test]
fn generate_scene_deform_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = path_in(dir.path(), "grid.obj");
    let o = run(&["generate", "grid", "--vertices", "900", "-o", &mesh]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = path_in(dir.path(), "scene.json");
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
    let out = path_in(dir.path(), "out.ply");
    let report = path_in(dir.path(), "report.json");
    let o = run(&[
        "deform", &mesh, "-c", &scene, "-o", &out, "--report", &report,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let deformed = read_mesh(Path::new(&out), lse_deform::limits::MemoryBudget::default())
        .unwrap()
        .mesh;
    let original = read_mesh(
        Path::new(&mesh),
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap()
    .mesh;
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
        let path = path_in(dir.path(), name);
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
        args.push(path_in(dir.path(), "out.obj"));
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
        &path_in(dir.path(), "ok.obj"),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// `export-system` then `solve` reproduces `deform`: same positions to
/// 1e-12 relative and the same redundant and conflicting constraints, for
/// every method that applies to a mixed scene.
#[test]
fn export_system_then_solve_reproduces_deform() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = path_in(dir.path(), "sphere.obj");
    let o = run(&[
        "generate",
        "bumpy-sphere",
        "--vertices",
        "1500",
        "-o",
        &mesh,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = path_in(dir.path(), "scene.json");
    let o = run(&[
        "scene",
        &mesh,
        "--relative",
        "4",
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
    for method in [
        vec!["--method", "nullspace-qr"],
        vec![
            "--method",
            "nullspace-qr",
            "--qr",
            "dense-householder",
            "--spd",
            "faer-simplicial",
        ],
        vec!["--method", "penalty", "--weight", "1e3"],
    ] {
        let deformed = path_in(dir.path(), "deformed.obj");
        let deform_report = path_in(dir.path(), "deform.json");
        let mut args = vec![
            "deform",
            &mesh,
            "-c",
            &scene,
            "-o",
            &deformed,
            "--report",
            &deform_report,
        ];
        args.extend(&method);
        let o = run(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let system = path_in(dir.path(), "system");
        let mut args = vec!["export-system", &mesh, "-c", &scene, "-o", &system];
        args.extend(&method);
        let o = run(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let meta: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(Path::new(&system).join("meta.json")).unwrap(),
        )
        .unwrap();
        for key in [
            "method",
            "spd_backend",
            "laplacian",
            "kkt_multiplier_scale",
            "penalty_weight",
            "factored_unknowns",
            "laplacian_rows",
            "length_scale",
        ] {
            assert!(meta.get(key).is_some(), "meta.json lacks {key}");
        }
        assert_eq!(meta["laplacian"], "cotan");
        let x_path = path_in(dir.path(), "X.mtx");
        let solve_report = path_in(dir.path(), "solve.json");
        let mut args = vec!["solve", &system, "-o", &x_path, "--report", &solve_report];
        args.extend(&method);
        let o = run(&args);
        assert!(o.status.success(), "{:?}: {}", method, stderr(&o));
        let x = lse_deform::mtx::read_dense(Path::new(&x_path)).unwrap();
        let positions = read_mesh(
            Path::new(&deformed),
            lse_deform::limits::MemoryBudget::default(),
        )
        .unwrap()
        .mesh
        .positions()
        .to_vec();
        let (mut num, mut den) = (0.0f64, 0.0f64);
        // X is in the problem's units: the positions over `length_unit`.
        let unit = meta["length_unit"].as_f64().unwrap();
        for (i, q) in positions.iter().enumerate() {
            for c in 0..3 {
                num = num.max((x[(i, c)] * unit - q[c]).abs());
                den = den.max(q[c].abs());
            }
        }
        assert!(
            num / den <= 1e-12,
            "{method:?}: relative difference {:e}",
            num / den
        );
        let read = |path: &str| -> serde_json::Value {
            serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
        };
        let (r1, r2) = (read(&deform_report), read(&solve_report));
        for key in ["rank", "redundant", "conflicting", "length_scale", "method"] {
            assert_eq!(r1[key], r2[key], "{method:?}: {key}");
        }
    }
}

/// `solve` on a random sparse LSE written as Matrix Market files names
/// exactly the dependent rows of B; bad matrix files are one-line errors
/// with exit code 2.
#[test]
fn solve_names_dependent_rows_and_refuses_bad_files() {
    use faer::Mat;
    use faer::sparse::{SparseColMat, Triplet};
    let dir = tempfile::tempdir().unwrap();
    let n = 12;
    let a: Vec<Triplet<usize, usize, f64>> = (0..n)
        .flat_map(|j| {
            [
                Triplet::new(j, j, 2.0 + j as f64 * 0.1),
                Triplet::new((j + 1) % n, j, -1.0),
            ]
        })
        .collect();
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &a).unwrap();
    // Rows 0, 1 independent; row 2 = row 0 + row 1 (consistent: redundant);
    // row 3 independent; row 4 = 2 row 3 with D off by 1 (conflicting).
    let b = [
        (0, 0, 1.0),
        (0, 3, 1.0),
        (1, 5, 2.0),
        (1, 3, -1.0),
        (2, 0, 1.0),
        (2, 3, 0.0 + 0.0),
        (2, 5, 2.0),
        (3, 7, 1.0),
        (3, 8, 0.5),
        (4, 7, 2.0),
        (4, 8, 1.0),
    ];
    let b: Vec<_> = b.iter().map(|&(i, j, v)| Triplet::new(i, j, v)).collect();
    let b = SparseColMat::<usize, f64>::try_new_from_triplets(5, n, &b).unwrap();
    let c = Mat::from_fn(n, 2, |i, k| (i as f64 * 0.3 + k as f64).sin());
    let mut d = Mat::from_fn(5, 2, |i, k| i as f64 - k as f64 * 0.5);
    d[(2, 0)] = d[(0, 0)] + d[(1, 0)];
    d[(2, 1)] = d[(0, 1)] + d[(1, 1)];
    d[(4, 0)] = 2.0 * d[(3, 0)] + 1.0;
    d[(4, 1)] = 2.0 * d[(3, 1)];
    let sys = dir.path().join("lse");
    std::fs::create_dir_all(&sys).unwrap();
    lse_deform::mtx::write_sparse(&sys.join("A.mtx"), a.as_ref()).unwrap();
    lse_deform::mtx::write_dense(&sys.join("C.mtx"), c.as_ref()).unwrap();
    lse_deform::mtx::write_sparse(&sys.join("B.mtx"), b.as_ref()).unwrap();
    lse_deform::mtx::write_dense(&sys.join("D.mtx"), d.as_ref()).unwrap();
    let x_path = path_in(dir.path(), "X.mtx");
    let report = path_in(dir.path(), "r.json");
    let sys_s = sys.to_string_lossy().into_owned();
    let o = run(&["solve", &sys_s, "-o", &x_path, "--report", &report]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r["rank"], serde_json::json!(3));
    assert_eq!(r["redundant"], serde_json::json!([2]));
    assert_eq!(r["conflicting"][0]["index"], serde_json::json!(4));
    assert_eq!(r["conflicting"].as_array().unwrap().len(), 1);
    let x = lse_deform::mtx::read_dense(Path::new(&x_path)).unwrap();
    assert_eq!((x.nrows(), x.ncols()), (n, 2));
    assert!((x[(0, 0)] + x[(3, 0)] - d[(0, 0)]).abs() < 1e-12);

    // Bad files: exit code 2, one line naming the file and line.
    let bad_c = path_in(dir.path(), "badC.mtx");
    std::fs::write(
        &bad_c,
        "%%MatrixMarket matrix array real general\n12 2\n1\nfoo\n",
    )
    .unwrap();
    let o = run(&["solve", &sys_s, "--c", &bad_c, "-o", &x_path]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("badC.mtx, line 4: 'foo' is not a number"),
        "{err}"
    );
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    let short_d = path_in(dir.path(), "shortD.mtx");
    lse_deform::mtx::write_dense(Path::new(&short_d), Mat::<f64>::zeros(4, 2).as_ref()).unwrap();
    let o = run(&["solve", &sys_s, "--d", &short_d, "-o", &x_path]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("D must have as many rows as B"), "{err}");
    let o = run(&["solve", "-o", &x_path]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// A 900-vertex grid, a scene with every constraint kind (and a duplicate
/// and a conflict) for it, in `dir`: `(mesh path, scene path)`.
fn grid_and_scene(dir: &Path) -> (String, String) {
    let mesh = path_in(dir, "grid.obj");
    let o = run(&["generate", "grid", "--vertices", "900", "-o", &mesh]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = path_in(dir, "scene.json");
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
    let out = path_in(dir.path(), "out.ply");
    let report = path_in(dir.path(), "report.json");
    let o = run(&[
        "deform", &mesh, "-c", &scene, "-o", &out, "--report", &report,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let x = read_mesh(Path::new(&out), lse_deform::limits::MemoryBudget::default())
        .unwrap()
        .mesh;
    let original = read_mesh(
        Path::new(&mesh),
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap()
    .mesh;
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
    let out = path_in(dir.path(), "out.obj");
    let missing_dir = path_in(dir.path(), "no-such-dir/out.obj");
    let missing_report = path_in(dir.path(), "no-such-dir/report.json");
    // A file where the export directory should be: it cannot be created.
    let blocker = path_in(dir.path(), "blocker");
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
        (deform(&["-o", &path_in(dir.path(), "out.stl")]), 2, ".stl"),
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
    let mesh = path_in(dir.path(), "grid.obj");
    let o = run(&["generate", "grid", "--vertices", "100", "-o", &mesh]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = path_in(dir.path(), "huge.json");
    std::fs::write(
        &scene,
        r#"{"constraints": [
            {"type": "position", "vertex": 0, "target": [1.7e308, 0, 0]},
            {"type": "position", "vertex": 99, "target": [-1.7e308, 0, 0]}
        ]}"#,
    )
    .unwrap();
    let out = path_in(dir.path(), "out.obj");
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
        &path_in(dir.path(), "missing.obj"),
        "-c",
        &path_in(dir.path(), "missing.json"),
        "-o",
        &path_in(dir.path(), "x.stl"),
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        err.contains(".stl") && !err.contains("missing.obj"),
        "{err}"
    );
    // An existing output file is checked without being changed.
    let existing = path_in(dir.path(), "keep.obj");
    std::fs::write(&existing, "keep me").unwrap();
    let o = run(&[
        "deform",
        &path_in(dir.path(), "missing.obj"),
        "-c",
        &path_in(dir.path(), "missing.json"),
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
    let out = path_in(dir.path(), "s.obj");
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

/// The mesh at `mesh` bent, as `dir/other.obj`: the same counts and faces,
/// other positions (so another fingerprint).
fn bent_copy(dir: &Path, mesh: &str) -> String {
    let grid = read_mesh(Path::new(mesh), lse_deform::limits::MemoryBudget::default())
        .unwrap()
        .mesh;
    let bent: Vec<[f64; 3]> = grid
        .positions()
        .iter()
        .map(|q| [q[0], q[1], q[2] + 0.2 * q[0] * q[0]])
        .collect();
    let other = path_in(dir, "other.obj");
    lse_deform::mesh::write_mesh(&grid.with_positions(bent).unwrap(), Path::new(&other)).unwrap();
    other
}

/// `scene` records the mesh; `deform` on another mesh with the same vertex
/// count warns, and with `--strict` refuses (exit 2).
#[test]
fn a_scene_for_another_mesh_warns_or_with_strict_fails() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let other = bent_copy(dir.path(), &mesh);
    let out = path_in(dir.path(), "out.obj");
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
    let bom = path_in(dir.path(), "bom.json");
    std::fs::write(&bom, format!("\u{feff}{text}")).unwrap();
    let o = run(&[
        "deform",
        &mesh,
        "-c",
        &bom,
        "-o",
        &path_in(dir.path(), "o.obj"),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A conflicting constraint is one warning naming the constraint it
/// contradicts (the scene's `--conflict` contradicts the second fixed one);
/// with `--strict` it is exit code 2, after the warnings and the summary
/// line with its counts, and nothing is written.
#[test]
fn a_conflict_warns_once_and_with_strict_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let n = lse_deform::constraints::parse_constraints(&std::fs::read_to_string(&scene).unwrap())
        .unwrap()
        .len();
    let line = format!(
        "warning: constraint {} conflicts with constraint 1 and was dropped (residual ",
        n - 1
    );
    let out = path_in(dir.path(), "out.obj");
    let report = path_in(dir.path(), "report.json");
    let o = run(&["deform", &mesh, "-c", &scene, "-o", &out]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert_eq!(err.matches(&line).count(), 1, "{err}");
    assert!(err.contains("(1 redundant, 1 conflicting)"), "{err}");
    std::fs::remove_file(&out).unwrap();
    let o = run(&[
        "deform", &mesh, "-c", &scene, "-o", &out, "--report", &report, "--strict",
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.matches(&line).count(), 1, "{err}");
    assert!(err.contains("(1 redundant, 1 conflicting)"), "{err}");
    let last = err.lines().last().unwrap();
    assert!(
        last.starts_with(
            "error: 1 conflicting hard constraint(s), and --strict makes that an error: constraint"
        ) && last.contains("conflicts with constraint 1"),
        "{err}"
    );
    assert!(!Path::new(&out).exists() && !Path::new(&report).exists());
    // The same for the ARAP energy.
    let o = run(&[
        "deform",
        &mesh,
        "-c",
        &scene,
        "-o",
        &out,
        "--energy",
        "arap",
        "--iterations",
        "2",
        "--strict",
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.matches(&line).count(), 1, "{err}");
    assert!(err.contains("1 redundant, 1 conflicting"), "{err}");
    assert!(!Path::new(&out).exists());
}

/// Options the chosen method or energy does not use are said to be
/// ignored, never silently: `--weight` without penalty, `--qr` with a
/// method other than nullspace-qr, the ARAP options without `--energy
/// arap`, `--laplacian` and `--condition` with it (`--condition` was
/// ignored silently on aa82d57); the run itself goes on and is the same as
/// without them. Options that apply draw no such warning.
#[test]
fn options_that_do_not_apply_are_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let out = path_in(dir.path(), "out.obj");
    let deform = |extra: &[&str]| {
        let mut args = vec!["deform", &mesh, "-c", &scene, "-o", &out];
        args.extend_from_slice(extra);
        let o = run(&args);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        (stderr(&o), std::fs::read(&out).unwrap())
    };
    let (_, plain) = deform(&[]);
    for (extra, flag) in [
        (
            &["--weight", "1e3"][..],
            "--weight applies to --method penalty only",
        ),
        (
            &[
                "--method",
                "penalty",
                "--weight",
                "1e3",
                "--qr",
                "dense-householder",
            ][..],
            "--qr applies to --method nullspace-qr only",
        ),
        (
            &["--iterations", "3"][..],
            "--iterations applies to --energy arap only",
        ),
        (
            &["--arap-init", "rest"][..],
            "--arap-init applies to --energy arap only",
        ),
        (
            &["--energy", "arap", "--laplacian", "uniform"][..],
            "--laplacian applies to --energy laplacian only",
        ),
        (
            &["--energy", "arap", "--condition"][..],
            "--condition applies to --energy laplacian only; ignored with --energy arap",
        ),
    ] {
        let (err, written) = deform(extra);
        assert!(
            err.contains(&format!("warning: {flag}")),
            "{extra:?}: {err}"
        );
        if !extra.contains(&"arap") && !extra.contains(&"penalty") {
            assert_eq!(written, plain, "{extra:?} changed the result");
        }
    }
    for extra in [
        &["--method", "penalty", "--weight", "1e3"][..],
        &["--qr", "dense-householder"][..],
        &["--energy", "arap", "--iterations", "3"][..],
    ] {
        let (err, _) = deform(extra);
        assert!(!err.contains("applies to"), "{extra:?}: {err}");
    }
}

/// `scene --axis -y` fixes the top of a grid and drags its bottom, `--axis
/// y` the other way round (a y-up model whose longest extent is another
/// axis, the Stanford Bunny's x, needs one of them to fix its feet); the
/// groups are `fixed` and `handle`; a bad axis is refused naming the
/// accepted ones.
#[test]
fn scene_axis_takes_a_direction() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = path_in(dir.path(), "grid.obj");
    assert!(
        run(&["generate", "grid", "--vertices", "400", "-o", &mesh])
            .status
            .success()
    );
    let ys: Vec<f64> = read_mesh(
        Path::new(&mesh),
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap()
    .mesh
    .positions()
    .iter()
    .map(|q| q[1])
    .collect();
    let (lo, hi) = ys
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &y| {
            (l.min(y), h.max(y))
        });
    for (axis, fixed_end, handle_end) in [("y", lo, hi), ("-y", hi, lo)] {
        let scene = path_in(dir.path(), &format!("scene{axis}.json"));
        let o = run(&["scene", &mesh, "--axis", axis, "-o", &scene]);
        assert!(o.status.success(), "{}", stderr(&o));
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&scene).unwrap()).unwrap();
        let mut nearest = [f64::INFINITY; 2];
        for c in v["constraints"].as_array().unwrap() {
            let y = ys[c["vertex"].as_u64().unwrap() as usize];
            let (k, end) = match c["group"].as_str().unwrap() {
                "fixed" => (0, fixed_end),
                "handle" => (1, handle_end),
                g => panic!("group {g}"),
            };
            nearest[k] = nearest[k].min((y - end).abs());
        }
        // Each region contains the vertices at its own end of the axis.
        assert_eq!(nearest, [0.0, 0.0], "--axis {axis}");
    }
    let o = run(&[
        "scene",
        &mesh,
        "--axis",
        "w",
        "-o",
        &path_in(dir.path(), "s.json"),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("expected x, y, z, -x, -y or -z"),
        "{}",
        stderr(&o)
    );
}

/// The warning that a constraints file was made for another mesh is in
/// the report as well as on stderr: in `deform --report` (Laplacian and
/// ARAP) and in every report of `compare --json`. (Before: on stderr only,
/// the report's `warnings` empty.)
#[test]
fn a_scene_for_another_mesh_is_warned_about_in_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let other = bent_copy(dir.path(), &mesh);
    let out = path_in(dir.path(), "out.obj");
    let report = path_in(dir.path(), "report.json");
    let warnings = |json: &serde_json::Value| -> Vec<String> {
        json["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .map(|w| w.as_str().unwrap().to_string())
            .collect()
    };
    let read = |path: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
    };
    for energy in ["laplacian", "arap"] {
        let o = run(&[
            "deform",
            &other,
            "-c",
            &scene,
            "-o",
            &out,
            "--report",
            &report,
            "--energy",
            energy,
            "--iterations",
            "1",
        ]);
        let err = stderr(&o);
        assert!(o.status.success(), "{energy}: {err}");
        assert_eq!(err.matches("fingerprint").count(), 1, "{energy}: {err}");
        let w = warnings(&read(&report));
        assert!(
            w.first().is_some_and(|w| w.contains("fingerprint")),
            "{energy}: {w:?}"
        );
    }
    let json = path_in(dir.path(), "compare.json");
    let o = run(&[
        "compare",
        &other,
        "-c",
        &scene,
        "--methods",
        "nullspace-qr",
        "--qr",
        "sparse-givens",
        "--spd",
        "faer-auto",
        "--repeat",
        "1",
        "--no-condition",
        "--json",
        &json,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = read(&json);
    let rows = rows.as_array().unwrap();
    assert!(!rows.is_empty());
    for row in rows {
        let w = warnings(&row["report"]);
        assert!(w.iter().any(|w| w.contains("fingerprint")), "{w:?}");
    }
}

/// `--strict` on an inaccurate solution advises what could help with the
/// method in use: never "use the null-space method" when that method is in
/// use, and it is named when another method is. A sliver grid with
/// refinement off gives a forward error of about 2e-2. (Before: the same
/// advice, null-space method included, whatever the method.)
#[test]
fn strict_advice_depends_on_the_method_in_use() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = path_in(dir.path(), "sliver.obj");
    let o = run(&["generate", "sliver", "--vertices", "3000", "-o", &mesh]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = path_in(dir.path(), "scene.json");
    assert!(run(&["scene", &mesh, "-o", &scene]).status.success());
    let out = path_in(dir.path(), "out.obj");
    let strict = |method: &str| {
        let o = run(&[
            "deform", &mesh, "-c", &scene, "-o", &out, "--method", method, "--refine", "off",
            "--strict",
        ]);
        assert_eq!(o.status.code(), Some(3), "{method}: {}", stderr(&o));
        stderr(&o)
    };
    let err = strict("nullspace-qr");
    assert!(err.contains("refinement `auto`"), "{err}");
    assert!(!err.contains("null-space method"), "{err}");
    let err = strict("kkt");
    assert!(
        err.contains("refinement `auto`") && err.contains("use the null-space method"),
        "{err}"
    );
    assert!(!Path::new(&out).exists());
}

/// `export-system -o /dev/full` says that the path is not a directory
/// (before: "File exists", from creating a directory on a device).
#[cfg(unix)]
#[test]
fn export_system_to_a_device_says_it_is_not_a_directory() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let o = run(&["export-system", &mesh, "-c", &scene, "-o", "/dev/full"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("/dev/full") && err.contains("not a directory"),
        "{err}"
    );
    assert!(!err.contains("File exists"), "{err}");
    // A regular file in the way says so too.
    let o = run(&["export-system", &mesh, "-c", &scene, "-o", &mesh]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("a regular file, not a directory"), "{err}");
}

/// `--factor` names the matrix factorisation; `--spd`, its old name, is
/// still accepted and means the same: the same output mesh
/// byte for byte, for KKT's LDLᵀ variant as for a Cholesky back end. With
/// no option at all the run is the one with every documented default
/// spelled out, and `--help` shows the library's defaults.
#[test]
fn factor_is_the_new_name_of_spd_and_defaults_are_the_documented_ones() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = path_in(dir.path(), "grid.obj");
    let o = run(&["generate", "grid", "--vertices", "400", "-o", &mesh]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = path_in(dir.path(), "scene.json");
    let o = run(&["scene", &mesh, "-o", &scene]);
    assert!(o.status.success(), "{}", stderr(&o));
    let deform = |name: &str, extra: &[&str]| {
        let out = path_in(dir.path(), name);
        let mut args = vec!["deform", &mesh, "-c", &scene, "-o", &out];
        args.extend(extra);
        let o = run(&args);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        std::fs::read(&out).unwrap()
    };
    for method in ["kkt", "nullspace-qr"] {
        let new = deform(
            "new.obj",
            &["--method", method, "--factor", "faer-simplicial"],
        );
        let old = deform("old.obj", &["--method", method, "--spd", "faer-simplicial"]);
        assert_eq!(new, old, "--method {method}");
    }
    let bare = deform("bare.obj", &[]);
    let spelled = deform(
        "spelled.obj",
        &[
            "--laplacian",
            "cotan",
            "--method",
            "nullspace-qr",
            "--qr",
            "sparse-givens",
            "--factor",
            "faer-auto",
            "--energy",
            "laplacian",
        ],
    );
    assert_eq!(bare, spelled);
    let help = String::from_utf8_lossy(&run(&["deform", "--help"]).stdout).into_owned();
    for shown in [
        "[default: cotan]",
        "[default: nullspace-qr]",
        "[default: sparse-givens]",
        "[default: faer-auto]",
        "--spd <SPD>",
        "[default: 10]",
        "[default: spokes-and-rims]",
        "[default: linear]",
    ] {
        assert!(help.contains(shown), "--help lacks {shown}:\n{help}");
    }
}

/// `--refine 0` applies no correction: the report says 0 steps and the
/// mesh is the one `--refine off` writes; `--refine 1` applies one.
/// (Before: `--refine 0` ran one step, its output byte-identical to
/// `--refine 1` and its report `steps 1`.)
#[test]
fn refine_zero_means_zero_steps() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mesh = path_in(d, "grid.obj");
    let o = run(&["generate", "grid", "--vertices", "400", "-o", &mesh]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = path_in(d, "scene.json");
    let o = run(&["scene", &mesh, "-o", &scene]);
    assert!(o.status.success(), "{}", stderr(&o));
    let deform = |refine: &str| {
        let (out, report) = (path_in(d, "out.ply"), path_in(d, "r.json"));
        let args = [
            "deform", &mesh, "-c", &scene, "-o", &out, "--report", &report,
        ];
        let o = run(&[&args[..], &["--refine", refine]].concat());
        assert!(o.status.success(), "--refine {refine}: {}", stderr(&o));
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        (std::fs::read(&out).unwrap(), r["refinement"].clone())
    };
    let (zero, r0) = deform("0");
    assert_eq!(r0["steps"], 0, "{r0}");
    assert_eq!(r0["stop_reason"], "off", "{r0}");
    let (off, _) = deform("off");
    assert_eq!(zero, off);
    let (_, r1) = deform("1");
    assert_eq!(r1["steps"], 1, "{r1}");
}

/// `--ordering` and `--threads` reach the back end and the report says
/// what was used; with one AMD permutation the exact-fill back ends agree
/// on the factor's size; a bad value is a usage error naming the flag.
#[test]
fn ordering_and_threads_are_held_and_reported() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_default_scene(dir.path(), 900);
    let report_of = |factor: &str, held: &[&str]| {
        let out = path_in(dir.path(), &format!("out-{factor}.obj"));
        let report = path_in(dir.path(), &format!("report-{factor}.json"));
        let mut args = vec![
            "deform", &mesh, "-c", &scene, "-o", &out, "--report", &report, "--factor", factor,
        ];
        args.extend_from_slice(held);
        let o = run(&args);
        assert!(o.status.success(), "{factor}: {}", stderr(&o));
        let text = std::fs::read_to_string(&report).unwrap();
        serde_json::from_str::<serde_json::Value>(&text).unwrap()
    };
    let own = report_of("faer-auto", &[]);
    assert_eq!(own["ordering"], "own (amd)");
    assert_eq!(own["threads"], 1);
    assert_eq!(own["timings_s"]["ordering"], 0.0);
    let held = ["--ordering", "amd", "--threads", "1"];
    let simplicial = report_of("faer-simplicial", &held);
    let nalgebra = report_of("nalgebra", &held);
    for r in [&simplicial, &nalgebra] {
        assert_eq!(r["ordering"], "amd");
        assert_eq!(r["threads"], 1);
        assert!(r["timings_s"]["ordering"].as_f64().unwrap() > 0.0);
    }
    assert_eq!(simplicial["nnz"]["factor"], nalgebra["nnz"]["factor"]);
    for (flag, value) in [("--ordering", "colamd"), ("--threads", "0")] {
        let out = path_in(dir.path(), "bad.obj");
        let o = run(&["deform", &mesh, "-c", &scene, "-o", &out, flag, value]);
        assert_eq!(o.status.code(), Some(2), "{flag} {value}");
        assert!(stderr(&o).contains(flag), "{}", stderr(&o));
    }
}

/// `--ordering-file`: the identity written as a file factors with the
/// factor `--ordering natural` gives (same fill), the report says `given`,
/// and the deformation is the default's; a word that is not an index, a
/// list that is not a permutation and an output onto the file are usage
/// errors naming what is wrong.
#[test]
fn an_ordering_file_is_given_to_the_back_end() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (mesh, scene) = grid_and_default_scene(d, 900);
    let original = read_mesh(
        Path::new(&mesh),
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap()
    .mesh;
    let n = original.n_vertices();
    let identity = path_in(d, "identity.txt");
    let words: Vec<String> = (0..n).map(|i| i.to_string()).collect();
    std::fs::write(
        &identity,
        format!("# the identity\n[{}]\n", words.join(", ")),
    )
    .unwrap();
    let deform = |name: &str, held: &[&str]| {
        let out = path_in(d, &format!("{name}.obj"));
        let report = path_in(d, &format!("{name}.json"));
        let mut args = vec![
            "deform",
            &mesh,
            "-c",
            &scene,
            "-o",
            &out,
            "--report",
            &report,
            "--factor",
            "faer-simplicial",
        ];
        args.extend_from_slice(held);
        let o = run(&args);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        let text = std::fs::read_to_string(&report).unwrap();
        let r: serde_json::Value = serde_json::from_str(&text).unwrap();
        let x = read_mesh(Path::new(&out), lse_deform::limits::MemoryBudget::default())
            .unwrap()
            .mesh;
        (r, x.positions().to_vec())
    };
    let (own, own_x) = deform("own", &[]);
    let (natural, _) = deform("natural", &["--ordering", "natural"]);
    let (given, given_x) = deform("given", &["--ordering-file", &identity]);
    assert_eq!(given["ordering"], "given");
    assert_eq!(given["nnz"]["factor"], natural["nnz"]["factor"]);
    assert_ne!(given["nnz"]["factor"], own["nnz"]["factor"]);
    let diagonal = original.bbox_diagonal();
    let worst = own_x
        .iter()
        .zip(&given_x)
        .flat_map(|(a, b)| a.iter().zip(b).map(|(p, q)| (p - q).abs()))
        .fold(0.0, f64::max);
    assert!(worst <= 1e-10 * diagonal, "{worst} of {diagonal}");

    let out = path_in(d, "bad.obj");
    let not_an_index = path_in(d, "word.txt");
    std::fs::write(&not_an_index, "0\n1\nthree\n").unwrap();
    let repeated = path_in(d, "repeated.txt");
    let mut twice = words.clone();
    twice[1] = "0".into();
    std::fs::write(&repeated, twice.join("\n")).unwrap();
    for (file, expected) in [(&not_an_index, "line 3"), (&repeated, "not a permutation")] {
        let o = run(&[
            "deform",
            &mesh,
            "-c",
            &scene,
            "-o",
            &out,
            "--ordering-file",
            file,
        ]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(expected), "{}", stderr(&o));
    }
    let o = run(&[
        "deform",
        &mesh,
        "-c",
        &scene,
        "-o",
        &identity,
        "--ordering-file",
        &identity,
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--ordering-file"), "{}", stderr(&o));
    assert!(
        std::fs::read_to_string(&identity)
            .unwrap()
            .starts_with("# the identity")
    );
}

/// Every door refuses an ordering file that is not a permutation of the
/// mesh's vertices the same way, exit 2 naming it: `compare` too (on
/// aa82d57 it exited 0 with every row "error (input)"), and every method
/// when every vertex is fixed, so that nothing is factored (on aa82d57
/// nullspace-qr and eliminate accepted a wrong-length ordering there,
/// kkt and penalty refused it).
#[test]
fn an_ordering_of_the_wrong_unknowns_is_refused_by_every_door_and_method() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (mesh, scene) = grid_and_default_scene(d, 900);
    let m = read_mesh(
        Path::new(&mesh),
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap()
    .mesh;
    let n = m.n_vertices();
    let short = path_in(d, "short.txt");
    let words: Vec<String> = (0..n - 1).map(|i| i.to_string()).collect();
    std::fs::write(&short, words.join("\n")).unwrap();
    let json = path_in(d, "rows.json");
    let o = run(&[
        "compare",
        &mesh,
        "-c",
        &scene,
        "--methods",
        "nullspace-qr,kkt",
        "--repeat",
        "1",
        "--no-condition",
        "--json",
        &json,
        "--ordering-file",
        &short,
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains(&format!("the problem has {n} unknowns")),
        "{}",
        stderr(&o)
    );
    assert!(!Path::new(&json).exists());
    // Every vertex fixed where it is.
    let fixed = path_in(d, "fixed.json");
    let items: Vec<serde_json::Value> = m
        .positions()
        .iter()
        .enumerate()
        .map(|(v, p)| serde_json::json!({"type": "position", "vertex": v, "target": p}))
        .collect();
    std::fs::write(
        &fixed,
        serde_json::json!({ "constraints": items }).to_string(),
    )
    .unwrap();
    let out = path_in(d, "out.obj");
    for method in ["nullspace-qr", "eliminate", "kkt", "penalty"] {
        let mut args = vec![
            "deform",
            &mesh,
            "-c",
            &fixed,
            "-o",
            &out,
            "--method",
            method,
            "--ordering-file",
            &short,
        ];
        if method == "penalty" {
            args.extend(["--weight", "1e4"]);
        }
        let o = run(&args);
        assert_eq!(o.status.code(), Some(2), "{method}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!("the problem has {n} unknowns")),
            "{method}: {}",
            stderr(&o)
        );
    }
}
