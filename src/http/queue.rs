//! The bounded estimation queue: CPU work runs on tokio's blocking threads, at most
//! `max_concurrent_estimations` at once, with at most `queue_length` requests waiting.
//!
//! A request first takes an [`Admission`] without waiting: when running + waiting already
//! equals the capacity it is refused at once (503 `overloaded`), so a burst never builds an
//! unbounded backlog. The admission then waits, first come first served, for a worker
//! [`Slot`], and the job runs on a blocking thread holding that slot. A request that times
//! out while waiting gives its place back; one that times out while its job runs leaves the
//! job to finish (CPU work cannot be cancelled) and the slot is freed when it does, so the
//! bound on running jobs always holds.

use super::error::ApiError;
use super::metrics::QueueMetrics;
use std::sync::Arc;
use tokio::sync::{OwnedSemaphorePermit, Semaphore};

/// The queue; cheap to clone (all clones share the same slots).
#[derive(Debug, Clone)]
pub struct EstimationQueue {
    inner: Arc<Inner>,
}

#[derive(Debug)]
struct Inner {
    /// Permits for running + waiting requests.
    admission: Arc<Semaphore>,
    /// Permits for running jobs.
    workers: Arc<Semaphore>,
    capacity: usize,
    max_running: usize,
    metrics: QueueMetrics,
}

/// A place in the queue: the request may wait for a worker.
#[derive(Debug)]
#[must_use = "an admission holds a place in the queue until it is dropped"]
pub struct Admission {
    queue: Arc<Inner>,
    /// `Some` while waiting; moved into the [`Slot`] by [`Admission::start`].
    place: Option<OwnedSemaphorePermit>,
}

/// A running worker slot: the job holding it counts against `max_concurrent_estimations`.
#[derive(Debug)]
#[must_use = "a slot holds a worker until it is dropped"]
pub struct Slot {
    queue: Arc<Inner>,
    _place: OwnedSemaphorePermit,
    _worker: OwnedSemaphorePermit,
}

/// The queue's occupancy at one moment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Occupancy {
    /// Jobs running now.
    pub running: usize,
    /// Requests waiting for a worker.
    pub waiting: usize,
    /// Running + waiting at most.
    pub capacity: usize,
}

impl EstimationQueue {
    /// A queue running at most `max_running` jobs with at most `max_waiting` requests waiting.
    pub fn new(max_running: usize, max_waiting: usize, metrics: QueueMetrics) -> Self {
        let capacity = max_running + max_waiting;
        Self {
            inner: Arc::new(Inner {
                admission: Arc::new(Semaphore::new(capacity)),
                workers: Arc::new(Semaphore::new(max_running)),
                capacity,
                max_running,
                metrics,
            }),
        }
    }

    /// Takes a place without waiting.
    ///
    /// # Errors
    /// 503 `overloaded` when running + waiting requests fill the capacity.
    pub fn try_admit(&self) -> Result<Admission, ApiError> {
        match Arc::clone(&self.inner.admission).try_acquire_owned() {
            Ok(place) => {
                self.inner.metrics.waiting.inc();
                Ok(Admission {
                    queue: Arc::clone(&self.inner),
                    place: Some(place),
                })
            }
            Err(_) => {
                self.inner.metrics.rejected.inc();
                tracing::warn!(capacity = self.inner.capacity, "estimation queue full");
                Err(ApiError::overloaded(self.inner.capacity))
            }
        }
    }

    /// Runs `job` on a blocking thread once a worker is free.
    ///
    /// # Errors
    /// 503 `overloaded` when the queue is full; 500 `internal` when the job panics.
    pub async fn run<T, F>(&self, job: F) -> Result<T, ApiError>
    where
        F: FnOnce() -> T + Send + 'static,
        T: Send + 'static,
    {
        self.try_admit()?.start().await?.run(job).await
    }

    /// How many jobs run and wait now.
    pub fn occupancy(&self) -> Occupancy {
        let free_workers = self.inner.workers.available_permits();
        let free_places = self.inner.admission.available_permits();
        let taken = self.inner.capacity - free_places;
        let running = (self.inner.max_running - free_workers).min(taken);
        Occupancy {
            running,
            waiting: taken - running,
            capacity: self.inner.capacity,
        }
    }
}

impl Admission {
    /// Waits for a free worker (first come, first served).
    ///
    /// # Errors
    /// 500 `internal` if the worker semaphore were closed (it never is).
    pub async fn start(mut self) -> Result<Slot, ApiError> {
        let worker = Arc::clone(&self.queue.workers)
            .acquire_owned()
            .await
            .map_err(|e| ApiError::internal(format!("estimation queue closed: {e}")))?;
        let place = self
            .place
            .take()
            .ok_or_else(|| ApiError::internal("admission started twice"))?;
        self.queue.metrics.waiting.dec();
        self.queue.metrics.running.inc();
        Ok(Slot {
            queue: Arc::clone(&self.queue),
            _place: place,
            _worker: worker,
        })
    }
}

impl Drop for Admission {
    fn drop(&mut self) {
        // Still waiting: a timed-out or cancelled request gives its place back.
        if self.place.is_some() {
            self.queue.metrics.waiting.dec();
        }
    }
}

impl Slot {
    /// Runs `job` on a blocking thread; the slot is held until the job returns, even when
    /// the awaiting request is gone.
    ///
    /// # Errors
    /// 500 `internal` when the job panics (the panic is logged).
    pub async fn run<T, F>(self, job: F) -> Result<T, ApiError>
    where
        F: FnOnce() -> T + Send + 'static,
        T: Send + 'static,
    {
        let span = tracing::Span::current();
        tokio::task::spawn_blocking(move || {
            let _slot = self;
            let _entered = span.enter();
            job()
        })
        .await
        .map_err(|e| ApiError::internal(format!("estimation job failed: {e}")))
    }
}

impl Drop for Slot {
    fn drop(&mut self) {
        self.queue.metrics.running.dec();
    }
}
