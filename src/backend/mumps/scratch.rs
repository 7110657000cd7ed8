//! Each rank's scratch directory for MUMPS's out-of-core factor
//! (`ICNTL(22) = 1`, `OOC_TMPDIR`), and what removes it.
//!
//! - **Names** are made like `mkdtemp`'s: `lse-deform-rankR-` and 16 hex
//!   digits, created with `mkdir` (which fails rather than reuse an
//!   existing entry) and retried with a new suffix on `EEXIST`, so a
//!   directory left behind by a killed run (whatever its process id) is
//!   never the reason a later run fails. The first 8 digits are the job's,
//!   drawn by rank 0 for all ranks ([`Job`]): they tell a rank which
//!   directories are its siblings'; the last 8 are random.
//! - **Removal**: when dropped (also after an error), and on SIGINT, SIGTERM
//!   or SIGHUP by [`remove_all`], which the command-line tool's signal
//!   thread calls on every rank (each rank removes the directories it
//!   made): every live directory is registered here while it exists. On
//!   two or more ranks, [`remove_all`] then waits until the siblings'
//!   directories are gone too (at most [`SIBLING_WAIT`]): Open MPI's
//!   `mpirun` kills every rank as soon as one has ended, so a rank that
//!   ended as soon as its own directory was gone would have the others
//!   killed while they remove theirs.
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
use std::time::{Duration, Instant};

/// The longest path MUMPS takes in `OOC_TMPDIR` (a `char[256]` with its
/// terminating zero).
pub(crate) const MAX_PATH_BYTES: usize = 255;

/// How many random names are tried before giving up on `EEXIST`.
const ATTEMPTS: usize = 100;

/// How long [`remove_all`] waits for the other ranks' directories to be
/// gone. Open MPI's `mpirun`, told to end a job, sends SIGCONT, a second
/// later SIGTERM, and SIGKILL once a rank has ended or another second has
/// passed (`odls_base_sigkill_timeout`, 1 s): 3 s is beyond both, so the
/// wait is ended by the siblings or by `mpirun`, and a sibling that was
/// not sent the signal (one rank killed alone) delays the end by 3 s at
/// most.
pub(crate) const SIBLING_WAIT: Duration = Duration::from_secs(3);

/// How often [`remove_all`] looks for the siblings' directories.
const SIBLING_POLL: Duration = Duration::from_millis(2);

/// The ranks that make their scratch directories together, and this
/// rank's place among them.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Job {
    /// Drawn by rank 0, the same on every rank: the first 8 hex digits of
    /// every directory name of the job.
    pub token: u32,
    pub rank: i32,
    pub ranks: i32,
}

impl Job {
    /// A process alone (no other rank, nothing to wait for).
    #[cfg(test)]
    fn alone() -> Job {
        Job {
            token: rand::random(),
            rank: 0,
            ranks: 1,
        }
    }

    /// `lse-deform-rankR-JOB` and 8 random hex digits.
    fn directory_name(&self) -> String {
        format!(
            "lse-deform-rank{}-{:08x}{:08x}",
            self.rank,
            self.token,
            rand::random::<u32>()
        )
    }

    /// Whether `name` is a directory name of this job (of any rank).
    fn names(&self, name: &[u8]) -> bool {
        let Some(rest) = name.strip_prefix(b"lse-deform-rank") else {
            return false;
        };
        let Some(dash) = rest.iter().position(|&b| b == b'-') else {
            return false;
        };
        let digits = &rest[dash + 1..];
        rest[..dash].iter().all(u8::is_ascii_digit)
            && digits.len() == 16
            && digits.starts_with(format!("{:08x}", self.token).as_bytes())
    }
}

/// A scratch directory that exists, the directory it is in and its job.
struct Live {
    path: PathBuf,
    parent: PathBuf,
    job: Job,
}

/// Every scratch directory of this process that exists.
static LIVE: Mutex<Vec<Live>> = Mutex::new(Vec::new());

fn live() -> MutexGuard<'static, Vec<Live>> {
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// A rank's scratch directory, removed with everything in it when dropped.
#[derive(Debug)]
pub(crate) struct ScratchDir(PathBuf);

