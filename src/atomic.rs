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
//!   left truncated;
//! - the temporary name is short (`.PREFIX.lse-PID-N.tmp`, `PREFIX` at most
//!   [`TEMP_PREFIX_BYTES`] bytes of the target's name), so it is never
//!   longer than a name the target's directory accepts: a target whose own
//!   name is accepted never fails for its temporary one.
//!
//! [`prepare`] is the check before any work: it opens a FIFO target for
//! writing without blocking — with no process reading it the open fails
//! (`ENXIO`) and the output is refused; with one it keeps the descriptor
//! open until the write, so the reader never sees an end of file before
//! the content — and it finishes the renames of a set interrupted by a
//! kill (below).
//!
//! [`staged`] makes the writes of a whole run one unit: inside it every
//! [`write`] on this thread fills and syncs its temporary file as above but
//! defers the rename; the renames are done together when the run succeeded,
//! and on any error every temporary file is removed, so that no output is
//! replaced and none is left behind. Writes to a non-regular target (a
//! device, a FIFO) cannot be deferred: they happen when asked, which is
//! before the renames, so that a failing `/dev/full` still prevents every
//! rename.
//!
//! A set of two or more renames is journalled: before the first rename a
//! marker `.lse-pending-HASH` (the hash of the target's name) listing every
//! `(temporary, target)` pair of the set is written and synced beside each
//! target, and removed after the last rename. A process killed in between
//! (`kill -9`) leaves some targets replaced and the others' complete
//! temporary files with the markers; [`prepare`] for any of the targets
//! finds its marker, finishes the renames and says so, so that the outputs
//! are again all from one run.
//!
//! Interruptions: every temporary file is listed while it exists, and
//! [`remove_temporaries`] (what the command-line tool calls on SIGINT and
//! SIGTERM) removes them, waiting for a set's renames in progress to end
//! first, so an interrupted run leaves no temporary file and no half-done
//! set.

use std::cell::RefCell;
use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard, PoisonError};

/// Size of the buffer between the caller's writer and the file.
const BUFFER_BYTES: usize = 1 << 16;

/// At most this many bytes of the target's name begin its temporary
/// file's name (cut at a character boundary): enough to tell whose it is,
/// short enough that the name stays far below the 255 bytes of a name.
pub const TEMP_PREFIX_BYTES: usize = 32;

