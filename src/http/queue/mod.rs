//! The bounded estimation queue: CPU-bound jobs run on `max_concurrent_estimations`
//! dedicated worker threads, with at most `queue_length` jobs waiting for one.
//!
//! A request first takes a place without waiting: when running + waiting jobs already fill
//! the capacity it is refused at once (503 `overloaded`), so a burst never builds an unbounded
//! backlog. Its job then goes into a channel that the workers drain in arrival order, and the
//! result comes back through a oneshot channel. A request that gives up while its job waits (a
//! timeout) leaves the job to be dropped unrun when a worker reaches it, which also frees the
//! place; a job that has started runs to the end (CPU work cannot be interrupted). The number
//! of running jobs is bounded by the number of threads, and jobs in the system by the
//! capacity, whatever the clients do.
//!
//! A request that gives up while its job *runs* raises the job's cancellation flag
//! ([`crate::app::CancelFlag`]), which the job hands to detection in its budget
//! ([`EstimationQueue::run_cancellable`]): detection stops before its next pass, so the worker is free
//! within one pass (a few ms on the crops `auto` works on) rather than when every pass has
//! run.
//!
//! Image jobs also take their share of a memory budget counted in pixels
//! ([`EstimationQueue::run_image`], `--max-inflight-pixels`): the decoded frame and every
//! working copy of detection are bounded per pixel (docs/deploy.md), so the pixels admitted
//! at once bound the memory of the image path. A job that does not fit is refused at once
//! with 503 `overloaded`, like a full queue.
//!
//! Why not `tokio::task::spawn_blocking`: with the admission bound in front of it, every job
//! woke an idle blocking thread and then the async task again, and on the 2-core load test
//! those thread switches cost more server CPU than the estimate itself (`perf`: a third of
//! all samples in the scheduler). Workers that stay busy while the channel has jobs avoid the
//! wake-ups under load, which is when they matter.

use super::error::ApiError;
use super::metrics::QueueMetrics;
use crate::app::{CancelFlag, contain};
use crossbeam_channel::{Receiver, Sender};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use tokio::sync::{OwnedSemaphorePermit, Semaphore, oneshot};

type Job = Box<dyn FnOnce() + Send + 'static>;

/// The queue and its worker threads; cheap to clone (clones share both). The threads end
/// when the last clone is dropped and the jobs already queued are done.
#[derive(Debug, Clone)]
pub struct EstimationQueue {
    inner: Arc<Inner>,
}

#[derive(Debug)]
struct Inner {
    /// Places for running + waiting jobs.
    places: Arc<Semaphore>,
    jobs: Sender<Job>,
    capacity: usize,
    running: Arc<AtomicUsize>,
    metrics: QueueMetrics,
    /// The image pixels admitted at once, at most.
    pixel_budget: Arc<AmountBudget>,
    /// The image body bytes held at once (being read, waiting or running), at most.
    body_budget: Arc<AmountBudget>,
}

/// An amount held against a fixed budget: pixels of admitted image jobs, or bytes of image
/// bodies.
#[derive(Debug)]
struct AmountBudget {
    capacity: u64,
    taken: std::sync::atomic::AtomicU64,
}

/// A share of a pixel or byte budget; given back when dropped.
#[derive(Debug)]
pub struct BudgetPermit {
    budget: Arc<AmountBudget>,
    amount: u64,
}

impl Drop for BudgetPermit {
    fn drop(&mut self) {
        self.budget.taken.fetch_sub(self.amount, Ordering::Relaxed);
    }
}

impl AmountBudget {
    /// Takes `amount` (at most the whole budget: a job larger than it runs alone) unless the
    /// jobs admitted already leave less than that free.
    fn try_take(budget: &Arc<Self>, amount: u64) -> Option<BudgetPermit> {
        let amount = amount.min(budget.capacity);
        budget
            .taken
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |taken| {
                (taken + amount <= budget.capacity).then_some(taken + amount)
            })
            .ok()
            .map(|_| BudgetPermit {
                budget: Arc::clone(budget),
                amount,
            })
    }
}

fn unbounded() -> Arc<AmountBudget> {
    bounded(u64::MAX)
}

