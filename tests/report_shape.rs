//! The report's JSON keeps its shape: for a fixed small problem
//! (tests/data/report_shape: a 100-vertex grid, a scene of every
//! constraint kind with a duplicate and a conflict, and one of positions
//! with a soft handle), `deform --report` with each method writes the keys
//! and values the release before the typed report wrote (the
//! `*.report.json` files there were written by that release, commit
//! 9e12bbd, from these inputs), in the same order, plus the keys added
//! since: `factor_backend` (equal to `spd_backend`, its deprecated alias),
//! `warning_codes` (one stable code per warning), `refactorizations`,
//! `ordering` and `threads` (what the factorisation used), and the phase
//! `timings_s.ordering`. Timings and the
//! memory budget (which depends on the machine) are compared by key only;
//! numbers to `1e-9` relative or `1e-12` absolute, since another CPU's
//! kernels may round differently (on the machine that wrote the files they
//! are equal bit for bit).

mod common;

use std::path::{Path, PathBuf};

use common::{path_in, run, stderr};
use serde_json::Value;

/// The keys added to the report since 9e12bbd.
const ADDED: [&str; 5] = [
    "factor_backend",
    "warning_codes",
    "refactorizations",
    "ordering",
    "threads",
];

/// The phase added to `timings_s` since 9e12bbd (computing a held
/// ordering).
const ADDED_TIMINGS: [&str; 1] = ["ordering"];

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/report_shape")
        .join(name)
}

/// Runs `deform` on the grid with `scene` and `args`, returns its report.
fn report_of(scene: &str, args: &[&str]) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let out = path_in(dir.path(), "out.obj");
    let report = path_in(dir.path(), "report.json");
    let (mesh, scene) = (data("grid.obj"), data(scene));
    let mut all = vec![
        "deform",
        mesh.to_str().unwrap(),
        "-c",
        scene.to_str().unwrap(),
        "-o",
        &out,
        "--report",
        &report,
    ];
    all.extend(args);
    let o = run(&all);
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap()
}

fn expected(name: &str) -> Value {
    let text = std::fs::read_to_string(data(&format!("{name}.report.json"))).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// Whether a key's value is a wall-clock time or the machine's memory.
fn machine_dependent(key: &str) -> bool {
    key == "memory_budget" || key == "timings_s" || key.contains("time")
}

/// `new` has `old`'s value at `path`: same keys in the same order (plus
/// [`ADDED`] at the top level), numbers to the tolerance of the module
/// documentation, machine-dependent values by shape only.
fn assert_same(old: &Value, new: &Value, path: &str, top: bool) {
    match (old, new) {
        (Value::Object(a), Value::Object(b)) => {
            let kept: Vec<&String> = b
                .keys()
                .filter(|k| !(top && ADDED.contains(&k.as_str())))
                .collect();
            let before: Vec<&String> = a.keys().collect();
            assert_eq!(kept, before, "{path}: the keys changed");
            for (k, v) in a {
                let here = format!("{path}.{k}");
                if machine_dependent(k) {
                    let mut now = b[k].clone();
                    if let (true, Value::Object(t)) = (top && k == "timings_s", &mut now) {
                        t.retain(|key, _| !ADDED_TIMINGS.contains(&key.as_str()));
                    }
                    assert_eq!(shape(v), shape(&now), "{here}");
                } else {
                    assert_same(v, &b[k], &here, false);
                }
            }
        }
        (Value::Array(a), Value::Array(b)) => {
            assert_eq!(a.len(), b.len(), "{path}: length");
            for (i, (x, y)) in a.iter().zip(b).enumerate() {
                assert_same(x, y, &format!("{path}[{i}]"), false);
            }
        }
        (Value::Number(x), Value::Number(y)) if x.is_f64() || y.is_f64() => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            let close = (x - y).abs() <= 1e-12 + 1e-9 * x.abs().max(y.abs());
            assert!(close, "{path}: {x:e} became {y:e}");
        }
        _ => assert_eq!(old, new, "{path}"),
    }
}

/// The keys and kinds of a value, without its numbers.
fn shape(v: &Value) -> Value {
    match v {
        Value::Object(m) => m.iter().map(|(k, v)| (k.clone(), shape(v))).collect(),
        Value::Array(a) => a.iter().map(shape).collect(),
        Value::Number(_) => Value::from("number"),
        other => other.clone(),
    }
}

/// The added keys: `factor_backend` equals `spd_backend`, and
/// `warning_codes` has one code per warning.
fn check_added(report: &Value, codes: &[&str]) {
    assert_eq!(report["factor_backend"], report["spd_backend"]);
    assert!(report["factor_backend"].is_string());
    let warnings = report["warnings"].as_array().unwrap();
    let got: Vec<&str> = report["warning_codes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_str().unwrap())
        .collect();
    assert_eq!(got.len(), warnings.len(), "{warnings:?}");
    assert_eq!(got, codes, "{warnings:?}");
}

#[test]
fn nullspace_report_is_unchanged_and_codes_its_conflict() {
    let new = report_of("all-kinds.json", &[]);
    assert_same(&expected("nullspace-qr"), &new, "", true);
    check_added(&new, &["conflicting-constraint"]);
}

#[test]
fn penalty_reports_are_unchanged_and_code_their_warnings() {
    let new = report_of(
        "all-kinds.json",
        &["--method", "penalty", "--weight", "1e4"],
    );
    assert_same(&expected("penalty"), &new, "", true);
    check_added(&new, &["penalty-approximate", "lost-accuracy-unrefined"]);
    // `--refine off` is still accepted, and written `off`.
    let new = report_of(
        "positions.json",
        &["--method", "penalty", "--weight", "1e6", "--refine", "off"],
    );
    assert_same(&expected("penalty-off"), &new, "", true);
    assert_eq!(new["refinement"]["mode"], "off");
    assert!(new["penalty_weight"].is_number() && new["penalty_weight_unit"].is_number());
    check_added(&new, &["penalty-approximate"]);
}

#[test]
fn kkt_and_elimination_reports_are_unchanged() {
    let new = report_of("positions.json", &["--method", "kkt"]);
    assert_same(&expected("kkt"), &new, "", true);
    assert_eq!(new["factor_backend"], "faer-ldlt-auto");
    assert!(new["kkt_multiplier_scale"].is_number());
    check_added(&new, &[]);
    let new = report_of("positions.json", &["--method", "eliminate"]);
    assert_same(&expected("eliminate"), &new, "", true);
    check_added(&new, &[]);
}

#[test]
fn arap_report_is_unchanged() {
    let new = report_of("all-kinds.json", &["--energy", "arap", "--iterations", "2"]);
    assert_same(&expected("arap"), &new, "", true);
    assert_eq!(new["laplacian"], "arap-spokes-and-rims");
    check_added(&new, &["conflicting-constraint"]);
}
