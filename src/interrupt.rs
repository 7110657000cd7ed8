//! Cancellation of long library calls: a front door installs a hook
//! ([`with_hook`]) around a call, and the library's long loops and phase
//! boundaries ask it whether to stop ([`check`]), returning
//! [`Error::Interrupted`] when it says so. Without a hook (the CLI, where
//! SIGINT ends the process, and every library user who does not install
//! one) [`check`] is one thread-local read.
//!
//! The hook is scoped and thread-local: it applies to the thread that
//! installed it, for the duration of [`with_hook`]'s closure. Work the
//! library hands to rayon's threads (the local step of ARAP, penalty
//! sweeps) checks nothing; the calling thread checks before and after it.
//!
//! Rate: [`check`] consults the hook at most once every
//! [`CONSULT_INTERVAL`] of wall time (the first time one interval after
//! installation), so a loop may call it once per iteration of a few
//! microseconds' work; a check in between costs a clock read. Once the hook
//! has said stop, every later [`check`] fails at once without consulting
//! it again (a signal is reported once, and a caller that recorded one
//! failure and went on — a comparison of configurations — must still stop).
//!
//! Granularity: a check runs between phases (normal matrix, symbolic
//! analysis, numeric factorisation, triangular solves), per iteration
//! (ARAP, refinement, Lanczos) and per block of work inside the library's
//! own long loops (sparse Givens QR, right-hand-side blocks). A single
//! call into faer (a numeric Cholesky or `LDLᵀ` factorisation, a
//! triangular solve) or SuiteSparse cannot be interrupted: the check right
//! after it sees the request, so the delay is at most the longest such
//! call.
//!
//! State after an interruption: what [`Error::Interrupted`] leaves is what
//! any error of the same call leaves — an interrupted precompute leaves no
//! factor (solves fail until the next precompute), an interrupted solve
//! leaves the factor and the targets as they were.

use std::cell::RefCell;
use std::time::{Duration, Instant};

use crate::error::Error;

/// How often [`check`] consults the hook at most: a person pressing
/// Ctrl-C waits at most this long beyond the longest uninterruptible call.
pub const CONSULT_INTERVAL: Duration = Duration::from_millis(50);

/// An installed hook and when it was last consulted.
struct Hook {
    stop: Box<dyn FnMut() -> bool>,
    last: Instant,
    stopped: bool,
}

thread_local! {
    static HOOK: RefCell<Option<Hook>> = const { RefCell::new(None) };
}

/// Puts back the hook that was installed before [`with_hook`] (also when
/// its closure panics).
struct Restore(Option<Hook>);

impl Drop for Restore {
    fn drop(&mut self) {
        let previous = self.0.take();
        HOOK.with(|h| *h.borrow_mut() = previous);
    }
}

/// Runs `f` with `stop` as this thread's hook: [`check`] inside `f` fails
/// with [`Error::Interrupted`] once `stop` returns `true`. `stop` is called
/// at most every [`CONSULT_INTERVAL`], on this thread, and never again
/// after it returned `true`. The previous hook (if any) is restored when
/// `f` returns.
pub fn with_hook<T>(stop: impl FnMut() -> bool + 'static, f: impl FnOnce() -> T) -> T {
    let hook = Hook {
        stop: Box::new(stop),
        last: Instant::now(),
        stopped: false,
    };
    let _restore = Restore(HOOK.with(|h| h.borrow_mut().replace(hook)));
    f()
}

/// `Err(Error::Interrupted)` when this thread's hook asks to stop (or has
/// asked before), `Ok(())` otherwise or without a hook. Consults the hook
/// at most every [`CONSULT_INTERVAL`].
pub fn check() -> Result<(), Error> {
    let stop = HOOK.with(|h| {
        // A hook that calls back into the library (which would check
        // again) finds the cell borrowed: that inner check does nothing.
        let Ok(mut slot) = h.try_borrow_mut() else {
            return false;
        };
        let Some(hook) = slot.as_mut() else {
            return false;
        };
        if !hook.stopped && hook.last.elapsed() >= CONSULT_INTERVAL {
            hook.stopped = (hook.stop)();
            hook.last = Instant::now();
        }
        hook.stopped
    });
    if stop {
        Err(Error::Interrupted)
    } else {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;
    use std::rc::Rc;

    #[test]
    fn without_a_hook_nothing_stops() {
        assert!(check().is_ok());
    }

    #[test]
    fn a_hook_that_says_stop_stops_every_later_check_and_is_asked_once() {
        let asked = Rc::new(Cell::new(0));
        let counter = asked.clone();
        let result = with_hook(
            move || {
                counter.set(counter.get() + 1);
                true
            },
            || {
                std::thread::sleep(CONSULT_INTERVAL);
                let first = check();
                let second = check();
                (first, second)
            },
        );
        assert!(matches!(result.0, Err(Error::Interrupted)));
        assert!(matches!(result.1, Err(Error::Interrupted)));
        assert_eq!(asked.get(), 1);
        // Restored: no hook after the call.
        assert!(check().is_ok());
    }

    #[test]
    fn the_hook_is_not_asked_more_often_than_the_interval() {
        let asked = Rc::new(Cell::new(0u32));
        let counter = asked.clone();
        let t = Instant::now();
        with_hook(
            move || {
                counter.set(counter.get() + 1);
                false
            },
            || {
                for _ in 0..10_000 {
                    assert!(check().is_ok());
                }
            },
        );
        let intervals = t.elapsed().as_secs_f64() / CONSULT_INTERVAL.as_secs_f64();
        assert!(
            f64::from(asked.get()) <= intervals,
            "asked {} times in {intervals} intervals",
            asked.get()
        );
    }
}
