//! [`AppState`]: what every handler shares, passed with axum's `State`.

use super::metrics::Metrics;
use super::queue::EstimationQueue;
use crate::config::Settings;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Whether the service still takes new work.
#[derive(Debug, Clone, Default)]
pub struct Lifecycle {
    draining: Arc<AtomicBool>,
}

impl Lifecycle {
    /// From now on `/readyz` answers 503 `shutting_down`.
    pub fn start_draining(&self) {
        self.draining.store(true, Ordering::Relaxed);
    }

    /// Whether a shutdown has begun.
    pub fn is_draining(&self) -> bool {
        self.draining.load(Ordering::Relaxed)
    }
}

/// Why the state could not be built.
#[derive(Debug, thiserror::Error)]
pub enum StateError {
    /// An estimation worker thread could not be spawned.
    #[error("cannot start the estimation workers: {0}")]
    Workers(#[from] std::io::Error),
}

/// The state shared by all handlers; cheap to clone.
#[derive(Debug, Clone)]
pub struct AppState {
    /// The validated configuration.
    pub settings: Arc<Settings>,
    /// The bounded queue in front of every CPU-bound job.
    pub queue: EstimationQueue,
    /// The metrics registry.
    pub metrics: Arc<Metrics>,
    /// Ready or draining.
    pub lifecycle: Lifecycle,
}

impl AppState {
    /// Fresh state for `settings`: an empty queue and zeroed metrics.
    ///
    /// # Errors
    /// [`StateError`] when a worker thread cannot be spawned.
    pub fn new(settings: Settings) -> Result<Self, StateError> {
        let metrics = Arc::new(Metrics::new());
        let queue = EstimationQueue::new(
            settings.max_concurrent_estimations.get(),
            settings.queue_length,
            metrics.queue(),
        )?;
        Ok(Self {
            settings: Arc::new(settings),
            queue,
            metrics,
            lifecycle: Lifecycle::default(),
        })
    }
}