/// Writes `path` atomically: `fill` writes the whole content into a
/// buffered temporary file beside `path`, which then replaces `path` (see
/// the module documentation). On an error of `fill` or of the file system
/// the temporary file is removed and `path` is left as it was; the error is
/// returned (`E` is `io::Error` or any error that converts from it).
pub(crate) fn write<T, E, F>(path: &Path, fill: F) -> Result<T, E>
where
    E: From<io::Error>,
    F: FnOnce(&mut BufWriter<File>) -> Result<T, E>,
{
    let target = resolve(path);
    let existing = std::fs::metadata(&target).ok();
    if existing.as_ref().is_some_and(|m| !m.is_file()) {
        // A device or FIFO: no rename possible (a directory fails here
        // with the system's message).
        let mut w = BufWriter::with_capacity(BUFFER_BYTES, open_in_place(&target)?);
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

/// Locks `m`, also after a panic elsewhere (the lists it guards stay
/// valid: each change is one push or one removal).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// FIFOs opened by [`prepare`], kept open until their write.
static HELD: Mutex<Vec<(PathBuf, File)>> = Mutex::new(Vec::new());

/// The non-regular `target` opened for writing: the descriptor
/// [`prepare`] kept for it, else a new one.
fn open_in_place(target: &Path) -> io::Result<File> {
    let mut held = lock(&HELD);
    match held.iter().position(|(p, _)| p == target) {
        Some(k) => Ok(held.swap_remove(k).1),
        None => {
            drop(held);
            File::create(target)
        }
    }
}

/// Checks before any work that `path` can be written, and readies it (see
/// the module documentation): a FIFO without a reader is an error (kind
/// `BrokenPipe`, saying so); a FIFO with one stays open for the write; an
/// interrupted set of renames that `path` belongs to is finished. Returns
/// what was done about such a set, as sentences to show; creates nothing.
pub(crate) fn prepare(path: &Path) -> io::Result<Vec<String>> {
    let target = resolve(path);
    let notes = journal::finish(&target)?.into_iter().collect();
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if std::fs::metadata(&target).is_ok_and(|m| m.file_type().is_fifo()) {
            let file = open_fifo(&target)?;
            lock(&HELD).push((target, file));
        }
    }
    Ok(notes)
}

/// Opens the FIFO `target` for writing without waiting for a reader, and
/// makes the descriptor blocking again for the write.
#[cfg(unix)]
fn open_fifo(target: &Path) -> io::Result<File> {
    use std::os::fd::AsRawFd;
    use std::os::unix::fs::OpenOptionsExt;
    let file = OpenOptions::new()
        .write(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(target)
        .map_err(|e| match e.raw_os_error() {
            Some(libc::ENXIO) => io::Error::new(
                io::ErrorKind::BrokenPipe,
                "a FIFO that no process is reading: start its reader first (the output is written after the work, and nothing is written without a reader)",
            ),
            _ => e,
        })?;
    // SAFETY: fcntl on a descriptor this function owns, with integer
    // arguments only.
    let fd = file.as_raw_fd();
    let flags = unsafe { libc::fcntl(fd, libc::F_GETFL) };
    if flags < 0 || unsafe { libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK) } < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(file)
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
    commit(set).map_err(|(target, e)| rename_error(&target, e))?;
    Ok(value)
}

/// Serialises [`commit`] and [`remove_temporaries`]: a signal's clean-up
/// waits for a set's renames to end.
static COMMIT: Mutex<()> = Mutex::new(());

/// Renames a staged set, journalled when it has two renames or more.
fn commit(set: Vec<(TempFile, PathBuf)>) -> Result<(), (PathBuf, io::Error)> {
    let _commit = lock(&COMMIT);
    let markers = if set.len() > 1 {
        let pairs: Vec<_> = set
            .iter()
            .map(|(t, p)| (t.path.as_path(), p.as_path()))
            .collect();
        journal::begin(&pairs)?
    } else {
        Vec::new()
    };
    let mut result = Ok(());
    for (temp, target) in set {
        #[cfg(test)]
        if tests::crash_now() {
            std::mem::forget(temp);
            std::mem::forget(markers);
            return Ok(());
        }
        if let Err(e) = temp.rename_to(&target) {
            // The files not renamed are removed as the loop ends.
            result = Err((target, e));
            break;
        }
    }
    journal::end(markers);
    result
}

/// Removes every temporary file of this process that still exists (the
/// command-line tool's clean-up on SIGINT and SIGTERM, before it ends),
/// after a set's renames in progress have ended.
pub fn remove_temporaries() {
    let _commit = lock(&COMMIT);
    for path in lock(&LIVE).drain(..) {
        let _ = std::fs::remove_file(path);
    }
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

/// The directory of `target` (`.` for a bare name).
fn dir_of(target: &Path) -> &Path {
    match target.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// The temporary files of this process that exist now, for
/// [`remove_temporaries`].
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// A temporary file beside the target, removed on drop unless renamed.
struct TempFile {
    path: PathBuf,
    renamed: bool,
}

impl TempFile {
    /// Creates `.PREFIX.lse-PID-N.tmp` in the directory of `target` (a
    /// fresh name: never an existing file; `PREFIX` the first
    /// [`TEMP_PREFIX_BYTES`] bytes of the target's name at most).
    fn create(target: &Path) -> io::Result<(File, TempFile)> {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let dir = dir_of(target);
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "output".into());
        let mut cut = name.len().min(TEMP_PREFIX_BYTES);
        while !name.is_char_boundary(cut) {
            cut -= 1;
        }
        let prefix = &name[..cut];
        loop {
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            let path = dir.join(format!(".{prefix}.lse-{}-{n}.tmp", std::process::id()));
            let mut live = lock(&LIVE);
            match OpenOptions::new().write(true).create_new(true).open(&path) {
                Ok(file) => {
                    live.push(path.clone());
                    let temp = TempFile {
                        path,
                        renamed: false,
                    };
                    return Ok((file, temp));
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
        forget_live(&self.path);
        sync_dir(dir_of(target));
        Ok(())
    }
}

/// Drops `path` from [`LIVE`].
fn forget_live(path: &Path) {
    let mut live = lock(&LIVE);
    if let Some(k) = live.iter().position(|p| p == path) {
        live.swap_remove(k);
    }
}

/// Syncs the directory `dir` (Unix, best effort).
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if !self.renamed {
            let _ = std::fs::remove_file(&self.path);
            forget_live(&self.path);
        }
    }
}

/// The journal of a set of renames: a marker beside each target, written
/// before the first rename and removed after the last (see the module
/// documentation).
mod journal {
    use std::io::{self, Write};
    use std::path::{Path, PathBuf};

    use super::{dir_of, sync_dir};

    /// The first line of a marker.
    const HEADER: &str = "lse-deform pending renames v1";

    /// The marker of `target`: `.lse-pending-HASH` in its directory, HASH
    /// the 64-bit FNV-1a of its name (short, whatever the name's length).
    fn marker_of(target: &Path) -> PathBuf {
        let name = target.file_name().unwrap_or_default().as_encoded_bytes();
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for &b in name {
            h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
        dir_of(target).join(format!(".lse-pending-{h:016x}"))
    }

    /// Writes and syncs the marker of every target of `pairs`
    /// (`(temporary, target)`, made absolute so that a run from another
    /// directory reads them); the markers written, to remove with [`end`].
    pub(super) fn begin(pairs: &[(&Path, &Path)]) -> Result<Vec<PathBuf>, (PathBuf, io::Error)> {
        let mut text = format!("{HEADER}\n{}\n", std::process::id()).into_bytes();
        for (temp, target) in pairs {
            for p in [temp, target] {
                let p = std::path::absolute(p).map_err(|e| (p.to_path_buf(), e))?;
                text.extend_from_slice(p.as_os_str().as_encoded_bytes());
                text.push(0);
            }
        }
        let mut written = Vec::new();
        for (_, target) in pairs {
            let marker = marker_of(target);
            let result = std::fs::File::create(&marker)
                .and_then(|mut f| f.write_all(&text).and_then(|()| f.sync_all()));
            if let Err(e) = result {
                end(written);
                let _ = std::fs::remove_file(&marker);
                return Err((target.to_path_buf(), e));
            }
            sync_dir(dir_of(target));
            written.push(marker);
        }
        Ok(written)
    }

    /// Removes the markers of a finished set.
    pub(super) fn end(markers: Vec<PathBuf>) {
        for m in markers {
            let _ = std::fs::remove_file(&m);
        }
    }

    /// A marker's process and `(temporary, target)` pairs.
    type Pending = (String, Vec<(PathBuf, PathBuf)>);

    /// An interrupted set `target` belongs to, read from its marker: the
    /// process and the `(temporary, target)` pairs. A marker that is not
    /// one is an error naming it.
    fn read(marker: &Path) -> io::Result<Option<Pending>> {
        let bytes = match std::fs::read(marker) {
            Ok(b) => b,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(e),
        };
        let invalid = || {
            io::Error::new(
                io::ErrorKind::InvalidData,
                format!(
                    "{} is not a marker of lse-deform's (a name it reserves beside its outputs): remove it",
                    marker.display()
                ),
            )
        };
        let mut lines = bytes.splitn(3, |&b| b == b'\n');
        if lines.next() != Some(HEADER.as_bytes()) {
            return Err(invalid());
        }
        let pid = lines
            .next()
            .and_then(|p| std::str::from_utf8(p).ok())
            .ok_or_else(invalid)?;
        let rest = lines.next().ok_or_else(invalid)?;
        let paths: Vec<PathBuf> = rest
            .split(|&b| b == 0)
            .filter(|p| !p.is_empty())
            .map(path_of)
            .collect();
        if paths.is_empty() || !paths.len().is_multiple_of(2) || !rest.ends_with(&[0]) {
            return Err(invalid());
        }
        let pairs = paths
            .chunks(2)
            .map(|c| (c[0].clone(), c[1].clone()))
            .collect();
        Ok(Some((pid.to_string(), pairs)))
    }

    /// A path from the bytes [`begin`] wrote.
    fn path_of(bytes: &[u8]) -> PathBuf {
        #[cfg(unix)]
        {
            use std::os::unix::ffi::OsStrExt;
            PathBuf::from(std::ffi::OsStr::from_bytes(bytes))
        }
        #[cfg(not(unix))]
        PathBuf::from(String::from_utf8_lossy(bytes).into_owned())
    }

    /// Finishes the interrupted set `target` belongs to, if any: renames
    /// the temporary files still there over their targets and removes the
    /// set's markers; a sentence saying what was done.
    pub(super) fn finish(target: &Path) -> io::Result<Option<String>> {
        let marker = marker_of(target);
        let Some((pid, pairs)) = read(&marker)? else {
            return Ok(None);
        };
        let mut finished = Vec::new();
        for (temp, t) in &pairs {
            if temp.exists() {
                std::fs::rename(temp, t)?;
                sync_dir(dir_of(t));
                finished.push(t.display().to_string());
            }
        }
        for (_, t) in &pairs {
            let _ = std::fs::remove_file(marker_of(t));
        }
        let _ = std::fs::remove_file(&marker);
        let all: Vec<_> = pairs.iter().map(|(_, t)| t.display().to_string()).collect();
        let done = if finished.is_empty() {
            "nothing was left to rename".to_string()
        } else {
            format!("renamed its new {} over the old", finished.join(", "))
        };
        Ok(Some(format!(
            "an earlier run (process {pid}) was stopped while replacing its outputs {} together: {done}, so they are all from that run now",
            all.join(", ")
        )))
    }
}

#[cfg(test)]
mod tests {
    use std::cell::Cell;
    use std::io::Write;

    use super::*;

    thread_local! {
        /// Renames [`commit`] does on this thread before it "is killed"
        /// (stops, leaving its files as a `kill -9` would); `None`: never.
        static RENAMES_BEFORE_KILL: Cell<Option<usize>> = const { Cell::new(None) };
    }

    /// Whether [`commit`] is to stop here, as a killed process would.
    pub(super) fn crash_now() -> bool {
        RENAMES_BEFORE_KILL.with(|c| match c.get() {
            Some(0) => true,
            Some(n) => {
                c.set(Some(n - 1));
                false
            }
            None => false,
        })
    }

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

    /// An output name of 255 bytes (251 and `.obj`) is written: its
    /// temporary name is short. (Before: `.NAME.PID.N.tmp`, longer than the
    /// name, failed with "File name too long".)
    #[test]
    fn a_name_of_255_bytes_is_written() {
        let dir = tempfile::tempdir().unwrap();
        let name = format!("{}.obj", "x".repeat(251));
        let path = dir.path().join(&name);
        write_bytes(&path, b"v 0 0 0\n").unwrap();
        assert_eq!(names(dir.path()), [name]);
    }

    /// A set killed after its first rename (`kill -9`) leaves a marker;
    /// the next [`prepare`] of one of its outputs finds it, finishes the
    /// renames and says so, and leaves only the outputs, both new.
    /// (Before: a new `a.ply`, an old `b.json` and `.b.json.PID.1.tmp`,
    /// found by nothing.)
    #[test]
    fn a_set_killed_between_renames_is_finished_by_the_next_prepare() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.ply"), dir.path().join("b.json"));
        std::fs::write(&a, "old a").unwrap();
        std::fs::write(&b, "old b").unwrap();
        RENAMES_BEFORE_KILL.with(|c| c.set(Some(1)));
        let set = || {
            write_bytes(&a, b"new a")?;
            write_bytes(&b, b"new b")
        };
        staged(set, |_, e| e).unwrap();
        RENAMES_BEFORE_KILL.with(|c| c.set(None));
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "new a");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "old b");
        assert_eq!(names(dir.path()).len(), 5, "{:?}", names(dir.path()));
        let notes = prepare(&b).unwrap();
        assert_eq!(notes.len(), 1);
        assert!(
            notes[0].contains("b.json") && notes[0].contains("a.ply"),
            "{notes:?}"
        );
        assert!(notes[0].contains("stopped while replacing"), "{notes:?}");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "new b");
        assert_eq!(names(dir.path()), ["a.ply", "b.json"]);
        assert!(prepare(&a).unwrap().is_empty());
    }
}
