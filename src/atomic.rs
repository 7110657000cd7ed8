//! Atomic file output: a file the library or the command-line tool writes
//! appears whole or not at all.
//!
//! [`write`] fills a temporary file in the target's own directory (a hidden
//! name beside it, so that the final rename stays on one file system),
//! flushes it, syncs it to the device and renames it over the target; on
//! Unix the directory is then synced too (best effort), so that the rename
//! survives a crash. Any error on the way — a full disk, a quota, a file
//! size limit, an error of the device or of the caller's own writer —
//! removes the temporary file and leaves a previous file at the target as
//! it was: a reader sees the old file or the complete new one, never a
//! truncated one.
//!
//! Details:
//! - a symbolic link at the target is followed: the file it points to is
//!   replaced and the link stays a link;
//! - an existing target's permissions are kept;
//! - a target that exists and is not a regular file (a character device
//!   such as `/dev/null` or `/dev/stdout`, a FIFO) is written in place, as
//!   before: it cannot be replaced by a rename, and nothing there can be
//!   left truncated.
//!
//! [`staged`] makes the writes of a whole run one unit: inside it every
//! [`write`] on this thread fills and syncs its temporary file as above but
//! defers the rename; the renames are done together when the run succeeded,
//! and on any error every temporary file is removed, so that no output is
//! replaced and none is left behind. Writes to a non-regular target (a
//! device, a FIFO) cannot be deferred: they happen when asked, which is
//! before the renames, so that a failing `/dev/full` still prevents every
//! rename.

use std::cell::RefCell;
use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Size of the buffer between the caller's writer and the file.
const BUFFER_BYTES: usize = 1 << 16;

/// Writes `path` atomically: `fill` writes the whole content into a
/// buffered temporary file beside `path`, which then replaces `path` (see
/// the module documentation). On an error of `fill` or of the file system
/// the temporary file is removed and `path` is left as it was; the error is
/// returned (`E` is `io::Error` or any error that converts from it).
pub fn write<T, E, F>(path: &Path, fill: F) -> Result<T, E>
where
    E: From<io::Error>,
    F: FnOnce(&mut BufWriter<File>) -> Result<T, E>,
{
    let target = resolve(path);
    let existing = std::fs::metadata(&target).ok();
    if existing.as_ref().is_some_and(|m| !m.is_file()) {
        // A device or FIFO: no rename possible (a directory fails here
        // with the system's message).
        let mut w = BufWriter::with_capacity(BUFFER_BYTES, File::create(&target)?);
        let value = fill(&mut w)?;
        w.into_inner().map_err(io::IntoInnerError::into_error)?;
        return Ok(value);
    }
    let (file, temp) = TempFile::create(&target)?;
    let mut w = BufWriter::with_capacity(BUFFER_BYTES, file);
    let value = fill(&mut w)?;
    let file = w.into_inner().map_err(io::IntoInnerError::into_error)?;
    if let Some(m) = &existing {
        file.set_permissions(m.permissions())?;
    }
    file.sync_all()?;
    drop(file);
    if let Some(temp) = defer(temp, &target) {
        temp.rename_to(&target)?;
    }
    Ok(value)
}

thread_local! {
    /// The renames deferred by [`staged`] on this thread (`None` outside
    /// it), in the order of the writes.
    static STAGE: RefCell<Option<Vec<(TempFile, PathBuf)>>> = const { RefCell::new(None) };
}

/// Inside [`staged`]: keeps `temp` to be renamed over `target` at the end
/// and returns `None`; outside: returns `temp` to be renamed now.
fn defer(temp: TempFile, target: &Path) -> Option<TempFile> {
    STAGE.with(|stage| match stage.borrow_mut().as_mut() {
        Some(set) => {
            set.push((temp, target.to_path_buf()));
            None
        }
        None => Some(temp),
    })
}

/// Runs `run` with every [`write`] of this thread staged (see the module
/// documentation): when `run` returns `Ok`, the staged files are renamed
/// over their targets, in the order they were written; when it returns an
/// error (or panics), they are removed and no target changes. A rename
/// that fails (the directory removed meanwhile) is returned through
/// `rename_error` with its target, and the files not yet renamed are
/// removed; renames done before it stay done — the one window left, after
/// every write has succeeded. Inside another `staged`, `run` joins the
/// outer set.
pub fn staged<T, E>(
    run: impl FnOnce() -> Result<T, E>,
    rename_error: impl FnOnce(&Path, io::Error) -> E,
) -> Result<T, E> {
    if STAGE.with(|stage| stage.borrow().is_some()) {
        return run();
    }
    /// Ends the stage however `run` ends: the files left in it are
    /// dropped, which removes them.
    struct Stage;
    impl Drop for Stage {
        fn drop(&mut self) {
            STAGE.with(|stage| stage.borrow_mut().take());
        }
    }
    STAGE.with(|stage| *stage.borrow_mut() = Some(Vec::new()));
    let guard = Stage;
    let value = run()?;
    let set = STAGE
        .with(|stage| stage.borrow_mut().take())
        .unwrap_or_default();
    drop(guard);
    for (temp, target) in set {
        if let Err(e) = temp.rename_to(&target) {
            return Err(rename_error(&target, e));
        }
    }
    Ok(value)
}

/// [`write`] of a byte string.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write(path, |w| io::Write::write_all(w, bytes))
}

