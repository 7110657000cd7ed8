//! The command-line tool's panic hook and the check that a thread can
//! start: neither may turn a shortage of memory into an abort, a panic or a hang.
//!
//! With `RUST_BACKTRACE` set, the standard panic hook captures and prints
//! a backtrace while holding the process's backtrace lock; resolving it
//! allocates (it maps the executable's debug information and parses it).
//! When that allocation fails, the standard allocation-error hook prints
//! its own backtrace, waits for the same lock, and the process sleeps
//! until it is killed (found in the latest round of faults, under
//! `prlimit --as`). [`install`] puts a hook in front of the standard one
//! that first reserves (and releases at once) [`headroom_bytes`] of
//! address space with a fallible allocation: when that fails, it prints
//! the panic's message and location without a backtrace, and the standard
//! hook is not called. Hooks installed later (MUMPS's abort of every rank)
//! take this one as their default and so chain to it.

use std::sync::OnceLock;

/// Address space a backtrace may take: twice the executable's size (its
/// debug information is mapped and parsed) plus 32 MiB for the resolver's
/// tables; 256 MiB when the executable's size cannot be read. Computed at
/// [`install`], so that the hook itself reads nothing.
pub(crate) fn headroom_bytes() -> usize {
    *HEADROOM.get_or_init(|| {
        std::env::current_exe()
            .and_then(std::fs::metadata)
            .map(|m| {
                (m.len() as usize)
                    .saturating_mul(2)
                    .saturating_add(32 << 20)
            })
            .unwrap_or(256 << 20)
    })
}

static HEADROOM: OnceLock<usize> = OnceLock::new();

/// Whether `bytes` of memory can be allocated now (allocated and freed at
/// once, never touched: for a large size `malloc` maps and unmaps it).
fn can_allocate(bytes: usize) -> bool {
    let mut probe: Vec<u8> = Vec::new();
    probe.try_reserve_exact(bytes).is_ok()
}

/// Installs the hook (once, at start, before any other hook).
pub(crate) fn install() {
    let headroom = headroom_bytes();
    let standard = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if can_allocate(headroom) {
            standard(info);
        } else {
            // `PanicHookInfo`'s Display writes the location and the
            // message; stderr is unbuffered, so this does not allocate.
            eprintln!(
                "{info}\nnote: no backtrace: memory is too short to resolve one (under the address-space limit)"
            );
        }
    }));
}

/// `Err` with the refusal when a thread cannot be started now (its stack
/// is mapped, and under a tight address-space limit the spawn fails):
/// one empty thread is started and joined.
pub(crate) fn can_start_a_thread() -> Result<(), String> {
    match std::thread::Builder::new().spawn(|| ()) {
        Ok(handle) => {
            let _ = handle.join();
            Ok(())
        }
        Err(e) => Err(refusal(&format!("a thread cannot start ({e})"))),
    }
}

/// The message of a refusal for lack of address space: `what`, and the
/// limit (`RLIMIT_AS`) when there is one.
fn refusal(what: &str) -> String {
    format!(
        "too large for the memory budget: {what}{}",
        lse_deform::limits::address_space_limit()
            .map(|b| format!(", under the address-space limit (RLIMIT_AS) of {b} bytes"))
            .unwrap_or_default()
    )
}
