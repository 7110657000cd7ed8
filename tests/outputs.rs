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
    let m =
        lse_deform::mesh::read_mesh(Path::new(&out), lse_deform::limits::MemoryBudget::default())
            .unwrap()
            .mesh;
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

/// FIFOs as outputs, and interrupted runs (Unix).
#[cfg(unix)]
mod pipes {
    use std::fs::{File, OpenOptions};
    use std::io::Read;
    use std::os::fd::AsRawFd;
    use std::os::unix::ffi::OsStrExt;
    use std::os::unix::fs::OpenOptionsExt;
    use std::path::Path;
    use std::process::{Child, Command, ExitStatus, Stdio};
    use std::time::{Duration, Instant};

    use super::{bin, grid_and_scene, names, p, run, stderr};

    /// How long a test waits for the binary or a pipe before it fails: a
    /// guard against a hang, not a measurement.
    const GUARD: Duration = Duration::from_secs(60);

    fn mkfifo(path: &str) {
        let c = std::ffi::CString::new(Path::new(path).as_os_str().as_bytes()).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    }

    /// The read end of the FIFO `path`, opened without waiting for a
    /// writer (it counts as a reader from now on).
    fn reader(path: &str) -> File {
        OpenOptions::new()
            .read(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(path)
            .unwrap()
    }

    /// Everything written to `file` until its writer closes it: what a
    /// reader that reads once gets. Panics after [`GUARD`] without data.
    fn read_to_end(mut file: File) -> Vec<u8> {
        let mut out = Vec::new();
        let mut buf = vec![0u8; 1 << 16];
        loop {
            let mut fd = libc::pollfd {
                fd: file.as_raw_fd(),
                events: libc::POLLIN,
                revents: 0,
            };
            // SAFETY: one valid pollfd.
            let ready = unsafe { libc::poll(&mut fd, 1, GUARD.as_millis() as libc::c_int) };
            assert!(ready > 0, "nothing came through the FIFO");
            match file.read(&mut buf) {
                Ok(0) => return out,
                Ok(n) => out.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                Err(e) => panic!("{e}"),
            }
        }
    }

    /// Waits for `child` at most [`GUARD`]; kills it and fails after.
    fn wait(mut child: Child) -> (ExitStatus, String) {
        let start = Instant::now();
        loop {
            if let Some(status) = child.try_wait().unwrap() {
                let mut err = String::new();
                child
                    .stderr
                    .take()
                    .unwrap()
                    .read_to_string(&mut err)
                    .unwrap();
                return (status, err);
            }
            if start.elapsed() > GUARD {
                child.kill().unwrap();
                panic!("the binary hung");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn spawn(args: &[&str]) -> Child {
        Command::new(bin())
            .args(args)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    }

    /// A FIFO as `-o` with a reader that reads once gets the whole mesh,
    /// the same bytes as a file gets. (Before: the check before the work
    /// opened and closed the FIFO, the reader got an empty input, and the
    /// real write then waited for a reader forever.)
    #[test]
    fn a_fifo_with_a_reader_receives_the_whole_mesh() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let (mesh, scene) = grid_and_scene(d);
        let file = p(d, "file.obj");
        let o = run(&["deform", &mesh, "-c", &scene, "-o", &file]);
        assert!(o.status.success(), "{}", stderr(&o));
        let fifo = p(d, "fifo.obj");
        mkfifo(&fifo);
        let read = reader(&fifo);
        let got = std::thread::spawn(move || read_to_end(read));
        let report = p(d, "r.json");
        let child = spawn(&[
            "deform", &mesh, "-c", &scene, "-o", &fifo, "--report", &report,
        ]);
        let (status, err) = wait(child);
        assert!(status.success(), "{err}");
        assert_eq!(got.join().unwrap(), std::fs::read(&file).unwrap());
        assert!(Path::new(&report).exists());
    }

    /// An input FIFO (the mesh, `-c`, `--ordering-file`) that no process
    /// writes is refused once `lse_deform::input::FIFO_WRITER_WAIT` has
    /// passed, exit 2 naming it; a mesh and constraints file whose writers
    /// come are read as the files are, the same output byte for byte.
    /// (Before: the run blocked in `open` forever.)
    #[test]
    fn an_input_fifo_is_read_when_written_and_refused_when_not() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let (mesh, scene) = grid_and_scene(d);
        let (in_mesh, in_scene, in_order) = (p(d, "in.obj"), p(d, "in.json"), p(d, "order.txt"));
        for fifo in [&in_mesh, &in_scene, &in_order] {
            mkfifo(fifo);
        }
        let out = p(d, "out.obj");
        let unwritten: [&[&str]; 3] = [
            &["deform", &in_mesh, "-c", &scene, "-o", &out],
            &["deform", &mesh, "-c", &in_scene, "-o", &out],
            &[
                "deform",
                &mesh,
                "-c",
                &scene,
                "-o",
                &out,
                "--ordering-file",
                &in_order,
            ],
        ];
        for (args, name) in unwritten.iter().zip(["in.obj", "in.json", "order.txt"]) {
            let (status, err) = wait(spawn(args));
            assert_eq!(status.code(), Some(2), "{name}: {err}");
            assert!(
                err.contains(name) && err.contains("no process wrote to within 5 s"),
                "{name}: {err}"
            );
            assert!(!Path::new(&out).exists(), "{name}");
        }
        let reference = p(d, "reference.obj");
        let o = run(&["deform", &mesh, "-c", &scene, "-o", &reference]);
        assert!(o.status.success(), "{}", stderr(&o));
        let writers: Vec<_> = [
            (in_mesh.clone(), mesh.clone()),
            (in_scene.clone(), scene.clone()),
        ]
        .into_iter()
        .map(|(fifo, file)| {
            std::thread::spawn(move || {
                let bytes = std::fs::read(file).unwrap();
                std::thread::sleep(Duration::from_millis(200));
                let mut w = OpenOptions::new().write(true).open(fifo).unwrap();
                std::io::Write::write_all(&mut w, &bytes).unwrap();
            })
        })
        .collect();
        let (status, err) = wait(spawn(&["deform", &in_mesh, "-c", &in_scene, "-o", &out]));
        for w in writers {
            w.join().unwrap();
        }
        assert!(status.success(), "{err}");
        assert_eq!(
            std::fs::read(&out).unwrap(),
            std::fs::read(&reference).unwrap()
        );
    }

    /// A FIFO as `-o` or `--report` that no process reads is refused
    /// before any work (exit 2, before the missing mesh is even looked
    /// at), naming the FIFO. (Before: the run waited for a reader forever.)
    #[test]
    fn a_fifo_without_a_reader_is_refused_before_any_work() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let fifo = p(d, "fifo.obj");
        mkfifo(&fifo);
        let (missing, scene, out) = (p(d, "missing.obj"), p(d, "c.json"), p(d, "out.obj"));
        for outputs in [
            ["-o", &fifo, "--report", "/dev/null"],
            ["-o", &out, "--report", &fifo],
        ] {
            let mut args = vec!["deform", &missing, "-c", &scene];
            args.extend(outputs);
            let (status, err) = wait(spawn(&args));
            assert_eq!(status.code(), Some(2), "{err}");
            assert!(
                err.contains("fifo.obj") && err.contains("no process is reading"),
                "{err}"
            );
            assert_eq!(names(d), ["fifo.obj"]);
        }
    }

    /// A FIFO `path` with a reader that does not read and a full buffer:
    /// a write to it waits. Returns both ends (drop them to release it).
    fn full_fifo(path: &str) -> (File, File) {
        use std::io::Write;
        let read = reader(path);
        let mut write = OpenOptions::new()
            .write(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(path)
            .unwrap();
        let filler = [b' '; 4096];
        loop {
            match write.write(&filler) {
                Ok(_) => {}
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return (read, write),
                Err(e) => panic!("{e}"),
            }
        }
    }

    /// SIGINT or SIGTERM while the report is being written to a FIFO
    /// that does not take it (its buffer full, its reader not reading: the
    /// run waits with its mesh staged) ends the run by the signal and
    /// leaves no temporary file. (Before: the staged mesh
    /// `.out.obj.PID.N.tmp` stayed.)
    #[test]
    fn an_interrupted_run_leaves_no_temporary_file() {
        use std::os::unix::process::ExitStatusExt;
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let (mesh, scene) = grid_and_scene(d);
        let fifo = p(d, "fifo.json");
        mkfifo(&fifo);
        let out = p(d, "out.obj");
        for signal in [libc::SIGINT, libc::SIGTERM] {
            let ends = full_fifo(&fifo);
            let child = spawn(&["deform", &mesh, "-c", &scene, "-o", &out, "--report", &fifo]);
            let start = Instant::now();
            while !names(d).iter().any(|n| n.ends_with(".tmp")) {
                assert!(start.elapsed() < GUARD, "no staged mesh appeared");
                std::thread::sleep(Duration::from_millis(10));
            }
            // SAFETY: a signal to our own child.
            unsafe { libc::kill(child.id() as libc::pid_t, signal) };
            let (status, err) = wait(child);
            assert_eq!(status.signal(), Some(signal), "{err}");
            assert_eq!(
                names(d),
                ["fifo.json", "grid.obj", "scene.json"],
                "signal {signal}"
            );
            drop(ends);
        }
    }

    /// An output name of 255 bytes (251 and `.obj`) is written. (Before:
    /// it passed the check before the work and failed after it with "File
    /// name too long", for the longer temporary name.)
    #[test]
    fn a_name_of_255_bytes_is_written() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let (mesh, scene) = grid_and_scene(d);
        let long = format!("{}.obj", "x".repeat(251));
        let out = p(d, &long);
        let o = run(&[
            "deform",
            &mesh,
            "-c",
            &scene,
            "-o",
            &out,
            "--report",
            &p(d, "r.json"),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        assert_eq!(
            names(d),
            ["grid.obj", "r.json", "scene.json", long.as_str()]
        );
    }
}
