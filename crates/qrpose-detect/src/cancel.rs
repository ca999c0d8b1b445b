//! Cancelling detection from outside: whoever waits for a detection (the service's worker
//! queue, for a request that timed out or whose client went away) raises a [`CancelFlag`];
//! detection checks it before every pass (the budget's [`crate::PassLog`]) and
//! stops, so the worker is free one pass later instead of when every pass has run.
//!
//! The flag travels in the detection's [`crate::Budget`], beside its deadline: whoever
//! builds the budget decides what may cancel it. A budget's default flag is never raised.

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

/// Two flags are equal when they are the same flag (clones of one another).
impl PartialEq for CancelFlag {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

impl Eq for CancelFlag {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_raised_flag_is_seen_by_its_clones_only() {
        let flag = CancelFlag::new();
        let clone = flag.clone();
        let other = CancelFlag::new();
        assert!(!clone.is_cancelled());
        flag.cancel();
        assert!(clone.is_cancelled() && !other.is_cancelled());
        assert_eq!(flag, clone);
        assert_ne!(flag, other);
    }
}
