//! Every file the binary writes appears whole or not at all, and `solve`
//! checks its outputs before any work, as `deform` does. Outputs never
//! replace inputs nor each other, and the outputs of one run are replaced
//! together or not at all.
//!
//! A full disk is made real without root or a mount: the binary runs under
//! a file size limit (`ulimit -f`, with `SIGXFSZ` ignored), so its writes
//! past the limit fail with `EFBIG` just as they fail with `ENOSPC` on a
//! full device.

use std::path::Path;
use std::process::{Command, Output};

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_lse-deform")
}

fn run(args: &[&str]) -> Output {
    Command::new(bin())
        .args(args)
        .output()
        .expect("the binary runs")
}

/// Runs the binary with writes limited to a few KiB per file.
#[cfg(unix)]
fn run_on_a_full_disk(args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg(r#"trap "" XFSZ; ulimit -f 4 && exec "$0" "$@""#)
        .arg(bin())
        .args(args)
        .output()
        .expect("sh runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn p(dir: &Path, name: &str) -> String {
    dir.join(name).to_string_lossy().into_owned()
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A 900-vertex grid and its fixed-and-handle scene in `dir`.
fn grid_and_scene(dir: &Path) -> (String, String) {
    let mesh = p(dir, "grid.obj");
    let o = run(&["generate", "grid", "--vertices", "900", "-o", &mesh]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = p(dir, "scene.json");
    let o = run(&["scene", &mesh, "-o", &scene]);
    assert!(o.status.success(), "{}", stderr(&o));
    (mesh, scene)
}

/// `deform -o` on a full disk: the error is reported (exit 2, naming the
/// file) and the previous good mesh is left whole, with no temporary file
/// beside it.
#[cfg(unix)]
#[test]
fn a_full_disk_keeps_the_previous_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let out = p(dir.path(), "out.obj");
    let o = run(&["deform", &mesh, "-c", &scene, "-o", &out]);
    assert!(o.status.success(), "{}", stderr(&o));
    let good = std::fs::read(&out).unwrap();
    assert!(good.len() > 16 << 10, "larger than the limit");
    let o = run_on_a_full_disk(&["deform", &mesh, "-c", &scene, "-o", &out]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("out.obj"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        std::fs::read(&out).unwrap() == good,
        "the old mesh is intact"
    );
    assert_eq!(names(dir.path()), ["grid.obj", "out.obj", "scene.json"]);
}

/// The same for every other writer: `solve`'s `X.mtx`, a `--report`, a
/// generated mesh, a scene and `export-system`'s files.
#[cfg(unix)]
#[test]
fn a_full_disk_keeps_every_previous_output() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let sys = p(dir.path(), "sys");
    let o = run(&["export-system", &mesh, "-c", &scene, "-o", &sys]);
    assert!(o.status.success(), "{}", stderr(&o));
    let x = p(dir.path(), "X.mtx");
    let report = p(dir.path(), "report.json");
    let solve = ["solve", &sys, "-o", &x, "--report", &report];
    let o = run(&solve);
    assert!(o.status.success(), "{}", stderr(&o));
    let big = p(dir.path(), "big.obj");
    let generate = ["generate", "grid", "--vertices", "900", "-o", &big];
    assert!(run(&generate).status.success());
    let contents = |paths: &[&str]| -> Vec<Vec<u8>> {
        paths.iter().map(|f| std::fs::read(f).unwrap()).collect()
    };
    let a_mtx = p(dir.path(), "sys/A.mtx");
    let files = [x.as_str(), &report, &big, &scene, &a_mtx];
    let kept = contents(&files);
    let listing = names(dir.path());
    let sys_listing = names(Path::new(&sys));
    // X.mtx alone is over the limit: 900 × 3 numbers.
    let o = run_on_a_full_disk(&solve);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("X.mtx"), "{}", stderr(&o));
    assert!(run_on_a_full_disk(&generate).status.code() == Some(2));
    let o = run_on_a_full_disk(&["export-system", &mesh, "-c", &scene, "-o", &sys]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("A.mtx"), "{}", stderr(&o));
    let now = contents(&files);
    for (k, f) in files.iter().enumerate() {
        assert!(now[k] == kept[k], "{f} changed");
    }
    assert_eq!(names(dir.path()), listing, "no temporary file left");
    assert_eq!(names(Path::new(&sys)), sys_listing);
}

/// `solve --report missing-dir/r.json` fails before any work: no `X.mtx`
/// is written, and with a missing input too it is the output that is
/// reported (the inputs were not read).
#[test]
fn solve_checks_its_outputs_before_working() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let sys = p(dir.path(), "sys");
    let o = run(&["export-system", &mesh, "-c", &scene, "-o", &sys]);
    assert!(o.status.success(), "{}", stderr(&o));
    let x = p(dir.path(), "X.mtx");
    let report = p(dir.path(), "missing-dir/r.json");
    let o = run(&["solve", &sys, "-o", &x, "--report", &report]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("missing-dir/r.json"), "{err}");
    assert!(
        !Path::new(&x).exists(),
        "X.mtx was written before the check"
    );
    let o = run(&[
        "solve",
        &p(dir.path(), "no-such-system"),
        "-o",
        &p(dir.path(), "missing-dir/X.mtx"),
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("missing-dir/X.mtx") && !err.contains("no-such-system"),
        "{err}"
    );
    assert_eq!(names(dir.path()), ["grid.obj", "scene.json", "sys"]);
}

/// Successful writes leave exactly the files asked for.
#[test]
fn writes_leave_no_temporary_files() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = grid_and_scene(dir.path());
    let out = p(dir.path(), "out.ply.gz");
    let report = p(dir.path(), "r.json");
    for _ in 0..2 {
        let o = run(&[
            "deform", &mesh, "-c", &scene, "-o", &out, "--report", &report,
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let m = lse_deform::mesh::read_mesh(Path::new(&out)).unwrap().mesh;
    assert_eq!(m.n_vertices(), 900);
    assert_eq!(
        names(dir.path()),
        ["grid.obj", "out.ply.gz", "r.json", "scene.json"]
    );
}

/// Runs the binary and checks it refused before any work: exit code 2, a
/// message naming `words`, and the files of `dir` unchanged (no output
/// created, no input replaced).
fn refused(dir: &Path, args: &[&str], words: &[&str]) {
    let before = contents(dir);
    let o = run(args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    for w in words {
        assert!(err.contains(w), "{args:?}: no {w:?} in {err}");
    }
    assert!(
        contents(dir) == before,
        "{args:?} changed the files of {dir:?}"
    );
}

/// The names and bytes of the files in `dir` (a directory's bytes empty).
fn contents(dir: &Path) -> Vec<(String, Vec<u8>)> {
    names(dir)
        .into_iter()
        .map(|n| {
            let bytes = std::fs::read(dir.join(&n)).unwrap_or_default();
            (n, bytes)
        })
        .collect()
}

/// `grid_and_scene` and its `export-system` in `dir/sys`.
fn grid_scene_and_export(dir: &Path) -> (String, String, String) {
    let (mesh, scene) = grid_and_scene(dir);
    let sys = p(dir, "sys");
    let o = run(&["export-system", &mesh, "-c", &scene, "-o", &sys]);
    assert!(o.status.success(), "{}", stderr(&o));
    (mesh, scene, sys)
}

/// Every output that is an input, or another output, is refused with exit
/// code 2 before any work, naming both roles; by any name of the file (a
/// symbolic link, a hard link, `.` in the path). Devices are no collision:
/// `/dev/null` may take two outputs. (Before: each of these ran with exit
/// code 0 and replaced the input or the other output.)
#[cfg(unix)]
#[test]
fn outputs_never_replace_inputs_or_each_other() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (mesh, scene, sys) = grid_scene_and_export(d);
    let out = p(d, "out.obj");
    let same = p(d, "same.obj");
    let link = p(d, "link.json");
    std::os::unix::fs::symlink("scene.json", &link).unwrap();
    let hard = p(d, "hard.obj");
    std::fs::hard_link(&mesh, &hard).unwrap();
    let dotted = d
        .join(".")
        .join("scene.json")
        .to_string_lossy()
        .into_owned();
    let deform = |extra: &[&str]| -> Vec<String> {
        let mut v: Vec<String> = ["deform", &mesh, "-c", &scene].map(String::from).to_vec();
        v.extend(extra.iter().map(|s| s.to_string()));
        v
    };
    let cases: Vec<(Vec<String>, Vec<&str>)> = vec![
        (
            deform(&["-o", &out, "--report", &scene]),
            vec!["--report", "is the constraints file given with -c"],
        ),
        (
            deform(&["-o", &out, "--report", &mesh]),
            vec!["--report", "is the input mesh"],
        ),
        (
            deform(&["-o", &same, "--report", &same]),
            vec!["--report", "is also the output of -o"],
        ),
        (deform(&["-o", &mesh]), vec!["-o", "is the input mesh"]),
        (
            deform(&["-o", &hard]),
            vec!["hard.obj", "grid.obj, the input mesh"],
        ),
        (
            deform(&["-o", &out, "--report", &link]),
            vec!["link.json", "scene.json", "the constraints file"],
        ),
        (
            deform(&["-o", &out, "--report", &dotted]),
            vec!["the constraints file"],
        ),
        (
            ["scene", &mesh, "-o", &mesh].map(String::from).to_vec(),
            vec!["-o", "is the input mesh"],
        ),
        (
            ["solve", &sys, "-o", &p(d, "sys/A.mtx")]
                .map(String::from)
                .to_vec(),
            vec!["-o", "is the matrix A"],
        ),
        (
            [
                "solve",
                &sys,
                "-o",
                &out,
                "--report",
                &p(d, "sys/meta.json"),
            ]
            .map(String::from)
            .to_vec(),
            vec!["--report", "meta.json"],
        ),
        (
            ["compare", &mesh, "-c", &scene, "--json", &scene]
                .map(String::from)
                .to_vec(),
            vec!["--json", "the constraints file"],
        ),
        (
            ["render", &mesh, &out, "-o", &mesh]
                .map(String::from)
                .to_vec(),
            vec!["-o", "is the input mesh"],
        ),
        (
            ["export-system", &mesh, "-c", &p(d, "sys/B.mtx"), "-o", &sys]
                .map(String::from)
                .to_vec(),
            vec!["B.mtx", "the constraints file"],
        ),
    ];
    let sys_files = contents(Path::new(&sys));
    for (args, words) in &cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        refused(d, &args, words);
    }
    assert!(contents(Path::new(&sys)) == sys_files, "the export changed");
    // Devices take any number of outputs.
    let o = run(&["solve", &sys, "-o", "/dev/null", "--report", "/dev/null"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A report that cannot be written (`/dev/full`) fails the run (exit 2)
/// and leaves no `-o`: none is created, and an existing one is unchanged;
/// for `deform` (Laplacian and ARAP) and `solve`. (Before: exit 2, but the
/// output had already been written.)
#[cfg(target_os = "linux")]
#[test]
fn a_failed_report_leaves_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (mesh, scene, sys) = grid_scene_and_export(d);
    let out = p(d, "out.obj");
    let x = p(d, "X.mtx");
    let runs: [Vec<&str>; 3] = [
        vec!["deform", &mesh, "-c", &scene, "-o", &out],
        vec![
            "deform",
            &mesh,
            "-c",
            &scene,
            "-o",
            &out,
            "--energy",
            "arap",
            "--iterations",
            "1",
        ],
        vec!["solve", &sys, "-o", &x],
    ];
    for args in &runs {
        let output = args[args.iter().position(|&a| a == "-o").unwrap() + 1];
        let full = [args.as_slice(), &["--report", "/dev/full"]].concat();
        let o = run(&full);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("/dev/full"), "{err}");
        assert!(!Path::new(output).exists(), "{args:?} wrote {output}");
        // An earlier output stays as it was.
        std::fs::write(output, "the previous output").unwrap();
        let o = run(&full);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert_eq!(
            std::fs::read_to_string(output).unwrap(),
            "the previous output"
        );
        std::fs::remove_file(output).unwrap();
        assert_eq!(names(d), ["grid.obj", "scene.json", "sys"], "{args:?}");
    }
}
