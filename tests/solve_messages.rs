//! Messages of `lse-deform solve` that used to mislead, on general problems
//! given as Matrix Market files:
//!
//! - a non-finite solution of a general problem names the row of X, not
//!   "a non-finite position at vertex 0" (no mesh, no vertex);
//! - KKT's failed pivots give no "NaN of the magnitude" and no "1-th";
//! - a full-rank A scaled by 1e±300 is never called "free" with a NaN
//!   ratio (it either solves, or says what is out of range).
//!

use std::path::Path;
use std::process::Output;

mod common;
use common::{path_in, run, stderr};

/// Writes `text` as `dir/name` and returns its path.
fn mtx(dir: &Path, name: &str, text: &str) -> String {
    let path = path_in(dir, name);
    std::fs::write(&path, text).unwrap();
    path
}

fn coordinate(rows: usize, cols: usize, entries: &[(usize, usize, f64)]) -> String {
    let mut s = format!(
        "%%MatrixMarket matrix coordinate real general\n{rows} {cols} {}\n",
        entries.len()
    );
    for (i, j, v) in entries {
        s.push_str(&format!("{i} {j} {v:e}\n"));
    }
    s
}

fn array(rows: usize, values: &[f64]) -> String {
    let mut s = format!("%%MatrixMarket matrix array real general\n{rows} 1\n");
    for v in values {
        s.push_str(&format!("{v:e}\n"));
    }
    s
}

/// `solve --a A --c C --b B --d D --method METHOD -o dir/x.mtx`.
fn solve(dir: &Path, files: [&str; 4], method: &str) -> Output {
    let [a, c, b, d] = files;
    run(&[
        "solve",
        "--a",
        a,
        "--c",
        c,
        "--b",
        b,
        "--d",
        d,
        "--method",
        method,
        "-o",
        &path_in(dir, "x.mtx"),
    ])
}

/// X = (1e600, ·) from a hard row 1e-300·x₀ = 1e300, and X = 1e308·(2, 1)
/// from soft rows alone: exit 3, naming the row of X. (Before: "solve
/// produced a non-finite position at vertex 0", for a problem without a
/// mesh.)
#[test]
fn a_non_finite_solution_of_a_general_problem_names_the_row_of_x() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let identity = mtx(d, "I.mtx", &coordinate(2, 2, &[(1, 1, 1.0), (2, 2, 1.0)]));
    let c = mtx(d, "C.mtx", &array(2, &[1.0, 2.0]));
    let tiny_row = mtx(d, "Bt.mtx", &coordinate(1, 2, &[(1, 1, 1e-300)]));
    let huge_d = mtx(d, "Dh.mtx", &array(1, &[1e300]));
    let shear = mtx(
        d,
        "S.mtx",
        &coordinate(2, 2, &[(1, 1, 1.0), (2, 2, 1.0), (2, 1, -1.0)]),
    );
    let huge_c = mtx(d, "Ch.mtx", &array(2, &[1e308, 1e308]));
    let no_rows = mtx(d, "B0.mtx", &coordinate(0, 2, &[]));
    let no_d = mtx(
        d,
        "D0.mtx",
        "%%MatrixMarket matrix array real general\n0 1\n",
    );
    for (files, method) in [
        ([&identity, &c, &tiny_row, &huge_d], "nullspace-qr"),
        ([&identity, &c, &tiny_row, &huge_d], "eliminate"),
        ([&shear, &huge_c, &no_rows, &no_d], "kkt"),
        ([&shear, &huge_c, &no_rows, &no_d], "eliminate"),
    ] {
        let files = files.map(String::as_str);
        let o = solve(d, files, method);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(3), "{method}: {err}");
        assert!(err.contains("row 0 of X"), "{method}: {err}");
        assert!(!err.contains("position at vertex"), "{method}: {err}");
    }
}

