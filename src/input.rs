//! Opening an input file without the risk of waiting forever.
//!
//! `open(2)` of a FIFO (a named pipe, `mkfifo`) for reading blocks until
//! some process opens it for writing, so a mesh, constraints, ordering or
//! Matrix Market file given as a FIFO that nobody writes used to hang the
//! run in `open`. [`open_input`] opens a FIFO without blocking instead and
//! waits at most [`FIFO_WRITER_WAIT`] for a writer to send something (or
//! to open and close it, an empty input); with none the open is refused
//! ([`std::io::ErrorKind::TimedOut`], "a FIFO that no process wrote to
//! within 5 s"). Then the file is read as any other stream: blocking,
//! within the budget of its reader. Any other path is opened as usual.

use std::fs::File;
use std::io;
use std::path::Path;
use std::time::Duration;

/// How long an input FIFO may wait for its writer (the documented bound
/// of docs/cli.md §6): long enough for a writer started just after the
/// run, short enough that a forgotten one is not mistaken for a hang.
pub const FIFO_WRITER_WAIT: Duration = Duration::from_secs(5);

/// Opens `path` for reading; a FIFO as the module documentation says.
pub(crate) fn open_input(path: &Path) -> io::Result<File> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if std::fs::metadata(path).is_ok_and(|m| m.file_type().is_fifo()) {
            return open_fifo(path, FIFO_WRITER_WAIT);
        }
    }
    File::open(path)
}

/// The FIFO `path`, opened without blocking, once a writer has written to
/// it (or opened and closed it) within `wait`; then blocking again.
#[cfg(unix)]
fn open_fifo(path: &Path, wait: Duration) -> io::Result<File> {
    use std::os::fd::AsRawFd;
    use std::os::unix::fs::OpenOptionsExt;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)?;
    let fd = file.as_raw_fd();
    if !wait_for_writer(fd, wait)? {
        return Err(io::Error::new(
            io::ErrorKind::TimedOut,
            format!(
                "a FIFO that no process wrote to within {} s: start its writer first",
                wait.as_secs()
            ),
        ));
    }
    // SAFETY: `fd` is the open descriptor of `file`.
    let flags = unsafe { libc::fcntl(fd, libc::F_GETFL) };
    // SAFETY: as above; only O_NONBLOCK changes.
    if flags < 0 || unsafe { libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK) } < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(file)
}

/// Whether the FIFO read end `fd` becomes readable (data, or a writer
/// that came and went: Linux reports a hang-up only after a writer has
/// closed) within `wait`; a signal does not end the wait early.
#[cfg(unix)]
fn wait_for_writer(fd: std::os::fd::RawFd, wait: Duration) -> io::Result<bool> {
    let deadline = std::time::Instant::now() + wait;
    loop {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        let ms = i32::try_from(left.as_millis()).unwrap_or(i32::MAX);
        let mut poll = libc::pollfd {
            fd,
            events: libc::POLLIN,
            revents: 0,
        };
        // SAFETY: one valid pollfd, for the duration of the call.
        let ready = unsafe { libc::poll(&mut poll, 1, ms) };
        match ready {
            n if n > 0 => return Ok(true),
            0 => return Ok(false),
            _ => {
                let e = io::Error::last_os_error();
                if e.kind() != io::ErrorKind::Interrupted {
                    return Err(e);
                }
            }
        }
    }
}

#[cfg(all(test, unix))]
mod tests {
    use std::io::{Read, Write};
    use std::time::Duration;

    use super::open_fifo;

    fn fifo(dir: &std::path::Path) -> std::path::PathBuf {
        let path = dir.join("in.fifo");
        let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
        // SAFETY: a NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        path
    }

    /// No writer within the wait: refused, not blocked (the open itself
    /// returns at once without O_NONBLOCK's wait).
    #[test]
    fn a_fifo_nobody_writes_is_refused_after_the_wait() {
        let dir = tempfile::tempdir().unwrap();
        let path = fifo(dir.path());
        let e = open_fifo(&path, Duration::from_millis(200)).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::TimedOut, "{e}");
        assert!(e.to_string().contains("no process wrote"), "{e}");
    }

    /// A writer that comes during the wait is read whole, however it
    /// splits its writes.
    #[test]
    fn a_fifo_whose_writer_comes_is_read_whole() {
        let dir = tempfile::tempdir().unwrap();
        let path = fifo(dir.path());
        let writer_path = path.clone();
        let writer = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(100));
            let mut w = std::fs::OpenOptions::new()
                .write(true)
                .open(writer_path)
                .unwrap();
            w.write_all(b"first ").unwrap();
            std::thread::sleep(Duration::from_millis(100));
            w.write_all(b"second").unwrap();
        });
        let mut text = String::new();
        open_fifo(&path, Duration::from_secs(20))
            .unwrap()
            .read_to_string(&mut text)
            .unwrap();
        writer.join().unwrap();
        assert_eq!(text, "first second");
    }
}
