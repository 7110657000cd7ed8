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
    temp.rename_to(&target)?;
    Ok(value)
}

/// [`write`] of a byte string.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write(path, |w| io::Write::write_all(w, bytes))
}

/// The file to replace: the target of a symbolic link (followed to the
/// end), otherwise `path` itself.
fn resolve(path: &Path) -> PathBuf {
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

    #[cfg(unix)]
    #[test]
    fn a_device_is_written_in_place() {
        use std::os::unix::fs::FileTypeExt;
        write_bytes(Path::new("/dev/null"), b"discarded").unwrap();
        let kind = std::fs::metadata("/dev/null").unwrap().file_type();
        assert!(kind.is_char_device());
    }
}