impl ScratchDir {
    /// Makes a new directory under `parent` for `job`'s rank. The error
    /// names `parent` and gives the system's reason.
    pub(crate) fn create(parent: &Path, job: Job) -> Result<ScratchDir, String> {
        let mut registry = live();
        for _ in 0..ATTEMPTS {
            let name = job.directory_name();
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
                    registry.push(Live {
                        path: path.clone(),
                        parent: parent.to_path_buf(),
                        job,
                    });
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
        registry.retain(|live| live.path != self.0);
    }
}

/// `the out-of-core directory DIR: WHAT: REASON`.
fn directory_error(dir: &Path, what: &str, e: &std::io::Error) -> String {
    format!("the out-of-core directory {}: {what}: {e}", dir.display())
}

/// Makes a scratch directory under `parent`, writes one block in it and
/// removes it: `Err` with the system's reason when this rank cannot keep a
/// factor there.
pub(crate) fn probe(parent: &Path, job: Job) -> Result<(), String> {
    let dir = ScratchDir::create(parent, job)?;
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
/// it). Then, for a job of two or more ranks, waits until no directory of
/// the job is left beside them (see [`SIBLING_WAIT`]). The registry stays
/// locked: no directory is made after this.
pub fn remove_all() {
    let registry = live();
    for live in registry.iter() {
        for _ in 0..ATTEMPTS {
            if std::fs::remove_dir_all(&live.path).is_ok() || !live.path.exists() {
                break;
            }
        }
    }
    let deadline = Instant::now() + SIBLING_WAIT;
    for live in registry.iter().filter(|live| live.job.ranks > 1) {
        while Instant::now() < deadline && holds_job(&live.parent, &live.job) {
            std::thread::sleep(SIBLING_POLL);
        }
    }
    std::mem::forget(registry);
}

/// Whether `parent` holds a directory of `job` (an unreadable `parent`
/// holds none that can be waited for).
fn holds_job(parent: &Path, job: &Job) -> bool {
    std::fs::read_dir(parent).is_ok_and(|entries| {
        entries
            .flatten()
            .any(|e| job.names(e.file_name().as_bytes()))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_leftover_with_the_same_prefix_does_not_collide_and_drop_removes() {
        let parent = tempfile::tempdir().unwrap();
        let job = Job::alone();
        let a = ScratchDir::create(parent.path(), job).unwrap();
        let b = ScratchDir::create(parent.path(), job).unwrap();
        assert_ne!(a.path(), b.path());
        std::fs::write(a.path().join("x"), b"x").unwrap();
        let (pa, pb) = (a.path().to_path_buf(), b.path().to_path_buf());
        drop(a);
        drop(b);
        assert!(!pa.exists() && !pb.exists());
    }

    #[test]
    fn a_job_knows_its_ranks_directories_and_no_others() {
        let job = Job {
            token: 0x0123_abcd,
            rank: 1,
            ranks: 2,
        };
        let mine = job.directory_name();
        assert!(mine.starts_with("lse-deform-rank1-0123abcd"), "{mine}");
        assert_eq!(mine.len(), "lse-deform-rank1-".len() + 16);
        for name in [
            mine.as_str(),
            "lse-deform-rank0-0123abcd00000000",
            "lse-deform-rank12-0123abcdffffffff",
        ] {
            assert!(job.names(name.as_bytes()), "{name}");
        }
        for name in [
            "lse-deform-rank0-0123abce00000000",
            "lse-deform-rank0-0123abcd0000000",
            "lse-deform-rankx-0123abcd00000000",
            "lse-deform-1-0-rank0",
            "someone-elses.txt",
        ] {
            assert!(!job.names(name.as_bytes()), "{name}");
        }
        let parent = tempfile::tempdir().unwrap();
        std::fs::create_dir(parent.path().join("lse-deform-rank0-0123abce00000000")).unwrap();
        assert!(!holds_job(parent.path(), &job));
        let sibling = ScratchDir::create(parent.path(), Job { rank: 0, ..job }).unwrap();
        assert!(holds_job(parent.path(), &job));
        drop(sibling);
        assert!(!holds_job(parent.path(), &job));
    }

    #[test]
    fn a_path_over_255_bytes_is_refused_naming_the_directory() {
        let parent = PathBuf::from(format!("/tmp/{}", "d".repeat(250)));
        let e = ScratchDir::create(&parent, Job::alone()).unwrap_err();
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