fn bounded(capacity: u64) -> Arc<AmountBudget> {
    Arc::new(AmountBudget {
        capacity: capacity.max(1),
        taken: 0.into(),
    })
}

/// Raises a running job's cancellation flag when the request that waits for it goes away
/// (a timeout, a closed connection): the request's future is dropped, and this with it.
struct CancelOnDrop(CancelFlag);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        self.0.cancel();
    }
}

/// The queue's occupancy at one moment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Occupancy {
    /// Jobs running now.
    pub running: usize,
    /// Jobs waiting for a worker (including those of requests that gave up, until a worker
    /// drops them).
    pub waiting: usize,
    /// Running + waiting at most.
    pub capacity: usize,
}

/// A taken place; given back when dropped.
struct Place {
    _permit: OwnedSemaphorePermit,
    metrics: QueueMetrics,
    running: Arc<AtomicUsize>,
    started: bool,
}

impl Place {
    fn start(&mut self) {
        self.started = true;
        self.metrics.waiting.dec();
        self.metrics.running.inc();
        self.running.fetch_add(1, Ordering::Relaxed);
    }
}

impl Drop for Place {
    fn drop(&mut self) {
        if self.started {
            self.running.fetch_sub(1, Ordering::Relaxed);
            self.metrics.running.dec();
        } else {
            self.metrics.waiting.dec();
        }
    }
}

fn work(jobs: &Receiver<Job>) {
    while let Ok(job) = jobs.recv() {
        job();
    }
}

impl EstimationQueue {
    /// A queue with `workers` threads and at most `max_waiting` jobs waiting, with no pixel
    /// budget ([`Self::with_pixel_budget`] sets one).
    ///
    /// # Errors
    /// The I/O error when a worker thread cannot be spawned.
    pub fn new(workers: usize, max_waiting: usize, metrics: QueueMetrics) -> std::io::Result<Self> {
        let (jobs, queued) = crossbeam_channel::unbounded::<Job>();
        for i in 0..workers {
            let queued = queued.clone();
            std::thread::Builder::new()
                .name(format!("qrpose-estimate-{i}"))
                .spawn(move || work(&queued))?;
        }
        let capacity = workers + max_waiting;
        Ok(Self {
            inner: Arc::new(Inner {
                places: Arc::new(Semaphore::new(capacity)),
                jobs,
                capacity,
                running: Arc::new(AtomicUsize::new(0)),
                metrics,
                pixel_budget: unbounded(),
                body_budget: unbounded(),
            }),
        })
    }

    /// This queue with image bodies admitted against `max_inflight_body_bytes`
    /// ([`Self::take_body_bytes`]). Call it before the queue is cloned or used.
    #[must_use]
    pub fn with_body_budget(mut self, max_inflight_body_bytes: u64) -> Self {
        if let Some(inner) = Arc::get_mut(&mut self.inner) {
            inner.body_budget = bounded(max_inflight_body_bytes);
        }
        self
    }

    /// Takes `bytes` of the body budget for an image body about to be read, to be held
    /// until the body is freed (the permit goes with the bytes, [`crate::http::image_input`]).
    ///
    /// # Errors
    /// 503 `overloaded` at once when the bodies held already leave too few bytes free.
    pub fn take_body_bytes(&self, bytes: u64) -> Result<BudgetPermit, ApiError> {
        AmountBudget::try_take(&self.inner.body_budget, bytes).ok_or_else(|| {
            self.inner.metrics.rejected.inc();
            tracing::debug!(
                bytes,
                budget = self.inner.body_budget.capacity,
                "body budget spent"
            );
            ApiError::body_budget_spent(bytes, self.inner.body_budget.capacity)
        })
    }

    /// This queue with image jobs admitted against `max_inflight_pixels`
    /// ([`Self::run_image`]). Call it before the queue is cloned or used.
    #[must_use]
    pub fn with_pixel_budget(mut self, max_inflight_pixels: u64) -> Self {
        if let Some(inner) = Arc::get_mut(&mut self.inner) {
            inner.pixel_budget = bounded(max_inflight_pixels);
        }
        self
    }

