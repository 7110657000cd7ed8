//! Outputs never replace inputs, nor each other: every output path of a
//! command is compared with every input and every other output before any
//! work, and a collision is refused (exit code 2) naming both roles.
//!
//! Two paths are the same file when they name the same regular file after
//! symbolic links are followed (by device and inode on Unix, so hard
//! links and `/dev/stdout` redirected to a file count), or, for a file that
//! does not exist yet, when they resolve to the same name in the same
//! (canonical) directory. A path that exists and is not a regular file —
//! a character device such as `/dev/null`, `/dev/stdout` on a terminal, a
//! FIFO — never collides: writing to it replaces no file, so two outputs
//! may both be `/dev/null` and a report may go to `/dev/stdout`. (A
//! directory as an output fails later with the system's message.)

use std::path::{Path, PathBuf};

use lse_deform::Error;
use lse_deform::error::ProblemError;

/// What identifies the file a path names, or would create.
#[derive(PartialEq, Eq)]
enum Identity {
    /// An existing regular file: device and inode (Unix), else its
    /// canonical path.
    #[cfg(unix)]
    Inode(u64, u64),
    /// A file that does not exist yet (or, off Unix, an existing one): its
    /// canonical directory and name.
    Path(PathBuf),
}

/// The identity of `path`; `None` for a device, FIFO or directory (they
/// never collide) and for a path whose directory does not exist (the
/// writability checks report it).
fn identity(path: &Path) -> Option<Identity> {
    match std::fs::metadata(path) {
        Ok(m) if !m.is_file() => None,
        #[cfg(unix)]
        Ok(m) => {
            use std::os::unix::fs::MetadataExt;
            Some(Identity::Inode(m.dev(), m.ino()))
        }
        #[cfg(not(unix))]
        Ok(_) => std::fs::canonicalize(path).ok().map(Identity::Path),
        Err(_) => {
            let target = lse_deform::atomic::resolve(path);
            let name = target.file_name()?;
            let dir = match target.parent() {
                Some(d) if !d.as_os_str().is_empty() => d,
                _ => Path::new("."),
            };
            let dir = std::fs::canonicalize(dir).ok()?;
            Some(Identity::Path(dir.join(name)))
        }
    }
}

/// One file of a command: how the messages name its role (an input's
/// description, an output's flag) and its path.
pub type Role<'a> = (&'a str, &'a Path);

/// The inputs of the commands that read a mesh and a constraints file.
pub(crate) fn mesh_and_constraints<'a>(mesh: &'a Path, constraints: &'a Path) -> [Role<'a>; 2] {
    [
        ("the input mesh", mesh),
        ("the constraints file given with -c", constraints),
    ]
}

/// Refuses (a [`ProblemError::InvalidArgument`], exit code 2) an output
/// that is one of the `inputs` or an earlier output. Inputs are described
/// ("the constraints file given with -c"), outputs named by their flag
/// ("--report"): "--report c.json is the constraints file given with -c".
pub(crate) fn check_distinct(inputs: &[Role<'_>], outputs: &[Role<'_>]) -> Result<(), Error> {
    let ins: Vec<_> = inputs.iter().map(|&(_, p)| identity(p)).collect();
    let outs: Vec<_> = outputs.iter().map(|&(_, p)| identity(p)).collect();
    for (k, &(flag, path)) in outputs.iter().enumerate() {
        let Some(id) = &outs[k] else { continue };
        let same = |other: &Option<Identity>| other.as_ref() == Some(id);
        if let Some(i) = ins.iter().position(same) {
            let (what, input) = inputs[i];
            return Err(refuse(
                flag,
                path,
                input,
                what,
                "outputs never replace inputs",
            ));
        }
        if let Some(j) = outs[..k].iter().position(same) {
            let (other, earlier) = outputs[j];
            let what = format!("also the output of {other}");
            return Err(refuse(
                flag,
                path,
                earlier,
                &what,
                "give each output its own file",
            ));
        }
    }
    Ok(())
}

/// "FLAG PATH is [OTHER, ]WHAT: ADVICE".
fn refuse(flag: &str, path: &Path, other: &Path, what: &str, advice: &str) -> Error {
    let alias = if other == path {
        String::new()
    } else {
        format!("{}, ", other.display())
    };
    ProblemError::InvalidArgument {
        message: format!("{flag} {} is {alias}{what}: {advice}", path.display()),
    }
    .into()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_file_by_another_name_is_refused_and_devices_are_not() {
        let dir = tempfile::tempdir().unwrap();
        let c = dir.path().join("c.json");
        std::fs::write(&c, "[]").unwrap();
        let dotted = dir.path().join(".").join("c.json");
        let e = check_distinct(
            &[("the constraints file", c.as_path())],
            &[("--report", dotted.as_path())],
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("is ") && e.contains("the constraints file"),
            "{e}"
        );
        let fresh = dir.path().join("new.obj");
        let e = check_distinct(
            &[],
            &[("-o", fresh.as_path()), ("--report", fresh.as_path())],
        )
        .unwrap_err();
        assert!(e.to_string().contains("also the output of -o"), "{e}");
        let null = Path::new("/dev/null");
        #[cfg(unix)]
        check_distinct(
            &[("the input mesh", null)],
            &[("-o", null), ("--report", null)],
        )
        .unwrap();
    }
}