/// KKT's singular pivots, of a multiplier (a hard row 1e-300·x₀ = 1e300)
/// and of an unknown (A of rank 3 on 4 unknowns): no NaN ratio and no
/// "1-th". (Before: "the pivot of its multiplier is 0e0, NaN of the
/// magnitude it was computed from" and "its pivot (eliminated 1-th)".)
#[test]
fn kkt_pivot_messages_have_no_nan_and_no_th_ordinal() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let identity = mtx(d, "I.mtx", &coordinate(2, 2, &[(1, 1, 1.0), (2, 2, 1.0)]));
    let c = mtx(d, "C.mtx", &array(2, &[1.0, 2.0]));
    let tiny_row = mtx(d, "Bt.mtx", &coordinate(1, 2, &[(1, 1, 1e-300)]));
    let huge_d = mtx(d, "Dh.mtx", &array(1, &[1e300]));
    let rank3 = mtx(
        d,
        "A4.mtx",
        &coordinate(
            4,
            4,
            &[
                (1, 1, 1.0),
                (1, 2, 1.0),
                (2, 1, 1.0),
                (2, 2, 1.0),
                (3, 3, 1.0),
                (4, 4, 1.0),
            ],
        ),
    );
    let c4 = mtx(d, "C4.mtx", &array(4, &[1.0, 2.0, 3.0, 4.0]));
    let b4 = mtx(d, "B4.mtx", &coordinate(1, 4, &[(1, 4, 1.0)]));
    let d1 = mtx(d, "D1.mtx", &array(1, &[0.5]));
    for (files, what) in [
        ([&identity, &c, &tiny_row, &huge_d], "multiplier"),
        ([&rank3, &c4, &b4, &d1], "unknown"),
    ] {
        let o = solve(d, files.map(String::as_str), "kkt");
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(3), "{what}: {err}");
        assert!(
            err.contains("KKT") && err.contains("singular"),
            "{what}: {err}"
        );
        assert!(!err.contains("NaN"), "{what}: {err}");
        assert!(!err.contains("-th"), "{what}: {err}");
    }
}

/// A full-rank A (3 × 2, columns independent) scaled by 1e300 or 1e-300,
/// with one hard row x₀ = 0.5: its solution (0.5, 2/s) is a double. Either
/// it is solved (exit 0, to 1e-12 of the solution's size, a missed hard
/// row warned about),
/// or refused with a message that does not call an unknown "free" (it is
/// not) nor print a NaN ratio. (Before: exit 3, "unknown 1 (row 1 of X)
/// is free … pivot/diagonal = NaN" for 1e300 and "unknown 1 … is free …
/// not positive" for 1e-300: the normal matrices squared entries near
/// 1e±300. `A` and `C` are now multiplied by a power of two first.)
#[test]
fn a_full_rank_a_scaled_by_1e_pm300_is_not_called_free() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let c = mtx(d, "C.mtx", &array(3, &[1.0, 2.0, 3.0]));
    let b = mtx(d, "B.mtx", &coordinate(1, 2, &[(1, 1, 1.0)]));
    let dd = mtx(d, "D.mtx", &array(1, &[0.5]));
    for s in [1e300, 1e-300] {
        let a = mtx(
            d,
            "A.mtx",
            &coordinate(3, 2, &[(1, 1, s), (2, 2, s), (3, 1, s)]),
        );
        for method in ["nullspace-qr", "kkt", "eliminate"] {
            let o = solve(d, [&a, &c, &b, &dd], method);
            let err = stderr(&o);
            if o.status.success() {
                let x: Vec<f64> = std::fs::read_to_string(path_in(d, "x.mtx"))
                    .unwrap()
                    .lines()
                    .filter(|l| !l.starts_with('%'))
                    .skip(1)
                    .map(|l| l.trim().parse().unwrap())
                    .collect();
                // Normwise: each component within 1e-12 of ‖X*‖∞ (with
                // s = 1e-300, X* = (0.5, 2e300), and KKT's x₀ carries a
                // rounding error of ~1e284, as any normwise-stable method
                // may); a hard row missed beyond 1e-12 of its target must
                // be warned about.
                let want = [0.5, 2.0 / s];
                let norm = want[1].max(0.5);
                for k in 0..2 {
                    assert!(
                        (x[k] - want[k]).abs() <= 1e-12 * norm,
                        "{s:e} {method}: {x:?}"
                    );
                }
                if (x[0] - 0.5).abs() > 1e-12 {
                    assert!(err.contains("warning"), "{s:e} {method}: {err}");
                }
            } else {
                assert!(!err.contains("is free"), "{s:e} {method}: {err}");
                assert!(!err.contains("NaN"), "{s:e} {method}: {err}");
            }
        }
    }
}

