//! How many poses this thread has solved: a counter that every solve entry point
//! ([`super::estimate_from_rays`], [`super::estimate_planar_points`]) raises by one.
//!
//! Callers that promise to solve each code once (the service's application layer, which
//! sizes each code before solving it) are checked against it: read it before and after an
//! operation on the same thread. It is per thread so that concurrent work on other threads
//! does not disturb the count, and costs one thread-local increment per solve.

use std::cell::Cell;

thread_local! {
    static SOLVES: Cell<u64> = const { Cell::new(0) };
}

/// Poses solved on this thread since it started.
#[must_use]
pub fn solves_on_this_thread() -> u64 {
    SOLVES.with(Cell::get)
}

/// Counts one solve on this thread.
pub(crate) fn count_solve() {
    SOLVES.with(|n| n.set(n.get().wrapping_add(1)));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_count_adds_one_on_this_thread_only() {
        let before = solves_on_this_thread();
        count_solve();
        count_solve();
        assert_eq!(solves_on_this_thread(), before + 2);
        let other = std::thread::spawn(solves_on_this_thread)
            .join()
            .expect("the other thread ends");
        assert_eq!(other, 0, "another thread's count starts at zero");
    }
}
