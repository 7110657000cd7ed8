//! SIGINT, SIGTERM and SIGHUP end the tool as before (killed by the
//! signal), but first remove what the run keeps on disk only while it
//! runs: the staged temporary files
//! ([`lse_deform::atomic::remove_temporaries`], waiting for a set's renames
//! in progress to end) and MUMPS's out-of-core scratch directories
//! (`lse_deform::backend::mumps::remove_scratch`, on every rank, each
//! removing its own). The signals are blocked in every thread and taken by
//! one thread ([`install`]), which cleans up and then lets the signal end
//! the process with its default action. A library call into MUMPS cannot
//! be interrupted, so the clean-up cannot wait for it: it happens beside
//! the factorisation, which the signal then ends.

/// The signals handled.
#[cfg(unix)]
const SIGNALS: [libc::c_int; 3] = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];

/// Blocks [`SIGNALS`] in this thread — and so in every thread started
/// after it, which inherit the mask: call it first in `main`, before MPI
/// and the thread pools start — and starts
/// the thread that takes them. Does nothing off Unix, or when the mask
/// cannot be set (the signals then end the process as before).
pub(crate) fn install() {
    #[cfg(unix)]
    {
        let Some(set) = signal_set() else { return };
        // SAFETY: `set` is an initialised signal set; the old mask is not
        // asked for.
        if unsafe { libc::pthread_sigmask(libc::SIG_BLOCK, &set, std::ptr::null_mut()) } != 0 {
            return;
        }
        std::thread::spawn(move || take(set));
    }
}

/// The set of [`SIGNALS`].
#[cfg(unix)]
fn signal_set() -> Option<libc::sigset_t> {
    // SAFETY: sigemptyset initialises the zeroed set; sigaddset adds valid
    // signal numbers to it.
    unsafe {
        let mut set: libc::sigset_t = std::mem::zeroed();
        if libc::sigemptyset(&mut set) != 0 {
            return None;
        }
        for s in SIGNALS {
            if libc::sigaddset(&mut set, s) != 0 {
                return None;
            }
        }
        Some(set)
    }
}

/// Waits for one of `set`, removes the temporary files, and ends the
/// process by that signal (with its default action, so the exit status
/// is the signal's, as without this thread).
#[cfg(unix)]
fn take(set: libc::sigset_t) {
    let mut signal: libc::c_int = 0;
    // SAFETY: `set` is a valid set blocked in every thread; `signal` is a
    // valid place for the number.
    while unsafe { libc::sigwait(&set, &mut signal) } != 0 {}
    lse_deform::atomic::remove_temporaries();
    #[cfg(feature = "mumps")]
    lse_deform::backend::mumps::remove_scratch();
    // SAFETY: restores the default action of a valid signal, unblocks it
    // in this thread and sends it to this thread: the process ends.
    unsafe {
        libc::signal(signal, libc::SIG_DFL);
        let mut one: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut one);
        libc::sigaddset(&mut one, signal);
        libc::pthread_sigmask(libc::SIG_UNBLOCK, &one, std::ptr::null_mut());
        libc::raise(signal);
    }
    std::process::exit(128 + signal);
}
