//! OpenBLAS's thread count, for the back ends whose dense kernels it runs
//! (CHOLMOD, MUMPS): read, and set for the length of a call.
//!
//! The functions are looked up in the running process
//! (`dlsym(RTLD_DEFAULT, "openblas_get_num_threads")`) rather than linked:
//! the system's BLAS is chosen by the distribution's alternatives, and when
//! it is not OpenBLAS (or no BLAS is loaded, as in a build without the
//! system back ends) there is no count to read or set: [`threads`] is then
//! `None`, and a back end records what it could not control.

use std::ffi::{c_char, c_int, c_void};

#[cfg(target_os = "linux")]
unsafe extern "C" {
    fn dlsym(handle: *mut c_void, symbol: *const c_char) -> *mut c_void;
}

/// The address of `symbol` (NUL-terminated) in the process, if loaded.
#[cfg(target_os = "linux")]
fn lookup(symbol: &'static [u8]) -> Option<*mut c_void> {
    // SAFETY: `symbol` is NUL-terminated; RTLD_DEFAULT is the null handle
    // on glibc and musl.
    let found = unsafe { dlsym(std::ptr::null_mut(), symbol.as_ptr().cast()) };
    (!found.is_null()).then_some(found)
}

#[cfg(not(target_os = "linux"))]
fn lookup(_symbol: &'static [u8]) -> Option<*mut c_void> {
    None
}

/// OpenBLAS's current thread count, `None` when OpenBLAS is not loaded.
pub(crate) fn threads() -> Option<usize> {
    let f = lookup(b"openblas_get_num_threads\0")?;
    // SAFETY: OpenBLAS's `int openblas_get_num_threads(void)`.
    let get: extern "C" fn() -> c_int = unsafe { std::mem::transmute(f) };
    usize::try_from(get()).ok()
}

fn set_threads(n: usize) -> bool {
    let Some(f) = lookup(b"openblas_set_num_threads\0") else {
        return false;
    };
    // SAFETY: OpenBLAS's `void openblas_set_num_threads(int)`.
    let set: extern "C" fn(c_int) = unsafe { std::mem::transmute(f) };
    set(c_int::try_from(n).unwrap_or(c_int::MAX));
    true
}

/// The threads a call on OpenBLAS ran on when `requested` were asked
/// for: what OpenBLAS takes when set to them (it clamps a count to the
/// maximum it was built for, `NUM_THREADS`, 64 in Debian's build: asked
/// for 1024 it runs on 64), read back after setting them for a moment;
/// with `None`, the count in effect; `None` without OpenBLAS.
pub(crate) fn threads_used(requested: Option<usize>) -> Option<usize> {
    let _set = ThreadsFor::new(requested);
    threads()
}

/// OpenBLAS on `n` threads until dropped (then back to the count before);
/// with `None` or without OpenBLAS, nothing changes.
pub(crate) struct ThreadsFor {
    before: Option<usize>,
}

impl ThreadsFor {
    /// Sets `n` threads (when `Some` and OpenBLAS is loaded).
    pub(crate) fn new(n: Option<usize>) -> ThreadsFor {
        let before = match n {
            Some(n) => threads().filter(|_| set_threads(n)),
            None => None,
        };
        ThreadsFor { before }
    }
}

impl Drop for ThreadsFor {
    fn drop(&mut self) {
        if let Some(n) = self.before {
            set_threads(n);
        }
    }
}

#[cfg(all(test, feature = "suitesparse", target_os = "linux"))]
mod tests {
    use super::*;

    /// OpenBLAS's own account of its maximum (`MAX_THREADS=` in
    /// `openblas_get_config()`), read apart from the thread calls.
    fn built_maximum() -> usize {
        let f = lookup(b"openblas_get_config\0").expect("OpenBLAS is loaded with CHOLMOD");
        // SAFETY: OpenBLAS's `char *openblas_get_config(void)`, a static
        // NUL-terminated string.
        let get: extern "C" fn() -> *const c_char = unsafe { std::mem::transmute(f) };
        let config = unsafe { std::ffi::CStr::from_ptr(get()) }.to_string_lossy();
        config
            .split_whitespace()
            .find_map(|w| w.strip_prefix("MAX_THREADS="))
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("no MAX_THREADS in {config:?}"))
    }

    /// Found in the latest round of faults: `--threads 1024` with cholmod
    /// or mumps reported 1024 while OpenBLAS, built for 64, ran 64. The
    /// count reported is what OpenBLAS takes, and the count in effect is
    /// left as it was.
    #[test]
    fn a_count_beyond_openblass_maximum_is_reported_as_what_it_runs() {
        let max = built_maximum();
        let before = threads();
        assert_eq!(threads_used(Some(1024)), Some(max.min(1024)));
        assert_eq!(threads_used(Some(1)), Some(1));
        assert_eq!(threads(), before);
    }
}