/// The file a [`write`] to `path` replaces: the target of a symbolic link
/// (followed to the end, also when it does not exist yet), otherwise `path`
/// itself.
pub fn resolve(path: &Path) -> PathBuf {
    let is_link = path
        .symlink_metadata()
        .is_ok_and(|m| m.file_type().is_symlink());
    if is_link {
        // A dangling link: its target does not exist, so `canonicalize`
        // fails; read the link and resolve it against its directory.
        if let Ok(real) = std::fs::canonicalize(path) {
            return real;
        }
        if let Ok(link) = std::fs::read_link(path) {
            return match path.parent() {
                Some(dir) if link.is_relative() => dir.join(link),
                _ => link,
            };
        }
    }
    path.to_path_buf()
}

/// A temporary file beside the target, removed on drop unless renamed.
struct TempFile {
    path: PathBuf,
    renamed: bool,
}

impl TempFile {
    /// Creates `.NAME.PID.N.tmp` in the directory of `target` (a fresh
    /// name: never an existing file).
    fn create(target: &Path) -> io::Result<(File, TempFile)> {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let dir = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "output".into());
        loop {
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            let path = dir.join(format!(".{name}.{}.{n}.tmp", std::process::id()));
            match OpenOptions::new().write(true).create_new(true).open(&path) {
                Ok(file) => {
                    return Ok((
                        file,
                        TempFile {
                            path,
                            renamed: false,
                        },
                    ));
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
                Err(e) => return Err(e),
            }
        }
    }

    /// Renames the file over `target`, then syncs the directory (Unix,
    /// best effort: a file system that cannot sync a directory still has
    /// the file).
    fn rename_to(mut self, target: &Path) -> io::Result<()> {
        std::fs::rename(&self.path, target)?;
        self.renamed = true;
        #[cfg(unix)]
        if let Some(dir) = target.parent() {
            let dir = if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            };
            if let Ok(d) = File::open(dir) {
                let _ = d.sync_all();
            }
        }
        Ok(())
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if !self.renamed {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

#[cfg(test)]
mod tests {
    use std::io::Write;

    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn replaces_the_file_and_leaves_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.txt");
        std::fs::write(&path, "old content that is longer").unwrap();
        write_bytes(&path, b"new").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new");
        assert_eq!(names(dir.path()), ["out.txt"]);
    }

    /// A write error in the middle (as a full disk gives): the old file is
    /// intact and the temporary file is gone.
    #[test]
    fn an_injected_write_error_keeps_the_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mesh.obj");
        std::fs::write(&path, "the previous good file").unwrap();
        let result: io::Result<()> = write(&path, |w| {
            for _ in 0..10_000 {
                w.write_all(b"v 1 2 3\n")?;
            }
            Err(io::Error::new(
                io::ErrorKind::StorageFull,
                "No space left on device (injected)",
            ))
        });
        let e = result.unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::StorageFull);
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "the previous good file"
        );
        assert_eq!(names(dir.path()), ["mesh.obj"]);
    }

    #[test]
    fn a_missing_directory_is_an_error_and_creates_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("missing").join("r.json");
        let e = write_bytes(&path, b"{}").unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::NotFound);
        assert!(names(dir.path()).is_empty());
    }

    #[cfg(unix)]
    #[test]
    fn links_are_followed_and_permissions_kept() {
        use std::os::unix::fs::{PermissionsExt, symlink};
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().join("real.json");
        std::fs::write(&real, "old").unwrap();
        std::fs::set_permissions(&real, std::fs::Permissions::from_mode(0o600)).unwrap();
        let link = dir.path().join("link.json");
        symlink("real.json", &link).unwrap();
        write_bytes(&link, b"new").unwrap();
        assert!(link.symlink_metadata().unwrap().file_type().is_symlink());
        assert_eq!(std::fs::read_to_string(&real).unwrap(), "new");
        let mode = std::fs::metadata(&real).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o600);
        assert_eq!(names(dir.path()), ["link.json", "real.json"]);
    }

    /// A staged set: nothing is replaced until the run succeeds, then
    /// everything is; an error after some writes leaves every previous
    /// file and no temporary one.
    #[test]
    fn a_staged_set_is_replaced_together_or_not_at_all() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.obj"), dir.path().join("b.json"));
        std::fs::write(&a, "old a").unwrap();
        let failed: io::Result<()> = staged(
            || {
                write_bytes(&a, b"new a")?;
                assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
                write_bytes(&b, b"new b")?;
                Err(io::Error::other("the run failed after its writes"))
            },
            |_, e| e,
        );
        assert!(failed.is_err());
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
        assert_eq!(names(dir.path()), ["a.obj"]);
        staged(
            || {
                write_bytes(&a, b"new a")?;
                write_bytes(&b, b"new b")
            },
            |_, e| e,
        )
        .unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "new a");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "new b");
        assert_eq!(names(dir.path()), ["a.obj", "b.json"]);
    }

    /// A device in a staged set is written when asked, before the renames:
    /// a full one (`/dev/full`) fails the set and nothing is replaced.
    #[cfg(target_os = "linux")]
    #[test]
    fn a_full_device_in_a_staged_set_replaces_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.obj");
        let e = staged(
            || {
                write_bytes(&a, b"new a")?;
                write_bytes(Path::new("/dev/full"), b"the report")
            },
            |_, e| e,
        )
        .unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::StorageFull);
        assert!(names(dir.path()).is_empty());
    }

    #[cfg(unix)]
    #[test]
    fn a_device_is_written_in_place() {
        use std::os::unix::fs::FileTypeExt;
        write_bytes(Path::new("/dev/null"), b"discarded").unwrap();
        let kind = std::fs::metadata("/dev/null").unwrap().file_type();
        assert!(kind.is_char_device());
    }
}
