//! Cancelling detection from outside: whoever waits for a detection (the service's worker
//! queue, for a request that timed out or whose client went away) raises a [`CancelFlag`];
//! detection checks it before every pass ([`crate::budget::PassLog::may_continue`]) and
//! stops, so the worker is free one pass later instead of when every pass has run.
//!
//! The flag reaches detection through a scope rather than a parameter: [`run_cancellable`]
//! makes a flag the current thread's for the duration of a closure, and every detection run
//! inside it (however deep in the call chain, whichever entry point) sees it. Outside any
//! scope nothing is ever cancelled. Scopes nest; leaving one (also by a panic) restores the
//! flag that was current before.

use std::cell::RefCell;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// A cancellation flag, shared by its clones.
#[derive(Debug, Clone, Default)]
pub struct CancelFlag(Arc<AtomicBool>);

impl CancelFlag {
    /// A flag not yet raised.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Raises the flag: detection running under it stops before its next pass.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// Whether the flag has been raised.
    #[must_use]
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

thread_local! {
    static CURRENT: RefCell<Option<CancelFlag>> = const { RefCell::new(None) };
}

/// Puts back the flag that was current before a scope, when the scope ends.
struct Restore(Option<CancelFlag>);

impl Drop for Restore {
    fn drop(&mut self) {
        let previous = self.0.take();
        CURRENT.with(|current| *current.borrow_mut() = previous);
    }
}

/// Runs `work` with `flag` as this thread's cancellation flag.
pub fn run_cancellable<T>(flag: &CancelFlag, work: impl FnOnce() -> T) -> T {
    let previous = CURRENT.with(|current| current.borrow_mut().replace(flag.clone()));
    let _restore = Restore(previous);
    work()
}

/// Whether the current scope's flag has been raised (never, outside a scope).
#[must_use]
pub fn cancelled() -> bool {
    CURRENT.with(|current| {
        current
            .borrow()
            .as_ref()
            .is_some_and(CancelFlag::is_cancelled)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_raised_flag_is_seen_inside_its_scope_only() {
        let flag = CancelFlag::new();
        assert!(!cancelled());
        run_cancellable(&flag, || {
            assert!(!cancelled());
            flag.cancel();
            assert!(cancelled());
            let inner = CancelFlag::new();
            run_cancellable(&inner, || assert!(!cancelled()));
            assert!(cancelled(), "the outer flag is current again");
        });
        assert!(!cancelled(), "no flag outside a scope");
    }

    #[test]
    fn a_panicking_scope_restores_the_previous_flag() {
        let outer = CancelFlag::new();
        outer.cancel();
        run_cancellable(&outer, || {
            let caught = std::panic::catch_unwind(|| {
                run_cancellable(&CancelFlag::new(), || panic!("a detector bug"));
            });
            assert!(caught.is_err());
            assert!(cancelled());
        });
    }
}
