//! One primitive for what the service swaps at run time: the site, the auth file's clients
//! and the TLS configuration ([`Reloadable`]). A request takes one snapshot and uses it
//! throughout, so it never sees half of a reload; a refused file keeps what was loaded.

use arc_swap::ArcSwap;
use std::sync::{Mutex, PoisonError};

/// A value swapped whole on reload: lock-free reads ([`arc_swap`]), reloads one at a time.
#[derive(Debug)]
pub struct Reloadable<T> {
    current: ArcSwap<T>,
    /// Held while a reload reads and swaps, so that two reloads cannot finish out of order.
    reloading: Mutex<()>,
}

impl<T: Clone> Reloadable<T> {
    /// Holds `value`, loaded once by the caller.
    pub fn new(value: T) -> Self {
        Self {
            current: ArcSwap::from_pointee(value),
            reloading: Mutex::new(()),
        }
    }

    /// The value in use now (a cheap clone: the stores keep `Arc`s and acceptors).
    pub fn get(&self) -> T {
        T::clone(&self.current.load())
    }

    /// Loads with `load` and, when it succeeds, swaps in what `stored` makes of the loaded
    /// value (a site kept as `Some(site)`, say); blocking while another reload runs. On
    /// failure the value in use stays.
    ///
    /// # Errors
    /// `load`'s error.
    pub fn reload<U, E>(
        &self,
        load: impl FnOnce() -> Result<U, E>,
        stored: impl FnOnce(&U) -> T,
    ) -> Result<U, E> {
        let _one_at_a_time = self
            .reloading
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let loaded = load()?;
        self.current.store(std::sync::Arc::new(stored(&loaded)));
        Ok(loaded)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn a_reload_swaps_the_value_and_a_failed_one_keeps_it() {
        let store = Reloadable::new(Some(Arc::new(1)));
        let before = store.get();
        assert_eq!(
            store.reload(|| Ok::<_, ()>(Arc::new(2)), |n| Some(Arc::clone(n))),
            Ok(Arc::new(2))
        );
        assert_eq!(store.get(), Some(Arc::new(2)));
        assert_eq!(
            before,
            Some(Arc::new(1)),
            "a snapshot taken before stays whole"
        );
        assert_eq!(
            store.reload(|| Err::<Arc<i32>, _>("refused"), |n| Some(Arc::clone(n))),
            Err("refused")
        );
        assert_eq!(store.get(), Some(Arc::new(2)));
    }

    #[test]
    fn reloads_run_one_at_a_time() {
        let store = Arc::new(Reloadable::new(0_u32));
        let inside = Arc::new(std::sync::atomic::AtomicU32::new(0));
        let threads: Vec<_> = (1..=8)
            .map(|n| {
                let (store, inside) = (Arc::clone(&store), Arc::clone(&inside));
                std::thread::spawn(move || {
                    store.reload(
                        || {
                            let was = inside.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                            std::thread::sleep(std::time::Duration::from_millis(2));
                            inside.fetch_sub(1, std::sync::atomic::Ordering::SeqCst);
                            if was == 0 { Ok(n) } else { Err(was) }
                        },
                        |n| *n,
                    )
                })
            })
            .collect();
        for thread in threads {
            assert!(
                thread.join().expect("joins").is_ok(),
                "two loads overlapped"
            );
        }
        assert!((1..=8).contains(&store.get()));
    }
}