/// The conflicting system x₀ = 0.5, x₀ = 0.6 (A = I on two unknowns) as a
/// directory `solve` reads: A.mtx, C.mtx, B.mtx, D.mtx in `dir`.
fn conflicting_system(dir: &Path) {
    mtx(dir, "A.mtx", &coordinate(2, 2, &[(1, 1, 1.0), (2, 2, 1.0)]));
    mtx(dir, "C.mtx", &array(2, &[1.0, 2.0]));
    mtx(dir, "B.mtx", &coordinate(2, 2, &[(1, 1, 1.0), (2, 1, 1.0)]));
    mtx(dir, "D.mtx", &array(2, &[0.5, 0.6]));
}

/// A meta.json left from another export (here: of a 900-vertex grid, on
/// the 2-unknown conflicting system) is refused (exit 2, naming the file
/// and what differs), as is one whose matrices changed since the export
/// (same shapes, other values: the fingerprint differs); the export's own
/// meta.json is accepted. (Before: used silently, exit 0, the conflict's
/// residual reported in the wrong length scale.)
#[test]
fn a_stale_meta_json_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mesh = path_in(d, "grid.obj");
    assert!(
        run(&["generate", "grid", "--vertices", "900", "-o", &mesh])
            .status
            .success()
    );
    let scene = path_in(d, "scene.json");
    assert!(run(&["scene", &mesh, "-o", &scene]).status.success());
    let export = path_in(d, "export");
    let o = run(&["export-system", &mesh, "-c", &scene, "-o", &export]);
    assert!(o.status.success(), "{}", stderr(&o));
    let x = path_in(d, "x.mtx");
    let o = run(&["solve", &export, "-o", &x]);
    assert!(o.status.success(), "the export's own meta: {}", stderr(&o));
    let meta = Path::new(&export).join("meta.json");
    // Another system with the grid's meta.json beside it.
    let small = d.join("small");
    std::fs::create_dir(&small).unwrap();
    conflicting_system(&small);
    std::fs::copy(&meta, small.join("meta.json")).unwrap();
    let o = run(&["solve", small.to_str().unwrap(), "-o", &x]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("meta.json") && err.contains("unknowns is 900"),
        "{err}"
    );
    // The grid's matrices with D changed (same shape): the fingerprint.
    let dpath = Path::new(&export).join("D.mtx");
    let text = std::fs::read_to_string(&dpath).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let last = lines.len() - 1;
    lines[last] = "1.25e-1".into();
    std::fs::write(&dpath, lines.join("\n") + "\n").unwrap();
    let o = run(&["solve", &export, "-o", &x]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("meta.json") && err.contains("fingerprint"),
        "{err}"
    );
}

/// A meta.json for the system in `dir` with the given units and the
/// fingerprint `export-system` would give it.
fn meta_for(dir: &Path, laplacian_rows: usize, length_scale: f64, length_unit: f64) -> String {
    use lse_deform::export::{MetaUnits, read_dense, read_sparse, system_fingerprint};
    let (a, c) = (
        read_sparse(&dir.join("A.mtx")).unwrap(),
        read_dense(&dir.join("C.mtx")).unwrap(),
    );
    let (b, d) = (
        read_sparse(&dir.join("B.mtx")).unwrap(),
        read_dense(&dir.join("D.mtx")).unwrap(),
    );
    let units = MetaUnits {
        laplacian_rows,
        length_scale,
        length_unit,
    };
    let f = system_fingerprint(a.as_ref(), c.as_ref(), b.as_ref(), d.as_ref(), &units);
    serde_json::json!({
        "laplacian_rows": laplacian_rows,
        "length_scale": length_scale,
        "length_unit": length_unit,
        "fingerprint": f,
    })
    .to_string()
}

