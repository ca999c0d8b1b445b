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
//! Why not `tokio::task::spawn_blocking`: with the admission bound in front of it, every job
//! woke an idle blocking thread and then the async task again, and on the 2-core load test
//! those thread switches cost more server CPU than the estimate itself (`perf`: a third of
//! all samples in the scheduler). Workers that stay busy while the channel has jobs avoid the
//! wake-ups under load, which is when they matter.

use super::error::ApiError;
use super::metrics::QueueMetrics;
use crate::detect::contain::contain;
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
    /// A queue with `workers` threads and at most `max_waiting` jobs waiting.
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
            }),
        })
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
        let mut place = self.try_take_place()?;
        let (reply, result) = oneshot::channel();
        let span = tracing::Span::current();
        let job: Job = Box::new(move || {
            if reply.is_closed() {
                // The request gave up while waiting: nothing to compute for.
                return;
            }
            place.start();
            let outcome = contain(|| span.in_scope(job));
            // Free the place before answering, so that the next request finds it free.
            drop(place);
            // The receiver may be gone (timed out meanwhile); the result is then unused.
            let _ = reply.send(outcome);
        });
        self.inner
            .jobs
            .send(job)
            .map_err(|_| ApiError::internal("the estimation workers have stopped"))?;
        match result.await {
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
mod tests {
    use super::*;
    use crate::api::problem::ErrorCode;
    use std::sync::mpsc;
    use std::time::Duration;

    const PATIENCE: Duration = Duration::from_secs(20);

    async fn until(what: &str, queue: &EstimationQueue, want: (usize, usize)) {
        let waited = tokio::time::timeout(PATIENCE, async {
            loop {
                let o = queue.occupancy();
                if (o.running, o.waiting) == want {
                    return;
                }
                tokio::time::sleep(Duration::from_millis(2)).await;
            }
        })
        .await;
        assert!(waited.is_ok(), "never reached {want:?}: {what}");
    }

    /// A job that runs until the returned sender sends (or is dropped).
    fn gate() -> (mpsc::Sender<()>, impl FnOnce() + Send + 'static) {
        let (open, gate) = mpsc::channel::<()>();
        (open, move || {
            let _ = gate.recv();
        })
    }

    #[tokio::test]
    async fn refuses_at_once_when_running_and_waiting_fill_the_capacity() {
        let queue = EstimationQueue::new(1, 1, QueueMetrics::default()).expect("threads");
        let (open_running, running) = gate();
        let (open_waiting, waiting) = gate();
        let first = tokio::spawn({
            let queue = queue.clone();
            async move { queue.run(running).await }
        });
        until("one running", &queue, (1, 0)).await;
        let second = tokio::spawn({
            let queue = queue.clone();
            async move { queue.run(waiting).await }
        });
        until("one waiting", &queue, (1, 1)).await;

        let refused = queue.run(|| ()).await.expect_err("full");
        assert_eq!(refused.code(), ErrorCode::Overloaded);

        open_running.send(()).expect("the first job waits");
        first.await.expect("task").expect("first job");
        open_waiting.send(()).expect("the second job waits");
        second.await.expect("task").expect("second job");
        until("empty", &queue, (0, 0)).await;
        assert_eq!(queue.run(|| 7).await.expect("room again"), 7);
    }

    #[tokio::test]
    async fn a_job_whose_request_gave_up_is_dropped_unrun() {
        let queue = EstimationQueue::new(1, 1, QueueMetrics::default()).expect("threads");
        let (open, blocker) = gate();
        let blocked = tokio::spawn({
            let queue = queue.clone();
            async move { queue.run(blocker).await }
        });
        until("one running", &queue, (1, 0)).await;
        let ran = Arc::new(AtomicUsize::new(0));
        let abandoned = {
            let ran = Arc::clone(&ran);
            queue.run(move || ran.fetch_add(1, Ordering::Relaxed))
        };
        let gave_up = tokio::time::timeout(Duration::from_millis(20), abandoned).await;
        assert!(gave_up.is_err(), "the job could not have run yet");

        open.send(()).expect("the blocker waits");
        blocked.await.expect("task").expect("blocker");
        until("empty", &queue, (0, 0)).await;
        assert_eq!(queue.run(|| ()).await.ok(), Some(()));
        assert_eq!(
            ran.load(Ordering::Relaxed),
            0,
            "the abandoned job never ran"
        );
    }

    #[tokio::test]
    async fn a_panicking_job_is_a_500_and_the_worker_lives_on() {
        let queue = EstimationQueue::new(1, 0, QueueMetrics::default()).expect("threads");
        let err = queue
            .run(|| -> u8 { panic!("secret detail") })
            .await
            .expect_err("a panic");
        assert_eq!(err.code(), ErrorCode::Internal);
        assert!(!err.problem().detail.contains("secret"));
        assert_eq!(queue.run(|| 1).await.expect("the worker lives on"), 1);
    }
}
