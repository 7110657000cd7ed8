//! Each rank's scratch directory for MUMPS's out-of-core factor
//! (`ICNTL(22) = 1`, `OOC_TMPDIR`), and what removes it.
//!
//! - **Names** are made like `mkdtemp`'s: `lse-deform-rankR-` and 16 random
//!   hex digits, created with `mkdir` (which fails rather than reuse an
//!   existing entry) and retried with a new suffix on `EEXIST`, so a
//!   directory left behind by a killed run (whatever its process id) is
//!   never the reason a later run fails.
//! - **Removal**: when dropped (also after an error), and on SIGINT, SIGTERM
//!   or SIGHUP by [`remove_all`], which the command-line tool's signal
//!   thread calls on every rank (each rank removes the directories it
//!   made): every live directory is registered here while it exists.
//! - **The directory given** is checked on every rank before any work
//!   ([`probe`]): a rank makes its scratch directory there and writes one
//!   block in it; a failure is the system's reason (read-only, no space,
//!   name too long, missing on that rank) naming the directory.
//! - **Free space**: out of core, each rank's share of the factor goes to
//!   disk; [`check_space`] compares MUMPS's estimate of it (`INFO(24)`
//!   entries of 8 bytes) with the space free for this process under the
//!   directory (`statvfs`'s `f_bavail`), before the factorisation.

use std::io::Write;
use std::os::unix::ffi::OsStrExt;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

/// The longest path MUMPS takes in `OOC_TMPDIR` (a `char[256]` with its
/// terminating zero).
pub(crate) const MAX_PATH_BYTES: usize = 255;

/// How many random names are tried before giving up on `EEXIST`.
const ATTEMPTS: usize = 100;

/// Every scratch directory of this process that exists.
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn live() -> MutexGuard<'static, Vec<PathBuf>> {
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// A rank's scratch directory, removed with everything in it when dropped.
#[derive(Debug)]
pub(crate) struct ScratchDir(PathBuf);

impl ScratchDir {
    /// Makes a new directory under `parent` for `rank`. The error names
    /// `parent` and gives the system's reason.
    pub(crate) fn create(parent: &Path, rank: i32) -> Result<ScratchDir, String> {
        let mut registry = live();
        for _ in 0..ATTEMPTS {
            let name = format!("lse-deform-rank{rank}-{:016x}", rand::random::<u64>());
            let path = parent.join(name);
            if path.as_os_str().len() > MAX_PATH_BYTES {
                return Err(format!(
                    "the out-of-core directory {} is too long: its scratch directory {} has {} bytes, more than MUMPS's {MAX_PATH_BYTES}",
                    parent.display(),
                    path.display(),
                    path.as_os_str().len()
                ));
            }
            match std::fs::create_dir(&path) {
                Ok(()) => {
                    registry.push(path.clone());
                    return Ok(ScratchDir(path));
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
                Err(e) => return Err(directory_error(parent, "cannot make a directory in it", &e)),
            }
        }
        Err(format!(
            "the out-of-core directory {}: {ATTEMPTS} random names were all taken",
            parent.display()
        ))
    }

    /// The path, as the bytes MUMPS reads (no terminating zero).
    pub fn bytes(&self) -> &[u8] {
        self.0.as_os_str().as_bytes()
    }

    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let mut registry = live();
        let _ = std::fs::remove_dir_all(&self.0);
        registry.retain(|p| p != &self.0);
    }
}

/// `the out-of-core directory DIR: WHAT: REASON`.
fn directory_error(dir: &Path, what: &str, e: &std::io::Error) -> String {
    format!("the out-of-core directory {}: {what}: {e}", dir.display())
}

/// Makes a scratch directory under `parent`, writes one block in it and
/// removes it: `Err` with the system's reason when this rank cannot keep a
/// factor there.
pub(crate) fn probe(parent: &Path, rank: i32) -> Result<(), String> {
    let dir = ScratchDir::create(parent, rank)?;
    let block = vec![0u8; 1 << 16];
    std::fs::File::create(dir.path().join("probe"))
        .and_then(|mut f| f.write_all(&block).and_then(|()| f.sync_all()))
        .map_err(|e| directory_error(parent, "cannot write a file in it", &e))
}

/// Bytes free for this process on the file system of `dir`.
pub(crate) fn free_bytes(dir: &Path) -> std::io::Result<u64> {
    let mut c_path = dir.as_os_str().as_bytes().to_vec();
    c_path.push(0);
    // SAFETY: statvfs is a plain C struct, for which zero is valid.
    let mut stat: libc::statvfs = unsafe { std::mem::zeroed() };
    // SAFETY: `c_path` is a NUL-terminated path; `stat` is a valid place
    // for the result.
    let rc = unsafe { libc::statvfs(c_path.as_ptr().cast(), &mut stat) };
    if rc != 0 {
        return Err(std::io::Error::last_os_error());
    }
    // The field types differ between platforms (u64 or c_ulong).
    #[allow(clippy::unnecessary_cast)]
    let free = (stat.f_bavail as u64).saturating_mul(stat.f_frsize as u64);
    Ok(free)
}

/// `Err` (the message names the directory and says "No space left on
/// device") when `needed` bytes of this rank's factor do not fit in the
/// space free under `dir`.
pub(crate) fn check_space(dir: &Path, needed: u64) -> Result<(), String> {
    let free =
        free_bytes(dir).map_err(|e| directory_error(dir, "cannot read its free space", &e))?;
    if needed <= free {
        return Ok(());
    }
    let enospc = std::io::Error::from_raw_os_error(libc::ENOSPC);
    Err(directory_error(
        dir,
        &format!(
            "MUMPS estimates this rank's share of the factor at {}, more than the {} free there",
            crate::limits::format_bytes(needed),
            crate::limits::format_bytes(free)
        ),
        &enospc,
    ))
}

/// Removes every scratch directory of this process, for a signal's
/// clean-up: MUMPS may still be writing in them, so each is removed until
/// it is gone (a file made meanwhile makes a removal fail with "directory
/// not empty"; once the directory itself is gone nothing can be made in
/// it). The registry stays locked: no directory is made after this.
pub fn remove_all() {
    let registry = live();
    for path in registry.iter() {
        for _ in 0..ATTEMPTS {
            if std::fs::remove_dir_all(path).is_ok() || !path.exists() {
                break;
            }
        }
    }
    std::mem::forget(registry);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_leftover_with_the_same_prefix_does_not_collide_and_drop_removes() {
        let parent = tempfile::tempdir().unwrap();
        let a = ScratchDir::create(parent.path(), 0).unwrap();
        let b = ScratchDir::create(parent.path(), 0).unwrap();
        assert_ne!(a.path(), b.path());
        std::fs::write(a.path().join("x"), b"x").unwrap();
        let (pa, pb) = (a.path().to_path_buf(), b.path().to_path_buf());
        drop(a);
        drop(b);
        assert!(!pa.exists() && !pb.exists());
    }

    #[test]
    fn a_path_over_255_bytes_is_refused_naming_the_directory() {
        let parent = PathBuf::from(format!("/tmp/{}", "d".repeat(250)));
        let e = ScratchDir::create(&parent, 0).unwrap_err();
        assert!(
            e.contains(&parent.display().to_string()) && e.contains("255"),
            "{e}"
        );
    }

    #[test]
    fn too_little_space_is_no_space_left_on_device() {
        let parent = tempfile::tempdir().unwrap();
        let e = check_space(parent.path(), u64::MAX).unwrap_err();
        assert!(e.contains("No space left on device"), "{e}");
        assert!(check_space(parent.path(), 0).is_ok());
    }
}