    /// As [`Self::run`], for a job on an image of `pixels` (weighted) pixels: the job first
    /// takes that share of the pixel budget and holds it until it ends.
    ///
    /// # Errors
    /// 503 `overloaded` at once when the images admitted already leave too few pixels free,
    /// or when the queue is full; as [`Self::run`] otherwise.
    pub async fn run_image<T, F>(&self, pixels: u64, job: F) -> Result<T, ApiError>
    where
        F: FnOnce(CancelFlag) -> T + Send + 'static,
        T: Send + 'static,
    {
        let Some(permit) = AmountBudget::try_take(&self.inner.pixel_budget, pixels) else {
            self.inner.metrics.rejected.inc();
            tracing::debug!(
                pixels,
                budget = self.inner.pixel_budget.capacity,
                "pixel budget spent"
            );
            return Err(ApiError::memory_budget_spent(
                pixels,
                self.inner.pixel_budget.capacity,
            ));
        };
        self.run_cancellable(move |cancel| {
            let _permit = permit;
            job(cancel)
        })
        .await
    }

    /// Runs `job` on a worker thread, in arrival order.
    ///
    /// # Errors
    /// 503 `overloaded` at once when the queue is full; 500 `internal` when the job panics
    /// (the panic is logged; the worker lives on).
    pub async fn run<T, F>(&self, job: F) -> Result<T, ApiError>
    where
        F: FnOnce() -> T + Send + 'static,
        T: Send + 'static,
    {
        self.run_cancellable(move |_| job()).await
    }

    /// [`Self::run`] for a job given the flag that is raised when its request gives up
    /// while it runs (a timeout, a closed connection): the job puts it into its detection
    /// budget, and detection stops before its next pass.
    ///
    /// # Errors
    /// As [`Self::run`].
    pub async fn run_cancellable<T, F>(&self, job: F) -> Result<T, ApiError>
    where
        F: FnOnce(CancelFlag) -> T + Send + 'static,
        T: Send + 'static,
    {
        let mut place = self.try_take_place()?;
        let (reply, result) = oneshot::channel();
        let span = tracing::Span::current();
        let cancel = CancelOnDrop(CancelFlag::new());
        let flag = cancel.0.clone();
        let job: Job = Box::new(move || {
            if reply.is_closed() {
                // The request gave up while waiting: nothing to compute for.
                return;
            }
            place.start();
            let outcome = contain(|| span.in_scope(|| job(flag)));
            // Free the place before answering, so that the next request finds it free.
            drop(place);
            // The receiver may be gone (timed out meanwhile); the result is then unused.
            let _ = reply.send(outcome);
        });
        self.inner
            .jobs
            .send(job)
            .map_err(|_| ApiError::internal("the estimation workers have stopped"))?;
        let answer = result.await;
        // Answered: raising the flag now stops nothing (the job has ended).
        drop(cancel);
        match answer {
            Ok(Ok(value)) => Ok(value),
            Ok(Err(panic)) => Err(ApiError::internal(format!(
                "estimation job panicked: {panic}"
            ))),
            Err(_) => Err(ApiError::internal("the estimation job was dropped")),
        }
    }

    fn try_take_place(&self) -> Result<Place, ApiError> {
        match Arc::clone(&self.inner.places).try_acquire_owned() {
            Ok(permit) => {
                self.inner.metrics.waiting.inc();
                Ok(Place {
                    _permit: permit,
                    metrics: self.inner.metrics.clone(),
                    running: Arc::clone(&self.inner.running),
                    started: false,
                })
            }
            Err(_) => {
                self.inner.metrics.rejected.inc();
                // Debug, not warn: under overload a line per refusal would add to the load;
                // the access log and `estimation_rejections_total` record every one.
                tracing::debug!(capacity = self.inner.capacity, "estimation queue full");
                Err(ApiError::overloaded(self.inner.capacity))
            }
        }
    }

    /// How many jobs run and wait now.
    pub fn occupancy(&self) -> Occupancy {
        let taken = self.inner.capacity - self.inner.places.available_permits();
        let running = self.inner.running.load(Ordering::Relaxed).min(taken);
        Occupancy {
            running,
            waiting: taken - running,
            capacity: self.inner.capacity,
        }
    }
}

#[cfg(test)]
mod tests;