/// A meta.json whose length_scale makes the conflict test meaningless
/// (1e300 for targets of size 0.6: the tolerance 1e-8 × 1e300 would call
/// the conflict x₀ = 0.5, x₀ = 0.6 redundant) is refused, exit 2, naming
/// the file and the key, even with a fingerprint that matches; one that
/// fits is used. (Before: exit 0, "1 redundant, 0 conflicting", forward
/// error ~4e-316.)
#[test]
fn an_implausible_length_scale_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    conflicting_system(d);
    let x = path_in(d, "x.mtx");
    let meta = path_in(d, "meta.json");
    std::fs::write(&meta, meta_for(d, 0, 1e300, 1.0)).unwrap();
    let dir_arg = d.to_str().unwrap();
    let o = run(&["solve", dir_arg, "-o", &x]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("meta.json") && err.contains("length_scale 1e300 is implausible"),
        "{err}"
    );
    assert!(!err.contains("0 conflicting"), "{err}");
    std::fs::write(&meta, meta_for(d, 0, 1e-30, 1.0)).unwrap();
    let o = run(&["solve", dir_arg, "-o", &x]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    std::fs::write(&meta, meta_for(d, 0, 2.0, 1.0)).unwrap();
    let o = run(&["solve", dir_arg, "-o", &x]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("1 conflicting"), "{err}");
}

/// `solve DIR` trusts nothing in meta.json that its fingerprint does not
/// cover: an edited length_scale (3.8e9, which would call a conflict
/// redundant), length_unit (1e300) or laplacian_rows, a file that is not
/// an object, a key given twice, a missing, null or old (`fnv1a64-v1`,
/// matrices only) fingerprint are each refused, exit 2, naming the file
/// and what is wrong; the export's own file is used. (Before: each was
/// used, exit 0: "1 redundant, 0 conflicting", residuals of 5e300, `[1,2,3]`
/// read as empty, the last of two keys kept.)
#[test]
fn meta_json_is_trusted_only_as_far_as_its_fingerprint_goes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mesh = path_in(d, "grid.obj");
    assert!(
        run(&["generate", "grid", "--vertices", "400", "-o", &mesh])
            .status
            .success()
    );
    let scene = path_in(d, "scene.json");
    assert!(
        run(&["scene", &mesh, "--conflict", "-o", &scene])
            .status
            .success()
    );
    let export = path_in(d, "export");
    let o = run(&["export-system", &mesh, "-c", &scene, "-o", &export]);
    assert!(o.status.success(), "{}", stderr(&o));
    let x = path_in(d, "x.mtx");
    let o = run(&["solve", &export, "-o", &x]);
    assert!(o.status.success(), "the export's own meta: {}", stderr(&o));
    assert!(stderr(&o).contains("1 conflicting"), "{}", stderr(&o));
    let path = Path::new(&export).join("meta.json");
    let original = std::fs::read_to_string(&path).unwrap();
    let value: serde_json::Value = serde_json::from_str(&original).unwrap();
    let edited = |key: &str, v: serde_json::Value| {
        let mut m = value.clone();
        m[key] = v;
        m.to_string()
    };
    let without_fingerprint = {
        let mut m = value.clone();
        m.as_object_mut().unwrap().remove("fingerprint");
        m.to_string()
    };
    let v1 = original.replace("fnv1a64-v2:", "fnv1a64-v1:");
    let twice = original.replacen('{', "{\"length_scale\": 3.8e9,", 1);
    let cases: [(String, &str); 9] = [
        (
            edited("length_scale", serde_json::json!(3.8e9)),
            "fingerprint",
        ),
        (
            edited("length_unit", serde_json::json!(1e300)),
            "fingerprint",
        ),
        (
            edited("laplacian_rows", serde_json::json!(3)),
            "laplacian_rows",
        ),
        ("[1,2,3]".into(), "JSON object"),
        (twice, "'length_scale' appears twice"),
        (without_fingerprint, "no 'fingerprint'"),
        (
            edited("fingerprint", serde_json::Value::Null),
            "no 'fingerprint'",
        ),
        (v1, "export the system again"),
        (
            edited("length_unit", serde_json::Value::Null),
            "no 'length_unit'",
        ),
    ];
    for (text, words) in cases {
        std::fs::write(&path, &text).unwrap();
        let o = run(&["solve", &export, "-o", &x]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{text}: {err}");
        assert!(
            err.contains("meta.json") && err.contains(words),
            "{words}: {err}"
        );
    }
}
