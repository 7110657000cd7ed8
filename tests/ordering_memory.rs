//! The ordering-file reader holds no more than the budget admits.
//!
//! Alone in its test binary: a child's `ru_maxrss` includes what its parent
//! held when it was forked, so the test process must stay small (no other
//! test beside it, the ordering files written in pieces).

use std::ffi::OsStr;
use std::io::{Read, Write};
use std::process::{Command, Stdio};

use lse_deform::constraints::{Constraint, ConstraintSet};
use lse_deform::mesh::{generate, write_mesh};

/// Runs `lse-deform ARGS` and returns its exit code, the most memory it
/// held (`ru_maxrss` of `wait4`, in bytes) and its error output.
#[allow(clippy::zombie_processes)] // waited for by `wait4`, which gives the peak
fn exit_and_peak(args: &[&OsStr]) -> (Option<i32>, u64, String) {
    let child = Command::new(env!("CARGO_BIN_EXE_lse-deform"))
        .args(args)
        .env_remove("LSE_MEMORY_LIMIT")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let pid = child.id() as libc::pid_t;
    let mut stderr = String::new();
    child.stderr.unwrap().read_to_string(&mut stderr).unwrap();
    let mut status = 0;
    // SAFETY: `rusage` is a plain C struct for which zero is valid; `pid`
    // is this test's own child, not yet waited for.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let waited = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    assert_eq!(waited, pid);
    let code = libc::WIFEXITED(status).then(|| libc::WEXITSTATUS(status));
    (code, usage.ru_maxrss as u64 * 1024, stderr)
}

/// Found in the latest round of faults: the ordering-file reader admitted
/// 5 bytes of memory per byte of file but held about 17 (a list of every
/// word with its line, 24 bytes a word, and the indices twice): a 40 MB
/// file under a 240 MiB budget peaked at 660 MiB, and 10⁸ entries under
/// 1 GiB at 3.2 GiB. Now the words are counted, then parsed into one
/// allocation: a 20 MB file (10⁷ entries) under 120 MiB stays within it
/// (it is then refused for its length, exit 2), and a 50 MB file under
/// 240 MiB is refused from its size before it is read.
#[test]
fn an_ordering_file_is_read_within_the_budget_or_refused_before() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene) = (dir.path().join("g.obj"), dir.path().join("s.json"));
    write_mesh(&generate::grid(10, 10).unwrap(), &mesh).unwrap();
    let set = ConstraintSet::from_vec(vec![Constraint::position(0, [0.0; 3])]);
    std::fs::write(&scene, set.unwrap().to_json()).unwrap();
    let deform_with = |name: &str, entries: usize, limit: &str| {
        let order = dir.path().join(name);
        let mut file = std::io::BufWriter::new(std::fs::File::create(&order).unwrap());
        for _ in 0..entries {
            file.write_all(b"0 ").unwrap();
        }
        file.flush().unwrap();
        drop(file);
        let out = dir.path().join("o.obj");
        let mut args: Vec<&OsStr> = vec![OsStr::new("deform"), mesh.as_os_str(), OsStr::new("-c")];
        args.extend([scene.as_os_str(), OsStr::new("-o"), out.as_os_str()]);
        args.extend([OsStr::new("--ordering-file"), order.as_os_str()]);
        args.extend([OsStr::new("--memory-limit"), OsStr::new(limit)]);
        exit_and_peak(&args)
    };
    let (code, peak, stderr) = deform_with("read.txt", 10_000_000, "120M");
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("10000000 entries"), "{stderr}");
    assert!(peak <= 120 << 20, "peak {} MiB: {stderr}", peak >> 20);
    let (code, peak, stderr) = deform_with("refused.txt", 25_000_000, "240M");
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("would need") && stderr.contains("240.0 MiB"),
        "{stderr}"
    );
    assert!(peak <= 64 << 20, "peak {} MiB: {stderr}", peak >> 20);
}
